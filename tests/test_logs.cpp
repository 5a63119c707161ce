// Importers of sonar logs (issue 14): ARIS files and ROS 2 bags. Every format is written by our
// own writer from the published layout, imported back (bit-identical images, poses within
// 1e-6 m), reconstructed, and corrupted in the ways real files break.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <utility>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/ros_msgs.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::poke;
using sonar3d::test::read_all;
using sonar3d::test::run_cli_log;
using sonar3d::test::temp_dir;
using sonar3d::test::write_all;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;

// A simulated pass along a 1 m sphere: 8-bit images (the ARIS sample range), vehicle navigation
// given as NED values exactly representable in the ARIS header's float fields, and a mounting.
struct SimulatedPass {
  SonarSpec spec;
  std::vector<SonarImage> images;                   // quantised to v/255
  std::vector<double> times;                        // s
  std::vector<Eigen::Vector3d> ned;                 // north, east, depth
  std::vector<Eigen::Vector3d> roll_pitch_heading;  // degrees
  Trajectory nav;                                   // T_world_vehicle
  std::vector<Eigen::Isometry3d> T_world_sonar;
};

SimulatedPass simulate_pass(const SonarSpec& spec_in, int frames) {
  SimulatedPass p;
  p.spec = spec_in;
  p.spec.bit_depth = 8;
  p.spec.intensity_scale = 1.0 / 255.0;
  // The sonar looks forward and 5° down from 0.3 m ahead of and 0.5 m above the vehicle origin.
  p.spec.T_vehicle_sonar =
      vehicle_pose_from_nav(Eigen::Vector3d(0.3, 0.0, 0.5), 0, 5 * kDeg, 0, NavConvention::Enu);
  Scene scene;
  scene.objects.push_back({"sphere", make_sphere(0.5, 48), 0.8});
  SimulatorConfig cfg;
  cfg.elevation_step_rad = 0.05 * kDeg;
  const Simulator sim(scene, p.spec, cfg);
  for (int k = 0; k < frames; ++k) {
    // The sphere sits at the world origin; the vehicle heads east (heading 90°) 2.3 m west of
    // it at 0.35 m depth, moving north, and turns slowly.
    const double north = -0.5 + 1.0 * k / std::max(1, frames - 1);
    p.ned.emplace_back(static_cast<float>(north), static_cast<float>(-2.3),
                       static_cast<float>(0.35));
    p.roll_pitch_heading.emplace_back(static_cast<float>(1.5), static_cast<float>(-2.0),
                                      static_cast<float>(90.0 + 0.1 * k));
    const Eigen::Vector3d& a = p.roll_pitch_heading.back();
    const Eigen::Isometry3d T_world_vehicle = vehicle_pose_from_nav(
        p.ned.back(), a.x() * kDeg, a.y() * kDeg, a.z() * kDeg, NavConvention::Ned);
    p.times.push_back(1700000000.0 + 0.125 * k);
    p.nav.push_back(p.times.back(), T_world_vehicle);
    p.T_world_sonar.push_back(T_world_vehicle * p.spec.T_vehicle_sonar);
    SonarImage img = sim.render(p.T_world_sonar.back(), 1 + k);
    p.images.push_back(img);
  }
  float peak = 0;
  for (const auto& im : p.images)
    for (float v : im.data) peak = std::max(peak, v);
  EXPECT_GT(peak, 0.0f) << "the sphere must be seen";
  for (auto& im : p.images) {
    for (float& v : im.data) {
      v = static_cast<float>(std::min(255.0, std::round(v / peak * 255.0 * 1.5))) / 255.0f;
    }
  }
  return p;
}

// The simulated pass as a dataset of its own, read back: the images every import must reproduce
// bit for bit (they went through the same 8-bit encoding and reader).
std::vector<SonarImage> as_dataset_frames(const SimulatedPass& p, const fs::path& dir) {
  {
    DatasetWriter w(dir, p.spec);
    for (std::size_t k = 0; k < p.images.size(); ++k) {
      SonarImage img = p.images[k];
      img.timestamp = p.times[k];
      w.add_frame(img);
    }
    w.set_navigation(p.nav);
    w.commit();
  }
  const Dataset ds = read_dataset(dir);
  std::vector<SonarImage> out;
  for (std::size_t k = 0; k < ds.size(); ++k) out.push_back(ds.load_frame(k));
  return out;
}

// ---------------------------------------------------------------------------------------- ARIS

// An ARIS 1800 at 48 beams, 20 µs samples (1.5 cm at 1500 m/s) from 1.2 m.
ArisFrameHeader aris_header_1800() {
  ArisFrameHeader h;
  h.ping_mode = 1;  // 48 beams
  h.system_type = 0;
  h.large_lens = 0;
  h.sound_speed = 1500.0f;
  h.sample_period_us = 20;
  h.sample_start_delay_us = 1600;  // 1.2 m
  h.samples_per_beam = 120;        // 1.8 m window
  h.reordered_samples = 1;
  return h;
}

SonarSpec aris_spec_1800() { return aris_sonar_spec(aris_header_1800(), 48, "test"); }

