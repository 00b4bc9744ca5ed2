// HDF5 result file and XDMF sidecar (docs/user-guide.md, "Result file (HDF5)").
// Layout: root attributes; /frames/NNNNNN groups (attribute `time`, one
// rows x cols double dataset per particle field); /probes/<name>/time and
// /probes/<name>/<field> extendible histories; root-level series such as
// /energy/time and /energy/<field>. The file is flushed after every frame and
// history sample and the sidecar is replaced atomically afterwards, so
// a run killed between two writes leaves a consistent pair of files.
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace otmpm {

using h5::checked;
using h5::checked_status;
using h5::Handle;
using h5::write_attribute;
using h5::write_matrix;
using h5::write_string_attribute;

namespace {

/// Longest wall time between two rewrites of the XDMF sidecar.
constexpr std::chrono::milliseconds kXdmfInterval{250};

/// Rows per chunk of the extendible probe datasets (one row per sample).
constexpr hsize_t kProbeChunkRows = 256;
/// Components of an XDMF XYZ geometry.
constexpr int kXdmfSpaceDim = 3;
/// Name of the zero-padded copy of a 1D `x` that the sidecar uses as XYZ geometry.
constexpr const char* kPaddedX = "x3";

/// Creates an extendible dataset of 0 x cols doubles (rank 1 when cols == 0).
void create_history(hid_t parent, const std::string& name, hsize_t cols, const std::string& path) {
  const std::string what = "create probe dataset " + name;
  const int rank = cols == 0 ? 1 : 2;
  const hsize_t dims[2] = {0, cols}, maxdims[2] = {H5S_UNLIMITED, cols}, chunk[2] = {kProbeChunkRows, cols};
  Handle space(checked(H5Screate_simple(rank, dims, maxdims), path, what), H5Sclose);
  Handle plist(checked(H5Pcreate(H5P_DATASET_CREATE), path, what), H5Pclose);
  checked_status(H5Pset_chunk(plist.get(), rank, chunk), path, what);
  Handle set(checked(H5Dcreate2(parent, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, plist.get(),
                                H5P_DEFAULT),
                     path, what),
             H5Dclose);
}

/// Appends row `row` (cols values; rank 1 when cols == 0) to an extendible dataset.
void append_row(hid_t parent, const std::string& name, hsize_t row, hsize_t cols, const double* values,
                const std::string& path, bool writes, hid_t transfer) {
  const std::string what = "append to probe dataset " + name;
  const int rank = cols == 0 ? 1 : 2;
  const hsize_t width = cols == 0 ? 1 : cols;
  Handle set(checked(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), path, what), H5Dclose);
  const hsize_t size[2] = {row + 1, cols}, start[2] = {row, 0}, count[2] = {1, width};
  checked_status(H5Dset_extent(set.get(), size), path, what);
  Handle file_space(checked(H5Dget_space(set.get()), path, what), H5Sclose);
  checked_status(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), path, what);
  Handle mem_space(checked(H5Screate_simple(rank, count, nullptr), path, what), H5Sclose);
  if (!writes) {
    checked_status(H5Sselect_none(file_space.get()), path, what);
    checked_status(H5Sselect_none(mem_space.get()), path, what);
  }
  checked_status(H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, mem_space.get(), file_space.get(), transfer, values), path,
                 what);
}

void check_name(const std::string& name, const std::string& what) {
  if (name.empty() || name.find('/') != std::string::npos || name == ".")
    throw std::invalid_argument("result file: invalid " + what + " name '" + name + "'");
}

/// A field's rows x cols must describe its data: rows >= 0, cols >= 1, data
/// when rows > 0, and the coordinates "x" one column per dimension (the XDMF
/// geometry). The length of `data` itself cannot be checked: the caller owns it.
void check_field_shape(const FieldView& f, int dimension, const std::string& path) {
  const std::string where = path + ": field '" + f.name + "': ";
  require<std::invalid_argument>(f.rows >= 0, where, "rows must be >= 0, got ", f.rows);
  require<std::invalid_argument>(f.cols >= 1, where, "cols must be >= 1, got ", f.cols);
  require<std::invalid_argument>(f.data || f.rows == 0, where, "data is null for ", f.rows, " x ", f.cols, " values");
  require<std::invalid_argument>(f.name != "x" || f.cols == dimension, where, "cols = ", f.cols,
                                 " but the coordinates need one column per dimension (", dimension, ")");
}

