// HDF5 result file and XDMF sidecar (docs/user-guide.md, "Result file (HDF5)").
// Layout: root attributes; /frames/NNNNNN groups (attribute `time`, one
// rows x cols double dataset per particle field); /probes/<name>/time and
// /probes/<name>/<field> extendible histories; root-level series such as
// /energy/time and /energy/<field>; /xdmf/vertices_N, the connectivity of the
// sidecar's Polyvertex topology. The file is flushed after every frame and
// history sample and the sidecar is replaced atomically afterwards, so a run
// killed between two writes leaves a consistent pair of files. Space for
// each write is reserved before HDF5 writes it (h5::reserve_space), so a full
// disk or a file size limit stops the output cleanly.
#include "otmpm/io/results.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/io/text_files.hpp"
#include "otmpm/io/undo_journal.hpp"
#include "otmpm/io/vtk.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace otmpm {

using h5::checked;
using h5::checked_status;
using h5::Handle;
using h5::write_attribute;
using h5::write_matrix;
using h5::write_string_attribute;
using text::xml_escape;

namespace {

/// Longest wall time between two rewrites of the XDMF sidecar (and the .pvd).
constexpr std::chrono::milliseconds kXdmfInterval{250};

/// Rows per chunk of the extendible probe datasets (one row per sample).
constexpr hsize_t kProbeChunkRows = 256;
/// Components of an XDMF XYZ geometry.
constexpr int kXdmfSpaceDim = 3;
/// Name of the zero-padded copy of a 1D `x` that the sidecar uses as XYZ geometry.
constexpr const char* kPaddedX = "x3";
/// The group of the sidecar's connectivity datasets (vertices_N: 0 .. N-1).
constexpr const char* kXdmfGroup = "xdmf";
/// Bytes of HDF5 metadata allowed per dataset or group written (object
/// header, link, B-tree and heap growth) when reserving space.
constexpr std::uint64_t kMetadataBytes = 4096;
/// Bytes always kept in reserve beyond the next write, so that the final
/// status and summary attributes fit after an output was refused.
constexpr std::uint64_t kFinalReserve = 64 * 1024;

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
  const std::string why = invalid_name_reason(name);
  if (!why.empty()) throw std::invalid_argument("result file: invalid " + what + " name '" + name + "': " + why);
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
  if (!f.components.empty()) {
    const auto names = 1 + std::count(f.components.begin(), f.components.end(), ' ');
    require<std::invalid_argument>(names == f.cols, where, "cols = ", f.cols, " but the components \"", f.components,
                                   "\" name ", names);
  }
}

/// The largest magnitude a 32-bit float holds (FLT_MAX).
constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());

/// In a single-precision file every value must fit in a float (beyond
/// FLT_MAX it would become Inf): a larger one means the run became unstable.
void check_float_range(const double* data, std::size_t n, const std::string& where) {
  for (std::size_t i = 0; i < n; ++i)
    if (std::abs(data[i]) > kFloatMax)
      throw InstabilityError(where + ": entry " + std::to_string(i) + " (" + format_number(data[i]) +
                             ") exceeds the range of single precision (output.precision = \"single\"); it is not "
                             "written to the result file");
}

/// NaN or Inf never reach the result file: they mean the run became unstable.
void check_finite(const double* data, std::size_t n, const std::string& where) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(data[i]))
      throw InstabilityError(where + ": entry " + std::to_string(i) + " is not finite (" + format_number(data[i]) +
                             "); it is not written to the result file");
}

std::string frame_name(int index) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%06d", index);
  return buf;
}

/// The XDMF AttributeType of a field with `cols` components in D dimensions
/// (`symmetric`: a symmetric tensor by its independent components).
const char* xdmf_attribute_type(int cols, int dimension, bool symmetric) {
  if (cols == 1) return "Scalar";
  if (symmetric) return cols == 6 ? "Tensor6" : "Matrix";
  if (cols == dimension || cols == kXdmfSpaceDim) return "Vector";
  if (cols == kXdmfSpaceDim * kXdmfSpaceDim) return "Tensor";
  if (cols == 6) return "Tensor6";
  return "Matrix";
}

/// The dataset holding the connectivity 0 .. points-1 of a Polyvertex topology.
std::string vertices_name(long long points) { return "vertices_" + std::to_string(points); }

/// What the sidecar needs to know about one written frame.
struct FrameInfo {
  std::string group;      ///< "/frames/000012"
  double time = 0;
  long long points = 0;   ///< rows of x (of all ranks)
  std::string geometry;   ///< dataset used as geometry ("x" or the padded copy)
  int geometry_cols = 0;
  /// Other fields with `points` rows: name, cols, whether a symmetric tensor's components.
  std::vector<std::tuple<std::string, int, bool>> attributes;
  int precision = 8; ///< bytes per value of the frame's datasets (XDMF Precision)
};

/// One history group's samples and the components of each field (0: rank-1 scalar).
struct ProbeInfo {
  hsize_t samples = 0;
  std::vector<std::pair<std::string, hsize_t>> fields;
};

