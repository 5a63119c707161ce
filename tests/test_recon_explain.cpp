// Return explanation (OcclusionConfig::explain_returns, recon/visibility.hpp): around an open
// frame flown with vertical passes ending 0.5 m over its top, carving keeps ghosts that lie, in
// every frame, on the elevation arc of a member's return (issue 15); the explanation pass removes
// most of them and keeps the members. The voxel-mode deconvolution of an orbit of the same frame
// inherits such ghosts from carving's candidates unless the candidates carving has proven ghosts
// are left out of its unknowns (VoxelDeconvConfig::support_min_bracket, support_refute).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/recon/visibility.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "test_support.hpp"

using namespace sonar3d;

namespace {

constexpr double kDeg = M_PI / 180.0;

// An open frame 0.66 × 0.66 × 0.6 m of 6 cm members: four legs at (±0.3, ±0.3), a top ring and
// a mid-height brace on the front and back faces.
constexpr double kHalf = 0.3, kMember = 0.06, kHeight = 0.6;
Scene frame_scene() {
  Scene scene;
  auto add = [&](const char* name, double sx, double sy, double sz, double x, double y, double z) {
    SceneObject o;
    o.name = name;
    o.mesh_world = make_box(sx, sy, sz);
    o.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(x, y, z)));
    o.reflectivity = 0.8;
    scene.objects.push_back(o);
  };
  const double top = kHeight - kMember / 2, span = 2 * kHalf - kMember;
  for (double x : {-kHalf, kHalf})
    for (double y : {-kHalf, kHalf}) add("leg", kMember, kMember, kHeight, x, y, kHeight / 2);
  for (double x : {-kHalf, kHalf}) {
    add("top_x", kMember, span, kMember, x, 0, top);
    add("brace", kMember, span, kMember, x, 0, kHeight / 2);
  }
  for (double y : {-kHalf, kHalf}) add("top_y", span, kMember, kMember, 0, y, top);
  return scene;
}

// Two vertical passes 2.5 m from the front (−x) and left (−y) faces, from 0.3 m below the base
// to 0.5 m above the top every 2 cm, carved at 1 cm voxels above the seabed; `pin_fraction` is
// the explanation's pin rule (OcclusionConfig::explain_pin_fraction).
PointCloud carve_frame(bool explain, std::size_t* ghosts = nullptr,
                       double pin_fraction = OcclusionConfig().explain_pin_fraction) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Scene scene = frame_scene();
  const Simulator sim(scene, spec, test::jittered_sim_config(0.05));
  CarveConfig cfg;
  cfg.voxel_size = 0.01;
  cfg.region =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.6, -0.6, -0.03), Eigen::Vector3d(0.6, 0.6, 1.5));
  cfg.occlusion.explain_returns = explain;
  cfg.occlusion.explain_pin_fraction = pin_fraction;
  Carver carver(spec, cfg);
  int seed = 0;
  for (double yaw : {0.0, 90 * kDeg}) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (double z = -0.3; z <= kHeight + 0.5 + 1e-9; z += 0.02) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = R;
      T.translation() = R * Eigen::Vector3d(-2.5 - kHalf, 0, 0) + Eigen::Vector3d(0, 0, z);
      carver.integrate(sim.render(T, ++seed), T);
    }
  }
  PointCloud cloud = carver.finalize();
  if (ghosts) *ghosts = carver.stats().ghosts;
  return cloud;
}

// Ghosts within the frame's bounding box: points more than `away` (4 cm) from every member (the
// open panels between the braces and the top ring, and the space they enclose).
std::size_t interior(const PointCloud& c, const TriangleMesh& truth, double away = 0.04) {
  const MeshDistance dist(truth);
  const double half = kHalf + kMember / 2;
  std::size_t n = 0;
  for (const auto& p : c.points)
    n += std::abs(p.x()) <= half && std::abs(p.y()) <= half && p.z() <= kHeight &&
         dist.distance(p) > away;
  return n;
}

}  // namespace