/// NaN or Inf never reach the result file: they mean the run became unstable.
void check_finite(const double* data, std::size_t n, const std::string& where) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(data[i]))
      throw InstabilityError(where + ": entry " + std::to_string(i) + " is not finite (" + std::to_string(data[i]) +
                             "); it is not written to the result file");
}

std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
    case '&': out += "&amp;"; break;
    case '<': out += "&lt;"; break;
    case '>': out += "&gt;"; break;
    case '"': out += "&quot;"; break;
    default: out += c;
    }
  }
  return out;
}

std::string format_double(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

std::string frame_name(int index) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%06d", index);
  return buf;
}

/// The XDMF AttributeType of a field with `cols` components in D dimensions.
const char* xdmf_attribute_type(int cols, int dimension) {
  if (cols == 1) return "Scalar";
  if (cols == dimension || cols == kXdmfSpaceDim) return "Vector";
  if (cols == kXdmfSpaceDim * kXdmfSpaceDim) return "Tensor";
  if (cols == 6) return "Tensor6";
  return "Matrix";
}

/// What the sidecar needs to know about one written frame.
struct FrameInfo {
  std::string group;      ///< "/frames/000012"
  double time = 0;
  int points = 0;         ///< rows of x
  std::string geometry;   ///< dataset used as geometry ("x" or the padded copy)
  int geometry_cols = 0;
  std::vector<std::pair<std::string, int>> attributes; ///< other fields with `points` rows: name, cols
};

/// One history group's samples and the components of each field (0: rank-1 scalar).
struct ProbeInfo {
  hsize_t samples = 0;
  std::vector<std::pair<std::string, hsize_t>> fields;
};

} // namespace

struct ResultWriter::Impl {
  ParallelIo parallel;
  Handle transfer; ///< collective data transfer (parallel files)
  hid_t dxpl() const { return transfer.valid() ? transfer.get() : H5P_DEFAULT; }
  bool root() const { return parallel.root; }
  Handle file;
  Handle frames;
  Handle probes;
  std::map<std::string, Handle> groups; ///< groups of histories (probes, walls), created on first use
  std::string path;
  std::string xdmf_path;
  std::string h5_name; ///< the .h5 file name as the sidecar refers to it (same directory)
  int dimension = 0;
  std::vector<FrameInfo> frame_infos;
  std::map<std::string, ProbeInfo> probe_infos; ///< by path: "probes/<name>" or a root series name

  /// Appends one sample to the histories of group `name` under `parent`
  /// (created with its datasets on the first sample; later samples must have
  /// the same fields). `scalars`: every field has one value and is stored as a
  /// rank-1 dataset, like `time`. `key` names the group in probe_infos.
  void append_sample(hid_t parent, const std::string& key, const std::string& name, double time,
                     const std::vector<std::pair<std::string, std::vector<double>>>& values, bool scalars,
                     const std::string& where);

  void write_xdmf() const;
  /// Writes field f (its rows of the frame) with `data` as dataset `name` of group g.
  void write_field(hid_t g, const std::string& name, const FieldView& f, const double* data) const {
    if (!parallel.mpi_comm)
      return write_matrix(g, name, static_cast<hsize_t>(f.rows), static_cast<hsize_t>(f.cols), data, path);
    const bool whole = f.total_rows < 0; // the root writes a whole frame alone
    const auto total = static_cast<hsize_t>(whole ? f.rows : f.total_rows);
    const auto rows = static_cast<hsize_t>(whole && !root() ? 0 : f.rows);
    h5::write_rows(g, name, total, static_cast<hsize_t>(f.cols), whole ? 0 : static_cast<hsize_t>(f.first_row), rows,
                   data, dxpl(), path);
  }
  /// Rewrites the sidecar if `force` or if the last rewrite is older than
  /// kXdmfInterval: the sidecar is O(frames) long, so rewriting it for every
  /// frame would cost O(frames^2). It only ever names flushed frames.
  void publish_xdmf(bool force);
  std::chrono::steady_clock::time_point xdmf_written{};
  std::size_t xdmf_frames = 0;
  FrameInfo describe_frame(const std::string& group, double time, const std::vector<FieldView>& fields) const;
};

