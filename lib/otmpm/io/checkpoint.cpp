// Checkpoint files (see checkpoint.hpp): the in-memory state groups, their
// HDF5 form with a checksum per group, the atomic write and the reader that
// turns every defect of a file into an InputError naming it.
#include "otmpm/io/checkpoint.hpp"

#include "otmpm/core.hpp"
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
#include <sstream>

namespace otmpm {

namespace fs = std::filesystem;
using h5::Handle;

namespace {

constexpr const char* kFormat = "otmpm checkpoint";
/// 2: the header with the file's size and CRC-64 in the HDF5 user block, and the run id.
/// 3: the energy friction dissipated and explicit_alpha's carried constraint momenta.
constexpr std::int64_t kFormatVersion = 3;
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

/// Checksum of everything in a group.
std::int64_t checksum(const StateGroup& g) {
  Digest d;
  d.add_all(g.reals);
  d.add_all(g.integers);
  d.add_all(g.strings);
  d.add_all(g.real_arrays);
  d.add_all(g.integer_arrays);
  return d.value();
}

/// Checksum of the root: scene text and dimension.
std::int64_t checksum(const Checkpoint& ck) {
  Digest d;
  d.add(ck.scene);
  d.add(static_cast<std::int64_t>(ck.dimension));
  return d.value();
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

/// CRC-64 of an open file whose first kHeaderBytes are `header` with the CRC
/// digits replaced by '0' (the value the CRC itself cannot include).
std::uint64_t file_crc(std::istream& in, const Header& h) {
  Crc64 crc;
  Header blank = h;
  blank.crc = 0;
  const std::string head = header_text(blank);
  crc.process_bytes(head.data(), head.size());
  in.seekg(static_cast<std::streamoff>(kHeaderBytes));
  std::vector<char> buf(kChunkBytes);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    crc.process_bytes(buf.data(), static_cast<std::size_t>(in.gcount()));
  }
  return crc.checksum();
}

/// Verifies the header, size and CRC of a checkpoint file before HDF5 opens
/// it; returns the header or throws InputError naming the file.
Header verify_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the checkpoint file");
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
  if (file_crc(in, h) != h.crc)
    throw InputError(path + ": checksum mismatch: the checkpoint file is damaged (CRC-64 of its bytes)");
  return h;
}

/// Writes the header into the user block of a closed checkpoint file: size and CRC.
void seal_file(const std::string& path, const std::string& run_id) {
  Header h;
  h.run_id = run_id;
  std::error_code ec;
  h.size = fs::file_size(path, ec);
  if (ec) throw OutputError(path + ": cannot size the checkpoint: " + ec.message());
  std::fstream io(path, std::ios::binary | std::ios::in | std::ios::out);
  if (!io) throw OutputError(path + ": cannot reopen the checkpoint to seal it: " + std::strerror(errno));
  h.crc = file_crc(io, h);
  io.clear();
  io.seekp(0);
  const std::string text = header_text(h);
  io.write(text.data(), static_cast<std::streamsize>(text.size()));
  if (!io.flush()) throw OutputError(path + ": cannot write the checkpoint header: " + std::strerror(errno));
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

// ---------------------------------------------------------------- writing

void write_group(hid_t file, const std::string& name, const StateGroup& g, const std::string& path) {
  const Handle group = h5::create_group(file, name, path);
  const hid_t id = group.get();
  for (const auto& [k, v] : g.reals) h5::write_attribute(id, k, H5T_NATIVE_DOUBLE, &v, path);
  for (const auto& [k, v] : g.integers) h5::write_attribute(id, k, H5T_NATIVE_INT64, &v, path);
  for (const auto& [k, v] : g.strings) h5::write_string_attribute(id, k, v, path);
  for (const auto& [k, a] : g.real_arrays) h5::write_matrix(id, k, a.rows(), a.cols, a.values.data(), path);
  for (const auto& [k, a] : g.integer_arrays) h5::write_matrix(id, k, a.rows(), a.cols, a.values.data(), path);
  const std::int64_t sum = checksum(g);
  h5::write_attribute(id, kChecksum, H5T_NATIVE_INT64, &sum, path);
}

/// fsync()s a closed file so that the rename that follows publishes complete data.
void sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  const bool ok = fd >= 0 && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!ok) throw OutputError(path + ": cannot sync the checkpoint to disk: " + std::strerror(errno));
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

void read_arrays(hid_t id, const std::string& name, StateGroup& g, const std::string& path) {
  for (const std::string& d : h5::link_names(id, path)) {
    const H5T_class_t cls = h5::dataset_class(id, d, path);
    if (cls == H5T_FLOAT) {
      h5::Matrix<double> m = h5::read_double_matrix(id, d, path);
      g.real_arrays[d] = {static_cast<std::size_t>(m.cols), std::move(m.values)};
    } else if (cls == H5T_INTEGER) {
      h5::Matrix<std::int64_t> m = h5::read_integer_matrix(id, d, path);
      g.integer_arrays[d] = {static_cast<std::size_t>(m.cols), std::move(m.values)};
    } else {
      h5::fail(path, "read dataset '" + d + "' of group '" + name + "' (unexpected type)");
    }
  }
}

StateGroup read_group(hid_t file, const std::string& name, const std::string& path) {
  StateGroup g;
  g.where = path + ": group '" + name + "'";
  const Handle group = h5::open_group(file, name, path);
  read_attributes(group.get(), name, g, path);
  read_arrays(group.get(), name, g, path);
  if (!h5::has_attribute(group.get(), kChecksum) || h5::read_integer(group.get(), kChecksum, path) != checksum(g))
    g.error("checksum mismatch: the checkpoint file is damaged");
  return g;
}

/// Reads an opened checkpoint file (HDF5 failures propagate as runtime_error).
Checkpoint read_root(hid_t file, const std::string& path) {
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
  for (const std::string& name : h5::link_names(file, path)) ck.groups.emplace(name, read_group(file, name, path));
  return ck;
}

} // namespace

