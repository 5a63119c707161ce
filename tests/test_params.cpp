// One declaration per parameter (core/params.hpp, docs/design.md "Parameters"): the bounds, the
// YAML round trip, the command line's --print-config/--config, and docs/reference.md generated
// from the declarations (kept current here).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/io/preview.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "sonar3d/pipeline/online_recognition.hpp"
#include "sonar3d/plan/sweep.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/sim/benchmark.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/change.hpp"
#include "sonar3d/world/relocalize.hpp"
#include "sonar3d/world/world_model.hpp"
#include "test_support.hpp"

using namespace sonar3d;
namespace fs = std::filesystem;
using sonar3d::test::read_all;
using sonar3d::test::run_cli_captured;

namespace {

std::string emit(const RecognizeConfig& c) {
  YAML::Emitter out;
  params::emit_yaml(out, c);
  return out.c_str();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

fs::path tmp_dir() {
  const fs::path d = fs::temp_directory_path() /
                     ("sonar3d_test_params_" +
                      std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A 30 cm sphere's surface, sampled: a cloud to map, score and show.
PointCloud sphere_cloud() {
  PointCloud c;
  const TriangleMesh m = make_sphere(0.3, 24);
  for (const auto& v : m.vertices) c.points.push_back(v + Eigen::Vector3f(1, 2, 0));
  c.intensity.assign(c.points.size(), 1.0f);
  return c;
}

// The configuration `command` prints with `flags`, written to dir/cfg.yaml; checks that a run
// from it prints it again, byte for byte, and that it holds each of `want`.
std::string print_and_reread(const fs::path& dir, const std::string& command,
                             const std::string& flags, const std::vector<std::string>& want) {
  const auto a = run_cli_captured(dir, command + " --print-config " + flags);
  EXPECT_EQ(a.code, 0) << a.err;
  for (const std::string& w : want)
    EXPECT_NE(a.out.find(w), std::string::npos) << w << "\n" << a.out;
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, command + " --print-config --config " + (dir / "cfg.yaml").string());
  EXPECT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out) << command;
  return a.out;
}

// The reference of every configuration declared with core/params.hpp.
std::string reference() {
  std::string out =
      "# Configuration reference\n\n"
      "Generated from the parameters' one declaration (core/params.hpp, docs/design.md "
      "\"Parameters\"); `tests/test_params.cpp` fails when this file is not current (regenerate: "
      "`SONAR3D_UPDATE_REFERENCE=1 build/tests/test_params`). Each key is the YAML key under the "
      "command's block (as `--print-config` prints it) and the Python attribute; the flag, when "
      "there is one, sets it on the command line.\n\n";
  out += params::reference_markdown(
      "recognize",
      "`sonar3d recognize --print-config` prints these under `recognize:`; Python: "
      "`sonar3d.RecognizeConfig` (groups as attributes: `cfg.two_d.verification.min_confidence`).",
      params::rows(RecognizeConfig()));
  out += "\n";
  out += params::reference_markdown(
      "reconstruct",
      "`sonar3d reconstruct --print-config` prints these under `reconstruct:`; Python: "
      "`sonar3d.ReconstructConfig` (`cfg.deconv.mode = \"voxel\"`) and "
      "`sonar3d.reconstruct(dataset, config=cfg)`. The settings every method shares (voxel size, "
      "region, denoising, observation filter, occlusion resolution, threads) are declared once "
      "at the top; `carve`, `deconv` and `bracket` hold what only that step has.",
      params::rows(ReconstructConfig()));
  out += "\n";
  out += params::reference_markdown(
      "relocalize",
      "`sonar3d relocalize --print-config` prints these under `relocalize:`; Python: "
      "`sonar3d.RelocalizeConfig` (docs/mapping.md \"Relocalisation\").",
      params::rows(RelocalizeConfig()));
  out += "\n";
  out += params::reference_markdown(
      "elevation",
      "`sonar3d elevation --print-config` prints these under `elevation:`; Python: "
      "`sonar3d.ElevationMapConfig` (`sonar3d.elevation_map(points, cell_m=0.05)`) and "
      "`sonar3d.ElevationWriteOptions` (`sonar3d.write_elevation_geotiff(path, map, "
      "uint16_step_m=0.001)`) (docs/mapping.md).",
      params::rows(ElevationFileConfig()));
  out += "\n";
  out += params::reference_markdown(
      "evaluate",
      "`sonar3d evaluate --print-config` prints these under `evaluate:`; Python: "
      "`sonar3d.EvalConfig` and `sonar3d.evaluate(points, mesh, cfg)`, "
      "`sonar3d.evaluate_dataset(points, dataset, cfg)` (thesis sec. 4.5.2.1; README.md).",
      params::rows(EvalConfig()));
  out += "\n";
  out += params::reference_markdown(
      "report",
      "`sonar3d report --print-config` prints these under `report:` (the survey's `report:` "
      "block takes them too, with `web_dir`; docs/survey.md); the page's inputs (placements, "
      "catalogue, overlays, -o) and --web-dir are flags only (docs/report.md).",
      params::rows(ReportConfig()));
  out += "\n";
  out += params::reference_markdown(
      "simulate",
      "`sonar3d simulate --print-config` prints these under `simulate:`; the scene file holds "
      "everything else (docs/formats.md). Python: `sonar3d.simulate(scene, output, seed=None)`.",
      params::rows(SimulateConfig()));
  out += "\n";
  out += params::reference_markdown(
      "plan",
      "`sonar3d plan --print-config` prints these under `plan:`; the sweep file holds everything "
      "the points run with (docs/planner.md).",
      params::rows(PlanConfig()));
  out += "\n";
  out += params::reference_markdown(
      "export rosbag",
      "`sonar3d export rosbag --print-config` prints these under `export:`; `--ros1` sets `wire` "
      "to ros1 (docs/import.md).",
      params::rows(RosbagExportConfig()));
  out += "\n";
  out += params::reference_markdown(
      "preview",
      "`sonar3d preview --print-config` prints these under `preview:`; the frame (`--frame`) is "
      "a flag only.",
      params::rows(PreviewConfig()));
  out += "\n";
  out += params::reference_markdown(
      "bench",
      "`sonar3d bench --print-config` prints these under `bench:`: the benchmark's sonar and run "
      "on the thesis' pipeline scene (sec. 2.5.2; docs/performance.md).",
      params::rows(SimBenchConfig()));
  out += "\n";
  out += params::reference_markdown(
      "diff",
      "`sonar3d diff --print-config` prints these under `diff:`; Python: `sonar3d.ChangeConfig` "
      "and `sonar3d.diff_surveys(a, b, config=cfg)` (docs/change.md).",
      params::rows(ChangeConfig()));
  out += "\n";
  out += params::reference_markdown(
      "world",
      "`sonar3d world --print-config` prints these under `world:` (the survey's `world:` block "
      "takes them too); Python: `sonar3d.WorldModelConfig` and `sonar3d.world_model(points, "
      "placements, catalogue, config=cfg)` (docs/world.md).",
      params::rows(WorldModelConfig()));
  out += "\n";
  out += params::reference_markdown(
      "map",
      "`sonar3d map --print-config` prints these under `map:` (the survey's `map:` block takes "
      "them too, with `max_memory_gb`); Python: `sonar3d.MapSurveyConfig` and "
      "`sonar3d.map_survey(dataset, output, config=cfg)` (docs/mapping.md). `carve` holds the "
      "carving settings the map leaves to the carving (voxel size, region and threads are the "
      "map's).",
      params::rows(MapSurveyConfig()));
  out += "\n";
  out += params::reference_markdown(
      "register",
      "`sonar3d register --print-config` prints these under `register:`; Python: "
      "`sonar3d.SwathRegistrationConfig` and `sonar3d.register_elevation_maps(a, b, cfg)`.",
      params::rows(SwathRegistrationConfig()));
  out += "\n";
  out += params::reference_markdown(
      "texture",
      "`sonar3d texture --print-config` prints these under `texture:`: the colouring's settings "
      "(Python: `sonar3d.TextureConfig`, `sonar3d.TexturePosesConfig`) and how the poses of "
      "`--neus`/`--colmap` relate to the "
      "cloud's world, with when to warn that they may not (docs/video.md \"Camera world\").",
      params::rows(TextureFilesConfig()));
  out += "\n";
  out += params::reference_markdown(
      "ros",
      "`sonar3d ros --print-config` prints these under `online_recognition:`, beside its "
      "`reconstruct:` and `recognize:` blocks (the tables above); used with `--catalogue` "
      "(docs/online.md \"Recognised placements\").",
      params::rows(OnlineRecognitionConfig()));
  // The importers: `sonar3d import <kind>` prints its settings under `import:`.
  const char* kImportIntro =
      "`sonar3d import {} --print-config` prints these under `import:`{}; Python: `sonar3d.{}` "
      "and `sonar3d.import_{}(..., config=cfg)` or keywords (docs/import.md).";
  // The survey's import block holds one such block per kind of log (not frames).
  const auto intro = [&](const std::string& kind, const std::string& cls, bool survey = true) {
    std::string t = kImportIntro;
    const std::string in_survey =
        survey ? " (the survey's `import:` block takes them under `" + kind + ":`, docs/survey.md)"
               : "";
    for (const std::string& v : {kind, in_survey, cls, kind}) t.replace(t.find("{}"), 2, v);
    return t;
  };
  out += "\n";
  out += params::reference_markdown("import aris", intro("aris", "ArisImportConfig"),
                                    params::rows(ArisImportConfig()));
  out += "\n";
  out += params::reference_markdown("import rosbag", intro("rosbag", "RosbagImportConfig"),
                                    params::rows(RosbagImportConfig()));
  out += "\n";
  out += params::reference_markdown("import oculus", intro("oculus", "OculusImportConfig"),
                                    params::rows(OculusImportConfig()));
  out += "\n";
  out += params::reference_markdown("import holoocean", intro("holoocean", "HoloOceanImportConfig"),
                                    params::rows(HoloOceanImportConfig()));
  out += "\n";
  out += params::reference_markdown(
      "import frames",
      intro("frames", "FrameImportConfig", false) +
          " The sensor is not a setting: `--sonar sonar.yaml` (Python: `sonar=`).",
      params::rows(FrameImportConfig()));
  return out;
}

}  // namespace

TEST(Params, BoundsNameTheFieldAndItsFlag) {
  RecognizeConfig c;
  c.two_d.verification.min_confidence = 1.5;
  const std::string e = error_of([&] { c.validate(); });
  EXPECT_NE(e.find("verification.min_confidence"), std::string::npos) << e;
  EXPECT_NE(e.find("--min-confidence"), std::string::npos) << e;
  EXPECT_NE(e.find("[0, 1]"), std::string::npos) << e;
  c = RecognizeConfig();
  c.method = "3d";
  c.three_d.period_fraction = 0.01;  // open lower bound 0.05
  EXPECT_NE(error_of([&] { c.validate(); }).find("(0.05, 4]"), std::string::npos);
  c.three_d.period_fraction = std::nan("");
  EXPECT_NE(error_of([&] { c.validate(); }).find("period_fraction"), std::string::npos);
}

TEST(Params, YamlRoundTripIsExact) {
  RecognizeConfig c;
  c.method = "3d";
  c.two_d.map_cell_m = 0.1 + 0.2;  // not a short decimal: the shortest exact form is written
  c.two_d.run_icp = false;
  c.three_d.max_subspaces = 12345;
  c.two_d.sampling.seed = 18446744073709551615ull;
  const std::string text = emit(c);
  RecognizeConfig back;
  params::read_yaml(YAML::Load(text), "mem.yaml", "", back);
  EXPECT_EQ(back.two_d.map_cell_m, c.two_d.map_cell_m);
  EXPECT_EQ(back.method, "3d");
  EXPECT_FALSE(back.two_d.run_icp);
  EXPECT_EQ(back.three_d.max_subspaces, 12345u);
  EXPECT_EQ(emit(back), text);
}

TEST(Params, YamlErrorsNameFileLineAndKey) {
  RecognizeConfig c;
  const auto read = [&](const std::string& text) {
    return error_of([&] { params::read_yaml(YAML::Load(text), "cfg.yaml", "recognize", c); });
  };
  EXPECT_NE(read("two_d: {map_cel_m: 1}").find("recognize.two_d.map_cel_m"), std::string::npos);
  EXPECT_NE(read("two_d: {map_cell_m: abc}").find("expected a finite number"), std::string::npos);
  EXPECT_NE(read("two_d: {map_cell_m: .nan}").find("expected a finite number"), std::string::npos);
  EXPECT_NE(read("two_d: {max_rejections: 2.5}").find("whole number"), std::string::npos);
  EXPECT_NE(read("two_d: {max_rejections: 0}").find("[1, 100]"), std::string::npos);
  EXPECT_NE(read("two_d: {run_icp: maybe}").find("true or false"), std::string::npos);
  EXPECT_NE(read("two_d: 3").find("expected a map"), std::string::npos);
  EXPECT_NE(read("two_d:\n  verification: {min_confidence: 7}").find("cfg.yaml:2"),
            std::string::npos);
}

TEST(Params, CliPrintConfigRunsBackByteForByte) {
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(dir,
                                  "recognize --print-config --method 3d --min-confidence 0.7 "
                                  "--no-icp --max-subspaces 5000");
  ASSERT_EQ(a.code, 0) << a.err;
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "recognize --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);  // the file reproduces the configuration that printed it
  EXPECT_NE(a.out.find("min_confidence: 0.7"), std::string::npos);
  EXPECT_NE(a.out.find("max_subspaces: 5000"), std::string::npos);
  // Flags override the file.
  const auto c = run_cli_captured(
      dir, "recognize --print-config --config " + (dir / "cfg.yaml").string() + " --method 2d");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("method: \"2d\""), std::string::npos);
  EXPECT_NE(c.out.find("min_confidence: 0.7"), std::string::npos);
  // A bad file: one line naming it.
  std::ofstream(dir / "bad.yaml") << "recognize:\n  two_d: {min_confidence: 0.7}\n";
  const auto d =
      run_cli_captured(dir, "recognize --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("bad.yaml:2"), std::string::npos) << d.err;
  EXPECT_NE(d.err.find("unknown key"), std::string::npos) << d.err;
  fs::remove_all(dir);
}

TEST(Params, ReconstructPrintConfigRunsBackByteForByte) {
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(dir,
                                  "reconstruct --print-config --method deconv --deconv-mode voxel "
                                  "--voxel-size 0.02 --roi -1 -2 -3 1 2 3 --no-dering --beam flat "
                                  "--explain-returns --min-bracket 0.25 --threads 1");
  ASSERT_EQ(a.code, 0) << a.err;
  for (const char* want :
       {"method: \"deconv\"", "voxel_size: 0.02", "region: [-1, -2, -3, 1, 2, 3]", "mode: voxel",
        "dering: false", "beam: flat", "explain_returns: true", "min_bracket: 0.25"}) {
    EXPECT_NE(a.out.find(want), std::string::npos) << want << "\n" << a.out;
  }
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "reconstruct --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  // The library reads the same file into the same configuration.
  ReconstructConfig lib;
  params::read_yaml(YAML::LoadFile((dir / "cfg.yaml").string())["reconstruct"], "cfg.yaml",
                    "reconstruct", lib);
  EXPECT_EQ(lib.method, "deconv");
  EXPECT_EQ(lib.deconv.mode, DeconvConfig::Mode::Voxel);
  EXPECT_EQ(lib.effective_deconv().voxel.voxel_size, 0.02);  // the one voxel size
  EXPECT_FALSE(lib.deconv.dering);
  ASSERT_TRUE(lib.region.has_value());
  EXPECT_EQ(lib.region->max().z(), 3.0);
  // A choice outside the declared ones: one line naming the file, line and the choices.
  std::ofstream(dir / "bad.yaml") << "reconstruct:\n  deconv:\n    mode: orbit\n";
  const auto c =
      run_cli_captured(dir, "reconstruct --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(c.code, 0);
  EXPECT_NE(c.err.find("bad.yaml:3"), std::string::npos) << c.err;
  EXPECT_NE(c.err.find("passes, voxel or auto"), std::string::npos) << c.err;
  // A shared setting is not a method's: deconv.voxel.voxel_size is no key.
  std::ofstream(dir / "dup.yaml")
      << "reconstruct:\n  deconv:\n    voxel:\n      voxel_size: 0.05\n";
  const auto d =
      run_cli_captured(dir, "reconstruct --print-config --config " + (dir / "dup.yaml").string());
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("unknown key"), std::string::npos) << d.err;
  // Out-of-bounds flags name the flag.
  const auto e = run_cli_captured(dir, "reconstruct --print-config --voxel-size 0");
  EXPECT_NE(e.code, 0);
  fs::remove_all(dir);
}

TEST(Params, DiffPrintConfigRunsBackByteForByte) {
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(dir,
                                  "diff --print-config --colour-space lab --cell 0.05 --search 0.8 "
                                  "--threads 1 --turn-tol-deg 5");
  ASSERT_EQ(a.code, 0) << a.err;
  for (const char* want :
       {"space: lab", "cell_m: 0.05", "search_m: 0.8", "num_threads: 1", "turn_tol_deg: 5"}) {
    EXPECT_NE(a.out.find(want), std::string::npos) << want << "\n" << a.out;
  }
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "diff --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  ChangeConfig lib;
  params::read_yaml(YAML::LoadFile((dir / "cfg.yaml").string())["diff"], "cfg.yaml", "diff", lib);
  EXPECT_EQ(lib.colour.space, ColourSpace::Lab);
  EXPECT_EQ(lib.registration.search_m, 0.8);
  // A cross-field rule names the field; an out-of-bounds flag names the flag.
  const auto c =
      run_cli_captured(dir, "diff --print-config --registration-cell 0.5 --yaw-cell 0.2");
  EXPECT_NE(c.code, 0);
  EXPECT_NE(c.err.find("yaw_cell_m"), std::string::npos) << c.err;
  const auto d = run_cli_captured(dir, "diff --print-config --k-sigma -1");
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("--k-sigma"), std::string::npos) << d.err;
  // Without --print-config, A, B and -o are required (usage error).
  EXPECT_EQ(run_cli_captured(dir, "diff").code, 2);
  fs::remove_all(dir);
}

