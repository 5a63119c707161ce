// world/change: change detection between two surveys (docs/change.md): registration of B onto A,
// placements compared (symmetry-aware), height change regions; synthetic pairs with known
// changes and offsets, a simulated pair end to end through the CLI, bad inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/change.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;

namespace {

constexpr double kDeg = M_PI / 180;

// A box standing on the seabed: centre (x, y), size (sx, sy), yaw, height above the seabed.
struct Box {
  double x, y, sx, sy, yaw_deg, h;
  bool covers(double px, double py, double margin = 0) const {
    const double c = std::cos(yaw_deg * kDeg), s = std::sin(yaw_deg * kDeg);
    const double u = c * (px - x) + s * (py - y), v = -s * (px - x) + c * (py - y);
    return std::abs(u) <= sx / 2 + margin && std::abs(v) <= sy / 2 + margin;
  }
};

// A seabed with relief and rocks (height z at world x, y), m.
double seabed(double x, double y) {
  double z = 0.2 * std::sin(0.6 * x) * std::cos(0.45 * y) + 0.08 * std::sin(1.7 * x + 1.1 * y);
  const double rocks[][3] = {{-2.5, 1.5, 0.15},  {1.0, -1.8, 0.2}, {2.8, 2.0, 0.12},
                             {-1.0, -0.5, 0.18}, {3.5, -0.8, 0.1}, {-3.2, -2.2, 0.14}};
  for (const auto& r : rocks) {
    const double q = (x - r[0]) * (x - r[0]) + (y - r[1]) * (y - r[1]);
    z += r[2] * std::exp(-q / (2 * 0.15 * 0.15));
  }
  return z;
}

// A survey of the site [−4, 4] × [−3, 3] m with `boxes` as seen from above (points every 2 cm,
// the highest surface), height noise `noise_m` (seeded), in a world frame where the site lies at
// T_world_site.
PointCloud survey(const std::vector<Box>& boxes, double noise_m, unsigned seed,
                  const Eigen::Isometry3d& T_world_site = Eigen::Isometry3d::Identity()) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise_m);
  PointCloud c;
  for (double x = -4; x <= 4; x += 0.02) {
    for (double y = -3; y <= 3; y += 0.02) {
      double z = seabed(x, y);
      for (const Box& b : boxes) {
        if (b.covers(x, y)) z = std::max(z, seabed(b.x, b.y) + b.h);
      }
      c.points.push_back((T_world_site * Eigen::Vector3d(x, y, z + n(rng))).cast<float>());
    }
  }
  return c;
}

Eigen::Isometry3d pose(double x, double y, double z, double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

SurveyPlacement placed(const std::string& model, const Box& b) {
  return {model, pose(b.x, b.y, seabed(b.x, b.y), b.yaw_deg)};
}

// B's world: the site moved by a navigation offset (yaw 1.2°, 23 cm East, −17 cm North, 6 cm up).
const Eigen::Isometry3d kTbA = pose(0.23, -0.17, 0.06, 1.2);

ChangeConfig test_config() {
  ChangeConfig c;
  c.registration.num_threads = 2;
  return c;
}

const Box kStay{-2.0, 1.0, 1.0, 0.6, 20, 0.4};   // untouched
const Box kMoveA{1.5, 1.2, 1.2, 0.5, 30, 0.35};  // moved 30 cm East and turned 10°
const Box kMoveB{1.8, 1.2, 1.2, 0.5, 40, 0.35};
const Box kRemoved{-1.8, -1.6, 0.6, 0.6, 0, 0.3};  // in A only
const Box kAdded{2.2, -1.5, 0.5, 0.5, 0, 0.5};     // in B only

// Colours (linear RGB) as a camera would map them onto a survey's cloud: the seabed sand with a
// pattern of ±10 %, each box its own colour (the top of the highest box under a point), 3 % noise
// per channel, all scaled by `light` (a lamp or altitude of that survey), 8-bit sRGB like
// sonar3d texture writes. `boxes` and `colours` pair up; T_world_site as in survey().
void colourise(PointCloud* cloud, const std::vector<Box>& boxes,
               const std::vector<Eigen::Vector3d>& colours, double light, unsigned seed,
               const Eigen::Isometry3d& T_world_site = Eigen::Isometry3d::Identity()) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 0.03);
  cloud->color.clear();
  for (const Eigen::Vector3f& p : cloud->points) {
    const Eigen::Vector3d s = T_world_site.inverse() * p.cast<double>();
    Eigen::Vector3d c =
        Eigen::Vector3d(0.7, 0.6, 0.3) * (1 + 0.1 * std::sin(2.3 * s.x()) * std::cos(1.9 * s.y()));
    double top = seabed(s.x(), s.y()) + 0.02;
    for (std::size_t k = 0; k < boxes.size(); ++k) {
      const double h = seabed(boxes[k].x, boxes[k].y) + boxes[k].h;
      if (boxes[k].covers(s.x(), s.y()) && h > top) top = h, c = colours[k];
    }
    std::array<std::uint8_t, 3> rgb{};
    for (int k = 0; k < 3; ++k) {
      const double v = std::clamp(light * c[k] * (1 + n(rng)), 0.0, 1.0);
      rgb[static_cast<std::size_t>(k)] =
          static_cast<std::uint8_t>(std::max(1L, std::lround(255 * linear_to_srgb(float(v)))));
    }
    cloud->color.push_back(rgb);
  }
}

