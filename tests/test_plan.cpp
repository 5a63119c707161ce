// plan: sweep files, grid and constraints, and a real small sweep through the CLI (parallel
// points, failures recorded, resume, ranking, MPI with two local ranks when mpirun exists).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/plan/sweep.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;
namespace fs = std::filesystem;

namespace {

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::trunc) << text;
}

// Small and fast: a 20° × 10° sensor at 4 cm range bins, 5–10 cm sampling, 4 cm voxels.
const char* kTiny = R"(
seed: 3
workers: 2
rank_by: median_to_coverage
constraints: ["standoff_m >= 2"]
elevation_step_deg: 0.1
axes:
  spacing_m: [0.05, 0.1]
  standoff_m: [1.0, 2.0]
  object: [sphere, nowhere.stl]
fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, voxel_m: 0.04}
)";

nlohmann::json read_json(const fs::path& p) {
  return nlohmann::json::parse(read_text_file(p.string()));
}

}  // namespace

TEST(Sweep, GridDefaultsAndConstraints) {
  const fs::path dir = temp_dir("grid");
  write(dir / "s.yaml", kTiny);
  const Sweep s = load_sweep((dir / "s.yaml").string());
  ASSERT_EQ(s.size(), 8u);
  // Row-major, last axis fastest.
  const auto p0 = s.point(0), p1 = s.point(1), p7 = s.point(7);
  EXPECT_EQ(to_string(p0.at("object")), "sphere");
  EXPECT_EQ(to_string(p1.at("object")), "nowhere.stl");
  EXPECT_EQ(to_string(p7.at("spacing_m")), "0.1");
  EXPECT_EQ(to_string(p7.at("standoff_m")), "2");
  EXPECT_EQ(to_string(p0.at("aperture_deg")), "10");  // fixed
  EXPECT_EQ(to_string(p0.at("method")), "carve");     // default
  EXPECT_EQ(to_string(p0.at("snr_db")), "none");      // default
  ASSERT_EQ(s.constraints.size(), 1u);
  EXPECT_FALSE(s.constraints[0].satisfied_by(p0));  // stand-off 1 m
  EXPECT_TRUE(s.constraints[0].satisfied_by(s.point(2)));
  EXPECT_THROW(s.point(8), Error);
}

TEST(Sweep, BadFilesNameTheProblem) {
  const fs::path dir = temp_dir("bad");
  auto check = [&](const std::string& text, const std::string& needle) {
    write(dir / "s.yaml", text);
    expect_error([&] { load_sweep((dir / "s.yaml").string()); }, needle);
  };
  check("axes: {aperture_deg: []}\n", "s.yaml:1: key 'axes.aperture_deg'");
  check("axes: {colour: [1]}\n", "colour");
  check("axes: {aperture_deg: [10]}\nbogus: 1\n", "bogus");
  check("axes: {aperture_deg: [10, wide]}\n", "expected a number");
  check("axes: {aperture_deg: [180]}\n", "(0°, 180°)");
  check("axes: {spacing_m: [0]}\n", "must be > 0");
  check("axes: {method: [magic]}\n", "method must be");
  check("axes: {aperture_deg: [10]}\nconstraints: [\"standoff_m >> 2\"]\n", "op one of");
  check("axes: {aperture_deg: [10]}\nconstraints: [\"object >= 2\"]\n", "not a numeric");
  check("axes: {aperture_deg: [10]}\nrank_by: beauty\n", "unknown metric");
  check("fixed: {aperture_deg: 10}\n", "'axes' must map");
  // Any reconstruction setting by its dotted path, checked as a configuration file's would be.
  check("axes: {reconstruct.carve.bogus: [1]}\n", "unknown key");
  check("axes: {reconstruct.deconv.mode: [orbit]}\n", "passes, voxel or auto");
  check("axes: {reconstruct.bracket.min_bracket: [0, 2]}\n", "s.yaml:1");
  check("axes: {reconstruct.bracket.min_bracket: [0, 2]}\n", "must lie in [0, 1]");
}

