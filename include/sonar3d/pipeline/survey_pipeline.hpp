#pragma once
// A survey log, as recorded, to a map, placements, a world model and a report in one call
// (`sonar3d survey`, `sonar3d.survey()`; docs/survey.md):
//
//   import → map → recognise → world model → texture → report
//
// Each stage is the library call its own command makes (`import`, `map`, `recognize`, `world`,
// `texture`, `report`), and takes its command's declared configuration (the same keys as the
// command's --print-config; import: one block per input kind), plus the few keys only the
// survey has.
// Outputs, under OUT:
//   dataset/            the imported dataset (not when INPUT is already a dataset: used in place)
//   map/                sonar3d map's directory (merged.ply, navigation_corrected.tum, ...)
//   placements.json     with --catalogue: sonar3d recognize's placements, and placements.ply
//   world/              sonar3d world's directory (world.glb, seabed_lod<k>.ply, graph.json)
//   textured.ply        when the dataset has camera frames: the merged cloud in video colours
//   report.html         sonar3d report of world/
//   summary.json        "format": "sonar3d-survey"; per stage its status, wall time, peak memory
//                       and key figures
//   stamps/<stage>.yaml what a finished stage was made from (inputs' paths, sizes and mtimes,
//                       its settings): a re-run skips a stage whose stamp matches
//
// Resume: a finished stage whose stamp matches is skipped; a stage whose inputs or settings
// changed runs again, and so does every stage after it. A failing stage throws
// Error("survey: stage NAME failed: ...") and leaves the finished stages in place. Each stage
// writes into a staging directory inside OUT and renames its outputs into place when complete.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d {

// Stage options (default-constructed: each as its command's defaults): each stage's block is its
// command's own declared configuration (core/params.hpp) — the keys of that command's
// `--print-config` — plus the few keys only the survey has.

// The input kinds of `import.kind`: auto (by the input's content), or one of them.
inline constexpr const char* kSurveyInputKinds[] = {"auto",   "dataset",   "aris",
                                                    "rosbag", "holoocean", "oculus"};

// sonar3d import <kind>: one block per kind of input, each the importer's own configuration (the
// keys of `sonar3d import <kind> --print-config`), plus the kind. Only the block of the kind
// imported is used (and stamped: changing another kind's block re-runs nothing).
struct SurveyImportOptions {
  std::string kind = "auto";
  ArisImportConfig aris;
  RosbagImportConfig rosbag;
  OculusImportConfig oculus;
  HoloOceanImportConfig holoocean;
};
template <class V>
void describe(SurveyImportOptions& o, V& v) {
  using params::param;
  v.field(o.kind, param("kind", "",
                        "the input's kind: 'auto' (by its content), or 'dataset' (used in place), "
                        "'aris', 'rosbag', 'holoocean', 'oculus'")
                      .choices(kSurveyInputKinds));
  // The importers' own keys (io/*.hpp), under the kind's name.
  v.group("aris", o.aris);
  v.group("rosbag", o.rosbag);
  v.group("oculus", o.oculus);
  v.group("holoocean", o.holoocean);
}

// sonar3d map: its configuration (the keys of `sonar3d map --print-config`), plus its memory
// limit.
struct SurveyMapOptions {
  MapSurveyConfig map;
  double max_memory_gb = 0;  // 0: the default limit
};
template <class V>
void describe(SurveyMapOptions& o, V& v) {
  describe(o.map, v);  // the map's own keys, at the stage's level
  v.field(o.max_memory_gb,
          params::param("max_memory_gb", "GB",
                        "refuse to start when the map's estimated memory exceeds this (0 = the "
                        "default limit)")
              .non_negative());
}

// sonar3d world: its configuration (the keys of `sonar3d world --print-config`), plus the files
// the command takes as options.
struct SurveyWorldOptions {
  WorldModelConfig model;
  std::string connections;  // YAML of known connections (relative: to the survey file)
  bool glb_all_lods = false;
};
template <class V>
void describe(SurveyWorldOptions& o, V& v) {
  using params::param;
  describe(o.model, v);  // the world's own keys, at the stage's level
  v.field(o.connections, param("connections", "",
                               "YAML of the connections you know ('connections: [{from: riser_0, "
                               "to: tank_0, kind: pipeline}]'); relative to the survey file"));
  v.field(o.glb_all_lods, param("glb_all_lods", "",
                                "world.glb carries every seabed level of detail (else the "
                                "coarsest)"));
}

