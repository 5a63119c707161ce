// recog: CAD-model recognition in 2D (thesis sec. 6.3.2): catalogue, ring descriptors, EMD, the
// patch scan with early abort, the 4D search (eq. 6.9), trimmed ICP, the whole method on
// synthetic and simulated scenes, and bad inputs.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "recog_test_support.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/descriptor.hpp"
#include "sonar3d/recog/icp.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/scale.hpp"
#include "sonar3d/recog/verify.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;

namespace {

using test::kDeg;
using test::pose;
using test::reference_template;

double seabed(double x, double y) {
  return 0.08 * std::sin(0.6 * x + 0.3) * std::cos(0.45 * y) + 0.03 * std::sin(1.7 * x - 1.1 * y);
}

// A 2.5D scene seen from above: on a grid of `step`, the highest of the seabed and the placed
// models, plus Gaussian noise. Rocks (small bumps) add clutter. `dzdx`: the seabed's slope.
PointCloud synthetic_scene(
    const std::vector<std::pair<const ModelTemplate*, Eigen::Isometry3d>>& placed, double x0,
    double y0, double x1, double y1, double step, double noise, unsigned seed = 1,
    double dzdx = 0) {
  ElevationMap top;
  top.cell_m = step;
  top.origin_xy = {x0, y1};
  top.cols = static_cast<int>(std::round((x1 - x0) / step));
  top.rows = static_cast<int>(std::round((y1 - y0) / step));
  top.z.assign(static_cast<std::size_t>(top.rows) * top.cols, ElevationMap::kNoData);
  for (const auto& [m, T] : placed) {
    TopViewConfig tv;
    tv.cell_m = step;
    tv.grid_anchor_xy = top.origin_xy;
    const Eigen::Vector2d c =
        (T * Eigen::Vector3d(m->center_xy.x(), m->center_xy.y(), 0)).head<2>();
    const ElevationMap v = render_placed_top_view(*m, T, c, tv);
    const int dc = static_cast<int>(std::lround((v.origin_xy.x() - x0) / step));
    const int dr = static_cast<int>(std::lround((y1 - v.origin_xy.y()) / step));
    for (int r = 0; r < v.rows; ++r) {
      for (int col = 0; col < v.cols; ++col) {
        const float z = v.at(r, col);
        const int rr = r + dr, cc = col + dc;
        if (z != z || rr < 0 || cc < 0 || rr >= top.rows || cc >= top.cols) continue;
        float& o = top.at(rr, cc);
        if (!(o >= z)) o = z;
      }
    }
  }
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  const double rocks[][3] = {
      {x0 + 1.1, y0 + 0.9, 0.15}, {x1 - 1.3, y1 - 0.8, 0.2}, {x0 + 0.7, y1 - 1.2, 0.12}};
  PointCloud cloud;
  for (int r = 0; r < top.rows; ++r) {
    for (int col = 0; col < top.cols; ++col) {
      const Eigen::Vector2d p = top.cell_center_xy(r, col);
      double z = seabed(p.x(), p.y()) + dzdx * p.x();
      for (const auto& k : rocks) {
        const double q = (p - Eigen::Vector2d(k[0], k[1])).squaredNorm();
        z += k[2] * std::exp(-q / (2 * 0.1 * 0.1));
      }
      const float zm = top.at(r, col);
      if (zm == zm) z = std::max(z, static_cast<double>(zm));
      cloud.points.emplace_back(p.x(), p.y(), z + (noise > 0 ? n(rng) : 0.0));
    }
  }
  return cloud;
}

double yaw_of(const Eigen::Isometry3d& T) { return std::atan2(T.linear()(1, 0), T.linear()(0, 0)); }

// Yaw difference modulo the symmetry's period, degrees.
double yaw_error_deg(double a, double b, double period = 2 * M_PI) {
  const double d = std::remainder(a - b, period);
  return std::abs(d) / kDeg;
}

}  // namespace

TEST(RecogEmd, OneDimensionalClosedFormMatchesHandAndOpenCv) {
  // Hand-computed: all mass one bin over = 1 bin width; half the mass two bins over = 1.
  EXPECT_NEAR(emd_1d({1, 0, 0}, {0, 1, 0}, 0.01), 0.01, 1e-9);
  EXPECT_NEAR(emd_1d({1, 0, 0}, {0, 0, 1}, 0.01), 0.02, 1e-9);
  EXPECT_NEAR(emd_1d({0.5f, 0, 0.5f}, {0, 1, 0}, 1.0), 1.0, 1e-6);
  EXPECT_NEAR(emd_1d({0.25f, 0.25f, 0.5f, 0}, {0.25f, 0.25f, 0.5f, 0}, 1.0), 0.0, 1e-9);
  // {0.5, 0.5, 0, 0} -> {0, 0, 0.5, 0.5}: each half moves two bins: 2.
  EXPECT_NEAR(emd_1d({0.5f, 0.5f, 0, 0}, {0, 0, 0.5f, 0.5f}, 1.0), 2.0, 1e-6);
  EXPECT_THROW(emd_1d({1, 0}, {1}, 1.0), Error);
  // Random histograms of equal mass: the closed form equals OpenCV's transport solver.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 5 + trial;
    std::vector<float> a(n), b(n);
    float sa = 0, sb = 0;
    for (int i = 0; i < n; ++i) {
      a[i] = u(rng) < 0.3f ? 0.f : u(rng);
      b[i] = u(rng);
      sa += a[i];
      sb += b[i];
    }
    if (sa == 0) a[0] = sa = 1;
    for (auto& v : a) v /= sa;
    for (auto& v : b) v /= sb;
    EXPECT_NEAR(emd_1d(a, b, 0.01), emd_opencv(a, b, 0.01), 2e-4) << "trial " << trial;
  }
}

TEST(RecogDescriptor, RingsAreEqualUnderRotationOfTheModel) {
  const ModelTemplate pillar = reference_template("pillar");
  const ModelTemplate riser = reference_template("riser");
  const double cell = 0.04, rp = pillar.radius_m + 0.1;
  DescriptorConfig dc;
  const RingLayout layout = make_ring_layout(cell, rp, dc.ring_width_m);
  ASSERT_GE(layout.rings.size(), 5u);
  auto desc = [&](const ModelTemplate& m, double yaw) {
    TopViewConfig tv;
    tv.cell_m = cell;
    tv.background_radius_m = rp + cell;
    // Rotated about the centre of the ring layout's centre cell.
    const ElevationMap v = render_top_view(m, yaw, {cell / 2, cell / 2}, tv);
    const int r = static_cast<int>(std::floor((v.origin_xy.y() - cell / 2) / cell));
    const int c = static_cast<int>(std::floor((cell / 2 - v.origin_xy.x()) / cell));
    return describe_model(v, r, c, layout, dc);
  };
  const RingDescriptor d0 = desc(pillar, 0);
  double worst_rotated = 0;
  for (double yaw : {17.0, 45.0, 90.0, 133.0, 250.0}) {
    const RingDescriptor dr = desc(pillar, yaw * kDeg);
    ASSERT_EQ(dr.num_rings(), d0.num_rings());
    for (int k = 0; k < d0.num_rings(); ++k) {
      // Equal up to rasterisation at 4 cm: the pillar's sloped square column crosses the rings'
      // circles in different cells at each yaw (exactly equal at 90°, where the grid maps onto
      // itself); under 4 % of the model's 2.5 m height per ring.
      const double e = emd_1d(d0.hist[k], dr.hist[k], d0.bin_m);
      EXPECT_LT(e, yaw == 90.0 ? 1e-6 : 0.1) << "yaw " << yaw << " ring " << k;
    }
    worst_rotated = std::max(worst_rotated, ring_distance(d0, dr, 1e9));
  }
  // A different model in the same rings is far more different than any rotation.
  RingDescriptor other;
  TopViewConfig tv;
  tv.cell_m = cell;
  tv.background_radius_m = rp + cell;
  const ElevationMap v = render_top_view(riser, 0, {cell / 2, cell / 2}, tv);
  ASSERT_TRUE(describe(v, {}, static_cast<int>(std::floor((v.origin_xy.y() - cell / 2) / cell)),
                       static_cast<int>(std::floor((cell / 2 - v.origin_xy.x()) / cell)), layout,
                       d0.z_lo, d0.num_bins, d0.bin_m, 0.0, &other));
  EXPECT_GT(ring_distance(d0, other, 1e9), 10 * worst_rotated);
}

