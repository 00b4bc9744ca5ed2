#include "otmpm/io/undo_journal.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/output_files.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <type_traits>
#include <vector>

namespace otmpm::h5 {
namespace {

constexpr std::size_t kPathBytes = 4096;
constexpr std::uint32_t kRecordMagic = 0x524a554fU; // "OUJR"
constexpr haddr_t kMaxAddress = (static_cast<haddr_t>(1) << 62) - 1;

/// The driver's file access information (copied by HDF5 with the list).
struct JournalInfo {
  char journal[kPathBytes];
};

/// One undo record: the bytes [addr, addr + size) held before a write,
/// followed by those bytes; `check` (record_check) covers the header fields and the bytes.
struct RecordHeader {
  std::uint32_t magic;
  std::uint32_t reserved;
  std::uint64_t addr;
  std::uint64_t size;
  std::uint64_t check;
};

/// CRC-64 of a record's header fields and bytes (the checkpoints' checksum):
/// detects a record cut short by the kill.
std::uint64_t record_check(const RecordHeader& r, const void* bytes) {
  const std::uint64_t fields[3] = {r.magic, r.addr, r.size};
  return crc64_combine(crc64(fields, sizeof fields), crc64(bytes, r.size), r.size);
}

/// An open file of the driver. `pub` comes first: HDF5 hands the driver its address.
struct UndoFile {
  H5FD_t pub;
  int fd = -1;
  int journal_fd = -1; ///< -1 for a file opened read-only
  JournalInfo info{};
  haddr_t eoa = 0, eof = 0;
  haddr_t committed = 0; ///< end of the last flushed state: a write below it is journalled first
  bool dirty = false;    ///< the journal holds records of the flush under way
  bool failed = false;   ///< a write failed: the file may be half-written, the journal stays
  dev_t device = 0;
  ino_t inode = 0;
};

UndoFile* as_undo(H5FD_t* f) { return reinterpret_cast<UndoFile*>(f); }
const UndoFile* as_undo(const H5FD_t* f) { return reinterpret_cast<const UndoFile*>(f); }

/// Repeats pread or pwrite (`io`) until all n bytes at `at` are moved; false on an error or the file's end.
template <class Io, class Byte> bool move_all(Io io, int fd, Byte* p, std::size_t n, off_t at) {
  while (n > 0) {
    const ssize_t moved = io(fd, p, n, at);
    if (moved < 0 && errno == EINTR) continue;
    if (moved <= 0) return false;
    p += moved, at += moved, n -= static_cast<std::size_t>(moved);
  }
  return true;
}

bool read_all(int fd, void* buf, std::size_t n, off_t at) { return move_all(::pread, fd, static_cast<char*>(buf), n, at); }

bool write_all(int fd, const void* buf, std::size_t n, off_t at) {
  return move_all(::pwrite, fd, static_cast<const char*>(buf), n, at);
}

/// Appends the bytes [addr, addr + n) as they are now to the journal, as one write.
/// Called by HDF5's C code: allocates without throwing (a failed allocation is a failed write).
bool journal_old_bytes(UndoFile& f, haddr_t addr, std::size_t n) {
  const std::unique_ptr<char, decltype(&std::free)> old(static_cast<char*>(std::malloc(n)), &std::free);
  if (!old || !read_all(f.fd, old.get(), n, static_cast<off_t>(addr))) return false;
  RecordHeader r{kRecordMagic, 0, addr, n, 0};
  r.check = record_check(r, old.get());
  iovec parts[2] = {{&r, sizeof r}, {old.get(), n}};
  const std::size_t total = sizeof r + n;
  ssize_t put = 0;
  do put = ::writev(f.journal_fd, parts, 2);
  while (put < 0 && errno == EINTR);
  if (put != static_cast<ssize_t>(total)) return false;
  f.dirty = true;
  return true;
}

void* info_copy(const void* info) {
  void* copy = std::malloc(sizeof(JournalInfo));
  if (copy) std::memcpy(copy, info, sizeof(JournalInfo));
  return copy;
}

herr_t info_free(void* info) {
  std::free(info);
  return 0;
}

void* info_get(H5FD_t* f) { return info_copy(&as_undo(f)->info); }

static_assert(std::is_trivially_destructible_v<UndoFile>);
void release_file(UndoFile* f) { std::free(f); }

int open_flags(unsigned flags) {
  int o = (flags & H5F_ACC_RDWR) ? O_RDWR : O_RDONLY;
  if (flags & H5F_ACC_TRUNC) o |= O_TRUNC;
  if (flags & H5F_ACC_CREAT) o |= O_CREAT;
  if (flags & H5F_ACC_EXCL) o |= O_EXCL;
  return o | O_CLOEXEC;
}

H5FD_t* open_file(const char* name, unsigned flags, hid_t fapl, haddr_t maxaddr) {
  const auto* info = static_cast<const JournalInfo*>(H5Pget_driver_info(fapl));
  if (!name || !*name || !info || maxaddr == 0 || maxaddr == HADDR_UNDEF || maxaddr > kMaxAddress) return nullptr;
  // HDF5's C code calls this: no exception may leave it, so the file's
  // record lives in malloc'ed memory (released by release_file).
  void* memory = std::malloc(sizeof(UndoFile));
  if (!memory) return nullptr;
  auto* f = new (memory) UndoFile{};
  f->info = *info;
  f->fd = ::open(name, open_flags(flags), 0666);
  struct stat st {};
  if (f->fd >= 0 && ::fstat(f->fd, &st) == 0) {
    f->eof = f->committed = static_cast<haddr_t>(st.st_size);
    f->device = st.st_dev;
    f->inode = st.st_ino;
    const bool writing = (flags & H5F_ACC_RDWR) != 0;
    if (!writing) return &f->pub;
    f->journal_fd = ::open(info->journal, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
    if (f->journal_fd >= 0) return &f->pub;
  }
  const int err = errno;
  if (f->fd >= 0) ::close(f->fd);
  release_file(f);
  errno = err;
  return nullptr;
}

/// HDF5 closes the driver's file after its last write (the superblock's
/// consistency flag cleared after the final flush): the file is complete,
/// unless a write failed on the way (then the journal stays for a restore).
herr_t close_file(H5FD_t* file) {
  UndoFile* f = as_undo(file);
  int status = 0;
  if (f->journal_fd >= 0) {
    if (!f->failed && f->eof > f->eoa) status |= ::ftruncate(f->fd, static_cast<off_t>(f->eoa));
    status |= ::close(f->journal_fd);
    if (!f->failed) ::unlink(f->info.journal);
  }
  status |= ::close(f->fd);
  release_file(f);
  return status == 0 ? 0 : -1;
}

int compare(const H5FD_t* a, const H5FD_t* b) {
  const UndoFile *x = as_undo(a), *y = as_undo(b);
  if (x->device != y->device) return x->device < y->device ? -1 : 1;
  if (x->inode != y->inode) return x->inode < y->inode ? -1 : 1;
  return 0;
}

herr_t query(const H5FD_t*, unsigned long* flags) {
  if (flags)
    *flags = H5FD_FEAT_AGGREGATE_METADATA | H5FD_FEAT_ACCUMULATE_METADATA | H5FD_FEAT_DATA_SIEVE |
             H5FD_FEAT_AGGREGATE_SMALLDATA | H5FD_FEAT_POSIX_COMPAT_HANDLE | H5FD_FEAT_DEFAULT_VFD_COMPATIBLE;
  return 0;
}

haddr_t get_eoa(const H5FD_t* f, H5FD_mem_t) { return as_undo(f)->eoa; }
herr_t set_eoa(H5FD_t* f, H5FD_mem_t, haddr_t addr) {
  as_undo(f)->eoa = addr;
  return 0;
}
haddr_t get_eof(const H5FD_t* f, H5FD_mem_t) { return as_undo(f)->eof; }

herr_t get_handle(H5FD_t* f, hid_t, void** handle) {
  if (!handle) return -1;
  *handle = &as_undo(f)->fd;
  return 0;
}

herr_t read_bytes(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, void* buf) {
  const UndoFile* f = as_undo(file);
  if (addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  const std::size_t stored = addr >= f->eof ? 0 : static_cast<std::size_t>(std::min<haddr_t>(size, f->eof - addr));
  if (stored > 0 && !read_all(f->fd, buf, stored, static_cast<off_t>(addr))) return -1;
  std::memset(static_cast<char*>(buf) + stored, 0, size - stored); // past the end of the file: zeros, as sec2
  return 0;
}

herr_t write_bytes(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, const void* buf) {
  UndoFile* f = as_undo(file);
  if (f->journal_fd < 0 || addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  if (addr < f->committed) {
    const auto n = static_cast<std::size_t>(std::min<haddr_t>(size, f->committed - addr));
    if (!journal_old_bytes(*f, addr, n)) return f->failed = true, -1;
  }
  if (!write_all(f->fd, buf, size, static_cast<off_t>(addr))) return f->failed = true, -1;
  f->eof = std::max<haddr_t>(f->eof, addr + size);
  return 0;
}

/// HDF5 calls this last in every flush, after the superblock: the file on
/// disk is the new flushed state, so the journal is emptied, and the file is
/// cut to the end of its allocated space only now (cut earlier, a kill would
/// leave a superblock whose end of file lies past the end of the file).
herr_t flush(H5FD_t* file, hid_t, hbool_t) {
  UndoFile* f = as_undo(file);
  if (f->journal_fd < 0) return 0;
  if (f->dirty && ::ftruncate(f->journal_fd, 0) != 0) return -1;
  f->dirty = false;
  if (f->eof > f->eoa && ::ftruncate(f->fd, static_cast<off_t>(f->eoa)) != 0) return -1;
  f->eof = std::min(f->eof, f->eoa);
  f->committed = f->eoa;
  return 0;
}

/// Grows the file to its allocated space; a shrink waits for the flush's end.
herr_t truncate(H5FD_t* file, hid_t, hbool_t) {
  UndoFile* f = as_undo(file);
  if (f->eoa <= f->eof) return 0;
  if (::ftruncate(f->fd, static_cast<off_t>(f->eoa)) != 0) return -1;
  f->eof = f->eoa;
  return 0;
}

herr_t lock(H5FD_t* f, hbool_t rw) {
  if (::flock(as_undo(f)->fd, (rw ? LOCK_EX : LOCK_SH) | LOCK_NB) == 0 || errno == ENOSYS) return 0;
  return -1;
}

herr_t unlock(H5FD_t* f) {
  if (::flock(as_undo(f)->fd, LOCK_UN) == 0 || errno == ENOSYS) return 0;
  return -1;
}

H5FD_class_t driver_class() {
  H5FD_class_t c{};
  c.name = "otmpm_undo_journal";
  c.maxaddr = kMaxAddress;
  c.fc_degree = H5F_CLOSE_WEAK;
  c.fapl_size = sizeof(JournalInfo);
  c.fapl_get = info_get;
  c.fapl_copy = info_copy;
  c.fapl_free = info_free;
  c.open = open_file;
  c.close = close_file;
  c.cmp = compare;
  c.query = query;
  c.get_eoa = get_eoa;
  c.set_eoa = set_eoa;
  c.get_eof = get_eof;
  c.get_handle = get_handle;
  c.read = read_bytes;
  c.write = write_bytes;
  c.flush = flush;
  c.truncate = truncate;
  c.lock = lock;
  c.unlock = unlock;
  const H5FD_mem_t map[H5FD_MEM_NTYPES] = H5FD_FLMAP_DICHOTOMY;
  std::copy(std::begin(map), std::end(map), std::begin(c.fl_map));
  return c;
}

hid_t driver_id(const std::string& path) {
  static const H5FD_class_t cls = driver_class();
  static hid_t id = -1;
  if (id < 0 || H5Iis_valid(id) <= 0) id = H5FDregister(&cls); // again after an H5close
  if (id < 0) throw InputError(path + ": HDF5 refused otmpm's file driver");
  return id;
}

/// The complete records of a journal, in the order they were written; a
/// record cut short by the kill ends the list (its write had not begun).
std::vector<std::pair<RecordHeader, std::vector<char>>> read_records(const std::string& journal) {
  std::vector<std::pair<RecordHeader, std::vector<char>>> records;
  const int fd = ::open(journal.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return records;
  struct stat st {};
  const off_t end = ::fstat(fd, &st) == 0 ? st.st_size : 0;
  off_t at = 0;
  RecordHeader r{};
  while (at + static_cast<off_t>(sizeof r) <= end && read_all(fd, &r, sizeof r, at)) {
    at += static_cast<off_t>(sizeof r);
    if (r.magic != kRecordMagic || r.size > static_cast<std::uint64_t>(end - at)) break;
    std::vector<char> bytes(r.size);
    if (!read_all(fd, bytes.data(), bytes.size(), at) || record_check(r, bytes.data()) != r.check) break;
    at += static_cast<off_t>(r.size);
    records.emplace_back(r, std::move(bytes));
  }
  ::close(fd);
  return records;
}

} // namespace

hid_t open_result_read_only(const std::string& path) {
  otmpm::roll_back_interrupted_flush(path);
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  if (fapl < 0) return fapl;
  hid_t file = -1;
  try {
    use_undo_journal(fapl, "", path); // read-only: no journal
    file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  } catch (...) {
    H5Pclose(fapl);
    throw;
  }
  H5Pclose(fapl);
  return file;
}

void use_undo_journal(hid_t fapl, const std::string& journal, const std::string& path) {
  JournalInfo info{};
  if (journal.size() >= sizeof info.journal) throw InputError(path + ": the undo journal's path is too long: " + journal);
  std::memcpy(info.journal, journal.c_str(), journal.size() + 1);
  if (H5Pset_driver(fapl, driver_id(path), &info) < 0) throw InputError(path + ": HDF5 refused otmpm's file driver");
}

bool apply_undo_journal(const std::string& path) {
  const std::string journal = undo_journal_path(path);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(journal, ec)) return false;
  const auto records = read_records(journal);
  if (!records.empty()) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0)
      throw InputError(path + ": cannot restore it from the undo journal " + journal + " its killed writer left: " +
                       std::strerror(errno));
    bool ok = true;
    for (auto r = records.rbegin(); r != records.rend() && ok; ++r)
      ok = write_all(fd, r->second.data(), r->second.size(), static_cast<off_t>(r->first.addr));
    const int err = errno;
    ::close(fd);
    if (!ok)
      throw InputError(path + ": cannot restore it from the undo journal " + journal + " its killed writer left: " +
                       std::strerror(err));
  }
  std::filesystem::remove(journal, ec);
  return !records.empty();
}

} // namespace otmpm::h5

namespace otmpm {

void roll_back_interrupted_flush(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(undo_journal_path(path), ec) || !lock_holder_of(path).empty()) return;
  const OutputLock lock({path}); // takes over the killed writer's lock, which applies its journal
}

} // namespace otmpm