std::vector<ArisWriteFrame> aris_frames(const SimulatedPass& p, bool with_nav) {
  std::vector<ArisWriteFrame> out;
  for (std::size_t k = 0; k < p.images.size(); ++k) {
    ArisWriteFrame f;
    f.header = aris_header_1800();
    f.header.frame_index = static_cast<std::uint32_t>(k);
    f.header.frame_time_us = static_cast<std::uint64_t>(std::llround(p.times[k] * 1e6));
    f.header.sonar_time_us = f.header.frame_time_us + 5000;
    if (with_nav) {
      const Eigen::Vector2d ll =
          geodetic_from_enu(Eigen::Vector2d(p.ned[k].y(), p.ned[k].x()), 47.6, -122.3);
      // Frame 0 is the origin of the local ENU frame: make its east/north zero by construction.
      f.header.latitude = ll.x();
      f.header.longitude = ll.y();
      f.header.depth = static_cast<float>(p.ned[k].z());
      f.header.roll = static_cast<float>(p.roll_pitch_heading[k].x());
      f.header.pitch = static_cast<float>(p.roll_pitch_heading[k].y());
      f.header.heading = static_cast<float>(p.roll_pitch_heading[k].z());
    }
    f.samples.resize(p.images[k].data.size());
    for (std::size_t i = 0; i < f.samples.size(); ++i) {
      f.samples[i] = static_cast<std::uint8_t>(std::lround(p.images[k].data[i] * 255.0f));
    }
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace

TEST(ArisTables, BearingsEqualSoundMetricsCurrentPublishedTables) {
  // Spot values of every lens and beam count, read from the current tables of Sound Metrics'
  // ARIS file SDK (approval files of SoundMetrics.Aris.BeamWidths.Tests): the outermost beams,
  // the two either side of the boresight and one in between. The telephoto 48-beam and ARIS 3000
  // tables are the revised ones (outer telephoto 48 beam at 7.339 deg, no longer 6.742).
  struct Case {
    ArisSystem s;
    bool tele;
    int beams;
    std::vector<std::pair<int, double>> published_deg;
  };
  const std::vector<std::pair<int, double>> std48 = {
      {0, -13.5735}, {23, -0.3461}, {24, 0.3461}, {36, 8.0899}, {47, 13.5735}};
  const std::vector<std::pair<int, double>> tele48 = {{0, -7.339}, {2, -6.744}, {23, -0.16},
                                                      {24, 0.16},  {37, 4.29},  {47, 7.339}};
  const std::vector<Case> cases = {
      {ArisSystem::Aris1800, false, 48, std48},
      {ArisSystem::Aris1200, false, 48, std48},
      {ArisSystem::Aris1800,
       false,
       96,
       {{0, -13.749}, {47, -0.1757}, {48, 0.1706}, {73, 8.315}, {95, 13.8759}}},
      {ArisSystem::Aris3000,
       false,
       64,
       {{0, -14.8872}, {31, -0.2389}, {32, 0.2389}, {47, 7.3742}, {63, 14.8872}}},
      {ArisSystem::Aris3000,
       false,
       128,
       {{0, -15.0068}, {63, -0.1196}, {64, 0.1194}, {100, 8.6812}, {127, 15.0156}}},
      {ArisSystem::Aris1800, true, 48, tele48},
      {ArisSystem::Aris1200, true, 48, tele48},
      {ArisSystem::Aris1800,
       true,
       96,
       {{0, -7.419}, {47, -0.08}, {48, 0.08}, {73, 4.055}, {95, 7.419}}}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(aris_system_name(c.s)) + (c.tele ? " telephoto " : " ") +
                 std::to_string(c.beams));
    const std::vector<double> b = aris_beam_bearings(c.s, c.tele, c.beams);
    ASSERT_EQ(static_cast<int>(b.size()), c.beams);
    for (const auto& [beam, deg] : c.published_deg) EXPECT_NEAR(b[beam], deg * kDeg, 1e-12);
    for (int j = 1; j < c.beams; ++j) EXPECT_GT(b[j], b[j - 1]);
    EXPECT_LT(std::abs(b.front() + b.back()), 0.2 * kDeg) << "centred on the boresight";
  }
  expect_error([] { aris_beam_bearings(ArisSystem::Aris1200, false, 96); }, "publishes no beam");
  EXPECT_EQ(aris_beams_of_ping_mode(1), 48);
  EXPECT_EQ(aris_beams_of_ping_mode(3), 96);
  EXPECT_EQ(aris_beams_of_ping_mode(6), 64);
  EXPECT_EQ(aris_beams_of_ping_mode(12), 128);
  EXPECT_EQ(aris_beams_of_ping_mode(13), 0);
  expect_error([] { aris_beam_bearings(ArisSystem::Aris3000, true, 128); }, "publishes no beam");
  EXPECT_NEAR(aris_vertical_aperture(ArisSystem::Aris3000, false), 14 * kDeg, 1e-12);
  EXPECT_NEAR(aris_vertical_aperture(ArisSystem::Aris1800, true), 3 * kDeg, 1e-12);
}

TEST(ArisTables, WindowFromTheHeaderPutsRowCentresOnSampleRanges) {
  const ArisFrameHeader h = aris_header_1800();
  const SonarSpec s = aris_spec_1800();
  const double c = 1500, dl = 20e-6 * c / 2, start = 1600e-6 * c / 2;
  EXPECT_EQ(s.range_bins, 120);
  EXPECT_EQ(s.beams(), 48);
  for (int i : {0, 1, 57, 119}) EXPECT_NEAR(s.range_of_bin(i), start + i * dl, 1e-12);
  EXPECT_NEAR(s.vertical_aperture_rad, 14 * kDeg, 1e-12);
  ArisFrameHeader bad = h;
  bad.sound_speed = 0;
  expect_error([&] { aris_sonar_spec(bad, 48, "here"); }, "here: SoundSpeed");
  bad = h;
  bad.sample_period_us = 0;
  expect_error([&] { aris_sonar_spec(bad, 48, "here"); }, "SamplePeriod");
}

TEST(ArisTables, GeodeticRoundTripIsSubMillimetreOverKilometres) {
  for (const Eigen::Vector2d& en : {Eigen::Vector2d(0, 0), Eigen::Vector2d(12.5, -3.25),
                                    Eigen::Vector2d(-1500, 2500), Eigen::Vector2d(8000, 9000)}) {
    const Eigen::Vector2d ll = geodetic_from_enu(en, 47.6, -122.3);
    EXPECT_LT((enu_from_geodetic(ll.x(), ll.y(), 47.6, -122.3) - en).norm(), 1e-8);
  }
  // One degree of latitude is ~111 km.
  EXPECT_NEAR(enu_from_geodetic(48.6, -122.3, 47.6, -122.3).y(), 111200, 300);
}

TEST(ArisImport, SimulatedPassRoundTripsThroughTheFrameHeaders) {
  const fs::path root = temp_dir("aris_roundtrip");
  const SimulatedPass p = simulate_pass(aris_spec_1800(), 6);
  write_aris(root / "pass.aris", aris_frames(p, true));
  EXPECT_EQ(fs::file_size(root / "pass.aris"), 1024u + 6 * (1024u + 48 * 120));

  ArisImportConfig cfg;
  cfg.mount = {0.3, 0, 0.5, 0, 5, 0};  // p.spec.T_vehicle_sonar
  const ArisImportResult r = import_aris(root / "pass.aris", root / "ds", cfg);
  EXPECT_EQ(r.frames, 6u);
  EXPECT_EQ(r.nav_source, ArisNavSource::Header);
  EXPECT_TRUE(r.warnings.empty());
  const Dataset ds = read_dataset(root / "ds");
  const std::vector<SonarImage> truth = as_dataset_frames(p, root / "simulated");
  ASSERT_EQ(ds.size(), 6u);
  EXPECT_EQ(ds.spec.bearings_rad, p.spec.bearings_rad);
  EXPECT_NEAR(ds.spec.r_min, p.spec.r_min, 1e-12);
  EXPECT_NEAR(ds.spec.r_max, p.spec.r_max, 1e-12);
  EXPECT_EQ(ds.spec.bit_depth, 8);
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const SonarImage img = ds.load_frame(k);
    ASSERT_EQ(img.data.size(), truth[k].data.size());
    EXPECT_EQ(std::memcmp(img.data.data(), truth[k].data.data(), img.data.size() * sizeof(float)),
              0)
        << "frame " << k << " is not bit-identical";
    EXPECT_NEAR(ds.frames[k].timestamp, p.times[k], 1e-6);
    // The local ENU frame is centred on frame 0's fix: compare relative to frame 0.
    const Eigen::Isometry3d got = ds.T_world_sonar(k);
    Eigen::Isometry3d want = p.T_world_sonar[k];
    want.translation() -= Eigen::Vector3d(p.ned[0].y(), p.ned[0].x(), 0);
    EXPECT_LT((got.translation() - want.translation()).norm(), 1e-6) << "frame " << k;
    EXPECT_LT((got.linear() - want.linear()).norm(), 1e-6) << "frame " << k;
  }
}

