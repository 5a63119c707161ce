#include "sonar3d/core/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <system_error>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

std::atomic<unsigned> g_counter{0};

fs::path parent_of(const fs::path& p) { return p.has_parent_path() ? p.parent_path() : "."; }

bool exists_no_follow(const fs::path& p) {
  std::error_code ec;
  return fs::exists(fs::symlink_status(p, ec));
}

// True when no process `pid` exists (kill(pid, 0) fails with ESRCH). Our own pid, and any pid
// we may not signal (EPERM: another user's live process), count as alive.
bool process_is_dead(long pid) {
  if (pid <= 0 || pid == static_cast<long>(::getpid())) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == -1 && errno == ESRCH;
}

struct LeftOver {
  long pid = 0;
  bool backup = false;  // a previous version of the output (restore it), else a temporary
};

// Recognises the names AtomicPath uses beside `final_name` (see atomic_file.hpp).
std::optional<LeftOver> parse_left_over(const std::string& entry, const std::string& final_name) {
  const std::string tmp1 = "." + final_name + ".tmp-", tmp2 = ".." + final_name + ".tmp-",
                    bak = "." + final_name + ".backup-";
  LeftOver lo;
  std::size_t pos = 0;
  if (entry.rfind(bak, 0) == 0) {
    pos = bak.size();
    lo.backup = true;
  } else if (entry.rfind(tmp1, 0) == 0) {
    pos = tmp1.size();
    // Before backup names existed, the previous directory was moved aside as .NAME.tmp-PID-N.old.
    lo.backup = entry.size() > 4 && entry.compare(entry.size() - 4, 4, ".old") == 0;
  } else if (entry.rfind(tmp2, 0) == 0) {
    pos = tmp2.size();
  } else {
    return std::nullopt;
  }
  std::size_t end = pos;
  while (end < entry.size() && end - pos < 10 &&
         std::isdigit(static_cast<unsigned char>(entry[end]))) {
    ++end;
  }
  if (end == pos || end >= entry.size() || entry[end] != '-') return std::nullopt;
  lo.pid = std::stol(entry.substr(pos, end - pos));
  return lo;
}

void fsync_or_throw(const fs::path& path, bool whole_file_system) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    throw Error("cannot open '" + path.string() + "' to flush it to disk: " + std::strerror(errno));
  }
  const int rc = whole_file_system ? ::syncfs(fd) : ::fsync(fd);
  const int err = errno;
  ::close(fd);
  // EINVAL/EROFS: the file system does not support syncing (e.g. a special file): nothing to do.
  if (rc != 0 && err != EINVAL && err != EROFS) {
    throw Error("cannot flush '" + path.string() + "' to disk: " + std::strerror(err) +
                " (disk full or failing?); the previous version, if any, is left in place");
  }
}

}  // namespace

std::vector<std::string> recover_interrupted_writes(const fs::path& final_path) {
  fs::path final_p = final_path;
  if (final_p.filename().empty()) final_p = final_p.parent_path();
  const std::string name = final_p.filename().string();
  std::vector<std::string> notes;
  if (name.empty() || name == "." || name == "..") return notes;
  std::error_code ec;
  std::vector<std::pair<fs::path, LeftOver>> found;
  for (fs::directory_iterator it(parent_of(final_p), ec), end; !ec && it != end; it.increment(ec)) {
    const auto lo = parse_left_over(it->path().filename().string(), name);
    if (lo && process_is_dead(lo->pid)) found.emplace_back(it->path(), *lo);
  }
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [path, lo] : found) {
    const std::string who =
        " left by an interrupted sonar3d run (process " + std::to_string(lo.pid) + ")";
    if (lo.backup && !exists_no_follow(final_p)) {
      fs::rename(path, final_p, ec);
      if (ec) {
        notes.push_back("could not restore '" + final_p.string() + "' from its backup '" +
                        path.string() + "'" + who + ": " + ec.message() +
                        "; rename it back by hand");
      } else {
        notes.push_back("restored '" + final_p.string() + "' from its backup '" + path.string() +
                        "'" + who);
      }
      continue;
    }
    fs::remove_all(path, ec);
    notes.push_back((ec ? "could not remove '" : "removed '") + path.string() + "'" + who +
                    (lo.backup ? " (a backup of an output that was replaced since)" : "") +
                    (ec ? ": " + ec.message() : ""));
  }
  return notes;
}

void sync_path(const fs::path& path) { fsync_or_throw(path, false); }

AtomicPath::AtomicPath(fs::path final_path) : final_(std::move(final_path)) {
  if (final_.filename().empty()) final_ = final_.parent_path();  // "dir/" -> "dir"
  const fs::path parent = parent_of(final_);
  if (!fs::exists(parent)) {
    throw Error("cannot write '" + final_.string() + "': directory '" + parent.string() +
                "' does not exist");
  }
  recover_interrupted_writes(final_);
  temp_ = parent / ("." + final_.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                    std::to_string(g_counter++));
}

AtomicPath::~AtomicPath() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(temp_, ec);  // best effort: never throw from a destructor
  }
}

void AtomicPath::commit() {
  std::error_code ec;
  const fs::path parent = parent_of(final_);
  const bool temp_is_dir = fs::is_directory(temp_);
  // Durable before it gets the final name: a crash must not leave a complete-looking name on
  // empty or truncated data. A directory of many files: one syncfs() rather than an fsync each.
  fsync_or_throw(temp_, temp_is_dir);
  if (temp_is_dir && exists_no_follow(final_)) {
    // The safety net under every directory output, whoever calls (the CLI checks first, with
    // OutputDirectory): only an empty directory or a sonar3d output of the same kind is replaced.
    std::error_code e2;
    const bool empty = fs::is_directory(final_, e2) && fs::is_empty(final_, e2) && !e2;
    if (!empty && !(is_sonar3d_output(temp_, OutputKind::Dataset) &&
                    is_sonar3d_output(final_, OutputKind::Dataset))) {
      throw Error("'" + final_.string() +
                  "' exists and is not a sonar3d dataset: sonar3d will not replace it; choose "
                  "another output or remove it yourself");
    }
    // rename() cannot replace a non-empty directory: move the old one to a backup name first.
    const fs::path backup =
        parent / ("." + final_.filename().string() + ".backup-" + std::to_string(::getpid()) + "-" +
                  std::to_string(g_counter++));
    fs::rename(final_, backup, ec);
    if (ec) throw Error("cannot replace '" + final_.string() + "': " + ec.message());
    fs::rename(temp_, final_, ec);
    if (ec) {
      std::error_code ec2;
      fs::rename(backup, final_, ec2);
      throw Error("cannot write '" + final_.string() + "': " + ec.message());
    }
    committed_ = true;
    sync_path(parent);  // both renames on disk before the old version goes
    fs::remove_all(backup, ec);
  } else {
    if (fs::is_directory(final_) && !temp_is_dir) {
      throw Error("cannot write file '" + final_.string() + "': a directory has that name");
    }
    fs::rename(temp_, final_, ec);
    if (ec) throw Error("cannot write '" + final_.string() + "': " + ec.message());
    committed_ = true;
    sync_path(parent);
  }
}

void write_text_file(const std::string& path, const std::string& contents) {
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path + "' for writing");
    f << contents;
    f.close();
    if (!f) throw Error("failed writing '" + path + "' (disk full?)");
  }
  out.commit();  // fsyncs before renaming
}

std::string read_text_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f)
    throw Error("cannot open '" + path + "' for reading: " +
                (fs::exists(path) ? "permission denied or not a file" : "no such file"));
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

}  // namespace sonar3d
