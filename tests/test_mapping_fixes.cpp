// mapping: absolute references (issue 26 item 3) — position fixes (USBL/GNSS) in the swath
// adjustment: the navigation's scale error and heading bias recovered, outliers rejected and
// reported, fixes files read or refused with one line naming the file, line and column.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/position_fixes.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  const fs::path d =
      fs::temp_directory_path() / ("sonar3d_test_mapping_fixes_" + std::to_string(getpid()));
  fs::create_directories(d);
  return d;
}

// A lawnmower of `lines` 40 m lines flown east and west 6 m apart at 0.5 m/s (80 s a line), with
// 20 s turns between them: the true position at time t.
struct Survey {
  int lines = 6;
  double speed = 0.5, line_s = 80, turn_s = 20;
  double t_end() const { return lines * line_s + (lines - 1) * turn_s; }
  Eigen::Vector3d truth(double t) const {
    const int k = std::min(lines - 1, static_cast<int>(t / (line_s + turn_s)));
    const double u = t - k * (line_s + turn_s);
    const double x_end = k % 2 == 0 ? 40.0 : 0.0;
    if (u <= line_s) {
      const double x = k % 2 == 0 ? speed * u : 40.0 - speed * u;
      return {x - 20, 6.0 * k - 15, -10};
    }
    // The turn: across to the next line (a straight leg is enough here).
    const double w = (u - line_s) / turn_s;
    return {x_end - 20, 6.0 * (k + w) - 15, -10};
  }
  sonar3d::SwathTiming timing(int k) const {
    sonar3d::SwathTiming w;
    w.t0 = k * (line_s + turn_s);
    w.t1 = w.t0 + line_s;
    w.speed_mps = speed;
    w.gap_to_next_m = k + 1 < lines ? 6.0 : 0.0;
    return w;
  }
};

// Dead reckoning with a DVL scale error s and heading bias β (as sim/dead_reckoning: logged
// displacements (1 + s)·R(β)·true ones), started at the true first position.
Eigen::Vector3d logged(const Survey& sv, double t, double s, double beta) {
  const Eigen::Vector3d p0 = sv.truth(0);
  Eigen::Vector3d d = sv.truth(t) - p0;
  d.head<2>() = (1 + s) * (Eigen::Rotation2Dd(beta) * d.head<2>());
  return p0 + d;
}

// Fixes every `every` s of σ `sigma` (seeded noise), tied to swaths as mapping/survey.cpp does.
std::vector<sonar3d::AbsoluteFix> make_fixes(const Survey& sv, double s, double beta, double every,
                                             double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, sigma);
  std::vector<sonar3d::AbsoluteFix> out;
  int line = 2;
  for (double t = every / 2; t < sv.t_end(); t += every) {
    sonar3d::AbsoluteFix f;
    f.time = t;
    f.p_world = sv.truth(t) + Eigen::Vector3d(n(rng), n(rng), 0);
    f.p_logged = logged(sv, t, s, beta);
    f.sigma_m = sigma;
    f.line = line++;
    const int k = std::min(sv.lines - 1, static_cast<int>(t / (sv.line_s + sv.turn_s)));
    const sonar3d::SwathTiming w = sv.timing(k);
    f.swath_a = f.swath_b = k;
    f.time_a = f.time_b = t;
    if (t > w.t1 && k + 1 < sv.lines) {  // in the turn: both swaths, interpolated
      f.swath_b = k + 1;
      f.time_a = w.t1;
      f.time_b = sv.timing(k + 1).t0;
      f.weight_b = (t - w.t1) / (f.time_b - w.t1);
    }
    out.push_back(f);
  }
  return out;
}

