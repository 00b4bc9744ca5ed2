// HDF5 C API helpers shared by the result and checkpoint files (see hdf5.hpp).
#include "otmpm/io/hdf5.hpp"

#include "otmpm/core.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace otmpm::h5 {

namespace {

/// Set once HDF5 failed to write a file (see hdf5.hpp).
std::atomic<bool> write_failure{false};

/// The library's replacement of HDF5's own exit handler: H5close() unless a
/// write failed, after which HDF5 1.10 crashes closing the damaged file.
void close_library_at_exit() {
  if (!write_failure.load()) H5close();
}

/// Installs close_library_at_exit() when libotmpm is loaded. H5dont_atexit()
/// only takes effect before HDF5 initialises itself; if something already
/// did, HDF5 keeps its own handler and nothing changes.
[[maybe_unused]] const bool exit_handler_installed = [] {
  if (H5dont_atexit() < 0) return false;
  return std::atexit(close_library_at_exit) == 0;
}();

/// H5Ewalk2 callback: keeps the text after "error message = '" of the
/// innermost error that has one (the system error of a failed read or write).
herr_t find_system_error(unsigned, const H5E_error2_t* error, void* out) {
  const std::string desc = error && error->desc ? error->desc : "";
  const std::string key = "error message = '";
  const auto at = desc.find(key);
  if (at != std::string::npos) {
    const auto start = at + key.size();
    *static_cast<std::string*>(out) = desc.substr(start, desc.find('\'', start) - start);
  }
  return 0;
}

} // namespace

void silence() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

std::string system_error() {
  std::string text;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, find_system_error, &text);
  return text;
}

void note_write_failure() { write_failure.store(true); }

bool write_failed() { return write_failure.load(); }

void output_failure(const std::string& path, const std::string& what) {
  const std::string cause = system_error();
  note_write_failure();
  throw OutputError(path + ": cannot " + what + ": " + (cause.empty() ? "HDF5 reported a write error" : cause) +
                    " (the disk may be full or a file size limit reached)");
}

int file_descriptor(hid_t file, const std::string& path) {
  void* handle = nullptr;
  checked_status(H5Fget_vfd_handle(file, H5P_DEFAULT, &handle), path, "find the file descriptor");
  if (!handle) fail(path, "find the file descriptor");
  return *static_cast<int*>(handle);
}

namespace {

/// OutputError for a reservation that failed: the file, its size, the request and the cause.
[[noreturn]] void no_room(const std::string& path, std::uint64_t size, std::uint64_t bytes, const std::string& cause) {
  throw OutputError(path + ": " + cause + ": the next output needs about " + std::to_string(bytes) + " bytes" +
                    (size > 0 ? " beyond the file's " + std::to_string(size) : std::string()) +
                    "; the files keep everything written before");
}

/// Bytes free for this process on the file system of `vfs`.
std::uint64_t available(const struct statvfs& vfs) { return static_cast<std::uint64_t>(vfs.f_bavail) * vfs.f_frsize; }

/// The statvfs fallback of reserve_space for file systems without fallocate.
void check_free_space(int fd, std::uint64_t size, std::uint64_t bytes, const std::string& path) {
  struct statvfs vfs {};
  if (::fstatvfs(fd, &vfs) != 0) return; // nothing known: let the write report it
  if (available(vfs) < bytes)
    no_room(path, size, bytes, "only " + std::to_string(available(vfs)) + " bytes are free on its file system");
}

/// no_room when a file of `size` + `bytes` bytes would exceed RLIMIT_FSIZE.
void check_file_size_limit(std::uint64_t size, std::uint64_t bytes, const std::string& path) {
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      size + bytes > static_cast<std::uint64_t>(limit.rlim_cur))
    no_room(path, size, bytes,
            "the file size limit of this process (RLIMIT_FSIZE, ulimit -f) is " + std::to_string(limit.rlim_cur) +
                " bytes");
}

} // namespace

