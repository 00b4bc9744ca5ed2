#pragma once
/// \file hdf5.hpp
/// Internal helpers over the HDF5 C API shared by the result file
/// (results.cpp) and the checkpoint file (checkpoint.cpp): an owning handle,
/// checks that turn a failed call into an exception naming the file, groups,
/// scalar attributes and 2D datasets of doubles or 64-bit integers. Writing
/// failures throw h5::Failure, a std::runtime_error ("PATH: HDF5 could not WHAT"); callers
/// that read user-supplied files turn them into InputError.
///
/// Output that cannot be written (no space left, a file size limit) is an
/// OutputError (core.hpp): reserve_space() finds it before HDF5 writes, and a
/// write HDF5 reports as failed afterwards is turned into one by
/// output_failure(). After such a failure HDF5 1.10 crashes when it closes the
/// file again at exit (H5close from its atexit handler), so the library
/// replaces that handler by one that skips H5close once a write failed.
#include "otmpm/io/parallel_io.hpp"

#include <hdf5.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace otmpm::h5 {

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
  /// Gives up ownership without closing (a file HDF5 failed to write, which
  /// closing would only try to write again).
  void release() { id_ = H5I_INVALID_HID; }
  /// Closes now and reports whether the close succeeded (a file's last flush).
  bool close() {
    const hid_t id = id_;
    id_ = H5I_INVALID_HID;
    return id < 0 || !close_ || close_(id) >= 0;
  }

private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

/// A failed HDF5 call (thrown by fail() and the checks below).
class Failure : public std::runtime_error {
public:
  explicit Failure(const std::string& what) : std::runtime_error(what) {}
};

/// Silences HDF5's default printing of its error stack: errors become
/// exceptions with context instead.
void silence();

/// The system error HDF5 recorded for the last failed call ("No space left on
/// device", "File too large", ...), or "" when its error stack has none.
std::string system_error();

/// Records that HDF5 failed to write a file (after which closing it again
/// may crash HDF5): the library's exit handler then skips H5close.
void note_write_failure();
/// True after note_write_failure().
bool write_failed();

/// Throws OutputError "PATH: cannot WHAT: SYSTEM ERROR (...)" for a failed
/// write, after note_write_failure().
[[noreturn]] void output_failure(const std::string& path, const std::string& what);

/// The POSIX file descriptor of a file opened with HDF5's default (sec2) driver.
int file_descriptor(hid_t file, const std::string& path);

/// Makes sure `bytes` more bytes can be written to the open file `fd`
/// (named `path` in messages) before anything is: the file must stay under
/// the file size limit (RLIMIT_FSIZE, `ulimit -f`) and the bytes must be free
/// on its file system (statvfs, as available to this user). Space another
/// process takes meanwhile, or a disk quota, is not foreseen: the write then
/// fails and output_failure() reports it. Throws OutputError naming the
/// file, the limit and the sizes when the bytes do not fit.
void check_room(int fd, std::uint64_t bytes, const std::string& path);

/// Allocates the first `bytes` bytes beyond the end of the open file `fd` on
/// the device (fallocate with FALLOC_FL_KEEP_SIZE: quota and free space are
/// taken now, so the writes that follow cannot fail for lack of either),
/// after check_room(). For a file written once and closed (a checkpoint's
/// temporary): HDF5 truncates files to its end of allocation at every flush,
/// which for a file kept open makes the flush slower. OutputError like check_room.
void reserve_space(int fd, std::uint64_t bytes, const std::string& path);

/// Makes sure the files written beside one (the XDMF sidecar, the VTK files)
/// will fit: `bytes` in all must be free on the file system of `path`, and
/// the largest of them, `largest`, must fit under RLIMIT_FSIZE. OutputError
/// naming `path` otherwise.
void require_room(const std::string& path, std::uint64_t bytes, std::uint64_t largest);

/// Throws Failure "PATH: HDF5 could not WHAT".
[[noreturn]] void fail(const std::string& path, const std::string& what);
/// Returns id, or fails when it is negative.
hid_t checked(hid_t id, const std::string& path, const std::string& what);
/// Fails when status is negative.
void checked_status(herr_t status, const std::string& path, const std::string& what);

