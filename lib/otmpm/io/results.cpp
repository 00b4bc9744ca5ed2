// HDF5 result file and XDMF sidecar (interfaces.md "Result file (HDF5)").
// Layout: root attributes; /frames/NNNNNN groups (attribute `time`, one
// rows x cols double dataset per particle field); /probes/<name>/time and
// /probes/<name>/<field> extendible histories; root-level series such as
// /energy/time and /energy/<field>. The file is flushed after every frame and
// history sample and the sidecar is replaced atomically afterwards, so
// a run killed between two writes leaves a consistent pair of files.
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"

#include <hdf5.h>

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

namespace {

/// Longest wall time between two rewrites of the XDMF sidecar.
constexpr std::chrono::milliseconds kXdmfInterval{250};

/// Rows per chunk of the extendible probe datasets (one row per sample).
constexpr hsize_t kProbeChunkRows = 256;
/// Components of an XDMF XYZ geometry.
constexpr int kXdmfSpaceDim = 3;
/// Name of the zero-padded copy of a 1D `x` that the sidecar uses as XYZ geometry.
constexpr const char* kPaddedX = "x3";

/// Owns one HDF5 identifier and closes it with the matching H5?close.
class Handle {
public:
  Handle() = default;
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept {
    std::swap(id_, o.id_);
    std::swap(close_, o.close_);
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (id_ >= 0 && close_) close_(id_);
  }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

/// Silences HDF5's default printing of its error stack: errors become
/// exceptions with context instead.
void silence_hdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": HDF5 could not " + what);
}

hid_t checked(hid_t id, const std::string& path, const std::string& what) {
  if (id < 0) fail(path, what);
  return id;
}
void checked_status(herr_t status, const std::string& path, const std::string& what) {
  if (status < 0) fail(path, what);
}

Handle group(hid_t parent, const std::string& name, const std::string& path) {
  return Handle(checked(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                        "create group " + name),
                H5Gclose);
}

/// A fixed-length, null-terminated UTF-8 string type of `length` characters.
Handle string_type(std::size_t length, const std::string& path) {
  Handle t(checked(H5Tcopy(H5T_C_S1), path, "copy the string type"), H5Tclose);
  checked_status(H5Tset_size(t.get(), length + 1), path, "size a string type");
  checked_status(H5Tset_strpad(t.get(), H5T_STR_NULLTERM), path, "pad a string type");
  checked_status(H5Tset_cset(t.get(), H5T_CSET_UTF8), path, "set a string character set");
  return t;
}

/// Writes a scalar attribute of memory type `type` on `object`, replacing an existing one.
void write_attribute(hid_t object, const std::string& name, hid_t type, const void* value, const std::string& path) {
  const std::string what = "write attribute " + name;
  const htri_t exists = H5Aexists(object, name.c_str());
  checked_status(exists, path, what);
  if (exists > 0) checked_status(H5Adelete(object, name.c_str()), path, "replace attribute " + name);
  Handle space(checked(H5Screate(H5S_SCALAR), path, what), H5Sclose);
  Handle attr(checked(H5Acreate2(object, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT), path, what),
              H5Aclose);
  checked_status(H5Awrite(attr.get(), type, value), path, what);
}

void write_string_attribute(hid_t object, const std::string& name, const std::string& value, const std::string& path) {
  Handle t = string_type(value.size(), path);
  write_attribute(object, name, t.get(), value.c_str(), path);
}