TEST(RecogScan, EarlyAbortNeverChangesTheWinner) {
  const ModelTemplate tank = reference_template("tank", Symmetry::Full);
  const ModelTemplate pillar = reference_template("pillar");
  const PointCloud cloud =
      synthetic_scene({{&pillar, pose(2.5, 3.0, 0.0, 30)}, {&tank, pose(6.0, 2.0, -0.05, 0)}}, 0, 0,
                      9, 6, 0.02, 0.005);
  ElevationMapConfig mc;
  mc.cell_m = 0.08;
  const ElevationMap map = elevation_map_from_points(cloud, mc);
  for (const ModelTemplate* m : {&tank, &pillar}) {
    SCOPED_TRACE(m->name);
    const double rp = m->radius_m + std::sqrt(0.5) * 0.16;
    DescriptorConfig dc;
    const RingLayout layout = make_ring_layout(map.cell_m, rp, dc.ring_width_m);
    TopViewConfig tv;
    tv.cell_m = map.cell_m;
    tv.background_radius_m = rp + map.cell_m;
    const ElevationMap v = render_top_view(*m, 0, {0, 0}, tv);
    const RingDescriptor md =
        describe_model(v, static_cast<int>(std::floor(v.origin_xy.y() / map.cell_m)),
                       static_cast<int>(std::floor(-v.origin_xy.x() / map.cell_m)), layout, dc);
    ScanConfig on, off;
    off.early_abort = false;
    const double inf = std::numeric_limits<double>::infinity();
    const ScanResult a = scan_patches(map, {}, {}, layout, md, 0.5, inf, on);
    const ScanResult b = scan_patches(map, {}, {}, layout, md, 0.5, inf, off);
    ASSERT_TRUE(a.found && b.found);
    EXPECT_EQ(a.row, b.row);
    EXPECT_EQ(a.col, b.col);
    EXPECT_EQ(a.score_m, b.score_m);
    EXPECT_EQ(b.aborted, 0u);
    EXPECT_GT(a.aborted, a.scored / 2) << "early abort should drop most candidates";
    EXPECT_LT(a.rings_evaluated, b.rings_evaluated);
    // And the winner is the model's own patch (within the patch period and a cell).
    const Eigen::Vector2d truth =
        m == &tank ? Eigen::Vector2d(6.0, 2.0) : Eigen::Vector2d(2.5, 3.0);
    const Eigen::Vector2d off_c = (pose(0, 0, 0, m == &tank ? 0 : 30).linear() *
                                   Eigen::Vector3d(m->center_xy.x(), m->center_xy.y(), 0))
                                      .head<2>();
    EXPECT_LT((a.center_xy - (truth + off_c)).norm(), 0.25);
  }
}

TEST(RecogSearch4d, RecoversKnownEastNorthHeightAndYaw) {
  const ModelTemplate pillar = reference_template("pillar");
  const Eigen::Isometry3d truth = pose(3.03, 2.47, -0.12, 37);
  const PointCloud cloud = synthetic_scene({{&pillar, truth}}, 0, 0, 6, 5, 0.01, 0.0);
  ElevationMapConfig mc;
  mc.cell_m = 0.08;
  const ElevationMap coarse = elevation_map_from_points(cloud, mc);
  mc.cell_m = 0.02;
  const ElevationMap fine = elevation_map_from_points(cloud, mc);
  const Eigen::Vector2d c_true =
      (truth * Eigen::Vector3d(pillar.center_xy.x(), pillar.center_xy.y(), 0)).head<2>();
  Search4dConfig cfg;
  // Start from a patch centre off by up to the scan's worst case (√2/2 · T_NE).
  const Search4dResult r =
      search_4d(pillar, coarse, fine, c_true + Eigen::Vector2d(0.09, -0.07), 0.16, cfg);
  ASSERT_TRUE(r.found);
  const Eigen::Vector3d c_found =
      r.T_world_model * Eigen::Vector3d(pillar.center_xy.x(), pillar.center_xy.y(), 0);
  EXPECT_NEAR(c_found.x(), c_true.x(), 0.03);
  EXPECT_NEAR(c_found.y(), c_true.y(), 0.03);
  EXPECT_NEAR(r.T_world_model.translation().z(), -0.12, 0.03);
  // The pillar's square column repeats every 90°, its footing too: yaw modulo 90°.
  EXPECT_LT(yaw_error_deg(yaw_of(r.T_world_model), 37 * kDeg, M_PI / 2), 2.0);
  EXPECT_GT(r.yaws_tried, 72);
}

namespace {
// An open frame of sx × sy × sz from square members `w` wide (top and bottom rectangles, four
// posts, a top cross rail) standing on the model frame's z = 0: seen from above, mostly the
// seabed through it.
ModelTemplate open_frame_template(double sx, double sy, double sz, double w) {
  TriangleMesh mesh;
  auto member = [&](double cx, double cy, double cz, double lx, double ly, double lz) {
    TriangleMesh b = make_box(lx, ly, lz);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(cx, cy, cz);
    b.transform(T);
    mesh.append(b);
  };
  const double hx = 0.5 * (sx - w), hy = 0.5 * (sy - w);
  for (const double z : {0.5 * w, sz - 0.5 * w}) {
    member(0, -hy, z, sx, w, w);
    member(0, hy, z, sx, w, w);
    member(-hx, 0, z, w, sy, w);
    member(hx, 0, z, w, sy, w);
  }
  for (const double x : {-hx, hx}) {
    for (const double y : {-hy, hy}) member(x, y, 0.5 * sz, w, w, sz);
  }
  member(0, 0, sz - 0.5 * w, w, sy, w);
  ModelSamplingConfig sc;
  sc.spacing_m = 0.015;
  return make_model_template("open_frame", mesh, Symmetry::Half, -1, sc);
}
}  // namespace

// Issue 28, mixed_buried field: the 4D search's height (eq. 6.1) on structures whose informative
// cells are the minority. Search4dConfig::seabed_ring_m > 0 (the default) takes the height from
// the model's structure, bounded by the seabed around it, and scores shifts by a truncated mean.
void expect_placed(const ModelTemplate& m, const Eigen::Isometry3d& truth, const Search4dResult& r,
                   double tol_xy, double tol_z) {
  ASSERT_TRUE(r.found);
  const Eigen::Vector3d c(m.center_xy.x(), m.center_xy.y(), 0);
  EXPECT_LT(((r.T_world_model * c) - (truth * c)).head<2>().norm(), tol_xy);
  EXPECT_NEAR(r.T_world_model.translation().z(), truth.translation().z(), tol_z);
}

// An open frame: seen from above, mostly the seabed through it. Placed standing where it is.
TEST(RecogSearch4d, AnOpenFrameIsPlacedStandingOnTheSeabed) {
  const ModelTemplate frame = open_frame_template(3.0, 2.4, 1.6, 0.06);
  const Eigen::Isometry3d truth = pose(4.02, 3.05, -0.03, 75);
  const PointCloud cloud = synthetic_scene({{&frame, truth}}, 0, 0, 8, 6.5, 0.02, 0.003, 4);
  ElevationMapConfig mc;
  mc.cell_m = 0.08;
  const ElevationMap coarse = elevation_map_from_points(cloud, mc);
  mc.cell_m = 0.02;
  const ElevationMap fine = elevation_map_from_points(cloud, mc);
  const Eigen::Vector2d c_true =
      (truth * Eigen::Vector3d(frame.center_xy.x(), frame.center_xy.y(), 0)).head<2>();
  // The scan's patch centre lies on a part of the structure, off its centre.
  const Search4dResult r = search_4d(frame, coarse, fine, c_true + Eigen::Vector2d(0.35, -0.3),
                                     0.16, Search4dConfig{}, 0.5);
  expect_placed(frame, truth, r, 0.05, 0.05);
  EXPECT_LT(yaw_error_deg(yaw_of(r.T_world_model), 75 * kDeg, M_PI), 2.0);
}