/// Bytes per chunk a compressed dataset may need beyond its values: deflate
/// stores at most 0.1% + 12 bytes more than it was given (zlib's bound, and
/// the filter is optional: a chunk it cannot shrink is stored as is), and
/// the chunk's entry in the dataset's B-tree index (its key and address)
/// with a share of the B-tree node, counted generously.
constexpr std::uint64_t kChunkOverhead = 256;

/// The bytes a dataset of rows x cols values of `value_bytes` bytes may
/// take, with its metadata: uncompressed (compressed data is bounded by the
/// uncompressed size plus kChunkOverhead and 0.1% per chunk).
std::uint64_t dataset_bytes(std::uint64_t rows, std::uint64_t cols, std::uint64_t value_bytes, bool compressed) {
  const std::uint64_t data = rows * cols * value_bytes;
  if (!compressed || data == 0) return data + kMetadataBytes;
  const std::uint64_t chunk = h5::chunk_rows(rows, cols, value_bytes);
  const std::uint64_t chunks = (rows + chunk - 1) / chunk;
  return data + data / 1000 + chunks * kChunkOverhead + 2 * kMetadataBytes;
}

/// The bytes a frame's datasets hold, with their metadata.
std::uint64_t frame_bytes(const std::vector<FieldView>& fields, int dimension, std::uint64_t value_bytes,
                          bool compressed) {
  std::uint64_t bytes = 2 * kMetadataBytes; // the group, the sidecar's vertices
  for (const FieldView& f : fields) {
    const auto rows = static_cast<std::uint64_t>(f.rows), cols = static_cast<std::uint64_t>(f.cols);
    bytes += dataset_bytes(rows, cols, value_bytes, compressed);
    if (f.name == "x" && dimension == 1) bytes += dataset_bytes(rows, kXdmfSpaceDim, value_bytes, compressed);
    if (f.name == "x") bytes += dataset_bytes(rows, 1, sizeof(std::int64_t), compressed);
  }
  return bytes;
}

} // namespace

struct ResultWriter::Impl {
  ParallelIo parallel;
  Handle transfer; ///< collective data transfer (parallel files)
  hid_t dxpl() const { return transfer.valid() ? transfer.get() : H5P_DEFAULT; }
  bool root() const { return parallel.root; }
  Handle file;
  Handle frames;
  Handle probes;
  Handle xdmf_group;
  std::map<std::string, Handle> groups; ///< groups of histories (probes, walls), created on first use
  std::string path;
  std::string xdmf_path;
  std::string h5_name; ///< the .h5 file name as the sidecar refers to it (same directory)
  std::string run_id;
  int dimension = 0;
  bool single = false;  ///< frames' particle datasets as 32-bit floats
  int deflate = 0;      ///< ResultOptions::compression
  int fd = -1;          ///< the file's descriptor (space reservations; a parallel file's on the root only)
  bool own_fd = false;  ///< fd was opened here (a parallel file, whose driver holds an MPI_File): closed at the end
  bool broken = false;  ///< an HDF5 write failed: the file is left alone from then on
  ~Impl() {
    if (own_fd) ::close(fd);
  }
  std::vector<FrameInfo> frame_infos;
  std::map<std::string, ProbeInfo> probe_infos; ///< by path: "probes/<name>" or a root series name
  std::set<long long> vertex_counts;                ///< the vertices_N datasets written
  std::unique_ptr<VtkSeriesWriter> vtk;

  /// Appends one sample to the histories of group `name` under `parent`
  /// (created with its datasets on the first sample; later samples must have
  /// the same fields). `scalars`: every field has one value and is stored as a
  /// rank-1 dataset, like `time`. `key` names the group in probe_infos.
  void append_sample(hid_t parent, const std::string& key, const std::string& name, double time,
                     const std::vector<std::pair<std::string, std::vector<double>>>& values, bool scalars,
                     const std::string& where);

