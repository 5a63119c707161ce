// sim: ray-traced images against analytic geometry, shadows, noise statistics, trajectories,
// scene files and their bad inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/noise.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;
namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;

namespace {

SonarSpec test_spec(double aperture_deg) {
  SonarSpec s;
  s.set_uniform_bearings(60 * kDeg, 120);
  s.r_min = 0.5;
  s.r_max = 6.0;
  s.range_bins = 275;  // 2 cm
  s.vertical_aperture_rad = aperture_deg * kDeg;
  return s;
}

SceneObject sphere_at(const Eigen::Vector3d& c, double r) {
  SceneObject o;
  o.name = "sphere";
  o.mesh_world = make_sphere(r, 128);
  o.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(c)));
  o.reflectivity = 1.0;
  return o;
}

// Smallest ray–sphere intersection distance over the rays of beam j (bearing cell × aperture).
double analytic_first_range(const SonarSpec& s, int j, const Eigen::Vector3d& c, double R) {
  double best = std::numeric_limits<double>::infinity();
  for (int a = 0; a <= 40; ++a) {
    const double phi = s.beam_edge_low(j) + (s.beam_edge_high(j) - s.beam_edge_low(j)) * a / 40.0;
    for (int b = 0; b <= 200; ++b) {
      const double theta = -s.theta_3db() + s.vertical_aperture_rad * b / 200.0;
      const Eigen::Vector3d u = polar_to_sonar({1.0, phi, theta});
      const double uc = u.dot(c);
      const double disc = uc * uc - (c.squaredNorm() - R * R);
      if (disc >= 0) best = std::min(best, uc - std::sqrt(disc));
    }
  }
  return best;
}

}  // namespace

TEST(Simulator, SphereFirstReturnMatchesAnalyticRange) {
  const SonarSpec s = test_spec(10);
  const Eigen::Vector3d c(3.0, 0.2, 0.05);
  const double R = 0.5;
  Scene scene;
  scene.objects.push_back(sphere_at(c, R));
  SimulatorConfig cfg;
  cfg.elevation_step_rad = 0.02 * kDeg;
  const Simulator sim(scene, s, cfg);
  const SonarImage img = sim.render(Eigen::Isometry3d::Identity(), 1);
  int beams_with_return = 0;
  for (int j = 0; j < s.beams(); ++j) {
    int first = -1;
    for (int i = 0; i < s.range_bins && first < 0; ++i) {
      if (img.at(i, j) > 0) first = i;
    }
    const double expected = analytic_first_range(s, j, c, R);
    if (!std::isfinite(expected)) {
      EXPECT_EQ(first, -1) << "beam " << j << " should see nothing";
      continue;
    }
    // Grazing beams at the limb may get no ray on the sphere: only beams well inside count.
    if (first < 0) {
      const double phi = s.bearings_rad[j];
      EXPECT_GT(std::abs(std::asin(std::sin(phi - std::atan2(c.y(), c.x())))),
                std::asin(R / c.norm()) - 1.0 * kDeg)
          << "beam " << j << " missed the sphere";
      continue;
    }
    ++beams_with_return;
    EXPECT_NEAR(s.range_of_bin(first), expected, s.range_resolution() * 1.01) << "beam " << j;
  }
  EXPECT_GT(beams_with_return, 30);
}