/// Creates the group `name` below `parent`.
Handle create_group(hid_t parent, const std::string& name, const std::string& path);
/// Opens the existing group `name` below `parent`.
Handle open_group(hid_t parent, const std::string& name, const std::string& path);
/// True when `parent` has a link called `name`.
bool has_link(hid_t parent, const std::string& name);
/// Names of the links in a group, in name order: its name index walked in
/// native order and sorted (listing in name order, HDF5 sorts a table of the
/// stored count of links and crashes when a killed writer left fewer in the
/// index). Failure naming the file when the count and the index differ (a
/// damaged file).
std::vector<std::string> link_names(hid_t group, const std::string& path);
/// The number of links in a group, from its stored count (H5Gget_info): no
/// iteration over the links (a killed writer's group may hold one less).
std::size_t link_count(hid_t group, const std::string& path);

/// A fixed-length, null-terminated UTF-8 string type of `length` characters.
Handle string_type(std::size_t length, const std::string& path);
/// Writes a scalar attribute of memory type `type` on `object`, replacing an existing one.
void write_attribute(hid_t object, const std::string& name, hid_t type, const void* value, const std::string& path);
/// Writes a string attribute (fixed-length UTF-8).
void write_string_attribute(hid_t object, const std::string& name, const std::string& value,
                            const std::string& path);

/// Largest chunk of a compressed dataset (dataset_creation), in bytes before compression.
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 20;
/// Highest deflate (gzip) level.
constexpr int kMaxDeflate = 9;

/// True when this HDF5 can compress with the deflate (gzip) filter
/// (H5Zfilter_avail and its encoder enabled, H5Zget_filter_info).
bool deflate_available();

/// Rows per chunk of a compressed rows x cols dataset of `value_bytes`-byte
/// values: the dataset is split along its rows into the fewest chunks of at
/// most kMaxChunkBytes (all columns in each chunk), of equal rows but the
/// last; at least 1 row.
hsize_t chunk_rows(hsize_t rows, hsize_t cols, std::size_t value_bytes);

/// The dataset creation list of a rows x cols dataset of `value_bytes`-byte
/// values compressed at deflate level `deflate` (1..kMaxDeflate): chunked
/// by chunk_rows(), the shuffle filter then deflate, no fill values written.
/// An invalid handle (use H5P_DEFAULT: contiguous) when `deflate` is 0 or
/// the dataset holds no value. Fails when deflate is not available.
/// `rank` 1: a rank-1 dataset of `rows` values (cols must be 1).
Handle dataset_creation(hsize_t rows, hsize_t cols, std::size_t value_bytes, int deflate, const std::string& path,
                        int rank = 2);

/// Writes a rows x cols dataset of doubles: contiguous, or with `deflate` >
/// 0 chunked and compressed (dataset_creation).
void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const double* data,
                  const std::string& path, int deflate = 0);
/// Writes a rows x cols dataset of 32-bit IEEE floats (`deflate` as above).
void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const float* data,
                  const std::string& path, int deflate = 0);
/// Writes a rows x cols dataset of 64-bit integers (`deflate` as above).
void write_matrix(hid_t parent, const std::string& name, hsize_t rows, hsize_t cols, const std::int64_t* data,
                  const std::string& path, int deflate = 0);

/// Makes `fapl` open the file with MPI-IO over the ranks of `mpi_comm` (an
/// MPI_Comm*) and returns a data transfer list for collective writes.
/// std::runtime_error when this HDF5 is not the parallel one.
Handle parallel_access(hid_t fapl, const void* mpi_comm, const std::string& path);

/// Writes rows [first, first + rows) of a new total_rows x cols dataset of
/// doubles; with a parallel file every rank creates the dataset and writes
/// its rows in one collective call (`transfer`: the data transfer list;
/// H5P_DEFAULT for a serial file, which writes all rows). `deflate` > 0:
/// chunked and compressed (dataset_creation; the parallel HDF5 writes
/// filtered datasets with collective transfers only, which `transfer` sets).
void write_rows(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols, hsize_t first, hsize_t rows,
                const double* data, hid_t transfer, const std::string& path, int deflate = 0);