// The bounded search's shifts coarse to fine (every second cell shift, then every shift about
// the best of them and a descent) end where the exhaustive search ends: an open frame of thin
// members (its score's basin is narrowest), searched from patches off its centre on both sides.
TEST(RecogSearch4d, CoarseToFineShiftsEndWhereTheExhaustiveSearchEnds) {
  const ModelTemplate frame = open_frame_template(3.0, 2.4, 1.6, 0.06);
  const Eigen::Isometry3d truth = pose(4.02, 3.05, -0.03, 75);
  const PointCloud cloud = synthetic_scene({{&frame, truth}}, 0, 0, 8, 6.5, 0.02, 0.003, 4);
  ElevationMapConfig mc;
  mc.cell_m = 0.08;
  const ElevationMap coarse = elevation_map_from_points(cloud, mc);
  mc.cell_m = 0.02;
  const ElevationMap fine = elevation_map_from_points(cloud, mc);
  const Eigen::Vector2d c_true =
      (truth * Eigen::Vector3d(frame.center_xy.x(), frame.center_xy.y(), 0)).head<2>();
  Search4dConfig exhaustive;
  exhaustive.shift_stride = 1;
  ASSERT_GT(Search4dConfig{}.shift_stride, 1);  // the default is coarse to fine
  for (const Eigen::Vector2d& off : {Eigen::Vector2d(0.35, -0.3), Eigen::Vector2d(-0.5, 0.45)}) {
    const Search4dResult a = search_4d(frame, coarse, fine, c_true + off, 0.16, {}, 0.5);
    const Search4dResult b = search_4d(frame, coarse, fine, c_true + off, 0.16, exhaustive, 0.5);
    ASSERT_TRUE(a.found && b.found);
    expect_placed(frame, truth, a, 0.05, 0.05);
    EXPECT_LT((a.T_world_model.translation() - b.T_world_model.translation()).norm(), 0.01)
        << "patch offset " << off.transpose();
    EXPECT_LT(yaw_error_deg(yaw_of(a.T_world_model), yaw_of(b.T_world_model), M_PI), 0.5);
  }
}

// A thin upright buoy (13 cm wide, 0.9 m tall) buried 20 cm: on 8 cm cells its top is 2 × 2 or
// 3 × 3 cells and its ring of seabed the majority. The thesis' median seats it on that ring (20 cm
// too high, or its top sunk to the seabed beside it); bounded by the seabed, its height comes from
// its top, and the small model is searched on the fine map.
TEST(RecogSearch4d, AThinBuriedBuoyIsPlacedAtItsDepth) {
  TriangleMesh mesh = make_cylinder(0.065, 0.9, 32);
  ModelSamplingConfig sc;
  sc.spacing_m = 0.01;
  const ModelTemplate buoy = make_model_template("buoy", mesh, Symmetry::Full, -1, sc);
  const Eigen::Isometry3d truth = pose(3.01, 2.47, seabed(3.01, 2.47) - 0.2, 0);
  const PointCloud cloud = synthetic_scene({{&buoy, truth}}, 0, 0, 6, 5, 0.02, 0.003, 6);
  ElevationMapConfig mc;
  mc.cell_m = 0.08;
  const ElevationMap coarse = elevation_map_from_points(cloud, mc);
  mc.cell_m = 0.02;
  const ElevationMap fine = elevation_map_from_points(cloud, mc);
  const Eigen::Vector2d patch = truth.translation().head<2>() + Eigen::Vector2d(0.1, -0.12);
  const Search4dResult r = search_4d(buoy, coarse, fine, patch, 0.16, Search4dConfig{}, 0.5);
  expect_placed(buoy, truth, r, 0.03, 0.03);
  Search4dConfig thesis;
  thesis.seabed_ring_m = 0;
  const Search4dResult u = search_4d(buoy, coarse, fine, patch, 0.16, thesis, 0.5);
  ASSERT_TRUE(u.found);
  const double dz = u.T_world_model.translation().z() - truth.translation().z();
  const double dxy = (u.T_world_model.translation() - truth.translation()).head<2>().norm();
  EXPECT_TRUE(std::abs(dz) > 0.1 || dxy > 0.1) << "dz " << dz << " dxy " << dxy;
}

TEST(RecogIcp, TrimmedIcpRecoversSmall6dPerturbationWithOutliers) {
  const ModelTemplate riser = reference_template("riser");
  const Eigen::Isometry3d truth = pose(1.0, -2.0, 0.3, 20, 1.5, -2.0);
  std::vector<Eigen::Vector3f> scene;
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0, 0.003f);
  for (std::size_t i = 0; i < riser.points.size(); i += 3) {
    // The structure seen from all sides (an orbit; seen only from above, horizontal shifts
    // along flat tops are unobservable and ICP rightly leaves them to the 4D search).
    scene.push_back((truth * riser.points[i].cast<double>()).cast<float>() +
                    Eigen::Vector3f(n(rng), n(rng), n(rng)));
  }
  const std::size_t inliers = scene.size();
  // 30 % outliers within the correspondence gate: debris lying 4-12 cm over the structure, all
  // on one side, so that plain least squares is pulled up.
  std::uniform_real_distribution<float> u(0.04f, 0.12f);
  std::uniform_int_distribution<std::size_t> pick(0, inliers - 1);
  for (std::size_t i = 0; i < inliers * 3 / 10; ++i) {
    scene.push_back(scene[pick(rng)] + Eigen::Vector3f(0, 0, u(rng)));
  }
  const Eigen::Isometry3d start = truth * pose(0.04, -0.03, 0.02, 3, -2, 2);
  const ModelIndex index(riser.points, riser.normals);
  TrimmedIcpConfig cfg;
  const IcpResult r = trimmed_icp(index, scene, start, cfg);
  const Eigen::Isometry3d err = truth.inverse() * r.T_world_model;
  EXPECT_LT(err.translation().norm(), 0.005);
  EXPECT_LT(Eigen::AngleAxisd(err.linear()).angle() / kDeg, 0.3);
  // Plain least squares (no trimming) is pulled by the outliers further than trimmed ICP.
  cfg.keep_fraction = 1.0;
  const IcpResult plain = trimmed_icp(index, scene, start, cfg);
  const Eigen::Isometry3d err_plain = truth.inverse() * plain.T_world_model;
  EXPECT_GT(err_plain.translation().norm(), err.translation().norm());
}

namespace {
RecognitionConfig test_config() {
  RecognitionConfig c;
  c.sampling.spacing_m = 0.015;
  if (std::getenv("RECOG_NO_ICP")) c.run_icp = false;
  if (std::getenv("RECOG_MAX_SCORE"))
    c.max_relative_score = std::atof(std::getenv("RECOG_MAX_SCORE"));
  return c;
}
}  // namespace