TEST(Params, WorldPrintConfigRunsBackByteForByte) {
  // A list (levels of detail), an optional number (unset: the placements file's threshold) and
  // switches turned by their flags.
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(
      dir, "world --print-config --lod-cells 0.1,0.3 --no-fill --no-connections --min-ridge 0.1");
  ASSERT_EQ(a.code, 0) << a.err;
  for (const char* want : {"lod_cells_m: [0.1, 0.3]", "fill_footprints: false",
                           "find_connections: false", "min_ridge_m: 0.1", "min_confidence: ~"}) {
    EXPECT_NE(a.out.find(want), std::string::npos) << want << "\n" << a.out;
  }
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "world --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  WorldModelConfig lib;
  params::read_yaml(YAML::LoadFile((dir / "cfg.yaml").string())["world"], "cfg.yaml", "world", lib);
  EXPECT_EQ(lib.seabed.lod_cells_m, (std::vector<double>{0.1, 0.3}));
  EXPECT_FALSE(lib.min_confidence.has_value());
  const auto c = run_cli_captured(dir, "world --print-config --min-confidence 0.4");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("min_confidence: 0.4"), std::string::npos) << c.out;
  // The levels' rule (integer multiples) and an element out of bounds, named.
  const auto d = run_cli_captured(dir, "world --print-config --lod-cells 0.1,0.25");
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("--lod-cells: 0.25 m is not an integer multiple"), std::string::npos)
      << d.err;
  std::ofstream(dir / "bad.yaml") << "world:\n  seabed:\n    lod_cells_m: [0.1, -1]\n";
  const auto e =
      run_cli_captured(dir, "world --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("bad.yaml:3"), std::string::npos) << e.err;
  EXPECT_NE(e.err.find("position 2"), std::string::npos) << e.err;
  EXPECT_EQ(run_cli_captured(dir, "world").code, 2);
  fs::remove_all(dir);
}

