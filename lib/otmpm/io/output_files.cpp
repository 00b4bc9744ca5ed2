// The files of one run: their names, collisions, otmpm's locks and the rules
// for replacing existing files (see output_files.hpp).
#include "otmpm/io/output_files.hpp"

#include "otmpm/core.hpp"
#include "otmpm/io/checkpoint.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/text_files.hpp"
#include "otmpm/io/undo_journal.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <climits>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string_view>

namespace otmpm {

namespace fs = std::filesystem;

namespace {

/// Extensions a result file may not have: the names of the files beside it.
constexpr std::array<const char*, 5> kReservedExtensions = {".xdmf", ".xmf", ".pvd", ".vtp", ".vtu"};
/// How much of an XML output is searched for its run id (it is on the first lines).
constexpr std::size_t kRunIdSearchBytes = 4096;
/// Attempts at taking a lock whose file another process removed meanwhile.
constexpr int kLockAttempts = 8;
/// Longest host name recorded in a lock file.
constexpr std::size_t kHostNameLength = 256;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

/// True when something (a file, a directory, a dangling symbolic link) is at `path`.
bool occupied(const std::string& path) {
  std::error_code ec;
  return fs::symlink_status(path, ec).type() != fs::file_type::not_found && !ec;
}

bool is_directory(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

/// A path as a message shows it: control characters as \\xHH, at most about kQuotedTextBytes.
std::string shown(const std::string& path) { return shortened(text::printable(path)); }

std::string quoted(const std::string& path) { return "'" + shown(path) + "'"; }

/// Why `result` (its file name `name`) cannot name a result file, or "": a
/// control character anywhere (NUL would end the path the system sees), and
/// in the name a ':' (the XDMF sidecar refers to datasets as NAME:PATH) or
/// text that is not UTF-8 - the sidecar and the VTK files, XML, quote the name.
std::string unusable_result_name(const std::string& result, const std::string& name) {
  if (const std::string c = text::control_character(result); !c.empty()) return "the result path contains " + c;
  if (name.find(':') != std::string::npos)
    return "the result file's name contains ':', which its XDMF sidecar cannot refer to (it names the datasets as "
           "FILE:PATH)";
  if (!text::valid_utf8(name)) return "the result file's name is not UTF-8 text, which its XML sidecar must quote";
  return "";
}

/// " (ORIGIN)" or "".
std::string from(const std::string& origin) { return origin.empty() ? "" : " (" + origin + ")"; }

/// How to replace a file anyway: the sentence every refusal ends with.
std::string how_to_replace() {
  return "; otmpm replaces it only when told to (otmpm run --force, RunOptions::force) - or move it away";
}

} // namespace

std::string output_base(const std::string& result) {
  const std::string ext = ".h5";
  return result.size() > ext.size() && result.ends_with(ext) ? result.substr(0, result.size() - ext.size()) : result;
}

std::string xdmf_path(const std::string& result) { return output_base(result) + ".xdmf"; }

std::string default_checkpoint_path(const std::string& result) { return output_base(result) + ".checkpoint.h5"; }

namespace {

/// InputError when the file name of `path` (the `role` of the run's files)
/// is longer than its directory's file system allows (NAME_MAX, 255 bytes
/// on Linux, when the directory does not exist yet): the run would create
/// nothing, so `run --check` must refuse it too.
void check_name_length(const std::string& path, const std::string& role) {
  const fs::path p(path);
  const std::string name = p.filename().string();
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  long limit = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  if (limit <= 0) limit = NAME_MAX;
  if (name.size() > static_cast<std::size_t>(limit))
    throw InputError(shown(path) + ": the file name of the " + role + " is " + std::to_string(name.size()) +
                     " bytes long; the file system allows at most " + std::to_string(limit) +
                     " - choose a shorter name - nothing was written");
}

} // namespace

OutputFiles output_files(const std::string& result, const std::string& checkpoint, const std::string& vtk_format) {
  require(!result.empty(), "the result file path is empty");
  require(vtk_format.empty() || vtk_format == "vtp" || vtk_format == "vtu", "output_files: VTK format '", vtk_format,
          "' is not \"vtp\" or \"vtu\"");
  const std::string ext = lower(fs::path(result).extension().string());
  for (const char* reserved : kReservedExtensions)
    if (ext == reserved)
      throw InputError(result + ": the result file is HDF5 and may not end in " + reserved +
                       " (that extension is for the files otmpm writes beside the result file: the XDMF sidecar, "
                       "the VTK files); name it " +
                       fs::path(result).replace_extension(".h5").string() + " - nothing was written");
  if (ext == ".png" || ext == ".gif")
    throw InputError(shown(result) + ": the result file is HDF5 and may not end in " + ext +
                     " (the pictures otmpm render writes: rendering it to a picture of its own name would replace "
                     "it); name it " + fs::path(result).replace_extension(".h5").string() + " - nothing was written");
  const std::string name = fs::path(result).filename().string();
  if (name.empty() || name == "." || name == ".." || is_directory(result))
    throw InputError(shown(result) + ": the result file path names a directory");
  if (const std::string why = unusable_result_name(result, name); !why.empty())
    throw InputError(shown(result) + ": " + why + "; choose another name - nothing was written");
  OutputFiles f;
  f.result = result;
  f.xdmf = xdmf_path(result);
  f.checkpoint = checkpoint;
  if (!vtk_format.empty()) {
    f.pvd = output_base(result) + ".pvd";
    f.vtk_dir = output_base(result) + "_vtk";
    f.vtk_extension = vtk_format;
  }
  for (const auto& [role, path] : written_paths(f)) {
    if (const std::string kind = special_file(path); !kind.empty())
      throw InputError(shown(path) + ": the " + role + " is " + kind +
                       ", not a regular file (otmpm writes only regular files); choose another name - nothing was "
                       "written");
    check_name_length(path, role);
  }
  return f;
}

std::vector<std::pair<std::string, std::string>> written_paths(const OutputFiles& f) {
  std::vector<std::pair<std::string, std::string>> out;
  auto add = [&](const std::string& role, const std::string& path, bool temporary) {
    if (path.empty()) return;
    out.emplace_back(role, path);
    out.emplace_back("lock file of the " + role, lock_path(path));
    if (temporary) out.emplace_back("temporary of the " + role, path + ".tmp");
  };
  add("result file", f.result, true);
  if (!f.result.empty()) out.emplace_back("undo journal of the result file", undo_journal_path(f.result));
  add("XDMF sidecar", f.xdmf, true);
  add("checkpoint", f.checkpoint, true);
  add("VTK collection", f.pvd, true);
  if (!f.vtk_dir.empty()) out.emplace_back("VTK frame directory", f.vtk_dir);
  return out;
}

namespace {

/// `path` absolute, with symbolic links resolved - also a link whose target
/// does not exist yet (weakly_canonical leaves such a link unresolved).
fs::path resolve(const std::string& path) {
  constexpr int kMaxLinks = 40; // as the kernel's ELOOP limit
  std::error_code ec;
  fs::path p = fs::absolute(path, ec);
  for (int i = 0; i < kMaxLinks && fs::is_symlink(p, ec); ++i) {
    const fs::path target = fs::read_symlink(p, ec);
    if (ec) break;
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  const fs::path c = fs::weakly_canonical(p, ec);
  return ec ? p.lexically_normal() : c;
}

} // namespace

std::string special_file(const std::string& path) {
  std::error_code ec;
  switch (fs::status(path, ec).type()) { // links followed
  case fs::file_type::fifo: return "a FIFO (named pipe)";
  case fs::file_type::character: return "a character device";
  case fs::file_type::block: return "a block device";
  case fs::file_type::socket: return "a socket";
  default: return "";
  }
}

bool same_file(const std::string& a, const std::string& b) {
  if (resolve(a) == resolve(b)) return true;
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

namespace {

/// True when `path` lies strictly inside directory `dir` (both resolved).
bool inside(const std::string& path, const std::string& dir) {
  const fs::path p = resolve(path), d = resolve(dir);
  auto pi = p.begin();
  for (auto di = d.begin(); di != d.end(); ++di, ++pi)
    if (pi == p.end() || *pi != *di) return false;
  return pi != p.end();
}

/// Where a path came from: the checkpoint's paths from the checkpoint's origin, the rest from the result's.
std::string origin_of(const OutputFiles& f, const std::string& role) {
  return role.find("checkpoint") != std::string::npos ? f.checkpoint_origin : f.result_origin;
}

} // namespace

void check_distinct(const OutputFiles& f) {
  const auto paths = written_paths(f);
  for (std::size_t i = 0; i < paths.size(); ++i)
    for (std::size_t j = i + 1; j < paths.size(); ++j) {
      const auto& [role_a, a] = paths[i];
      const auto& [role_b, b] = paths[j];
      const bool clash = same_file(a, b) || (!f.vtk_dir.empty() && (a == f.vtk_dir ? inside(b, a) : b == f.vtk_dir && inside(a, b)));
      if (clash)
        throw InputError("the " + role_a + " " + quoted(a) + from(origin_of(f, role_a)) + " and the " + role_b + " " +
                         quoted(b) + from(origin_of(f, role_b)) + " are the same file (" + resolve(a).string() +
                         "): nothing was written; choose different names");
    }
}

// ---------------------------------------------------------------- locks

namespace {

/// DIR/.NAME<suffix> for `path` made absolute with its symlinks followed:
/// one file however the path is spelt (relative, absolute, a symlink).
std::string hidden_beside(const std::string& path, const char* suffix) {
  const fs::path p = resolve(path);
  return (p.parent_path() / ("." + p.filename().string() + suffix)).string();
}

} // namespace

std::string lock_path(const std::string& path) { return hidden_beside(path, ".otmpm-lock"); }

std::string undo_journal_path(const std::string& path) { return hidden_beside(path, ".otmpm-undo"); }

namespace {

/// The holder recorded in a lock file: "process PID on host HOST", or "another process".
std::string lock_holder(int fd) {
  char buf[kHostNameLength + 64] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  std::string text(buf, n > 0 ? static_cast<std::size_t>(n) : 0);
  const auto nl = text.find('\n');
  if (nl != std::string::npos) text.resize(nl);
  const auto space = text.find(' ');
  if (text.empty() || space == std::string::npos) return "another process";
  return "process " + text.substr(0, space) + " on host " + text.substr(space + 1);
}

/// Records this process in a lock file it holds.
void record_holder(int fd) {
  char host[kHostNameLength] = {};
  if (::gethostname(host, sizeof host - 1) != 0) std::strcpy(host, "?");
  const std::string line = std::to_string(::getpid()) + " " + host + "\n";
  if (::ftruncate(fd, 0) == 0 && ::pwrite(fd, line.data(), line.size(), 0) < 0) {
    // The holder is only informative; the lock itself is held.
  }
}

/// True when the open file `fd` is still the file at `path` (not removed by its previous holder).
bool still_linked(int fd, const std::string& path) {
  struct stat by_fd {}, by_path {};
  return ::fstat(fd, &by_fd) == 0 && ::stat(path.c_str(), &by_path) == 0 && by_fd.st_dev == by_path.st_dev &&
         by_fd.st_ino == by_path.st_ino;
}

/// Takes the lock of `path`; returns the lock file's descriptor or throws InputError.
int take_lock(const std::string& path) {
  const std::string file = lock_path(path);
  for (int attempt = 0; attempt < kLockAttempts; ++attempt) {
    const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
      throw InputError(path + ": cannot create otmpm's lock file " + file + ": " + std::strerror(errno) +
                       " (does the directory exist, and may this process write in it?)");
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      const std::string holder = lock_holder(fd);
      ::close(fd);
      if (err == EWOULDBLOCK)
        throw InputError(path + ": is being written by " + holder + " (otmpm's lock file " + file +
                         "); nothing was changed - wait for that run to end or stop it");
      throw InputError(path + ": cannot lock " + file + ": " + std::strerror(err));
    }
    if (still_linked(fd, file)) {
      record_holder(fd);
      try {
        h5::apply_undo_journal(path); // a killed writer's interrupted flush, undone before anyone reads
      } catch (...) {
        ::close(fd);
        throw;
      }
      return fd;
    }
    ::close(fd); // its holder removed it between our open and our flock: take the new one
  }
  throw InputError(path + ": cannot take otmpm's lock " + file + " (it keeps being replaced)");
}

} // namespace

std::string lock_holder_of(const std::string& path) {
  const int fd = ::open(lock_path(path).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return "";
  const bool held = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  const std::string holder = held ? lock_holder(fd) : "";
  ::close(fd); // also ends the shared lock taken to test it
  return holder;
}

OutputLock::OutputLock(const std::vector<std::string>& paths) {
  try {
    for (const std::string& p : paths) {
      // The same file under another name (./r.h5, /abs/r.h5, through a linked directory) is held already.
      const bool again =
          std::any_of(held_.begin(), held_.end(), [&](const Held& h) { return same_file(h.path, lock_path(p)); });
      if (p.empty() || again) continue;
      const int fd = take_lock(p);
      held_.push_back({lock_path(p), fd});
    }
  } catch (...) {
    release();
    throw;
  }
}

OutputLock::~OutputLock() { release(); }

OutputLock::OutputLock(OutputLock&& other) noexcept : held_(std::move(other.held_)) { other.held_.clear(); }

OutputLock& OutputLock::operator=(OutputLock&& other) noexcept {
  if (this != &other) {
    release();
    held_ = std::move(other.held_);
    other.held_.clear();
  }
  return *this;
}

void OutputLock::release() noexcept {
  // Removed while still locked: a process that opened the file meanwhile
  // finds it unlinked once it gets the lock and takes a new one (take_lock).
  for (const Held& h : held_) {
    ::unlink(h.path.c_str());
    ::close(h.fd);
  }
  held_.clear();
}

// ---------------------------------------------------------------- run ids

std::string new_run_id() {
  std::random_device rd;
  std::string id;
  constexpr const char* hex = "0123456789abcdef";
  for (int word = 0; word < 4; ++word) {
    std::uint32_t bits = rd();
    for (int k = 0; k < 8; ++k, bits >>= 4) id += hex[bits & 0xfu];
  }
  return id;
}

namespace {

/// `v` with the entities xml_escape writes (&amp; &lt; &gt; &quot;) replaced by their characters.
std::string xml_unescape(std::string_view v) {
  constexpr std::array<std::pair<std::string_view, char>, 4> kEntities = {
      {{"&amp;", '&'}, {"&lt;", '<'}, {"&gt;", '>'}, {"&quot;", '"'}}};
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    bool replaced = false;
    for (const auto& [entity, c] : kEntities)
      if (v.substr(i, entity.size()) == entity) {
        out += c;
        i += entity.size() - 1;
        replaced = true;
        break;
      }
    if (!replaced) out += v[i];
  }
  return out;
}

/// The first value V for which `accept(V)` holds of `KEY="V"` (the VTKFile
/// attributes of otmpm's VTK outputs), `<Information Name="KEY" Value="V"/>`
/// (the XDMF sidecar) or `KEY Value="V"` (the comment of VTK outputs of
/// otmpm before the attributes) in the first kRunIdSearchBytes of an XML
/// file, unescaped; "" when there is none. (Plain string search: GCC 12's
/// std::regex does not compile warning-free under the sanitizers.)
std::string xml_mark(const std::string& path, const std::string& key, bool (*accept)(std::string_view)) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return ""; // a FIFO would block the read
  std::ifstream in(path, std::ios::binary);
  std::string head(kRunIdSearchBytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  const std::string_view text = head;
  for (std::size_t at = text.find(key); at != std::string_view::npos; at = text.find(key, at + 1)) {
    const std::size_t after = at + key.size();
    std::size_t v = std::string_view::npos;
    for (const std::string_view marker : {std::string_view("=\""), std::string_view("\" Value=\""),
                                          std::string_view(" Value=\"")})
      if (text.substr(after, marker.size()) == marker) v = after + marker.size();
    if (v == std::string_view::npos) continue;
    const std::size_t end = text.find('"', v);
    if (end == std::string_view::npos) break;
    const std::string value = xml_unescape(text.substr(v, end - v));
    if (accept(value)) return value;
  }
  return "";
}

/// A run id: 32 lowercase hexadecimal digits (new_run_id).
bool is_run_id(std::string_view s) {
  return s.size() == 32 && s.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

/// A file name without a directory part.
bool is_file_name(std::string_view s) { return !s.empty() && s.find('/') == std::string_view::npos; }

} // namespace

std::string xml_run_id(const std::string& path) { return xml_mark(path, "otmpm_run_id", is_run_id); }

std::string xml_result(const std::string& path) {
  const std::string name = xml_mark(path, "otmpm_result", is_file_name);
  return name.empty() ? "" : (fs::path(path).parent_path() / name).string();
}

namespace {

/// What claim_outputs needs of an existing result file.
struct ExistingResult {
  bool present = false;
  bool readable = false; ///< an HDF5 file otmpm could open
  bool otmpm = false;    ///< it has otmpm's root attributes
  std::string run_id, scene, version;
  int frames = 0;     ///< links in /frames
  std::string damage; ///< why HDF5 failed to read what it opened ("" when it did not)
};

/// The root attribute `name` as a string, "" when absent or of another type.
std::string optional_string(hid_t file, const char* name, const std::string& path) {
  if (!h5::has_attribute(file, name) || h5::attribute_class(file, name, path) != H5T_STRING) return "";
  return h5::read_string(file, name, path);
}

ExistingResult inspect_result(const std::string& path) {
  ExistingResult r;
  r.present = occupied(path);
  if (!r.present || is_directory(path) || !special_file(path).empty()) return r; // never open a FIFO
  h5::silence();
  if (H5Fis_hdf5(path.c_str()) <= 0) return r;
  const hid_t id = h5::open_result_read_only(path);
  if (id < 0) return r;
  const h5::Handle file(id, H5Fclose);
  r.readable = true;
  try {
    r.run_id = optional_string(id, "run_id", path);
    r.scene = optional_string(id, "scene", path);
    r.version = optional_string(id, "otmpm_version", path);
    r.otmpm = !r.version.empty() && h5::has_attribute(id, "status");
    if (h5::has_link(id, "frames")) {
      const h5::Handle frames = h5::open_group(id, "frames", path);
      r.frames = static_cast<int>(h5::link_count(frames.get(), path)); // a killed run's file: no link iteration
    }
  } catch (const std::runtime_error& e) {
    r.otmpm = false;
    r.damage = e.what();
  }
  return r;
}

/// True when another process holds a lock on the file itself (an HDF5 writer or reader).
bool locked_by_other(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool locked = ::flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);
  return locked;
}

/// Why an existing result file may not be replaced ("" when it may).
std::string result_refusal(const ExistingResult& r, const ClaimRules& rules, const std::string& path) {
  if (!rules.continued_run.empty() && r.run_id == rules.continued_run) return "";
  if (rules.force) return "";
  if (is_directory(path)) return "is a directory";
  if (!r.readable)
    return locked_by_other(path) ? "is locked by another process (an HDF5 reader or writer such as ParaView or h5py "
                                   "holds it open)"
                                 : "exists and is not an otmpm result file (HDF5 cannot open it: another kind of "
                                   "file, or one truncated or damaged)";
  if (!r.damage.empty()) return "exists and is damaged (" + r.damage + "); --force replaces it";
  if (!r.otmpm) return "exists and is an HDF5 file not written by otmpm";
  if (r.scene != rules.scene_text) return "holds the results of another scene";
  if (r.version != OTMPM_VERSION) return "was written by otmpm " + r.version + ", not by this otmpm " OTMPM_VERSION;
  return "";
}

/// A view (sidecar, .pvd) may be replaced when it is otmpm's and belongs to
/// the replaced or continued run, or when the result file it was written for
/// is gone (a view holds no data of its own).
bool view_replaceable(const std::string& view, const std::string& owner, const ClaimRules& rules) {
  if (rules.force) return true;
  const std::string id = xml_run_id(view), result = xml_result(view);
  if (id.empty()) return false;
  return id == owner || id == rules.continued_run || (!result.empty() && !occupied(result));
}

/// True when an otmpm checkpoint's result file is gone: a restart from it is
/// impossible, so it holds nothing a user can use.
bool orphan_checkpoint(const std::string& path) {
  try {
    const std::string result = read_checkpoint_head(path).group("recorder").string("result_file");
    return !result.empty() && !occupied(result);
  } catch (const InputError&) {
    return false;
  }
}

/// VTK frame files written by otmpm: frame_NNNNNN.vtp / .vtu, and a
/// distributed run's frame_NNNNNN.pvtp / .pvtu and their pieces
/// frame_NNNNNN_RRRR.vtp / .vtu.
bool is_vtk_frame(const std::string& name) {
  const std::string_view n = name, prefix = "frame_";
  const std::size_t dot = n.rfind('.');
  if (dot == std::string_view::npos || n.substr(0, prefix.size()) != prefix) return false;
  const std::string_view ext = n.substr(dot), stem = n.substr(prefix.size(), dot - prefix.size());
  const std::size_t cut = stem.find('_');
  const std::string_view frame = stem.substr(0, cut), piece = cut == std::string_view::npos ? "" : stem.substr(cut + 1);
  auto digits = [](std::string_view d, std::size_t least) {
    return d.size() >= least && d.find_first_not_of("0123456789") == std::string_view::npos;
  };
  if (!digits(frame, 6)) return false;
  if (cut != std::string_view::npos) return digits(piece, 4) && (ext == ".vtp" || ext == ".vtu");
  return ext == ".vtp" || ext == ".vtu" || ext == ".pvtp" || ext == ".pvtu";
}

} // namespace

std::string result_run_id(const std::string& path) { return inspect_result(path).run_id; }

std::vector<std::string> claim_outputs(const OutputFiles& f, const ClaimRules& rules) {
  std::vector<std::string> remove;
  const ExistingResult existing = inspect_result(f.result);
  if (existing.present) {
    const std::string why = result_refusal(existing, rules, f.result);
    if (!why.empty()) throw InputError(f.result + ": the result file " + why + how_to_replace());
  }
  const std::string owner = existing.present ? existing.run_id : "";
  const bool continued = !rules.continued_run.empty();
  for (const std::string& view : {f.xdmf, f.pvd}) {
    if (view.empty() || !occupied(view)) continue;
    if (is_directory(view)) throw InputError(view + ": is a directory, where otmpm writes a file" + how_to_replace());
    if (!view_replaceable(view, owner, rules))
      throw InputError(view + ": exists and does not belong to the result file " + f.result +
                       " (another run's, or not otmpm's)" + how_to_replace());
  }
  if (!f.checkpoint.empty() && occupied(f.checkpoint)) {
    const std::string id = checkpoint_run_id(f.checkpoint);
    const bool mine = !id.empty() && (id == owner || id == rules.continued_run || orphan_checkpoint(f.checkpoint));
    if (!rules.force && !mine)
      throw InputError(f.checkpoint + ": the checkpoint file exists and belongs to another run (or is not otmpm's)" +
                       how_to_replace());
    if (!continued && !is_directory(f.checkpoint)) remove.push_back(f.checkpoint); // the replaced run's restart point
  }
  if (!f.vtk_dir.empty() && occupied(f.vtk_dir)) {
    if (!is_directory(f.vtk_dir))
      throw InputError(f.vtk_dir + ": exists and is not a directory (otmpm writes the VTK frames there)" +
                       how_to_replace());
    for (const auto& entry : fs::directory_iterator(f.vtk_dir)) {
      const std::string name = entry.path().filename().string();
      if (!is_vtk_frame(name)) continue; // otmpm never writes that name
      const std::string id = xml_run_id(entry.path().string());
      if (!rules.force && (id.empty() || (id != owner && id != rules.continued_run)))
        throw InputError(entry.path().string() + ": a VTK frame of another run (or not otmpm's)" + how_to_replace());
      remove.push_back(entry.path().string());
    }
  }
  return remove;
}

// ---------------------------------------------------------------- restart

std::string before_restart_path(const std::string& previous, const std::string& run_id) {
  return previous + ".before-restart." + run_id;
}

PreviousResults find_previous_results(const std::string& previous, const std::string& out, const std::string& run_id,
                                      int frames) {
  require(!run_id.empty(), previous, ": the checkpoint has no run id");
  const std::string aside = before_restart_path(previous, run_id);
  const ExistingResult real = inspect_result(previous), copy = inspect_result(aside);
  const bool real_ok = real.run_id == run_id && real.frames >= frames;
  const bool copy_ok = copy.run_id == run_id && copy.frames >= frames;
  if (!real_ok && !copy_ok) {
    std::string why;
    if (!real.present) why = "is missing";
    else if (!real.readable)
      why = "cannot be opened by HDF5 (truncated or damaged, or not an HDF5 file)";
    else if (!real.damage.empty()) why = "is damaged (" + real.damage + ")";
    else if (real.run_id != run_id)
      why = "is not the result file of the checkpoint's run (run id " + run_id + ", the file has " +
            (real.run_id.empty() ? std::string("none") : real.run_id) + "): frames are copied only from the same run";
    else why = "holds " + std::to_string(real.frames) + " frames, fewer than the " + std::to_string(frames) + " written before the checkpoint";
    throw InputError(previous + ": the result file of the interrupted run " + why +
                     " (it holds the frames written before the checkpoint)" +
                     (copy.present ? "; " + aside + " does not hold them either" : ""));
  }
  if (!real_ok) return {aside, true, ""};
  if (!same_file(previous, out)) return {previous, false, ""};
  return {aside, true, previous};
}

void set_aside_results(const PreviousResults& previous) {
  if (previous.rename_from.empty()) return;
  std::error_code ec;
  fs::rename(previous.rename_from, previous.path, ec); // over an older copy of the same run, if any
  if (ec) throw InputError(previous.rename_from + ": cannot rename it to " + previous.path + ": " + ec.message());
}

void release_previous_results(const PreviousResults& previous) {
  std::error_code ec;
  if (previous.set_aside && !fs::remove(previous.path, ec))
    throw InputError(previous.path + ": cannot remove it after copying its frames: " + ec.message());
}

// ---------------------------------------------------------------- prepare

namespace {

/// A restart's previous result file, when it is not the run's own result
/// file, must not be any other file the run writes.
void check_previous_distinct(const OutputFiles& f, const std::string& previous) {
  if (previous.empty() || same_file(previous, f.result)) return;
  for (const auto& [role, path] : written_paths(f))
    if (same_file(previous, path))
      throw InputError("the interrupted run's result file '" + previous + "' (from the checkpoint) and the " + role +
                       " '" + path + "' are the same file: nothing was written; choose another --out");
}

} // namespace

OutputFiles checked_output_files(const OutputRequest& r) {
  OutputFiles files = output_files(r.result, r.checkpoint, r.vtk_format);
  files.result_origin = r.result_origin;
  files.checkpoint_origin = r.checkpoint_origin;
  check_distinct(files);
  return files;
}

PreparedOutputs prepare_outputs(const OutputRequest& r) {
  PreparedOutputs out;
  out.files = checked_output_files(r);
  check_previous_distinct(out.files, r.previous_result);
  std::vector<std::string> locked = {out.files.result, out.files.xdmf, out.files.checkpoint, out.files.pvd};
  if (!r.previous_result.empty()) locked.push_back(r.previous_result);
  out.lock = OutputLock(locked);
  if (!r.continued_run.empty())
    out.previous = find_previous_results(r.previous_result, r.result, r.continued_run, r.previous_frames);
  const std::vector<std::string> stale =
      claim_outputs(out.files, ClaimRules{r.scene_text, r.force, r.continued_run});
  for (const std::string& path : stale) {
    std::error_code ec;
    fs::remove(path, ec);
    if (ec) throw InputError(path + ": cannot remove this file of the replaced run: " + ec.message());
  }
  if (out.previous) set_aside_results(*out.previous);
  out.run_id = r.continued_run.empty() ? new_run_id() : r.continued_run;
  return out;
}

} // namespace otmpm
