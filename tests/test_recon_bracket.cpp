// Elevation bracketing of reconstructions (recon/bracketing.hpp): per-point "bracket" and "views"
// properties, the never-bracketed share of the region, and the warning that a pass stops short of
// the rule 2·r·tan(A_v/2) past the surface (docs/experiments.md), with the extension it needs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "test_support.hpp"

using namespace sonar3d;

namespace {

constexpr double kDeg = M_PI / 180.0;

// A box 0.4 × 0.6 × 0.6 m standing on z = 0 (top at 0.6 m, front face at x = -0.2 m).
constexpr double kTop = 0.6, kFront = -0.2, kSonarX = -2.5;
TriangleMesh box_mesh() {
  TriangleMesh m = make_box(0.4, 0.6, 0.6);
  m.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.3)));
  return m;
}

// A scene of one object (reflectivity 0.8).
Scene one_object(const std::string& name, const TriangleMesh& mesh) {
  Scene scene;
  SceneObject o;
  o.name = name;
  o.mesh_world = mesh;
  o.reflectivity = 0.8;
  scene.objects.push_back(o);
  return scene;
}

Eigen::AlignedBox3d region() {
  return Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -0.03), Eigen::Vector3d(1, 1, 2.5));
}

struct PassRun {
  PointCloud cloud;
  std::vector<Eigen::Isometry3d> poses;
};

// A vertical pass at x = -2.5 m from z0 to z1 every 2 cm, carved at 2 cm voxels above the seabed.
PassRun carve_pass(double z0, double z1) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(one_object("box", box_mesh()), spec, test::jittered_sim_config(0.05));
  CarveConfig cfg;
  cfg.voxel_size = 0.02;
  cfg.region = region();
  Carver carver(spec, cfg);
  PassRun run;
  const int n = static_cast<int>(std::round((z1 - z0) / 0.02)) + 1;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(kSonarX, 0, z0 + 0.02 * k);
    carver.integrate(sim.render(T, 100 + k), T);
    run.poses.push_back(T);
  }
  run.cloud = carver.finalize();
  return run;
}

const PassExtension* upper_extension(const BracketReport& r) {
  for (const auto& e : r.extensions)
    if (e.upper) return &e;
  return nullptr;
}

std::size_t count_above(const PointCloud& c, double z) {
  return static_cast<std::size_t>(
      std::count_if(c.points.begin(), c.points.end(), [z](const auto& p) { return p.z() > z; }));
}

}  // namespace

// A pass ending r·tan(A_v/2) above the top (the case: 0.5 m above at 3 m, 20°) is short
// by the other r·tan(A_v/2): the warning gives that extension, upward.
TEST(Bracket, PassStoppingShortWarnsWithTheRuleExtension) {
  const double rt = (kFront - kSonarX) * std::tan(10 * kDeg);  // 0.41 m at the front face
  const double end = kTop + rt;
  PassRun run = carve_pass(-0.3, end);
  ASSERT_FALSE(run.cloud.empty());
  const BracketReport rep =
      assess_bracketing(run.cloud, run.poses, test::reduced_spec_20deg(), {}, region());
  ASSERT_EQ(rep.passes, 1u);
  const PassExtension* e = upper_extension(rep);
  ASSERT_NE(e, nullptr) << "no warning for a pass that stops short";
  // The extreme surface is the box top, 2.3–2.7 m from the pass: the rule 2·r·tan 10°.
  EXPECT_GT(e->range, 2.2);
  EXPECT_LT(e->range, 2.8);
  EXPECT_NEAR(e->rule, 2 * e->range * std::tan(10 * kDeg), 1e-9);
  EXPECT_NEAR(e->past_surface, end - kTop, 0.04);
  EXPECT_NEAR(e->extend, e->rule - (end - kTop), 0.04);
  EXPECT_GT(e->direction.z(), 0.99);
  EXPECT_NE(e->message().find("extend it by"), std::string::npos) << e->message();
  // The seabed region hides the unbracketed space under the pass' start: no lower warning.
  for (const auto& x : rep.extensions) EXPECT_TRUE(x.upper) << x.message();
}