// ---------------------------------------------------------------- files

void write_checkpoint_file(const std::string& path, const Checkpoint& ck) {
  h5::silence();
  const std::string run_id = ck.run_id.empty() ? new_run_id() : ck.run_id; // a Checkpoint built in code
  // The 1.8 file format, as the result file: attributes above 64 KiB (a long
  // scene); the user block holds the header written by seal_file.
  const Handle fapl(h5::checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  h5::checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  const Handle fcpl(h5::checked(H5Pcreate(H5P_FILE_CREATE), path, "create a file creation list"), H5Pclose);
  h5::checked_status(H5Pset_userblock(fcpl.get(), kHeaderBytes), path, "reserve the checkpoint header");
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get());
  // Its location was checked when the run started: failing now is an I/O
  // error (a directory removed meanwhile, a file system gone), not bad input.
  if (id < 0) throw OutputError(path + ": cannot create the checkpoint file: " + std::strerror(errno));
  Handle file(id, H5Fclose);
  h5::reserve_space(h5::file_descriptor(id, path), checkpoint_bytes(ck), path);
  try {
    h5::write_string_attribute(id, "format", kFormat, path);
    const std::int64_t version = kFormatVersion, dimension = ck.dimension, sum = checksum(ck);
    h5::write_attribute(id, "format_version", H5T_NATIVE_INT64, &version, path);
    h5::write_string_attribute(id, "otmpm_version", OTMPM_VERSION, path);
    h5::write_string_attribute(id, "run_id", run_id, path);
    h5::write_attribute(id, "dimension", H5T_NATIVE_INT64, &dimension, path);
    h5::write_string_attribute(id, "scene", ck.scene, path);
    h5::write_attribute(id, kChecksum, H5T_NATIVE_INT64, &sum, path);
    for (const auto& [name, g] : ck.groups) write_group(id, name, g, path);
    h5::checked_status(H5Fflush(id, H5F_SCOPE_GLOBAL), path, "flush the file");
    if (!file.close()) h5::fail(path, "close the file");
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const OutputError*>(&e) || dynamic_cast<const InputError*>(&e)) throw;
    h5::output_failure(path, std::string("write the checkpoint (") + e.what() + ")");
  }
  seal_file(path, run_id);
  sync_file(path);
}

void write_checkpoint(const std::string& path, const Checkpoint& ck) {
  const std::string tmp = path + ".tmp";
  try {
    write_checkpoint_file(tmp, ck);
  } catch (const OutputError&) {
    std::error_code ec;
    fs::remove(tmp, ec); // a partial temporary is worthless; the previous checkpoint stays
    throw;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw OutputError(path + ": cannot move the checkpoint into place: " + std::strerror(errno));
}

Checkpoint read_checkpoint(const std::string& path) {
  h5::silence();
  std::error_code ec;
  if (const std::string kind = special_file(path); !kind.empty())
    throw InputError(path + ": is " + kind + ", not a checkpoint file");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a directory, not a checkpoint file");
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": no such checkpoint file");
  const Header header = verify_file(path); // before HDF5 parses anything
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw InputError(path + ": cannot open the checkpoint file (not HDF5, or truncated)");
  const Handle file(id, H5Fclose);
  try {
    Checkpoint ck = read_root(id, path);
    if (ck.run_id != header.run_id)
      throw InputError(path + ": the run id of the header and of the file differ: the checkpoint file is damaged");
    return ck;
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw InputError(path + ": damaged checkpoint file: " + e.what());
  }
}

std::string checkpoint_run_id(const std::string& path) {
  if (!special_file(path).empty()) return ""; // never open a FIFO
  std::ifstream in(path, std::ios::binary);
  std::string text(kHeaderBytes, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  Header h;
  return in.gcount() == static_cast<std::streamsize>(kHeaderBytes) && parse_header(text, h) ? h.run_id : "";
}

} // namespace otmpm