void require_room(const std::string& path, std::uint64_t bytes, std::uint64_t largest) {
  check_file_size_limit(0, largest, path);
  std::string dir = path.substr(0, path.rfind('/') == std::string::npos ? 0 : path.rfind('/') + 1);
  if (dir.empty()) dir = ".";
  struct statvfs vfs {};
  if (::statvfs(dir.c_str(), &vfs) == 0 && available(vfs) < bytes)
    no_room(path, 0, bytes, "only " + std::to_string(available(vfs)) + " bytes are free on its file system");
}

void check_room(int fd, std::uint64_t bytes, const std::string& path) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return;
  const auto size = static_cast<std::uint64_t>(st.st_size);
  check_file_size_limit(size, bytes, path);
  check_free_space(fd, size, bytes, path);
}

void reserve_space(int fd, std::uint64_t bytes, const std::string& path) {
  check_room(fd, bytes, path);
  struct stat st {};
  if (::fstat(fd, &st) != 0) return;
  if (::fallocate(fd, FALLOC_FL_KEEP_SIZE, st.st_size, static_cast<off_t>(bytes)) == 0) return;
  const int err = errno;
  if (err == ENOSPC || err == EDQUOT || err == EFBIG)
    no_room(path, static_cast<std::uint64_t>(st.st_size), bytes, std::strerror(err));
  // EOPNOTSUPP, ENOSYS, EINVAL: no fallocate on this file system; check_room was all we could do.
}

void fail(const std::string& path, const std::string& what) {
  throw Failure(path + ": HDF5 could not " + what);
}

hid_t checked(hid_t id, const std::string& path, const std::string& what) {
  if (id < 0) fail(path, what);
  return id;
}

void checked_status(herr_t status, const std::string& path, const std::string& what) {
  if (status < 0) fail(path, what);
}

Handle create_group(hid_t parent, const std::string& name, const std::string& path) {
  return Handle(checked(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                        "create group " + name),
                H5Gclose);
}

Handle open_group(hid_t parent, const std::string& name, const std::string& path) {
  return Handle(checked(H5Gopen2(parent, name.c_str(), H5P_DEFAULT), path, "open group " + name), H5Gclose);
}

bool has_link(hid_t parent, const std::string& name) { return H5Lexists(parent, name.c_str(), H5P_DEFAULT) > 0; }

namespace {
/// Iteration callback of H5Literate / H5Aiterate2: appends the name to a vector.
template <class Info> herr_t collect_name(hid_t, const char* name, const Info*, void* out) {
  static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}

/// The names an HDF5 iteration visits, sorted: `iterate(H5_INDEX_NAME,
/// H5_ITER_NATIVE, &index, callback, data)` is H5Literate or H5Aiterate2
/// bound to an object. The native order walks the name index (a B-tree)
/// directly; an iteration in increasing order first builds a table of the
/// stored count of entries and sorts it, and HDF5 crashes (SIGSEGV in the
/// sort) when that count is larger than the entries the index holds - the
/// dense link table a killed writer left half-written. `stored`: that count,
/// checked against the names found (Failure "damaged" when they differ).
template <class Info, class Iterate>
std::vector<std::string> iterated_names(Iterate&& iterate, hsize_t stored, const std::string& path,
                                        const std::string& what) {
  std::vector<std::string> names;
  hsize_t index = 0;
  checked_status(iterate(H5_INDEX_NAME, H5_ITER_NATIVE, &index, collect_name<Info>, &names), path, what);
  std::sort(names.begin(), names.end()); // byte order, as HDF5's name order (strcmp)
  if (names.size() != stored)
    fail(path, what + ": it records " + std::to_string(stored) + " entries but its index holds " +
                   std::to_string(names.size()) + " (a damaged file, e.g. left by a killed writer)");
  return names;
}

/// The object's path in its file ("/frames"), "?" when HDF5 has none.
std::string object_path(hid_t object) {
  const ssize_t n = H5Iget_name(object, nullptr, 0);
  if (n <= 0) return "?";
  std::string name(static_cast<std::size_t>(n) + 1, '\0');
  H5Iget_name(object, name.data(), name.size());
  name.resize(static_cast<std::size_t>(n));
  return name;
}
} // namespace

std::vector<std::string> link_names(hid_t group, const std::string& path) {
  const auto iterate = [group](auto... args) { return H5Literate(group, args...); };
  return iterated_names<H5L_info_t>(iterate, link_count(group, path), path, "list group " + object_path(group));
}