// A pass that ends at the top itself cannot tell how high the surface goes: the warning asks for
// at least 1.1·r·tan(A_v/2), a lower bound of the rule's 2·r·tan(A_v/2) from the true top.
TEST(Bracket, PassEndingAtTheTopWarnsWithALowerBound) {
  PassRun run = carve_pass(-0.3, kTop);
  const BracketReport rep =
      assess_bracketing(run.cloud, run.poses, test::reduced_spec_20deg(), {}, region());
  const PassExtension* e = upper_extension(rep);
  ASSERT_NE(e, nullptr);
  const double rt = e->range * std::tan(10 * kDeg);
  EXPECT_GT(e->extend, 1.0 * rt);
  EXPECT_LE(e->extend, 2 * rt + 0.04);  // never more than the rule from the true top
  EXPECT_NE(e->message().find("at least"), std::string::npos) << e->message();
}

// A pass that runs the rule's length past the top gives no warning, and brackets more of the
// region than a short one.
TEST(Bracket, LongPassGivesNoWarningAndBracketsTheRegion) {
  PassRun longer = carve_pass(-0.3, kTop + 1.0);
  PassRun shorter = carve_pass(-0.3, kTop + 0.1);
  const BracketReport a =
      assess_bracketing(longer.cloud, longer.poses, test::reduced_spec_20deg(), {}, region());
  const BracketReport b =
      assess_bracketing(shorter.cloud, shorter.poses, test::reduced_spec_20deg(), {}, region());
  EXPECT_EQ(upper_extension(a), nullptr) << a.warnings().front();
  EXPECT_NE(upper_extension(b), nullptr);
  EXPECT_GT(a.region_samples, 1000u);
  EXPECT_LT(a.unbracketed_share, b.unbracketed_share);
  EXPECT_LT(a.never_bracketed_share, b.never_bracketed_share);
}

// Every point carries bracket and views; they survive a PLY round trip; min_bracket removes the
// ghosts above the top of a short pass and keeps the front face.
TEST(Bracket, PropertiesAndGhostFilter) {
  PassRun run = carve_pass(-0.3, kTop + 0.2);
  PointCloud all = run.cloud;
  const BracketReport rep =
      assess_bracketing(all, run.poses, test::reduced_spec_20deg(), {}, region());
  ASSERT_EQ(rep.kept, all.size());
  const PointProperty* b = all.property("bracket");
  const PointProperty* v = all.property("views");
  ASSERT_NE(b, nullptr);
  ASSERT_NE(v, nullptr);
  ASSERT_EQ(b->values.size(), all.size());
  // Front-face points at mid height were seen across the whole aperture, from 40+ frames.
  int face = 0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const auto& p = all.points[i];
    if (std::abs(p.x() - kFront) < 0.03 && p.z() > 0.2 && p.z() < 0.4) {
      ++face;
      EXPECT_GT(b->values[i], 0.95f) << p.transpose();
      EXPECT_GT(v->values[i], 40.0f);
    }
    EXPECT_GE(b->values[i], 0.0f);
    EXPECT_LE(b->values[i], 1.0f);
  }
  EXPECT_GT(face, 20);

  const auto dir = test::temp_dir("ply");
  write_ply((dir / "c.ply").string(), all);
  const PointCloud back = read_ply((dir / "c.ply").string());
  ASSERT_NE(back.property("bracket"), nullptr);
  EXPECT_EQ(back.property("bracket")->values, b->values);
  EXPECT_EQ(back.property("views")->values, v->values);

  BracketConfig cfg;
  cfg.min_bracket = 0.5;
  PointCloud filtered = run.cloud;
  const BracketReport fr =
      assess_bracketing(filtered, run.poses, test::reduced_spec_20deg(), cfg, region());
  EXPECT_EQ(fr.kept, filtered.size());
  const EvalResult before = evaluate(all, box_mesh(), EvalConfig());
  const EvalResult after = evaluate(filtered, box_mesh(), EvalConfig());
  std::printf(
      "short pass: %zu -> %zu points above the top + 10 cm; outliers %.1f -> %.1f %%, "
      "coverage %.1f -> %.1f %%\n",
      count_above(all, kTop + 0.1), count_above(filtered, kTop + 0.1), 100 * before.outliers,
      100 * after.outliers, 100 * before.coverage, 100 * after.coverage);
  EXPECT_LT(count_above(filtered, kTop + 0.1), count_above(all, kTop + 0.1));
  EXPECT_LE(after.outliers, before.outliers);
  EXPECT_GT(after.coverage, 0.9 * before.coverage);
}

