// Checkpoint files (see checkpoint.hpp): the in-memory state groups, their
// HDF5 form with a checksum per group, the atomic write and the reader that
// turns every defect of a file into an InputError naming it.
#include "otmpm/io/checkpoint.hpp"

#include "otmpm/core.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/output_files.hpp"

#include <boost/crc.hpp>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

namespace otmpm {

namespace fs = std::filesystem;
using h5::Handle;

namespace {

constexpr const char* kFormat = "otmpm checkpoint";
/// 2: the header with the file's size and CRC-64 in the HDF5 user block, and the run id.
/// 3: per-row arrays of a distributed run in rank order (particles/global_id,
/// the group "decomposition"); group checksums over the arrays' shapes.
/// 4: the energy friction dissipated and explicit_alpha's carried constraint momenta.
constexpr std::int64_t kFormatVersion = 4;
/// Bytes of the header at the start of the file (the HDF5 user block: a power of 2, >= 512).
constexpr std::size_t kHeaderBytes = 512;
/// Digits of the CRC in the header, and the placeholder it is computed with.
constexpr std::size_t kCrcDigits = 16;
/// Bytes read at a time when checksumming a file.
constexpr std::size_t kChunkBytes = std::size_t{1} << 16;
/// Metadata bytes allowed per group and per item when reserving space for a checkpoint.
constexpr std::uint64_t kGroupOverhead = 8192, kItemOverhead = 2048;
/// CRC-64/XZ (ECMA-182 polynomial, reflected): detects every error of up to
/// 64 consecutive bits, so every single-bit flip.
using Crc64 = boost::crc_optimal<64, 0x42F0E1EBA9EA3693ull, ~0ull, ~0ull, true, true>;
/// Attribute of every group (and of the root) holding the checksum of its content.
constexpr const char* kChecksum = "checksum";
/// FNV-1a 64-bit offset basis and prime.
constexpr std::uint64_t kFnvOffset = 14695981039346656037ull;
constexpr std::uint64_t kFnvPrime = 1099511628211ull;

/// FNV-1a over the bytes of a checkpoint's content: detects a damaged file
/// whose HDF5 structure still reads (HDF5 does not checksum raw data).
class Digest {
public:
  void bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * kFnvPrime;
  }
  void add(double x) { bytes(&x, sizeof x); }
  void add(std::int64_t x) { bytes(&x, sizeof x); }
  void add(const std::string& s) {
    add(static_cast<std::int64_t>(s.size()));
    bytes(s.data(), s.size());
  }
  template <class T> void add(const StateArray<T>& a) {
    add(static_cast<std::int64_t>(a.cols));
    add(static_cast<std::int64_t>(a.values.size()));
    bytes(a.values.data(), a.values.size() * sizeof(T));
  }
  /// Every (name, value) of a map, in name order.
  template <class Map> void add_all(const Map& map) {
    for (const auto& [name, v] : map) {
      add(name);
      add(v);
    }
  }
  /// The digest stored as a signed 64-bit attribute (same bits).
  std::int64_t value() const { return static_cast<std::int64_t>(h_); }

private:
  std::uint64_t h_ = kFnvOffset;
};

/// The shape of a per-row array of a group as the file holds it: rows of
/// all ranks (the values are covered by the file's CRC-64).
struct RowShape {
  std::string name;
  std::int64_t rows = 0, cols = 0;
  bool integer = false;
};

/// The per-row arrays of group `group` held in `g` (real arrays, then
/// integer ones, each in name order), with `total(kind)` rows each (null:
/// the rows held).
std::vector<RowShape> row_shapes(const std::string& group, const StateGroup& g,
                                 const std::function<long long(RowKind)>& total = nullptr) {
  std::vector<RowShape> out;
  auto add = [&](const auto& arrays, bool integer) {
    for (const auto& [name, a] : arrays) {
      const RowKind kind = checkpoint_row_kind(group, name);
      if (kind == RowKind::whole) continue;
      out.push_back({name, static_cast<std::int64_t>(total ? total(kind) : static_cast<long long>(a.rows())),
                     static_cast<std::int64_t>(a.cols), integer});
    }
  };
  add(g.real_arrays, false);
  add(g.integer_arrays, true);
  return out;
}

/// Checksum of a group: its scalars and whole arrays, and the names and
/// shapes of its per-row arrays `rows` (row_shapes; their values are in the
/// file's CRC-64, which every reader verifies first).
std::int64_t checksum(const std::string& group, const StateGroup& g, const std::vector<RowShape>& rows) {
  Digest d;
  d.add_all(g.reals);
  d.add_all(g.integers);
  d.add_all(g.strings);
  auto whole = [&](const auto& arrays) {
    for (const auto& [name, a] : arrays)
      if (checkpoint_row_kind(group, name) == RowKind::whole) {
        d.add(name);
        d.add(a);
      }
  };
  whole(g.real_arrays);
  whole(g.integer_arrays);
  for (const RowShape& r : rows) {
    d.add(r.name);
    d.add(r.rows);
    d.add(r.cols);
    d.add(static_cast<std::int64_t>(r.integer));
  }
  return d.value();
}

/// Checksum of the root: scene text and dimension.
std::int64_t checksum(const Checkpoint& ck) {
  Digest d;
  d.add(ck.scene);
  d.add(static_cast<std::int64_t>(ck.dimension));
  return d.value();
}

/// The CRC-64 tables of the polynomial, reflected (bit 0 first).
constexpr std::uint64_t kCrcPolynomial = 0xC96C5795D7870F42ull; // 0x42F0E1EBA9EA3693 reflected

/// vec times the 64 x 64 matrix over GF(2) `mat` (zlib's gf2_matrix_times).
std::uint64_t gf2_times(const std::uint64_t* mat, std::uint64_t vec) {
  std::uint64_t sum = 0;
  for (; vec; vec >>= 1, ++mat)
    if (vec & 1) sum ^= *mat;
  return sum;
}

/// square = mat^2 over GF(2).
void gf2_square(std::uint64_t* square, const std::uint64_t* mat) {
  for (int n = 0; n < 64; ++n) square[n] = gf2_times(mat, mat[n]);
}

// ---------------------------------------------------------------- header

/// The values the header of a checkpoint file holds.
struct Header {
  std::string run_id;
  std::uint64_t size = 0;
  std::uint64_t crc = 0;
};

/// True when a run id can be stored in the header: 1 to kMaxRunId letters, digits, '_' or '-'.
bool storable_run_id(const std::string& id) {
  constexpr std::size_t kMaxRunId = 400;
  return !id.empty() && id.size() <= kMaxRunId &&
         std::all_of(id.begin(), id.end(), [](unsigned char c) { return std::isalnum(c) || c == '_' || c == '-'; });
}

/// The header as it is stored: text lines, padded with NUL to kHeaderBytes.
std::string header_text(const Header& h) {
  if (!storable_run_id(h.run_id))
    throw std::invalid_argument("checkpoint header: run id '" + h.run_id + "' is not 1 to 400 letters, digits, _ or -");
  char crc[kCrcDigits + 1];
  std::snprintf(crc, sizeof crc, "%016llx", static_cast<unsigned long long>(h.crc));
  std::string text = std::string(kFormat) + "\nformat_version " + std::to_string(kFormatVersion) + "\nrun_id " +
                     h.run_id + "\nsize " + std::to_string(h.size) + "\ncrc64 " + crc + "\n";
  text.resize(kHeaderBytes, '\0');
  return text;
}

/// Parses a stored header; false unless it is exactly what header_text writes.
bool parse_header(const std::string& text, Header& h) {
  std::istringstream in(text.substr(0, text.find('\0')));
  std::string line, key;
  std::getline(in, line);
  if (line != kFormat) return false;
  std::int64_t version = 0;
  std::string crc;
  if (!(in >> key >> version) || key != "format_version" || version != kFormatVersion) return false;
  if (!(in >> key >> h.run_id) || key != "run_id") return false;
  if (!(in >> key >> h.size) || key != "size") return false;
  if (!(in >> key >> crc) || key != "crc64" || crc.size() != kCrcDigits) return false;
  if (!storable_run_id(h.run_id) || crc.find_first_not_of("0123456789abcdef") != std::string::npos) return false;
  h.crc = std::stoull(crc, nullptr, 16);
  return header_text(h) == text;
}

/// CRC-64 of the header with the CRC digits replaced by '0' (the value the CRC itself cannot include).
std::uint64_t blank_header_crc(const Header& h) {
  Header blank = h;
  blank.crc = 0;
  const std::string head = header_text(blank);
  return crc64(head.data(), head.size());
}

/// Runs `step` on every rank of `io` and agrees on how it ended
/// (ParallelIo::agree: an error on any rank is thrown on every rank).
template <class Step> void on_all(const ParallelIo& io, Step&& step) {
  if (io.size <= 1 || !io.agree) return step();
  io.agree(step);
}

/// What a stop while a checkpoint is read says (interrupt_point).
constexpr const char* kReading = "reading a checkpoint";

/// CRC-64 of bytes [first, first + count) of an open file; with `polled`
/// (reading a checkpoint, never while writing one) interrupt_point(polled)
/// after each chunk.
std::uint64_t range_crc(std::istream& in, std::uint64_t first, std::uint64_t count, const char* polled) {
  Crc64 crc;
  in.clear();
  in.seekg(static_cast<std::streamoff>(first));
  std::vector<char> buf(kChunkBytes);
  while (in && count > 0) {
    in.read(buf.data(), static_cast<std::streamsize>(std::min<std::uint64_t>(count, buf.size())));
    const auto got = static_cast<std::size_t>(in.gcount());
    crc.process_bytes(buf.data(), got);
    count -= got;
    if (polled) interrupt_point(polled);
  }
  return crc.checksum();
}

/// The part of the file's bytes after the header that rank `rank` of `size` checksums.
std::pair<std::uint64_t, std::uint64_t> crc_part(std::uint64_t file_size, int rank, int size) {
  const std::uint64_t body = file_size > kHeaderBytes ? file_size - kHeaderBytes : 0;
  const auto at = [&](int r) { return kHeaderBytes + body / static_cast<std::uint64_t>(size) * static_cast<std::uint64_t>(r) +
                                      std::min<std::uint64_t>(static_cast<std::uint64_t>(r), body % static_cast<std::uint64_t>(size)); };
  return {at(rank), at(rank + 1) - at(rank)};
}

/// CRC-64 of a whole file of `h.size` bytes whose header is `h` (its CRC
/// left out): the header, then each rank's part (io: every rank checksums
/// its own part and the parts are combined; collective) - every rank gets
/// the same value. `in`: the open file; `polled`: as range_crc (the ranks
/// then agree on a stop).
std::uint64_t file_crc(std::istream& in, const Header& h, const ParallelIo& io, const char* polled) {
  const std::pair<std::uint64_t, std::uint64_t> part = crc_part(h.size, io.rank, io.size);
  const std::uint64_t first = part.first, count = part.second; // named: clang captures no structured binding
  std::uint64_t mine = 0;
  if (polled) on_all(io, [&] { mine = range_crc(in, first, count, polled); });
  else mine = range_crc(in, first, count, nullptr);
  std::vector<std::int64_t> parts{static_cast<std::int64_t>(mine)};
  if (io.size > 1) parts = io.allgather(static_cast<std::int64_t>(mine));
  std::uint64_t crc = blank_header_crc(h);
  for (int r = 0; r < io.size; ++r)
    crc = crc64_combine(crc, static_cast<std::uint64_t>(parts[static_cast<std::size_t>(r)]), crc_part(h.size, r, io.size).second);
  return crc;
}

/// The header of a checkpoint file and its size on disk, checked (InputError naming the file).
Header read_header(std::istream& in, const std::string& path) {
  std::string text(kHeaderBytes, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  Header h;
  if (in.gcount() != static_cast<std::streamsize>(kHeaderBytes) || !parse_header(text, h))
    throw InputError(path + ": not an otmpm checkpoint file of format version " + std::to_string(kFormatVersion) +
                     " (no valid header: not a checkpoint, damaged, or written by an older otmpm)");
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || size != h.size)
    throw InputError(path + ": the checkpoint file has " + std::to_string(ec ? 0 : size) + " bytes but was written with " +
                     std::to_string(h.size) + ": it is truncated or damaged");
  return h;
}

/// The ranks that read `path` together each checksum a part of it: they
/// must read the same file (the same run, step and bytes), or their parts
/// would combine to a false "damaged". InputError naming the first rank whose
/// header differs from rank 0's (a node that sees another file at that path).
void same_file_on_every_rank(const std::string& path, const Header& h, const ParallelIo& io) {
  const std::string mine = header_text(h);
  const bool same = io.broadcast(mine) == mine;
  const std::vector<std::int64_t> all = io.allgather(same ? 1 : 0);
  const auto first = std::find(all.begin(), all.end(), 0);
  if (first == all.end()) return;
  throw InputError("rank " + std::to_string(first - all.begin()) + " reads another checkpoint than rank 0's " +
                   (io.root ? path : std::string("file")) +
                   " (another run, step or copy: its header differs); every rank must restart from the same file");
}

/// Verifies the header, size and CRC of a checkpoint file before HDF5 opens
/// it (io: the ranks that read it together, each checksumming a part);
/// returns the header or throws InputError naming the file.
Header verify_file(const std::string& path, const ParallelIo& io = {}) {
  std::ifstream in(path, std::ios::binary);
  Header h;
  on_all(io, [&] {
    if (!in) throw InputError(path + ": cannot open the checkpoint file");
    h = read_header(in, path);
  });
  if (io.mpi_comm) same_file_on_every_rank(path, h, io);
  if (file_crc(in, h, io, kReading) != h.crc)
    throw InputError(path + ": checksum mismatch: the checkpoint file is damaged (CRC-64 of its bytes)");
  return h;
}

/// Writes the header into the user block of a closed checkpoint file: size
/// and CRC (io: every rank checksums its part; the root writes the header).
void seal_file(const std::string& path, const std::string& run_id, const ParallelIo& io = {}) {
  Header h;
  h.run_id = run_id;
  std::ifstream in;
  on_all(io, [&] {
    std::error_code ec;
    h.size = fs::file_size(path, ec);
    if (ec) throw OutputError(path + ": cannot size the checkpoint: " + ec.message());
    in.open(path, std::ios::binary);
    if (!in) throw OutputError(path + ": cannot reopen the checkpoint to seal it: " + std::strerror(errno));
  });
  h.crc = file_crc(in, h, io, nullptr);
  on_all(io, [&] {
    if (!io.root) return;
    std::fstream out(path, std::ios::binary | std::ios::in | std::ios::out);
    const std::string text = header_text(h);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    if (!out.flush()) throw OutputError(path + ": cannot write the checkpoint header: " + std::strerror(errno));
  });
}

/// Bytes a checkpoint will take, generously (raw data plus HDF5 metadata).
std::uint64_t checkpoint_bytes(const Checkpoint& ck) {
  std::uint64_t bytes = kHeaderBytes + kGroupOverhead + ck.scene.size();
  for (const auto& [name, g] : ck.groups) {
    bytes += kGroupOverhead;
    const std::size_t items = g.reals.size() + g.integers.size() + g.strings.size() + g.real_arrays.size() +
                              g.integer_arrays.size();
    bytes += items * kItemOverhead;
    for (const auto& [k, v] : g.strings) bytes += v.size();
    for (const auto& [k, a] : g.real_arrays) bytes += a.values.size() * sizeof(double);
    for (const auto& [k, a] : g.integer_arrays) bytes += a.values.size() * sizeof(std::int64_t);
  }
  return bytes + bytes / 4;
}

// ---------------------------------------------------------------- the head of a checkpoint, as bytes

/// Appends the bytes of a value, of a string (with its length), of an array.
void pack(std::string& out, const void* data, std::size_t n) { out.append(static_cast<const char*>(data), n); }
template <class T> void pack(std::string& out, const T& v) { pack(out, &v, sizeof v); }
void pack(std::string& out, const std::string& s) {
  pack(out, static_cast<std::uint64_t>(s.size()));
  out += s;
}
template <class T> void pack(std::string& out, const StateArray<T>& a) {
  pack(out, static_cast<std::uint64_t>(a.cols));
  pack(out, static_cast<std::uint64_t>(a.values.size()));
  pack(out, a.values.data(), a.values.size() * sizeof(T));
}

/// Reads back what pack() appended, in order.
class Unpack {
public:
  explicit Unpack(const std::string& in) : in_(in) {}
  void get(void* data, std::size_t n) {
    if (at_ + n > in_.size()) throw std::runtime_error("checkpoint head: truncated message");
    std::memcpy(data, in_.data() + at_, n);
    at_ += n;
  }
  template <class T> T get() {
    T v;
    get(&v, sizeof v);
    return v;
  }
  std::string string() {
    std::string s(get<std::uint64_t>(), '\0');
    get(s.data(), s.size());
    return s;
  }
  template <class T> StateArray<T> array() {
    StateArray<T> a;
    a.cols = get<std::uint64_t>();
    a.values.resize(get<std::uint64_t>());
    get(a.values.data(), a.values.size() * sizeof(T));
    return a;
  }

private:
  const std::string& in_;
  std::size_t at_ = 0;
};

/// Every map entry of `m` whose name `keep` accepts, with its count first.
template <class Map, class Keep> void pack_map(std::string& out, const Map& m, Keep&& keep) {
  std::uint64_t n = 0;
  for (const auto& e : m) n += keep(e.first);
  pack(out, n);
  for (const auto& [name, v] : m)
    if (keep(name)) pack(out, name), pack(out, v);
}

/// The head of `ck` (the root text of the file, every group's scalars and
/// whole arrays) as bytes, and back.
std::string pack_head(const Checkpoint& ck) {
  std::string out;
  pack(out, ck.scene);
  pack(out, ck.run_id);
  pack(out, static_cast<std::int64_t>(ck.dimension));
  pack(out, static_cast<std::uint64_t>(ck.groups.size()));
  for (const auto& [group, g] : ck.groups) {
    const auto all = [](const std::string&) { return true; };
    const auto whole = [&group = group](const std::string& name) {
      return checkpoint_row_kind(group, name) == RowKind::whole;
    };
    pack(out, group);
    pack_map(out, g.reals, all);
    pack_map(out, g.integers, all);
    pack_map(out, g.strings, all);
    pack_map(out, g.real_arrays, whole);
    pack_map(out, g.integer_arrays, whole);
  }
  return out;
}

Checkpoint unpack_head(const std::string& bytes) {
  Unpack in(bytes);
  Checkpoint ck;
  ck.scene = in.string();
  ck.run_id = in.string();
  ck.dimension = static_cast<int>(in.get<std::int64_t>());
  for (auto groups = in.get<std::uint64_t>(); groups > 0; --groups) {
    StateGroup& g = ck.group(in.string());
    // each entry: its name, then its value (read in that order)
    auto entries = [&in](auto& map, auto value) {
      for (auto n = in.get<std::uint64_t>(); n > 0; --n) {
        const std::string name = in.string();
        map[name] = value();
      }
    };
    entries(g.reals, [&in] { return in.get<double>(); });
    entries(g.integers, [&in] { return in.get<std::int64_t>(); });
    entries(g.strings, [&in] { return in.string(); });
    entries(g.real_arrays, [&in] { return in.array<double>(); });
    entries(g.integer_arrays, [&in] { return in.array<std::int64_t>(); });
  }
  return ck;
}

// ---------------------------------------------------------------- writing

/// How a group's arrays are written: whole (a serial file), or by the ranks
/// of a parallel file (`share`: each rank its rows; the root the whole
/// arrays), with the data transfer list `transfer`.
struct Layout {
  const CheckpointShare* share = nullptr;
  hid_t transfer = H5P_DEFAULT;
  /// The rows of all ranks and this rank's blocks of an array of `kind`.
  std::pair<long long, std::vector<RowBlock>> rows(RowKind kind, long long held) const {
    if (!share || kind == RowKind::whole)
      return {held, share && !share->io.root ? std::vector<RowBlock>{} : std::vector<RowBlock>{{0, 1, 1, held}}};
    if (kind == RowKind::particle) return {share->particles, share->particle_rows};
    return {share->points, share->point_rows};
  }
};

template <class T>
void write_array(hid_t group, const std::string& gname, const std::string& name, const StateArray<T>& a,
                 const Layout& layout, const std::string& path) {
  if (!layout.share) return h5::write_matrix(group, name, a.rows(), a.cols, a.values.data(), path);
  const auto [total, blocks] = layout.rows(checkpoint_row_kind(gname, name), static_cast<long long>(a.rows()));
  h5::write_blocks(group, name, static_cast<hsize_t>(total), a.cols, blocks, a.values.data(), layout.transfer, path);
}

void write_group(hid_t file, const std::string& name, const StateGroup& g, const Layout& layout,
                 const std::string& path) {
  const Handle group = h5::create_group(file, name, path);
  const hid_t id = group.get();
  for (const auto& [k, v] : g.reals) h5::write_attribute(id, k, H5T_NATIVE_DOUBLE, &v, path);
  for (const auto& [k, v] : g.integers) h5::write_attribute(id, k, H5T_NATIVE_INT64, &v, path);
  for (const auto& [k, v] : g.strings) h5::write_string_attribute(id, k, v, path);
  for (const auto& [k, a] : g.real_arrays) write_array(id, name, k, a, layout, path);
  for (const auto& [k, a] : g.integer_arrays) write_array(id, name, k, a, layout, path);
  std::function<long long(RowKind)> total; // a parallel file: the rows of all ranks
  if (layout.share) total = [&layout](RowKind kind) { return layout.rows(kind, 0).first; };
  const std::int64_t sum = checksum(name, g, row_shapes(name, g, total));
  h5::write_attribute(id, kChecksum, H5T_NATIVE_INT64, &sum, path);
}

/// fsync()s a closed file so that the rename that follows publishes complete data.
void sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  const bool ok = fd >= 0 && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!ok) throw OutputError(path + ": cannot sync the checkpoint to disk: " + std::strerror(errno));
}