std::size_t link_count(hid_t group, const std::string& path) {
  H5G_info_t info;
  checked_status(H5Gget_info(group, &info), path, "count the links of a group");
  return static_cast<std::size_t>(info.nlinks);
}

Handle string_type(std::size_t length, const std::string& path) {
  Handle t(checked(H5Tcopy(H5T_C_S1), path, "copy the string type"), H5Tclose);
  checked_status(H5Tset_size(t.get(), length + 1), path, "size a string type");
  checked_status(H5Tset_strpad(t.get(), H5T_STR_NULLTERM), path, "pad a string type");
  checked_status(H5Tset_cset(t.get(), H5T_CSET_UTF8), path, "set a string character set");
  return t;
}

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

void write_string_attribute(hid_t object, const std::string& name, const std::string& value,
                            const std::string& path) {
  Handle t = string_type(value.size(), path);
  write_attribute(object, name, t.get(), value.c_str(), path);
}

bool deflate_available() {
  if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0 || H5Zfilter_avail(H5Z_FILTER_SHUFFLE) <= 0) return false;
  unsigned int config = 0;
  if (H5Zget_filter_info(H5Z_FILTER_DEFLATE, &config) < 0) return false;
  return (config & H5Z_FILTER_CONFIG_ENCODE_ENABLED) != 0;
}

hsize_t chunk_rows(hsize_t rows, hsize_t cols, std::size_t value_bytes) {
  const hsize_t row_bytes = std::max<hsize_t>(cols * value_bytes, 1);
  const hsize_t most = std::max<hsize_t>(kMaxChunkBytes / row_bytes, 1); // rows in the largest chunk
  if (rows <= most) return std::max<hsize_t>(rows, 1);
  const hsize_t chunks = (rows + most - 1) / most;
  return (rows + chunks - 1) / chunks;
}

Handle dataset_creation(hsize_t rows, hsize_t cols, std::size_t value_bytes, int deflate, const std::string& path,
                        int rank) {
  if (deflate <= 0 || rows * cols == 0) return Handle();
  if (deflate > kMaxDeflate) fail(path, "compress at deflate level " + std::to_string(deflate) + " (at most 9)");
  if (!deflate_available()) fail(path, "compress: this HDF5 has no deflate (gzip) encoder");
  const std::string what = "set up a compressed dataset";
  Handle plist(checked(H5Pcreate(H5P_DATASET_CREATE), path, what), H5Pclose);
  const hsize_t chunk[2] = {chunk_rows(rows, cols, value_bytes), cols};
  checked_status(H5Pset_chunk(plist.get(), rank == 1 ? 1 : 2, chunk), path, what);
  checked_status(H5Pset_shuffle(plist.get()), path, what);
  checked_status(H5Pset_deflate(plist.get(), static_cast<unsigned>(deflate)), path, what);
  // Every value is written: no fill values (the parallel HDF5 allocates the
  // chunks when it creates the dataset and would otherwise write them).
  checked_status(H5Pset_fill_time(plist.get(), H5D_FILL_TIME_NEVER), path, what);
  return plist;
}

namespace {
/// The creation list of `layout`, or H5P_DEFAULT when it is not set.
hid_t creation(const Handle& layout) { return layout.valid() ? layout.get() : H5P_DEFAULT; }

/// Writes a rows x cols dataset stored as `file_type` from memory of type
/// `memory_type` (contiguous, or compressed when `deflate` > 0).
void write_dataset(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, hid_t file_type,
                   hid_t memory_type, const void* data, const std::string& path, int deflate) {
  const std::string what = "write dataset " + name;
  const hsize_t dims[2] = {rows, cols};
  Handle space(checked(H5Screate_simple(2, dims, nullptr), path, what), H5Sclose);
  const Handle layout = dataset_creation(rows, cols, H5Tget_size(file_type), deflate, path);
  Handle set(checked(H5Dcreate2(parent, name.c_str(), file_type, space.get(), H5P_DEFAULT, creation(layout),
                                H5P_DEFAULT),
                     path, what),
             H5Dclose);
  if (rows * cols > 0) checked_status(H5Dwrite(set.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), path, what);
}
} // namespace

