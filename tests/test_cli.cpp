// End to end through the command-line tool: simulate → info → preview → noise → evaluate, and the
// bad inputs a user meets (one clear error line, a non-zero exit, nothing half-written).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

// Each test runs in its own process under ctest, possibly in parallel: one directory per test.
fs::path kTmp;

sonar3d::test::CliRunSplit run(const std::string& args) {
  return sonar3d::test::run_cli_captured(kTmp, args);
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::trunc) << text;
}

const char* kScene = R"(
seed: 2
sensor: {preset: sim-10deg, beams: 80, fov_deg: 40}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.1}
)";

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    kTmp = fs::temp_directory_path() /
           ("sonar3d_test_cli_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(kTmp);
    fs::create_directories(kTmp);
  }
};

void expect_one_line_error(const sonar3d::test::CliRunSplit& r, const std::string& needle) {
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("error"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  EXPECT_LE(std::count(r.err.begin(), r.err.end(), '\n'), 2) << r.err;
}

}  // namespace

TEST_F(Cli, SimulateInfoPreviewNoiseEvaluate) {
  write(kTmp / "scene.yaml", kScene);
  const fs::path ds = kTmp / "ds";
  auto r = run("simulate " + (kTmp / "scene.yaml").string() + " -o " + ds.string() + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote 7 frames"), std::string::npos) << r.out;
  r = run("info " + ds.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("frames       7"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ground truth truth/scene.yaml"), std::string::npos) << r.out;
  r = run("preview " + ds.string() + " --frame 3 -o " + (kTmp / "f.png").string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_GT(fs::file_size(kTmp / "f.png"), 1000u);
  r = run("noise estimate " + ds.string() + " -o " + (kTmp / "noise").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(kTmp / "noise/mean.tiff"));
  EXPECT_TRUE(fs::exists(kTmp / "noise/std.tiff"));

  // A cloud sampled on the truth surface, pushed 1 cm outward: median 1 cm, full coverage.
  const auto truth = sonar3d::read_truth(ds);
  sonar3d::PointCloud cloud;
  const Eigen::Vector3f c(2.5f, 0, 0);
  for (const auto& p : sonar3d::sample_surface(truth[0].mesh_world, 20000, 5)) {
    cloud.points.push_back(c + (p - c) * (1.0f + 0.01f / (p - c).norm()));
  }
  sonar3d::write_ply((kTmp / "cloud.ply").string(), cloud);
  r = run("evaluate " + (kTmp / "cloud.ply").string() + " --truth " + ds.string() + " --json " +
          (kTmp / "m.json").string());
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream j(kTmp / "m.json");
  std::stringstream js;
  js << j.rdbuf();
  EXPECT_NE(js.str().find("\"object\": \"ball\""), std::string::npos) << js.str();
  EXPECT_NE(r.out.find("ball"), std::string::npos);
}

// A pass that stops short (the ball's top at 0.4 m, the pass ending at 0.3 m): the carving summary
// warns and suggests the filters for the ghosts beyond it and inside open structures; once
// --explain-returns is given, it no longer suggests it.
// A pass that stops short turns the bracket filter on by default and says so (issue 29); with the
// ghost filters switched off, the notes suggest them.
TEST_F(Cli, ShortPassFiltersGhostsAndSaysSo) {
  write(kTmp / "scene.yaml", kScene);
  const fs::path ds = kTmp / "ds";
  ASSERT_EQ(run("simulate " + (kTmp / "scene.yaml").string() + " -o " + ds.string() + " -q").code,
            0);
  const std::string cmd = "reconstruct " + ds.string() + " -o " + (kTmp / "c.ply").string();
  auto r = run(cmd);
  ASSERT_EQ(r.code, 0) << r.err;
  // Warnings and notes on stderr, never on stdout (issue 29).
  EXPECT_NE(r.err.find("sonar3d: warning: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("stops short"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sonar3d: note: points bracketed below 0.50 were dropped"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--no-auto-min-bracket"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("a pass stops short: the bracket filter at 0.50 kept"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("the return explanation dropped"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("--explain-returns"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("note:"), std::string::npos) << r.out;
  // Both filters off (the defaults before issue 29): the notes suggest them.
  r = run(cmd + " --no-auto-min-bracket --no-explain-returns --overwrite");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("sonar3d: note: --min-bracket 0.5 drops"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the return explanation (on unless --no-explain-returns)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.out.find("the return explanation dropped"), std::string::npos) << r.out;
  // An explicit --min-bracket: no note.
  r = run(cmd + " --min-bracket 0.5 --overwrite");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("stops short"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("note:"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("note:"), std::string::npos) << r.out;
}

TEST_F(Cli, BadInputsFailCleanlyAndLeaveNothing) {
  const fs::path out = kTmp / "never";
  // Missing scene file.
  auto r = run("simulate " + (kTmp / "missing.yaml").string() + " -o " + out.string());
  EXPECT_NE(r.code, 0);
  // Malformed YAML: file and line named.
  write(kTmp / "bad.yaml", "sensor: {preset: sim-10deg\nobjects: [\n");
  r = run("simulate " + (kTmp / "bad.yaml").string() + " -o " + out.string());
  expect_one_line_error(r, "bad.yaml:");
  // A missing mesh: named, and no dataset appears.
  std::string scene = kScene;
  scene.replace(scene.find("primitive: {type: sphere, radius: 0.4}"),
                std::string("primitive: {type: sphere, radius: 0.4}").size(), "mesh: nowhere.dae");
  write(kTmp / "nomesh.yaml", scene);
  r = run("simulate " + (kTmp / "nomesh.yaml").string() + " -o " + out.string());
  expect_one_line_error(r, "nowhere.dae");
  // Aperture of 0 and 180 degrees, NaN, negative spacing, empty scene.
  for (const std::string& bad :
       {std::string("vertical_aperture_deg: 0"), std::string("vertical_aperture_deg: 180"),
        std::string("r_max: .nan")}) {
    std::string s = kScene;
    s.replace(s.find("beams: 80"), 9, "beams: 80, " + bad);
    write(kTmp / "param.yaml", s);
    r = run("simulate " + (kTmp / "param.yaml").string() + " -o " + out.string());
    expect_one_line_error(r, bad.substr(0, bad.find(':')));
  }
  scene = kScene;
  scene.replace(scene.find("spacing: 0.1"), 12, "spacing: -0.1");
  write(kTmp / "neg.yaml", scene);
  r = run("simulate " + (kTmp / "neg.yaml").string() + " -o " + out.string());
  expect_one_line_error(r, "spacing");
  write(kTmp / "empty.yaml",
        "sensor: {preset: sim-10deg}\nobjects: []\ntrajectory: {type: straight, start: [0,0,0], "
        "end: [0,0,1], spacing: 0.1}\n");
  r = run("simulate " + (kTmp / "empty.yaml").string() + " -o " + out.string());
  expect_one_line_error(r, "empty");
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(kTmp)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
  // Not a dataset; a corrupt cloud.
  r = run("info " + kTmp.string());
  expect_one_line_error(r, "sonar.yaml is missing");
  write(kTmp / "corrupt.ply",
        "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n"
        "property float y\nproperty float z\nend_header\nabc");
  write(kTmp / "m.yaml", "");
  write(kTmp / "scene.yaml", kScene);
  ASSERT_EQ(
      run("simulate " + (kTmp / "scene.yaml").string() + " -o " + (kTmp / "ds").string()).code, 0);
  r = run("evaluate " + (kTmp / "corrupt.ply").string() + " --truth " + (kTmp / "ds").string());
  expect_one_line_error(r, "corrupt.ply");
  // A region of interest that is not finite or is flat, for either method: named, nothing written.
  for (const char* method : {"carve", "deconv"}) {
    r = run("reconstruct " + (kTmp / "ds").string() + " --method " + std::string(method) + " -o " +
            (kTmp / "roi.ply").string() + " -q --roi 0 0 nan 1 1 1");
    expect_one_line_error(r, "--roi must have finite corners");
    r = run("reconstruct " + (kTmp / "ds").string() + " --method " + std::string(method) + " -o " +
            (kTmp / "roi.ply").string() + " -q --roi 0 0 1 1 1 1");
    expect_one_line_error(r, "--roi must");
    EXPECT_FALSE(fs::exists(kTmp / "roi.ply"));
  }
  // The voxel mode's options out of range: the flag named (not the library's field), nothing
  // written.
  for (const auto& [option, parameter] :
       {std::pair<std::string, std::string>{"--voxel-support-bracket 1.5",
                                            "--voxel-support-bracket must lie in [0, 1]"},
        {"--voxel-bracketed 1.5", "--voxel-bracketed must lie in [0, 1]"},
        {"--kernel occlusion", "--kernel"}}) {
    r = run("reconstruct " + (kTmp / "ds").string() + " --method deconv --deconv-mode voxel -o " +
            (kTmp / "roi.ply").string() + " -q " + option);
    expect_one_line_error(r, parameter);
    EXPECT_FALSE(fs::exists(kTmp / "roi.ply")) << option;
  }
  // Unknown subcommand and --help.
  EXPECT_NE(run("frobnicate").code, 0);
  r = run("simulate --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("scene YAML file"), std::string::npos);
}