/// Writes the HDF5 content of `ck` (layout: serial, or this rank's share)
/// into the file created at `path` (after its user block for the header).
void write_content(const std::string& path, const Checkpoint& ck, const Layout& layout, const ParallelIo& io) {
  h5::silence();
  // The 1.8 file format, as the result file: attributes above 64 KiB (a long
  // scene); the user block holds the header written by seal_file.
  const Handle fapl(h5::checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  h5::checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  Layout l = layout;
  Handle transfer;
  if (io.mpi_comm) {
    transfer = h5::parallel_access(fapl.get(), io.mpi_comm, path);
    l.transfer = transfer.get();
  }
  const Handle fcpl(h5::checked(H5Pcreate(H5P_FILE_CREATE), path, "create a file creation list"), H5Pclose);
  h5::checked_status(H5Pset_userblock(fcpl.get(), kHeaderBytes), path, "reserve the checkpoint header");
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get());
  // Its location was checked when the run started: failing now is an I/O
  // error (a directory removed meanwhile, a file system gone), not bad input.
  if (id < 0) throw OutputError(path + ": cannot create the checkpoint file: " + std::strerror(errno));
  Handle file(id, H5Fclose);
  if (!io.mpi_comm) h5::reserve_space(h5::file_descriptor(id, path), checkpoint_bytes(ck), path);
  try {
    h5::write_string_attribute(id, "format", kFormat, path);
    const std::int64_t version = kFormatVersion, dimension = ck.dimension, sum = checksum(ck);
    h5::write_attribute(id, "format_version", H5T_NATIVE_INT64, &version, path);
    h5::write_string_attribute(id, "otmpm_version", OTMPM_VERSION, path);
    h5::write_string_attribute(id, "run_id", ck.run_id, path);
    h5::write_attribute(id, "dimension", H5T_NATIVE_INT64, &dimension, path);
    h5::write_string_attribute(id, "scene", ck.scene, path);
    h5::write_attribute(id, kChecksum, H5T_NATIVE_INT64, &sum, path);
    for (const auto& [name, g] : ck.groups) write_group(id, name, g, l, path);
    h5::checked_status(H5Fflush(id, H5F_SCOPE_GLOBAL), path, "flush the file");
    if (!file.close()) h5::fail(path, "close the file");
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const OutputError*>(&e) || dynamic_cast<const InputError*>(&e)) throw;
    h5::output_failure(path, std::string("write the checkpoint (") + e.what() + ")");
  }
}