// The planner varies any setting of the reconstruction by its dotted path (ReconstructConfig's one
// declaration, docs/reference.md), and the point runs with it.
TEST(Plan, SweepsAnyReconstructionSettingByItsPath) {
  const fs::path dir = temp_dir("dotted");
  write(dir / "s.yaml", R"(
seed: 3
workers: 1
elevation_step_deg: 0.1
axes:
  reconstruct.bracket.min_bracket: [0, 0.9]
fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, voxel_m: 0.04,
        spacing_m: 0.1, standoff_m: 2.0, reconstruct.carve.occlusion.explain_returns: true}
constraints: ["reconstruct.bracket.min_bracket <= 0.9"]
)");
  const Sweep s = load_sweep((dir / "s.yaml").string());
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(to_string(s.point(1).at("reconstruct.bracket.min_bracket")), "0.9");
  EXPECT_EQ(to_string(s.point(0).at("reconstruct.carve.occlusion.explain_returns")), "true");
  const fs::path out = dir / "out";
  const std::string cmd = std::string(SONAR3D_CLI) + " plan " + (dir / "s.yaml").string() + " -o " +
                          out.string() + " -q > " + (dir / "log.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << read_text_file((dir / "log.txt").string());
  const auto results = read_json(out / "results.json");
  ASSERT_EQ(results["points"].size(), 2u);
  double kept[2] = {0, 0};
  for (const auto& p : results["points"]) {
    ASSERT_EQ(p["status"], "ok") << p.dump();
    const int k = p["params"]["reconstruct.bracket.min_bracket"].get<double>() > 0 ? 1 : 0;
    kept[k] = p["metrics"]["num_points"].get<double>();
  }
  EXPECT_GT(kept[0], 100);
  EXPECT_LT(kept[1], kept[0]);  // the setting reached the reconstruction: fewer points kept
}

TEST(Plan, RunsRanksResumesAndRecordsFailures) {
  const fs::path dir = temp_dir("run");
  write(dir / "s.yaml", kTiny);
  const fs::path out = dir / "out";
  const std::string cmd = std::string(SONAR3D_CLI) + " plan " + (dir / "s.yaml").string() + " -o " +
                          out.string() + " -q > " + (dir / "log.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << read_text_file((dir / "log.txt").string());
  const auto results = read_json(out / "results.json");
  ASSERT_EQ(results["points"].size(), 8u);
  int ok = 0, failed = 0, skipped = 0;
  for (const auto& p : results["points"]) {
    const std::string st = p["status"];
    const bool constrained = p["params"]["standoff_m"].get<double>() < 2;
    if (constrained) {
      EXPECT_EQ(st, "skipped_constraint") << p.dump();
      ++skipped;
    } else if (p["params"]["object"] == "nowhere.stl") {
      EXPECT_EQ(st, "failed");
      EXPECT_NE(p["message"].get<std::string>().find("nowhere.stl"), std::string::npos);
      ++failed;
    } else {
      ASSERT_EQ(st, "ok") << p.dump();
      ++ok;
      EXPECT_TRUE(fs::exists(out / p["cloud"].get<std::string>()));
      EXPECT_GT(p["metrics"]["num_points"].get<double>(), 100);
      EXPECT_LT(p["metrics"]["median_error_m"].get<double>(), 0.06);
      EXPECT_GT(p["metrics"]["coverage"].get<double>(), 0.05);
      EXPECT_GT(p["peak_rss_mb"].get<double>(), 1.0);
      EXPECT_GT(p["data_bytes"].get<double>(), 1000);
      EXPECT_TRUE(p["rank"].is_number());
    }
  }
  EXPECT_EQ(ok, 2);
  EXPECT_EQ(failed, 2);
  EXPECT_EQ(skipped, 4);
  EXPECT_TRUE(fs::exists(out / "truth/sphere.ply"));
  // Ranking: rank 1 has the smallest ratio.
  double best = 1e9, rank1 = -1;
  for (const auto& p : results["points"]) {
    if (p["status"] != "ok") continue;
    best = std::min(best, p["metrics"]["median_to_coverage"].get<double>());
    if (p["rank"] == 1) rank1 = p["metrics"]["median_to_coverage"].get<double>();
  }
  EXPECT_EQ(best, rank1);
  const std::string csv = read_text_file((out / "results.csv").string());
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 9);
  EXPECT_NE(csv.find("median_to_coverage"), std::string::npos);

  // Resume: finished points are not run again (their status files keep their timestamps).
  const auto before = fs::last_write_time(out / "points/p0002/status.json");
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_EQ(fs::last_write_time(out / "points/p0002/status.json"), before);
  EXPECT_NE(read_text_file((dir / "log.txt").string()).find("2 already done"), std::string::npos)
      << read_text_file((dir / "log.txt").string());
}