/// Writes a contiguous rows x cols dataset of doubles.
void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const double* data,
                  const std::string& path) {
  const std::string what = "write dataset " + name;
  const hsize_t dims[2] = {rows, cols};
  Handle space(checked(H5Screate_simple(2, dims, nullptr), path, what), H5Sclose);
  Handle set(checked(H5Dcreate2(parent, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                                H5P_DEFAULT),
                     path, what),
             H5Dclose);
  if (rows * cols > 0) checked_status(H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), path, what);
}

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
                const std::string& path) {
  const std::string what = "append to probe dataset " + name;
  const int rank = cols == 0 ? 1 : 2;
  const hsize_t width = cols == 0 ? 1 : cols;
  Handle set(checked(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), path, what), H5Dclose);
  const hsize_t size[2] = {row + 1, cols}, start[2] = {row, 0}, count[2] = {1, width};
  checked_status(H5Dset_extent(set.get(), size), path, what);
  Handle file_space(checked(H5Dget_space(set.get()), path, what), H5Sclose);
  checked_status(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), path, what);
  Handle mem_space(checked(H5Screate_simple(rank, count, nullptr), path, what), H5Sclose);
  checked_status(H5Dwrite(set.get(), H5T_NATIVE_DOUBLE, mem_space.get(), file_space.get(), H5P_DEFAULT, values), path,
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
  Handle file;
  Handle frames;
  Handle probes;
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
  /// Rewrites the sidecar if `force` or if the last rewrite is older than
  /// kXdmfInterval: the sidecar is O(frames) long, so rewriting it for every
  /// frame would cost O(frames^2). It only ever names flushed frames.
  void publish_xdmf(bool force);
  std::chrono::steady_clock::time_point xdmf_written{};
  std::size_t xdmf_frames = 0;
  FrameInfo describe_frame(const std::string& group, double time, const std::vector<FieldView>& fields) const;
};