/// Writes to path.tmp with `write`, then renames it over `path` (on the root);
/// a failed write removes the worthless temporary.
template <class Write> void write_atomically(const std::string& path, const ParallelIo& io, Write&& write) {
  const std::string tmp = path + ".tmp";
  try {
    write(tmp);
  } catch (const OutputError&) {
    std::error_code ec;
    if (io.root) fs::remove(tmp, ec); // the previous checkpoint stays
    throw;
  }
  on_all(io, [&] {
    if (io.root && std::rename(tmp.c_str(), path.c_str()) != 0)
      throw OutputError(path + ": cannot move the checkpoint into place: " + std::strerror(errno));
  });
}

// ---------------------------------------------------------------- reading

void read_attributes(hid_t id, const std::string& name, StateGroup& g, const std::string& path) {
  for (const std::string& a : h5::attribute_names(id, path)) {
    if (a == kChecksum) continue;
    switch (h5::attribute_class(id, a, path)) {
    case H5T_FLOAT: g.reals[a] = h5::read_double(id, a, path); break;
    case H5T_INTEGER: g.integers[a] = h5::read_integer(id, a, path); break;
    case H5T_STRING: g.strings[a] = h5::read_string(id, a, path); break;
    default: h5::fail(path, "read attribute '" + a + "' of group '" + name + "' (unexpected type)");
    }
  }
}