TEST(Plan, TwoMpiRanksMergeOnRankZero) {
  if (std::system("command -v mpirun > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "mpirun not installed";
  }
  const fs::path dir = temp_dir("mpi");
  write(dir / "s.yaml", R"(
seed: 3
workers: 1
elevation_step_deg: 0.1
axes: {spacing_m: [0.05, 0.1]}
fixed: {aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04, voxel_m: 0.04, standoff_m: 2}
)");
  const fs::path out = dir / "out";
  const std::string cmd =
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "OMPI_MCA_btl_vader_single_copy_mechanism=none mpirun --oversubscribe --bind-to none -np 2 " +
      std::string(SONAR3D_CLI) + " plan " + (dir / "s.yaml").string() + " -o " + out.string() +
      " -q > " + (dir / "log.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << read_text_file((dir / "log.txt").string());
  const std::string log = read_text_file((dir / "log.txt").string());
  EXPECT_NE(log.find("on 2 ranks"), std::string::npos) << log;
  const auto results = read_json(out / "results.json");
  ASSERT_EQ(results["points"].size(), 2u);
  for (const auto& p : results["points"]) EXPECT_EQ(p["status"], "ok") << p.dump();
}

// Resolutions so fine that their counts overflow an int (they silently became 1 beam, 1 bin or 8
// frames and were ranked ok): each point fails, naming the count and the parameter to change.
TEST(Plan, AbsurdResolutionsFailTheirPointsWithAClearMessage) {
  const fs::path dir = temp_dir("absurd");
  write(dir / "s.yaml", R"(
seed: 3
workers: 1
elevation_step_deg: 0.1
axes:
  bearing_res_deg: [1e-9, 0.5]
  range_res_m: [1e-12, 0.04]
fixed: {object: sphere, aperture_deg: 10, fov_deg: 30, voxel_m: 0.04, spacing_m: 1e-14, path: orbit}
)");
  const fs::path out = dir / "out";
  const std::string cmd = std::string(SONAR3D_CLI) + " plan " + (dir / "s.yaml").string() + " -o " +
                          out.string() + " -q --allow-empty > " + (dir / "log.txt").string() +
                          " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << read_text_file((dir / "log.txt").string());
  const auto results = read_json(out / "results.json");
  ASSERT_EQ(results["points"].size(), 4u);
  for (const auto& p : results["points"]) {
    EXPECT_EQ(p["status"], "failed") << p.dump();
    const std::string msg = p["message"];
    const bool bad_beams = p["params"]["bearing_res_deg"].get<double>() < 1e-6;
    const bool bad_bins = p["params"]["range_res_m"].get<double>() < 1e-6;
    const char* expected = bad_beams  ? "bearing_res_deg"
                           : bad_bins ? "range_res_m"
                                      : "spacing_m";  // the orbit's frame count
    EXPECT_NE(msg.find(expected), std::string::npos) << msg;
  }
}

// A sweep whose largest point does not fit the memory limit (issue 29 item 5): refused before
// anything runs or is written, naming the estimate, the point and voxel_m.
TEST(Plan, AVoxelBeyondTheMemoryLimitRefusesTheSweepBeforeItRuns) {
  const fs::path dir = temp_dir("memory");
  const std::string sweep = R"(
seed: 3
workers: 1
elevation_step_deg: 0.1
axes:
  voxel_m: [0.04, 0.002]
fixed: {object: sphere, aperture_deg: 10, fov_deg: 30, bearing_res_deg: 0.5, range_res_m: 0.04,
        spacing_m: 0.1, standoff_m: 2.0}
)";
  write(dir / "s.yaml", sweep);
  const fs::path out = dir / "out";
  const std::string cmd = std::string(SONAR3D_CLI) + " plan " + (dir / "s.yaml").string() + " -o " +
                          out.string() + " --max-memory 0.01 -q > " + (dir / "log.txt").string() +
                          " 2>&1";
  EXPECT_NE(std::system(cmd.c_str()), 0);
  const std::string log = read_text_file((dir / "log.txt").string());
  EXPECT_NE(log.find("plan needs an estimated"), std::string::npos) << log;
  EXPECT_NE(log.find("point p0001"), std::string::npos) << log;
  EXPECT_NE(log.find("voxel_m"), std::string::npos) << log;
  EXPECT_NE(log.find("--max-memory"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(out / "points")) << "nothing may run or be written";
  EXPECT_FALSE(fs::exists(out / "results.json"));
}