Handle parallel_access(hid_t fapl, const void* mpi_comm, const std::string& path) {
#ifdef H5_HAVE_PARALLEL
  const MPI_Comm comm = *static_cast<const MPI_Comm*>(mpi_comm);
  checked_status(H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL), path, "open the file with MPI-IO");
  Handle transfer(checked(H5Pcreate(H5P_DATASET_XFER), path, "create a data transfer list"), H5Pclose);
  checked_status(H5Pset_dxpl_mpio(transfer.get(), H5FD_MPIO_COLLECTIVE), path, "set collective transfers");
  return transfer;
#else
  (void)fapl, (void)mpi_comm;
  throw std::runtime_error(path + ": this otmpm is built with the serial HDF5 (a parallel file needs OTMPM_MPI)");
#endif
}

namespace {
/// The buffer of a rank that writes no rows (HDF5 wants a pointer).
const double kNoData = 0.0;

/// Selects the rows of `blocks` (all columns) in the file space of a
/// dataset of `cols` columns and a memory space of as many values; none
/// when the blocks hold no row.
void select_blocks(hid_t file_space, hid_t memory, hsize_t cols, const std::vector<RowBlock>& blocks,
                   const std::string& path, const std::string& what) {
  if (static_cast<hsize_t>(block_rows(blocks)) * cols == 0) {
    checked_status(H5Sselect_none(file_space), path, what);
    checked_status(H5Sselect_none(memory), path, what);
    return;
  }
  checked_status(H5Sselect_none(file_space), path, what);
  for (const RowBlock& b : blocks) {
    if (b.count * b.block == 0) continue;
    const hsize_t start[2] = {static_cast<hsize_t>(b.first), 0}, stride[2] = {static_cast<hsize_t>(b.stride), 1},
                  count[2] = {static_cast<hsize_t>(b.count), 1}, block[2] = {static_cast<hsize_t>(b.block), cols};
    checked_status(H5Sselect_hyperslab(file_space, H5S_SELECT_OR, start, stride, count, block), path, what);
  }
}

/// write_blocks for elements stored as `file_type` from memory of type `memory_type`.
void write_blocks_as(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols,
                     const std::vector<RowBlock>& blocks, hid_t file_type, hid_t memory_type, const void* data,
                     hid_t transfer, const std::string& path, int deflate) {
  const std::string what = "write dataset " + name;
  const hsize_t dims[2] = {total_rows, cols},
                values = std::max<hsize_t>(1, static_cast<hsize_t>(block_rows(blocks)) * cols);
  Handle space(checked(H5Screate_simple(2, dims, nullptr), path, what), H5Sclose);
  const Handle layout = dataset_creation(total_rows, cols, H5Tget_size(file_type), deflate, path);
  Handle set(checked(H5Dcreate2(parent, name.c_str(), file_type, space.get(), H5P_DEFAULT, creation(layout),
                                H5P_DEFAULT),
                     path, what),
             H5Dclose);
  Handle file_space(checked(H5Dget_space(set.get()), path, what), H5Sclose);
  Handle memory(checked(H5Screate_simple(1, &values, nullptr), path, what), H5Sclose);
  select_blocks(file_space.get(), memory.get(), cols, blocks, path, what);
  if (total_rows * cols > 0)
    checked_status(
        H5Dwrite(set.get(), memory_type, memory.get(), file_space.get(), transfer, data ? data : &kNoData), path, what);
}

/// write_rows for elements stored as `file_type` from memory of type `memory_type`.
void write_rows_as(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols, hsize_t first,
                   hsize_t rows, hid_t file_type, hid_t memory_type, const void* data, hid_t transfer,
                   const std::string& path, int deflate) {
  const RowBlock one{static_cast<long long>(first), 1, 1, static_cast<long long>(rows)};
  write_blocks_as(parent, name, total_rows, cols, {one}, file_type, memory_type, data, transfer, path, deflate);
}

/// read_blocks into memory of type `memory_type` from a dataset of type class `cls`.
void read_blocks_as(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                    H5T_class_t cls, hid_t memory_type, void* out, hid_t transfer, const std::string& path);
} // namespace