// Ties between neighbouring lines, piece by piece: a uniform scale and heading error leaves the
// swaths agreeing, so each measures ~0 (map-cell noise) — as if the sonar's rays were scaled with
// the navigation. With `s`, `beta` the ties as swath maps measure them: a map is the logged
// vehicle position plus the sonar's rays, which carry no DVL scale, so lines whose true positions
// abeam the tie differ by Δ are logged (1 + s)·R(β)·Δ apart and their maps disagree by
// t = s·R(β)·Δ (SwathTie::nav_separation = (1 + s)·R(β)·Δ).
std::vector<sonar3d::SwathTie> make_ties(const Survey& sv, unsigned seed, double s = 0,
                                         double beta = 0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 0.005);
  std::vector<sonar3d::SwathTie> ties;
  for (int a = 0; a + 1 < sv.lines; ++a) {
    for (double x = 5; x < 40; x += 10) {
      sonar3d::SwathTie t;
      t.reference = a;
      t.moving = a + 1;
      auto time_at = [&](int k) {
        return sv.timing(k).t0 + (k % 2 == 0 ? x : 40.0 - x) / sv.speed;
      };
      t.time_reference = time_at(a);
      t.time_moving = time_at(a + 1);
      t.t = Eigen::Vector3d(n(rng), n(rng), 0);
      const Eigen::Vector2d delta =
          (sv.truth(t.time_reference) - sv.truth(t.time_moving)).head<2>();
      t.t.head<2>() += s * (Eigen::Rotation2Dd(beta) * delta);
      if (s != 0 || beta != 0) t.nav_separation = (1 + s) * (Eigen::Rotation2Dd(beta) * delta);
      t.confidence = 0.8;
      ties.push_back(t);
    }
  }
  return ties;
}

double worst_error(const Survey& sv, const sonar3d::SwathAdjustment& adj, double s, double beta) {
  double worst = 0;
  for (int k = 0; k < sv.lines; ++k) {
    const sonar3d::SwathTiming w = sv.timing(k);
    for (double t = w.t0; t <= w.t1; t += 5) {
      const Eigen::Vector3d c = adj.corrected(k, t, logged(sv, t, s, beta));
      worst = std::max(worst, (c - sv.truth(t)).head<2>().norm());
    }
  }
  return worst;
}

}  // namespace

// A survey logged with a 1.5 % DVL scale error and a 0.4° heading bias: its lines agree with
// each other (no tie sees it); fixes of 2 cm (RTK GNSS-like) every 10 s give the scale back within
// 0.1 % and the heading within 0.02°, and the corrected navigation within 5 cm.
TEST(MappingFixes, ScaleErrorAndHeadingBiasRecovered) {
  const Survey sv;
  const double s = 0.015, beta = 0.4 * M_PI / 180;
  sonar3d::AbsoluteConstraints abs;
  abs.fixes = make_fixes(sv, s, beta, 10, 0.02, 1);
  abs.pivot = sv.truth(0);
  const auto ties = make_ties(sv, 2);
  std::vector<sonar3d::SwathTiming> timing;
  for (int k = 0; k < sv.lines; ++k) timing.push_back(sv.timing(k));
  const sonar3d::SwathAdjustment global = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  const sonar3d::SwathAdjustment drift = sonar3d::adjust_swaths_drift(timing, ties, {}, &abs);
  // The global adjustment: the scale within 0.1 %, the heading within 0.02°.
  EXPECT_NEAR(global.scale_error(), s, 0.001);
  EXPECT_NEAR(global.heading_bias_rad() * 180 / M_PI, 0.4, 0.02);
  for (const auto* adj : {&global, &drift}) {
    SCOPED_TRACE(adj == &global ? "global" : "drift");
    ASSERT_TRUE(adj->has_fixes);
    ASSERT_TRUE(adj->estimated_scale_heading);
    // Honest σ: finite, small, and the estimate within 3 of them. The drift method's rates
    // overlap with the scale and heading (both drift along a line, with a sign that flips with
    // the direction of travel), only their priors tell them apart: its σ are wider (measured
    // 0.05 % and 0.11 %).
    EXPECT_GT(adj->scale_error_sigma, 0);
    EXPECT_LT(adj->scale_error_sigma, 0.002);
    EXPECT_LT(std::abs(adj->scale_error() - s), 3 * adj->scale_error_sigma);
    EXPECT_LT(std::abs(adj->heading_bias_rad() - beta), 3 * adj->heading_bias_sigma_rad);
    EXPECT_LT(worst_error(sv, *adj, s, beta), 0.05);
    for (const sonar3d::FixReport& f : adj->fixes) EXPECT_FALSE(f.rejected) << f.time;
  }
  // Without fixes the scale is not observable: nothing estimated, the survey as logged.
  const sonar3d::SwathAdjustment none = sonar3d::adjust_swaths(sv.lines, ties, {});
  EXPECT_FALSE(none.has_fixes);
  EXPECT_EQ(none.scale_error(), 0.0);
  EXPECT_GT(worst_error(sv, none, s, beta), 0.5);
}

