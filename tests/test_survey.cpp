// sonar3d survey (pipeline/survey_pipeline.hpp, docs/survey.md): a small simulated survey through
// every stage; resume (stamps); a changed setting re-runs its stage and the later ones only; a
// failing stage is named and leaves the finished ones in place; the configuration's strictness and
// its printed form; the output rule.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/pipeline/survey_pipeline.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using sonar3d::test::CliRun;
using sonar3d::test::run_cli;

namespace {

// A 10 × 8 m seabed with relief and rocks and a tank, surveyed by a downward-looking
// MB2250-like sonar 4 m up on four East–West lines 2 m apart (804 frames; the recognition tests'
// scene without its pillar).
constexpr const char* kScene = R"(seed: 4
sensor:
  preset: mb2250
  r_min: 1.0
  r_max: 6.0
  range_bins: 250
  T_vehicle_sonar: {rpy_deg: [0, 90, 0]}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: seabed, primitive: {type: terrain, size: [10, 8], cell: 0.05, relief: 0.15, wavelength: 6, trenches: 0, rocks: 8, seed: 4}, reflectivity: 0.3}
  - {name: tank, reference: tank, pose: {translation: [2.2, -1.0, -0.05]}, reflectivity: 0.8}
trajectory: {type: lawnmower, x: [-4, 4], y: [-3, 3], z: 4.0, line_spacing: 2.0, spacing: 0.04, period: 0.1}
)";

nlohmann::json read_json(const fs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Stage name → status of a summary.json.
std::map<std::string, std::string> statuses(const nlohmann::json& summary) {
  std::map<std::string, std::string> s;
  for (const auto& st : summary["stages"]) s[st["name"]] = st["status"];
  return s;
}

fs::file_time_type mtime(const fs::path& p) { return fs::last_write_time(p); }

}  // namespace

