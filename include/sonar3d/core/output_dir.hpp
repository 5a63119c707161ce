#pragma once
// The one output rule of sonar3d (docs/formats.md, "Replacing an output"), for every file and
// directory any command writes — sonar3d never destroys what it did not write:
//   - a path that does not exist (or, for a directory output, an empty directory) is written;
//   - a sonar3d output of the same kind (recognised by its content: a header comment, a
//     "format" key, a TIFF/PNG Software tag, a dataset's sonar.yaml) is replaced only with
//     `overwrite`;
//   - anything else — a file or directory of other data, another kind of output, a FIFO, a
//     device, a socket — is an Error naming it;
//   - an input of the command can be neither the output, nor contain it, nor lie inside it;
//   - outputs that belong together (OutputFiles) appear together or not at all, also after a kill.
// check_output() applies the rule to one path; OutputDirectory writes a directory output,
// OutputFiles a set of files; both write under temporary names and rename when complete.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace sonar3d {

class AtomicPath;

enum class OutputKind {
  Dataset,             // a dataset directory: sonar.yaml with `format: sonar3d-dataset`
  Plan,                // a plan directory (sonar3d plan): points/ and sweep.yaml
  PointCloud,          // a PLY cloud (write_ply) or textured mesh: its header comment
  Mesh,                // a PLY mesh (save_mesh: "comment sonar3d mesh") or textured mesh
  GeoTiff,             // an elevation map: TIFF Software tag "sonar3d"
  Tiff,                // a float image (noise mean/std): TIFF Software tag "sonar3d"
  Png,                 // a picture (preview, elevation --png): PNG tEXt Software "sonar3d"
  Gltf,                // a glTF binary (texture --mesh -o X.glb): asset.generator "sonar3d"
  VoxelMap,            // an OpenVDB file of carving (--vdb): its "sonar3d" creator metadata
  ReconstructionJson,  // "format": "sonar3d-reconstruction"
  EvaluationJson,      // "format": "sonar3d-evaluation"
  RegistrationJson,    // "format": "sonar3d-registration"
  PlacementsJson,      // "format": "sonar3d-placements"
  PlanResultsJson,     // a plan's results.json: "format": "sonar3d-plan-results"
  PlanResultsCsv,      // a plan's results.csv: its header line "id,status,rank,..."
  Survey,  // a survey directory (sonar3d survey): summary.json "format": "sonar3d-survey"
  // a relocalisation directory (sonar3d relocalize): relocalization.json "format":
  // "sonar3d-relocalization"
  Relocalization,
};
const char* output_kind_name(OutputKind kind);
// True for the kinds that are directories (Dataset, Plan, Survey, Relocalization).
bool is_directory_kind(OutputKind kind);
// The "format" value of a JSON kind ("sonar3d-evaluation", ...); empty for other kinds.
const char* json_format_marker(OutputKind kind);

// True when `path` holds a sonar3d output of `kind` (see the list above).
bool is_sonar3d_output(const std::filesystem::path& path, OutputKind kind);

// The provenance marks that is_sonar3d_output() looks for in pictures, written by sonar3d's
// writers into the file they just wrote (before it is renamed): a Software tag in a classic
// little- or big-endian TIFF (IFD 0 rewritten at the end of the file), a tEXt chunk after a
// PNG's IHDR. Throw Error naming the file when it is not such a file.
void mark_tiff_as_sonar3d(const std::filesystem::path& path);
void mark_png_as_sonar3d(const std::filesystem::path& path);

struct OutputPolicy {
  bool overwrite = false;  // replace an existing sonar3d output of the same kind
  // Inputs of the command (files or directories): none may be, contain or lie inside the output.
  std::vector<std::filesystem::path> sources;
  // Called with each line about interrupted runs cleaned up beside the output (also when the
  // check then refuses the output), e.g. to print them.
  std::function<void(const std::string&)> on_note;
};

// Throws Error naming `path` when the rule forbids writing it as an output of `kind` (see the
// top of this file); `flag` names the option in the messages (e.g. "-o", "--json").
void check_output(const std::filesystem::path& path, OutputKind kind, const OutputPolicy& policy,
                  const std::string& flag = "-o");
// The part of the rule that holds for any path, also one that will be created: it is not an
// input, does not contain one nor lie inside one, and is no special file (FIFO, device, socket).
// E.g. for a directory an output goes into (noise estimate -o DIR: created if missing).
void check_output_location(const std::filesystem::path& path, const OutputPolicy& policy,
                           const std::string& flag = "-o", const std::string& what = "output");
// check_output() for a directory kind (kept for the callers that predate check_output()).
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

// Files that belong together (a placements JSON and its mesh, an elevation map and its picture,
// a plan's results), or a single file, written under temporary names and renamed together:
//   OutputFiles out(policy);
//   const auto json = out.add(json_path, OutputKind::PlacementsJson, "-o");   // checks now
//   const auto mesh = out.add(mesh_path, OutputKind::Mesh, "--mesh");
//   write_everything(json, mesh);        // temporary paths, same extensions as the final ones
//   out.commit();                        // all or none
// add() applies check_output() (fail fast, before the work) and returns the temporary path,
// which keeps the final extension (writers pick encoders by it). commit() checks again (the
// paths may have changed meanwhile), flushes every file to disk, writes a journal
// `.NAME.group-PID-N` beside each member, moves the previous versions to backup names, renames
// every file into place, then removes the journals and backups. After a kill in between, the
// next sonar3d run writing any member (recover_interrupted_writes) completes the set when every
// new file is in place and rolls it back otherwise: the members appear together or not at all.
// Uncommitted temporaries are removed by the destructor.
class OutputFiles {
 public:
  explicit OutputFiles(OutputPolicy policy);
  ~OutputFiles();
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;

  std::filesystem::path add(std::filesystem::path final_path, OutputKind kind,
                            const std::string& flag = "-o");
  // Lines for the user about interrupted runs cleaned up beside the outputs.
  const std::vector<std::string>& notes() const { return notes_; }
  // `after_rename(i)` is called after the i-th file got its final name (tests: a kill there).
  void commit(const std::function<void(std::size_t)>& after_rename = {});

 private:
  struct Member {
    std::filesystem::path final_path, temp;
    OutputKind kind;
    std::string flag;
  };
  OutputPolicy policy_;
  std::vector<Member> members_;
  std::vector<std::string> notes_;
  bool committed_ = false;
};

}  // namespace sonar3d