TEST(Simulator, ShadowBehindAnObjectIsEmpty) {
  const SonarSpec s = test_spec(10);
  Scene scene;
  scene.objects.push_back(sphere_at(Eigen::Vector3d(2.0, 0, 0), 0.5));
  SceneObject wall;
  wall.name = "wall";
  wall.mesh_world = make_plane(20, 20);  // z = 0, rotated to face the sonar at x = 4
  wall.mesh_world.transform(Eigen::Translation3d(4.0, 0, 0) *
                            Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  wall.reflectivity = 0.5;
  scene.objects.push_back(wall);
  const Simulator sim(scene, s, SimulatorConfig{});
  const SonarImage img = sim.render(Eigen::Isometry3d::Identity(), 3);
  const int wall_bin = s.bin_of_range(3.9);
  for (int j = 0; j < s.beams(); ++j) {
    const double phi = std::abs(s.bearings_rad[j]);
    double behind = 0;  // everything beyond the sphere's far side
    for (int i = s.bin_of_range(2.6); i < s.range_bins; ++i) behind += img.at(i, j);
    if (phi < 10 * kDeg) {
      // asin(0.5/2) = 14.5°: all rays of these beams (±5° elevation) hit the sphere first.
      EXPECT_EQ(behind, 0.0) << "beam " << j << " sees through the sphere";
    } else if (phi > 20 * kDeg) {
      EXPECT_GT(behind, 0.0) << "beam " << j << " should see the wall";
      double near_wall = 0;
      for (int i = wall_bin; i < s.range_bins; ++i) near_wall += img.at(i, j);
      EXPECT_GT(near_wall, 0.0);
    }
  }
}

TEST(Simulator, IntensityNormalisationOnAWall) {
  // A wall facing the sonar, μ = 1, flat pattern, gain 1: every ray returns cos(incidence), so
  // each column sums to the mean cosine over the beam (≈ 1 for a 1° aperture near boresight).
  SonarSpec s = test_spec(1);
  s.beam_pattern.kind = BeamPattern::Kind::Flat;
  Scene scene;
  SceneObject wall;
  wall.name = "wall";
  wall.mesh_world = make_plane(50, 50);
  wall.mesh_world.transform(Eigen::Translation3d(2.0, 0, 0) *
                            Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitY()));
  wall.reflectivity = 1.0;
  scene.objects.push_back(wall);
  SimulatorConfig cfg;
  cfg.gain = 1.0;
  const Simulator sim(scene, s, cfg);
  const SonarImage img = sim.render(Eigen::Isometry3d::Identity(), 1);
  for (int j = 0; j < s.beams(); ++j) {
    double sum = 0;
    for (int i = 0; i < s.range_bins; ++i) sum += img.at(i, j);
    EXPECT_NEAR(sum, std::cos(s.bearings_rad[j]), 0.01) << "beam " << j;
  }
}

TEST(Simulator, SameSeedSameImage) {
  const SonarSpec s = test_spec(10);
  Scene scene;
  scene.objects.push_back(sphere_at(Eigen::Vector3d(3.0, 0, 0), 0.5));
  SimulatorConfig one;
  one.num_threads = 1;
  SimulatorConfig two;
  two.num_threads = 2;
  const Simulator a(scene, s, one), b(scene, s, two);
  const SonarImage ia = a.render(Eigen::Isometry3d::Identity(), 11);
  const SonarImage ib = b.render(Eigen::Isometry3d::Identity(), 11);
  EXPECT_EQ(ia.data, ib.data);
  const SonarImage ic = b.render(Eigen::Isometry3d::Identity(), 12);
  EXPECT_NE(ia.data, ic.data);
}

TEST(Simulator, RejectsBadSetups) {
  Scene empty;
  expect_error([&] { Simulator(empty, test_spec(10), SimulatorConfig{}); }, "empty");
  Scene scene;
  scene.objects.push_back(sphere_at(Eigen::Vector3d(3.0, 0, 0), 0.5));
  SimulatorConfig cfg;
  cfg.elevation_step_rad = 2 * kDeg;
  expect_error([&] { Simulator(scene, test_spec(1), cfg); }, "elevation_step");
  cfg = SimulatorConfig{};
  cfg.gain = std::nan("");
  expect_error([&] { Simulator(scene, test_spec(10), cfg); }, "gain");
  expect_error([&] { Simulator(scene, test_spec(180), SimulatorConfig{}); },
               "vertical_aperture_deg");
  const Simulator sim(scene, test_spec(10), SimulatorConfig{});
  Eigen::Isometry3d nan_pose = Eigen::Isometry3d::Identity();
  nan_pose.translation().x() = std::nan("");
  expect_error([&] { sim.render(nan_pose, 1); }, "not finite");
}

TEST(Noise, StripeSamplesMatchTheirModel) {
  SonarSpec s = test_spec(10);
  StripeNoiseConfig c;
  c.floor_mean = 0.2;  // far from 0 so that clamping at zero does not bias the moments
  c.floor_std = 0.01;
  c.stripe_mean = 0.05;
  c.stripe_std = 0.02;
  const NoiseImages model = stripe_noise_images(s, c);
  // 7 stripes: the mean across bearing has 7 local maxima.
  int peaks = 0;
  for (int j = 1; j + 1 < s.beams(); ++j) {
    if (model.mean.at(0, j) > model.mean.at(0, j - 1) &&
        model.mean.at(0, j) >= model.mean.at(0, j + 1))
      ++peaks;
  }
  EXPECT_EQ(peaks, 7);
  std::mt19937_64 rng(9);
  NoiseEstimator est;
  for (int k = 0; k < 400; ++k) {
    SonarImage img(s.range_bins, s.beams());
    add_noise(img, model, rng);
    est.add(img);
  }
  const NoiseImages got = est.result();
  double mean_err = 0, std_err = 0, std_sum = 0;
  for (std::size_t k = 0; k < got.mean.data.size(); ++k) {
    mean_err += std::abs(got.mean.data[k] - model.mean.data[k]);
    std_err += got.std.data[k] - model.std.data[k];
    std_sum += model.std.data[k];
  }
  const double n = static_cast<double>(got.mean.data.size());
  EXPECT_LT(mean_err / n, 0.002);                // σ/√400 ≈ 0.001 per pixel
  EXPECT_LT(std::abs(std_err) / std_sum, 0.01);  // no bias in the spread over 33k pixels
}