// One fix 25 m off (a USBL multipath) among fixes of 1 m: rejected and reported with its time
// and residual; the answer is that of the clean fixes; the gate iterates.
TEST(MappingFixes, OutlierRejectedAndReported) {
  const Survey sv;
  const double s = 0.01, beta = 0.2 * M_PI / 180;
  sonar3d::AbsoluteConstraints abs;
  abs.fixes = make_fixes(sv, s, beta, 10, 1.0, 3);
  abs.pivot = sv.truth(0);
  const auto ties = make_ties(sv, 4);
  const sonar3d::SwathAdjustment clean = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  const std::size_t bad = abs.fixes.size() / 2;
  abs.fixes[bad].p_world.x() += 25;
  const sonar3d::SwathAdjustment adj = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  ASSERT_EQ(adj.fixes.size(), abs.fixes.size());
  std::size_t rejected = 0;
  for (const sonar3d::FixReport& f : adj.fixes) rejected += f.rejected;
  EXPECT_EQ(rejected, 1u);
  EXPECT_TRUE(adj.fixes[bad].rejected);
  EXPECT_EQ(adj.fixes[bad].time, abs.fixes[bad].time);
  EXPECT_EQ(adj.fixes[bad].line, abs.fixes[bad].line);
  EXPECT_NEAR(adj.fixes[bad].residual_m, 25, 1.5);
  EXPECT_GT(adj.fixes[bad].normalized, 20);
  EXPECT_GE(adj.fix_rounds, 2);
  // The same answer as without the outlier (to a small fraction of its σ).
  EXPECT_NEAR(adj.scale_error(), clean.scale_error(), 0.2 * clean.scale_error_sigma);
  EXPECT_NEAR(adj.heading_bias_rad(), clean.heading_bias_rad(), 0.2 * clean.heading_bias_sigma_rad);
  EXPECT_LT((adj.offsets[0] - clean.offsets[0]).head<2>().norm(), 0.05);
}

namespace {

// Known structure poses (issue 26 item 3): a structure at `p_true`, seen from line k as the
// vehicle passed it (the sonar's ray: true lever p_true − vehicle, logged turned by the heading
// bias β, with no DVL scale), known to be at p_true + `known_error`.
sonar3d::AbsoluteFix structure_constraint(const Survey& sv, int k, const Eigen::Vector3d& p_true,
                                          const Eigen::Vector3d& known_error, double s, double beta,
                                          const std::string& name) {
  const sonar3d::SwathTiming w = sv.timing(k);
  const double x0 = k % 2 == 0 ? -20.0 : 20.0, dir = k % 2 == 0 ? 1.0 : -1.0;
  const double t = w.t0 + dir * (p_true.x() - x0) / sv.speed;
  sonar3d::AbsoluteFix f;
  f.time = t;
  f.p_logged = logged(sv, t, s, beta);
  const Eigen::Vector3d lever_true = p_true - sv.truth(t);
  f.lever = lever_true;
  f.lever.head<2>() = Eigen::Rotation2Dd(beta) * lever_true.head<2>();
  f.p_world = p_true + known_error;
  f.sigma_m = 0.03;
  f.name = name;
  f.line = k;
  f.swath_a = f.swath_b = k;
  f.time_a = f.time_b = t;
  return f;
}

}  // namespace