// Issue 29: the defaults of a reconstruction remove the ghosts of a pass that stops short. The box
// seen by one pass ending 0.2 m over its top (20°, 2.5 m: the rule asks 0.88 m), written as a
// dataset and reconstructed (carving, 2 cm) with the defaults and with both ghost filters off —
// the defaults before issue 29, which kept the unbracketed arcs above the top.
TEST(Bracket, DefaultsDropTheGhostsOfAShortPass) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(one_object("box", box_mesh()), spec, test::jittered_sim_config(0.05));
  const auto dir = test::temp_dir("bracket_defaults");
  {
    DatasetWriter w(dir / "ds", spec);
    Trajectory nav;
    const double z0 = -0.3, z1 = kTop + 0.2;
    const int n = static_cast<int>(std::round((z1 - z0) / 0.02)) + 1;
    for (int k = 0; k < n; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(kSonarX, 0, z0 + 0.02 * k);
      SonarImage img = sim.render(T, 100 + k);
      img.timestamp = 0.1 * k;
      w.add_frame(img);
      nav.push_back(0.1 * k, T);
    }
    w.set_navigation(nav);
    w.commit();
  }
  const Dataset ds = read_dataset(dir / "ds");
  ReconstructConfig defaults;
  defaults.voxel_size = 0.02;
  defaults.region = region();
  ReconstructConfig off = defaults;
  off.carve.occlusion.explain_returns = false;
  off.bracket.auto_min_bracket = false;
  const ReconstructResult r_def = reconstruct_dataset(ds, defaults);
  const ReconstructResult r_off = reconstruct_dataset(ds, off);
  const EvalResult e_def = evaluate(r_def.cloud, box_mesh(), EvalConfig());
  const EvalResult e_off = evaluate(r_off.cloud, box_mesh(), EvalConfig());
  const std::size_t above_def = count_above(r_def.cloud, kTop + 0.1);
  const std::size_t above_off = count_above(r_off.cloud, kTop + 0.1);
  std::printf(
      "short pass, filters off -> defaults: %zu -> %zu points above the top + 10 cm; outliers "
      "%.1f -> %.1f %%, coverage %.1f -> %.1f %%, median %.2f -> %.2f cm\n",
      above_off, above_def, 100 * e_off.outliers, 100 * e_def.outliers, 100 * e_off.coverage,
      100 * e_def.coverage, 100 * e_off.median_error, 100 * e_def.median_error);
  // The data shows the ghosts: the pass stops short, and the defaults filter on their own.
  ASSERT_FALSE(r_def.bracketing.extensions.empty());
  EXPECT_TRUE(r_def.bracketing.min_bracket_auto);
  EXPECT_FALSE(r_off.bracketing.min_bracket_auto);
  EXPECT_GT(above_off, 20u);
  EXPECT_LT(above_def, above_off / 10 + 1);
  EXPECT_LT(e_def.outliers, 0.5 * e_off.outliers);
  EXPECT_GT(e_def.coverage, e_off.coverage - 0.02);
  EXPECT_LE(e_def.median_error, e_off.median_error + 1e-9);
}

// An open gate: two posts 8 cm square and 0.52 m high at y = ±0.4 m, a crossbar on them (top at
// 0.6 m = kTop). Open structures leave ghost arcs over their members (docs/carving.md).
TriangleMesh gate_mesh() {
  TriangleMesh m;
  for (double y : {-0.4, 0.4}) {
    TriangleMesh post = make_box(0.08, 0.08, 0.52);
    post.transform(Eigen::Isometry3d(Eigen::Translation3d(0, y, 0.26)));
    m.append(post);
  }
  TriangleMesh bar = make_box(0.08, 0.88, 0.08);
  bar.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.56)));
  m.append(bar);
  return m;
}