  void write_xdmf() const;
  /// Writes field f (its rows of the frame) with `data` as dataset `name` of group g.
  /// In a single-precision file the values are rounded to float first.
  void write_field(hid_t g, const std::string& name, const FieldView& f, const double* data) const {
    std::vector<float> rounded;
    if (single) {
      rounded.resize(static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols));
      for (std::size_t i = 0; i < rounded.size(); ++i) rounded[i] = static_cast<float>(data[i]);
    }
    const auto write = [&](const auto* values) {
      if (!parallel.mpi_comm)
        return write_matrix(g, name, static_cast<hsize_t>(f.rows), static_cast<hsize_t>(f.cols), values, path,
                            deflate);
      const bool whole = f.total_rows < 0; // the root writes a whole frame alone
      const auto total = static_cast<hsize_t>(whole ? f.rows : f.total_rows);
      const auto rows = static_cast<hsize_t>(whole && !root() ? 0 : f.rows);
      h5::write_rows(g, name, total, static_cast<hsize_t>(f.cols), whole ? 0 : static_cast<hsize_t>(f.first_row),
                     rows, values, dxpl(), path, deflate);
    };
    if (single) write(rounded.data());
    else write(data);
    if (!f.components.empty()) {
      Handle set(checked(H5Dopen2(g, name.c_str(), H5P_DEFAULT), path, "open dataset " + name), H5Dclose);
      write_string_attribute(set.get(), "components", f.components, path);
    }
  }
  /// Rewrites the sidecar (and the .pvd) if `force` or if the last rewrite is
  /// older than kXdmfInterval: the sidecar is O(frames) long, so rewriting it
  /// for every frame would cost O(frames^2). It only ever names flushed frames.
  void publish_xdmf(bool force);
  std::chrono::steady_clock::time_point xdmf_written{};
  std::size_t xdmf_frames = 0;
  FrameInfo describe_frame(const std::string& group, double time, const std::vector<FieldView>& fields) const;
  /// Writes /xdmf/vertices_N unless it exists.
  void write_vertices(const FieldView& x, long long points);

  /// Size of the last sidecar written and the frames it named (its growth per frame).
  mutable std::uint64_t xdmf_bytes = 0, xdmf_bytes_frames = 0;

  /// Checks that `bytes` (plus kFinalReserve) fit beyond the end of the file
  /// before they are written (h5::check_room), and that the sidecars
  /// (written as a temporary beside the old one) and `beside` bytes of VTK
  /// frame fit too: OutputError when they do not. (The result file's space
  /// is not allocated ahead with fallocate: HDF5 truncates the file at every
  /// flush, and freeing preallocated blocks there widened the moment in which
  /// a killed run leaves a "truncated file" from microseconds to milliseconds.)
  /// A parallel file: the root checks (it holds the file's size and writes
  /// the sidecars) and every rank throws when it found no room (collective),
  /// so no rank starts a write the others do not make.
  void reserve(std::uint64_t bytes, std::uint64_t beside = 0) const {
    std::string refused;
    try {
      if (fd >= 0) {
        h5::check_room(fd, bytes + kFinalReserve, path);
        const std::uint64_t per_frame = xdmf_bytes_frames > 0 ? xdmf_bytes / xdmf_bytes_frames + 1 : kMetadataBytes;
        const std::uint64_t sidecar = kMetadataBytes + (frame_infos.size() + 2) * per_frame;
        h5::require_room(xdmf_path, 2 * sidecar * (vtk ? 2 : 1) + beside, std::max(sidecar, beside));
      }
    } catch (const OutputError& e) {
      if (!parallel.all) throw;
      refused = e.what();
    }
    if (parallel.all && !parallel.all(refused.empty()))
      throw OutputError(refused.empty() ? path + ": no room for the next write (found by rank 0)" : refused);
  }

  /// Renames the new file `created` over `path` once every rank has flushed
  /// its part of the header (the root renames; every rank learns whether it
  /// could): from then on `path` names a file that opens. OutputError when
  /// the rename fails.
  void publish_created(const std::string& created) {
    if (parallel.all) parallel.all(true);
    std::error_code ec;
    if (root()) std::filesystem::rename(created, path, ec);
    const bool renamed = !ec;
    if (parallel.all ? !parallel.all(renamed) : !renamed)
      throw OutputError(path + ": cannot rename the new result file " + created + " into place" +
                        (ec ? ": " + ec.message() : std::string(" (on rank 0)")));
  }

  /// Runs `write`, which writes to the HDF5 file. An HDF5 failure marks the
  /// file broken and becomes an OutputError (h5::output_failure); a broken
  /// file is not written again.
  template <class Write> void guarded(const std::string& what, Write&& write) {
    if (broken) throw OutputError(path + ": cannot " + what + ": an earlier write to the file failed");
    try {
      write();
    } catch (const h5::Failure& e) {
      broken = true;
      h5::output_failure(path, what + " (" + e.what() + ")");
    }
  }
};