const Eigen::Vector3d kYellow(0.8, 0.7, 0.1), kRed(0.7, 0.08, 0.06), kGrey(0.4, 0.4, 0.4),
    kBrown(0.35, 0.2, 0.08);

}  // namespace

// Registration recovers a known offset of B's frame (yaw, shift, height) within a centimetre and
// a tenth of a degree, with different noise in each survey.
TEST(ChangeRegistration, RecoversAKnownOffset) {
  const PointCloud a = survey({kStay}, 0.005, 1);
  const PointCloud b = survey({kStay}, 0.008, 2, kTbA);
  const ChangeRegistration r = register_surveys(a, b, test_config().registration);
  const Eigen::Isometry3d err = r.T_a_b * kTbA;  // identity when exact
  // Within 2.5 cm horizontally (the site's edges are 5 m from its centre: 0.1° is 0.9 cm there)
  // and 1 cm vertically: each map keeps the highest of ~6 noisy points per 5 cm cell, which
  // raises A by ~6 mm and B by ~10 mm.
  EXPECT_LT(err.translation().head<2>().norm(), 0.025) << err.matrix();
  EXPECT_NEAR(err.translation().z(), 0, 0.01);
  EXPECT_NEAR(r.yaw_deg, -1.2, 0.1);
  EXPECT_GT(r.overlap_cells, 4000u);  // of the 8 × 6 m site at 10 cm
}

// The same site surveyed twice with different noise, a navigation offset and placements that
// differ by recognition noise (1 cm, 0.5°): no change at all.
TEST(ChangeDetection, IdenticalSurveysWithDifferentNoiseGiveNoChange) {
  const std::vector<Box> site{kStay, kMoveA, kRemoved};
  const PointCloud a = survey(site, 0.005, 3);
  const PointCloud b = survey(site, 0.01, 4, kTbA);
  std::vector<SurveyPlacement> pa{placed("frame", kStay), placed("frame", kMoveA),
                                  placed("crate", kRemoved)};
  std::vector<SurveyPlacement> pb;
  for (const SurveyPlacement& p : pa) {
    pb.push_back({p.model, kTbA * pose(0.01, -0.005, 0, 0.5) * p.T_world_model});
  }
  const ObjectModels sym{{"frame", {Symmetry::Half}}, {"crate", {Symmetry::None}}};
  const ChangeResult r = diff_surveys(a, b, pa, pb, sym, test_config());
  EXPECT_TRUE(r.regions.empty()) << r.regions.size() << " regions, the first at "
                                 << r.regions[0].centroid.transpose();
  ASSERT_EQ(r.objects.size(), 3u);
  for (const ObjectChange& o : r.objects) {
    EXPECT_EQ(o.status, ObjectStatus::Unchanged) << o.id;
    EXPECT_LT(o.shift_m, 0.05) << o.id;  // 1.1 cm of recognition noise + registration
    EXPECT_LT(o.turn_deg, 1.0) << o.id;
  }
  EXPECT_LT(r.registration.rms_m, 0.03);
  EXPECT_GT(r.thresholds.sigma_m, 0.005);  // derived from the noise of both
}