// A survey logged with a 1.5 % DVL scale error and a 0.4° heading bias, no fixes: two structures
// 27 m apart whose poses are known (a previous survey's world model, as-built drawings),
// recognised in the map within 1 cm, give the scale back within 0.1 % and the whole navigation
// within 5 cm; one alone places the map but cannot give a scale.
TEST(MappingKnownPoses, TwoKnownStructuresFixTheScale) {
  const Survey sv;
  const double s = 0.015, beta = 0.4 * M_PI / 180;
  const auto ties = make_ties(sv, 5, s, beta);
  sonar3d::AbsoluteConstraints abs;
  abs.pivot = sv.truth(0);
  abs.fixes.push_back(structure_constraint(sv, 3, {-12, 5, -10.5}, {0.01, 0, 0}, s, beta, "a"));
  abs.fixes.push_back(structure_constraint(sv, 1, {15, -11, -10.5}, {0, -0.01, 0}, s, beta, "b"));
  const sonar3d::SwathAdjustment adj = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  ASSERT_TRUE(adj.has_fixes);
  ASSERT_TRUE(adj.estimated_scale_heading);
  EXPECT_NEAR(adj.scale_error(), s, 0.001);
  EXPECT_NEAR(adj.heading_bias_rad() * 180 / M_PI, 0.4, 0.1);
  EXPECT_LT(worst_error(sv, adj, s, beta), 0.05);
  ASSERT_EQ(adj.fixes.size(), 2u);
  for (const sonar3d::FixReport& f : adj.fixes) {
    EXPECT_FALSE(f.rejected) << f.name;
    EXPECT_LT(f.residual_m, 0.02) << f.name;
  }
  EXPECT_EQ(adj.fixes[0].name, "a");
  EXPECT_TRUE(std::isfinite(adj.scale_error_sigma));
  EXPECT_LT(std::abs(adj.scale_error() - s), 3 * adj.scale_error_sigma + 1e-4);
  // The drift method too.
  std::vector<sonar3d::SwathTiming> timing;
  for (int k = 0; k < sv.lines; ++k) timing.push_back(sv.timing(k));
  const sonar3d::SwathAdjustment drift = sonar3d::adjust_swaths_drift(timing, ties, {}, &abs);
  EXPECT_NEAR(drift.scale_error(), s, 0.001);
  EXPECT_LT(worst_error(sv, drift, s, beta), 0.05);
  // One known structure: a shift only (the scale stays as logged), the map placed there.
  abs.fixes.pop_back();
  const sonar3d::SwathAdjustment one = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  EXPECT_FALSE(one.estimated_scale_heading);
  EXPECT_EQ(one.scale_error(), 0.0);
  EXPECT_LT(one.fixes[0].residual_m, 0.01);
}

// Four known structures, one of whose known pose is 0.8 m off (moved since the as-built
// drawing, or a wrong match): rejected and reported by name with its residual; the other three
// give the scale within 0.1 %.
TEST(MappingKnownPoses, WrongKnownPoseRejectedAndReported) {
  const Survey sv;
  const double s = 0.01, beta = 0.2 * M_PI / 180;
  const auto ties = make_ties(sv, 6, s, beta);
  sonar3d::AbsoluteConstraints abs;
  abs.pivot = sv.truth(0);
  abs.fixes.push_back(structure_constraint(sv, 3, {-12, 5, -10.5}, {0.01, 0, 0}, s, beta, "a"));
  abs.fixes.push_back(structure_constraint(sv, 1, {15, -11, -10.5}, {0, -0.01, 0}, s, beta, "b"));
  abs.fixes.push_back(structure_constraint(sv, 5, {4, 13, -10.5}, {-0.01, 0.01, 0}, s, beta, "c"));
  abs.fixes.push_back(structure_constraint(sv, 2, {-3, -2, -10.5}, {0.6, -0.5, 0}, s, beta, "d"));
  const sonar3d::SwathAdjustment adj = sonar3d::adjust_swaths(sv.lines, ties, {}, 0, &abs);
  ASSERT_EQ(adj.fixes.size(), 4u);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_FALSE(adj.fixes[k].rejected) << adj.fixes[k].name;
    EXPECT_LT(adj.fixes[k].residual_m, 0.03) << adj.fixes[k].name;
  }
  EXPECT_TRUE(adj.fixes[3].rejected);
  EXPECT_EQ(adj.fixes[3].name, "d");
  EXPECT_NEAR(adj.fixes[3].residual_m, std::hypot(0.6, 0.5), 0.05);
  EXPECT_GT(adj.fixes[3].normalized, 20);
  EXPECT_NEAR(adj.scale_error(), s, 0.001);
  EXPECT_LT(worst_error(sv, adj, s, beta), 0.05);
}