// sonar3d texture (--dataset: the dataset's camera frames on the corrected navigation): its
// configuration (the keys of `sonar3d texture --print-config`), plus its --drop-uncoloured.
struct SurveyTextureOptions {
  TextureFilesConfig texture;
  bool drop_uncoloured = false;
};
template <class V>
void describe(SurveyTextureOptions& o, V& v) {
  describe(o.texture, v);  // the texture's own keys, at the stage's level
  v.field(o.drop_uncoloured,
          params::param("drop_uncoloured", "",
                        "leave out the points no frame saw (else they are black)"));
}

// sonar3d report: its configuration (the keys of `sonar3d report --print-config`), plus its
// --web-dir. An empty title is "sonar3d survey: <OUT's name>".
struct SurveyReportOptions {
  ReportConfig report;
  std::string web_dir;  // relative: to the survey file
};
template <class V>
void describe(SurveyReportOptions& o, V& v) {
  describe(o.report, v);  // the report's own keys, at the stage's level
  v.field(o.web_dir, params::param("web_dir", "",
                                   "web assets directory (empty: as sonar3d report finds it); "
                                   "relative to the survey file"));
}

struct SurveyConfig {
  SurveyImportOptions import;
  SurveyMapOptions map;
  // sonar3d recognize's configuration, as its --print-config prints it (docs/reference.md).
  RecognizeConfig recognize;
  SurveyWorldOptions world;
  SurveyTextureOptions texture;
  SurveyReportOptions report;
};

// Reads a survey YAML (stage keys import, map, recognize, world, texture, report; each optional):
// unknown keys, wrong types and bad values are Errors naming file, line and key. Paths in it
// (import.aris.navigation, import.oculus.navigation, import.rosbag.sonar_description,
// world.connections, report.web_dir) are taken relative to `base_dir`, by default the file's
// directory (Python's dict configurations: the working directory).
SurveyConfig load_survey_config(const std::string& path,
                                const std::filesystem::path& base_dir = {});
// The whole configuration as that YAML (every key, defaults included): load_survey_config() of
// it gives the same configuration.
std::string survey_config_yaml(const SurveyConfig& config);

struct SurveyStageReport {
  std::string name;    // import, map, recognize, world, texture, report
  std::string status;  // ran, unchanged (skipped: its stamp matched), skipped (not applicable)
  std::string note;    // why skipped, what was used
  double seconds = 0;  // wall time when it ran (or when it last ran, when unchanged)
  double peak_memory_mb = 0;  // peak resident memory of the process during the stage, MB
  std::vector<std::pair<std::string, double>> figures;  // points, swaths, placements, ...
};

struct SurveyResult {
  std::vector<SurveyStageReport> stages;
  std::filesystem::path dataset;  // the dataset mapped (OUT/dataset or INPUT)
  std::string summary_json;       // the text of OUT/summary.json
  double seconds = 0;
};

struct SurveyOptions {
  std::filesystem::path input;        // dataset, .aris, ROS 1/2 bag, HoloOcean dir, Oculus stream
  std::filesystem::path output;       // OUT: new, empty, or a survey directory (resumed)
  std::filesystem::path catalogue;    // empty: no recognition
  std::filesystem::path config_file;  // recorded in summary.json only (config holds its values)
  SurveyConfig config;
  bool progress = true;  // the stages' progress bars on a terminal
  // Called as each stage starts (k of n, 1-based) and ends (status: ran, unchanged, skipped).
  std::function<void(int k, int n, const std::string& stage, const std::string& status)> on_stage;
  std::function<void(const std::string&)> on_warning;
};

// Runs (or resumes) the survey. OUT that exists and is no survey directory (summary.json with
// "format": "sonar3d-survey", or empty) is an Error naming it; so is an input inside OUT.
SurveyResult run_survey(const SurveyOptions& options);

// The kind of input run_survey would import ("dataset", "aris", "rosbag", "holoocean", "oculus");
// an Error naming the path and the kinds accepted otherwise.
std::string survey_input_kind(const std::filesystem::path& input);

}  // namespace sonar3d