// One structure moved 30 cm and turned 10°, one added, one removed, the rest untouched: exactly
// those objects change, and every region of height change lies on one of them.
TEST(ChangeDetection, SyntheticPairGivesExactlyItsChanges) {
  const PointCloud a = survey({kStay, kMoveA, kRemoved}, 0.005, 5);
  const PointCloud b = survey({kStay, kMoveB, kAdded}, 0.008, 6, kTbA);
  const std::vector<SurveyPlacement> pa{placed("frame", kStay), placed("frame", kMoveA),
                                        placed("crate", kRemoved)};
  const std::vector<SurveyPlacement> pb{{"frame", kTbA * placed("frame", kStay).T_world_model},
                                        {"frame", kTbA * placed("frame", kMoveB).T_world_model},
                                        {"crate", kTbA * placed("crate", kAdded).T_world_model}};
  const ObjectModels sym{{"frame", {Symmetry::Half}}, {"crate", {Symmetry::None}}};
  const ChangeResult r = diff_surveys(a, b, pa, pb, sym, test_config());
  ASSERT_EQ(r.objects.size(), 4u);
  EXPECT_EQ(r.objects[0].id, "frame_0");
  EXPECT_EQ(r.objects[0].status, ObjectStatus::Unchanged);
  EXPECT_EQ(r.objects[1].id, "frame_1");
  EXPECT_EQ(r.objects[1].status, ObjectStatus::Moved);
  EXPECT_NEAR(r.objects[1].shift_m, 0.3, 0.02);
  EXPECT_NEAR(r.objects[1].turn_deg, 10, 0.3);
  EXPECT_EQ(r.objects[2].id, "crate_0");
  EXPECT_EQ(r.objects[2].status, ObjectStatus::Removed);
  EXPECT_EQ(r.objects[3].id, "crate_1");
  EXPECT_EQ(r.objects[3].status, ObjectStatus::Added);

  // Regions: raised where the moved box and the added one now stand, lowered where the removed
  // one and the moved one stood; none elsewhere.
  bool raised_added = false, lowered_removed = false, raised_moved = false, lowered_moved = false;
  for (const ChangeRegion& g : r.regions) {
    const double x = g.centroid.x(), y = g.centroid.y();
    const bool on_changed = kAdded.covers(x, y, 0.1) || kRemoved.covers(x, y, 0.1) ||
                            kMoveA.covers(x, y, 0.1) || kMoveB.covers(x, y, 0.1);
    EXPECT_TRUE(on_changed) << "a region of change at " << g.centroid.transpose();
    raised_added |= g.raised && kAdded.covers(x, y);
    lowered_removed |= !g.raised && kRemoved.covers(x, y);
    raised_moved |= g.raised && kMoveB.covers(x, y, 0.1);
    lowered_moved |= !g.raised && kMoveA.covers(x, y, 0.1);
    if (g.raised && kAdded.covers(x, y)) {
      EXPECT_NEAR(g.area_m2, 0.25, 0.08);  // the 50 × 50 cm box, less a cell at its edge
      EXPECT_NEAR(g.max_abs_change_m, 0.5, 0.06);
    }
  }
  EXPECT_TRUE(raised_added && lowered_removed && raised_moved && lowered_moved);

  // The outputs: a change directory, written once.
  const fs::path dir = test::temp_dir("out");
  write_change_directory((dir / "D").string(), r);
  const nlohmann::json j = nlohmann::json::parse(read_text_file((dir / "D/changes.json").string()));
  EXPECT_EQ(j["format"], "sonar3d-changes");
  EXPECT_EQ(j["T_a_b"].size(), 16u);
  EXPECT_EQ(j["objects"][3]["status"], "added");
  EXPECT_TRUE(j["objects"][3]["T_world_model_a"].is_null());
  EXPECT_TRUE(j["objects"][3]["shift_m"].is_null());
  EXPECT_EQ(j["regions"].size(), r.regions.size());
  const ElevationMap m = read_elevation_geotiff((dir / "D/change_map.tif").string());
  EXPECT_EQ(m.num_valid(), r.registration.overlap_cells);
  const PointCloud pts = read_ply((dir / "D/change_points.ply").string());
  ASSERT_NE(pts.property("change_m"), nullptr);
  EXPECT_EQ(pts.size(), r.registration.overlap_cells);
  test::expect_error([&] { write_change_directory((dir / "D").string(), r); }, "already exists");
}

// Turns are compared modulo the model's symmetry; an object beyond the match radius is one
// removed and one added.
TEST(ChangeDetection, TurnsAreSymmetryAware) {
  const ObjectModels sym{
      {"tank", {Symmetry::Full}}, {"pillar", {Symmetry::Half}}, {"riser", {Symmetry::None}}};
  const std::vector<SurveyPlacement> a{{"tank", pose(0, 0, 0, 0)},
                                       {"pillar", pose(5, 0, 0, 10)},
                                       {"riser", pose(10, 0, 0, 350)},
                                       {"riser", pose(20, 0, 0, 0)}};
  const std::vector<SurveyPlacement> b{{"tank", pose(0.02, 0, 0, 90)},
                                       {"pillar", pose(5, 0.03, 0, 190)},
                                       {"riser", pose(10, 0, 0, 5)},
                                       {"riser", pose(22, 0, 0, 0)}};
  const auto c = compare_placements(a, b, sym, test_config());
  ASSERT_EQ(c.size(), 5u);
  EXPECT_EQ(c[0].status, ObjectStatus::Unchanged);  // a tank turned 90°: the same tank
  EXPECT_EQ(c[1].status, ObjectStatus::Unchanged);  // a pillar turned 180°
  EXPECT_NEAR(c[1].turn_deg, 0, 1e-9);
  EXPECT_EQ(c[2].status, ObjectStatus::Moved);  // 350° → 5°: turned by 15°
  EXPECT_NEAR(c[2].turn_deg, 15, 1e-9);
  EXPECT_EQ(c[3].status, ObjectStatus::Removed);  // 2 m away: another riser
  EXPECT_EQ(c[4].status, ObjectStatus::Added);
  EXPECT_EQ(c[4].id, "riser_2");
}

// A model of `sx` × `sy` m centred on its origin (its footprint, as catalogue_object_models gives).
static ObjectModel sized(Symmetry symmetry, double sx, double sy) {
  return {symmetry,
          Eigen::AlignedBox2d(Eigen::Vector2d(-sx / 2, -sy / 2), Eigen::Vector2d(sx / 2, sy / 2))};
}

