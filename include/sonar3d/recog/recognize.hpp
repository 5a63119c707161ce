#pragma once
// The recognition as one call, for the command, Python and the survey: the method chosen, the
// settings the two methods share applied to both (docs/recognition.md). The configuration is the
// one the command prints with `--print-config` and reads with `--config` (core/params.hpp).
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognition_3d.hpp"

namespace sonar3d {

struct RecognizeConfig {
  std::string method = "2d";  // "2d" (sec. 6.3.2) or "3d" (sec. 6.3.1)
  RecognitionConfig two_d;    // the 2D method; its verification and num_threads serve both
  Recognition3dConfig three_d;
  // The 3D method's configuration as it runs: the shared verification and thread count.
  Recognition3dConfig effective_3d() const;
  // The chosen method's configuration checked; errors name the field and its flag.
  void validate() const;
};

template <class V>
void describe(RecognizeConfig& c, V& v) {
  v.field(c.method, params::param("method", "",
                                  "2d: elevation-map recognition (sec. 6.3.2); 3d: subspaces "
                                  "and direct 3D matching (sec. 6.3.1)")
                        .flag("--method"));
  v.group("two_d", c.two_d);
  v.group("three_d", c.three_d);
}

// The catalogue's models found in a world-frame cloud by the configured method. `searches3`
// receives the 3D method's per-model analysis (when the method is 3d and it is not null).
RecognitionResult recognize(const PointCloud& scene_world, const std::vector<ModelTemplate>& models,
                            const RecognizeConfig& config,
                            std::vector<Search3dRecord>* searches3 = nullptr,
                            bool progress = false);

// Memory the configured method will allocate for this scene and `models` catalogue models
// (core/memory.hpp), before anything is allocated (issue 29 item 5): the 2D method's fine and
// coarse elevation maps with their working copies (the live, levelled and removal maps, the
// relief and blob labels, the point grid), the 3D method's fine map, top map and the working
// copies and index of the scene points. Each part names the flag (or YAML key) that scales it.
MemoryEstimate estimate_recognition_memory(const PointCloud& scene_world, std::size_t models,
                                           const RecognizeConfig& config);

// The placements JSON of the configured method (placements_json or placements_json_3d).
std::string recognize_json(const RecognitionResult& result,
                           const std::vector<Search3dRecord>& searches3,
                           const std::string& map_source, const std::string& catalogue_source,
                           const RecognizeConfig& config);

// The recognition's outputs as `sonar3d recognize` (and Python's recognize(output=...)) write
// them: the placements JSON (recognize_json) and the placed models as one binary PLY mesh
// (placed_models_mesh; default path: the JSON's with .ply), under the output rule
// (core/output_dir.hpp). The constructor checks both paths before any work (a foreign file, an
// input, a special file is refused there, naming `json_flag` / `mesh_flag`); write() writes
// both under temporary names and renames them together: both appear or neither does.
class RecognitionFiles {
 public:
  RecognitionFiles(const std::filesystem::path& json_path, std::filesystem::path mesh_path,
                   const OutputPolicy& policy, const std::string& json_flag = "-o",
                   const std::string& mesh_flag = "--mesh");
  const std::filesystem::path& json_path() const { return json_; }
  const std::filesystem::path& mesh_path() const { return mesh_; }
  void write(const RecognitionResult& result, const std::vector<Search3dRecord>& searches3,
             const std::vector<ModelTemplate>& models, const std::string& map_source,
             const std::string& catalogue_source, const RecognizeConfig& config);

 private:
  std::filesystem::path json_, mesh_, json_tmp_, mesh_tmp_;
  std::unique_ptr<OutputFiles> out_;
};

}  // namespace sonar3d