TEST(SurveyCli, EndToEndResumesRerunsChangedStagesAndNamesFailures) {
  const fs::path dir = sonar3d::test::temp_dir("e2e");
  { std::ofstream(dir / "scene.yaml") << kScene; }
  {
    std::ofstream(dir / "cat.yaml")
        << "models:\n  - {name: tank, reference: tank, symmetry: full}\n";
  }
  {
    std::ofstream(dir / "survey.yaml")
        << "map: {region: [-5, -4, -1, 5, 4, 1.5], registration: {search_m: 0.3}}\n";
  }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "scene.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  std::size_t ds_files = 0;
  for (auto it = fs::recursive_directory_iterator(dir / "ds"); it != decltype(it)(); ++it) {
    ++ds_files;
  }
  const fs::path out = dir / "out";
  const std::string base = "survey " + (dir / "ds").string() + " -o " + out.string() +
                           " --catalogue " + (dir / "cat.yaml").string();

  // 1. Every stage; the dataset is used in place, read-only.
  r = run_cli(dir, base + " --config " + (dir / "survey.yaml").string());
  ASSERT_EQ(r.code, 0) << r.out;
  // The one progress display: "survey: stage k/6 NAME", then the stage's own.
  int k = 0;
  for (const char* stage : {"import", "map", "recognize", "world", "texture", "report"}) {
    const std::string line = "survey: stage " + std::to_string(++k) + "/6 " + stage;
    EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
  }
  for (const char* f :
       {"map/merged.ply", "map/navigation_corrected.tum", "placements.json", "placements.ply",
        "world/world.glb", "world/graph.json", "report.html", "summary.json"}) {
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  }
  EXPECT_FALSE(fs::exists(out / "dataset"));       // the input is a dataset: not copied
  EXPECT_FALSE(fs::exists(out / "textured.ply"));  // no camera frames
  std::size_t ds_files_after = 0;
  for (auto it = fs::recursive_directory_iterator(dir / "ds"); it != decltype(it)(); ++it) {
    ++ds_files_after;
  }
  EXPECT_EQ(ds_files_after, ds_files);
  nlohmann::json s = read_json(out / "summary.json");
  EXPECT_EQ(s["format"], "sonar3d-survey");
  EXPECT_EQ(s["input_kind"], "dataset");
  ASSERT_EQ(s["stages"].size(), 6u);
  EXPECT_EQ(statuses(s), (std::map<std::string, std::string>{{"import", "skipped"},
                                                             {"map", "ran"},
                                                             {"recognize", "ran"},
                                                             {"world", "ran"},
                                                             {"texture", "skipped"},
                                                             {"report", "ran"}}));
  for (const auto& st : s["stages"]) {
    if (st["status"] != "ran") continue;
    EXPECT_GT(st["seconds"].get<double>(), 0) << st.dump();
    EXPECT_GT(st["peak_memory_mb"].get<double>(), 10) << st.dump();
  }
  const auto& map = s["stages"][1]["figures"];
  EXPECT_EQ(map["swaths"].get<int>(), 4);
  EXPECT_EQ(map["frames"].get<int>(), 804);
  EXPECT_GT(map["points"].get<double>(), 1e5);
  EXPECT_EQ(s["stages"][2]["figures"]["placements"].get<int>(), 1) << s.dump(1);
  EXPECT_EQ(s["stages"][3]["figures"]["objects"].get<int>(), 1);
  const nlohmann::json placements = read_json(out / "placements.json");
  ASSERT_EQ(placements["placements"].size(), 1u);
  EXPECT_EQ(placements["placements"][0]["model"], "tank");
  EXPECT_NEAR(placements["placements"][0]["translation"][0].get<double>(), 2.2, 0.05);
  EXPECT_NEAR(placements["placements"][0]["translation"][1].get<double>(), -1.0, 0.05);

  // 2. A re-run skips every stage: nothing is rewritten.
  const auto t_merged = mtime(out / "map/merged.ply");
  const auto t_placements = mtime(out / "placements.json");
  const auto t_glb = mtime(out / "world/world.glb");
  const auto t_report = mtime(out / "report.html");
  r = run_cli(dir, base + " --config " + (dir / "survey.yaml").string());
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(out / "summary.json");
  EXPECT_EQ(statuses(s), (std::map<std::string, std::string>{{"import", "skipped"},
                                                             {"map", "unchanged"},
                                                             {"recognize", "unchanged"},
                                                             {"world", "unchanged"},
                                                             {"texture", "skipped"},
                                                             {"report", "unchanged"}}));
  EXPECT_EQ(mtime(out / "map/merged.ply"), t_merged);
  EXPECT_EQ(mtime(out / "placements.json"), t_placements);
  EXPECT_EQ(mtime(out / "world/world.glb"), t_glb);
  EXPECT_EQ(mtime(out / "report.html"), t_report);
  // The figures of a skipped stage are those of its run.
  EXPECT_EQ(s["stages"][1]["figures"]["swaths"].get<int>(), 4);

  // 3. A recognize setting changed: recognize and the stages after it run again, map does not.
  {
    std::ofstream(dir / "survey2.yaml")
        << "map: {region: [-5, -4, -1, 5, 4, 1.5], registration: {search_m: 0.3}}\n"
           "recognize: {two_d: {verification: {min_confidence: 0.45}}}\n";
  }
  r = run_cli(dir, base + " --config " + (dir / "survey2.yaml").string());
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(out / "summary.json");
  EXPECT_EQ(statuses(s), (std::map<std::string, std::string>{{"import", "skipped"},
                                                             {"map", "unchanged"},
                                                             {"recognize", "ran"},
                                                             {"world", "ran"},
                                                             {"texture", "skipped"},
                                                             {"report", "ran"}}));
  EXPECT_EQ(mtime(out / "map/merged.ply"), t_merged);
  EXPECT_EQ(read_json(out / "placements.json")["settings"]["min_confidence"].get<double>(), 0.45);

  // 4. --print-config round trip: the printed configuration is the same configuration, so a run
  // with it finds every stage unchanged.
  r = run_cli(dir, "survey --config " + (dir / "survey2.yaml").string() + " --print-config");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("min_confidence: 0.45"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("region: [-5, -4, -1, 5, 4, 1.5]"), std::string::npos) << r.out;
  { std::ofstream(dir / "printed.yaml") << r.out; }
  r = run_cli(dir, base + " --config " + (dir / "printed.yaml").string());
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(out / "summary.json");
  EXPECT_EQ(statuses(s)["map"], "unchanged");
  EXPECT_EQ(statuses(s)["recognize"], "unchanged");
  EXPECT_EQ(statuses(s)["report"], "unchanged");

  // 5. A failing stage is named; the finished stages stay in place.
  { std::ofstream(dir / "bad_cat.yaml") << "models:\n  - {name: tank, mesh: no_such_mesh.obj}\n"; }
  r = run_cli(dir, "survey " + (dir / "ds").string() + " -o " + out.string() + " --catalogue " +
                       (dir / "bad_cat.yaml").string() + " --config " +
                       (dir / "printed.yaml").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("sonar3d: error: survey: stage recognize failed: "), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("no_such_mesh.obj"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::is_regular_file(out / "map/merged.ply"));
  EXPECT_EQ(mtime(out / "map/merged.ply"), t_merged);
  s = read_json(out / "summary.json");
  EXPECT_EQ(s["failed_stage"], "recognize");
  EXPECT_EQ(statuses(s)["map"], "unchanged");
  for (const auto& e : fs::directory_iterator(out)) {  // no staging left behind
    EXPECT_EQ(e.path().filename().string().rfind(".staging", 0), std::string::npos) << e.path();
  }
  // ... and the next good run picks up from the failed stage.
  r = run_cli(dir, base + " --config " + (dir / "printed.yaml").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(out / "summary.json");
  EXPECT_EQ(statuses(s)["map"], "unchanged");
  EXPECT_EQ(statuses(s)["recognize"], "ran");
  EXPECT_FALSE(s.contains("failed_stage"));

  // 6. Without a catalogue recognition is skipped (and its old outputs removed); the world is the
  // seabed alone.
  r = run_cli(dir, "survey " + (dir / "ds").string() + " -o " + out.string() + " --config " +
                       (dir / "printed.yaml").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(out / "summary.json");
  EXPECT_EQ(statuses(s)["recognize"], "skipped");
  EXPECT_EQ(statuses(s)["world"], "ran");
  EXPECT_FALSE(fs::exists(out / "placements.json"));
  EXPECT_EQ(s["stages"][3]["figures"]["objects"].get<int>(), 0);
  fs::remove_all(dir);
}

// OUT that sonar3d did not write is refused, naming it, and left as it was; so is an input.
TEST(SurveyCli, ForeignOutputAndBadInputsAreOneLineErrors) {
  const fs::path dir = sonar3d::test::temp_dir("foreign");
  fs::create_directories(dir / "mine");
  { std::ofstream(dir / "mine/notes.txt") << "mine\n"; }
  fs::create_directories(dir / "in");
  CliRun r = run_cli(dir, "survey " + (dir / "in").string() + " -o " + (dir / "mine").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("sonar3d: error: '" + (dir / "mine").string() + "'"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("is not a sonar3d survey directory"), std::string::npos) << r.out;
  EXPECT_EQ(slurp(dir / "mine/notes.txt"), "mine\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "mine"), fs::directory_iterator()), 1);
  // An input sonar3d cannot survey: the kinds accepted are listed.
  { std::ofstream(dir / "random.bin") << "hello"; }
  r = run_cli(dir, "survey " + (dir / "random.bin").string() + " -o " + (dir / "o").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("is not an input sonar3d can survey"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  // The output inside the input.
  r = run_cli(dir, "survey " + (dir / "in").string() + " -o " + (dir / "in/o").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_FALSE(fs::exists(dir / "in/o"));
  // A configuration key that does not exist: file, line and key.
  { std::ofstream(dir / "bad.yaml") << "map:\n  cell_m: 0.05\n  voxel: 0.02\n"; }
  r = run_cli(dir, "survey --config " + (dir / "bad.yaml").string() + " --print-config");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find((dir / "bad.yaml").string() + ":3: key 'map.voxel': unknown key"),
            std::string::npos)
      << r.out;
  // Missing arguments, and the help names units.
  r = run_cli(dir, "survey " + (dir / "in").string());
  EXPECT_EQ(r.code, 2);
  r = run_cli(dir, "survey --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("metres"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// The configuration: every stage key and option read strictly, printed in full, read back the
// same; relative paths taken from the file's directory.
TEST(SurveyConfig, PrintedConfigurationReadsBackTheSame) {
  const fs::path dir = sonar3d::test::temp_dir("config");
  {
    std::ofstream(dir / "c.yaml")
        << "import: {kind: oculus, oculus: {navigation: nav.tum, mount: [0, 0, 0, 0, 90, 0], "
           "static_sonar: true, vertical_aperture_deg: 8}, rosbag: {sonar_description: "
           "s.yaml}}\n"
           "map: {cell_m: 0.05, method: drift, split: {time_ranges_s: [0, 10, "
           "12, 20]}}\n"
           "recognize: {method: 3d, three_d: {yaw_step_deg: 7.5}, two_d: {run_icp: false}}\n"
           "world: {seabed: {lod_cells_m: [0.1, 0.5]}, min_confidence: 0.3}\n"
           "texture: {max_range_m: 12, warn_dark_share: 0.5, drop_uncoloured: true}\n"
           "report: {title: 'a \"quoted\" title', seed: 7, color: height, web_dir: web}\n";
  }
  const sonar3d::SurveyConfig c = sonar3d::load_survey_config((dir / "c.yaml").string());
  EXPECT_EQ(c.import.kind, "oculus");
  EXPECT_EQ(c.import.oculus.navigation, (dir / "nav.tum").string());
  EXPECT_EQ(c.import.rosbag.sonar_description, (dir / "s.yaml").string());
  EXPECT_TRUE(c.import.oculus.static_sonar);
  EXPECT_EQ(c.import.oculus.mount, (sonar3d::params::List{0, 0, 0, 0, 90, 0}));
  ASSERT_TRUE(c.import.oculus.vertical_aperture_deg.has_value());
  EXPECT_EQ(*c.import.oculus.vertical_aperture_deg, 8);
  EXPECT_FALSE(c.import.aris.vertical_aperture_deg.has_value());  // the other kinds: defaults
  EXPECT_EQ(c.import.holoocean.pose_key, sonar3d::HoloOceanImportConfig().pose_key);
  EXPECT_EQ(c.map.map.cell_m, 0.05);
  EXPECT_EQ(c.map.map.method, sonar3d::SwathAdjustMethod::Drift);
  EXPECT_EQ(c.map.map.carve.voxel_size, sonar3d::MapSurveyConfig().carve.voxel_size);  // default
  EXPECT_EQ(c.map.map.split.time_ranges_s.size(), 4u);
  EXPECT_EQ(c.recognize.method, "3d");
  EXPECT_EQ(c.recognize.three_d.yaw_step_deg, 7.5);
  EXPECT_FALSE(c.recognize.two_d.run_icp);
  EXPECT_EQ(c.recognize.three_d.max_residual_median_m,
            sonar3d::Recognition3dConfig().max_residual_median_m);  // default kept
  EXPECT_EQ(c.world.model.seabed.lod_cells_m, (std::vector<double>{0.1, 0.5}));
  // The texture and report blocks: their commands' declarations (TextureFilesConfig,
  // ReportConfig), plus the survey's drop_uncoloured and web_dir.
  EXPECT_EQ(c.texture.texture.texture.max_range_m, 12);
  EXPECT_EQ(c.texture.texture.poses.warn_dark_share, 0.5);
  EXPECT_TRUE(c.texture.drop_uncoloured);
  EXPECT_EQ(c.report.report.title, "a \"quoted\" title");
  EXPECT_EQ(c.report.report.seed, 7u);
  EXPECT_EQ(c.report.report.color, sonar3d::ReportColor::Height);
  EXPECT_EQ(c.report.web_dir, (dir / "web").lexically_normal().string());
  const std::string printed = sonar3d::survey_config_yaml(c);
  { std::ofstream(dir / "printed.yaml") << printed; }
  const sonar3d::SurveyConfig back = sonar3d::load_survey_config((dir / "printed.yaml").string());
  EXPECT_EQ(sonar3d::survey_config_yaml(back), printed);
  // Defaults are the commands' defaults.
  EXPECT_EQ(sonar3d::SurveyMapOptions().map.split.turn_threshold_deg, 30);
  EXPECT_EQ(sonar3d::SurveyMapOptions().map.method, sonar3d::SwathAdjustMethod::Global);
  // Errors name file, line and key.
  { std::ofstream(dir / "e1.yaml") << "mapping: {}\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e1.yaml").string()); },
                              "e1.yaml:1: key 'mapping': unknown key");
  { std::ofstream(dir / "e2.yaml") << "world:\n  seabed:\n    margin_m: wide\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e2.yaml").string()); },
                              "e2.yaml:3");
  // The import block is the importers' own: their keys, their choices and bounds.
  { std::ofstream(dir / "e4.yaml") << "import:\n  nav: nav.tum\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e4.yaml").string()); },
                              "e4.yaml:2: key 'import.nav': the import block holds each "
                              "importer's own settings under its kind (docs/survey.md): write "
                              "import.aris.navigation, import.oculus.navigation");
  { std::ofstream(dir / "e5.yaml") << "import:\n  aris:\n    clock: gps\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e5.yaml").string()); },
                              "e5.yaml:3");
  { std::ofstream(dir / "e6.yaml") << "import: {kind: sonar}\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e6.yaml").string()); },
                              "must be one of");
  // The texture keys of earlier versions (the flags' names) name the key now.
  { std::ofstream(dir / "e7.yaml") << "texture:\n  max_range: 12\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e7.yaml").string()); },
                              "e7.yaml:2: key 'texture.max_range': the texture block holds the "
                              "keys of `sonar3d texture --print-config` (docs/survey.md): write "
                              "texture.max_range_m");
  { std::ofstream(dir / "e8.yaml") << "report:\n  max_points: 0\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e8.yaml").string()); },
                              "e8.yaml:2");
  { std::ofstream(dir / "e3.yaml") << "report: [1, 2]\n"; }
  sonar3d::test::expect_error([&] { sonar3d::load_survey_config((dir / "e3.yaml").string()); },
                              "expected a map");
  fs::remove_all(dir);
}