TEST(Explain, GhostsOfAnOpenFrameGoMembersStay) {
  const TriangleMesh truth = frame_scene().merged_world();
  std::size_t ghosts = 0;
  const PointCloud before = carve_frame(false);
  const PointCloud after = carve_frame(true, &ghosts);
  const EvalResult eb = evaluate(before, truth, EvalConfig());
  const EvalResult ea = evaluate(after, truth, EvalConfig());
  std::printf(
      "open frame: %zu -> %zu points (%zu ghosts), %zu -> %zu inside; outliers %.1f -> %.1f %%, "
      "coverage %.1f -> %.1f %%, median %.2f -> %.2f cm\n",
      before.size(), after.size(), ghosts, interior(before, truth), interior(after, truth),
      100 * eb.outliers, 100 * ea.outliers, 100 * eb.coverage, 100 * ea.coverage,
      100 * eb.median_error, 100 * ea.median_error);
  // Measured (1 cm voxels, pin fraction 0.2): outliers 16.8 -> 9.1 %, coverage 69.1 -> 69.0 %,
  // ghosts in the frame's box 430 -> 407. Before the refutation that follows the explanation
  // shielded whole voxels: 7.1 % and 274, most of the difference ghosts behind a member in every
  // frame that could refute them, refuted through the gaps of its one-voxel shell
  // (docs/carving.md, "Interior ghosts").
  ASSERT_GT(interior(before, truth), 100u);
  EXPECT_EQ(before.size() - after.size(), ghosts);
  EXPECT_LT(ea.outliers, 0.6 * eb.outliers);
  EXPECT_LT(interior(after, truth), interior(before, truth));
  EXPECT_GT(ea.coverage, eb.coverage - 0.01);  // the members stay: at most 1 point of coverage
  EXPECT_LE(ea.median_error, eb.median_error);
}

namespace {

// An orbit of the open frame (test::orbit_poses: 24 views at 2.5 m from its centre on each of 9
// levels from 0.3 m below its base to 0.3 m above its top), carved at 1 cm.
PointCloud carve_frame_orbit(bool explain, double pin_fraction) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(frame_scene(), spec, test::jittered_sim_config(0.05));
  CarveConfig cfg;
  cfg.voxel_size = 0.01;
  cfg.occlusion.explain_returns = explain;
  cfg.occlusion.explain_pin_fraction = pin_fraction;
  Carver carver(spec, cfg);
  const std::vector<Eigen::Isometry3d> poses = test::orbit_poses(2.5, 9, 24, -0.3, 0.15);
  for (std::size_t k = 0; k < poses.size(); ++k)
    carver.integrate(sim.render(poses[k], static_cast<int>(k + 1)), poses[k]);
  return carver.finalize();
}

}  // namespace

// The refutation that follows the explanation (drop_unexplained) sees the kept points only: the
// members' interiors went in the first occlusion resolution, so their faces are a shell one
// voxel thick. Each point shields its whole voxel there, so that a face turned away from a frame
// does not show through the gaps of the shell in front of it and get refuted as free space;
// with the first resolution's footprint (0.5 voxel), an orbit lost its members' back faces,
// layer by layer, as soon as they were not pinned (the lattice frame orbit at the pin fraction
// 0.4: coverage 98.2 -> 91.2 %, docs/experiments.md).
TEST(Explain, AnOrbitKeepsItsMembersAtAHighPinFraction) {
  const TriangleMesh truth = frame_scene().merged_world();
  const PointCloud plain = carve_frame_orbit(false, 0.2);
  const PointCloud strict = carve_frame_orbit(true, 0.4);
  const EvalResult ep = evaluate(plain, truth, EvalConfig());
  const EvalResult es = evaluate(strict, truth, EvalConfig());
  std::printf(
      "frame orbit, explanation at pin fraction 0.4: %zu -> %zu points; outliers %.2f -> %.2f "
      "%%, coverage %.1f -> %.1f %%, median %.2f -> %.2f cm\n",
      plain.size(), strict.size(), 100 * ep.outliers, 100 * es.outliers, 100 * ep.coverage,
      100 * es.coverage, 100 * ep.median_error, 100 * es.median_error);
  // Measured: outliers 47.5 -> 6.2 %, coverage 97.6 -> 96.9 %, median 8 -> 1 cm; with the first
  // resolution's footprint in the refutation, 2.4 % and 94.8 % (fails). The ghosts left lie
  // above and below the frame, never bracketed: --min-bracket removes them.
  EXPECT_LT(es.outliers, 0.25 * ep.outliers);
  EXPECT_GT(es.coverage, ep.coverage - 0.01);  // the members stay: at most 1 point of coverage
  EXPECT_LE(es.median_error, ep.median_error);
}