TEST(ArisImport, NavigationFileAndStaticSonar) {
  const fs::path root = temp_dir("aris_navfile");
  const SimulatedPass p = simulate_pass(aris_spec_1800(), 4);
  write_aris(root / "pass.aris", aris_frames(p, false));
  write_tum((root / "nav.tum").string(), p.nav);
  // Without navigation fields and without --nav: one clear error, nothing written.
  expect_error([&] { import_aris(root / "pass.aris", root / "ds0"); }, "no navigation");
  EXPECT_FALSE(fs::exists(root / "ds0"));

  ArisImportConfig cfg;
  cfg.navigation = root / "nav.tum";
  cfg.mount = {0.3, 0, 0.5, 0, 5, 0};  // p.spec.T_vehicle_sonar
  const ArisImportResult r = import_aris(root / "pass.aris", root / "ds", cfg);
  EXPECT_EQ(r.nav_source, ArisNavSource::File);
  const Dataset ds = read_dataset(root / "ds");
  for (std::size_t k = 0; k < ds.size(); ++k) {
    EXPECT_LT((ds.T_world_sonar(k).translation() - p.T_world_sonar[k].translation()).norm(), 1e-6);
  }
  // The sonar clock is 5 ms late: the last frame falls outside the navigation span.
  cfg.clock = ArisClock::Sonar;
  expect_error([&] { import_aris(root / "pass.aris", root / "ds2", cfg); }, "frame 3 at t = ");
  cfg.drop_outside = true;
  EXPECT_EQ(import_aris(root / "pass.aris", root / "ds2", cfg).dropped, 1u);

  ArisImportConfig fixed;
  fixed.nav_source = ArisNavSource::Static;
  import_aris(root / "pass.aris", root / "ds3", fixed);
  const Dataset d3 = read_dataset(root / "ds3");
  EXPECT_TRUE(d3.T_world_sonar(2).isApprox(Eigen::Isometry3d::Identity(), 1e-12));
}

namespace {

struct ArisFixture : ::testing::Test {
  fs::path root;
  std::string good;  // bytes of a valid 3-frame file
  const std::size_t frame_bytes = 1024 + 48 * 120;
  void SetUp() override {
    // One directory per test: ctest runs the tests of a fixture side by side.
    root = temp_dir(std::string("aris_bad_") +
                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    SimulatedPass p;
    p.spec = aris_spec_1800();
    std::vector<ArisWriteFrame> frames;
    for (int k = 0; k < 3; ++k) {
      ArisWriteFrame f;
      f.header = aris_header_1800();
      f.header.frame_time_us = 1000000u * (k + 1);
      f.samples.assign(48 * 120, static_cast<std::uint8_t>(10 * k));
      frames.push_back(f);
    }
    write_aris(root / "good.aris", frames);
    good = read_all(root / "good.aris");
  }
  std::size_t frame_at(int k) const { return 1024 + k * frame_bytes; }
  // Imports `bytes` (written as bad.aris) expecting one error mentioning every needle, and
  // nothing at the output.
  void expect_bad(const std::string& bytes, std::initializer_list<std::string> needles,
                  ArisImportConfig cfg = {}) {
    write_all(root / "bad.aris", bytes);
    if (cfg.nav_source == ArisNavSource::Auto) cfg.nav_source = ArisNavSource::Static;
    try {
      import_aris(root / "bad.aris", root / "out", cfg);
      ADD_FAILURE() << "expected an error";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find((root / "bad.aris").string()), std::string::npos) << what;
      for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << what;
    }
    EXPECT_FALSE(fs::exists(root / "out"));
  }
};

}  // namespace

TEST_F(ArisFixture, TheGoodFileImports) {
  ArisImportConfig cfg;
  cfg.nav_source = ArisNavSource::Static;
  EXPECT_EQ(import_aris(root / "good.aris", root / "ok", cfg).frames, 3u);
}

TEST_F(ArisFixture, ShorterThanTheFileHeader) { expect_bad(good.substr(0, 100), {"too short"}); }

TEST_F(ArisFixture, NoFrame) { expect_bad(good.substr(0, 1024), {"holds no frame"}); }

TEST_F(ArisFixture, WrongSignature) {
  std::string b = good;
  poke<std::uint32_t>(b, 0, 0x12345678u);
  expect_bad(b, {"offset 0", "not an ARIS file", "0x12345678"});
}

TEST_F(ArisFixture, DidsonIsNamed) {
  std::string b = good;
  poke<std::uint32_t>(b, 0, 0x04464444u);
  expect_bad(b, {"DIDSON", "DDF_04"});
}

TEST_F(ArisFixture, TruncatedInsideTheFirstFrame) {
  expect_bad(good.substr(0, 1024 + 1024 + 100), {"offset 1024", "truncated"});
}

TEST_F(ArisFixture, CutLastFrameFailsOrIsDropped) {
  const std::string cut = good.substr(0, frame_at(2) + 1500);
  expect_bad(cut, {"offset " + std::to_string(frame_at(2)), "partial frame", "--drop-partial"});
  ArisImportConfig cfg;
  cfg.nav_source = ArisNavSource::Static;
  cfg.drop_partial = true;
  const ArisImportResult r = import_aris(root / "bad.aris", root / "out", cfg);
  EXPECT_EQ(r.frames, 2u);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("partial frame"), std::string::npos);
}

TEST_F(ArisFixture, FrameCountDisagreeingWithTheSizeIsOnlyAWarning) {
  std::string b = good;
  poke<std::uint32_t>(b, 4, 4000000000u);
  write_all(root / "lie.aris", b);
  ArisImportConfig cfg;
  cfg.nav_source = ArisNavSource::Static;
  const ArisImportResult r = import_aris(root / "lie.aris", root / "out", cfg);
  EXPECT_EQ(r.frames, 3u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("4000000000"), std::string::npos);
}

TEST_F(ArisFixture, UnknownPingMode) {
  std::string b = good;
  poke<std::uint32_t>(b, 1024 + 436, 99u);
  expect_bad(b, {"offset 1460", "PingMode 99"});
}

TEST_F(ArisFixture, AbsurdSampleCountAllocatesNothing) {
  std::string b = good;
  poke<std::uint32_t>(b, 1024 + 468, 0xffffffffu);
  expect_bad(b, {"SamplesPerBeam 4294967295"});
  poke<std::uint32_t>(b, 1024 + 468, 60000u);  // allowed, but the file cannot hold it
  expect_bad(b, {"truncated"});
}

TEST_F(ArisFixture, LaterFrameLosesItsSignature) {
  std::string b = good;
  poke<std::uint32_t>(b, frame_at(2) + 12, 0u);
  expect_bad(b, {"offset " + std::to_string(frame_at(2) + 12), "frame 2", "signature"});
}

TEST_F(ArisFixture, LaterFrameChangesSize) {
  std::string b = good;
  poke<std::uint32_t>(b, frame_at(1) + 436, 3u);  // 96 beams
  expect_bad(b, {"frame 1", "PingMode 3"});
}

TEST_F(ArisFixture, WindowMoves) {
  std::string b = good;
  poke<std::uint32_t>(b, frame_at(2) + 476, 3000u);
  expect_bad(b, {"frame 2", "window moves"});
}

TEST_F(ArisFixture, TimeGoesBackwards) {
  std::string b = good;
  poke<std::uint64_t>(b, frame_at(2) + 4, 5u);
  expect_bad(b, {"frame 2", "goes backwards"});
}

TEST_F(ArisFixture, UnorderedSamples) {
  std::string b = good;
  poke<std::uint32_t>(b, frame_at(1) + 516, 0u);
  expect_bad(b, {"frame 1", "ReorderedSamples = 0"});
}