// Fixes files: CSV with a header in any order (z optional, comments, extra columns) and TUM with
// one σ; every bad file refused with one line naming the file, the line and the column.
TEST(MappingFixes, FixesFilesReadOrRefusedWithOneLine) {
  using sonar3d::parse_position_fixes;
  auto fixes = parse_position_fixes(
      "# USBL\nsigma_m, quality, time_s, y_m, x_m\n1.5, 3, 10, 2, 1\n\n0.5, 2, 20.5, 4, 3\n",
      "f.csv");
  ASSERT_EQ(fixes.size(), 2u);
  EXPECT_EQ(fixes[0].time, 10);
  EXPECT_EQ(fixes[0].p, Eigen::Vector3d(1, 2, 0));
  EXPECT_FALSE(fixes[0].has_z);
  EXPECT_EQ(fixes[0].sigma_m, 1.5);
  EXPECT_EQ(fixes[1].line, 5);
  fixes = parse_position_fixes("time_s,x_m,y_m,z_m,sigma_m\n1,2,3,-4,0.1\n", "f.csv");
  EXPECT_TRUE(fixes[0].has_z);
  EXPECT_EQ(fixes[0].p.z(), -4);
  fixes = parse_position_fixes("# t x y z qx qy qz qw\n1 2 3 4 0 0 0 1\n2 3 4 5 0 0 0 1\n", "f.tum",
                               sonar3d::FixFormat::Auto, 0.7);
  ASSERT_EQ(fixes.size(), 2u);
  EXPECT_EQ(fixes[1].p, Eigen::Vector3d(3, 4, 5));
  EXPECT_EQ(fixes[1].sigma_m, 0.7);

  const std::string h = "time_s,x_m,y_m,sigma_m\n";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {h + "1,2,3,abc\n", "f.csv:2: column 'sigma_m' (field 4) 'abc' is not a number"},
      {h + "1,nan,3,1\n", "f.csv:2: column 'x_m' (field 2) is not finite"},
      {h + "1,2,3,-1\n", "f.csv:2: column 'sigma_m' (field 4): σ -1 m must lie in (0,"},
      {h + "1,2,3,0\n", "f.csv:2: column 'sigma_m' (field 4): σ 0 m must lie in (0,"},
      {h + "2,2,3,1\n1,2,3,1\n", "f.csv:3: time 1 s goes back from the fix of line 2"},
      {h + "2,2,3,1\n2,2,3,1\n", "f.csv:3: time 2 s repeats the fix of line 2"},
      {h + "1,2\n", "f.csv:2: expected at least 4 fields, got 2"},
      {h + "1,2e9,3,1\n", "f.csv:2: coordinate 2000000000 m is beyond"},
      {h + "1,2,3,1e9\n", "must lie in (0, 10000] m"},
      {"time,x,y\n1,2,3\n", "f.csv:1: expected a header naming the columns time_s, x_m, y_m"},
      {"", "f.csv: empty fixes file"},
      {h, "f.csv: the fixes file holds no fix"},
  };
  for (const auto& [text, expected] : bad) {
    try {
      parse_position_fixes(text, "f.csv");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const sonar3d::Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(expected), std::string::npos) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
  try {
    parse_position_fixes("1 2 3 4 0 0 0 1\n", "f.tum");
    ADD_FAILURE();
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("--fix-sigma"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_position_fixes("1 2 3\n", "f.tum", sonar3d::FixFormat::Auto, 1),
               sonar3d::Error);
  EXPECT_THROW(sonar3d::read_position_fixes("/nonexistent/f.csv"), sonar3d::Error);
}

namespace {

// A small simulated site (as test_mapping.cpp's field): four 6 m lines, dead reckoning with a 2 %
// DVL scale error and a 0.3° heading bias.
const std::string kScene = std::string(R"(seed: 3
navigation_error: {velocity_scale: 0.02, heading_bias_deg: 0.3, bias_walk: 0}
)") + sonar3d::test::kDownwardSonarYaml +
                           R"(objects:
  - {name: seabed, primitive: {type: plane, size: [20, 20]}, pose: {translation: [0, 0, 0.013]}, reflectivity: 0.3, kind: terrain}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [2.0, 1.5, 0], rpy_deg: [0, 0, 30]}, reflectivity: 0.8}
  - {name: pipe, primitive: {type: cylinder, radius: 0.15, height: 5}, pose: {translation: [3, 2.0, 0.05], rpy_deg: [0, 90, 20]}, reflectivity: 0.8}
  - {name: rock, primitive: {type: sphere, radius: 0.3}, pose: {translation: [4.5, 3.2, -0.1]}, reflectivity: 0.6}