namespace {

// An orbit of the open frame: 12 views at 2.5 m from its centre on each of 9 levels from 0.3 m
// below its base to 0.3 m above its top; voxel-mode deconvolution at 1 cm with the given support
// rules.
PointCloud deconvolve_frame_orbit(double support_min_bracket, bool support_refute,
                                  DeconvReport* report) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(frame_scene(), spec, test::jittered_sim_config(0.05));
  const std::vector<Eigen::Isometry3d> poses = test::orbit_poses(2.5, 9, 12, -0.3, 0.15);
  std::vector<SonarImage> frames;
  for (std::size_t k = 0; k < poses.size(); ++k)
    frames.push_back(sim.render(poses[k], static_cast<int>(k + 1)));
  DeconvConfig cfg;
  cfg.mode = DeconvConfig::Mode::Voxel;
  cfg.voxel.support_min_bracket = support_min_bracket;
  cfg.voxel.support_refute = support_refute;
  return deconvolve_frames(frames, poses, spec, cfg, report);
}

}  // namespace

TEST(Explain, VoxelDeconvolutionOfAnOrbitLeavesProvenGhostsOut) {
  const TriangleMesh truth = frame_scene().merged_world();
  DeconvReport rb, ra;
  const PointCloud before = deconvolve_frame_orbit(0.0, false, &rb);
  const PointCloud after = deconvolve_frame_orbit(VoxelDeconvConfig().support_min_bracket,
                                                  VoxelDeconvConfig().support_refute, &ra);
  const EvalResult eb = evaluate(before, truth, EvalConfig());
  const EvalResult ea = evaluate(after, truth, EvalConfig());
  std::printf(
      "frame orbit, voxel mode: %zu -> %zu points, %zu -> %zu inside beyond 10 cm (left out: %zu "
      "never bracketed, %zu seen free); outliers %.1f -> %.1f %%, coverage %.1f -> %.1f %%, "
      "median %.2f -> %.2f cm\n",
      before.size(), after.size(), interior(before, truth, 0.1), interior(after, truth, 0.1),
      ra.voxel.unbracketed, ra.voxel.refuted, 100 * eb.outliers, 100 * ea.outliers,
      100 * eb.coverage, 100 * ea.coverage, 100 * eb.median_error, 100 * ea.median_error);
  EXPECT_EQ(rb.voxel.unbracketed + rb.voxel.refuted, 0u);  // the rules off: every candidate
  EXPECT_GT(ra.voxel.unbracketed, 0u);
  EXPECT_GT(ra.voxel.refuted, 0u);
  EXPECT_EQ(ra.voxel.candidates, rb.voxel.candidates);  // the same carving
  // Measured: points farther than 10 cm from every member inside the frame's box 306 -> 38,
  // outliers 28.3 -> 10.6 %, coverage 95.1 -> 96.3 %, median 2 -> 1 cm. Those 4–10 cm from a
  // member mostly stay (1 123 -> 762 beyond 4 cm): bracketed, and never seen free.
  ASSERT_GT(interior(before, truth, 0.1), 100u);
  EXPECT_LT(interior(after, truth, 0.1), 0.2 * interior(before, truth, 0.1));
  EXPECT_LT(ea.outliers, 0.5 * eb.outliers);
  EXPECT_GT(ea.coverage, eb.coverage - 0.01);  // the members stay: at most 1 point of coverage
  EXPECT_LE(ea.median_error, eb.median_error);
}