TEST_F(ArisFixture, BadSoundSpeedAndSystem) {
  std::string b = good;
  poke<float>(b, 1024 + 464, std::nanf(""));
  expect_bad(b, {"SoundSpeed"});
  b = good;
  poke<std::uint32_t>(b, 1024 + 484, 7u);
  expect_bad(b, {"TheSystemType 7"});
}

TEST_F(ArisFixture, HeaderNavigationMissingInOneFrame) {
  std::string b = good;
  for (int k = 0; k < 3; ++k) {
    poke<double>(b, frame_at(k) + 172, 47.0 + 1e-5 * k);
    poke<double>(b, frame_at(k) + 180, -122.0);
  }
  write_all(root / "nav.aris", b);
  EXPECT_TRUE(import_aris(root / "nav.aris", root / "navok").warnings.empty());
  EXPECT_EQ(read_dataset(root / "navok").size(), 3u);
  {
    // Platform attitude all zero but the sonar's compass turning: said, not guessed.
    std::string c = b;
    poke<float>(c, frame_at(1) + 160, 45.0f);
    write_all(root / "compass.aris", c);
    const ArisImportResult r = import_aris(root / "compass.aris", root / "compass");
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_NE(r.warnings[0].find("compass"), std::string::npos);
  }
  poke<double>(b, frame_at(1) + 172, 0.0);
  poke<double>(b, frame_at(1) + 180, 0.0);
  ArisImportConfig cfg;
  cfg.nav_source = ArisNavSource::Header;
  expect_bad(b, {"frame 1", "no position"}, cfg);
}

TEST_F(ArisFixture, NotAFile) {
  expect_error([&] { import_aris(root, root / "out"); }, "not a regular file");
  expect_error([&] { import_aris(root / "missing.aris", root / "out"); }, "not a regular file");
}

TEST(ArisMounting, ParsesSixNumbers) {
  const Eigen::Isometry3d T = parse_mounting("0.5, 0, -0.25, 0, 90, 0");
  EXPECT_NEAR(T.translation().x(), 0.5, 1e-15);
  EXPECT_NEAR(T.translation().z(), -0.25, 1e-15);
  EXPECT_NEAR((T.linear() * Eigen::Vector3d::UnitX()).z(), -1.0, 1e-12) << "pitch 90° looks down";
  expect_error([] { parse_mounting("1,2,3"); }, "expected 6 numbers");
  expect_error([] { parse_mounting("1,2,3,4,5,x"); }, "'x' is not a number");
  expect_error([] { parse_mounting("1e300,2,3,4,5,6"); }, "offset beyond");
}

TEST(ArisCli, ImportAndReconstruct) {
  const fs::path root = temp_dir("aris_cli");
  const SimulatedPass p = simulate_pass(aris_spec_1800(), 41);
  write_aris(root / "pass.aris", aris_frames(p, true));
  const fs::path log = root / "log.txt";
  ASSERT_EQ(run_cli_log("import aris " + (root / "pass.aris").string() + " -o " +
                            (root / "ds").string() + " --mount 0.3,0,0.5,0,5,0 -q",
                        log),
            0)
      << read_all(log);
  EXPECT_NE(read_all(log).find("imported 41 frames (120 samples × 48 beams, aris-1800)"),
            std::string::npos)
      << read_all(log);
  EXPECT_NE(read_all(log).find("poses: frame headers"), std::string::npos) << read_all(log);
  const Dataset ds = read_dataset(root / "ds");
  for (std::size_t k = 0; k < ds.size(); k += 10) {
    EXPECT_TRUE(ds.T_world_sonar(k).linear().isApprox(p.T_world_sonar[k].linear(), 1e-6));
  }
  // Refuses to overwrite what it did not write; a bad file fails with one line.
  fs::create_directories(root / "precious");
  write_all(root / "precious/data.txt", "mine");
  EXPECT_EQ(run_cli_log("import aris " + (root / "pass.aris").string() + " -o " +
                            (root / "precious").string() + " -q",
                        log),
            1);
  EXPECT_EQ(read_all(root / "precious/data.txt"), "mine");
  std::string bytes = read_all(root / "pass.aris");
  write_all(root / "cut.aris", bytes.substr(0, bytes.size() - 10));
  EXPECT_EQ(run_cli_log("import aris " + (root / "cut.aris").string() + " -o " +
                            (root / "ds_cut").string() + " -q",
                        log),
            1);
  EXPECT_NE(read_all(log).find("sonar3d: error: " + (root / "cut.aris").string()),
            std::string::npos)
      << read_all(log);
  EXPECT_FALSE(fs::exists(root / "ds_cut"));

  // A reconstruction runs on the import and finds the sphere (the local ENU origin is frame 0's
  // fix, so the sphere sits at −(east, north) of frame 0).
  const fs::path ply = root / "cloud.ply";
  ASSERT_EQ(run_cli_log("reconstruct " + (root / "ds").string() + " --voxel-size 0.03 -o " +
                            ply.string() + " -q",
                        log),
            0)
      << read_all(log);
  PointCloud cloud = read_ply(ply.string());
  ASSERT_GT(cloud.size(), 50u);
  const Eigen::Vector3d centre(-p.ned[0].y(), -p.ned[0].x(), 0);
  std::vector<double> d;
  for (const auto& q : cloud.points)
    d.push_back(std::abs((q.cast<double>() - centre).norm() - 0.5));
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  EXPECT_LT(d[d.size() / 2], 0.08) << "median distance of the carved points to the sphere";
}

// ------------------------------------------------------------------------------------ ROS bags

namespace {

// A simulated pass written as a dataset with `bits` = 8, 16 or 32 (float TIFF), and its frames
// read back.
struct PassDataset {
  SimulatedPass pass;
  std::vector<SonarImage> frames;
};

PassDataset pass_dataset(const fs::path& dir, int bits, int frames = 5) {
  SonarSpec spec;
  spec.name = "sim";
  spec.set_uniform_bearings(30 * kDeg, 40);
  spec.r_min = 1.0;
  spec.r_max = 3.0;
  spec.range_bins = 90;
  spec.vertical_aperture_rad = 12 * kDeg;
  PassDataset d{simulate_pass(spec, frames), {}};
  SimulatedPass& p = d.pass;
  if (bits == 16) {
    p.spec.bit_depth = 16;
    p.spec.intensity_scale = 1.0 / 65535.0;
  }
  {
    DatasetWriter w(
        dir, p.spec,
        bits == 32 ? DatasetWriter::ImageFormat::Tiff : DatasetWriter::ImageFormat::Png);
    for (std::size_t k = 0; k < p.images.size(); ++k) {
      SonarImage img = p.images[k];
      if (bits != 8) {
        for (std::size_t i = 0; i < img.data.size(); ++i) img.data[i] *= 0.37f + 0.001f * (i % 7);
      }
      img.timestamp = p.times[k];
      w.add_frame(img);
    }
    w.set_navigation(p.nav);
    w.commit();
  }
  const Dataset ds = read_dataset(dir);
  for (std::size_t k = 0; k < ds.size(); ++k) d.frames.push_back(ds.load_frame(k));
  return d;
}

void expect_same_dataset(const fs::path& imported, const PassDataset& d, bool tiff = false) {
  const Dataset ds = read_dataset(imported);
  const SimulatedPass& p = d.pass;
  ASSERT_EQ(ds.size(), d.frames.size());
  EXPECT_EQ(ds.spec.range_bins, p.spec.range_bins);
  ASSERT_EQ(ds.spec.beams(), p.spec.beams());
  for (int j = 0; j < p.spec.beams(); ++j) {
    EXPECT_NEAR(ds.spec.bearings_rad[j], p.spec.bearings_rad[j], 1e-9);
  }
  EXPECT_NEAR(ds.spec.r_min, p.spec.r_min, 1e-6);
  EXPECT_NEAR(ds.spec.r_max, p.spec.r_max, 1e-6);
  EXPECT_NEAR(ds.spec.vertical_aperture_rad, p.spec.vertical_aperture_rad, 1e-6);
  if (!tiff) {
    EXPECT_EQ(ds.spec.bit_depth, p.spec.bit_depth);
  }
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const SonarImage img = ds.load_frame(k);
    ASSERT_EQ(img.data.size(), d.frames[k].data.size());
    EXPECT_EQ(std::memcmp(img.data.data(), d.frames[k].data.data(), img.data.size() * 4), 0)
        << "frame " << k << " is not bit-identical";
    EXPECT_NEAR(ds.frames[k].timestamp, p.times[k], 1e-6);
    EXPECT_LT((ds.T_world_sonar(k).translation() - p.T_world_sonar[k].translation()).norm(), 1e-6)
        << "frame " << k;
    EXPECT_LT((ds.T_world_sonar(k).linear() - p.T_world_sonar[k].linear()).norm(), 1e-6);
  }
}

}  // namespace