ResultWriter::ResultWriter(const std::string& path, const std::string& scene_text, int dimension,
                           const ResultOptions& options, ParallelIo parallel)
    : impl_(std::make_unique<Impl>()), path_(path) {
  h5::silence();
  require(!path.empty(), "ResultWriter: the result file path is empty");
  require<std::invalid_argument>(dimension >= 1 && dimension <= kXdmfSpaceDim, path,
                                 ": ResultWriter: dimension must be 1, 2 or 3, got ", dimension);
  const OutputFiles files = output_files(path, "", options.vtk_format);
  check_distinct(files); // the sidecar is never the result file, even through a link
  Impl& m = *impl_;
  m.parallel = std::move(parallel);
  m.path = path;
  m.dimension = dimension;
  m.single = options.single_precision;
  require<std::invalid_argument>(options.compression >= 0 && options.compression <= h5::kMaxDeflate, path,
                                 ": ResultWriter: compression must be 0..9, got ", options.compression);
  if (options.compression > 0 && !h5::deflate_available())
    throw InputError(path + ": output.compression = " + std::to_string(options.compression) +
                     " needs HDF5's deflate (gzip) filter, which this HDF5 library does not provide; use 0");
  m.deflate = options.compression;
  m.run_id = options.run_id.empty() ? new_run_id() : options.run_id;
  m.xdmf_path = files.xdmf;
  m.h5_name = std::filesystem::path(path).filename().string();
  // Created as PATH.tmp and renamed over PATH once its root attributes are
  // on disk: a process killed while the ranks create it together leaves no
  // result file that does not open, and a reader holding the old one open
  // (ParaView, h5py) keeps reading it and does not block the run. A link at
  // PATH is replaced, not written through.
  const std::string created = path + ".tmp";
  std::error_code ec;
  if (m.root()) std::filesystem::remove(created, ec); // a killed run's (the run holds PATH's lock)
  if (m.parallel.all) m.parallel.all(true); // the other ranks create the file after the root removed the old one
  // The 1.8 file format: readable by every current HDF5 and allows attributes
  // above 64 KiB (a long scene text) in dense storage.
  Handle fapl(checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  if (m.parallel.mpi_comm) m.transfer = h5::parallel_access(fapl.get(), m.parallel.mpi_comm, path);
  else h5::use_undo_journal(fapl.get(), undo_journal_path(path), path); // a kill inside a flush is undone
  const hid_t file = H5Fcreate(created.c_str(), H5F_ACC_EXCL, H5P_DEFAULT, fapl.get());
  if (file < 0) {
    const std::string cause = h5::system_error();
    throw InputError(path + ": cannot create the result file" + (cause.empty() ? "" : ": " + cause));
  }
  m.file = Handle(file, H5Fclose);
  struct Unpublished { // removes the new file when the constructor ends before its rename
    std::string path;
    bool root;
    ~Unpublished() {
      std::error_code ignored;
      if (root && !path.empty()) std::filesystem::remove(path, ignored);
    }
  } unpublished{created, m.root()};
  // A parallel file's driver handle is an MPI_File, not a descriptor: the
  // root opens the file once more to check the room for each write.
  if (!m.parallel.mpi_comm) m.fd = h5::file_descriptor(file, path);
  else if (m.root()) m.own_fd = (m.fd = ::open(created.c_str(), O_RDONLY | O_CLOEXEC)) >= 0;
  m.reserve(scene_text.size() + 8 * kMetadataBytes);
  m.guarded("write the root attributes", [&] {
    m.frames = h5::create_group(file, "frames", path);
    m.probes = h5::create_group(file, "probes", path);
    m.xdmf_group = h5::create_group(file, kXdmfGroup, path);
    write_string_attribute(file, "otmpm_version", OTMPM_VERSION, path);
    write_string_attribute(file, "run_id", m.run_id, path);
    write_string_attribute(file, "scene", scene_text, path);
    write_string_attribute(file, "status", "running", path);
  });
  set_attribute("dimension", static_cast<long long>(dimension));
  flush();
  m.publish_created(created);
  unpublished.path.clear();
  if (!options.vtk_format.empty()) { // a distributed run: on every rank, each writes its pieces
    m.vtk = std::make_unique<VtkSeriesWriter>(files.pvd, files.vtk_dir, files.vtk_extension, dimension, m.run_id,
                                              m.h5_name, m.single, m.parallel);
    if (m.parallel.all) m.parallel.all(true); // the root made the directory before any rank writes there
  }
  if (m.root()) m.write_xdmf();
  if (m.vtk) m.vtk->publish();
}

ResultWriter::~ResultWriter() {
  if (!impl_) return;
  if (impl_->broken) {
    // HDF5 could not write the file: closing it would only fail again.
    for (Handle* h : {&impl_->xdmf_group, &impl_->probes, &impl_->frames, &impl_->file}) h->release();
    return;
  }
  try {
    if (impl_->file.valid()) H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL);
    impl_->publish_xdmf(true);
  } catch (...) { // a destructor must not throw; the .h5 file is complete anyway
  }
}

const std::string& ResultWriter::run_id() const { return impl_->run_id; }

const ParallelIo& ResultWriter::parallel() const { return impl_->parallel; }

bool ResultWriter::writable() const { return !impl_->broken; }

void ResultWriter::Impl::publish_xdmf(bool force) {
  const auto now = std::chrono::steady_clock::now();
  if (!root() || (!force && now - xdmf_written < kXdmfInterval)) return;
  if (force && xdmf_frames == frame_infos.size() && (!vtk || xdmf_frames == vtk->frames())) return;
  write_xdmf();
  if (vtk) vtk->publish();
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
  info.points = total(*x);
  info.geometry = x->cols == 1 ? kPaddedX : "x";
  info.geometry_cols = x->cols == 1 ? kXdmfSpaceDim : x->cols;
  info.precision = single ? 4 : 8;
  for (const FieldView& f : fields)
    if (f.name != "x" && total(f) == total(*x)) info.attributes.emplace_back(f.name, f.cols, !f.components.empty());
  return info;
}

