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
  bool group = false;   // the journal of an interrupted OutputFiles::commit()
};

// Recognises the names AtomicPath uses beside `final_name` (see atomic_file.hpp).
std::optional<LeftOver> parse_left_over(const std::string& entry, const std::string& final_name) {
  const std::string tmp1 = "." + final_name + ".tmp-", tmp2 = ".." + final_name + ".tmp-",
                    bak = "." + final_name + ".backup-", grp = "." + final_name + ".group-";
  LeftOver lo;
  std::size_t pos = 0;
  if (entry.rfind(grp, 0) == 0) {
    pos = grp.size();
    lo.group = true;
  } else if (entry.rfind(bak, 0) == 0) {
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

void put_record(std::string& out, const std::string& value) {
  out += std::to_string(value.size()) + " " + value + "\n";
}

bool get_record(const std::string& in, std::size_t& pos, std::string& value) {
  const std::size_t sp = in.find(' ', pos);
  if (sp == std::string::npos || sp == pos || sp - pos > 9) return false;
  for (std::size_t i = pos; i < sp; ++i) {
    if (!std::isdigit(static_cast<unsigned char>(in[i]))) return false;
  }
  const std::size_t len = std::stoul(in.substr(pos, sp - pos));
  if (sp + 1 + len >= in.size() || in[sp + 1 + len] != '\n') return false;
  value = in.substr(sp + 1, len);
  pos = sp + 2 + len;
  return true;
}

constexpr const char* kGroupMagic = "sonar3d-output-group 1\n";

// A member or journal count: 1–3 digits.
bool is_count(const std::string& v) {
  return !v.empty() && v.size() < 4 &&
         std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; });
}

}  // namespace

std::string group_journal_text(const std::vector<GroupJournalEntry>& members,
                               const std::vector<fs::path>& journals) {
  std::string out = kGroupMagic;
  put_record(out, std::to_string(members.size()));
  for (const auto& m : members) {
    put_record(out, m.final_path.string());
    put_record(out, m.temp.string());
    put_record(out, m.backup.string());
  }
  put_record(out, std::to_string(journals.size()));
  for (const auto& j : journals) put_record(out, j.string());
  return out;
}

std::string finish_interrupted_group(const fs::path& journal) {
  std::string text;
  {
    std::ifstream f(journal, std::ios::binary);
    std::ostringstream os;
    os << f.rdbuf();
    text = os.str();
  }
  std::vector<GroupJournalEntry> members;
  std::vector<fs::path> journals;
  std::size_t pos = std::string(kGroupMagic).size();
  std::string v;
  bool ok = text.rfind(kGroupMagic, 0) == 0 && get_record(text, pos, v) && is_count(v);
  const std::size_t n = ok ? std::stoul(v) : 0;
  for (std::size_t i = 0; ok && i < n; ++i) {
    GroupJournalEntry e;
    ok = get_record(text, pos, v) && !v.empty();
    e.final_path = v;
    ok = ok && get_record(text, pos, v) && !v.empty();
    e.temp = v;
    ok = ok && get_record(text, pos, v);
    e.backup = v;
    members.push_back(e);
  }
  ok = ok && get_record(text, pos, v) && is_count(v);
  const std::size_t m = ok ? std::stoul(v) : 0;
  for (std::size_t i = 0; ok && i < m; ++i) {
    ok = get_record(text, pos, v);
    journals.emplace_back(v);
  }
  std::error_code ec;
  if (!ok) {
    // Cut short while being written: the commit had not started renaming (the journals are
    // complete before the first rename), so the generic clean-up of temporaries applies.
    fs::remove(journal, ec);
    return "removed the incomplete journal '" + journal.string() +
           "' of an interrupted sonar3d run (nothing had been renamed yet)";
  }
  bool all_in = true;  // every new file got its final name: complete the set
  for (const auto& e : members)
    all_in = all_in && !exists_no_follow(e.temp) && exists_no_follow(e.final_path);
  std::string names;
  for (const auto& e : members)
    names += (names.empty() ? "'" : ", '") + e.final_path.string() + "'";
  std::string problems;
  for (const auto& e : members) {
    if (!all_in) {
      if (exists_no_follow(e.temp)) {
        fs::remove(e.temp, ec);
      } else if (exists_no_follow(e.final_path)) {
        fs::remove(e.final_path, ec);  // the new file, whose partners are missing
      }
      if (!e.backup.empty() && exists_no_follow(e.backup)) {
        fs::rename(e.backup, e.final_path, ec);
        if (ec)
          problems += "; could not restore '" + e.final_path.string() + "' from '" +
                      e.backup.string() + "': " + ec.message();
      }
    } else if (!e.backup.empty()) {
      fs::remove(e.backup, ec);
    }
  }
  for (const auto& j : journals) fs::remove(j, ec);
  fs::remove(journal, ec);
  return std::string(all_in ? "completed" : "rolled back") + " the outputs " + names +
         " that an interrupted sonar3d run was renaming into place together" +
         (all_in ? "" : " (the previous versions, if any, are back)") + problems;
}

std::vector<std::string> recover_interrupted_writes(const fs::path& final_path) {
  fs::path final_p = final_path;
  if (final_p.filename().empty()) final_p = final_p.parent_path();
  const std::string name = final_p.filename().string();
  std::vector<std::string> notes;
  if (name.empty() || name == "." || name == "..") return notes;
  std::error_code ec;
  // First the journals of interrupted group commits: they decide for every member of the set.
  std::vector<fs::path> journals;
  for (fs::directory_iterator it(parent_of(final_p), ec), end; !ec && it != end; it.increment(ec)) {
    const auto lo = parse_left_over(it->path().filename().string(), name);
    if (lo && lo->group && process_is_dead(lo->pid)) journals.push_back(it->path());
  }
  std::sort(journals.begin(), journals.end());
  for (const fs::path& j : journals) {
    if (exists_no_follow(j)) notes.push_back(finish_interrupted_group(j));
  }
  ec.clear();
  std::vector<std::pair<fs::path, LeftOver>> found;
  for (fs::directory_iterator it(parent_of(final_p), ec), end; !ec && it != end; it.increment(ec)) {
    const auto lo = parse_left_over(it->path().filename().string(), name);
    if (lo && !lo->group && process_is_dead(lo->pid)) found.emplace_back(it->path(), *lo);
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
    bool same_kind = false;
    for (const OutputKind k : {OutputKind::Dataset, OutputKind::Relocalization}) {
      same_kind = same_kind || (is_sonar3d_output(temp_, k) && is_sonar3d_output(final_, k));
    }
    if (!empty && !same_kind) {
      throw Error("'" + final_.string() +
                  "' exists and is not a sonar3d output of the same kind (a dataset, a "
                  "relocalization directory): sonar3d will not replace it; choose another output "
                  "or remove it yourself");
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
    const fs::file_status st = fs::symlink_status(final_, ec);
    if (fs::exists(st) && !fs::is_regular_file(st) && !fs::is_symlink(st)) {
      throw Error("cannot write '" + final_.string() +
                  "': it is a special file (FIFO, device or socket), which sonar3d never "
                  "replaces; choose a regular file");
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