ResultWriter::ResultWriter(const std::string& path, const std::string& scene_text, int dimension, ParallelIo parallel)
    : impl_(std::make_unique<Impl>()), path_(path) {
  h5::silence();
  require(!path.empty(), "ResultWriter: the result file path is empty");
  require<std::invalid_argument>(dimension >= 1 && dimension <= kXdmfSpaceDim, path,
                                 ": ResultWriter: dimension must be 1, 2 or 3, got ", dimension);
  Impl& m = *impl_;
  m.parallel = std::move(parallel);
  m.path = path;
  m.dimension = dimension;
  m.xdmf_path = std::filesystem::path(path).replace_extension(".xdmf").string();
  m.h5_name = std::filesystem::path(path).filename().string();
  // The 1.8 file format: readable by every current HDF5 and allows attributes
  // above 64 KiB (a long scene text) in dense storage.
  Handle fapl(checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  if (m.parallel.mpi_comm) m.transfer = h5::parallel_access(fapl.get(), m.parallel.mpi_comm, path);
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (file < 0) throw InputError(path + ": cannot create the result file");
  m.file = Handle(file, H5Fclose);
  m.frames = h5::create_group(file, "frames", path);
  m.probes = h5::create_group(file, "probes", path);
  write_string_attribute(file, "otmpm_version", OTMPM_VERSION, path);
  write_string_attribute(file, "scene", scene_text, path);
  write_string_attribute(file, "status", "running", path);
  set_attribute("dimension", static_cast<long long>(dimension));
  flush();
  if (m.root()) m.write_xdmf();
}

ResultWriter::~ResultWriter() {
  if (impl_ && impl_->file.valid()) H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL);
  try {
    if (impl_) impl_->publish_xdmf(true);
  } catch (...) { // a destructor must not throw; the .h5 file is complete anyway
  }
}

void ResultWriter::Impl::publish_xdmf(bool force) {
  const auto now = std::chrono::steady_clock::now();
  if (!root() || (!force && now - xdmf_written < kXdmfInterval)) return;
  if (force && xdmf_frames == frame_infos.size()) return;
  write_xdmf();
  xdmf_written = now;
  xdmf_frames = frame_infos.size();
}

FrameInfo ResultWriter::Impl::describe_frame(const std::string& group_path, double time,
                                             const std::vector<FieldView>& fields) const {
  FrameInfo info;
  info.group = group_path;
  info.time = time;
  const FieldView* x = nullptr;
  for (const FieldView& f : fields)
    if (f.name == "x") x = &f;
  if (!x) return info; // no coordinates: the frame is in the .h5 file only
  const auto total = [](const FieldView& f) { return f.total_rows >= 0 ? f.total_rows : f.rows; };
  info.points = static_cast<int>(total(*x));
  info.geometry = x->cols == 1 ? kPaddedX : "x";
  info.geometry_cols = x->cols == 1 ? kXdmfSpaceDim : x->cols;
  for (const FieldView& f : fields)
    if (f.name != "x" && total(f) == total(*x)) info.attributes.emplace_back(f.name, f.cols);
  return info;
}

void ResultWriter::write_frame(double time, const std::vector<FieldView>& fields) {
  Impl& m = *impl_;
  const std::string name = frame_name(frames_);
  std::set<std::string> seen;
  std::string bad; // the first non-finite entry of this rank's rows
  for (const FieldView& f : fields) {
    check_name(f.name, "field");
    if (f.name == kPaddedX) throw std::invalid_argument(path_ + ": field name 'x3' is reserved for the XDMF geometry");
    if (!seen.insert(f.name).second)
      throw std::invalid_argument(path_ + ": field '" + f.name + "' given twice in one frame");
    check_field_shape(f, impl_->dimension, path_);
    try {
      check_finite(f.data, static_cast<std::size_t>(f.rows) * f.cols,
                   path_ + ": frame at t = " + format_double(time) + ", field '" + f.name + "'");
    } catch (const InstabilityError& e) {
      if (!m.parallel.mpi_comm) throw;
      if (bad.empty()) bad = e.what();
    }
  }
  if (m.parallel.all && !m.parallel.all(bad.empty()))
    throw InstabilityError(bad.empty() ? path_ + ": frame at t = " + format_double(time) +
                                             ": a field is not finite on another rank; it is not written to the result file"
                                       : bad);
  if (!std::isfinite(time)) throw InstabilityError(path_ + ": frame time is not finite");
  Handle g = h5::create_group(m.frames.get(), name, path_);
  write_attribute(g.get(), "time", H5T_NATIVE_DOUBLE, &time, path_);
  for (const FieldView& f : fields) m.write_field(g.get(), f.name, f, f.data);
  FrameInfo info = m.describe_frame("/frames/" + name, time, fields);
  if (info.geometry == kPaddedX) {
    const auto& x = *std::find_if(fields.begin(), fields.end(), [](const FieldView& f) { return f.name == "x"; });
    std::vector<double> padded(static_cast<std::size_t>(x.rows) * kXdmfSpaceDim, 0.0);
    for (int p = 0; p < x.rows; ++p) padded[static_cast<std::size_t>(p) * kXdmfSpaceDim] = x.data[p];
    FieldView x3 = x;
    x3.cols = kXdmfSpaceDim;
    m.write_field(g.get(), kPaddedX, x3, padded.data());
  }
  ++frames_;
  flush();
  if (!info.geometry.empty()) m.frame_infos.push_back(std::move(info));
  m.publish_xdmf(false);
}