void write_blocks(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols,
                  const std::vector<RowBlock>& blocks, const double* data, hid_t transfer, const std::string& path) {
  write_blocks_as(parent, name, total_rows, cols, blocks, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, data, transfer, path, 0);
}

void write_blocks(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols,
                  const std::vector<RowBlock>& blocks, const std::int64_t* data, hid_t transfer,
                  const std::string& path) {
  write_blocks_as(parent, name, total_rows, cols, blocks, H5T_STD_I64LE, H5T_NATIVE_INT64, data, transfer, path, 0);
}

void read_blocks(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                 double* out, hid_t transfer, const std::string& path) {
  read_blocks_as(parent, name, cols, blocks, H5T_FLOAT, H5T_NATIVE_DOUBLE, out, transfer, path);
}

void read_blocks(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                 std::int64_t* out, hid_t transfer, const std::string& path) {
  read_blocks_as(parent, name, cols, blocks, H5T_INTEGER, H5T_NATIVE_INT64, out, transfer, path);
}

void write_rows(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols, hsize_t first, hsize_t rows,
                const double* data, hid_t transfer, const std::string& path, int deflate) {
  write_rows_as(parent, name, total_rows, cols, first, rows, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, data, transfer, path,
                deflate);
}

void write_rows(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols, hsize_t first, hsize_t rows,
                const float* data, hid_t transfer, const std::string& path, int deflate) {
  write_rows_as(parent, name, total_rows, cols, first, rows, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, data, transfer, path,
                deflate);
}

void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const float* data,
                  const std::string& path, int deflate) {
  write_dataset(parent, name, rows, cols, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, data, path, deflate);
}

void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const double* data,
                  const std::string& path, int deflate) {
  write_dataset(parent, name, rows, cols, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, data, path, deflate);
}

void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const std::int64_t* data,
                  const std::string& path, int deflate) {
  write_dataset(parent, name, rows, cols, H5T_STD_I64LE, H5T_NATIVE_INT64, data, path, deflate);
}

bool has_attribute(hid_t object, const std::string& name) { return H5Aexists(object, name.c_str()) > 0; }

std::vector<std::string> attribute_names(hid_t object, const std::string& path) {
  const std::string what = "list the attributes of " + object_path(object);
#if H5_VERSION_GE(1, 12, 0)
  H5O_info2_t info;
  checked_status(H5Oget_info3(object, &info, H5O_INFO_NUM_ATTRS), path, what);
#else
  H5O_info_t info;
  checked_status(H5Oget_info2(object, &info, H5O_INFO_NUM_ATTRS), path, what);
#endif
  const auto iterate = [object](auto... args) { return H5Aiterate2(object, args...); };
  return iterated_names<H5A_info_t>(iterate, info.num_attrs, path, what);
}

H5T_class_t attribute_class(hid_t object, const std::string& name, const std::string& path) {
  Handle attr(checked(H5Aopen(object, name.c_str(), H5P_DEFAULT), path, "open attribute " + name), H5Aclose);
  Handle type(checked(H5Aget_type(attr.get()), path, "read attribute " + name), H5Tclose);
  return H5Tget_class(type.get());
}

H5T_class_t dataset_class(hid_t parent, const std::string& name, const std::string& path) {
  Handle set(checked(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), path, "open dataset " + name), H5Dclose);
  Handle type(checked(H5Dget_type(set.get()), path, "read dataset " + name), H5Tclose);
  return H5Tget_class(type.get());
}

namespace {
/// Opens attribute `name` of `object` and checks that its type is of class `cls` (or `alt`).
Handle open_attribute(hid_t object, const std::string& name, const std::string& path, H5T_class_t cls,
                      H5T_class_t alt, const char* kind) {
  if (!has_attribute(object, name)) fail(path, "find attribute '" + name + "'");
  Handle attr(checked(H5Aopen(object, name.c_str(), H5P_DEFAULT), path, "open attribute " + name), H5Aclose);
  Handle type(checked(H5Aget_type(attr.get()), path, "read attribute " + name), H5Tclose);
  const H5T_class_t c = H5Tget_class(type.get());
  if (c != cls && c != alt) fail(path, std::string("read attribute '") + name + "' as " + kind);
  return attr;
}
} // namespace