TEST(RosMessages, EveryMessageRoundTripsOnBothWires) {
  for (RosWire wire : {RosWire::Cdr, RosWire::Ros1}) {
    RosSonarImage m;
    m.stamp = RosTime::from_seconds(1700000000.125);
    m.frame_id = "oculus";
    m.frequency = 1.2e6f;
    m.sound_speed = 1500;
    m.tx_beamwidths = {0.3f, 0.3f};
    m.rx_beamwidths = {0.01f, 0.01f};
    m.beam_directions = {Eigen::Vector3d(0, 0.1, 0.99), Eigen::Vector3d(0, -0.1, 0.99)};
    m.ranges = {1.0f, 1.5f, 2.0f};
    m.dtype = kRosDtypeUint16;
    m.beam_count = 2;
    m.data = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    const auto bytes = encode_sonar_image(m, wire);
    const RosSonarImage r = decode_sonar_image(bytes.data(), bytes.size(), wire, "x");
    EXPECT_EQ(r.stamp.ns(), m.stamp.ns());
    EXPECT_EQ(r.frame_id, "oculus");
    EXPECT_EQ(r.tx_beamwidths, m.tx_beamwidths);
    EXPECT_EQ(r.beam_directions, m.beam_directions);
    EXPECT_EQ(r.ranges, m.ranges);
    EXPECT_EQ(r.data, m.data);
    EXPECT_EQ(r.dtype, kRosDtypeUint16);
    // Every truncation is one Error naming the message, never a crash or a wild allocation.
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      expect_error([&] { decode_sonar_image(bytes.data(), n, wire, "msg 7"); }, "msg 7: byte");
    }
    RosPose pose;
    pose.stamp = RosTime::from_seconds(12.5);
    pose.frame_id = "map";
    pose.child_frame_id = "base_link";
    pose.position = Eigen::Vector3d(1, 2, 3);
    pose.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
    for (const auto& [type, b] :
         {std::make_pair(std::string("nav_msgs/msg/Odometry"), encode_odometry(pose, wire)),
          std::make_pair(std::string("geometry_msgs/PoseStamped"),
                         encode_pose_stamped(pose, wire))}) {
      const RosPose q = decode_pose(type, b.data(), b.size(), wire, "p");
      EXPECT_EQ(q.position, pose.position);
      EXPECT_NEAR(q.orientation.angularDistance(pose.orientation), 0, 1e-12);
      EXPECT_EQ(q.stamp.ns(), 12500000000LL);
    }
    RosTransform t;
    t.parent = "base_link";
    t.child = "sonar";
    t.translation = Eigen::Vector3d(0.1, 0.2, 0.3);
    const auto tb = encode_tf({t, t}, wire);
    const auto ts = decode_tf(tb.data(), tb.size(), wire, "tf");
    ASSERT_EQ(ts.size(), 2u);
    EXPECT_EQ(ts[1].child, "sonar");
    EXPECT_EQ(ts[1].translation, t.translation);
  }
}

TEST(RosMessages, HostileCountsAndEncodingsAreNamed) {
  RosSonarImage m;
  m.ranges = {1.0f};
  auto b = encode_sonar_image(m, RosWire::Cdr);
  // The beam_directions count (after header, ping_info) claims 2^32 − 1 entries.
  std::vector<std::uint8_t> bad = b;
  const std::size_t at = 4 + 8 + 4 + 4 + 4 + 4 + 4;  // stamp, frame_id "" (len 1 + pad), …
  (void)at;
  RosTransform t;
  auto tf = encode_tf({t}, RosWire::Cdr);
  tf[4] = tf[5] = tf[6] = tf[7] = 0xff;
  expect_error([&] { decode_tf(tf.data(), tf.size(), RosWire::Cdr, "tf 3"); },
               "claims 4294967295 elements");
  bad[1] = 0x00;  // big-endian CDR
  expect_error([&] { decode_sonar_image(bad.data(), bad.size(), RosWire::Cdr, "m"); },
               "big-endian CDR");
  bad[0] = 0x07;
  expect_error([&] { decode_sonar_image(bad.data(), bad.size(), RosWire::Cdr, "m"); },
               "unknown CDR encapsulation");
  RosPose pose;
  pose.orientation.coeffs() << 0, 0, 0, 2;
  auto pb = encode_pose_stamped(pose, RosWire::Cdr);
  expect_error(
      [&] {
        decode_pose("geometry_msgs/PoseStamped", pb.data(), pb.size(), RosWire::Cdr, "nav 2");
      },
      "not a unit quaternion");
  expect_error([&] { decode_pose("std_msgs/String", pb.data(), pb.size(), RosWire::Cdr, "n"); },
               "not a navigation message");
}

class RosbagRoundTrip : public ::testing::TestWithParam<std::tuple<RosWire, int>> {};

TEST_P(RosbagRoundTrip, SimulatedDatasetSurvivesExportAndImport) {
  const auto [wire, bits] = GetParam();
  const fs::path root =
      temp_dir(std::string(wire == RosWire::Cdr ? "ros2_" : "ros1_") + std::to_string(bits));
  const PassDataset d = pass_dataset(root / "sim", bits);
  RosbagExportConfig ec;
  ec.wire = wire;
  const fs::path bag = root / (wire == RosWire::Cdr ? "bag" : "sim.bag");
  const RosbagExportResult er = export_rosbag(root / "sim", bag, ec);
  EXPECT_EQ(er.frames, d.frames.size());
  EXPECT_EQ(er.navigation_samples, d.pass.nav.size());
  if (wire == RosWire::Cdr) {
    EXPECT_TRUE(fs::exists(bag / "metadata.yaml"));
    EXPECT_TRUE(fs::exists(bag / "bag_0.db3"));
  }
  const std::unique_ptr<BagReader> reader = BagReader::open(bag);
  ASSERT_NE(reader->find("/sonar3d/image"), nullptr);
  EXPECT_EQ(reader->find("/sonar3d/image")->messages, d.frames.size());
  EXPECT_EQ(ros_type_name(reader->find("/sonar3d/image")->type),
            "marine_acoustic_msgs/ProjectedSonarImage");

  RosbagImportConfig ic;
  ic.sonar_topic = "/sonar3d/image";
  ic.nav_topic = "/sonar3d/odom";
  const RosbagImportResult r = import_rosbag(bag, root / "ds", ic);
  EXPECT_EQ(r.frames, d.frames.size());
  EXPECT_EQ(r.mounting_source, "/tf_static: base_link -> sonar");
  expect_same_dataset(root / "ds", d, bits == 32);
}