void ResultWriter::Impl::append_sample(hid_t parent, const std::string& key, const std::string& name, double time,
                                       const std::vector<std::pair<std::string, std::vector<double>>>& values,
                                       bool scalars, const std::string& where) {
  check_finite(&time, 1, where + ", time");
  for (const auto& [field, v] : values) {
    check_name(field, "history field");
    if (field == "time") throw std::invalid_argument(where + ": a history field may not be called 'time'");
    if (scalars && v.size() != 1) throw std::invalid_argument(where + ": field '" + field + "' is not a scalar");
    check_finite(v.data(), v.size(), where + ", field '" + field + "'");
  }
  auto it = probe_infos.find(key);
  if (it == probe_infos.end()) {
    Handle g = h5::create_group(parent, name, path);
    ProbeInfo info;
    create_history(g.get(), "time", 0, path);
    for (const auto& [field, v] : values) {
      if (v.empty()) throw std::invalid_argument(where + ": field '" + field + "' has no components");
      const hsize_t cols = scalars ? 0 : v.size();
      create_history(g.get(), field, cols, path);
      info.fields.emplace_back(field, cols);
    }
    it = probe_infos.emplace(key, std::move(info)).first;
  }
  ProbeInfo& info = it->second;
  if (values.size() != info.fields.size())
    throw std::invalid_argument(where + ": the fields differ from the first sample");
  for (std::size_t i = 0; i < values.size(); ++i)
    if (values[i].first != info.fields[i].first || std::max<hsize_t>(info.fields[i].second, 1) != values[i].second.size())
      throw std::invalid_argument(where + ": field '" + values[i].first + "' differs from the first sample");
  Handle g(checked(H5Gopen2(parent, name.c_str(), H5P_DEFAULT), path, "open " + key), H5Gclose);
  const bool writes = root(); // in a parallel file the root writes the row, the others select none
  append_row(g.get(), "time", info.samples, 0, &time, path, writes, dxpl());
  for (std::size_t i = 0; i < values.size(); ++i)
    append_row(g.get(), values[i].first, info.samples, info.fields[i].second, values[i].second.data(), path, writes,
               dxpl());
  ++info.samples;
}

void ResultWriter::append_probe(const std::string& probe, double time,
                                const std::vector<std::pair<std::string, std::vector<double>>>& values) {
  append_group_sample("probes", probe, time, values);
}

void ResultWriter::append_group_sample(const std::string& group, const std::string& name, double time,
                                       const std::vector<std::pair<std::string, std::vector<double>>>& values) {
  check_name(group, "history group");
  check_name(name, "history");
  if (group == "frames") throw std::invalid_argument(path_ + ": group name 'frames' is reserved");
  Impl& m = *impl_;
  auto it = m.groups.find(group);
  if (it == m.groups.end()) {
    Handle g = group == "probes" ? std::move(m.probes) : h5::create_group(m.file.get(), group, path_);
    it = m.groups.emplace(group, std::move(g)).first;
  }
  m.append_sample(it->second.get(), group + "/" + name, name, time, values, false,
                  path_ + ": " + group + " '" + name + "' at t = " + format_double(time));
  flush_sample();
}

void ResultWriter::flush_sample() {
  // A parallel file flushes with MPI_File_sync, which costs a disk sync: its
  // samples are flushed with the frame that a run writes after them.
  if (!impl_->parallel.mpi_comm) flush();
}