// Issue 28: a structure that moved 1.07 m and turned 30° is one object moved, with that shift
// and turn — paired over a radius that scales with it (its footprint's half diagonal, 1.17 m),
// not the fixed 1 m that split it into one removed and one added. A crate really taken away
// (its heights are gone) stays removed.
TEST(ChangeDetection, ALargeStructureMovedAMetreAndTurnedIsMoved) {
  const Box big_a{-0.9, 0.2, 2.0, 1.2, 10, 0.4};
  const Box big_b{0.1, 0.58, 2.0, 1.2, 40, 0.4};  // 1.0 m East, 0.38 m North: 1.07 m; +30°
  const PointCloud a = survey({big_a, kRemoved}, 0.005, 11);
  const PointCloud b = survey({big_b}, 0.008, 12, kTbA);
  const ObjectModels models{{"frame", sized(Symmetry::None, 2.0, 1.2)},
                            {"crate", sized(Symmetry::None, 0.6, 0.6)}};
  const std::vector<SurveyPlacement> pa{placed("frame", big_a), placed("crate", kRemoved)};
  const std::vector<SurveyPlacement> pb{{"frame", kTbA * placed("frame", big_b).T_world_model}};
  const ChangeResult r = diff_surveys(a, b, pa, pb, models, test_config());
  ASSERT_EQ(r.objects.size(), 2u);
  const ObjectChange& f = r.objects[0];
  EXPECT_EQ(f.id, "frame_0");
  EXPECT_EQ(f.status, ObjectStatus::Moved);
  EXPECT_TRUE(f.in_a && f.in_b);
  EXPECT_NEAR(f.shift_m, std::hypot(1.0, 0.38), 0.03);  // registration within 2.5 cm
  EXPECT_NEAR(f.turn_deg, 30, 0.3);
  EXPECT_NEAR(f.match_radius_m, std::hypot(1.0, 0.6), 1e-9);
  EXPECT_GT(f.change_area_m2, 1.0);  // where it stood and where it stands now
  EXPECT_TRUE(f.reason.empty());
  EXPECT_EQ(r.objects[1].id, "crate_0");
  EXPECT_EQ(r.objects[1].status, ObjectStatus::Removed);
  EXPECT_NEAR(r.objects[1].change_area_m2, 0.36, 0.12);

  // The same placements with sizes unknown: the fixed 1 m radius splits the frame in two.
  std::vector<SurveyPlacement> pb_in_a = pb;
  for (SurveyPlacement& p : pb_in_a) p.T_world_model = r.registration.T_a_b * p.T_world_model;
  const auto fixed = compare_placements(pa, pb_in_a, {}, test_config());
  ASSERT_EQ(fixed.size(), 3u);
  EXPECT_EQ(fixed[0].status, ObjectStatus::Removed);
  EXPECT_EQ(fixed[2].status, ObjectStatus::Added);

  // changes.json: shift, turn and the evidence per object.
  const nlohmann::json j = nlohmann::json::parse(changes_json(r));
  EXPECT_EQ(j["objects"][0]["status"], "moved");
  EXPECT_NEAR(j["objects"][0]["shift_m"].get<double>(), f.shift_m, 1e-9);
  EXPECT_NEAR(j["objects"][0]["turn_deg"].get<double>(), f.turn_deg, 1e-9);
  EXPECT_GT(j["objects"][0]["change_area_m2"].get<double>(), 1.0);
  EXPECT_TRUE(j["objects"][0]["reason"].is_null());
  EXPECT_DOUBLE_EQ(j["thresholds"]["match_radius_factor"].get<double>(), 1.0);
}

// Issue 28: recognitions that disagree between surveys over a site that did not change — a
// structure missed in B, one recognised as another model in B, one placed where neither survey
// looked — are uncertain (with why), never added or removed; the agreeing one is unchanged.
TEST(ChangeDetection, ARecognitionInOneSurveyWithoutHeightChangeIsUncertain) {
  const std::vector<Box> site{kStay, kMoveA, kRemoved};
  const PointCloud a = survey(site, 0.005, 13);
  const PointCloud b = survey(site, 0.008, 14, kTbA);
  const ObjectModels models{{"frame", sized(Symmetry::Half, 1.2, 0.6)},
                            {"crate", sized(Symmetry::None, 0.6, 0.6)}};
  const Box outside{12.0, 9.0, 0.6, 0.6, 0, 0.3};  // beyond both surveys
  const std::vector<SurveyPlacement> pa{placed("frame", kStay), placed("frame", kMoveA),
                                        placed("crate", kRemoved), placed("crate", outside)};
  const std::vector<SurveyPlacement> pb{{"frame", kTbA * placed("frame", kStay).T_world_model},
                                        {"crate", kTbA * placed("crate", kMoveA).T_world_model}};
  const ChangeResult r = diff_surveys(a, b, pa, pb, models, test_config());
  EXPECT_TRUE(r.regions.empty()) << r.regions.size() << " regions";
  ASSERT_EQ(r.objects.size(), 5u);
  EXPECT_EQ(r.objects[0].status, ObjectStatus::Unchanged);  // frame_0: both agree
  const ObjectChange& relabel_a = r.objects[1];             // frame_1: a crate in B
  EXPECT_EQ(relabel_a.status, ObjectStatus::Uncertain);
  EXPECT_EQ(relabel_a.other_model, "crate");
  EXPECT_NE(relabel_a.reason.find("recognised in A as frame, in B as crate; no height change"),
            std::string::npos)
      << relabel_a.reason;
  const ObjectChange& missed = r.objects[2];  // crate_0: not recognised in B
  EXPECT_EQ(missed.status, ObjectStatus::Uncertain);
  EXPECT_TRUE(missed.other_model.empty());
  EXPECT_NE(missed.reason.find("recognised in A only; no height change within its footprint"),
            std::string::npos)
      << missed.reason;
  EXPECT_EQ(missed.change_area_m2, 0.0);
  EXPECT_GT(missed.observed_fraction, 0.9);
  const ObjectChange& unseen = r.objects[3];  // crate_1: where the surveys have no data
  EXPECT_EQ(unseen.status, ObjectStatus::Uncertain);
  EXPECT_NE(unseen.reason.find("not observed by both surveys"), std::string::npos) << unseen.reason;
  const ObjectChange& relabel_b = r.objects[4];  // crate_2: B's crate over A's frame
  EXPECT_EQ(relabel_b.status, ObjectStatus::Uncertain);
  EXPECT_TRUE(relabel_b.in_b && !relabel_b.in_a);
  EXPECT_EQ(relabel_b.other_model, "frame");

  // Written and read back by sonar3d report's reader (a one-survey object is no longer an
  // "unchanged" one with a null pose).
  const fs::path dir = test::temp_dir("uncertain");
  write_change_directory((dir / "D").string(), r);
  const std::string text = read_text_file((dir / "D/changes.json").string());
  const nlohmann::json j = nlohmann::json::parse(text);
  EXPECT_EQ(j["objects"][2]["status"], "uncertain");
  EXPECT_TRUE(j["objects"][2]["T_world_model_b_in_a"].is_null());
  EXPECT_EQ(j["objects"][4]["other_model"], "frame");
  EXPECT_NE(j["objects"][2]["reason"].get<std::string>().find("A only"), std::string::npos);
  fs::remove_all(dir);
}