TEST(RosbagCompressed, Ros1ChunksInBz2AndLz4) {
  const fs::path root = temp_dir("ros1_compressed");
  const PassDataset d = pass_dataset(root / "sim", 16, 4);
  for (const std::string c : {"bz2", "lz4"}) {
    RosbagExportConfig ec;
    ec.wire = RosWire::Ros1;
    ec.ros1_compression = c;
    export_rosbag(root / "sim", root / (c + ".bag"), ec);
    const std::string bytes = read_all(root / (c + ".bag"));
    EXPECT_NE(bytes.find("compression=" + c), std::string::npos);
    if (c == "lz4") {
      // ROS 1's roslz4 reads only independent blocks with a content checksum, no content size,
      // no block checksums, blocks of 64 KB–4 MB (tests/test_rosbag_debian.py reads the bag with
      // it): the frame descriptor after the magic 04 22 4d 18 must say so.
      const std::size_t f = bytes.find("\x04\x22\x4d\x18");
      ASSERT_NE(f, std::string::npos);
      const auto flg = static_cast<unsigned char>(bytes[f + 4]);
      const auto bd = static_cast<unsigned char>(bytes[f + 5]);
      EXPECT_EQ(flg, 0x64) << "version 1, independent blocks, content checksum";
      EXPECT_GE((bd >> 4) & 7, 4);
    }
    RosbagImportConfig ic;
    ic.sonar_topic = "/sonar3d/image";
    ic.nav_topic = "/sonar3d/odom";
    import_rosbag(root / (c + ".bag"), root / ("ds_" + c), ic);
    expect_same_dataset(root / ("ds_" + c), d);
    // A corrupted compressed chunk is one error naming the offset.
    std::string bad = bytes;
    const std::size_t at = bad.find("compression=" + c);
    for (std::size_t k = 0; k < 64; ++k) bad[at + 400 + k] = static_cast<char>(k * 37);
    write_all(root / ("bad_" + c + ".bag"), bad);
    expect_error([&] { import_rosbag(root / ("bad_" + c + ".bag"), root / "out", ic); },
                 "chunk does not decompress");
    EXPECT_FALSE(fs::exists(root / "out"));
  }
}

INSTANTIATE_TEST_SUITE_P(Wires, RosbagRoundTrip,
                         ::testing::Combine(::testing::Values(RosWire::Cdr, RosWire::Ros1),
                                            ::testing::Values(8, 16, 32)));

TEST(RosbagImport, PredecessorPackageImageTopicAndPoseStamped) {
  const fs::path root = temp_dir("rosbag_variants");
  const PassDataset d = pass_dataset(root / "sim", 16, 4);
  const SimulatedPass& p = d.pass;
  // acoustic_msgs/ProjectedSonarImage, navigation as PoseStamped, mounting given on the command
  // line.
  RosbagExportConfig ec;
  ec.message_package = "acoustic_msgs";
  export_rosbag(root / "sim", root / "old", ec);
  {
    // Rewrite the navigation as PoseStamped into a second bag with the same sonar messages.
    const auto reader = BagReader::open(root / "old");
    std::vector<BagOutMessage> msgs;
    reader->read("/sonar3d/image",
                 [&](std::int64_t t, const std::uint8_t* b, std::size_t n, const std::string&) {
                   msgs.push_back({0, t, std::vector<std::uint8_t>(b, b + n)});
                 });
    for (std::size_t k = 0; k < p.nav.size(); ++k) {
      RosPose pose;
      pose.stamp = RosTime::from_seconds(p.nav.times[k]);
      pose.frame_id = "map";
      pose.position = p.nav.poses[k].translation();
      pose.orientation = Eigen::Quaterniond(p.nav.poses[k].linear());
      msgs.push_back({1, pose.stamp.ns(), encode_pose_stamped(pose, RosWire::Cdr)});
    }
    // sensor_msgs/Image of the same frames (16-bit, rows = range bins).
    for (std::size_t k = 0; k < d.frames.size(); ++k) {
      RosImage im;
      im.stamp = RosTime::from_seconds(p.times[k]);
      im.frame_id = "sonar_flu";
      im.height = static_cast<std::uint32_t>(d.frames[k].rows);
      im.width = static_cast<std::uint32_t>(d.frames[k].cols);
      im.encoding = "mono16";
      im.step = im.width * 2;
      for (float v : d.frames[k].data) {
        const auto q = static_cast<std::uint16_t>(std::lround(v * 65535.0));
        im.data.push_back(static_cast<std::uint8_t>(q & 0xff));
        im.data.push_back(static_cast<std::uint8_t>(q >> 8));
      }
      msgs.push_back({2, im.stamp.ns(), encode_image(im, RosWire::Cdr)});
    }
    write_bag(root / "posestamped", RosWire::Cdr,
              {{"/sonar", "acoustic_msgs/msg/ProjectedSonarImage"},
               {"/pose", "geometry_msgs/msg/PoseStamped"},
               {"/image", "sensor_msgs/msg/Image"}},
              msgs);
  }
  RosbagImportConfig ic;
  ic.sonar_topic = "/sonar";
  ic.nav_topic = "/pose";
  ic.mount = {0.3, 0, 0.5, 0, 5, 0};  // p.spec.T_vehicle_sonar
  const RosbagImportResult r = import_rosbag(root / "posestamped", root / "ds", ic);
  EXPECT_EQ(r.sonar_type, "acoustic_msgs/msg/ProjectedSonarImage");
  EXPECT_EQ(r.mounting_source, "--mount");
  expect_same_dataset(root / "ds", d);

  // sensor_msgs/Image needs the sonar description; with it the frames are the same.
  ic.sonar_topic = "/image";
  expect_error([&] { import_rosbag(root / "posestamped", root / "ds_img", ic); },
               "give its description (--sonar");
  EXPECT_FALSE(fs::exists(root / "ds_img"));
  ic.sonar_description = root / "sim" / "sonar.yaml";
  import_rosbag(root / "posestamped", root / "ds_img", ic);
  expect_same_dataset(root / "ds_img", d);
}