ResultWriter::ResultWriter(const std::string& path, const std::string& scene_text, int dimension)
    : impl_(std::make_unique<Impl>()), path_(path) {
  silence_hdf5();
  require(!path.empty(), "ResultWriter: the result file path is empty");
  require<std::invalid_argument>(dimension >= 1 && dimension <= kXdmfSpaceDim, path,
                                 ": ResultWriter: dimension must be 1, 2 or 3, got ", dimension);
  Impl& m = *impl_;
  m.path = path;
  m.dimension = dimension;
  m.xdmf_path = std::filesystem::path(path).replace_extension(".xdmf").string();
  m.h5_name = std::filesystem::path(path).filename().string();
  // The 1.8 file format: readable by every current HDF5 and allows attributes
  // above 64 KiB (a long scene text) in dense storage.
  Handle fapl(checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (file < 0) throw InputError(path + ": cannot create the result file");
  m.file = Handle(file, H5Fclose);
  m.frames = group(file, "frames", path);
  m.probes = group(file, "probes", path);
  write_string_attribute(file, "otmpm_version", OTMPM_VERSION, path);
  write_string_attribute(file, "scene", scene_text, path);
  write_string_attribute(file, "status", "running", path);
  set_attribute("dimension", static_cast<long long>(dimension));
  flush();
  m.write_xdmf();
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
  if (!force && now - xdmf_written < kXdmfInterval) return;
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
  info.points = x->rows;
  info.geometry = x->cols == 1 ? kPaddedX : "x";
  info.geometry_cols = x->cols == 1 ? kXdmfSpaceDim : x->cols;
  for (const FieldView& f : fields)
    if (f.name != "x" && f.rows == x->rows) info.attributes.emplace_back(f.name, f.cols);
  return info;
}

void ResultWriter::write_frame(double time, const std::vector<FieldView>& fields) {
  Impl& m = *impl_;
  const std::string name = frame_name(frames_);
  std::set<std::string> seen;
  for (const FieldView& f : fields) {
    check_name(f.name, "field");
    if (f.name == kPaddedX) throw std::invalid_argument(path_ + ": field name 'x3' is reserved for the XDMF geometry");
    if (!seen.insert(f.name).second)
      throw std::invalid_argument(path_ + ": field '" + f.name + "' given twice in one frame");
    check_field_shape(f, impl_->dimension, path_);
    check_finite(f.data, static_cast<std::size_t>(f.rows) * f.cols,
                 path_ + ": frame at t = " + format_double(time) + ", field '" + f.name + "'");
  }
  if (!std::isfinite(time)) throw InstabilityError(path_ + ": frame time is not finite");
  Handle g = group(m.frames.get(), name, path_);
  write_attribute(g.get(), "time", H5T_NATIVE_DOUBLE, &time, path_);
  for (const FieldView& f : fields)
    write_matrix(g.get(), f.name, static_cast<hsize_t>(f.rows), static_cast<hsize_t>(f.cols), f.data, path_);
  FrameInfo info = m.describe_frame("/frames/" + name, time, fields);
  if (info.geometry == kPaddedX) {
    const auto& x = *std::find_if(fields.begin(), fields.end(), [](const FieldView& f) { return f.name == "x"; });
    std::vector<double> padded(static_cast<std::size_t>(x.rows) * kXdmfSpaceDim, 0.0);
    for (int p = 0; p < x.rows; ++p) padded[static_cast<std::size_t>(p) * kXdmfSpaceDim] = x.data[p];
    write_matrix(g.get(), kPaddedX, static_cast<hsize_t>(x.rows), kXdmfSpaceDim, padded.data(), path_);
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
    Handle g = group(parent, name, path);
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
  append_row(g.get(), "time", info.samples, 0, &time, path);
  for (std::size_t i = 0; i < values.size(); ++i)
    append_row(g.get(), values[i].first, info.samples, info.fields[i].second, values[i].second.data(), path);
  ++info.samples;
}

void ResultWriter::append_probe(const std::string& probe, double time,
                                const std::vector<std::pair<std::string, std::vector<double>>>& values) {
  check_name(probe, "probe");
  impl_->append_sample(impl_->probes.get(), "probes/" + probe, probe, time, values, false,
                       path_ + ": probe '" + probe + "' at t = " + format_double(time));
  flush();
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
  flush();
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

// ---------------------------------------------------------------- reading

namespace {

/// Opens `path` read-only and the root attribute `name` (InputError if either is absent).
std::pair<Handle, Handle> open_attribute(const std::string& path, const std::string& name) {
  silence_hdf5();
  require(!path.empty(), "read attribute '", name, "': the result file path is empty");
  check_name(name, "attribute");
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) throw InputError(path + ": cannot open the result file");
  Handle f(file, H5Fclose);
  if (H5Aexists(file, name.c_str()) <= 0) throw InputError(path + ": no root attribute '" + name + "'");
  Handle a(checked(H5Aopen(file, name.c_str(), H5P_DEFAULT), path, "open attribute " + name), H5Aclose);
  return {std::move(f), std::move(a)};
}

} // namespace

std::string read_string_attribute(const std::string& path, const std::string& name) {
  auto [file, attr] = open_attribute(path, name);
  Handle type(checked(H5Aget_type(attr.get()), path, "read attribute " + name), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING) throw InputError(path + ": attribute '" + name + "' is not a string");
  if (H5Tis_variable_str(type.get()) > 0) {
    char* value = nullptr;
    checked_status(H5Aread(attr.get(), type.get(), &value), path, "read attribute " + name);
    std::string out = value ? value : "";
    H5free_memory(value);
    return out;
  }
  std::string buf(H5Tget_size(type.get()), '\0');
  checked_status(H5Aread(attr.get(), type.get(), buf.data()), path, "read attribute " + name);
  return buf.substr(0, buf.find('\0'));
}

double read_double_attribute(const std::string& path, const std::string& name) {
  auto [file, attr] = open_attribute(path, name);
  Handle type(checked(H5Aget_type(attr.get()), path, "read attribute " + name), H5Tclose);
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_FLOAT && cls != H5T_INTEGER) throw InputError(path + ": attribute '" + name + "' is not a number");
  double value = 0;
  checked_status(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value), path, "read attribute " + name);
  return value;
}

} // namespace otmpm
