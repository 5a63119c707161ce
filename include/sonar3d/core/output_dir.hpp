#pragma once
// Output directories that sonar3d replaces as a whole (datasets from `simulate` and `import`),
// guarded so that sonar3d never destroys what it did not write (docs/formats.md, "Replacing an
// output"):
//   - a path that does not exist, or an empty directory, is written;
//   - a sonar3d output of the same kind is replaced only with `overwrite`;
//   - anything else (a file, a directory of other data, another kind of output) is an Error
//     naming it;
//   - an input of the command can be neither the destination, inside it, nor contain it.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace sonar3d {

class AtomicPath;

enum class OutputKind {
  Dataset,  // a dataset directory: sonar.yaml with `format: sonar3d-dataset`
};
const char* output_kind_name(OutputKind kind);

// True when `dir` is a directory holding a sonar3d output of `kind`.
bool is_sonar3d_output(const std::filesystem::path& dir, OutputKind kind);

struct OutputPolicy {
  bool overwrite = false;  // replace an existing sonar3d output of the same kind
  // Inputs of the command (files or directories): none may be, contain or lie inside the output.
  std::vector<std::filesystem::path> sources;
  // Called with each line about interrupted runs cleaned up beside the output (also when the
  // check then refuses the output), e.g. to print them.
  std::function<void(const std::string&)> on_note;
};

// Throws Error naming `dir` when the policy forbids writing it (see the top of this file).
void check_output_directory(const std::filesystem::path& dir, OutputKind kind,
                            const OutputPolicy& policy);

// A directory output written under a staging name beside it and swapped in by commit():
//   OutputDirectory out(dir, OutputKind::Dataset, policy);   // recovers, checks
//   write_everything_into(out.staging());                     // staging() does not exist yet
//   out.commit();                                             // atomic as a whole
// The constructor first cleans up after interrupted runs (recover_interrupted_writes(): a
// backup beside a missing `dir` is restored; what it did is in notes()), then applies
// check_output_directory(). An uncommitted staging directory is removed by the destructor.
class OutputDirectory {
 public:
  OutputDirectory(std::filesystem::path dir, OutputKind kind, const OutputPolicy& policy);
  ~OutputDirectory();
  OutputDirectory(const OutputDirectory&) = delete;
  OutputDirectory& operator=(const OutputDirectory&) = delete;

  const std::filesystem::path& path() const { return final_; }
  const std::filesystem::path& staging() const { return staging_; }
  // Lines for the user about interrupted runs cleaned up or restored beside the output.
  const std::vector<std::string>& notes() const { return notes_; }
  // Checks that staging() holds an output of the kind, then replaces path() by it atomically.
  void commit();

 private:
  std::filesystem::path final_, staging_;
  OutputKind kind_;
  std::vector<std::string> notes_;
  std::unique_ptr<AtomicPath> atomic_;  // staging_ is its temporary name
};

}  // namespace sonar3d
