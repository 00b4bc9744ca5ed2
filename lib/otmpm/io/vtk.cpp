// VTK XML frame files (.vtp / .vtu) and their .pvd collection (see vtk.hpp).
#include "otmpm/io/vtk.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/text_files.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

namespace otmpm {

namespace fs = std::filesystem;

namespace {

/// Components of a VTK point.
constexpr int kPointComponents = 3;
/// VTK_VERTEX, the cell type of one particle in a .vtu file.
constexpr std::uint8_t kVtkVertex = 1;

constexpr const char* byte_order() { return std::endian::native == std::endian::little ? "LittleEndian" : "BigEndian"; }

/// The raw appended data of one VTK XML file: blocks of a UInt64 byte count
/// followed by the bytes, addressed by their offset from the start.
class Appended {
public:
  /// Appends an array and returns its offset.
  template <class T> std::size_t add(const std::vector<T>& values) {
    const std::size_t offset = bytes_.size();
    const std::uint64_t n = values.size() * sizeof(T);
    put(&n, sizeof n);
    put(values.data(), n);
    return offset;
  }
  const std::string& bytes() const { return bytes_; }

private:
  void put(const void* data, std::size_t n) { bytes_.append(static_cast<const char*>(data), n); }
  std::string bytes_;
};

/// `<DataArray .../>` naming an appended array; `names`: the components'
/// names separated by spaces (ComponentName0, ...), or "".
std::string data_array(const char* type, const std::string& name, int components, std::size_t offset,
                       const std::string& names = "") {
  std::string labels;
  std::size_t start = 0;
  for (int i = 0; !names.empty() && start <= names.size(); ++i) {
    const std::size_t end = std::min(names.find(' ', start), names.size());
    labels += " ComponentName" + std::to_string(i) + "=\"" + text::xml_escape(names.substr(start, end - start)) + "\"";
    start = end + 1;
  }
  return "<DataArray type=\"" + std::string(type) + "\" Name=\"" + text::xml_escape(name) +
         "\" NumberOfComponents=\"" + std::to_string(components) + "\"" + labels + " format=\"appended\" offset=\"" +
         std::to_string(offset) + "\"/>";
}

/// Appends `values` as doubles, or rounded to float when `single`; returns
/// the offset and the VTK type.
std::pair<std::size_t, const char*> add_real(Appended& data, const double* values, std::size_t n, bool single) {
  if (single) return {data.add(std::vector<float>(values, values + n)), "Float32"};
  return {data.add(std::vector<double>(values, values + n)), "Float64"};
}

std::string frame_file_name(int index, const std::string& extension) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%06d.", index);
  return buf + extension;
}

/// The piece of rank `piece` of frame `index`: frame_NNNNNN_RRRR.EXT.
std::string piece_file_name(int index, int piece, const std::string& extension) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "frame_%06d_%04d.", index, piece);
  return buf + extension;
}

/// The VTK type of the point data of a file (output.precision).
const char* real_type(bool single) { return single ? "Float32" : "Float64"; }

} // namespace

VtkSeriesWriter::VtkSeriesWriter(std::string pvd, std::string dir, std::string extension, int dimension,
                                 std::string run_id, std::string result_name, bool single, ParallelIo io)
    : pvd_(std::move(pvd)), dir_(std::move(dir)), extension_(std::move(extension)), run_id_(std::move(run_id)),
      result_name_(std::move(result_name)), dimension_(dimension), single_(single), io_(std::move(io)) {
  require<std::invalid_argument>(extension_ == "vtp" || extension_ == "vtu", "VtkSeriesWriter: extension '",
                                 extension_, "' is not vtp or vtu");
  require<std::invalid_argument>(dimension_ >= 1 && dimension_ <= kPointComponents,
                                 "VtkSeriesWriter: dimension must be 1, 2 or 3, got ", dimension_);
  if (!io_.root) return;
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw OutputError(dir_ + ": cannot create the directory of the VTK frames: " + ec.message());
}