TEST(Params, MapPrintConfigRunsBackByteForByte) {
  // An enum, a box, a list of time ranges, a switch turned by its flag, nested carving settings.
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(
      dir,
      "map --print-config --method drift --roi -1 -2 -3 1 2 3 --swath-times 0,5,7,12 "
      "--fixes-shift-only --resolution 0.05 --search 0.3 --turn-deg 45 --carve-margin 0.5");
  ASSERT_EQ(a.code, 0) << a.err;
  for (const char* want :
       {"method: drift", "region: [-1, -2, -3, 1, 2, 3]", "time_ranges_s: [0, 5, 7, 12]",
        "fix_scale_heading: false", "cell_m: 0.05", "search_m: 0.3", "turn_threshold_deg: 45",
        "carve_margin: 0.5"}) {
    EXPECT_NE(a.out.find(want), std::string::npos) << want << "\n" << a.out;
  }
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "map --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  MapSurveyConfig lib;
  params::read_yaml(YAML::LoadFile((dir / "cfg.yaml").string())["map"], "cfg.yaml", "map", lib);
  EXPECT_EQ(lib.method, SwathAdjustMethod::Drift);
  EXPECT_EQ(lib.split.time_ranges_s, (std::vector<double>{0, 5, 7, 12}));
  EXPECT_EQ(lib.registration.search_m, 0.3);
  EXPECT_FALSE(lib.fix_scale_heading);
  // Space-separated times still work; an odd count and an out-of-bounds value name the flag.
  const auto c = run_cli_captured(dir, "map --print-config --swath-times 0 5");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("time_ranges_s: [0, 5]"), std::string::npos) << c.out;
  const auto d = run_cli_captured(dir, "map --print-config --swath-times 0,5,7");
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("--swath-times"), std::string::npos) << d.err;
  const auto e = run_cli_captured(dir, "map --print-config --turn-deg 200");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--turn-deg must lie in (0, 180)"), std::string::npos) << e.err;
  // Without --print-config, the dataset and -o are required (usage error).
  EXPECT_EQ(run_cli_captured(dir, "map").code, 2);
  // register: the same registration declaration, its own block.
  const auto r = run_cli_captured(dir, "register --print-config --search 0.2 --coarse-factor 2");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("register:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("search_m: 0.2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("coarse_factor: 2"), std::string::npos) << r.out;
  EXPECT_EQ(run_cli_captured(dir, "register").code, 2);
  fs::remove_all(dir);
}