TEST(RecogPipeline, FindsStructuresAtTheirPosesAndNotAbsentModels) {
  const ModelTemplate pillar = reference_template("pillar");
  const ModelTemplate tank = reference_template("tank", Symmetry::Full);
  const ModelTemplate riser = reference_template("riser");  // absent from the scene
  const Eigen::Isometry3d T_pillar = pose(3.0, 3.5, -0.05, 65);
  const Eigen::Isometry3d T_tank = pose(8.2, 2.0, -0.1, 0);
  const PointCloud cloud =
      synthetic_scene({{&pillar, T_pillar}, {&tank, T_tank}}, 0, 0, 11, 6.5, 0.02, 0.005, 9);
  const RecognitionResult r = recognize_2d(cloud, {pillar, tank, riser}, test_config());
  ASSERT_EQ(r.placements.size(), 2u) << placements_json(r, "", "", test_config());
  for (const Placement& p : r.placements) {
    SCOPED_TRACE(p.model);
    ASSERT_NE(p.model, "riser");
    const ModelTemplate& m = p.model == "pillar" ? pillar : tank;
    const Eigen::Isometry3d& T = p.model == "pillar" ? T_pillar : T_tank;
    const Eigen::Vector3d c(m.center_xy.x(), m.center_xy.y(), 0.5);
    EXPECT_LT((p.T_world_model * c - T * c).norm(), 0.03);
    if (p.model == "pillar") {
      EXPECT_LT(yaw_error_deg(yaw_of(p.T_world_model), yaw_of(T), M_PI / 2), 2.0);
    }
    EXPECT_LT(p.residual.median_m, 0.02);
    if (std::getenv("RECOG_PRINT"))
      std::printf("%s", placements_json(r, "", "", test_config()).c_str());
    EXPECT_GT(p.support, 0.7) << placements_json(r, "", "", test_config());
    EXPECT_GE(p.confidence, test_config().verification.min_confidence);
  }
  // The riser was searched and its best candidate rejected, or no patch scored.
  bool riser_searched = false;
  for (const auto& s : r.searches) riser_searched = riser_searched || s.model == "riser";
  EXPECT_TRUE(riser_searched);
}

namespace {
// A box of sx × sy × sz standing on the model frame's z = 0, as a catalogue model.
ModelTemplate box_template(const std::string& name, double sx, double sy, double sz) {
  TriangleMesh mesh = make_box(sx, sy, sz);
  Eigen::Isometry3d up = Eigen::Isometry3d::Identity();
  up.translation().z() = 0.5 * sz;
  mesh.transform(up);
  ModelSamplingConfig sc;
  sc.spacing_m = 0.015;
  return make_model_template(name, mesh, Symmetry::Half, -1, sc);
}

ElevationMap scene_map(const PointCloud& cloud) {
  ElevationMapConfig mc;
  mc.cell_m = 0.02;
  return elevation_map_from_points(cloud, mc);
}
}  // namespace

// Verification terms on hand-made cases (docs/recognition.md, "Verification").
TEST(RecogVerify, ModelOverFreeSpaceIsRejectedAndTheTruePlacementConfirmed) {
  const ModelTemplate tank = reference_template("tank", Symmetry::Full);
  const Eigen::Isometry3d T_tank = pose(3.0, 2.5, -0.05, 30);
  const PointCloud cloud = synthetic_scene({{&tank, T_tank}}, 0, 0, 8, 5, 0.02, 0.005, 3);
  const ElevationMap map = scene_map(cloud);
  const VerificationConfig vc;
  const Verification right = verify_placement(tank, T_tank, map, {}, vc);
  ASSERT_TRUE(right.valid);
  EXPECT_GT(right.seen, 0.9);
  EXPECT_GT(right.explained, 0.85);
  EXPECT_LT(right.violation, 0.05);
  EXPECT_LT(right.unexplained, 0.1);
  EXPECT_LT(right.spill, 0.05);
  EXPECT_GE(right.confidence, vc.min_confidence);
  // The same tank over bare seabed 2.5 m away: the survey saw water where it would stand.
  const Eigen::Isometry3d T_free = pose(5.6, 2.5, -0.05, 30);
  const Verification free = verify_placement(tank, T_free, map, {}, vc);
  ASSERT_TRUE(free.valid);
  EXPECT_GT(free.violation, 0.8);
  EXPECT_LT(free.explained, 0.2);
  EXPECT_LT(free.confidence, vc.min_confidence);
  EXPECT_LT(free.score_m3, 0.0);
  // Unobserved (cells removed): neither for nor against, and no seabed to stand on.
  std::vector<uint8_t> all(map.z.size(), 1);
  const Verification unseen = verify_placement(tank, T_tank, map, all, vc);
  EXPECT_FALSE(unseen.valid);
  EXPECT_EQ(unseen.confidence, 0.0);
  EXPECT_DOUBLE_EQ(unseen.overlap, 1.0);
}

TEST(RecogVerify, AModelExplainingARegionScoresAboveOneExplainingHalfOfIt) {
  const ModelTemplate whole = box_template("whole", 2.0, 0.8, 0.5);
  const ModelTemplate half = box_template("half", 1.0, 0.8, 0.5);
  const Eigen::Isometry3d T = pose(3.0, 2.5, 0.0, 0);
  const PointCloud cloud = synthetic_scene({{&whole, T}}, 0, 0, 7, 5, 0.02, 0.004, 5);
  const ElevationMap map = scene_map(cloud);
  const VerificationConfig vc;
  const Verification w = verify_placement(whole, T, map, {}, vc);
  // The half box on one half of the whole one: what it covers agrees, but the other half stands
  // beside it unexplained.
  const Verification h = verify_placement(half, pose(2.5, 2.5, 0.0, 0), map, {}, vc);
  ASSERT_TRUE(w.valid && h.valid);
  EXPECT_GT(h.explained, 0.85);
  EXPECT_GT(h.unexplained, w.unexplained + 0.05);  // h: 0.097 measured
  EXPECT_GT(h.spill, 0.15);
  EXPECT_LT(w.unexplained, 0.05);
  EXPECT_LT(w.spill, 0.05);
  EXPECT_GT(w.score_m3, h.score_m3 + 0.1);
  EXPECT_GT(w.confidence, h.confidence);
  // A model larger than the structure hangs over free seabed.
  const ModelTemplate wide = box_template("wide", 2.6, 0.8, 0.5);
  const Verification o = verify_placement(wide, T, map, {}, vc);
  EXPECT_GT(o.violation, 0.15);
  EXPECT_GT(w.score_m3, o.score_m3 + 0.05);
}

// Relief evidence (issue 28): a small model whose relief above the 10 cm threshold is a sliver
// is confirmed by that sliver alone, and a rock of its height explains it (a false hot stab on a
// rock, confidence 0.78, in the benchmark's ordnance field). Its whole shape above the seabed
// must be there: a rock's flanks fall away under the model's ends; a true object, even partly
// buried, shows its shape.
TEST(RecogVerify, ASmallModelOnARockIsRejectedAndAPartlyBuriedObjectKept) {
  // A hot stab's size: a lying cylinder 0.5 m long, 8 cm thick, with a 13 cm-high handle in its
  // middle (its only part above the 10 cm relief threshold); and a 0.6 × 0.4 × 0.4 m block.
  TriangleMesh rod_mesh = make_cylinder(0.04, 0.5, 24);
  rod_mesh.transform(pose(0, 0, 0.04, 0, 0, 90));  // axis along x, lying on z = 0
  TriangleMesh handle = make_box(0.12, 0.08, 0.13);
  handle.transform(pose(0, 0, 0.065, 0));
  rod_mesh.append(handle);
  ModelSamplingConfig sc;
  sc.spacing_m = 0.01;
  const ModelTemplate rod = make_model_template("rod", rod_mesh, Symmetry::Half, -1, sc);
  const ModelTemplate block = box_template("block", 0.6, 0.4, 0.4);
  // The rod lying on the seabed, the block 40 % buried.
  const Eigen::Isometry3d T_rod = pose(3.0, 1.3, seabed(3.0, 1.3), 25);
  const Eigen::Isometry3d T_block = pose(4.2, 2.6, seabed(4.2, 2.6) - 0.16, -10);
  PointCloud cloud =
      synthetic_scene({{&rod, T_rod}, {&block, T_block}}, 0, 0, 6, 4, 0.02, 0.004, 13);
  // A rock as broad as the rod is long: a 10 cm dome, σ 12 cm, at (1.8, 2.8).
  const Eigen::Vector2d rock(1.8, 2.8);
  for (auto& p : cloud.points) {
    const double q = (p.head<2>().cast<double>() - rock).squaredNorm();
    p.z() += 0.10 * std::exp(-q / (2 * 0.12 * 0.12));
  }
  const ElevationMap map = scene_map(cloud);
  const VerificationConfig vc;
  const Verification rod_true = verify_placement(rod, T_rod, map, {}, vc);
  const Verification block_true = verify_placement(block, T_block, map, {}, vc);
  // The rod on the rock, its handle's top 3 cm above the rock's: as a search registering the
  // handle on the rock's top does.
  const Eigen::Isometry3d T_rock = pose(rock.x(), rock.y(), seabed(rock.x(), rock.y()), 0);
  const Verification on_rock = verify_placement(rod, T_rock, map, {}, vc);
  ASSERT_TRUE(rod_true.valid && block_true.valid && on_rock.valid);
  if (std::getenv("RECOG_PRINT")) {
    for (const Verification* v : {&rod_true, &block_true, &on_rock}) {
      std::printf(
          "seen %.2f explained %.2f violation %.2f unexplained %.2f spill %.2f evidence "
          "%.2f relief %.4f confidence %.2f\n",
          v->seen, v->explained, v->violation, v->unexplained, v->spill, v->evidence, v->relief_m3,
          v->confidence);
    }
  }
  // On the rock the other terms read as certainty: the handle, all of the model above 10 cm, is
  // explained by the rock's top, and the body below 10 cm is not judged.
  EXPECT_GT(on_rock.explained, 0.9);
  EXPECT_LT(on_rock.violation, 0.1);
  EXPECT_GE(on_rock.confidence, vc.min_confidence);
  // The relief evidence tells them apart.
  EXPECT_LT(on_rock.evidence, vc.min_evidence);
  EXPECT_GE(rod_true.evidence, vc.min_evidence + 0.05);
  EXPECT_GE(block_true.evidence, vc.min_evidence + 0.05);
  EXPECT_GE(rod_true.confidence, vc.min_confidence);
  EXPECT_GE(block_true.confidence, vc.min_confidence);
}