trajectory: {type: lawnmower, x: [0, 6], y: [0, 4.5], z: 3.0, line_spacing: 1.5, spacing: 0.04, period: 0.1}
)";

}  // namespace

// End to end: `sonar3d map --fixes` on a simulated survey with fixes of 2 cm every 2 s from the
// true navigation, one of them 3 m off and two after the survey: the outlier is rejected and
// reported in the printout and summary.json, the two ignored and counted, the map placed in the
// world within centimetres, the scale error found within its σ; bad fixes files are one line.
TEST(MappingCli, FixesPlaceTheMapAndRejectAnOutlier) {
  const fs::path dir = temp_dir() / "cli";
  fs::create_directories(dir);
  { std::ofstream(dir / "f.yaml") << kScene; }
  using sonar3d::test::run_cli;
  auto r = run_cli(
      dir, "simulate " + (dir / "f.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const sonar3d::Trajectory truth = sonar3d::read_tum((dir / "ds/truth/navigation.tum").string());
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0, 0.02);
  double outlier_t = 0;
  {
    std::ofstream f(dir / "fixes.csv");
    f << "time_s,x_m,y_m,sigma_m\n";
    int k = 0;
    for (double t = 1; t < truth.times.back() + 3; t += 2, ++k) {
      const double tc = std::min(t, truth.times.back());
      Eigen::Vector3d p = truth.interpolate(tc).translation();
      p.x() += n(rng);
      p.y() += n(rng);
      if (k == 15) {
        p.x() += 3;
        outlier_t = t;
      }
      f << t << "," << p.x() << "," << p.y() << ",0.02\n";
    }
  }
  const std::string args = " --roi -1 -1 -0.6 7 6 0.8 --search 0.3 ";
  const fs::path out = dir / "m";
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + out.string() + args + "--fixes " +
                       (dir / "fixes.csv").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("1 rejected"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("navigation model: scale error"), std::string::npos) << r.out;
  std::ifstream fs_(out / "summary.json");
  const nlohmann::json s = nlohmann::json::parse(fs_);
  ASSERT_TRUE(s.contains("fixes")) << s.dump();
  EXPECT_EQ(s["fixes"]["rejected"].get<int>(), 1);
  EXPECT_EQ(s["fixes"]["outside_time_span"].get<int>(), 2);
  EXPECT_NEAR(s["fixes"]["rejected_fixes"][0]["time_s"].get<double>(), outlier_t, 1e-9);
  EXPECT_NEAR(s["fixes"]["rejected_fixes"][0]["residual_m"].get<double>(), 3, 0.2);
  const auto& model = s["navigation_model"];
  const double se = model["scale_error"].get<double>();
  const double ss = model["scale_error_sigma"].get<double>();
  EXPECT_GT(ss, 0);
  EXPECT_LT(std::abs(se - 0.02), std::max(4 * ss, 0.002)) << model.dump();
  const auto& nav = s["navigation_error"];
  // The world-frame figure, computed here from the written corrected navigation and the truth
  // over the swaths' frames.
  {
    const sonar3d::Trajectory corrected =
        sonar3d::read_tum((out / "navigation_corrected.tum").string());
    const sonar3d::Dataset ds = sonar3d::read_dataset(dir / "ds");
    std::vector<double> err;
    for (const auto& w : s["swaths"]) {
      for (int i = w["frames"][0].get<int>(); i <= w["frames"][1].get<int>(); ++i) {
        const double t = ds.frames[static_cast<std::size_t>(i)].timestamp;
        err.push_back((corrected.interpolate(t).translation() - truth.interpolate(t).translation())
                          .head<2>()
                          .norm());
      }
    }
    std::nth_element(err.begin(), err.begin() + static_cast<std::ptrdiff_t>(err.size() / 2),
                     err.end());
    EXPECT_NEAR(nav["after"]["world_m"].get<double>(), err[err.size() / 2], 1e-6);
  }
  EXPECT_GT(nav["before"]["world_m"].get<double>(), 0.05);
  EXPECT_LT(nav["after"]["world_m"].get<double>(), 0.03);
  EXPECT_LT(nav["after"]["within_map_m"].get<double>(),
            nav["before"]["within_map_m"].get<double>());

  // Bad fixes files: one line naming the file, line and column; nothing written.
  { std::ofstream(dir / "bad.csv") << "time_s,x_m,y_m,sigma_m\n1,2,3,-0.5\n"; }
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "m2").string() + args +
                       "--fixes " + (dir / "bad.csv").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("bad.csv:2: column 'sigma_m' (field 4)"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_FALSE(fs::exists(dir / "m2"));
  // Fixes all outside the survey: refused, naming the file and the clock.
  { std::ofstream(dir / "late.csv") << "time_s,x_m,y_m,sigma_m\n1000,2,3,1\n"; }
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "m3").string() + args +
                       "--fixes " + (dir / "late.csv").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("outside the survey's time span"), std::string::npos) << r.out;
  // The consecutive method has no adjustment to take them.
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "m4").string() + args +
                       "--method consecutive --fixes " + (dir / "fixes.csv").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--fixes needs --method global or drift"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// End to end: `sonar3d map --known-poses --placements` on the small simulated site (2 % DVL scale