TEST(ChangeDetection, BadInputsGiveClearErrors) {
  // A placement of a model the catalogue does not list.
  test::expect_error(
      [] {
        compare_placements({{"tank", pose(0, 0, 0, 0)}}, {{"valve", pose(0, 0, 0, 0)}},
                           {{"tank", {Symmetry::Full}}}, test_config());
      },
      "placement 0 is a model 'valve' that the catalogue does not list");
  // Surveys that do not overlap.
  const PointCloud a = survey({}, 0.005, 1);
  const PointCloud far = survey({}, 0.005, 2, pose(30, 0, 0, 0));
  test::expect_error([&] { register_surveys(a, far, test_config().registration); },
                     "do not overlap");
  test::expect_error([&] { register_surveys(a, PointCloud{}, test_config().registration); },
                     "survey B has no points");
  // Placements files (the reader is world_model.hpp's; its own tests are in test_world.cpp).
  test::expect_error([] { read_placements("/nonexistent/p.json"); }, "no such file");
  const std::string head = R"({"format": "sonar3d-placements", "version": 1, "placements": )";
  test::expect_error(
      [&] {
        parse_placements(head +
                             "[{\"model\": \"t\", \"T_world_model\": "
                             "[2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}]}",
                         "p.json");
      },
      "not a rotation");
  const auto ok = parse_placements(
      head + "[{\"model\": \"t\", \"T_world_model\": [[1,0,0,4],[0,1,0,5],[0,0,1,6],[0,0,0,1]]}]}",
      "p.json");
  ASSERT_EQ(ok.placements.size(), 1u);
  EXPECT_EQ(ok.placements[0].T_world_model.translation(), Eigen::Vector3d(4, 5, 6));
  test::expect_error([] { parse_placements(std::string(200000, '['), "deep.json"); },
                     "nested more than");
  ChangeConfig bad = test_config();
  bad.cell_m = 0;
  test::expect_error([&] { bad.validate(); }, "cell_m");
}

// Marine growth: one box's colour changed (red to brown), nothing moved, survey B lit at 70 % of
// A's brightness: exactly one region of colour change, on that box, and no height change.
TEST(ColourChange, OneBoxRecolouredIsOneRegion) {
  const std::vector<Box> site{kStay, kMoveA, kRemoved};
  PointCloud a = survey(site, 0.005, 3);
  PointCloud b = survey(site, 0.008, 4, kTbA);
  colourise(&a, site, {kYellow, kRed, kGrey}, 1.0, 7);
  colourise(&b, site, {kYellow, kBrown, kGrey}, 0.7, 8, kTbA);
  const ChangeResult r = diff_surveys(a, b, {}, {}, {}, test_config(), &a, &b);
  EXPECT_TRUE(r.regions.empty()) << r.regions.size() << " regions of height change";
  const ColourChange& c = r.colour;
  ASSERT_TRUE(c.compared);
  EXPECT_EQ(c.space, ColourSpace::Chromaticity);
  EXPECT_GT(c.compared_cells, 4000u);  // of the 8 × 6 m site at 10 cm
  ASSERT_EQ(c.regions.size(), 1u) << "the second at " << c.regions[1].centroid.transpose();
  const ColourRegion& g = c.regions[0];
  EXPECT_TRUE(kMoveA.covers(g.centroid.x(), g.centroid.y())) << g.centroid.transpose();
  EXPECT_NEAR(g.area_m2, 1.2 * 0.5, 0.15);      // the box's top, less its edge cells
  EXPECT_GT(g.colour_a[0], 2 * g.colour_a[1]);  // red before
  EXPECT_LT(g.colour_b[0], 2 * g.colour_b[1]);  // brown after: more green than red's
  EXPECT_GT(g.colour_b[1], g.colour_b[2]);
  EXPECT_GT(g.mean_delta, c.threshold);
  EXPECT_EQ(g.height_change_fraction, 0.0);  // the surface changed, not the geometry
  EXPECT_GE(c.sigma, 1.0);                   // at least the floor (percentage points)
  // The change map of colour: no data outside the compared cells, the box above the threshold.
  EXPECT_EQ(c.delta_map.num_valid(), c.compared_cells);
  // In CIELAB the 30 % darker B is a lightness offset (the median, taken out) and the box is
  // found too.
  ChangeConfig lab = test_config();
  lab.colour.space = ColourSpace::Lab;
  const ChangeResult rl = diff_surveys(a, b, {}, {}, {}, lab, &a, &b);
  ASSERT_EQ(rl.colour.offset.size(), 3u);
  EXPECT_LT(rl.colour.offset[0], -5);  // L*: B darker
  bool box = false;
  for (const ColourRegion& q : rl.colour.regions)
    box |= kMoveA.covers(q.centroid.x(), q.centroid.y());
  EXPECT_TRUE(box);
  // Written next to the geometry change map.
  const fs::path dir = test::temp_dir("out");
  write_change_directory((dir / "D").string(), r);
  const nlohmann::json j = nlohmann::json::parse(read_text_file((dir / "D/changes.json").string()));
  EXPECT_EQ(j["colour"]["space"], "chromaticity");
  ASSERT_EQ(j["colour"]["regions"].size(), 1u);
  EXPECT_EQ(j["colour"]["regions"][0]["colour_a"][0].get<int>(), g.colour_a[0]);
  EXPECT_EQ(j["colour"]["offset"].size(), 2u);
  const ElevationMap m = read_elevation_geotiff((dir / "D/colour_change_map.tif").string());
  EXPECT_EQ(m.num_valid(), c.compared_cells);
}

