#pragma once
// Outputs are written under a temporary name and renamed when complete, so a failed or
// interrupted run never leaves a file or directory that looks finished.
#include <filesystem>
#include <string>

namespace sonar3d {

// A temporary sibling path for `final_path`; commit() renames it into place (replacing an old
// file or directory), the destructor removes it if commit() was never called.
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

// Writes `contents` to path atomically.
void write_text_file(const std::string& path, const std::string& contents);
std::string read_text_file(const std::string& path);

}  // namespace sonar3d
