// core: projector, beam pattern, sonar description, trajectories, point clouds.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;
namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;

TEST(Projector, RandomRoundTrips) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> r(0.1, 50), phi(-M_PI + 1e-3, M_PI - 1e-3),
      theta(-M_PI / 2 + 1e-3, M_PI / 2 - 1e-3);
  for (int k = 0; k < 10000; ++k) {
    const Polar p{r(rng), phi(rng), theta(rng)};
    const Polar q = sonar_to_polar(polar_to_sonar(p));
    ASSERT_NEAR(q.range, p.range, 1e-9);
    ASSERT_NEAR(q.bearing, p.bearing, 1e-9);
    ASSERT_NEAR(q.elevation, p.elevation, 1e-9);
  }
}

TEST(Projector, FrameConvention) {
  // +x boresight, bearing toward +y (left), elevation toward +z.
  EXPECT_TRUE(polar_to_sonar({2.0, 0, 0}).isApprox(Eigen::Vector3d(2, 0, 0)));
  EXPECT_TRUE(polar_to_sonar({1.0, M_PI / 2, 0}).isApprox(Eigen::Vector3d(0, 1, 0)));
  EXPECT_TRUE(polar_to_sonar({1.0, 0, M_PI / 2}).isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
}

TEST(BeamPattern, HalfPowerAtTheta3dB) {
  BeamPattern b;
  const double t3 = 5 * kDeg;
  EXPECT_NEAR(b.power(t3, t3), 0.5, 1e-4);  // eq. 2.8 with κ = 1.39156
  EXPECT_NEAR(b.power(-t3, t3), 0.5, 1e-4);
  EXPECT_DOUBLE_EQ(b.amplitude(0, t3), 1.0);
  b.kind = BeamPattern::Kind::Flat;
  EXPECT_EQ(b.amplitude(t3 * 0.99, t3), 1.0);
  EXPECT_EQ(b.amplitude(t3 * 1.01, t3), 0.0);
  b.kind = BeamPattern::Kind::Table;
  b.table_elevation_rad = {-0.1, 0.0, 0.1};
  b.table_amplitude = {0.0, 1.0, 0.0};
  EXPECT_NEAR(b.amplitude(0.05, t3), 0.5, 1e-12);
  EXPECT_EQ(b.amplitude(0.2, t3), 0.0);
}

TEST(SonarSpec, BinsAndBeams) {
  SonarSpec s;
  s.r_min = 1.0;
  s.r_max = 5.0;
  s.range_bins = 200;
  s.set_uniform_bearings(60 * kDeg, 300);
  s.validate();
  EXPECT_NEAR(s.range_resolution(), 0.02, 1e-12);
  EXPECT_NEAR(s.range_of_bin(0), 1.01, 1e-12);
  EXPECT_EQ(s.bin_of_range(1.0), 0);
  EXPECT_EQ(s.bin_of_range(1.0199), 0);
  EXPECT_EQ(s.bin_of_range(1.0201), 1);
  EXPECT_EQ(s.bin_of_range(0.99), -1);
  EXPECT_EQ(s.bin_of_range(5.0), -1);
  EXPECT_EQ(s.beam_of_bearing(-30 * kDeg), 0);
  EXPECT_EQ(s.beam_of_bearing(29.99 * kDeg), 299);
  EXPECT_EQ(s.beam_of_bearing(31 * kDeg), -1);
  EXPECT_NEAR(s.fov_min(), -30 * kDeg, 1e-12);
  // A non-uniform table: the nearest bearing owns the angle.
  SonarSpec t = s;
  t.bearings_rad = {-0.3, -0.1, 0.0, 0.05, 0.3};
  EXPECT_FALSE(t.uniform_bearings());
  EXPECT_EQ(t.beam_of_bearing(-0.21), 0);
  EXPECT_EQ(t.beam_of_bearing(-0.19), 1);
  EXPECT_EQ(t.beam_of_bearing(0.03), 3);
  EXPECT_EQ(t.beam_of_bearing(0.2), 4);
  EXPECT_EQ(t.beam_of_bearing(0.5), -1);
  for (double phi = -0.39; phi < 0.42; phi += 0.001) {
    const int j = t.beam_of_bearing(phi);
    if (j >= 0) {
      EXPECT_GE(phi, t.beam_edge_low(j) - 1e-12);
      EXPECT_LT(phi, t.beam_edge_high(j) + 1e-12);
    }
  }
}

TEST(SonarSpec, RejectsBadParameters) {
  const SonarSpec good = sonar_preset("sim-10deg");
  good.validate();
  auto expect_error = [](SonarSpec s, const std::string& needle) {
    try {
      s.validate();
      FAIL() << "expected an error mentioning " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  SonarSpec s = good;
  s.vertical_aperture_rad = 0;
  expect_error(s, "vertical_aperture_deg");
  s.vertical_aperture_rad = M_PI;
  expect_error(s, "vertical_aperture_deg");
  s.vertical_aperture_rad = std::nan("");
  expect_error(s, "vertical_aperture_deg");
  s = good;
  s.r_max = -1;
  expect_error(s, "r_max");
  s = good;
  s.r_max = s.r_min;
  expect_error(s, "r_max");
  s = good;
  s.range_bins = 0;
  expect_error(s, "range_bins");
  s = good;
  s.bearings_rad = {0.1, 0.0};
  expect_error(s, "increasing");
  s = good;
  s.bit_depth = 12;
  expect_error(s, "bit_depth");
  EXPECT_THROW(sonar_preset("nope"), Error);
  for (const auto& n : sonar_preset_names()) EXPECT_NO_THROW(sonar_preset(n).validate()) << n;
}

TEST(SonarSpec, PresetsFollowTheThesis) {
  const SonarSpec p = sonar_preset("p900-130");
  EXPECT_EQ(p.beams(), 768);
  EXPECT_NEAR(p.vertical_aperture_rad, 20 * kDeg, 1e-12);
  EXPECT_NEAR(p.range_resolution(), 0.025, 1e-12);
  EXPECT_NEAR(p.fov_max() - p.fov_min(), 130 * kDeg, 1e-9);
  const SonarSpec a = sonar_preset("aris3000");
  EXPECT_EQ(a.beams(), 128);
  EXPECT_EQ(a.range_bins, 341);
  EXPECT_NEAR(a.vertical_aperture_rad, 14 * kDeg, 1e-12);
  const SonarSpec s1 = sonar_preset("sim-1deg");
  EXPECT_NEAR(s1.range_resolution(), 0.02, 1e-12);
  EXPECT_NEAR(s1.bearings_rad[1] - s1.bearings_rad[0], 0.2 * kDeg, 1e-12);
}

static Eigen::Isometry3d random_pose(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 10;
  return T;
}

TEST(Trajectory, InterpolationHitsSamplesAndMidpoints) {
  std::mt19937_64 rng(7);
  Trajectory traj;
  for (int k = 0; k < 50; ++k) traj.push_back(0.5 * k + 0.01 * (k % 3), random_pose(rng));
  traj.validate();
  for (std::size_t k = 0; k < traj.size(); ++k) {
    EXPECT_TRUE(traj.interpolate(traj.times[k]).isApprox(traj.poses[k], 1e-9));
  }
  // Linear translation, slerp rotation: halfway between two samples.
  for (std::size_t k = 0; k + 1 < traj.size(); ++k) {
    const double t = 0.5 * (traj.times[k] + traj.times[k + 1]);
    const Eigen::Isometry3d T = traj.interpolate(t);
    EXPECT_TRUE(T.translation().isApprox(
        0.5 * (traj.poses[k].translation() + traj.poses[k + 1].translation()), 1e-9));
    const Eigen::Quaterniond q0(traj.poses[k].linear()), q1(traj.poses[k + 1].linear()),
        q(T.linear());
    EXPECT_NEAR(q.angularDistance(q0), q.angularDistance(q1), 1e-9);
    EXPECT_NEAR(q.angularDistance(q0) * 2, q0.angularDistance(q1), 1e-9);
  }
}

TEST(Trajectory, OutsideSpanIsAnError) {
  Trajectory traj;
  traj.push_back(1.0, Eigen::Isometry3d::Identity());
  traj.push_back(2.0, Eigen::Isometry3d::Identity());
  EXPECT_THROW(traj.interpolate(0.5), Error);
  EXPECT_THROW(traj.interpolate(2.5), Error);
  EXPECT_THROW(traj.interpolate(std::nan("")), Error);
  EXPECT_THROW(Trajectory().interpolate(0.0), Error);
  Eigen::Isometry3d bad = Eigen::Isometry3d::Identity();
  bad.linear() *= 2.0;
  traj.push_back(3.0, bad);
  EXPECT_THROW(traj.validate(), Error);
}

TEST(Trajectory, TumRoundTripAndErrors) {
  const fs::path dir = temp_dir("tum");
  std::mt19937_64 rng(3);
  Trajectory traj;
  for (int k = 0; k < 20; ++k) traj.push_back(100.0 + 0.1 * k, random_pose(rng));
  write_tum((dir / "a.tum").string(), traj);
  const Trajectory back = read_tum((dir / "a.tum").string());
  ASSERT_EQ(back.size(), traj.size());
  for (std::size_t k = 0; k < traj.size(); ++k) {
    EXPECT_NEAR(back.times[k], traj.times[k], 1e-12);
    EXPECT_TRUE(back.poses[k].isApprox(traj.poses[k], 1e-12));
  }
  auto expect_line_error = [&](const std::string& text, const std::string& needle) {
    std::ofstream(dir / "bad.tum") << text;
    try {
      read_tum((dir / "bad.tum").string());
      FAIL() << "expected an error for: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_line_error("# c\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0\n", "bad.tum:3");
  expect_line_error("0 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", "does not increase");
  expect_line_error("0 0 0 0 0 0 0 2\n", "not 1");
  expect_line_error("0 0 nan 0 0 0 0 1\n", "bad.tum:1");
  EXPECT_THROW(read_tum((dir / "missing.tum").string()), Error);
}

TEST(PointCloud, PlyRoundTripBinaryAndAscii) {
  const fs::path dir = temp_dir("ply");
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-5, 5);
  PointCloud c;
  for (int k = 0; k < 1000; ++k) {
    c.points.emplace_back(u(rng), u(rng), u(rng));
    c.intensity.push_back(std::abs(u(rng)));
  }
  for (auto fmt : {PlyFormat::Binary, PlyFormat::Ascii}) {
    const std::string p = (dir / "c.ply").string();
    write_ply(p, c, fmt);
    const PointCloud b = read_ply(p);
    ASSERT_EQ(b.size(), c.size());
    ASSERT_TRUE(b.has_intensity());
    for (std::size_t k = 0; k < c.size(); ++k) {
      EXPECT_TRUE(b.points[k].isApprox(c.points[k], 1e-6f));
      EXPECT_NEAR(b.intensity[k], c.intensity[k], 1e-5);
    }
  }
  // Truncated binary file: a clear error, not garbage.
  write_ply((dir / "t.ply").string(), c, PlyFormat::Binary);
  fs::resize_file(dir / "t.ply", fs::file_size(dir / "t.ply") - 100);
  EXPECT_THROW(read_ply((dir / "t.ply").string()), Error);
  std::ofstream(dir / "g.ply") << "not a ply\n";
  EXPECT_THROW(read_ply((dir / "g.ply").string()), Error);
  // Nothing half-written is left behind next to the outputs.
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos);
  }
}