/// Reads the arrays of group `name` into g; with `heads` set, the per-row
/// arrays are not read but their shapes noted there (in row_shapes' order).
void read_arrays(hid_t id, const std::string& name, StateGroup& g, std::vector<RowShape>* heads,
                 const std::string& path) {
  std::vector<RowShape> reals, integers;
  for (const std::string& d : h5::link_names(id, path)) {
    // one process reading the whole file (with `heads`, the ranks of a
    // distributed restart open it together: HDF5's calls must not stop on one)
    if (!heads) interrupt_point(kReading);
    const H5T_class_t cls = h5::dataset_class(id, d, path);
    if (cls != H5T_FLOAT && cls != H5T_INTEGER)
      h5::fail(path, "read dataset '" + d + "' of group '" + name + "' (unexpected type)");
    if (heads && checkpoint_row_kind(name, d) != RowKind::whole) {
      const auto [rows, cols] = h5::dataset_shape(id, d, path);
      (cls == H5T_FLOAT ? reals : integers)
          .push_back({d, static_cast<std::int64_t>(rows), static_cast<std::int64_t>(cols), cls == H5T_INTEGER});
    } else if (cls == H5T_FLOAT) {
      h5::Matrix<double> m = h5::read_double_matrix(id, d, path);
      g.real_arrays[d] = {static_cast<std::size_t>(m.cols), std::move(m.values)};
    } else {
      h5::Matrix<std::int64_t> m = h5::read_integer_matrix(id, d, path);
      g.integer_arrays[d] = {static_cast<std::size_t>(m.cols), std::move(m.values)};
    }
  }
  if (heads) {
    *heads = std::move(reals);
    heads->insert(heads->end(), integers.begin(), integers.end());
  }
}