void ResultWriter::Impl::write_vertices(const FieldView& x, long long points) {
  if (!vertex_counts.insert(points).second) return;
  // this rank's rows of the frame (a serial file, or the root writing a whole frame: all of them)
  const bool block = parallel.mpi_comm && x.total_rows >= 0;
  const long long first = block ? x.first_row : 0;
  const long long rows = block ? x.rows : parallel.mpi_comm && !root() ? 0 : points;
  std::vector<std::int64_t> ids(static_cast<std::size_t>(std::max(rows, 1LL))); // never a null buffer
  std::iota(ids.begin(), ids.end(), std::int64_t{first});
  const hsize_t dims[1] = {static_cast<hsize_t>(points)};
  const std::string name = vertices_name(points);
  Handle space(checked(H5Screate_simple(1, dims, nullptr), path, "write " + name), H5Sclose);
  const Handle layout = h5::dataset_creation(dims[0], 1, sizeof(std::int64_t), deflate, path, 1); // as the frames
  Handle set(checked(H5Dcreate2(xdmf_group.get(), name.c_str(), H5T_STD_I64LE, space.get(), H5P_DEFAULT,
                                layout.valid() ? layout.get() : H5P_DEFAULT, H5P_DEFAULT),
                     path, "write " + name),
             H5Dclose);
  if (points == 0) return;
  if (!parallel.mpi_comm)
    return checked_status(H5Dwrite(set.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, ids.data()), path,
                          "write " + name);
  // Every rank takes part in the collective write, each with its rows.
  Handle file_space(checked(H5Dget_space(set.get()), path, "write " + name), H5Sclose);
  const hsize_t count[1] = {static_cast<hsize_t>(std::max(rows, 1LL))};
  Handle mem_space(checked(H5Screate_simple(1, count, nullptr), path, "write " + name), H5Sclose);
  if (rows == 0) {
    checked_status(H5Sselect_none(file_space.get()), path, "write " + name);
    checked_status(H5Sselect_none(mem_space.get()), path, "write " + name);
  } else {
    const hsize_t start[1] = {static_cast<hsize_t>(first)};
    checked_status(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), path,
                   "write " + name);
  }
  checked_status(H5Dwrite(set.get(), H5T_NATIVE_INT64, mem_space.get(), file_space.get(), dxpl(), ids.data()), path,
                 "write " + name);
}

void ResultWriter::check_field(const FieldView& f, double time, std::set<std::string>& seen) const {
  check_name(f.name, "field");
  if (f.name == kPaddedX) throw std::invalid_argument(path_ + ": field name 'x3' is reserved for the XDMF geometry");
  if (!seen.insert(f.name).second)
    throw std::invalid_argument(path_ + ": field '" + f.name + "' given twice in one frame");
  check_field_shape(f, impl_->dimension, path_);
  const std::string where = path_ + ": frame at t = " + format_number(time) + ", field '" + f.name + "'";
  check_finite(f.data, static_cast<std::size_t>(f.rows) * f.cols, where);
  if (impl_->single) check_float_range(f.data, static_cast<std::size_t>(f.rows) * f.cols, where);
}

void ResultWriter::check_frame(double time, const std::vector<FieldView>& fields) const {
  std::set<std::string> seen;
  for (const FieldView& f : fields) check_field(f, time, seen);
  if (!std::isfinite(time)) throw InstabilityError(path_ + ": frame time is not finite");
}

void ResultWriter::write_frame(double time, const std::vector<FieldView>& fields) {
  Impl& m = *impl_;
  const std::string name = frame_name(frames_);
  std::set<std::string> seen;
  std::string bad; // the first non-finite entry of this rank's rows
  for (const FieldView& f : fields) {
    try {
      check_field(f, time, seen);
    } catch (const InstabilityError& e) {
      if (!m.parallel.mpi_comm) throw;
      if (bad.empty()) bad = e.what();
    }
  }
  if (m.parallel.all && !m.parallel.all(bad.empty()))
    throw InstabilityError(bad.empty() ? path_ + ": frame at t = " + format_number(time) +
                                             ": a field is not finite on another rank; it is not written to the result file"
                                       : bad);
  if (!std::isfinite(time)) throw InstabilityError(path_ + ": frame time is not finite");
  const std::uint64_t bytes = frame_bytes(fields, m.dimension, m.single ? sizeof(float) : sizeof(double), m.deflate > 0);
  m.reserve(bytes, m.vtk ? bytes : 0);
  FrameInfo info = m.describe_frame("/frames/" + name, time, fields);
  m.guarded("write frame " + name, [&] {
    Handle g = h5::create_group(m.frames.get(), name, path_);
    write_attribute(g.get(), "time", H5T_NATIVE_DOUBLE, &time, path_);
    for (const FieldView& f : fields) m.write_field(g.get(), f.name, f, f.data);
    if (info.geometry == kPaddedX) {
      const auto& x = *std::find_if(fields.begin(), fields.end(), [](const FieldView& f) { return f.name == "x"; });
      std::vector<double> padded(static_cast<std::size_t>(x.rows) * kXdmfSpaceDim, 0.0);
      for (int p = 0; p < x.rows; ++p) padded[static_cast<std::size_t>(p) * kXdmfSpaceDim] = x.data[p];
      FieldView x3 = x;
      x3.cols = kXdmfSpaceDim;
      m.write_field(g.get(), kPaddedX, x3, padded.data());
    }
    if (!info.geometry.empty())
      m.write_vertices(*std::find_if(fields.begin(), fields.end(), [](const FieldView& f) { return f.name == "x"; }),
                       info.points);
  });
  ++frames_;
  flush();
  if (!info.geometry.empty()) {
    if (m.vtk) m.vtk->write_frame(frames_ - 1, time, fields);
    m.frame_infos.push_back(std::move(info));
  }
  m.publish_xdmf(false);
}