TEST(RecogPipeline, CompetingLabelsAreResolvedByExplanationNotSearchOrder) {
  // The thesis' order (sec. 6.3.2.6) searches the larger model first: a 2.4 m box placed over a
  // 1.6 m one passed the old support test and took its area. The better explanation must win.
  const ModelTemplate right = box_template("right", 1.6, 0.8, 0.5);
  const ModelTemplate larger = box_template("larger", 2.4, 0.8, 0.5);
  const Eigen::Isometry3d T = pose(3.0, 2.8, -0.02, 20);
  const PointCloud cloud = synthetic_scene({{&right, T}}, 0, 0, 7, 5.5, 0.02, 0.004, 7);
  for (const auto& catalogue :
       {std::vector<ModelTemplate>{larger, right}, std::vector<ModelTemplate>{right, larger}}) {
    const RecognitionResult r = recognize_2d(cloud, catalogue, test_config());
    ASSERT_EQ(r.placements.size(), 1u) << placements_json(r, "", "", test_config());
    const Placement& p = r.placements[0];
    EXPECT_EQ(p.model, "right");
    EXPECT_LT((p.T_world_model.translation() - T.translation()).head<2>().norm(), 0.05);
    EXPECT_GE(p.confidence, test_config().verification.min_confidence);
    EXPECT_LE(p.confidence, 1.0);
  }
}

// Relief proposals: a tank 40 % buried among rocks, with the descriptor scan unable to propose
// anything (its bound set to nothing): the blob of relief that fits the tank is proposed once
// the scan gives up, registered and verified; the rocks (too small for the tank) are not
// proposed to it. Without relief proposals nothing is found.
TEST(RecogPipeline, ABuriedStructureTheScanDoesNotProposeIsFoundFromItsRelief) {
  const ModelTemplate tank = reference_template("tank", Symmetry::Full);
  const double buried = 0.4 * tank.height();
  const Eigen::Isometry3d T = pose(4.0, 2.6, -buried - tank.base_z, 0);
  const PointCloud cloud = synthetic_scene({{&tank, T}}, 0, 0, 8, 5.5, 0.02, 0.004, 11);
  RecognitionConfig cfg = test_config();
  cfg.max_relative_score = 1e-9;  // no patch ever scores below this
  cfg.max_relief_proposals = 0;
  EXPECT_TRUE(recognize_2d(cloud, {tank}, cfg).placements.empty());
  cfg.max_relief_proposals = 4;
  const RecognitionResult r = recognize_2d(cloud, {tank}, cfg);
  ASSERT_EQ(r.placements.size(), 1u) << placements_json(r, "", "", cfg);
  const Placement& p = r.placements[0];
  EXPECT_LT((p.T_world_model.translation() - T.translation()).head<2>().norm(), 0.05);
  EXPECT_GE(p.confidence, cfg.verification.min_confidence);
  std::size_t relief = 0;
  for (const SearchRecord& s : r.searches) {
    if (s.proposal != "relief") continue;
    ++relief;
    // Every relief proposal lay on the tank, none on a rock.
    EXPECT_LT((s.scan.center_xy - T.translation().head<2>()).norm(), 0.5 * tank.radius_m);
  }
  EXPECT_GE(relief, 1u);
  // The JSON names where the candidate came from.
  EXPECT_NE(placements_json(r, "", "", cfg).find("\"proposal\": \"relief\""), std::string::npos);
}

// Issue 28 (recog2d28): a low model's relief threshold (RecognitionConfig::low_relief_fraction).
TEST(RecogRelief, ALowModelsThresholdFollowsItsHeightAboveTheMapsNoise) {
  RecognitionConfig cfg;  // relief_m 0.10, low_relief_fraction 0.5, min_relief_m 0.04
  const ModelTemplate tall = box_template("tall", 0.6, 0.4, 0.5);
  const ModelTemplate low = box_template("low", 0.6, 0.4, 0.07);
  const ModelTemplate flat = box_template("flat", 0.6, 0.4, 0.03);
  EXPECT_DOUBLE_EQ(model_relief_m(tall, cfg, 0.0), 0.10);   // 0.5 × 0.5 m: relief_m
  EXPECT_NEAR(model_relief_m(low, cfg, 0.0), 0.04, 1e-6);   // 0.035 < min_relief_m
  EXPECT_NEAR(model_relief_m(low, cfg, 0.02), 0.06, 1e-6);  // 3 × the map's noise
  EXPECT_NEAR(model_relief_m(flat, cfg, 0.0), 0.04, 1e-6);
  EXPECT_DOUBLE_EQ(model_relief_m(low, cfg, 0.1), 0.10);  // never above relief_m
  const ModelTemplate mid = box_template("mid", 0.6, 0.4, 0.16);
  EXPECT_NEAR(model_relief_m(mid, cfg, 0.0), 0.08, 1e-6);
  cfg.low_relief_fraction = 0;  // off: every model uses relief_m
  EXPECT_DOUBLE_EQ(model_relief_m(low, cfg, 0.0), 0.10);

  // The map's noise: a flat map with Gaussian noise σ gives σ back (robust σ of one cell).
  ElevationMap map;
  map.cell_m = 0.02;
  map.rows = map.cols = 200;
  map.z.assign(200 * 200, 0.f);
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0, 0.01f);
  for (float& z : map.z) z = n(rng);
  EXPECT_NEAR(map_height_noise(map), 0.01, 0.001);
  map.z.assign(200 * 200, ElevationMap::kNoData);
  EXPECT_EQ(map_height_noise(map), 0.0);
}