// error, 0.3° heading bias). The structures "recognised" in the map as logged (where the logged
// navigation puts what the sonar saw of them: the true lever carried by the logged attitude) are
// matched to their known poses; the box's and the rock's are right, the pipe's 1.3 m off (moved
// since): it is rejected and reported in the printout and summary.json, the map is placed by the
// other two; a directory without graph.json, or --placements alone, is one error line.
TEST(MappingCli, KnownPosesPlaceTheMapAndRejectAWrongOne) {
  const fs::path dir = temp_dir() / "cli_known";
  fs::create_directories(dir);
  { std::ofstream(dir / "f.yaml") << kScene; }
  using sonar3d::test::run_cli;
  auto r = run_cli(
      dir, "simulate " + (dir / "f.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const sonar3d::Trajectory truth = sonar3d::read_tum((dir / "ds/truth/navigation.tum").string());
  const sonar3d::Trajectory nav = sonar3d::read_tum((dir / "ds/navigation.tum").string());
  struct Obj {
    std::string model;
    Eigen::Vector3d p, known_error;
  };
  const std::vector<Obj> objs = {{"box", {2.0, 1.5, 0}, {0, 0, 0}},
                                 {"rock", {4.5, 3.2, -0.1}, {0, 0, 0}},
                                 {"pipe", {3.0, 2.0, 0.05}, {1.0, -0.8, 0}}};
  auto pose_json = [](const Eigen::Vector3d& p) {
    return nlohmann::json::array(
        {nlohmann::json::array({1, 0, 0, p.x()}), nlohmann::json::array({0, 1, 0, p.y()}),
         nlohmann::json::array({0, 0, 1, p.z()}), nlohmann::json::array({0, 0, 0, 1})});
  };
  nlohmann::json recognised = {{"format", "sonar3d-placements"}, {"version", 1}};
  nlohmann::json known = recognised;
  for (const Obj& o : objs) {
    // Where the map as logged shows it: from the frame whose true position passes closest.
    std::size_t best = 0;
    for (std::size_t k = 0; k < truth.size(); ++k) {
      if ((truth.poses[k].translation() - o.p).head<2>().norm() <
          (truth.poses[best].translation() - o.p).head<2>().norm()) {
        best = k;
      }
    }
    const double t = truth.times[best];
    const Eigen::Isometry3d Tt = truth.interpolate(t), Tl = nav.interpolate(t);
    const Eigen::Vector3d p_map =
        Tl.translation() + Tl.linear() * Tt.linear().transpose() * (o.p - Tt.translation());
    recognised["placements"].push_back({{"model", o.model}, {"T_world_model", pose_json(p_map)}});
    known["placements"].push_back(
        {{"model", o.model}, {"T_world_model", pose_json(o.p + o.known_error)}});
  }
  { std::ofstream(dir / "recognised.json") << recognised.dump(); }
  { std::ofstream(dir / "known.json") << known.dump(); }
  const std::string args = " --roi -1 -1 -0.6 7 6 0.8 --search 0.3 ";
  const std::string kp = " --known-poses " + (dir / "known.json").string() + " --placements " +
                         (dir / "recognised.json").string() + " --placements-nav " +
                         (dir / "ds/navigation.tum").string();
  const fs::path out = dir / "m";
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + out.string() + args + kp);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("3 matched"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rejected: pipe_0"), std::string::npos) << r.out;
  std::ifstream fs_(out / "summary.json");
  const nlohmann::json s = nlohmann::json::parse(fs_);
  ASSERT_TRUE(s.contains("known_poses")) << s.dump();
  const auto& k = s["known_poses"];
  EXPECT_EQ(k["matched"].get<int>(), 3);
  EXPECT_EQ(k["rejected"].get<int>(), 1);
  EXPECT_FALSE(s.contains("fixes"));
  for (const auto& m : k["matches"]) {
    if (m["model"] == "pipe") {
      EXPECT_TRUE(m["rejected"].get<bool>()) << m.dump();
      EXPECT_NEAR(m["residual_m"].get<double>(), std::hypot(1.0, 0.8), 0.15) << m.dump();
    } else {
      EXPECT_FALSE(m["rejected"].get<bool>()) << m.dump();
      EXPECT_LT(m["residual_m"].get<double>(), 0.05) << m.dump();
    }
  }
  const auto& navs = s["navigation_error"];
  EXPECT_LT(navs["after"]["world_m"].get<double>(), navs["before"]["world_m"].get<double>());
  EXPECT_LT(navs["after"]["world_m"].get<double>(), 0.05) << navs.dump();

  // A directory that is no world model; --placements without --known-poses: one line each.
  fs::create_directories(dir / "notworld");
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "m2").string() + args +
                       "--known-poses " + (dir / "notworld").string() + " --placements " +
                       (dir / "recognised.json").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("without graph.json"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "m3").string() + args +
                       "--placements " + (dir / "recognised.json").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--known-poses and --placements go together"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "m2"));
  EXPECT_FALSE(fs::exists(dir / "m3"));
}