/// Reads group `name` (without its per-row arrays when `heads` is given:
/// their shapes go there) and checks its checksum.
StateGroup read_group(hid_t file, const std::string& name, std::vector<RowShape>* heads, const std::string& path) {
  StateGroup g;
  g.where = path + ": group '" + name + "'";
  const Handle group = h5::open_group(file, name, path);
  read_attributes(group.get(), name, g, path);
  read_arrays(group.get(), name, g, heads, path);
  const std::vector<RowShape> rows = heads ? *heads : row_shapes(name, g);
  if (!h5::has_attribute(group.get(), kChecksum) || h5::read_integer(group.get(), kChecksum, path) != checksum(name, g, rows))
    g.error("checksum mismatch: the checkpoint file is damaged");
  return g;
}

/// Reads an opened checkpoint file (HDF5 failures propagate as runtime_error);
/// with `heads`, without the per-row arrays (their shapes: heads[group]).
Checkpoint read_root(hid_t file, const std::string& path, std::map<std::string, std::vector<RowShape>>* heads) {
  if (!h5::has_attribute(file, "format") || h5::read_string(file, "format", path) != kFormat)
    throw InputError(path + ": not an otmpm checkpoint file (no format = \"" + kFormat + "\")");
  const std::int64_t version = h5::read_integer(file, "format_version", path);
  if (version != kFormatVersion)
    throw InputError(path + ": checkpoint format version " + std::to_string(version) +
                     " is not supported (this otmpm reads version " + std::to_string(kFormatVersion) + ")");
  Checkpoint ck;
  ck.file = path;
  ck.scene = h5::read_string(file, "scene", path);
  ck.run_id = h5::read_string(file, "run_id", path);
  ck.dimension = static_cast<int>(h5::read_integer(file, "dimension", path));
  if (h5::read_integer(file, kChecksum, path) != checksum(ck))
    throw InputError(path + ": checksum mismatch of the stored scene: the checkpoint file is damaged");
  for (const std::string& name : h5::link_names(file, path))
    ck.groups.emplace(name, read_group(file, name, heads ? &(*heads)[name] : nullptr, path));
  return ck;
}