TEST(Params, ReconstructSettingsAsJson) {
  ReconstructConfig c;
  c.region = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 3));
  c.deconv.kernel = DeconvConfig::Kernel::NormalOcclusion;
  const std::string j = params::to_json(c);
  EXPECT_NE(j.find("\"region\": [0, 0, 0, 1, 2, 3]"), std::string::npos) << j;
  EXPECT_NE(j.find("\"kernel\": \"normal+occlusion\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"carve\": {\"occlusion\": {"), std::string::npos) << j;
  EXPECT_EQ(std::count(j.begin(), j.end(), '{'), std::count(j.begin(), j.end(), '}'));
}

TEST(Params, ReferenceIsCurrent) {
  const fs::path path = fs::path(SONAR3D_SOURCE_DIR) / "docs/reference.md";
  const std::string want = reference();
  if (const char* u = std::getenv("SONAR3D_UPDATE_REFERENCE"); u && std::string(u) == "1") {
    std::ofstream(path, std::ios::trunc) << want;
  }
  EXPECT_EQ(read_all(path), want)
      << "docs/reference.md is not current: SONAR3D_UPDATE_REFERENCE=1 build/tests/test_params";
}

TEST(Params, ImportPrintConfigRunsBackByteForByte) {
  // Every importer: enums, a mounting list, an optional aperture, switches, the CSV group.
  const fs::path dir = tmp_dir();
  struct Case {
    std::string command;
    std::vector<std::string> want;
  };
  const std::vector<Case> cases = {
      {"import aris --nav-source static --clock sonar --mount 0.4,0,-0.2,0,20,0 "
       "--vertical-aperture-deg 12 --angles rad --nav-convention ned --drop-partial "
       "--time-offset 0.5",
       {"nav_source: static", "clock: sonar", "mount: [0.4, 0, -0.2, 0, 20, 0]",
        "vertical_aperture_deg: 12", "angles: rad", "convention: ned", "drop_partial: true",
        "time_offset: 0.5"}},
      {"import rosbag --sonar-topic /sonar --static --mount 0,0,0,0,90,0 --base-frame base_link "
       "--drop-outside",
       {"sonar_topic: \"/sonar\"", "static_sonar: true", "mount: [0, 0, 0, 0, 90, 0]",
        "base_frame: \"base_link\"", "vertical_aperture_deg: ~", "drop_outside: true"}},
      {"import oculus --static --clock rate --rate 10 --gains divide --mirror",
       {"static_sonar: true", "clock: rate", "rate_hz: 10", "gains: divide", "mirror: true"}},
      {"import holoocean --bins cell --rate 5 --pose-key P",
       {"bins: cell", "frame_rate_hz: 5", "pose_key: \"P\""}},
      {"import frames --images img --times t.csv --nav nav.csv --nav-format csv",
       {"images_dir: \"img\"", "times_csv: \"t.csv\"", "navigation: \"nav.csv\"",
        "navigation_format: \"csv\""}},
  };
  for (const Case& k : cases) {
    const auto a = run_cli_captured(dir, k.command + " --print-config");
    ASSERT_EQ(a.code, 0) << k.command << "\n" << a.err;
    EXPECT_NE(a.out.find("import:"), std::string::npos) << a.out;
    for (const std::string& w : k.want) {
      EXPECT_NE(a.out.find(w), std::string::npos) << k.command << ": " << w << "\n" << a.out;
    }
    std::ofstream(dir / "cfg.yaml") << a.out;
    const std::string kind = k.command.substr(0, k.command.find(' ', 7));
    const auto b =
        run_cli_captured(dir, kind + " --print-config --config " + (dir / "cfg.yaml").string());
    ASSERT_EQ(b.code, 0) << b.err;
    EXPECT_EQ(a.out, b.out) << kind;
  }
  // Flags override the file.
  const auto o =
      run_cli_captured(dir, "import oculus --print-config --clock ping --rate 0 --config " +
                                (dir / "cfg.yaml").string());
  // (cfg.yaml is the frames block now: an oculus run refuses its keys, naming them.)
  EXPECT_NE(o.code, 0);
  EXPECT_NE(o.err.find("images_dir"), std::string::npos) << o.err;
  const auto p1 = run_cli_captured(dir, "import aris --print-config --clock sonar");
  std::ofstream(dir / "aris.yaml") << p1.out;
  const auto p2 = run_cli_captured(
      dir, "import aris --print-config --clock pc --config " + (dir / "aris.yaml").string());
  ASSERT_EQ(p2.code, 0) << p2.err;
  EXPECT_NE(p2.out.find("clock: pc"), std::string::npos) << p2.out;
  // Bad values name the flag (or the file, line and key).
  const auto e1 = run_cli_captured(dir, "import aris --print-config --vertical-aperture-deg 200");
  EXPECT_NE(e1.code, 0);
  EXPECT_NE(e1.err.find("--vertical-aperture-deg must lie in [0.01, 180) deg"), std::string::npos)
      << e1.err;
  const auto e2 = run_cli_captured(dir, "import oculus --print-config --mount 1,2,3");
  EXPECT_NE(e2.code, 0);
  EXPECT_NE(e2.err.find("--mount"), std::string::npos) << e2.err;
  const auto e3 = run_cli_captured(dir, "import aris --print-config --nav-format kml");
  EXPECT_NE(e3.code, 0);
  EXPECT_NE(e3.err.find("--nav-format must be tum, csv or empty"), std::string::npos) << e3.err;
  std::ofstream(dir / "bad.yaml") << "import:\n  mount: [1, 2]\n";
  const auto e4 =
      run_cli_captured(dir, "import rosbag --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(e4.code, 0);
  EXPECT_NE(e4.err.find("--mount must hold 6 numbers"), std::string::npos) << e4.err;
  std::ofstream(dir / "bad2.yaml") << "import:\n  navigation_csv: {angles: grad}\n";
  const auto e5 =
      run_cli_captured(dir, "import aris --print-config --config " + (dir / "bad2.yaml").string());
  EXPECT_NE(e5.code, 0);
  EXPECT_NE(e5.err.find("bad2.yaml:2"), std::string::npos) << e5.err;
  EXPECT_NE(e5.err.find("deg or rad"), std::string::npos) << e5.err;
  // Without --print-config the recording and -o are required (usage error).
  EXPECT_EQ(run_cli_captured(dir, "import aris").code, 2);
  EXPECT_EQ(run_cli_captured(dir, "import frames -o x").code, 2);
  fs::remove_all(dir);
}

TEST(Params, ImportArisFromPrintedConfigWritesTheSameDataset) {
  // A run from the configuration a run printed writes the same dataset, byte for byte.
  const fs::path dir = tmp_dir();
  std::vector<ArisWriteFrame> frames(3);
  for (std::size_t k = 0; k < frames.size(); ++k) {
    ArisFrameHeader& h = frames[k].header;
    h.frame_index = static_cast<std::uint32_t>(k);
    h.ping_mode = 1;  // 48 beams
    h.sound_speed = 1500.0f;
    h.sample_period_us = 20;
    h.sample_start_delay_us = 1600;
    h.samples_per_beam = 40;
    h.frame_time_us = 1000000 + 100000 * k;
    h.sonar_time_us = h.frame_time_us + 5000;
    frames[k].samples.resize(48 * 40);
    for (std::size_t i = 0; i < frames[k].samples.size(); ++i) {
      frames[k].samples[i] = static_cast<std::uint8_t>((i * 7 + k * 13) % 256);
    }
  }
  write_aris(dir / "f.aris", frames);
  const std::string flags =
      "--nav-source static --clock sonar --mount 0.4,0,-0.2,0,20,0 --vertical-aperture-deg 12";
  const auto a = run_cli_captured(dir, "import aris " + (dir / "f.aris").string() + " -o " +
                                           (dir / "a").string() + " " + flags);
  ASSERT_EQ(a.code, 0) << a.err;
  const auto p = run_cli_captured(dir, "import aris " + flags + " --print-config");
  ASSERT_EQ(p.code, 0) << p.err;
  std::ofstream(dir / "cfg.yaml") << p.out;
  const auto b =
      run_cli_captured(dir, "import aris " + (dir / "f.aris").string() + " -o " +
                                (dir / "b").string() + " --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  for (const char* f : {"sonar.yaml", "frames.csv", "navigation.tum", "frames/000002.png"}) {
    EXPECT_EQ(read_all(dir / "a" / f), read_all(dir / "b" / f)) << f;
  }
  EXPECT_NE(read_all(dir / "a" / "sonar.yaml").find("12"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Params, RelocalizePrintConfigRunsBackByteForByte) {
  // The registration nested (its threads are relocalize's), the swath split, a switch-less config.
  const fs::path dir = tmp_dir();
  const auto a = run_cli_captured(dir,
                                  "relocalize --print-config --voxel-size 0.04 --search 0.6 "
                                  "--yaw-search-deg 3 --min-overlap 0.4 --piece 0 --turn-deg 50 "
                                  "--threads 1");
  ASSERT_EQ(a.code, 0) << a.err;
  for (const char* want :
       {"relocalize:", "voxel_m: 0.04", "search_m: 0.6", "yaw_search_deg: 3",
        "min_overlap_fraction: 0.4", "piece_m: 0", "turn_threshold_deg: 50", "num_threads: 1"}) {
    EXPECT_NE(a.out.find(want), std::string::npos) << want << "\n" << a.out;
  }
  std::ofstream(dir / "cfg.yaml") << a.out;
  const auto b =
      run_cli_captured(dir, "relocalize --print-config --config " + (dir / "cfg.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  RelocalizeConfig lib;
  params::read_yaml(YAML::LoadFile((dir / "cfg.yaml").string())["relocalize"], "cfg.yaml",
                    "relocalize", lib);
  EXPECT_EQ(lib.voxel_m, 0.04);
  EXPECT_EQ(lib.registration.search_m, 0.6);
  EXPECT_EQ(lib.split.turn_threshold_deg, 50);
  EXPECT_EQ(lib.piece_m, 0);
  // Flags override the file.
  const auto c = run_cli_captured(
      dir, "relocalize --print-config --config " + (dir / "cfg.yaml").string() + " --piece 4");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("piece_m: 4"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("voxel_m: 0.04"), std::string::npos) << c.out;
  // Errors name the user's flag: a bound, and a cross-field rule.
  const auto d = run_cli_captured(dir, "relocalize --print-config --min-overlap 0");
  EXPECT_NE(d.code, 0);
  EXPECT_NE(d.err.find("--min-overlap"), std::string::npos) << d.err;
  const auto e =
      run_cli_captured(dir, "relocalize --print-config --search 0.05 --registration-cell 0.1");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--search must be at least one cell (--registration-cell)"),
            std::string::npos)
      << e.err;
  // Without --print-config the dataset, --world and -o are required (usage error).
  EXPECT_EQ(run_cli_captured(dir, "relocalize").code, 2);
  fs::remove_all(dir);
}

TEST(Params, ElevationFromPrintedConfigWritesTheSameGeoTiff) {
  const fs::path dir = tmp_dir();
  write_ply((dir / "c.ply").string(), sphere_cloud());
  const std::string flags = "--cell-m 0.05 --uint16-step-m 0.002";
  const std::string printed = print_and_reread(
      dir, "elevation", flags, {"elevation:", "cell_m: 0.05", "uint16_step_m: 0.002"});
  EXPECT_NE(print_and_reread(dir, "elevation", "", {"uint16_step_m: ~"}), printed);
  std::ofstream(dir / "run.yaml") << printed;
  const std::string c = (dir / "c.ply").string();
  const auto a = run_cli_captured(dir, "elevation " + c + " -o " + (dir / "a.tif").string() + " " +
                                           flags + " --png " + (dir / "a.png").string());
  ASSERT_EQ(a.code, 0) << a.err;
  const auto b =
      run_cli_captured(dir, "elevation " + c + " -o " + (dir / "b.tif").string() + " --config " +
                                (dir / "run.yaml").string() + " --png " + (dir / "b.png").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(read_all(dir / "a.tif"), read_all(dir / "b.tif"));
  EXPECT_EQ(read_all(dir / "a.png"), read_all(dir / "b.png"));
  const ElevationMap m = read_elevation_geotiff((dir / "b.tif").string());
  EXPECT_DOUBLE_EQ(m.cell_m, 0.05);  // the file's cell, not the default
  // A flag overrides the file; errors name the flag; the cloud and -o are required.
  const auto d = run_cli_captured(
      dir, "elevation --print-config --config " + (dir / "run.yaml").string() + " --cell-m 0.1");
  EXPECT_NE(d.out.find("cell_m: 0.1"), std::string::npos) << d.out;
  const auto e = run_cli_captured(dir, "elevation --print-config --cell-m 0");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--cell-m must be"), std::string::npos) << e.err;
  const auto f = run_cli_captured(dir, "elevation --print-config --uint16-step-m -1");
  EXPECT_NE(f.err.find("--uint16-step-m must be"), std::string::npos) << f.err;
  EXPECT_EQ(run_cli_captured(dir, "elevation").code, 2);
  fs::remove_all(dir);
}

TEST(Params, EvaluateFromPrintedConfigWritesTheSameMetrics) {
  const fs::path dir = tmp_dir();
  write_ply((dir / "c.ply").string(), sphere_cloud());
  TriangleMesh truth = make_sphere(0.31, 32);
  for (auto& v : truth.vertices) v += Eigen::Vector3f(1, 2, 0);
  save_mesh((dir / "truth.ply").string(), truth);
  const std::string flags =
      "--coverage-radius 0.02 --outlier-radius 0.05 --samples-per-cm2 2 --seed 9";
  const std::string printed =
      print_and_reread(dir, "evaluate", flags,
                       {"evaluate:", "coverage_radius: 0.02", "outlier_radius: 0.05",
                        "samples_per_cm2: 2", "seed: 9", "histogram_bins: 40"});
  std::ofstream(dir / "run.yaml") << printed;
  const std::string in = (dir / "c.ply").string() + " -t " + (dir / "truth.ply").string();
  const auto a = run_cli_captured(
      dir, "evaluate " + in + " " + flags + " --json " + (dir / "a.json").string());
  ASSERT_EQ(a.code, 0) << a.err;
  const auto b =
      run_cli_captured(dir, "evaluate " + in + " --config " + (dir / "run.yaml").string() +
                                " --json " + (dir / "b.json").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(read_all(dir / "a.json"), read_all(dir / "b.json"));
  EXPECT_NE(read_all(dir / "a.json").find("0.02"), std::string::npos);  // r_c as given
  EXPECT_EQ(a.out, b.out);
  EvalConfig lib;
  params::read_yaml(YAML::Load(printed)["evaluate"], "run.yaml", "evaluate", lib);
  EXPECT_EQ(lib.seed, 9u);
  EXPECT_EQ(lib.samples_per_cm2, 2);
  const auto e = run_cli_captured(dir, "evaluate --print-config --outlier-radius -1");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--outlier-radius must be"), std::string::npos) << e.err;
  std::ofstream(dir / "bad.yaml") << "evaluate:\n  histogram_bins: 0\n";
  const auto f =
      run_cli_captured(dir, "evaluate --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("bad.yaml:2"), std::string::npos) << f.err;
  EXPECT_EQ(run_cli_captured(dir, "evaluate").code, 2);
  fs::remove_all(dir);
}

TEST(Params, ReportFromPrintedConfigWritesTheSamePage) {
  const fs::path dir = tmp_dir();
  write_ply((dir / "c.ply").string(), sphere_cloud());
  const std::string flags =
      "--max-points 500 --max-total-points 800 --max-mesh-triangles 1000 --color height "
      "--error-max 0.05 --title \"a sphere\" --seed 3";
  const std::string printed = print_and_reread(
      dir, "report", flags,
      {"report:", "max_points: 500", "max_total_points: 800", "max_mesh_triangles: 1000",
       "color: height", "error_max: 0.05", "title: \"a sphere\"", "seed: 3"});
  std::ofstream(dir / "run.yaml") << printed;
  ReportConfig lib;
  params::read_yaml(YAML::Load(printed)["report"], "run.yaml", "report", lib);
  EXPECT_EQ(lib.color, ReportColor::Height);
  EXPECT_EQ(lib.max_points_per_cloud, 500u);
  // The web assets where sonar3d report finds them ($SONAR3D_WEB_DIR, else the source tree's).
  const std::string web = " -q";
  const std::string c = (dir / "c.ply").string();
  const auto a =
      run_cli_captured(dir, "report " + c + " -o " + (dir / "a.html").string() + " " + flags + web);
  ASSERT_EQ(a.code, 0) << a.err;
  const auto b = run_cli_captured(dir, "report " + c + " -o " + (dir / "b.html").string() +
                                           " --config " + (dir / "run.yaml").string() + web);
  ASSERT_EQ(b.code, 0) << b.err;
  const std::string page = read_all(dir / "a.html");
  EXPECT_EQ(page, read_all(dir / "b.html"));
  EXPECT_NE(page.find("a sphere"), std::string::npos);  // the file's title
  const auto e = run_cli_captured(dir, "report --print-config --max-mesh-triangles 10");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--max-mesh-triangles must be"), std::string::npos) << e.err;
  EXPECT_NE(run_cli_captured(dir, "report --print-config --color hue").code, 0);
  EXPECT_EQ(run_cli_captured(dir, "report").code, 2);
  fs::remove_all(dir);
}

TEST(Params, SimulateExportPreviewFromPrintedConfigWriteTheSameFiles) {
  const fs::path dir = tmp_dir();
  std::ofstream(dir / "scene.yaml") << R"(
seed: 2
sensor: {preset: sim-10deg, beams: 40, fov_deg: 40, range_bins: 200}
simulation: {elevation_step_deg: 0.2}
noise: {model: stripes}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.1], end: [0, 0, 0.1], spacing: 0.1}
)";
  // simulate: a seed replacing the scene's (none: the scene's), a switch.
  EXPECT_NE(
      print_and_reread(dir, "simulate", "", {"simulate:", "seed: ~", "allow_empty: false"}).size(),
      0u);
  const std::string sim = print_and_reread(dir, "simulate", "--seed 17 --allow-empty",
                                           {"seed: 17", "allow_empty: true"});
  std::ofstream(dir / "sim.yaml") << sim;
  const std::string scene = (dir / "scene.yaml").string();
  const auto a = run_cli_captured(
      dir, "simulate " + scene + " -o " + (dir / "a").string() + " --seed 17 --allow-empty -q");
  ASSERT_EQ(a.code, 0) << a.err;
  const auto b = run_cli_captured(dir, "simulate " + scene + " -o " + (dir / "b").string() +
                                           " --config " + (dir / "sim.yaml").string() + " -q");
  ASSERT_EQ(b.code, 0) << b.err;
  const auto c = run_cli_captured(dir, "simulate " + scene + " -o " + (dir / "c").string() + " -q");
  ASSERT_EQ(c.code, 0) << c.err;
  for (const char* f : {"sonar.yaml", "frames.csv", "navigation.tum", "frames/000001.png"}) {
    EXPECT_EQ(read_all(dir / "a" / f), read_all(dir / "b" / f)) << f;
  }
  // The seed is the noise's: the scene's own seed gives other frames.
  EXPECT_NE(read_all(dir / "a/frames/000001.png"), read_all(dir / "c/frames/000001.png"));
  const auto e = run_cli_captured(dir, "simulate --print-config --seed 1.5");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--seed must be a whole number"), std::string::npos) << e.err;
  EXPECT_EQ(run_cli_captured(dir, "simulate").code, 2);

  // export rosbag: the wire (--ros1), topics, frames, compression, package.
  const std::string flags =
      "--ros1 --compression lz4 --sonar-topic /s --nav-topic /n --package acoustic_msgs "
      "--world-frame odom --base-frame vehicle --sonar-frame fls";
  const std::string ex = print_and_reread(
      dir, "export rosbag", flags,
      {"export:", "wire: ros1", "ros1_compression: \"lz4\"", "sonar_topic: \"/s\"",
       "nav_topic: \"/n\"", "message_package: \"acoustic_msgs\"", "world_frame: \"odom\"",
       "base_frame: \"vehicle\"", "sonar_frame: \"fls\""});
  std::ofstream(dir / "ex.yaml") << ex;
  const auto x = run_cli_captured(dir, "export rosbag " + (dir / "a").string() + " -o " +
                                           (dir / "x.bag").string() + " " + flags + " -q");
  ASSERT_EQ(x.code, 0) << x.err;
  const auto y = run_cli_captured(dir, "export rosbag " + (dir / "a").string() + " -o " +
                                           (dir / "y.bag").string() + " --config " +
                                           (dir / "ex.yaml").string() + " -q");
  ASSERT_EQ(y.code, 0) << y.err;
  const std::string bag = read_all(dir / "x.bag");
  EXPECT_EQ(bag, read_all(dir / "y.bag"));
  EXPECT_EQ(bag.rfind("#ROSBAG V2.0", 0), 0u);  // a ROS 1 bag: the file's wire
  EXPECT_NE(bag.find("/s"), std::string::npos);
  const auto f = run_cli_captured(dir, "export rosbag --print-config --compression zip");
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("--compression"), std::string::npos) << f.err;
  const auto h = run_cli_captured(dir, "export rosbag --print-config --nav-topic \"\"");
  EXPECT_NE(h.code, 0);
  EXPECT_NE(h.err.find("--nav-topic must not be empty"), std::string::npos) << h.err;
  EXPECT_EQ(run_cli_captured(dir, "export rosbag").code, 2);

  // preview: switches turned by their flags (--polar, --grey), numbers.
  const std::string pv_flags = "--polar --grey --max 0.5 --gamma 0.8";
  const std::string pv = print_and_reread(
      dir, "preview", pv_flags,
      {"preview:", "fan: false", "colormap: false", "max_value: 0.5", "gamma: 0.8"});
  std::ofstream(dir / "pv.yaml") << pv;
  const std::string ds = (dir / "a").string();
  ASSERT_EQ(run_cli_captured(
                dir, "preview " + ds + " --frame 1 -o " + (dir / "p.png").string() + " " + pv_flags)
                .code,
            0);
  ASSERT_EQ(run_cli_captured(dir, "preview " + ds + " --frame 1 -o " + (dir / "q.png").string() +
                                      " --config " + (dir / "pv.yaml").string())
                .code,
            0);
  ASSERT_EQ(
      run_cli_captured(dir, "preview " + ds + " --frame 1 -o " + (dir / "r.png").string()).code, 0);
  EXPECT_EQ(read_all(dir / "p.png"), read_all(dir / "q.png"));
  EXPECT_NE(read_all(dir / "p.png"), read_all(dir / "r.png"));  // the fan, in colour
  const auto pw = run_cli_captured(dir, "preview --print-config --width 8");
  EXPECT_NE(pw.code, 0);
  EXPECT_NE(pw.err.find("--width must lie in [16, 16384]"), std::string::npos) << pw.err;
  EXPECT_EQ(run_cli_captured(dir, "preview").code, 2);
  fs::remove_all(dir);
}

TEST(Params, PlanFromPrintedConfigKeepsItsSetting) {
  // The planner's own setting (the sweep file holds the rest).
  const fs::path dir = tmp_dir();
  const std::string printed =
      print_and_reread(dir, "plan", "--allow-empty", {"plan:", "allow_empty: true"});
  EXPECT_NE(print_and_reread(dir, "plan", "", {"allow_empty: false"}), printed);
  std::ofstream(dir / "bad.yaml") << "plan:\n  workers: 2\n";
  const auto e =
      run_cli_captured(dir, "plan --print-config --config " + (dir / "bad.yaml").string());
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("bad.yaml:2"), std::string::npos) << e.err;
  EXPECT_EQ(run_cli_captured(dir, "plan").code, 2);
  // A sweep whose one point fails: an error, unless the printed file says allow_empty.
  std::ofstream(dir / "allow.yaml") << printed;
  std::ofstream(dir / "s.yaml") << "seed: 3\nworkers: 1\nelevation_step_deg: 0.1\n"
                                   "axes:\n  range_res_m: [1e-12]\n"
                                   "fixed: {object: sphere, aperture_deg: 10, fov_deg: 30, "
                                   "voxel_m: 0.04, spacing_m: 0.5, path: orbit}\n";
  const std::string sweep = "plan " + (dir / "s.yaml").string() + " -q -o ";
  const auto r1 = run_cli_captured(dir, sweep + (dir / "p1").string());
  EXPECT_EQ(r1.code, 1) << r1.err;
  EXPECT_NE(r1.err.find("--allow-empty"), std::string::npos) << r1.err;
  const auto r2 = run_cli_captured(
      dir, sweep + (dir / "p2").string() + " --config " + (dir / "allow.yaml").string());
  EXPECT_EQ(r2.code, 0) << r2.err;
  EXPECT_TRUE(fs::exists(dir / "p2/results.csv"));
  fs::remove_all(dir);
}

TEST(Params, BenchPrintConfigRunsBack) {
  // The benchmark's sensor and run: the printed file runs the same benchmark (its timings differ).
  const fs::path dir = tmp_dir();
  const std::string flags =
      "--fov-deg 20 --aperture-deg 4 --bearing-step-deg 1 --elevation-step-deg 0.5 "
      "--range-max 5 --range-res 0.05 --frames 2 --threads 1";
  const std::string printed = print_and_reread(
      dir, "bench", flags,
      {"bench:", "fov_deg: 20", "aperture_deg: 4", "bearing_step_deg: 1", "elevation_step_deg: 0.5",
       "range_max_m: 5", "range_res_m: 0.05", "frames: 2", "num_threads: 1"});
  std::ofstream(dir / "run.yaml") << printed;
  const auto a = run_cli_captured(dir, "bench --config " + (dir / "run.yaml").string());
  ASSERT_EQ(a.code, 0) << a.err;
  EXPECT_NE(a.out.find("20 beams × 100 bins"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("2 frames"), std::string::npos) << a.out;
  const auto e = run_cli_captured(dir, "bench --print-config --frames 0");
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--frames must be"), std::string::npos) << e.err;
  const auto f = run_cli_captured(dir, "bench --print-config --fov-deg 10 --bearing-step-deg 30");
  EXPECT_NE(f.code, 0);
  EXPECT_NE(f.err.find("--bearing-step-deg is wider than --fov-deg"), std::string::npos) << f.err;
  fs::remove_all(dir);
}