// The fast paths of issue 29 (docs/performance.md, "Ghost removal") skip only work that cannot
// change the result: the occlusion resolution defers the blocks that hold no return pixel and
// skips those whose candidates are already refuted or cannot be refuted by the frame; the
// explanation skips the blocks with no return pixel in reach and sorts hits by counting. Same
// kept points, in the same order, as the straightforward computations, on one pass of the open
// frame (1 cm) — the first resolution, then the explanation's rounds (with their whole-voxel
// resolutions).
TEST(Explain, FastPathsKeepTheSamePointsAsTheStraightforwardOnes) {
  const SonarSpec spec = test::reduced_spec_20deg();
  const Simulator sim(frame_scene(), spec, test::jittered_sim_config(0.05));
  CarveConfig cfg;
  cfg.voxel_size = 0.01;
  cfg.resolve_occlusions = false;  // the candidates
  cfg.region =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.6, -0.6, -0.03), Eigen::Vector3d(0.6, 0.6, 1.5));
  Carver carver(spec, cfg);
  int seed = 0;
  for (double z = -0.3; z <= kHeight + 0.5 + 1e-9; z += 0.02) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(-2.5 - kHalf, 0.1, z);
    carver.integrate(sim.render(T, ++seed), T);
  }
  const PointCloud candidates = carver.finalize();
  OcclusionConfig occ = cfg.occlusion;
  occ.voxel_size = cfg.voxel_size;
  occ.explain_returns = false;
  const PointCloud fast = resolve_occlusions(candidates, carver.frame_returns(), spec, occ);
  const PointCloud ref =
      detail::resolve_occlusions_reference(candidates, carver.frame_returns(), spec, occ);
  std::size_t removed_fast = 0, removed_ref = 0;
  const PointCloud explained =
      drop_unexplained(fast, carver.frame_returns(), spec, occ, &removed_fast);
  const PointCloud explained_ref =
      detail::drop_unexplained_reference(ref, carver.frame_returns(), spec, occ, &removed_ref);
  std::printf("one pass of the open frame: %zu candidates -> %zu points -> %zu explained\n",
              candidates.size(), fast.size(), explained.size());
  ASSERT_GT(candidates.size(), 2 * fast.size());  // the resolution removes much
  ASSERT_GT(removed_ref, 0u);                     // and so does the explanation
  EXPECT_EQ(fast.points, ref.points);
  EXPECT_EQ(fast.intensity, ref.intensity);
  EXPECT_EQ(removed_fast, removed_ref);
  EXPECT_EQ(explained.points, explained_ref.points);
}

// Points no frame put in a return pixel, and a cloud without frames, are left alone; a sensor
// mismatch is an error naming the frame.
TEST(Explain, EdgeCases) {
  const SonarSpec spec = test::reduced_spec_20deg();
  PointCloud cloud;
  cloud.points = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(2, 0, 0)};
  OcclusionConfig cfg;
  EXPECT_EQ(explain_returns(cloud, {}, spec, cfg), (std::vector<std::uint8_t>{1, 1}));
  SonarImage empty(spec.range_bins, spec.beams());
  const FrameReturns f = summarize_frame(empty, Eigen::Isometry3d::Identity(), spec);
  ExplainStats st;
  EXPECT_EQ(explain_returns(cloud, {f}, spec, cfg, &st), (std::vector<std::uint8_t>{1, 1}));
  EXPECT_EQ(st.removed, 0u);
  FrameReturns wrong = f;
  wrong.beams = spec.beams() + 1;
  test::expect_error([&] { explain_returns(cloud, {f, wrong}, spec, cfg); }, "frame 1");
  OcclusionConfig bad;
  bad.explain_pin_fraction = 0;
  test::expect_error([&] { bad.validate(); }, "explain_pin_fraction");
}