std::string VtkSeriesWriter::frame_text(double time, const std::vector<FieldView>& fields) const {
  const FieldView* x = nullptr;
  for (const FieldView& f : fields)
    if (f.name == "x") x = &f;
  require<std::invalid_argument>(x != nullptr, "VtkSeriesWriter: a frame needs the field x");
  const int n = x->rows;
  Appended data;
  const std::size_t time_offset = data.add(std::vector<double>{time});
  std::vector<double> points(static_cast<std::size_t>(n) * kPointComponents, 0.0);
  for (int p = 0; p < n; ++p)
    for (int k = 0; k < dimension_; ++k) points[static_cast<std::size_t>(p) * kPointComponents + k] = x->data[p * dimension_ + k];
  const auto [points_offset, points_type] = add_real(data, points.data(), points.size(), single_);
  std::ostringstream point_data;
  for (const FieldView& f : fields) {
    if (f.name == "x" || f.rows != n) continue;
    const auto [offset, type] = add_real(data, f.data, static_cast<std::size_t>(f.rows) * f.cols, single_);
    point_data << "        " << data_array(type, f.name, f.cols, offset, f.components) << "\n";
  }
  std::vector<std::int64_t> connectivity(static_cast<std::size_t>(n)), offsets(static_cast<std::size_t>(n));
  for (int p = 0; p < n; ++p) {
    connectivity[static_cast<std::size_t>(p)] = p;
    offsets[static_cast<std::size_t>(p)] = p + 1;
  }
  const std::size_t connectivity_offset = data.add(connectivity), offsets_offset = data.add(offsets);
  const bool poly = extension_ == "vtp";
  const std::string type = poly ? "PolyData" : "UnstructuredGrid";
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"" << type << "\" version=\"1.0\" byte_order=\"" << byte_order()
     << "\" header_type=\"UInt64\"" << text::run_id_attributes(run_id_, result_name_) << ">\n  <" << type
     << ">\n    <FieldData>\n      "
     << "<DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"appended\" offset=\""
     << time_offset << "\"/>\n    </FieldData>\n";
  if (poly)
    os << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfVerts=\"" << n
       << "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  else os << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n";
  os << "      <PointData>\n" << point_data.str() << "      </PointData>\n      <Points>\n        "
     << data_array(points_type, "Points", kPointComponents, points_offset) << "\n      </Points>\n      <"
     << (poly ? "Verts" : "Cells") << ">\n        " << data_array("Int64", "connectivity", 1, connectivity_offset)
     << "\n        " << data_array("Int64", "offsets", 1, offsets_offset) << "\n";
  if (!poly)
    os << "        "
       << data_array("UInt8", "types", 1, data.add(std::vector<std::uint8_t>(static_cast<std::size_t>(n), kVtkVertex)))
       << "\n";
  os << "      </" << (poly ? "Verts" : "Cells") << ">\n    </Piece>\n  </" << type
     << ">\n  <AppendedData encoding=\"raw\">\n   _" << data.bytes() << "\n  </AppendedData>\n</VTKFile>\n";
  return os.str();
}

std::string VtkSeriesWriter::pieces_text(int index, const std::vector<FieldView>& fields) const {
  const bool poly = extension_ == "vtp";
  const std::string type = poly ? "PPolyData" : "PUnstructuredGrid";
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"" << type << "\" version=\"1.0\" byte_order=\"" << byte_order()
     << "\" header_type=\"UInt64\"" << text::run_id_attributes(run_id_, result_name_) << ">\n  <" << type
     << " GhostLevel=\"0\">\n    <PPointData>\n";
  for (const FieldView& f : fields)
    if (f.name != "x")
      os << "      <PDataArray type=\"" << real_type(single_) << "\" Name=\"" << text::xml_escape(f.name)
         << "\" NumberOfComponents=\"" << f.cols << "\"/>\n";
  os << "    </PPointData>\n    <PPoints>\n      <PDataArray type=\"" << real_type(single_)
     << "\" Name=\"Points\" NumberOfComponents=\"" << kPointComponents << "\"/>\n    </PPoints>\n";
  for (int r = 0; r < io_.size; ++r)
    os << "    <Piece Source=\"" << text::xml_escape(piece_file_name(index, r, extension_)) << "\"/>\n";
  os << "  </" << type << ">\n</VTKFile>\n";
  return os.str();
}

void VtkSeriesWriter::write_file(const std::string& name, const std::string& text) const {
  const std::string path = (fs::path(dir_) / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  if (!out.flush()) throw OutputError(path + ": cannot write the VTK frame: " + std::strerror(errno));
}

void VtkSeriesWriter::write_frame(int index, double time, const std::vector<FieldView>& fields) {
  std::string name = frame_file_name(index, extension_);
  if (io_.size > 1) {
    write_file(piece_file_name(index, io_.rank, extension_), frame_text(time, fields));
    name = frame_file_name(index, "p" + extension_);
    if (io_.root) write_file(name, pieces_text(index, fields));
  } else {
    write_file(name, frame_text(time, fields));
  }
  frames_.emplace_back(time, (fs::path(dir_).filename() / name).string());
}

void VtkSeriesWriter::publish() {
  if (!io_.root) return;
  if (published_ == frames_.size() && published_ > 0) return;
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"" << byte_order() << "\""
     << text::run_id_attributes(run_id_, result_name_) << ">\n  <Collection>\n";
  for (const auto& [time, file] : frames_)
    os << "    <DataSet timestep=\"" << text::exact(time) << "\" group=\"\" part=\"0\" file=\""
       << text::xml_escape(file) << "\"/>\n";
  os << "  </Collection>\n</VTKFile>\n";
  text::replace_file(pvd_, os.str(), "VTK collection");
  published_ = frames_.size();
}

} // namespace otmpm