void ResultWriter::Impl::append_sample(hid_t parent, const std::string& key, const std::string& name, double time,
                                       const std::vector<std::pair<std::string, std::vector<double>>>& values,
                                       bool scalars, const std::string& where) {
  check_finite(&time, 1, where + ", time");
  std::uint64_t bytes = kMetadataBytes;
  for (const auto& [field, v] : values) {
    check_name(field, "history field");
    if (field == "time") throw std::invalid_argument(where + ": a history field may not be called 'time'");
    if (scalars && v.size() != 1) throw std::invalid_argument(where + ": field '" + field + "' is not a scalar");
    check_finite(v.data(), v.size(), where + ", field '" + field + "'");
    bytes += kProbeChunkRows * v.size() * sizeof(double) + kMetadataBytes; // at most a new chunk
  }
  auto it = probe_infos.find(key);
  if (it != probe_infos.end()) {
    const ProbeInfo& info = it->second;
    if (values.size() != info.fields.size())
      throw std::invalid_argument(where + ": the fields differ from the first sample");
    for (std::size_t i = 0; i < values.size(); ++i)
      if (values[i].first != info.fields[i].first ||
          std::max<hsize_t>(info.fields[i].second, 1) != values[i].second.size())
        throw std::invalid_argument(where + ": field '" + values[i].first + "' differs from the first sample");
  } else {
    for (const auto& [field, v] : values)
      if (v.empty()) throw std::invalid_argument(where + ": field '" + field + "' has no components");
  }
  reserve(bytes + kProbeChunkRows * sizeof(double));
  guarded("append to " + key, [&] {
    if (it == probe_infos.end()) {
      Handle g = h5::create_group(parent, name, path);
      ProbeInfo info;
      create_history(g.get(), "time", 0, path);
      for (const auto& [field, v] : values) {
        const hsize_t cols = scalars ? 0 : v.size();
        create_history(g.get(), field, cols, path);
        info.fields.emplace_back(field, cols);
      }
      it = probe_infos.emplace(key, std::move(info)).first;
    }
    ProbeInfo& info = it->second;
    Handle g(checked(H5Gopen2(parent, name.c_str(), H5P_DEFAULT), path, "open " + key), H5Gclose);
    const bool writes = root(); // in a parallel file the root writes the row, the others select none
    append_row(g.get(), "time", info.samples, 0, &time, path, writes, dxpl());
    for (std::size_t i = 0; i < values.size(); ++i)
      append_row(g.get(), values[i].first, info.samples, info.fields[i].second, values[i].second.data(), path, writes,
                 dxpl());
    ++info.samples;
  });
}

void ResultWriter::append_probe(const std::string& probe, double time,
                                const std::vector<std::pair<std::string, std::vector<double>>>& values) {
  append_group_sample("probes", probe, time, values);
}

void ResultWriter::append_group_sample(const std::string& group, const std::string& name, double time,
                                       const std::vector<std::pair<std::string, std::vector<double>>>& values) {
  check_name(group, "history group");
  check_name(name, "history");
  if (group == "frames" || group == kXdmfGroup)
    throw std::invalid_argument(path_ + ": group name '" + group + "' is reserved");
  Impl& m = *impl_;
  auto it = m.groups.find(group);
  if (it == m.groups.end()) {
    Handle g = group == "probes" ? std::move(m.probes) : h5::create_group(m.file.get(), group, path_);
    it = m.groups.emplace(group, std::move(g)).first;
  }
  m.append_sample(it->second.get(), group + "/" + name, name, time, values, false,
                  path_ + ": " + group + " '" + name + "' at t = " + format_number(time));
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
  if (series == "frames" || series == "probes" || series == kXdmfGroup)
    throw std::invalid_argument(path_ + ": series name '" + series + "' is reserved");
  std::vector<std::pair<std::string, std::vector<double>>> rows;
  for (const auto& [field, v] : values) rows.emplace_back(field, std::vector<double>{v});
  impl_->append_sample(impl_->file.get(), series, series, time, rows, true,
                       path_ + ": series '" + series + "' at t = " + format_number(time));
  flush_sample();
}

void ResultWriter::set_attribute(const std::string& name, double value) {
  check_name(name, "attribute");
  impl_->guarded("write attribute " + name,
                 [&] { write_attribute(impl_->file.get(), name, H5T_NATIVE_DOUBLE, &value, path_); });
}
void ResultWriter::set_attribute(const std::string& name, long long value) {
  check_name(name, "attribute");
  impl_->guarded("write attribute " + name,
                 [&] { write_attribute(impl_->file.get(), name, H5T_NATIVE_LLONG, &value, path_); });
}
void ResultWriter::set_attribute(const std::string& name, const std::string& value) {
  check_name(name, "attribute");
  impl_->guarded("write attribute " + name,
                 [&] { write_string_attribute(impl_->file.get(), name, value, path_); });
}

void ResultWriter::flush() {
  impl_->guarded("flush the file",
                 [&] { checked_status(H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL), path_, "flush the file"); });
}

void ResultWriter::publish() {
  flush();
  impl_->publish_xdmf(true);
}