// The moved/added/removed pair with unchanged colours (B darker): colour changes only where the
// geometry changed, none on the untouched box.
TEST(ColourChange, MovedAddedRemovedPairHasNoColourChangeOnUntouchedObjects) {
  const std::vector<Box> sa{kStay, kMoveA, kRemoved}, sb{kStay, kMoveB, kAdded};
  PointCloud a = survey(sa, 0.005, 5);
  PointCloud b = survey(sb, 0.008, 6, kTbA);
  colourise(&a, sa, {kYellow, kRed, kGrey}, 1.0, 9);
  colourise(&b, sb, {kYellow, kRed, kGrey}, 0.8, 10, kTbA);
  const ChangeResult r = diff_surveys(a, b, {}, {}, {}, test_config(), &a, &b);
  ASSERT_TRUE(r.colour.compared);
  bool on_moved = false;
  for (const ColourRegion& g : r.colour.regions) {
    const double x = g.centroid.x(), y = g.centroid.y();
    EXPECT_FALSE(kStay.covers(x, y, 0.2)) << "colour change on the untouched box";
    EXPECT_TRUE(kAdded.covers(x, y, 0.2) || kRemoved.covers(x, y, 0.2) ||
                kMoveA.covers(x, y, 0.2) || kMoveB.covers(x, y, 0.2))
        << "a colour region at " << g.centroid.transpose();
    on_moved |= kMoveA.covers(x, y, 0.2) || kMoveB.covers(x, y, 0.2);
    if (kAdded.covers(x, y) || kRemoved.covers(x, y)) {
      EXPECT_GT(g.height_change_fraction, 0.5) << g.centroid.transpose();  // geometry changed
    }
  }
  EXPECT_TRUE(on_moved);  // the red box left sand where it stood and covers sand where it stands
  EXPECT_FALSE(r.regions.empty());
}

TEST(ColourChange, BadInputsGiveClearErrors) {
  const std::vector<Box> site{kStay};
  PointCloud a = survey(site, 0.005, 1);
  PointCloud b = survey(site, 0.005, 2);
  // A colour cloud without colour.
  test::expect_error([&] { diff_surveys(a, b, {}, {}, {}, test_config(), &a, &b); },
                     "colour cloud A has no colour");
  colourise(&a, site, {kYellow}, 1.0, 3);
  colourise(&b, site, {kYellow}, 1.0, 4);
  // Only one survey's colour.
  test::expect_error([&] { diff_surveys(a, b, {}, {}, {}, test_config(), &a, nullptr); },
                     "a coloured cloud of each survey");
  // Colour clouds that do not overlap (B's colours 30 m away).
  PointCloud far = b;
  for (Eigen::Vector3f& p : far.points) p.x() += 30;
  test::expect_error([&] { compare_colour(a, far, test_config().colour); },
                     "the colour clouds overlap on 0 cells");
  // A NaN colour (a float colour property, as a PLY with float red/green/blue is read).
  PointCloud nan = b;
  nan.color.clear();
  for (const char* ch : {"red", "green", "blue"}) {
    nan.properties.push_back({ch, std::vector<float>(nan.size(), 0.5f)});
  }
  nan.properties[1].values[17] = std::nanf("");
  test::expect_error([&] { check_colour_cloud(nan, "c.ply"); },
                     "c.ply: vertex 17 has a colour that is not finite (green");
  // Every point black: no camera saw any.
  PointCloud black = b;
  for (auto& c : black.color) c = {0, 0, 0};
  test::expect_error([&] { check_colour_cloud(black, "black.ply"); }, "no coloured point");
  // ... unless its `views` (sonar3d texture) say cameras saw them: a black surface.
  black.properties.push_back({"views", std::vector<float>(black.size(), 2.0f)});
  EXPECT_NO_THROW(check_colour_cloud(black, "black.ply"));
  black.properties.back().values.assign(black.size(), 0.0f);
  test::expect_error([&] { check_colour_cloud(black, "black.ply"); }, "no coloured point");
  // A colour cell so small that the grid would take gigabytes: refused before allocating.
  ColourChangeConfig tiny = test_config().colour;
  tiny.cell_m = 1e-4;
  tiny.tolerance_m = tiny.link_m = 0;
  test::expect_error([&] { compare_colour(a, b, tiny); }, "colour cell_m too small");
  ChangeConfig bad = test_config();
  bad.colour.cell_m = -1;
  test::expect_error([&] { bad.validate(); }, "colour.cell_m (--colour-cell) must be");
}