// A 7 cm-high box lying on the seabed (the benchmark's 11 cm hot stab lying has no cell 10 cm
// above it): with relief_m for every model it has no relief, is never proposed and its
// verification sees nothing (seen 0); with its own threshold (half its height) it is found from
// its relief at its pose.
TEST(RecogPipeline, ALowModelIsFoundWithItsOwnReliefThreshold) {
  const ModelTemplate low = box_template("low_box", 0.5, 0.25, 0.07);
  const Eigen::Isometry3d T = pose(4.0, 2.6, -0.01, 30);
  const PointCloud cloud = synthetic_scene({{&low, T}}, 0, 0, 8, 5.5, 0.02, 0.004, 13);
  RecognitionConfig cfg = test_config();
  cfg.low_relief_fraction = 0;
  const RecognitionResult before = recognize_2d(cloud, {low}, cfg);
  EXPECT_TRUE(before.placements.empty()) << placements_json(before, "", "", cfg);
  cfg.low_relief_fraction = 0.5;
  const RecognitionResult r = recognize_2d(cloud, {low}, cfg);
  ASSERT_EQ(r.placements.size(), 1u) << placements_json(r, "", "", cfg);
  const Placement& p = r.placements[0];
  EXPECT_LT((p.T_world_model.translation() - T.translation()).head<2>().norm(), 0.05);
  EXPECT_LT(yaw_error_deg(yaw_of(p.T_world_model), yaw_of(T), M_PI), 3.0);
  EXPECT_GT(p.verification.seen, 0.5);
  EXPECT_GE(p.confidence, cfg.verification.min_confidence);
}

// Issue 28, manifold_slope field (recog28f): eq. 6.9 searches an upright model; on a 6° slope a
// 2.6 m manifold's ends lie 27 cm apart in height, and its three towers 0.8 m apart let an upright
// search slide it by one tower. RecognitionConfig::level_by_seabed levels the scene by the seabed
// plane under the placement, searches again and tilts the model onto the plane: placed within
// 5 cm and 1° of its tilt, step 1 already tilted. (On this clean scene ICP also recovers the
// tilt from an upright start; on the benchmark's field, with marine growth and the manifold
// tilted across the slope, it did not: docs/recognition.md, "After, recog28f".)
namespace {
ModelTemplate manifold_template() {
  TriangleMesh mesh;
  auto part = [&](TriangleMesh b, double cx, double cy, double cz) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(cx, cy, cz);
    b.transform(T);
    mesh.append(b);
  };
  part(make_box(2.6, 1.8, 0.2), 0, 0, 0.1);
  for (const double x : {-0.8, 0.0, 0.8}) part(make_cylinder(0.13, 0.7, 24), x, 0.5, 0.55);
  for (const double x : {-0.9, 0.9}) part(make_box(0.2, 0.3, 0.24), x, -0.4, 0.32);
  part(make_box(0.3, 0.4, 0.4), 1.05, 0.5, 0.4);
  ModelSamplingConfig sc;
  sc.spacing_m = 0.015;
  return make_model_template("manifold", mesh, Symmetry::None, -1, sc);
}
double tilt_between_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return std::acos(std::clamp(a.linear().col(2).dot(b.linear().col(2)), -1.0, 1.0)) / kDeg;
}
}  // namespace

TEST(RecogPipeline, AStructureOnASlopeIsFoundWithTheSeabedsTilt) {
  const ModelTemplate manifold = manifold_template();
  const double slope = std::tan(6 * kDeg);
  const double x = 4.0, y = 3.2;
  // On the slope: the model's vertical turned to the seabed's normal, its base on the seabed.
  Eigen::Isometry3d truth = pose(x, y, 0, 110);
  truth.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(),
                                                      Eigen::Vector3d(-slope, 0, 1).normalized())
                       .toRotationMatrix() *
                   truth.linear();
  truth.translation().z() = seabed(x, y) + slope * x - 0.03;
  const PointCloud cloud =
      synthetic_scene({{&manifold, truth}}, 0, 0, 8, 6.5, 0.02, 0.004, 5, slope);
  RecognitionConfig cfg = test_config();
  const RecognitionResult r = recognize_2d(cloud, {manifold}, cfg);
  ASSERT_EQ(r.placements.size(), 1u) << placements_json(r, "", "", cfg);
  const Placement& p = r.placements[0];
  const Eigen::Vector3d c(manifold.center_xy.x(), manifold.center_xy.y(), 0.3);
  EXPECT_LT((p.T_world_model * c - truth * c).norm(), 0.05);
  EXPECT_LT(tilt_between_deg(p.T_world_model, truth), 1.0);
  // Step 1 (the 4D search) already carries the seabed's tilt, so ICP starts right (upright, as
  // with level_by_seabed off, it is 6° off).
  EXPECT_LT(tilt_between_deg(p.T_world_model_4d, truth), 1.5);
  EXPECT_LT(yaw_error_deg(yaw_of(p.T_world_model), yaw_of(truth)), 1.0);
  EXPECT_GE(p.confidence, cfg.verification.min_confidence);
  if (std::getenv("RECOG_PRINT")) {
    cfg.level_by_seabed = false;
    std::printf("%s", placements_json(recognize_2d(cloud, {manifold}, cfg), "", "", cfg).c_str());
  }
}

// Issue 28, ordnance field (recog28f): a 35 %-buried shell touching a half-buried pipeline: their
// relief is one blob, too large for the shell, so no whole blob is proposed to it
// (RecognitionConfig::split_relief_blobs off: nothing found with the scan disabled). Split by
// the shell's footprint, the matched filter's best peak lies on the shell, not along the pipe.
TEST(RecogPipeline, ABlobMergedWithAPipelineIsSplitByTheModelsFootprint) {
  auto lying_cylinder = [](const std::string& name, double radius, double length) {
    TriangleMesh mesh = make_cylinder(radius, length, 32);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T.translation() =
        Eigen::Vector3d(-0.5 * length, 0, radius);  // lying on z = 0, centred, along x
    mesh.transform(T);
    ModelSamplingConfig sc;
    sc.spacing_m = 0.015;
    return make_model_template(name, mesh, Symmetry::Half, -1, sc);
  };
  const ModelTemplate shell = lying_cylinder("shell", 0.16, 2.6);
  const ModelTemplate pipe = lying_cylinder("pipe", 0.15, 12.0);  // not in the catalogue
  const Eigen::Isometry3d T_shell = pose(6.0, 3.3, -0.35 * 0.32, -60);
  // The pipe runs along x across the scene, 60 % buried, across the shell's upper half.
  const Eigen::Isometry3d T_pipe = pose(6.0, 4.0, -0.6 * 0.3, 0);
  const PointCloud cloud =
      synthetic_scene({{&shell, T_shell}, {&pipe, T_pipe}}, 0, 0, 12, 6, 0.02, 0.004, 13);
  RecognitionConfig cfg = test_config();
  cfg.max_relative_score = 1e-9;  // the scan proposes nothing
  auto found_at_truth = [&](const RecognitionResult& r) {
    for (const Placement& p : r.placements) {
      if ((p.T_world_model.translation() - T_shell.translation()).head<2>().norm() < 0.1 &&
          yaw_error_deg(yaw_of(p.T_world_model), yaw_of(T_shell), M_PI) < 2.0) {
        return true;
      }
    }
    return false;
  };
  cfg.split_relief_blobs = false;
  const RecognitionResult off = recognize_2d(cloud, {shell}, cfg);
  EXPECT_FALSE(found_at_truth(off)) << placements_json(off, "", "", cfg);
  cfg.split_relief_blobs = true;
  const RecognitionResult on = recognize_2d(cloud, {shell}, cfg);
  EXPECT_TRUE(found_at_truth(on)) << placements_json(on, "", "", cfg);
}