/// Opens a verified checkpoint file (`fapl`: serial or MPI-IO) and reads it
/// with read_root; every failure an InputError naming the file.
Checkpoint read_verified(const std::string& path, const Header& header, hid_t fapl,
                         std::map<std::string, std::vector<RowShape>>* heads, Handle* keep_open = nullptr) {
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  if (id < 0) throw InputError(path + ": cannot open the checkpoint file (not HDF5, or truncated)");
  Handle file(id, H5Fclose);
  try {
    Checkpoint ck = read_root(id, path, heads);
    if (ck.run_id != header.run_id)
      throw InputError(path + ": the run id of the header and of the file differ: the checkpoint file is damaged");
    if (keep_open) *keep_open = std::move(file);
    return ck;
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw InputError(path + ": damaged checkpoint file: " + e.what());
  }
}

/// InputError unless `path` is a regular file (a FIFO is never opened).
void require_checkpoint_file(const std::string& path) {
  std::error_code ec;
  if (const std::string kind = special_file(path); !kind.empty())
    throw InputError(path + ": is " + kind + ", not a checkpoint file");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a directory, not a checkpoint file");
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": no such checkpoint file");
}

/// read_checkpoint of one process, with or without the per-row arrays.
Checkpoint read_serial(const std::string& path, bool rows) {
  h5::silence();
  require_checkpoint_file(path);
  const Header header = verify_file(path); // before HDF5 parses anything
  std::map<std::string, std::vector<RowShape>> heads;
  return read_verified(path, header, H5P_DEFAULT, rows ? nullptr : &heads);
}

} // namespace

// ---------------------------------------------------------------- files