TEST(Noise, EstimatorNeedsTwoFramesOfOneSize) {
  NoiseEstimator est;
  est.add(SonarImage(4, 4));
  EXPECT_THROW(est.result(), Error);
  EXPECT_THROW(est.add(SonarImage(4, 5)), Error);
}

TEST(TrajectoryGen, StraightOrbitLawnmower) {
  const Trajectory p =
      straight_pass({0, 0, 0}, {0, 0, 1}, 0.01, Eigen::Matrix3d::Identity(), 0, 0.1);
  ASSERT_EQ(p.size(), 101u);
  EXPECT_NEAR(p.poses[100].translation().z(), 1.0, 1e-12);
  EXPECT_NEAR(p.times[100], 10.0, 1e-12);
  const Trajectory o = orbit({1, 2, 3}, 4.0, 36, 0.0, 2 * M_PI, 0, 0.1);
  ASSERT_EQ(o.size(), 36u);
  for (const auto& T : o.poses) {
    EXPECT_NEAR((T.translation() - Eigen::Vector3d(1, 2, 3)).norm(), 4.0, 1e-9);
    const Eigen::Vector3d to_centre = (Eigen::Vector3d(1, 2, 3) - T.translation()).normalized();
    EXPECT_NEAR(T.linear().col(0).dot(to_centre), 1.0, 1e-9);  // +x faces the centre
  }
  LawnmowerConfig lc;
  lc.x1 = 10;
  lc.y1 = 4;
  lc.z = -5;
  lc.line_spacing = 2;
  lc.spacing = 1;
  const Trajectory l = lawnmower(lc, 0, 0.1);
  EXPECT_EQ(l.size(), 3u * 11u);
  l.validate();
  EXPECT_THROW(straight_pass({0, 0, 0}, {0, 0, 1}, 0, Eigen::Matrix3d::Identity(), 0, 0.1), Error);
}

// Lines along any heading with turns a vehicle can fly: every frame a spacing apart along the
// track (no jump), the yaw along the direction of travel, the lines along the heading and inside
// the turned rectangle, the turns outside it with the given radius.
TEST(TrajectoryGen, LawnmowerAlongAHeadingWithTurns) {
  LawnmowerConfig c;
  c.x0 = -10;
  c.x1 = 10;
  c.y0 = -6;
  c.y1 = 6;
  c.z = 5;
  c.line_spacing = 6;
  c.spacing = 0.05;
  c.heading = 30.0 * M_PI / 180;
  c.turn_radius = 2;
  const Trajectory t = lawnmower(c, 0, 0.1);
  t.validate();
  // Length: 3 lines of 20 m, 2 turns of two quarter circles (π·R) and a 2 m leg.
  const double length = 3 * 20.0 + 2 * (M_PI * 2 + 2.0);
  EXPECT_EQ(t.size(), static_cast<std::size_t>(std::floor(length / 0.05 + 1e-9)) + 1);
  const Eigen::Vector2d centre(0, 0);
  const Eigen::Rotation2Dd back(-c.heading);
  int on_lines = 0;
  for (std::size_t k = 0; k + 1 < t.size(); ++k) {
    const Eigen::Vector3d p = t.poses[k].translation(), q = t.poses[k + 1].translation();
    EXPECT_NEAR((q - p).norm(), 0.05, 2e-3) << "frame " << k;  // chords on the arcs: < spacing
    EXPECT_NEAR(p.z(), 5.0, 1e-12);
    // +x of the vehicle along the track.
    const Eigen::Vector3d fwd = t.poses[k].linear().col(0);
    EXPECT_GT(fwd.dot((q - p).normalized()), std::cos(2.0 * 0.05 / 2)) << "frame " << k;
    // In the survey frame: on a line (|v| within the rectangle) or on a turn outside it.
    const Eigen::Vector2d s = back * (p.head<2>() - centre);
    if (s.x() >= -10 - 1e-9 && s.x() <= 10 + 1e-9) {
      ++on_lines;
      EXPECT_TRUE(std::abs(s.y() + 6) < 1e-9 || std::abs(s.y()) < 1e-9 ||
                  std::abs(s.y() - 6) < 1e-9)
          << "frame " << k << " at " << s.transpose();
      const double yaw = std::atan2(fwd.y(), fwd.x());
      EXPECT_NEAR(std::abs(std::sin(yaw - c.heading)), 0.0, 1e-9);  // along the heading
    } else {
      EXPECT_LE(std::abs(s.x()), 10 + 2 + 1e-9);  // the turn stays within R of the line ends
    }
  }
  EXPECT_GT(on_lines, static_cast<int>(0.9 * 60 / 0.05));
  // A turn wider than half the line spacing cannot be flown with two quarter circles.
  c.turn_radius = 3.5;
  EXPECT_THROW(lawnmower(c, 0, 0.1), Error);
  c.turn_radius = -1;
  EXPECT_THROW(lawnmower(c, 0, 0.1), Error);
  c.turn_radius = 0;
  c.heading = std::nan("");
  EXPECT_THROW(lawnmower(c, 0, 0.1), Error);
}