// Issue 28 item 4 (thesis sec. 6.7: sizes off by ±10 %): structures built 8 % larger and smaller
// than their CAD models are found, with their scale within 2 %, when the catalogue gives
// scale_range [0.9, 1.1]; the placed mesh is drawn at that scale.
TEST(RecogScale, ScaledModelsRecoverTheirScaleWithinTwoPercent) {
  ModelTemplate pillar = reference_template("pillar");
  ModelTemplate riser = reference_template("riser");
  const Eigen::Isometry3d T_pillar = pose(3.0, 3.4, -0.04, 65);
  const Eigen::Isometry3d T_riser = pose(8.3, 3.0, -0.08, 20);
  const double s_pillar = 1.08, s_riser = 0.92;
  const ModelTemplate pillar_built = scaled_template(pillar, s_pillar);
  const ModelTemplate riser_built = scaled_template(riser, s_riser);
  const PointCloud cloud = synthetic_scene({{&pillar_built, T_pillar}, {&riser_built, T_riser}}, 0,
                                           0, 11.5, 6.5, 0.02, 0.005, 11);
  for (ModelTemplate* m : {&pillar, &riser}) {
    m->scale_min = 0.9;
    m->scale_max = 1.1;
  }
  const RecognitionResult r = recognize_2d(cloud, {pillar, riser}, test_config());
  ASSERT_EQ(r.placements.size(), 2u) << placements_json(r, "", "", test_config());
  for (const Placement& p : r.placements) {
    SCOPED_TRACE(p.model);
    const bool is_pillar = p.model == "pillar";
    const double truth = is_pillar ? s_pillar : s_riser;
    EXPECT_LT(std::abs(p.scale / truth - 1), 0.02) << p.scale;
    // The structure's points: T_true · (s · p) against the placement T · (scale · p).
    const ModelTemplate& m = is_pillar ? pillar : riser;
    const Eigen::Isometry3d& T = is_pillar ? T_pillar : T_riser;
    const Eigen::Vector3d c(m.center_xy.x(), m.center_xy.y(), 0.5 * (m.base_z + m.top_z));
    EXPECT_LT((p.T_world_model * (p.scale * c) - T * (truth * c)).norm(), 0.04);
    EXPECT_GE(p.confidence, test_config().verification.min_confidence);
    EXPECT_LT(p.residual.median_m, 0.02);
  }
  const nlohmann::json j = nlohmann::json::parse(placements_json(r, "", "", test_config()));
  EXPECT_NEAR(j["placements"][0]["scale"].get<double>(), r.placements[0].scale, 1e-12);
  // The placed mesh is drawn at the placement's scale.
  const TriangleMesh placed = placed_models_mesh({pillar, riser}, {r.placements[0]});
  const ModelTemplate& m0 = r.placements[0].model == "pillar" ? pillar : riser;
  EXPECT_NEAR(placed.bounding_box().sizes().z(), r.placements[0].scale * m0.height(), 0.02);
  // Without a scale range the sizes are not searched: the placements stay at scale 1.
  pillar.scale_min = pillar.scale_max = 1;
  const RecognitionResult fixed = recognize_2d(cloud, {pillar}, test_config());
  for (const Placement& p : fixed.placements) EXPECT_EQ(p.scale, 1.0);
}

TEST(RecogScale, ScaleHelpersKeepTheBaseAndTheConvention) {
  const ModelTemplate riser = reference_template("riser");
  const ModelTemplate big = scaled_template(riser, 1.1);
  EXPECT_NEAR(big.height(), 1.1 * riser.height(), 1e-5);
  EXPECT_NEAR(big.radius_m, 1.1 * riser.radius_m, 1e-9);
  // pose_at_scale keeps the base centre where it stood.
  const Eigen::Isometry3d T = pose(2, 1, -0.1, 30);
  const Eigen::Isometry3d T11 = pose_at_scale(riser, T, 1.0, 1.1);
  const Eigen::Vector3d b(riser.center_xy.x(), riser.center_xy.y(), riser.base_z);
  EXPECT_LT((T11 * (1.1 * b) - T * b).norm(), 1e-9);
  EXPECT_TRUE(T11.linear().isApprox(T.linear()));
  // No scale range: an error, not a silent scale 1.
  test::expect_error(
      [&] { search_scale(riser, T, ElevationMap{}, {}, {}, nullptr, ScaleSearchConfig{}); },
      "no scale range");
  ScaleSearchConfig bad;
  bad.tolerance = 0;
  test::expect_error([&] { bad.validate(); }, "tolerance");
}