/// Writes the sidecar: a temporal collection of Polyvertex grids (one vertex
/// cell per particle, with explicit connectivity: ParaView's Xdmf3 readers
/// show no cells without it) whose geometry and attributes point into the .h5
/// datasets. Written to a temporary file and renamed into place, so readers
/// never see half a file.
void ResultWriter::Impl::write_xdmf() const {
  std::ostringstream os;
  os << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
     << "    <Information Name=\"otmpm_run_id\" Value=\"" << xml_escape(run_id) << "\"/>\n"
     << "    <Information Name=\"otmpm_result\" Value=\"" << xml_escape(h5_name) << "\"/>\n"
     << "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const std::string h5 = xml_escape(h5_name);
  auto data_item = [&](const std::string& dataset, const std::string& dims, const char* type, int precision) {
    return "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + type + "\" Precision=\"" +
           std::to_string(precision) + "\" Format=\"HDF\">" + h5 + ":" + xml_escape(dataset) + "</DataItem>";
  };
  auto matrix = [](long long rows, int cols) { return std::to_string(rows) + " " + std::to_string(cols); };
  for (const FrameInfo& f : frame_infos) {
    os << "      <Grid Name=\"frame " << f.group.substr(f.group.rfind('/') + 1) << "\" GridType=\"Uniform\">\n"
       << "        <Time Value=\"" << text::exact(f.time) << "\"/>\n"
       << "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << f.points
       << "\" NodesPerElement=\"1\">\n          "
       << data_item(std::string("/") + kXdmfGroup + "/" + vertices_name(f.points), std::to_string(f.points), "Int", 8)
       << "\n        </Topology>\n"
       << "        <Geometry GeometryType=\"" << (f.geometry_cols == 2 ? "XY" : "XYZ") << "\">\n          "
       << data_item(f.group + "/" + f.geometry, matrix(f.points, f.geometry_cols), "Float", f.precision) << "\n        </Geometry>\n";
    for (const auto& [name, cols, symmetric] : f.attributes)
      os << "        <Attribute Name=\"" << xml_escape(name) << "\" AttributeType=\""
         << xdmf_attribute_type(cols, dimension, symmetric) << "\" Center=\"Node\">\n          "
         << data_item(f.group + "/" + name, matrix(f.points, cols), "Float", f.precision) << "\n        </Attribute>\n";
    os << "      </Grid>\n";
  }
  os << "    </Grid>\n  </Domain>\n</Xdmf>\n";
  const std::string content = os.str();
  text::replace_file(xdmf_path, content, "XDMF sidecar");
  xdmf_bytes = content.size();
  xdmf_bytes_frames = frame_infos.size();
}

// ---------------------------------------------------------------- copying

namespace {

/// One history read from a result file: its layout, time and each field.
struct StoredHistory {
  HistoryLayout layout;
  h5::Matrix<double> time;
  std::vector<h5::Matrix<double>> fields;
};

/// Fails unless the first `rows` rows of `m` (dataset `name`) are finite:
/// otmpm never writes a value that is not (ResultWriter refuses it), so one
/// is damage to the file (HDF5 keeps no checksum of raw data).
void check_finite(const h5::Matrix<double>& m, hsize_t rows, const std::string& name, const std::string& path) {
  const std::size_t n = static_cast<std::size_t>(std::min(rows, m.rows) * m.cols);
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(m.values[i]))
      h5::fail(path, "copy dataset " + name + ": row " + std::to_string(i / m.cols) +
                         " is not finite, which otmpm never writes (the file is damaged)");
}

/// A column of `samples` zeros (a series an older file lacks).
h5::Matrix<double> zero_column(int samples) {
  return {static_cast<hsize_t>(samples), 1, std::vector<double>(static_cast<std::size_t>(samples), 0.0)};
}