RowKind checkpoint_row_kind(const std::string& group, const std::string& array) {
  if (group == "particles") return RowKind::particle;
  if (group == "basis")
    for (const char* n : {"lambda", "lambda_slope", "lambda_curvature", "lambda_history", "cell_hint"})
      if (array == n) return RowKind::particle;
  if (group == "nodes" && (array == "x" || array == "absent")) return RowKind::point;
  // the particles' cells of a node reset's lattice (older checkpoints: their F-bar patches)
  if (group == "nodes" && (array == "home_cell" || array == "patch")) return RowKind::particle;
  if (group == "engine" && (array.rfind("wall_held_", 0) == 0 || array.rfind("carried_", 0) == 0)) return RowKind::point;
  return RowKind::whole;
}

std::uint64_t crc64(const void* data, std::size_t n) {
  Crc64 crc;
  crc.process_bytes(data, n);
  return crc.checksum();
}

std::uint64_t crc64_combine(std::uint64_t a, std::uint64_t b, std::uint64_t b_bytes) {
  if (b_bytes == 0) return a;
  std::uint64_t even[64], odd[64]; // operators for 2^k zero bits
  odd[0] = kCrcPolynomial;
  std::uint64_t row = 1;
  for (int n = 1; n < 64; ++n, row <<= 1) odd[n] = row;
  gf2_square(even, odd); // two zero bits
  gf2_square(odd, even); // four
  // append b_bytes zero bytes to a, one bit of the length at a time
  do {
    gf2_square(even, odd);
    if (b_bytes & 1) a = gf2_times(even, a);
    b_bytes >>= 1;
    if (!b_bytes) break;
    gf2_square(odd, even);
    if (b_bytes & 1) a = gf2_times(odd, a);
    b_bytes >>= 1;
  } while (b_bytes);
  return a ^ b;
}

void write_checkpoint_file(const std::string& path, const Checkpoint& ck) {
  const std::string run_id = ck.run_id.empty() ? new_run_id() : ck.run_id; // a Checkpoint built in code
  if (run_id == ck.run_id) {
    write_content(path, ck, {}, {});
  } else {
    Checkpoint named = ck;
    named.run_id = run_id;
    write_content(path, named, {}, {});
  }
  seal_file(path, run_id);
  sync_file(path);
}

void write_checkpoint(const std::string& path, const Checkpoint& ck) {
  write_atomically(path, {}, [&](const std::string& tmp) { write_checkpoint_file(tmp, ck); });
}

void write_checkpoint(const std::string& path, Checkpoint mine, const CheckpointShare& share) {
  const ParallelIo& io = share.io;
  if (!io.mpi_comm) return write_checkpoint(path, mine);
  // The root's scalars and whole arrays on every rank (the collective HDF5
  // calls write the same values everywhere), with this rank's rows (moved:
  // a rank holds its rows once).
  Checkpoint ck = unpack_head(io.broadcast(io.root ? pack_head(mine) : std::string()));
  if (ck.run_id.empty()) ck.run_id = io.broadcast(io.root ? new_run_id() : std::string());
  for (auto& [gname, g] : mine.groups) {
    StateGroup& out = ck.group(gname);
    for (auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) != RowKind::whole) out.real_arrays[name] = std::move(a);
    for (auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) != RowKind::whole) out.integer_arrays[name] = std::move(a);
  }
  write_atomically(path, io, [&](const std::string& tmp) {
    on_all(io, [&] { write_content(tmp, ck, Layout{&share}, io); });
    seal_file(tmp, ck.run_id, io);
    on_all(io, [&] {
      if (io.root) sync_file(tmp);
    });
  });
}

Checkpoint read_checkpoint(const std::string& path) { return read_serial(path, true); }

Checkpoint read_checkpoint_head(const std::string& path) { return read_serial(path, false); }