TEST(RosbagImport, SplitRos2BagReadsItsFilesInOrder) {
  // `ros2 bag record --max-bag-size` splits a recording over several .db3 files listed in
  // metadata.yaml; topic ids may differ between the files.
  const fs::path root = temp_dir("rosbag_split");
  const PassDataset d = pass_dataset(root / "sim", 16, 6);
  export_rosbag(root / "sim", root / "whole", {});
  const auto reader = BagReader::open(root / "whole");
  std::vector<BagOutMessage> first, second;
  std::vector<BagOutTopic> topics;
  for (const auto& t : reader->topics()) {
    topics.push_back({t.name, t.type, t.name == "/tf_static"});
  }
  for (std::size_t k = 0; k < topics.size(); ++k) {
    std::size_t n = 0;
    reader->read(topics[k].name,
                 [&](std::int64_t ts, const std::uint8_t* b, std::size_t size, const std::string&) {
                   // Topic ids of the second file are reversed.
                   BagOutMessage m{static_cast<int>(k), ts, std::vector<std::uint8_t>(b, b + size)};
                   if (topics[k].name == "/tf_static" || n++ < 3) {
                     first.push_back(m);
                   } else {
                     m.topic = static_cast<int>(topics.size() - 1 - k);
                     second.push_back(m);
                   }
                 });
  }
  std::vector<BagOutTopic> reversed(topics.rbegin(), topics.rend());
  write_bag(root / "p0", RosWire::Cdr, topics, first);
  write_bag(root / "p1", RosWire::Cdr, reversed, second);
  fs::create_directories(root / "split");
  fs::copy_file(root / "p0/p0_0.db3", root / "split/split_0.db3");
  fs::copy_file(root / "p1/p1_0.db3", root / "split/split_1.db3");
  std::string meta = read_all(root / "whole/metadata.yaml");
  const std::size_t at = meta.find("  relative_file_paths:");
  ASSERT_NE(at, std::string::npos);
  meta = meta.substr(0, at) + "  relative_file_paths:\n    - split_0.db3\n    - split_1.db3\n";
  write_all(root / "split/metadata.yaml", meta);
  const auto split = BagReader::open(root / "split");
  EXPECT_EQ(split->find("/sonar3d/image")->messages, 6u);
  RosbagImportConfig ic;
  ic.sonar_topic = "/sonar3d/image";
  ic.nav_topic = "/sonar3d/odom";
  import_rosbag(root / "split", root / "ds", ic);
  expect_same_dataset(root / "ds", d);
  // A file the metadata names but that is missing: one error naming it.
  fs::remove(root / "split/split_1.db3");
  expect_error([&] { import_rosbag(root / "split", root / "ds2", ic); }, "split_1.db3");
  EXPECT_FALSE(fs::exists(root / "ds2"));
}