#ifdef SONAR3D_CLI
// End to end on the simulated small pair (data/scenes/change_a.yaml, change_b.yaml, written by
// scripts/change_pair.py small changed): each survey simulated with its own seed and dead
// reckoning, mapped, recognised with the catalogue and compared. It must report exactly the
// riser moved 30 cm and turned 10°, the pillar removed and a tank added, the other tank
// unchanged; every region of height change on one of those.
TEST(ChangeCli, SimulatedPairGivesExactlyItsChanges) {
  const fs::path dir = test::temp_dir("cli");
  const std::string src = SONAR3D_SOURCE_DIR;
  {
    std::ofstream(dir / "cat.yaml") << R"(models:
  - {name: riser, reference: riser, symmetry: none}
  - {name: tank, reference: tank, symmetry: full}
  - {name: pillar, reference: pillar, symmetry: "180"}
)";
  }
  for (const char* w : {"a", "b"}) {
    test::CliRun r = test::run_cli(dir, "simulate " + src + "/data/scenes/change_" + w +
                                            ".yaml -o " + (dir / w).string() + " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    r = test::run_cli(
        dir, "map " + (dir / w).string() + " -o " + (dir / w).string() + "_map --search 0.3 -q");
    ASSERT_EQ(r.code, 0) << r.out;
  }
  const std::string args = "diff " + (dir / "a_map").string() + " " + (dir / "b_map").string() +
                           " --catalogue " + (dir / "cat.yaml").string() + " -o ";
  test::CliRun r = test::run_cli(dir, args + (dir / "D").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(read_text_file((dir / "D/changes.json").string()));
  // T_a_b: the inverse of B's frame offset (scripts/change_pair.py: 1° yaw, 25 cm East, −15 cm
  // North) composed with what each survey's dead reckoning did to its map (heading biases 0.2°
  // and −0.1°): the rigid fit of each map's corrected navigation to its true one gives yaw
  // −0.52°, shift (−0.278, 0.150) m; the maps themselves depart from rigid by 3–7 cm.
  EXPECT_NEAR(j["T_a_b"][3].get<double>(), -0.278, 0.05) << r.out;
  EXPECT_NEAR(j["T_a_b"][7].get<double>(), 0.150, 0.05) << r.out;
  EXPECT_NEAR(std::atan2(j["T_a_b"][4].get<double>(), j["T_a_b"][0].get<double>()) / kDeg, -0.52,
              0.4)
      << r.out;
  std::map<std::string, std::string> status;
  for (const auto& o : j["objects"]) {
    status[o["model"].get<std::string>() + ":" + o["status"].get<std::string>()] =
        o["id"].get<std::string>();
  }
  EXPECT_EQ(status.size(), 4u) << r.out;
  EXPECT_EQ(j["objects"].size(), 4u) << r.out;
  EXPECT_TRUE(status.count("riser:moved")) << r.out;
  EXPECT_TRUE(status.count("tank:unchanged")) << r.out;
  EXPECT_TRUE(status.count("tank:added")) << r.out;
  EXPECT_TRUE(status.count("pillar:removed")) << r.out;
  // Every region within 1.5 m of a changed object (riser before/after, pillar, added tank; A's
  // frame), and a region at each.
  const std::vector<Eigen::Vector2d> changed{{-2.0, 1.0}, {-1.7, 1.0}, {1.8, 1.6}, {-1.2, -1.6}};
  std::vector<bool> seen(changed.size(), false);
  for (const auto& g : j["regions"]) {
    const Eigen::Vector2d c(g["centroid"][0].get<double>(), g["centroid"][1].get<double>());
    bool near = false;
    for (std::size_t k = 0; k < changed.size(); ++k) {
      if ((c - changed[k]).norm() < 1.5) near = true, seen[k] = true;
    }
    EXPECT_TRUE(near) << "a region of change at " << c.transpose() << "\n" << r.out;
  }
  EXPECT_TRUE(seen[2] && seen[3]) << r.out;  // the pillar's and the added tank's
  EXPECT_TRUE(fs::exists(dir / "D/change_map.tif"));
  EXPECT_TRUE(fs::exists(dir / "D/change_points.ply"));

  // Bad inputs: one clear line, no output.
  r = test::run_cli(dir, args + (dir / "D").string() + " -q");  // exists
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("already exists"), std::string::npos) << r.out;
  r = test::run_cli(dir, "diff " + (dir / "a_map").string() + " " + (dir / "nothing").string() +
                             " -o " + (dir / "E").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("nothing"), std::string::npos) << r.out;
  {
    std::ofstream(dir / "pa.json")
        << R"({"format": "sonar3d-placements", "version": 1, "placements": [
  {"model": "valve", "T_world_model": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})";
  }
  r = test::run_cli(dir, args + (dir / "E").string() + " --placements-a " +
                             (dir / "pa.json").string() + " --placements-b " +
                             (dir / "pa.json").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("'valve' that the catalogue does not list"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "E"));
  fs::remove_all(dir);
}