TEST(SceneFile, SimulatesADatasetWithTruth) {
  const fs::path dir = temp_dir("scene");
  std::ofstream(dir / "scene.yaml") << R"(
seed: 4
sensor: {preset: sim-10deg, beams: 60, fov_deg: 30}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.3}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory:
  period: 0.2
  type: straight
  start: [0, 0, -0.2]
  end: [0, 0, 0.2]
  spacing: 0.1
noise: {model: stripes, scale: 0.5}
)";
  const SimulationSetup setup = load_simulation_setup((dir / "scene.yaml").string());
  simulate_dataset(setup, dir / "ds", false);
  const Dataset ds = read_dataset(dir / "ds");
  ASSERT_EQ(ds.size(), 5u);
  EXPECT_NEAR(ds.frames[4].timestamp, 0.8, 1e-12);
  EXPECT_NEAR(ds.T_world_sonar(4).translation().z(), 0.2, 1e-9);
  ASSERT_TRUE(ds.noise.has_value());
  const auto truth = read_truth(dir / "ds");
  ASSERT_EQ(truth.size(), 1u);
  EXPECT_EQ(truth[0].name, "ball");
  EXPECT_NEAR(truth[0].mesh_world.bounding_box().center().x(), 2.5, 1e-3);
  // The middle frame sees the ball at ~2.2 m.
  const SonarImage mid = ds.load_frame(2);
  float peak = 0;
  int peak_row = -1;
  for (int i = 0; i < mid.rows; ++i) {
    if (mid.at(i, 30) > peak) {
      peak = mid.at(i, 30);
      peak_row = i;
    }
  }
  EXPECT_NEAR(ds.spec.range_of_bin(peak_row), 2.2, 0.05);
}