// Input kinds by content.
TEST(SurveyConfig, InputKindsAreRecognised) {
  const fs::path dir = sonar3d::test::temp_dir("kinds");
  fs::create_directories(dir / "ds");
  { std::ofstream(dir / "ds/sonar.yaml") << "format: sonar3d-dataset\n"; }
  fs::create_directories(dir / "holo/Data");
  { std::ofstream(dir / "holo/Config.json") << "{}"; }
  fs::create_directories(dir / "bag2");
  { std::ofstream(dir / "bag2/metadata.yaml") << "rosbag2_bagfile_information: {}\n"; }
  { std::ofstream(dir / "x.bag") << "#ROSBAG V2.0\n"; }
  { std::ofstream(dir / "x.aris") << "DDF"; }
  { std::ofstream(dir / "stream.raw", std::ios::binary) << std::string("\x53\x4f\x00\x00", 4); }
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "ds"), "dataset");
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "holo"), "holoocean");
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "bag2"), "rosbag");
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "x.bag"), "rosbag");
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "x.aris"), "aris");
  EXPECT_EQ(sonar3d::survey_input_kind(dir / "stream.raw"), "oculus");
  sonar3d::test::expect_error([&] { sonar3d::survey_input_kind(dir); }, "Oculus ping stream");
  fs::remove_all(dir);
}