void ResultWriter::append_series(const std::string& series, double time,
                                 const std::vector<std::pair<std::string, double>>& values) {
  check_name(series, "series");
  if (series == "frames" || series == "probes")
    throw std::invalid_argument(path_ + ": series name '" + series + "' is reserved");
  std::vector<std::pair<std::string, std::vector<double>>> rows;
  for (const auto& [field, v] : values) rows.emplace_back(field, std::vector<double>{v});
  impl_->append_sample(impl_->file.get(), series, series, time, rows, true,
                       path_ + ": series '" + series + "' at t = " + format_double(time));
  flush_sample();
}

void ResultWriter::set_attribute(const std::string& name, double value) {
  check_name(name, "attribute");
  write_attribute(impl_->file.get(), name, H5T_NATIVE_DOUBLE, &value, path_);
}
void ResultWriter::set_attribute(const std::string& name, long long value) {
  check_name(name, "attribute");
  write_attribute(impl_->file.get(), name, H5T_NATIVE_LLONG, &value, path_);
}
void ResultWriter::set_attribute(const std::string& name, const std::string& value) {
  check_name(name, "attribute");
  write_string_attribute(impl_->file.get(), name, value, path_);
}

void ResultWriter::flush() {
  checked_status(H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL), path_, "flush the file");
}

void ResultWriter::publish() {
  flush();
  impl_->publish_xdmf(true);
}

/// Writes the sidecar: a temporal collection of Polyvertex grids whose
/// geometry and attributes point into the .h5 datasets. Written to a
/// temporary file and renamed into place, so readers never see half a file.
void ResultWriter::Impl::write_xdmf() const {
  std::ostringstream os;
  os << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
     << "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const std::string h5 = xml_escape(h5_name);
  auto data_item = [&](const std::string& dataset, int rows, int cols) {
    return "<DataItem Dimensions=\"" + std::to_string(rows) + " " + std::to_string(cols) +
           "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" + h5 + ":" + xml_escape(dataset) + "</DataItem>";
  };
  for (const FrameInfo& f : frame_infos) {
    os << "      <Grid Name=\"frame " << f.group.substr(f.group.rfind('/') + 1) << "\" GridType=\"Uniform\">\n"
       << "        <Time Value=\"" << format_double(f.time) << "\"/>\n"
       << "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << f.points
       << "\" NodesPerElement=\"1\"/>\n"
       << "        <Geometry GeometryType=\"" << (f.geometry_cols == 2 ? "XY" : "XYZ") << "\">\n          "
       << data_item(f.group + "/" + f.geometry, f.points, f.geometry_cols) << "\n        </Geometry>\n";
    for (const auto& [name, cols] : f.attributes)
      os << "        <Attribute Name=\"" << xml_escape(name) << "\" AttributeType=\""
         << xdmf_attribute_type(cols, dimension) << "\" Center=\"Node\">\n          "
         << data_item(f.group + "/" + name, f.points, cols) << "\n        </Attribute>\n";
    os << "      </Grid>\n";
  }
  os << "    </Grid>\n  </Domain>\n</Xdmf>\n";
  const std::string tmp = xdmf_path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << os.str();
    if (!out.flush()) throw std::runtime_error(tmp + ": cannot write the XDMF sidecar");
  }
  if (std::rename(tmp.c_str(), xdmf_path.c_str()) != 0)
    throw std::runtime_error(xdmf_path + ": cannot move the XDMF sidecar into place");
}

// ---------------------------------------------------------------- copying