// Pipelines laid between two seabed points, sunk by a fraction of their diameter; the seabed and
// the pipeline keep their kind in the dataset's truth.
TEST(SceneFile, PipelinesAndObjectKinds) {
  const fs::path dir = temp_dir("pipeline");
  std::ofstream(dir / "scene.yaml") << R"(
sensor: {preset: mb2250, r_min: 1, r_max: 4, range_bins: 40, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
objects:
  - {name: seabed, primitive: {type: terrain, size: [8, 6], cell: 0.1, relief: 0.1, rocks: 0, trenches: 0}}
  - {name: pipe, pipeline: {from: [-3, -1, 0.1], to: [3, 2, 0.1], radius: 0.2, burial: 0.5}}
  - {name: slab, primitive: {type: box, size: [1, 1, 0.2]}, kind: terrain}
trajectory: {type: straight, start: [0, 0, 2], end: [0.1, 0, 2], spacing: 0.05}
)";
  const SimulationSetup setup = load_simulation_setup((dir / "scene.yaml").string());
  ASSERT_EQ(setup.scene.objects.size(), 3u);
  EXPECT_EQ(setup.scene.objects[0].kind, ObjectKind::Terrain);
  EXPECT_EQ(setup.scene.objects[1].kind, ObjectKind::Pipeline);
  EXPECT_EQ(setup.scene.objects[2].kind, ObjectKind::Terrain);
  // Half buried: the axis on the seabed line, the top 0.2 m above it, the bottom 0.2 m below.
  const auto box = setup.scene.objects[1].mesh_world.bounding_box();
  EXPECT_NEAR(box.max().z(), 0.1 + 0.2, 1e-4);
  EXPECT_NEAR(box.min().z(), 0.1 - 0.2, 1e-4);
  const Eigen::Vector3f dir_xy = Eigen::Vector3f(6, 3, 0).normalized();
  float lo = 1e9f, hi = -1e9f;
  for (const auto& v : setup.scene.objects[1].mesh_world.vertices) {
    const float along = (v - Eigen::Vector3f(-3, -1, 0.1f)).dot(dir_xy);
    lo = std::min(lo, along);
    hi = std::max(hi, along);
  }
  EXPECT_NEAR(lo, 0.0, 1e-3);
  EXPECT_NEAR(hi, std::sqrt(45.0), 1e-3);
  simulate_dataset(setup, dir / "ds", false);
  const auto truth = read_truth(dir / "ds");
  ASSERT_EQ(truth.size(), 3u);
  EXPECT_EQ(truth[0].kind, ObjectKind::Terrain);
  EXPECT_EQ(truth[1].kind, ObjectKind::Pipeline);
  // Bad pipelines name the problem.
  auto check = [&](const std::string& object, const std::string& needle) {
    std::ofstream(dir / "bad.yaml", std::ios::trunc)
        << "sensor: {preset: sim-10deg}\nobjects: [" << object
        << "]\ntrajectory: {type: straight, start: [0,0,0], end: [0,0,0.1], spacing: 0.05}\n";
    expect_error([&] { load_simulation_setup((dir / "bad.yaml").string()); }, needle);
  };
  check("{name: p, pipeline: {from: [0,0,0], to: [0,0,0], radius: 0.1}}", "distinct");
  check("{name: p, pipeline: {from: [0,0,0], to: [1,0,0], radius: 0.1, burial: 1}}", "burial");
  check("{name: p, pipeline: {from: [0,0,0], to: [1,0,0], radius: -1}}", "radius");
  check(
      "{name: p, pipeline: {from: [0,0,0], to: [1,0,0], radius: 0.1}, pose: {translation: "
      "[1,0,0]}}",
      "no 'pose'");
  check("{name: p, reference: sphere, kind: rock}", "kind");
  // Found by fuzz_scene: a terrain of 6.8e93 m made the vertex count overflow the integer its
  // error message printed it as (undefined behaviour); now one error naming the count.
  check("{name: t, primitive: {type: terrain, size: [6.8e93, 6], cell: 0.2}}", "vertices");
}

TEST(SceneFile, BadScenesNameTheProblem) {
  const fs::path dir = temp_dir("badscene");
  auto check = [&](const std::string& text, const std::string& needle) {
    std::ofstream(dir / "s.yaml", std::ios::trunc) << text;
    expect_error([&] { load_simulation_setup((dir / "s.yaml").string()); }, needle);
  };
  const std::string traj =
      "trajectory: {type: straight, start: [0,0,0], end: [0,0,0.1], spacing: 0.05}\n";
  const std::string obj = "objects: [{name: a, reference: sphere}]\n";
  check("sensor: {preset: sim-10deg}\nobjects: []\n" + traj, "empty");
  check("sensor: {preset: sim-10deg}\n" + traj, "empty");
  check("sensor: {preset: sim-10deg, vertical_aperture_deg: 0}\n" + obj + traj,
        "vertical_aperture_deg");
  check("sensor: {preset: sim-10deg, vertical_aperture_deg: 180}\n" + obj + traj,
        "vertical_aperture_deg");
  check("sensor: {preset: sim-10deg, r_max: .nan}\n" + obj + traj, "r_max");
  check("sensor: {preset: sim-10deg}\nobjects: [{name: a, mesh: missing.dae}]\n" + traj,
        "missing.dae");
  check("sensor: {preset: sim-10deg}\n" + obj +
            "trajectory: {type: straight, start: [0,0,0], end: [0,0,1], spacing: -1}\n",
        "spacing");
  check("sensor: {preset: sim-10deg}\n" + obj + traj + "colour: red\n", "s.yaml:4: key 'colour'");
  check("sensor: {preset: sim-10deg}\n" + obj + "trajectory: {type: spiral}\n", "spiral");
  check("sensor: {preset: sim-10deg\n", "s.yaml:");
  check("sensor: {preset: sim-10deg}\nobjects: [{name: a, reference: sphere, reflectivity: 2}]\n" +
            traj,
        "reflectivity");
}