std::string checkpoint_run_id(const std::string& path) {
  if (!special_file(path).empty()) return ""; // never open a FIFO
  std::ifstream in(path, std::ios::binary);
  std::string text(kHeaderBytes, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  Header h;
  return in.gcount() == static_cast<std::streamsize>(kHeaderBytes) && parse_header(text, h) ? h.run_id : "";
}

// ---------------------------------------------------------------- read by all ranks

struct CheckpointFile::Impl {
  std::string path;
  Handle file, transfer;
  std::map<std::string, std::vector<RowShape>> arrays; ///< per group: its per-row arrays
};

CheckpointFile::CheckpointFile(const std::string& path, const ParallelIo& io) : impl_(std::make_unique<Impl>()) {
  h5::silence();
  impl_->path = path;
  on_all(io, [&] { require_checkpoint_file(path); });
  const Header header = verify_file(path, io); // before HDF5 parses anything
  const Handle fapl(h5::checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  if (io.mpi_comm) impl_->transfer = h5::parallel_access(fapl.get(), io.mpi_comm, path);
  head_ = read_verified(path, header, fapl.get(), &impl_->arrays, &impl_->file);
}

CheckpointFile::~CheckpointFile() = default;

long long CheckpointFile::rows(RowKind kind) const {
  for (const auto& [group, shapes] : impl_->arrays)
    for (const RowShape& r : shapes)
      if (checkpoint_row_kind(group, r.name) == kind) return r.rows;
  return 0;
}

void CheckpointFile::read(RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into) const {
  read(kind, blocks, into, {});
}

void CheckpointFile::read(RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into,
                          const std::vector<std::string>& names) const {
  const std::string& path = impl_->path;
  const hid_t transfer = impl_->transfer.valid() ? impl_->transfer.get() : H5P_DEFAULT;
  const auto rows = static_cast<std::size_t>(block_rows(blocks));
  try {
    for (const auto& [gname, shapes] : impl_->arrays) {
      const Handle group = h5::open_group(impl_->file.get(), gname, path);
      for (const RowShape& r : shapes) {
        if (checkpoint_row_kind(gname, r.name) != kind) continue;
        if (!names.empty() && std::find(names.begin(), names.end(), gname + "/" + r.name) == names.end()) continue;
        StateGroup& g = into.group(gname);
        const auto cols = static_cast<std::size_t>(r.cols);
        if (r.integer) {
          StateArray<std::int64_t>& a = g.integer_arrays[r.name];
          a = {cols, std::vector<std::int64_t>(rows * cols)};
          h5::read_blocks(group.get(), r.name, cols, blocks, a.values.data(), transfer, path);
        } else {
          StateArray<double>& a = g.real_arrays[r.name];
          a = {cols, std::vector<double>(rows * cols)};
          h5::read_blocks(group.get(), r.name, cols, blocks, a.values.data(), transfer, path);
        }
      }
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw InputError(path + ": damaged checkpoint file: " + e.what());
  }
}

long long checkpoint_rows(const Checkpoint& ck, RowKind kind) {
  if (ck.source) return ck.source->rows(kind);
  for (const auto& [gname, g] : ck.groups)
    for (const auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == kind) return static_cast<long long>(a.rows());
  for (const auto& [gname, g] : ck.groups)
    for (const auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == kind) return static_cast<long long>(a.rows());
  return 0;
}

namespace {
/// The rows `blocks` of an array in memory (InputError naming it when it is too short).
template <class T>
StateArray<T> block_values(const StateGroup& g, const std::string& name, const StateArray<T>& a,
                           const std::vector<RowBlock>& blocks) {
  StateArray<T> out;
  out.cols = a.cols;
  out.values.reserve(static_cast<std::size_t>(block_rows(blocks)) * a.cols);
  for (const RowBlock& b : blocks)
    for (long long i = 0; i < b.count; ++i) {
      const auto first = static_cast<std::size_t>(b.first + i * b.stride) * a.cols;
      const auto n = static_cast<std::size_t>(b.block) * a.cols;
      if (first + n > a.values.size()) g.error("array '" + name + "' has no row " + std::to_string(first / a.cols + n / a.cols - 1));
      out.values.insert(out.values.end(), a.values.begin() + static_cast<std::ptrdiff_t>(first),
                        a.values.begin() + static_cast<std::ptrdiff_t>(first + n));
    }
  return out;
}
} // namespace

void read_checkpoint_rows(const Checkpoint& ck, RowKind kind, const std::vector<RowBlock>& blocks, Checkpoint& into,
                          const std::vector<std::string>& names) {
  if (ck.source) return ck.source->read(kind, blocks, into, names);
  for (const auto& entry : ck.groups) { // no structured binding: clang does not capture one in a lambda
    const std::string& gname = entry.first;
    const StateGroup& g = entry.second;
    auto copy = [&](const auto& arrays, auto& out) {
      for (const auto& [name, a] : arrays)
        if (checkpoint_row_kind(gname, name) == kind &&
            (names.empty() || std::find(names.begin(), names.end(), gname + "/" + name) != names.end()))
          out[name] = block_values(g, name, a, blocks);
    };
    copy(g.real_arrays, into.group(gname).real_arrays);
    copy(g.integer_arrays, into.group(gname).integer_arrays);
  }
}

Checkpoint checkpoint_head(const Checkpoint& ck) {
  Checkpoint head;
  head.file = ck.file, head.scene = ck.scene, head.run_id = ck.run_id, head.dimension = ck.dimension;
  for (const auto& [gname, g] : ck.groups) {
    StateGroup& out = head.groups[gname];
    out.where = g.where, out.reals = g.reals, out.integers = g.integers, out.strings = g.strings;
    for (const auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::whole) out.real_arrays[name] = a;
    for (const auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::whole) out.integer_arrays[name] = a;
  }
  return head;
}

void order_by_global_id(Checkpoint& ck) {
  const auto particles = ck.groups.find("particles");
  if (particles == ck.groups.end()) return;
  const auto ids = particles->second.integer_arrays.find("global_id");
  if (ids == particles->second.integer_arrays.end()) return;
  const std::vector<std::int64_t>& id = ids->second.values;
  std::vector<std::size_t> order(id.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&id](std::size_t a, std::size_t b) { return id[a] < id[b]; });
  if (std::is_sorted(order.begin(), order.end())) return;
  auto permute = [&order](auto& a) {
    auto values = a.values;
    for (std::size_t i = 0; i < order.size(); ++i)
      std::copy_n(values.begin() + static_cast<std::ptrdiff_t>(order[i] * a.cols), a.cols,
                  a.values.begin() + static_cast<std::ptrdiff_t>(i * a.cols));
  };
  for (auto& [gname, g] : ck.groups) {
    for (auto& [name, a] : g.real_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle && a.rows() == order.size()) permute(a);
    for (auto& [name, a] : g.integer_arrays)
      if (checkpoint_row_kind(gname, name) == RowKind::particle && a.rows() == order.size()) permute(a);
  }
}

Checkpoint open_checkpoint(const std::string& path, const ParallelIo& io) {
  auto file = std::make_shared<const CheckpointFile>(path, io);
  Checkpoint ck = file->head();
  ck.source = std::move(file);
  return ck;
}

} // namespace otmpm