// Orbits around the gate at several heights (sonar level, looking at its centre from 2.5 m, 24
// frames a level) written as a dataset and reconstructed (carving, 2 cm) with the defaults and
// with the automatic filter off.
ReconstructResult reconstruct_orbits(const std::vector<double>& levels, bool auto_filter,
                                     const std::string& name) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(one_object("gate", gate_mesh()), spec, test::jittered_sim_config(0.05));
  const auto dir = test::temp_dir(name);
  {
    DatasetWriter w(dir / "ds", spec);
    Trajectory nav;
    int k = 0;
    for (std::size_t l = 0; l < levels.size(); ++l) {
      for (int a = 0; a < 24; ++a, ++k) {
        const double yaw = (15.0 * a + (l % 2 ? 7.5 : 0.0)) * kDeg;
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::AngleAxisd(yaw + M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        T.translation() = Eigen::Vector3d(2.5 * std::cos(yaw), 2.5 * std::sin(yaw), levels[l]);
        SonarImage img = sim.render(T, 500 + k);
        img.timestamp = 0.1 * k;
        w.add_frame(img);
        nav.push_back(0.1 * k, T);
      }
    }
    w.set_navigation(nav);
    w.commit();
  }
  ReconstructConfig cfg;
  cfg.voxel_size = 0.02;
  cfg.region = region();
  cfg.bracket.auto_min_bracket = auto_filter;
  return reconstruct_dataset(read_dataset(dir / "ds"), cfg);
}

// Issue 29: orbits at several heights whose top level stops short (0.2 m over the gate's top; the
// rule asks about 0.9 m) leave ghost arcs above the top, seen from below only; the defaults drop
// them. One orbit at one height does not sweep the elevation and keeps everything.
TEST(Bracket, DefaultsDropTheGhostsAboveOrbitsThatStopShort) {
  std::vector<double> levels;
  for (int l = 0; l <= 5; ++l) levels.push_back(-0.3 + (kTop + 0.2 + 0.3) * l / 5.0);
  const ReconstructResult on = reconstruct_orbits(levels, true, "orbits_on");
  const ReconstructResult off = reconstruct_orbits(levels, false, "orbits_off");
  const EvalResult e_on = evaluate(on.cloud, gate_mesh(), EvalConfig());
  const EvalResult e_off = evaluate(off.cloud, gate_mesh(), EvalConfig());
  const std::size_t above_on = count_above(on.cloud, kTop + 0.1);
  const std::size_t above_off = count_above(off.cloud, kTop + 0.1);
  const LevelStack& st = on.bracketing.level_stack;
  std::printf(
      "orbits at %zu heights, filter off -> defaults: %zu -> %zu points above the top + 10 cm; "
      "outliers %.1f -> %.1f %%, coverage %.1f -> %.1f %%; %s\n",
      levels.size(), above_off, above_on, 100 * e_off.outliers, 100 * e_on.outliers,
      100 * e_off.coverage, 100 * e_on.coverage, st.message().c_str());
  EXPECT_EQ(st.frames, 24 * levels.size());
  EXPECT_TRUE(st.sweeps);
  ASSERT_TRUE(st.stops_short);
  EXPECT_NEAR(st.z_max, kTop + 0.2, 1e-9);
  EXPECT_GT(st.extend, 0.2);
  EXPECT_GT(st.dropped, 0u);
  EXPECT_EQ(on.bracketing.warnings().size(), 1u);  // the stack's, no pass
  EXPECT_EQ(off.bracketing.level_stack.dropped, 0u);
  EXPECT_GT(above_off, 20u);
  EXPECT_LT(above_on, above_off / 5 + 1);
  EXPECT_LT(e_on.outliers, 0.5 * e_off.outliers);
  EXPECT_GT(e_on.coverage, e_off.coverage - 0.01);  // what the orbits saw from above stays

  // One orbit at mid-height: no sweep, nothing dropped, the same cloud with the filter on or off.
  const ReconstructResult one_on = reconstruct_orbits({0.3}, true, "orbit_one_on");
  const ReconstructResult one_off = reconstruct_orbits({0.3}, false, "orbit_one_off");
  EXPECT_FALSE(one_on.bracketing.level_stack.sweeps);
  EXPECT_EQ(one_on.bracketing.level_stack.dropped, 0u);
  EXPECT_TRUE(one_on.bracketing.warnings().empty());
  EXPECT_EQ(one_on.cloud.size(), one_off.cloud.size());
}

TEST(Bracket, ConfigErrors) {
  BracketConfig c;
  c.min_bracket = 1.5;
  test::expect_error([&] { c.validate(); }, "min_bracket");
  c = {};
  c.bracketed_level = 0;
  test::expect_error([&] { c.validate(); }, "bracketed_level");
  PointCloud cloud;
  cloud.properties.push_back({"bad name", {}});
  cloud.points.emplace_back(0, 0, 0);
  const auto dir = test::temp_dir("err");
  test::expect_error([&] { write_ply((dir / "x.ply").string(), cloud); }, "property");
}