// Colour change end to end: a site simulated twice with a camera (terrain, a yellow box and a red
// box; in B the red box has turned brown — marine growth — and the lamp is weaker), each
// survey's cloud (sampled from the truth) coloured by `sonar3d texture --dataset`, then
// `sonar3d diff` with the coloured clouds as surveys and as --colour-a/--colour-b: exactly one
// region of colour change, on the recoloured box, and no height change.
TEST(ColourChangeCli, SimulatedRecolouredBoxIsTheOnlyColourChange) {
  const fs::path dir = test::temp_dir("colour_cli");
  auto scene = [](const char* red_box, double ambient) {
    return std::string(R"(seed: 5
sensor: {preset: sim-10deg, beams: 20, fov_deg: 40, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
simulation: {elevation_step_deg: 0.5}
objects:
  - {name: seabed, primitive: {type: terrain, size: [6, 6], cell: 0.05, relief: 0.15, wavelength: 3, trenches: 0, rocks: 5, seed: 3}, color: [0.7, 0.6, 0.3]}
  - {name: yellow, primitive: {type: box, size: [0.6, 0.4, 0.4]}, pose: {translation: [-0.9, 0.4, 0.2], rpy_deg: [0, 0, 15]}, color: [0.8, 0.7, 0.1]}
  - {name: growth, primitive: {type: box, size: [0.7, 0.5, 0.5]}, pose: {translation: [0.8, -0.3, 0.25], rpy_deg: [0, 0, -10]}, color: )") +
           red_box + R"(}
trajectory: {period: 0.1, type: straight, start: [-1.5, 0, 3], end: [1.5, 0, 3], spacing: 0.1}
camera: {width: 240, height: 180, fx: 150, fy: 150, cx: 119.5, cy: 89.5, T_vehicle_camera: {rpy_deg: [180, 0, 0]}, rate_hz: 2, ambient: )" +
           std::to_string(ambient) + R"(, attenuation_per_m: 0.05}
)";
  };
  std::ofstream(dir / "a.yaml") << scene("[0.7, 0.08, 0.06]", 0.6);
  std::ofstream(dir / "b.yaml") << scene("[0.35, 0.2, 0.08]", 0.4);
  for (const char* w : {"a", "b"}) {
    const fs::path ds = dir / (std::string(w) + "_ds");
    test::CliRun r = test::run_cli(dir, "simulate " + (dir / (std::string(w) + ".yaml")).string() +
                                            " -o " + ds.string() + " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    PointCloud cloud;
    for (const SceneObject& o : read_truth(ds)) {
      const auto pts = sample_surface(o.mesh_world, o.name == "seabed" ? 120000 : 8000,
                                      std::string(w) == "a" ? 1 : 2);
      cloud.points.insert(cloud.points.end(), pts.begin(), pts.end());
    }
    write_ply((dir / (std::string(w) + ".ply")).string(), cloud);
    r = test::run_cli(dir, "texture " + (dir / (std::string(w) + ".ply")).string() + " --dataset " +
                               ds.string() + " --point-spacing 0.03 -q -o " +
                               (dir / (std::string(w) + "_rgb.ply")).string());
    ASSERT_EQ(r.code, 0) << r.out;
  }
  const std::string a = (dir / "a_rgb.ply").string(), b = (dir / "b_rgb.ply").string();
  const std::string args = "diff " + a + " " + b + " --colour-a " + a + " --colour-b " + b + " -o ";
  test::CliRun r = test::run_cli(dir, args + (dir / "D").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("0 regions of change, 1 regions of colour change"), std::string::npos)
      << r.out;
  const nlohmann::json j = nlohmann::json::parse(read_text_file((dir / "D/changes.json").string()));
  ASSERT_EQ(j["colour"]["regions"].size(), 1u) << r.out;
  const auto& g = j["colour"]["regions"][0];
  const Eigen::Vector2d c(g["centroid"][0].get<double>(), g["centroid"][1].get<double>());
  EXPECT_LT((c - Eigen::Vector2d(0.8, -0.3)).norm(), 0.15) << r.out;
  EXPECT_GT(g["area_m2"].get<double>(), 0.15) << r.out;  // of the 0.35 m² top
  EXPECT_GT(g["colour_a"][0].get<int>(), 2 * g["colour_a"][1].get<int>()) << r.out;  // red
  EXPECT_LT(g["colour_b"][0].get<int>(), 2 * g["colour_b"][1].get<int>()) << r.out;  // brown
  EXPECT_EQ(g["height_change_fraction"].get<double>(), 0.0) << r.out;
  EXPECT_NE(r.out.find("surface only"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir / "D/colour_change_map.tif"));

  // Bad inputs: one line naming the file, no output.
  r = test::run_cli(dir, args.substr(0, args.find(" --colour-b ")) + " --colour-b " +
                             (dir / "a.ply").string() + " -o " + (dir / "E").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--colour-b '" + (dir / "a.ply").string() + "' has no colour"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  r = test::run_cli(dir,
                    "diff " + a + " " + b + " --colour-a " + a + " -o " + (dir / "E").string());
  EXPECT_EQ(r.code, 2) << r.out;  // --colour-a needs --colour-b
  EXPECT_FALSE(fs::exists(dir / "E"));
  fs::remove_all(dir);
}
#endif
