// Checkpoint files (see checkpoint.hpp): the in-memory state groups, their
// HDF5 form with a checksum per group, the atomic write and the reader that
// turns every defect of a file into an InputError naming it.
#include "otmpm/io/checkpoint.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/hdf5.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace otmpm {

namespace fs = std::filesystem;
using h5::Handle;

namespace {

constexpr const char* kFormat = "otmpm checkpoint";
constexpr std::int64_t kFormatVersion = 1;
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
  if (!ok) throw std::runtime_error(path + ": cannot sync the checkpoint to disk: " + std::strerror(errno));
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
  // The 1.8 file format, as the result file: attributes above 64 KiB (a long scene).
  const Handle fapl(h5::checked(H5Pcreate(H5P_FILE_ACCESS), path, "create a file access list"), H5Pclose);
  h5::checked_status(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), path, "set the file format");
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (id < 0) throw InputError(path + ": cannot create the checkpoint file");
  Handle file(id, H5Fclose);
  h5::write_string_attribute(id, "format", kFormat, path);
  const std::int64_t version = kFormatVersion, dimension = ck.dimension, sum = checksum(ck);
  h5::write_attribute(id, "format_version", H5T_NATIVE_INT64, &version, path);
  h5::write_string_attribute(id, "otmpm_version", OTMPM_VERSION, path);
  h5::write_attribute(id, "dimension", H5T_NATIVE_INT64, &dimension, path);
  h5::write_string_attribute(id, "scene", ck.scene, path);
  h5::write_attribute(id, kChecksum, H5T_NATIVE_INT64, &sum, path);
  for (const auto& [name, g] : ck.groups) write_group(id, name, g, path);
  h5::checked_status(H5Fflush(id, H5F_SCOPE_GLOBAL), path, "flush the file");
  if (!file.close()) h5::fail(path, "close the file");
  sync_file(path);
}

void write_checkpoint(const std::string& path, const Checkpoint& ck) {
  const std::string tmp = path + ".tmp";
  write_checkpoint_file(tmp, ck);
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw std::runtime_error(path + ": cannot move the checkpoint into place: " + std::strerror(errno));
}

Checkpoint read_checkpoint(const std::string& path) {
  h5::silence();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": no such checkpoint file");
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw InputError(path + ": cannot open the checkpoint file (not HDF5, or truncated)");
  const Handle file(id, H5Fclose);
  try {
    return read_root(id, path);
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw InputError(path + ": damaged checkpoint file: " + e.what());
  }
}

} // namespace otmpm