double read_double(hid_t object, const std::string& name, const std::string& path) {
  Handle attr = open_attribute(object, name, path, H5T_FLOAT, H5T_INTEGER, "a number");
  double value = 0;
  checked_status(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value), path, "read attribute " + name);
  return value;
}

std::int64_t read_integer(hid_t object, const std::string& name, const std::string& path) {
  Handle attr = open_attribute(object, name, path, H5T_INTEGER, H5T_INTEGER, "an integer");
  std::int64_t value = 0;
  checked_status(H5Aread(attr.get(), H5T_NATIVE_INT64, &value), path, "read attribute " + name);
  return value;
}

std::string read_string(hid_t object, const std::string& name, const std::string& path) {
  Handle attr = open_attribute(object, name, path, H5T_STRING, H5T_STRING, "a string");
  Handle type(checked(H5Aget_type(attr.get()), path, "read attribute " + name), H5Tclose);
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

namespace {
/// An open rank-1 or rank-2 dataset whose type is of class `cls` and its size.
struct OpenMatrix {
  Handle set;
  hsize_t rows = 0, cols = 1;
};

OpenMatrix open_matrix(hid_t parent, const std::string& name, const std::string& path, H5T_class_t cls) {
  const std::string what = "read dataset " + name;
  if (!has_link(parent, name)) fail(path, "find dataset '" + name + "'");
  OpenMatrix m;
  m.set = Handle(checked(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), path, what), H5Dclose);
  Handle type(checked(H5Dget_type(m.set.get()), path, what), H5Tclose);
  if (H5Tget_class(type.get()) != cls) fail(path, what + " (unexpected element type)");
  Handle space(checked(H5Dget_space(m.set.get()), path, what), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank != 1 && rank != 2) fail(path, what + " (rank " + std::to_string(rank) + ", expected 1 or 2)");
  hsize_t dims[2] = {0, 1};
  checked_status(H5Sget_simple_extent_dims(space.get(), dims, nullptr), path, what);
  m.rows = dims[0];
  m.cols = dims[1];
  return m;
}

void read_blocks_as(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                    H5T_class_t cls, hid_t memory_type, void* out, hid_t transfer, const std::string& path) {
  const std::string what = "read dataset " + name;
  const OpenMatrix m = open_matrix(parent, name, path, cls);
  if (m.cols != cols) fail(path, what + " (" + std::to_string(m.cols) + " columns, expected " + std::to_string(cols) + ")");
  for (const RowBlock& b : blocks)
    if (b.count * b.block > 0 && static_cast<hsize_t>(b.first + (b.count - 1) * b.stride + b.block) > m.rows)
      fail(path, what + " (rows up to " + std::to_string(b.first + (b.count - 1) * b.stride + b.block) + " of " +
                     std::to_string(m.rows) + ")");
  const hsize_t values = std::max<hsize_t>(1, static_cast<hsize_t>(block_rows(blocks)) * cols);
  Handle file_space(checked(H5Dget_space(m.set.get()), path, what), H5Sclose);
  Handle memory(checked(H5Screate_simple(1, &values, nullptr), path, what), H5Sclose);
  if (H5Sget_simple_extent_ndims(file_space.get()) != 2) fail(path, what + " (rank 1, expected rows x columns)");
  select_blocks(file_space.get(), memory.get(), cols, blocks, path, what);
  double unused = 0.0;
  checked_status(H5Dread(m.set.get(), memory_type, memory.get(), file_space.get(), transfer, out ? out : &unused), path,
                 what);
}

/// Reads a rank-1 or rank-2 dataset whose type is of class `cls` into memory type `memory_type`.
template <class T>
Matrix<T> read_matrix(hid_t parent, const std::string& name, const std::string& path, H5T_class_t cls,
                      hid_t memory_type) {
  const OpenMatrix open = open_matrix(parent, name, path, cls);
  Matrix<T> m;
  m.rows = open.rows;
  m.cols = open.cols;
  m.values.resize(static_cast<std::size_t>(m.rows * m.cols));
  if (!m.values.empty())
    checked_status(H5Dread(open.set.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, m.values.data()), path,
                   "read dataset " + name);
  return m;
}

/// Bytes of the chunks a block of rows of the chunked dataset `set` passes
/// through (one chunk along the rows, all of them across the columns), or 0
/// when it is not chunked.
std::size_t chunk_row_bytes(hid_t set, hsize_t cols, const std::string& path, const std::string& what) {
  Handle create(checked(H5Dget_create_plist(set), path, what), H5Pclose);
  if (H5Pget_layout(create.get()) != H5D_CHUNKED) return 0;
  hsize_t chunk[2] = {1, 1};
  if (H5Pget_chunk(create.get(), 2, chunk) < 1) return 0;
  Handle type(checked(H5Dget_type(set), path, what), H5Tclose);
  const hsize_t across = chunk[1] > 0 ? (cols + chunk[1] - 1) / chunk[1] : 1;
  return static_cast<std::size_t>(chunk[0] * chunk[1] * across * H5Tget_size(type.get()));
}
} // namespace

