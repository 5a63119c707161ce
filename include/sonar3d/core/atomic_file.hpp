#pragma once
// Outputs are written under a temporary name and renamed when complete, so a failed or
// interrupted run never leaves a file or directory that looks finished.
//
// Names used beside an output NAME (docs/formats.md, "Temporary and backup names"):
//   .NAME.tmp-PID-N      being written by process PID (removed on failure)
//   .NAME.backup-PID-N   the previous NAME while a directory (or a group of files) is replaced
//   .NAME.group-PID-N    the journal of files renamed into place together (OutputFiles)
// Both are recognised after a crash (see recover_interrupted_writes()).
#include <filesystem>
#include <string>
#include <vector>

namespace sonar3d {

// A temporary sibling path for `final_path`; commit() renames it into place (replacing an old
// file or directory), the destructor removes it if commit() was never called.
//
// commit() makes the new contents durable before they get the final name: a file is fsync'ed
// (a directory's file system is synced) before the rename, the parent directory after it.
// A directory replaces only an empty directory or a sonar3d output of the same kind (see
// output_dir.hpp); anything else at final_path is an Error, never deleted. Replacing a directory
// is atomic as a whole: the old one is renamed to a backup name, the new
// one renamed in, then the backup deleted; a crash in between leaves the backup, which the next
// sonar3d run writing that output restores (recover_interrupted_writes()).
class AtomicPath {
 public:
  explicit AtomicPath(std::filesystem::path final_path);
  ~AtomicPath();
  AtomicPath(const AtomicPath&) = delete;
  AtomicPath& operator=(const AtomicPath&) = delete;

  const std::filesystem::path& temp() const { return temp_; }
  const std::filesystem::path& final_path() const { return final_; }
  void commit();

 private:
  std::filesystem::path final_;
  std::filesystem::path temp_;
  bool committed_ = false;
};

// Cleans up after sonar3d processes that died while writing `final_path` (entries of live
// processes are left alone; a process counts as dead when kill(pid, 0) fails with ESRCH):
//   - their temporaries .NAME.tmp-PID-N (and ..NAME.tmp-PID-N.tmp-…) are removed;
//   - a backup .NAME.backup-PID-N is renamed back to NAME when NAME is missing (a crash between
//     the two renames of a replacement), and removed when NAME exists (a crash after them).
// Returns one line per action, for the user. AtomicPath's constructor calls it.
std::vector<std::string> recover_interrupted_writes(const std::filesystem::path& final_path);

// The journal of a group commit (OutputFiles::commit(), output_dir.hpp): for each member its
// final name, temporary name and backup name (empty: there was no previous version).
struct GroupJournalEntry {
  std::filesystem::path final_path, temp, backup;
};
std::string group_journal_text(const std::vector<GroupJournalEntry>& members,
                               const std::vector<std::filesystem::path>& journals);
// Finishes the group commit that `journal` describes, left by a dead process: when every new
// file has its final name the set is completed (backups removed), otherwise it is rolled back
// (new files and temporaries removed, previous versions restored). Removes every journal of the
// group and returns one line for the user. recover_interrupted_writes() calls it first.
std::string finish_interrupted_group(const std::filesystem::path& journal);

// fsync()s a file or directory (a directory: its entries, i.e. renames inside it). Throws Error
// naming the path when the data cannot be made durable (e.g. EIO, ENOSPC on write-back).
void sync_path(const std::filesystem::path& path);

// Writes `contents` to path atomically (written, fsync'ed, renamed).
void write_text_file(const std::string& path, const std::string& contents);
std::string read_text_file(const std::string& path);

}  // namespace sonar3d