namespace {

/// One history read from a result file: its layout, time and each field.
struct StoredHistory {
  HistoryLayout layout;
  h5::Matrix<double> time;
  std::vector<h5::Matrix<double>> fields;
};

/// Reads what copy_results needs of a history, checking it has `samples` rows.
StoredHistory read_history(hid_t file, const HistoryLayout& layout, int samples, const std::string& path) {
  StoredHistory h;
  h.layout = layout;
  Handle g = h5::open_group(file, (layout.probe ? layout.group + "/" : "") + layout.name, path);
  h.time = h5::read_double_matrix(g.get(), "time", path);
  for (const std::string& f : layout.fields) h.fields.push_back(h5::read_double_matrix(g.get(), f, path));
  bool complete = h.time.rows >= static_cast<hsize_t>(samples);
  for (const auto& m : h.fields) complete = complete && m.rows >= static_cast<hsize_t>(samples);
  if (!complete) h5::fail(path, "find " + std::to_string(samples) + " samples of history '" + layout.name + "'");
  return h;
}

/// Appends row `row` of a stored history to `to` (append_probe or append_series).
void append_stored_sample(const StoredHistory& h, hsize_t row, ResultWriter& to) {
  const double t = h.time.values[static_cast<std::size_t>(row)];
  std::vector<std::pair<std::string, std::vector<double>>> vectors;
  std::vector<std::pair<std::string, double>> scalars;
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    const auto begin = h.fields[i].values.begin() + static_cast<std::ptrdiff_t>(row * h.fields[i].cols);
    vectors.emplace_back(h.layout.fields[i],
                         std::vector<double>(begin, begin + static_cast<std::ptrdiff_t>(h.fields[i].cols)));
    scalars.emplace_back(h.layout.fields[i], *begin);
  }
  if (h.layout.probe) to.append_group_sample(h.layout.group, h.layout.name, t, vectors);
  else to.append_series(h.layout.name, t, scalars);
}

/// Frame `index` of a result file: its time and the datasets `fields`.
struct StoredFrame {
  double time = 0;
  std::vector<h5::Matrix<double>> fields;
};

StoredFrame read_frame(hid_t file, int index, const std::vector<std::string>& fields, const std::string& path) {
  Handle g = h5::open_group(file, "frames/" + frame_name(index), path);
  StoredFrame f;
  f.time = h5::read_double(g.get(), "time", path);
  for (const std::string& name : fields) f.fields.push_back(h5::read_double_matrix(g.get(), name, path));
  return f;
}

/// Runs `read`, turning an HDF5 failure into an InputError naming the file.
template <class F> auto reading(const std::string& path, F&& read) {
  try {
    return read();
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw InputError(path + ": cannot copy the results of the interrupted run: " + e.what());
  }
}

} // namespace

void copy_results(const std::string& from, ResultWriter& to, int frames, const std::vector<HistoryLayout>& histories,
                  const std::vector<std::string>& frame_fields) {
  h5::silence();
  const hid_t id = H5Fopen(from.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw InputError(from + ": cannot open the result file of the interrupted run");
  const Handle file(id, H5Fclose);
  std::vector<StoredHistory> stored;
  for (const HistoryLayout& layout : histories)
    stored.push_back(reading(from, [&] { return read_history(file.get(), layout, frames, from); }));
  for (int i = 0; i < frames; ++i) {
    for (const StoredHistory& h : stored) append_stored_sample(h, static_cast<hsize_t>(i), to);
    const StoredFrame frame = reading(from, [&] { return read_frame(file.get(), i, frame_fields, from); });
    std::vector<FieldView> views;
    for (std::size_t k = 0; k < frame_fields.size(); ++k)
      views.push_back({frame_fields[k], static_cast<int>(frame.fields[k].rows),
                       static_cast<int>(frame.fields[k].cols), frame.fields[k].values.data()});
    to.write_frame(frame.time, views);
  }
}

// ---------------------------------------------------------------- reading

namespace {

/// Opens `path` read-only and checks that it has a root attribute `name` of
/// type class `cls` or `alt` (InputError naming the file otherwise).
Handle open_with_attribute(const std::string& path, const std::string& name, H5T_class_t cls, H5T_class_t alt,
                           const char* kind) {
  h5::silence();
  require(!path.empty(), "read attribute '", name, "': the result file path is empty");
  check_name(name, "attribute");
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) throw InputError(path + ": cannot open the result file");
  Handle f(file, H5Fclose);
  if (!h5::has_attribute(file, name)) throw InputError(path + ": no root attribute '" + name + "'");
  const H5T_class_t c = h5::attribute_class(file, name, path);
  if (c != cls && c != alt) throw InputError(path + ": attribute '" + name + "' is not " + kind);
  return f;
}

} // namespace

std::string read_string_attribute(const std::string& path, const std::string& name) {
  const Handle file = open_with_attribute(path, name, H5T_STRING, H5T_STRING, "a string");
  return h5::read_string(file.get(), name, path);
}

double read_double_attribute(const std::string& path, const std::string& name) {
  const Handle file = open_with_attribute(path, name, H5T_FLOAT, H5T_INTEGER, "a number");
  return h5::read_double(file.get(), name, path);
}

} // namespace otmpm