/// Reads what copy_results needs of a history, checking it has `samples`
/// rows of finite values and increasing times; the columns of
/// `layout.zero_if_absent` the file lacks are zeros.
StoredHistory read_history(hid_t file, const HistoryLayout& layout, int samples, const std::string& path) {
  StoredHistory h;
  h.layout = layout;
  Handle g = h5::open_group(file, (layout.probe ? layout.group + "/" : "") + layout.name, path);
  h.time = h5::read_double_matrix(g.get(), "time", path);
  for (const std::string& f : layout.fields) {
    const bool absent = std::count(layout.zero_if_absent.begin(), layout.zero_if_absent.end(), f) > 0 &&
                        !h5::has_link(g.get(), f);
    h.fields.push_back(absent ? zero_column(samples) : h5::read_double_matrix(g.get(), f, path));
  }
  bool complete = h.time.rows >= static_cast<hsize_t>(samples);
  for (const auto& m : h.fields) complete = complete && m.rows >= static_cast<hsize_t>(samples);
  if (!complete) h5::fail(path, "find " + std::to_string(samples) + " samples of history '" + layout.name + "'");
  const std::string where = (layout.probe ? layout.group + "/" : "") + layout.name;
  for (std::size_t i = 0; i < h.fields.size(); ++i)
    check_finite(h.fields[i], static_cast<hsize_t>(samples), where + "/" + layout.fields[i], path);
  check_finite(h.time, static_cast<hsize_t>(samples), where + "/time", path);
  for (std::size_t i = 1; i < static_cast<std::size_t>(samples); ++i)
    if (h.time.values[i] < h.time.values[i - 1]) // equal times: Simulation::write_frame() at a recorded time
      h5::fail(path, "copy dataset " + where + "/time: its times decrease at row " + std::to_string(i) +
                         " (the file is damaged)");
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

/// Frame `index` of a result file: its time and the datasets `fields` (a
/// parallel file: this rank's block of rows, from `first` of `total`).
struct StoredFrame {
  double time = 0;
  std::vector<h5::Matrix<double>> fields;
  std::vector<std::string> components; ///< each field's attribute `components` ("" when absent)
  long long first = 0, total = -1;     ///< total -1: the whole frame
};

/// The string attribute `components` of dataset `name` below `g`, or "".
std::string stored_components(hid_t g, const std::string& name, const std::string& path) {
  Handle set(checked(H5Dopen2(g, name.c_str(), H5P_DEFAULT), path, "open dataset " + name), H5Dclose);
  return h5::has_attribute(set.get(), "components") ? h5::read_string(set.get(), "components", path) : "";
}

/// Rows [total r / P, total (r + 1) / P) of a dataset of `total` rows for rank r of P.
h5::Matrix<double> read_block(hid_t g, const std::string& name, const ParallelIo& io, long long& first, long long& total,
                              const std::string& path) {
  const h5::DoubleRows rows(g, name, path);
  total = static_cast<long long>(rows.rows());
  first = total * io.rank / io.size;
  h5::Matrix<double> m;
  m.cols = rows.cols();
  m.rows = static_cast<hsize_t>(total * (io.rank + 1) / io.size - first);
  m.values.resize(static_cast<std::size_t>(m.rows * m.cols));
  rows.read(static_cast<hsize_t>(first), m.rows, m.values.data());
  return m;
}

StoredFrame read_frame(hid_t file, int index, const std::vector<std::string>& fields, const ParallelIo& io,
                       const std::string& path) {
  Handle g = h5::open_group(file, "frames/" + frame_name(index), path);
  StoredFrame f;
  f.time = h5::read_double(g.get(), "time", path);
  if (!std::isfinite(f.time))
    h5::fail(path, "copy frame " + frame_name(index) + ": its time is not finite (the file is damaged)");
  for (const std::string& name : fields) {
    f.fields.push_back(io.size > 1 ? read_block(g.get(), name, io, f.first, f.total, path)
                                   : h5::read_double_matrix(g.get(), name, path));
    f.components.push_back(stored_components(g.get(), name, path));
    check_finite(f.fields.back(), f.fields.back().rows, "frames/" + frame_name(index) + "/" + name, path);
  }
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
  const hid_t id = h5::open_result_read_only(from);
  if (id < 0) throw InputError(from + ": cannot open the result file of the interrupted run");
  const Handle file(id, H5Fclose);
  std::vector<StoredHistory> stored;
  for (const HistoryLayout& layout : histories)
    stored.push_back(reading(from, [&] { return read_history(file.get(), layout, frames, from); }));
  for (int i = 0; i < frames; ++i) {
    for (const StoredHistory& h : stored) append_stored_sample(h, static_cast<hsize_t>(i), to);
    const StoredFrame frame = reading(from, [&] { return read_frame(file.get(), i, frame_fields, to.parallel(), from); });
    // A run writes each history's sample and the frame at the same output time.
    for (const StoredHistory& h : stored)
      if (h.time.values[static_cast<std::size_t>(i)] != frame.time)
        throw InputError(from + ": cannot copy the results of the interrupted run: frame " + frame_name(i) +
                         " has time " + text::exact(frame.time) + " but history '" + h.layout.name + "' " +
                         text::exact(h.time.values[static_cast<std::size_t>(i)]) + " (the file is damaged)");
    std::vector<FieldView> views;
    for (std::size_t k = 0; k < frame_fields.size(); ++k)
      views.push_back({frame_fields[k], static_cast<int>(frame.fields[k].rows),
                       static_cast<int>(frame.fields[k].cols), frame.fields[k].values.data(), frame.total, frame.first,
                       frame.components[k]});
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
  const hid_t file = h5::open_result_read_only(path);
  if (file < 0) throw InputError(path + ": cannot open the result file");
  Handle f(file, H5Fclose);
  if (!h5::has_attribute(file, name)) throw InputError(path + ": no root attribute '" + name + "'");
  const H5T_class_t c = h5::attribute_class(file, name, path);
  if (c != cls && c != alt) throw InputError(path + ": attribute '" + name + "' is not " + kind);
  return f;
}

} // namespace

// An HDF5 failure on a file it opened (a damaged file) is an InputError
// naming the file, as the refusals of open_with_attribute are.
std::string read_string_attribute(const std::string& path, const std::string& name) {
  try {
    const Handle file = open_with_attribute(path, name, H5T_STRING, H5T_STRING, "a string");
    return h5::read_string(file.get(), name, path);
  } catch (const h5::Failure& e) {
    throw InputError(e.what());
  }
}

double read_double_attribute(const std::string& path, const std::string& name) {
  try {
    const Handle file = open_with_attribute(path, name, H5T_FLOAT, H5T_INTEGER, "a number");
    return h5::read_double(file.get(), name, path);
  } catch (const h5::Failure& e) {
    throw InputError(e.what());
  }
}

} // namespace otmpm