namespace {

struct BagFixture : ::testing::Test {
  fs::path root;
  PassDataset d;
  void SetUp() override {
    root = temp_dir(std::string("rosbag_bad_") +
                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    d = pass_dataset(root / "sim", 8, 3);
    export_rosbag(root / "sim", root / "bag", {});
    RosbagExportConfig e1;
    e1.wire = RosWire::Ros1;
    export_rosbag(root / "sim", root / "sim.bag", e1);
  }
  RosbagImportConfig cfg() const {
    RosbagImportConfig c;
    c.sonar_topic = "/sonar3d/image";
    c.nav_topic = "/sonar3d/odom";
    return c;
  }
  void expect_bad(const fs::path& bag, const RosbagImportConfig& c,
                  std::initializer_list<std::string> needles) {
    try {
      import_rosbag(bag, root / "out", c);
      ADD_FAILURE() << "expected an error";
    } catch (const Error& e) {
      for (const auto& n : needles)
        EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(root / "out"));
  }
  // A copy of the ROS 2 bag whose sonar messages are replaced by `mutate(bytes)`.
  fs::path mutated_ros2(const std::string& name,
                        const std::function<void(std::vector<std::uint8_t>&)>& mutate) {
    const auto reader = BagReader::open(root / "bag");
    std::vector<BagOutTopic> topics;
    std::vector<BagOutMessage> msgs;
    int k = 0;
    for (const auto& t : reader->topics()) {
      topics.push_back({t.name, t.type, t.name == "/tf_static"});
      reader->read(t.name,
                   [&](std::int64_t ts, const std::uint8_t* b, std::size_t n, const std::string&) {
                     std::vector<std::uint8_t> bytes(b, b + n);
                     if (t.name == "/sonar3d/image") mutate(bytes);
                     msgs.push_back({k, ts, bytes});
                   });
      ++k;
    }
    write_bag(root / name, RosWire::Cdr, topics, msgs);
    return root / name;
  }
};

}  // namespace

TEST_F(BagFixture, MissingAndWronglyTypedTopics) {
  RosbagImportConfig c = cfg();
  c.sonar_topic = "/nope";
  expect_bad(root / "bag", c, {"no topic '/nope'", "/sonar3d/image (marine_acoustic_msgs"});
  c = cfg();
  c.sonar_topic = "/sonar3d/odom";
  expect_bad(root / "bag", c, {"'/sonar3d/odom' is of type nav_msgs/msg/Odometry"});
  c = cfg();
  c.nav_topic = "/sonar3d/image";
  expect_bad(root / "sim.bag", c, {"is of type marine_acoustic_msgs/ProjectedSonarImage"});
  c = cfg();
  c.nav_topic = "";
  expect_error([&] { import_rosbag(root / "bag", root / "out", c); }, "--nav-topic");
  c.static_sonar = true;
  EXPECT_EQ(import_rosbag(root / "bag", root / "static", c).frames, 3u);
}

// Topics left out are found by message type (sonar3d survey, import rosbag without
// --sonar-topic/--nav-topic); named ones are kept.
TEST_F(BagFixture, TopicsFoundByMessageType) {
  for (const std::string bag : {"bag", "sim.bag"}) {
    RosbagImportConfig c;
    const std::vector<std::string> lines = choose_rosbag_topics(root / bag, c);
    EXPECT_EQ(c.sonar_topic, "/sonar3d/image") << bag;
    EXPECT_EQ(c.nav_topic, "/sonar3d/odom") << bag;
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_NE(lines[0].find("sonar topic /sonar3d/image (by type"), std::string::npos) << lines[0];
    EXPECT_EQ(import_rosbag(root / bag, root / ("by_type_" + bag), c).frames, 3u);
  }
  RosbagImportConfig c;
  c.sonar_topic = "/mine";
  c.static_sonar = true;
  EXPECT_TRUE(choose_rosbag_topics(root / "bag", c).empty());
  EXPECT_EQ(c.sonar_topic, "/mine");
}

TEST_F(BagFixture, TruncatedAndCorruptMessages) {
  const fs::path cut =
      mutated_ros2("cut", [](std::vector<std::uint8_t>& b) { b.resize(b.size() / 2); });
  expect_bad(cut, cfg(), {"cut_0.db3: /sonar3d/image message 0", ": byte ", "left"});
  const fs::path dtype = mutated_ros2("dtype", [](std::vector<std::uint8_t>& b) {
    // image.dtype sits before beam_count and the data sequence at the end.
    const std::size_t n = b.size();
    const std::size_t data_len = 90 * 40;
    b[n - data_len - 4 - 4 - 4] = 9;  // float64
  });
  expect_bad(dtype, cfg(), {"message 0", "image.dtype 9 (float64) is not read"});
  const fs::path huge = mutated_ros2("huge", [](std::vector<std::uint8_t>& b) {
    const std::size_t n = b.size();
    const std::size_t data_len = 90 * 40;
    std::uint32_t c = 0xfffffff0u;
    std::memcpy(&b[n - data_len - 4], &c, 4);
  });
  expect_bad(huge, cfg(), {"image.data claims 4294967280 elements"});
}

TEST_F(BagFixture, BrokenRos2Storage) {
  // Not a database, a truncated database, a metadata.yaml pointing outside, MCAP, compression.
  fs::create_directories(root / "garbage");
  write_all(root / "garbage/x.db3", std::string(5000, 'x'));
  expect_bad(root / "garbage", cfg(), {"x.db3", "not an sqlite3 database"});
  fs::create_directories(root / "trunc");
  const std::string db = read_all(root / "bag/bag_0.db3");
  write_all(root / "trunc/t.db3", db.substr(0, db.size() / 3));
  expect_bad(root / "trunc", cfg(), {"t.db3"});
  fs::copy(root / "bag", root / "escape", fs::copy_options::recursive);
  std::string meta = read_all(root / "escape/metadata.yaml");
  meta.replace(meta.find("    - bag_0.db3"), 15, "    - ../bag/bag_0.db3");
  write_all(root / "escape/metadata.yaml", meta);
  expect_bad(root / "escape", cfg(), {"metadata.yaml", "is not a file name inside the bag"});
  std::string m2 = read_all(root / "bag/metadata.yaml");
  fs::copy(root / "bag", root / "mcap", fs::copy_options::recursive);
  write_all(root / "mcap/metadata.yaml",
            std::string(m2).replace(m2.find("storage_identifier: sqlite3"), 27,
                                    "storage_identifier: mcap"));
  expect_bad(root / "mcap", cfg(), {"storage 'mcap' is not read", "ros2 bag convert"});
  fs::copy(root / "bag", root / "zstd", fs::copy_options::recursive);
  write_all(
      root / "zstd/metadata.yaml",
      std::string(m2).replace(m2.find("compression_format: \"\""), 22, "compression_format: zstd"));
  expect_bad(root / "zstd", cfg(), {"compressed bags ('zstd')"});
  expect_bad(root / "does-not-exist", cfg(), {"does not exist"});
}

TEST_F(BagFixture, BrokenRos1Files) {
  const std::string good = read_all(root / "sim.bag");
  write_all(root / "cut.bag", good.substr(0, good.size() - 100));
  expect_bad(root / "cut.bag", cfg(), {"cut.bag (offset", "truncated"});
  std::string b = good;
  b[8] = '1';  // "#ROSBAG V1.0"
  write_all(root / "v1.bag", b);
  expect_bad(root / "v1.bag", cfg(), {"other than 2.0"});
  // The first chunk claims 3 GB uncompressed.
  b = good;
  const std::size_t at = b.find("size=", 13 + 4096);
  ASSERT_NE(at, std::string::npos);
  poke<std::uint32_t>(b, at + 5, 3000000000u);
  write_all(root / "big.bag", b);
  expect_bad(root / "big.bag", cfg(), {"claims 3000000000 bytes uncompressed"});
  b = good;
  const std::size_t comp = b.find("compression=none");
  b.replace(comp + 12, 4, "bz2\0", 4);
  b[comp - 4] = static_cast<char>(b[comp - 4] - 0);  // same length: "bz2\0" keeps the field size
  write_all(root / "bz2.bag", b);
  expect_bad(root / "bz2.bag", cfg(), {"chunk compression"});
}

namespace {
std::size_t mapped_regions() {
  std::ifstream f("/proc/self/maps");
  std::size_t n = 0;
  for (std::string line; std::getline(f, line);) ++n;
  return n;
}
}  // namespace

// Found by fuzz_rosbag: a ROS 1 bag rejected while it was being opened kept its mapping, so a
// long-running caller (a fuzzer, the Python module) ran out of address space after ~65k bad bags.
TEST_F(BagFixture, RejectedRos1BagsReleaseTheirMapping) {
  const std::string good = read_all(root / "sim.bag");
  write_all(root / "cut.bag", good.substr(0, good.size() - 100));
  expect_error([&] { BagReader::open(root / "cut.bag"); }, "truncated");
  const std::size_t before = mapped_regions();
  for (int k = 0; k < 200; ++k) {
    expect_error([&] { BagReader::open(root / "cut.bag"); }, "truncated");
  }
  EXPECT_LE(mapped_regions(), before + 5);
}

TEST(RosbagCli, ExportImportAndReconstruct) {
  const fs::path root = temp_dir("rosbag_cli");
  SonarSpec spec = aris_spec_1800();
  const SimulatedPass p = simulate_pass(spec, 41);
  {
    DatasetWriter w(root / "sim", p.spec);
    for (std::size_t k = 0; k < p.images.size(); ++k) {
      SonarImage img = p.images[k];
      img.timestamp = p.times[k];
      w.add_frame(img);
    }
    w.set_navigation(p.nav);
    w.commit();
  }
  const fs::path log = root / "log.txt";
  ASSERT_EQ(run_cli_log("export rosbag " + (root / "sim").string() + " -o " +
                            (root / "bag").string() + " -q",
                        log),
            0)
      << read_all(log);
  EXPECT_NE(read_all(log).find("exported 41 frames and 41 navigation samples"), std::string::npos)
      << read_all(log);
  // Never over anything: an existing output is refused.
  EXPECT_EQ(run_cli_log(
                "export rosbag " + (root / "sim").string() + " -o " + (root / "bag").string(), log),
            1);
  EXPECT_NE(read_all(log).find("exists"), std::string::npos);
  ASSERT_EQ(run_cli_log("export rosbag --ros1 " + (root / "sim").string() + " -o " +
                            (root / "sim.bag").string() + " -q",
                        log),
            0)
      << read_all(log);
  for (const std::string bag : {"bag", "sim.bag"}) {
    ASSERT_EQ(run_cli_log("import rosbag " + (root / bag).string() +
                              " --sonar-topic /sonar3d/image "
                              "--nav-topic /sonar3d/odom -o " +
                              (root / ("ds_" + bag)).string() + " -q",
                          log),
              0)
        << read_all(log);
    EXPECT_NE(read_all(log).find("imported 41 frames"), std::string::npos) << read_all(log);
    EXPECT_NE(read_all(log).find("mounting: /tf_static: base_link -> sonar"), std::string::npos)
        << read_all(log);
  }
  EXPECT_EQ(
      run_cli_log("import rosbag " + (root / "bag").string() +
                      " --sonar-topic /x --nav-topic /sonar3d/odom -o " + (root / "ds_x").string(),
                  log),
      1);
  EXPECT_NE(read_all(log).find("sonar3d: error: " + (root / "bag").string() + ": no topic '/x'"),
            std::string::npos)
      << read_all(log);
  const fs::path ply = root / "cloud.ply";
  ASSERT_EQ(run_cli_log("reconstruct " + (root / "ds_bag").string() + " --voxel-size 0.03 -o " +
                            ply.string() + " -q",
                        log),
            0)
      << read_all(log);
  PointCloud cloud = read_ply(ply.string());
  ASSERT_GT(cloud.size(), 50u);
  std::vector<double> dist;
  for (const auto& q : cloud.points) dist.push_back(std::abs(q.cast<double>().norm() - 0.5));
  std::nth_element(dist.begin(), dist.begin() + dist.size() / 2, dist.end());
  EXPECT_LT(dist[dist.size() / 2], 0.08) << "median distance of the carved points to the sphere";
}