TEST(RecogVerify, BadSettingsGiveClearErrors) {
  auto message = [](VerificationConfig c) {
    try {
      c.validate();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  VerificationConfig c;
  c.tol_m = 0;
  EXPECT_NE(message(c).find("tol_m"), std::string::npos);
  c = {};
  c.min_confidence = 1.5;
  EXPECT_NE(message(c).find("min_confidence"), std::string::npos);
  c = {};
  c.w_violation = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message(c).find("w_violation"), std::string::npos);
  EXPECT_EQ(message(VerificationConfig{}), "");
}

TEST(RecogCatalogue, ParsesAndGivesClearErrors) {
  const fs::path dir = test::temp_dir("catalogue");
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  const Catalogue c = read_catalogue(write("ok.yaml", R"(models:
  - {name: pillar, reference: pillar, symmetry: "180", expected: 1}
  - {name: box, mesh: box.stl, symmetry: full, scale: 1.1}
)"));
  ASSERT_EQ(c.models.size(), 2u);
  EXPECT_EQ(c.models[0].symmetry, Symmetry::Half);
  EXPECT_EQ(c.models[0].expected, 1);
  EXPECT_EQ(c.models[1].mesh_path, (dir / "box.stl").string());
  EXPECT_DOUBLE_EQ(c.models[1].scale, 1.1);
  EXPECT_EQ(c.models[1].line, 3);
  // The mesh that fails to load: the error names the catalogue, line, model and file.
  test::expect_error([&] { load_catalogue_mesh(c, c.models[1]); }, "ok.yaml:3: model 'box'");
  test::expect_error([&] { load_catalogue_mesh(c, c.models[1]); }, "box.stl");
  test::expect_error([&] { read_catalogue(write("empty.yaml", "")); }, "the catalogue is empty");
  test::expect_error([&] { read_catalogue(write("e2.yaml", "models: []\n")); },
                     "the catalogue is empty");
  test::expect_error(
      [&] {
        read_catalogue(
            write("sym.yaml", "models:\n  - {name: a, reference: tank, symmetry: 90}\n"));
      },
      "sym.yaml:2");
  test::expect_error(
      [&] {
        read_catalogue(
            write("both.yaml", "models:\n  - {name: a, reference: tank, mesh: a.stl}\n"));
      },
      "exactly one of");
  test::expect_error(
      [&] {
        read_catalogue(
            write("dup.yaml",
                  "models:\n  - {name: a, reference: tank}\n  - {name: a, reference: riser}\n"));
      },
      "duplicate model name");
  test::expect_error(
      [&] {
        read_catalogue(write("key.yaml", "models:\n  - {name: a, reference: tank, colour: red}\n"));
      },
      "unknown key");
  test::expect_error(
      [&] {
        read_catalogue(
            write("neg.yaml", "models:\n  - {name: a, reference: tank, expected: -2}\n"));
      },
      "expected");
  test::expect_error(
      [&] { read_catalogue(write("ref.yaml", "models:\n  - {name: a, reference: cube}\n")); },
      "unknown 'cube'");
  test::expect_error([&] { read_catalogue((dir / "missing.yaml").string()); }, "missing.yaml");
  // scale_range (issue 28 item 4): parsed, and bad ranges refused with one line naming the file,
  // the line, the key and the model.
  const Catalogue sc = read_catalogue(
      write("scale.yaml", "models:\n  - {name: a, reference: tank, scale_range: [0.9, 1.1]}\n"));
  EXPECT_DOUBLE_EQ(sc.models[0].scale_min, 0.9);
  EXPECT_DOUBLE_EQ(sc.models[0].scale_max, 1.1);
  EXPECT_DOUBLE_EQ(c.models[0].scale_min, 1.0);  // absent: [1, 1], not searched
  EXPECT_DOUBLE_EQ(c.models[0].scale_max, 1.0);
  const struct {
    std::string range, needle;
  } bad_ranges[] = {{"[1.1, 0.9]", "scale range inverted"}, {"[0.1, 1.1]", "lies outside [0.5, 2]"},
                    {"[0.9, 5]", "lies outside [0.5, 2]"},  {"[.nan, 1.1]", "two finite numbers"},
                    {"[0.9]", "two finite numbers"},        {"wide", "two finite numbers"},
                    {"[1.05, 1.1]", "must contain 1"}};
  for (const auto& b : bad_ranges) {
    SCOPED_TRACE(b.range);
    const std::string f = write("badscale.yaml",
                                "models:\n  - {name: tank, reference: tank}\n"
                                "  - {name: frame, reference: riser, "
                                "scale_range: " +
                                    b.range + "}\n");
    try {
      read_catalogue(f);
      ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(b.needle), std::string::npos) << what;
      EXPECT_NE(what.find("badscale.yaml:3"), std::string::npos) << what;
      EXPECT_NE(what.find("scale_range"), std::string::npos) << what;
      EXPECT_NE(what.find("model 'frame'"), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

TEST(RecogPipeline, BadInputsGiveClearErrors) {
  const ModelTemplate pillar = reference_template("pillar");
  const PointCloud small = synthetic_scene({}, 0, 0, 1.5, 1.5, 0.02, 0.0);
  test::expect_error([&] { recognize_2d(small, {pillar}, test_config()); }, "larger than the map");
  test::expect_error([&] { recognize_2d(small, {}, test_config()); }, "catalogue is empty");
  test::expect_error([&] { recognize_2d(PointCloud{}, {pillar}, test_config()); },
                     "cloud is empty");
  RecognitionConfig bad = test_config();
  bad.scan.period_m = 0;
  test::expect_error([&] { recognize_2d(small, {pillar}, bad); }, "period_m");
  bad = test_config();
  bad.recog_cell_m = 0.01;
  test::expect_error([&] { recognize_2d(small, {pillar}, bad); }, "recog_cell_m");
}

namespace {

using sonar3d::test::CliRun;
using sonar3d::test::run_cli;

// A 10 × 8 m seabed with relief and rocks, a pillar (yaw 30°) and a tank, surveyed by a
// downward-looking MB2250-like sonar 4 m up on four East-West lines 2 m apart.
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
  - {name: pillar, reference: pillar, pose: {translation: [-1.5, 0.5, -0.05], rpy_deg: [0, 0, 30]}, reflectivity: 0.8}
  - {name: tank, reference: tank, pose: {translation: [2.2, -1.0, -0.05]}, reflectivity: 0.8}
trajectory: {type: lawnmower, x: [-4, 4], y: [-3, 3], z: 4.0, line_spacing: 2.0, spacing: 0.04, period: 0.1}
)";

}  // namespace

// End to end: simulate, carve (MAP = the dataset), recognise. Both structures at their true poses;
// the riser of the catalogue, absent from the scene, is not reported; the outputs are complete
// and replaced only with --overwrite.
TEST(RecogCli, SimulatedSceneStructuresFoundAtTheirTruePoses) {
  const fs::path dir = test::temp_dir("cli");
  { std::ofstream(dir / "scene.yaml") << kScene; }
  {
    std::ofstream(dir / "cat.yaml") << R"(models:
  - {name: pillar, reference: pillar, symmetry: "180", expected: 1}
  - {name: tank, reference: tank, symmetry: full}
  - {name: riser, reference: riser}
)";
  }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "scene.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string args = "recognize " + (dir / "ds").string() + " --catalogue " +
                           (dir / "cat.yaml").string() + " -o " + (dir / "p.json").string() + " -q";
  r = run_cli(dir, args);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream f(dir / "p.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["format"], "sonar3d-placements");
  // The 2.5 m pillar surveyed from 4 m: its upper part lies in the sonar's blind range, so only
  // ~20 % of its relief is observed and the calibrated confidence (fitted on structures mostly
  // seen) stays below the threshold. Known limitation (docs/recognition.md, "Verification"): the
  // pillar must then be the best-placed rejected candidate, at its true pose, with a low `seen`.
  std::vector<nlohmann::json> judged(j["placements"].begin(), j["placements"].end());
  bool pillar_placed = false;
  for (const auto& p : j["placements"]) pillar_placed = pillar_placed || p["model"] == "pillar";
  if (!pillar_placed) {
    bool pillar_seen_low = false;
    for (const auto& s : j["searches"]) {
      if (s["model"] != "pillar" || !s.contains("translation")) continue;
      const Eigen::Vector2d at(s["translation"][0], s["translation"][1]);
      if ((at - Eigen::Vector2d(-1.5, 0.5)).norm() < 0.04) {
        EXPECT_LT(s["verification"]["seen"].get<double>(), 0.5);
        EXPECT_GT(s["verification"]["explained"].get<double>(), 0.8);
        pillar_seen_low = true;
      }
    }
    EXPECT_TRUE(pillar_seen_low) << j.dump(1);
  }
  ASSERT_EQ(j["placements"].size(), pillar_placed ? 2u : 1u) << j.dump(1);
  for (const auto& p : judged) {
    const std::string model = p["model"];
    ASSERT_TRUE(model == "pillar" || model == "tank") << model;
    const Eigen::Vector2d truth =
        model == "pillar" ? Eigen::Vector2d(-1.5, 0.5) : Eigen::Vector2d(2.2, -1.0);
    const Eigen::Vector2d found(p["translation"][0], p["translation"][1]);
    EXPECT_LT((found - truth).norm(), 0.04) << model;
    EXPECT_NEAR(p["translation"][2].get<double>(), -0.05, 0.04) << model;
    if (model == "pillar") {  // square: yaw modulo 90°
      EXPECT_LT(yaw_error_deg(p["rpy_deg"][2].get<double>() * kDeg, 30 * kDeg, M_PI / 2), 3.0);
    }
    EXPECT_LT(p["residual_median_m"].get<double>(), 0.03) << model;
  }
  EXPECT_TRUE(fs::exists(dir / "p.ply"));
  const TriangleMesh placed = load_mesh((dir / "p.ply").string());
  EXPECT_EQ(placed.triangles.size(),
            (pillar_placed ? make_reference_object("pillar").triangles.size() : 0) +
                make_reference_object("tank").triangles.size());
  // An existing output is not replaced without --overwrite, and never when sonar3d did not
  // write it.
  r = run_cli(dir, args);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--overwrite"), std::string::npos) << r.out;
  { std::ofstream(dir / "mine.json") << "{\"mine\": 1}\n"; }
  r = run_cli(dir, "recognize " + (dir / "ds").string() + " --catalogue " +
                       (dir / "cat.yaml").string() + " -o " + (dir / "mine.json").string() +
                       " --overwrite -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("not a sonar3d placements file"), std::string::npos) << r.out;
  std::ifstream mine(dir / "mine.json");
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(mine)), std::istreambuf_iterator<char>()),
            "{\"mine\": 1}\n");
}

TEST(RecogCli, BadInputsGiveOneClearLine) {
  const fs::path dir = test::temp_dir("cli_bad");
  // A small cloud: a 1.5 m square of seabed.
  PointCloud cloud;
  for (int i = 0; i < 75; ++i) {
    for (int k = 0; k < 75; ++k) cloud.points.emplace_back(0.02 * i, 0.02 * k, 0.0f);
  }
  write_ply((dir / "small.ply").string(), cloud);
  { std::ofstream(dir / "empty.yaml") << "models: []\n"; }
  { std::ofstream(dir / "big.yaml") << "models:\n  - {name: pillar, reference: pillar}\n"; }
  { std::ofstream(dir / "broken.stl") << "solid nothing\nthis is not an stl\n"; }
  { std::ofstream(dir / "mesh.yaml") << "models:\n  - {name: part, mesh: broken.stl}\n"; }
  const std::string small = (dir / "small.ply").string();
  const struct {
    std::string catalogue, needle;
  } cases[] = {{"empty.yaml", "the catalogue is empty"},
               {"big.yaml", "larger than the map"},
               {"mesh.yaml", "broken.stl"}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.catalogue);
    const CliRun r =
        run_cli(dir, "recognize " + small + " --catalogue " + (dir / c.catalogue).string() +
                         " -o " + (dir / "p.json").string() + " -q");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.out.find(c.needle), std::string::npos) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_FALSE(fs::exists(dir / "p.json"));
    EXPECT_FALSE(fs::exists(dir / "p.ply"));
  }
}