/// write_rows of 32-bit IEEE floats.
void write_rows(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols, hsize_t first, hsize_t rows,
                const float* data, hid_t transfer, const std::string& path, int deflate = 0);

/// Writes the rows of `blocks` (RowBlock: regular hyperslabs along the rows,
/// every column; in increasing order, none twice) of a new
/// total_rows x cols dataset of doubles or 64-bit integers; `data` holds them
/// in that order. With a parallel file every rank creates the dataset and
/// writes its rows in one collective call (`transfer`; H5P_DEFAULT: serial).
void write_blocks(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols,
                  const std::vector<RowBlock>& blocks, const double* data, hid_t transfer, const std::string& path);
void write_blocks(hid_t parent, const std::string& name, hsize_t total_rows, hsize_t cols,
                  const std::vector<RowBlock>& blocks, const std::int64_t* data, hid_t transfer,
                  const std::string& path);
/// Reads the rows of `blocks` (in increasing order) of the rank-2 dataset
/// `name` (of `cols` columns; Failure when it has other columns,
/// fewer rows or another type class) into `out`, in that order (collective
/// with a parallel file: every rank calls it, `transfer` as above).
void read_blocks(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                 double* out, hid_t transfer, const std::string& path);
void read_blocks(hid_t parent, const std::string& name, hsize_t cols, const std::vector<RowBlock>& blocks,
                 std::int64_t* out, hid_t transfer, const std::string& path);
/// Rows and columns of the rank-1 or rank-2 dataset `name` below `parent`.
std::pair<hsize_t, hsize_t> dataset_shape(hid_t parent, const std::string& name, const std::string& path);

/// True when `object` has an attribute `name`.
bool has_attribute(hid_t object, const std::string& name);
/// Names of the attributes of `object`, in name order (listed as link_names lists links).
std::vector<std::string> attribute_names(hid_t object, const std::string& path);
/// The type class (H5T_FLOAT, H5T_INTEGER, H5T_STRING, ...) of attribute `name` of `object`.
H5T_class_t attribute_class(hid_t object, const std::string& name, const std::string& path);
/// The type class of dataset `name` below `parent`.
H5T_class_t dataset_class(hid_t parent, const std::string& name, const std::string& path);
/// A numeric scalar attribute converted to double (fails if absent or not a number).
double read_double(hid_t object, const std::string& name, const std::string& path);
/// An integer scalar attribute (fails if absent or not an integer).
std::int64_t read_integer(hid_t object, const std::string& name, const std::string& path);
/// A string attribute, fixed or variable length (fails if absent or not a string).
std::string read_string(hid_t object, const std::string& name, const std::string& path);

/// A dataset read back: rows x cols values (cols = 1 for a rank-1 dataset).
template <class T> struct Matrix {
  hsize_t rows = 0, cols = 0;
  std::vector<T> values;
};
/// Reads a rank-1 or rank-2 dataset of numbers as doubles.
Matrix<double> read_double_matrix(hid_t parent, const std::string& name, const std::string& path);
/// A rank-1 or rank-2 dataset of numbers read a block of rows at a time
/// (hyperslabs; a rank-1 dataset has one column), as doubles: a dataset
/// larger than memory can be read in pieces.
class DoubleRows {
public:
  /// Opens dataset `name` below `parent` (of the file `path`); Failure with
  /// the messages of read_double_matrix when it is missing, not of numbers
  /// or of rank other than 1 and 2.
  DoubleRows(hid_t parent, const std::string& name, const std::string& path);
  hsize_t rows() const { return rows_; }
  hsize_t cols() const { return cols_; }
  /// Reads rows [first, first + count) into out (count x cols, row-major).
  void read(hsize_t first, hsize_t count, double* out) const;

private:
  Handle set_;
  std::string name_, path_;
  hsize_t rows_ = 0, cols_ = 1;
};
/// Reads a rank-1 or rank-2 dataset of integers as 64-bit integers.
Matrix<std::int64_t> read_integer_matrix(hid_t parent, const std::string& name, const std::string& path);

} // namespace otmpm::h5