// A log with camera frames is textured on the corrected map; a ROS 1 bag is imported first (its
// topics found by message type) into OUT/dataset, then resumed like any survey.
TEST(SurveyCli, TexturesCameraFramesAndImportsABag) {
  const fs::path dir = sonar3d::test::temp_dir("bag");
  {
    std::ofstream(dir / "field.yaml") << R"(seed: 3
)" + sonar3d::test::kDownwardSonarYaml + R"(objects:
  - {name: seabed, primitive: {type: plane, size: [20, 20]}, pose: {translation: [0, 0, 0.013]}, reflectivity: 0.3, kind: terrain, color: [0.8, 0.7, 0.5]}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [2.0, 1.5, 0], rpy_deg: [0, 0, 30]}, reflectivity: 0.8, color: [0.9, 0.8, 0.1]}
camera: {width: 160, height: 120, fx: 100, fy: 100, cx: 79.5, cy: 59.5, T_vehicle_camera: {translation: [0, 0, -0.2], rpy_deg: [180, 0, 90]}, rate_hz: 0.5, ambient: 1, attenuation_per_m: 0}
trajectory: {type: lawnmower, x: [0, 6], y: [0, 4.5], z: 3.0, line_spacing: 1.5, spacing: 0.04, period: 0.1}
)";
  }
  {
    std::ofstream(dir / "survey.yaml")
        << "map: {region: [-1, -1, -0.6, 7, 6, 0.8], registration: {search_m: 0.3}}\n";
  }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "field.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  ASSERT_TRUE(fs::is_directory(dir / "ds/camera"));
  r = run_cli(dir, "survey " + (dir / "ds").string() + " -o " + (dir / "out").string() +
                       " --config " + (dir / "survey.yaml").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  nlohmann::json s = read_json(dir / "out/summary.json");
  EXPECT_EQ(statuses(s)["texture"], "ran") << s.dump(1);
  EXPECT_GT(s["stages"][4]["figures"]["coloured"].get<double>(), 1000) << s.dump(1);
  EXPECT_GT(s["stages"][4]["figures"]["frames"].get<double>(), 10) << s.dump(1);
  EXPECT_TRUE(fs::is_regular_file(dir / "out/textured.ply"));

  r = run_cli(dir, "export rosbag --ros1 " + (dir / "ds").string() + " -o " +
                       (dir / "log.bag").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  // The import block is the importers' own configuration: a setting of the bag's importer
  // reaches the imported dataset (the messages say 1°).
  const auto write_bag_config = [&](const std::string& import) {
    std::ofstream(dir / "bag.yaml")
        << "import: " << import << "\n"
        << "map: {region: [-1, -1, -0.6, 7, 6, 0.8], registration: {search_m: 0.3}}\n";
  };
  write_bag_config("{rosbag: {vertical_aperture_deg: 1.5}}");
  const std::string bag = "survey " + (dir / "log.bag").string() + " -o " +
                          (dir / "bag_out").string() + " --config " + (dir / "bag.yaml").string() +
                          " -q";
  r = run_cli(dir, bag);
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(dir / "bag_out/summary.json");
  EXPECT_EQ(s["input_kind"], "rosbag");
  EXPECT_EQ(statuses(s)["import"], "ran");
  EXPECT_EQ(s["stages"][0]["figures"]["frames"].get<int>(), 604) << s.dump(1);
  EXPECT_NE(s["stages"][0]["note"].get<std::string>().find("sonar topic"), std::string::npos);
  EXPECT_EQ(statuses(s)["texture"], "skipped");  // the bag carries no camera images
  EXPECT_TRUE(fs::is_regular_file(dir / "bag_out/dataset/sonar.yaml"));
  EXPECT_TRUE(fs::is_regular_file(dir / "bag_out/map/merged.ply"));
  EXPECT_NEAR(sonar3d::read_dataset(dir / "bag_out/dataset").spec.vertical_aperture_rad,
              1.5 * M_PI / 180, 1e-9);
  // Another kind's block is not this import's setting: nothing re-runs.
  write_bag_config("{rosbag: {vertical_aperture_deg: 1.5}, aris: {clock: sonar}}");
  r = run_cli(dir, bag);
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(dir / "bag_out/summary.json");
  EXPECT_EQ(statuses(s)["import"], "unchanged");
  EXPECT_EQ(statuses(s)["map"], "unchanged");
  // The bag importer's own setting changed: the import runs again (and the stages after it).
  write_bag_config("{rosbag: {vertical_aperture_deg: 1}}");
  r = run_cli(dir, bag);
  ASSERT_EQ(r.code, 0) << r.out;
  s = read_json(dir / "bag_out/summary.json");
  EXPECT_EQ(statuses(s)["import"], "ran");
  EXPECT_EQ(statuses(s)["map"], "ran");
  EXPECT_NEAR(sonar3d::read_dataset(dir / "bag_out/dataset").spec.vertical_aperture_rad, M_PI / 180,
              1e-9);
  fs::remove_all(dir);
}