DoubleRows::DoubleRows(hid_t parent, const std::string& name, const std::string& path) : name_(name), path_(path) {
  OpenMatrix m = open_matrix(parent, name, path, H5T_FLOAT);
  rows_ = m.rows;
  cols_ = m.cols;
  // A chunked (e.g. compressed) dataset read a block of rows at a time: its
  // chunk cache must hold the chunks a block passes through, or a chunk larger
  // than the default cache (1 MiB) is read and inflated again for every block
  // that touches it (a dataset stored as one chunk: once per block).
  const std::string what = "read dataset " + name;
  if (const std::size_t bytes = chunk_row_bytes(m.set.get(), cols_, path, what); bytes > (std::size_t{1} << 20)) {
    Handle access(checked(H5Pcreate(H5P_DATASET_ACCESS), path, what), H5Pclose);
    checked_status(H5Pset_chunk_cache(access.get(), 12421, 2 * bytes, 1.0), path, what);
    m.set.close(); // else the reopened dataset shares the open one's cache
    m.set = Handle(checked(H5Dopen2(parent, name.c_str(), access.get()), path, what), H5Dclose);
  }
  set_ = std::move(m.set);
}

void DoubleRows::read(hsize_t first, hsize_t count, double* out) const {
  const std::string what = "read dataset " + name_;
  if (count == 0) return;
  if (first + count > rows_) fail(path_, what + " (rows " + std::to_string(first) + " + " + std::to_string(count) +
                                             " beyond " + std::to_string(rows_) + ")");
  Handle file_space(checked(H5Dget_space(set_.get()), path_, what), H5Sclose);
  const hsize_t start[2] = {first, 0}, size[2] = {count, cols_};
  checked_status(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, size, nullptr), path_, what);
  const hsize_t values = count * cols_;
  Handle memory_space(checked(H5Screate_simple(1, &values, nullptr), path_, what), H5Sclose);
  checked_status(H5Dread(set_.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT, out), path_,
                 what);
}

std::pair<hsize_t, hsize_t> dataset_shape(hid_t parent, const std::string& name, const std::string& path) {
  const std::string what = "read dataset " + name;
  if (!has_link(parent, name)) fail(path, "find dataset '" + name + "'");
  Handle set(checked(H5Dopen2(parent, name.c_str(), H5P_DEFAULT), path, what), H5Dclose);
  Handle space(checked(H5Dget_space(set.get()), path, what), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank != 1 && rank != 2) fail(path, what + " (rank " + std::to_string(rank) + ", expected 1 or 2)");
  hsize_t dims[2] = {0, 1};
  checked_status(H5Sget_simple_extent_dims(space.get(), dims, nullptr), path, what);
  return {dims[0], dims[1]};
}

Matrix<double> read_double_matrix(hid_t parent, const std::string& name, const std::string& path) {
  return read_matrix<double>(parent, name, path, H5T_FLOAT, H5T_NATIVE_DOUBLE);
}

Matrix<std::int64_t> read_integer_matrix(hid_t parent, const std::string& name, const std::string& path) {
  return read_matrix<std::int64_t>(parent, name, path, H5T_INTEGER, H5T_NATIVE_INT64);
}

} // namespace otmpm::h5
