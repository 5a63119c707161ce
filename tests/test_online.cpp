// Online maps (issue 25): frames pushed one by one give the batch reconstruction's cloud, the
// incremental occlusion resolution redoes only what changed, a rolling window bounds memory, and
// bad input is counted, never thrown.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <tuple>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/mapping/online.hpp"
#include "sonar3d/pipeline/online_feed.hpp"
#include "sonar3d/pipeline/online_recognition.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;

namespace {

constexpr double kDeg = M_PI / 180.0;

// A reduced sensor: 30° × 10°, 60 beams (0.5°), 1–4 m in 2 cm bins.
SonarSpec small_spec() {
  SonarSpec s;
  s.name = "test-online";
  s.set_uniform_bearings(30 * kDeg, 60);
  s.r_min = 1.0;
  s.r_max = 4.0;
  s.range_bins = 150;
  s.vertical_aperture_rad = 10 * kDeg;
  return s;
}

SceneObject sphere(double radius, const Eigen::Vector3d& centre) {
  SceneObject obj;
  obj.name = "sphere";
  obj.mesh_world = make_sphere(radius, 32);
  obj.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(centre)));
  obj.reflectivity = 0.8;
  return obj;
}

SimulatorConfig sim_config() {
  SimulatorConfig c;
  c.elevation_step_rad = 0.05 * kDeg;
  c.jitter = true;
  c.gain = 2.0;
  return c;
}

Eigen::Isometry3d sonar_at(double x, double y, double z, double yaw = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// Two spheres 6 m apart along y; the sonar looks along +x from x = -2.5 and travels along y with
// a vertical zig-zag (so the elevation arcs are bracketed): frames far apart see different
// spheres, so an incremental resolution has blocks it need not redo.
struct Survey {
  SonarSpec spec = small_spec();
  std::vector<double> times;
  std::vector<SonarImage> images;
  std::vector<Eigen::Isometry3d> poses;  // T_world_sonar (= T_world_vehicle: no mounting)
  Survey() {
    Scene scene;
    scene.objects.push_back(sphere(0.3, {0, 0, 1.0}));
    scene.objects.push_back(sphere(0.3, {0, 6, 1.0}));
    const Simulator sim(scene, spec, sim_config());
    const int n = 160;
    for (int k = 0; k < n; ++k) {
      const double y = -1.0 + 8.0 * k / (n - 1);
      const double z = 1.0 + 0.5 * std::sin(k * 0.35);
      times.push_back(0.1 * k);
      poses.push_back(sonar_at(-2.5, y, z));
      images.push_back(sim.render(poses.back(), 500 + k));
      images.back().timestamp = times.back();
    }
  }
  static const Survey& get() {
    static const Survey s;
    return s;
  }
};

CarveConfig carve_config() {
  CarveConfig c;
  c.voxel_size = 0.02;
  c.region = Eigen::AlignedBox3d(Eigen::Vector3d(-0.6, -1.0, 0.2), Eigen::Vector3d(0.6, 7.0, 1.8));
  return c;
}

// Points and bounds, in order, bit for bit.
void expect_same_cloud(const PointCloud& a, const PointCloud& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  ASSERT_EQ(a.intensity.size(), b.intensity.size()) << what;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    differ += a.points[i] != b.points[i] || a.intensity[i] != b.intensity[i];
  EXPECT_EQ(differ, 0u) << what;
}

PointCloud batch_of(const Survey& s, const CarveConfig& cfg, std::size_t n) {
  Carver carver(s.spec, cfg);
  for (std::size_t k = 0; k < n; ++k) carver.integrate(s.images[k], s.poses[k]);
  return carver.finalize();
}

}  // namespace

// The same frames pushed online give, after every query, exactly the cloud a batch carving of
// the frames pushed so far gives (same points, bounds and order), while the queries after the
// first redo only part of the map.
TEST(Online, SameCloudAsBatchAtEveryQuery) {
  const Survey& s = Survey::get();
  for (int min_obs : {1, 2}) {
    CarveConfig cfg = carve_config();
    cfg.min_observations = min_obs;
    OnlineMapConfig oc;
    oc.carve = cfg;
    OnlineMapper map(s.spec, oc);
    std::size_t partial = 0, redone = 0, cached = 0;
    for (std::size_t k = 0; k < s.images.size(); ++k) {
      ASSERT_EQ(map.push_frame(s.times[k], s.images[k], s.poses[k]), FrameDrop::None);
      if (k % 20 != 19 && k + 1 != s.images.size()) continue;
      const PointCloud online = map.cloud();
      const OnlineMapStats st = map.stats();
      if (!st.last_resolve.full) {
        ++partial;
        redone += st.last_resolve.blocks;
        cached += st.last_resolve.cached;
      }
      expect_same_cloud(online, batch_of(s, cfg, k + 1),
                        "min_observations " + std::to_string(min_obs) + ", after " +
                            std::to_string(k + 1) + " frames");
    }
    EXPECT_EQ(map.stats().frames_used, s.images.size());
    EXPECT_GT(map.stats().points, 500u);
    // Incremental: some queries resolved only part of the blocks.
    EXPECT_GT(partial, 2u) << "min_observations " << min_obs;
    EXPECT_LT(redone, cached) << "min_observations " << min_obs;
  }
}

// Navigation and images pushed separately (the pose interpolated as import does) give the cloud
// of `reconstruct` on the dataset written from the same frames and navigation.
TEST(Online, NavigationAndImagesMatchReconstructDataset) {
  const Survey& s = Survey::get();
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_ds_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  SonarSpec spec = s.spec;
  spec.T_vehicle_sonar = sonar_at(0.1, 0.0, -0.05);
  {
    DatasetWriter w(dir, spec, DatasetWriter::ImageFormat::Tiff);
    for (const auto& im : s.images) w.add_frame(im);
    // Navigation at twice the frame rate, offset by a quarter frame: every frame interpolates.
    Trajectory nav;
    for (std::size_t k = 0; k < s.poses.size(); ++k) {
      const std::size_t next = std::min(k + 1, s.poses.size() - 1);
      for (double a : {0.0, 0.5}) {
        const Eigen::Vector3d p =
            (1 - a) * s.poses[k].translation() + a * s.poses[next].translation();
        nav.push_back(s.times[k] - 0.025 + a * 0.1,
                      sonar_at(p.x(), p.y(), p.z(), 0.01 * std::sin(0.3 * k + a)) *
                          spec.T_vehicle_sonar.inverse());
      }
    }
    w.set_navigation(nav);
    w.commit();
  }
  const Dataset ds = read_dataset(dir);
  ReconstructOptions ro;
  ro = ReconstructConfig::from_carve(carve_config());
  const ReconstructResult batch = reconstruct_dataset(ds, ro);

  OnlineMapConfig oc;
  oc.carve = carve_config();
  OnlineMapper map(ds.spec, oc);
  // As a live system sees it: each frame arrives a little before the navigation that brackets
  // it (it waits in the queue), interleaved with the navigation samples.
  std::size_t nav_i = 0;
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const double t = ds.frames[k].timestamp;
    while (nav_i < ds.navigation.size() && ds.navigation.times[nav_i] < t - 0.03) {
      map.push_navigation(ds.navigation.times[nav_i], ds.navigation.poses[nav_i]);
      ++nav_i;
    }
    map.push_image(t, ds.load_frame(k));
  }
  for (; nav_i < ds.navigation.size(); ++nav_i)
    map.push_navigation(ds.navigation.times[nav_i], ds.navigation.poses[nav_i]);
  const OnlineMapStats st = map.stats();
  // Frames outside the navigation span would be dropped (never extrapolated); here the
  // navigation brackets them all.
  std::size_t placeable = 0;
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const double t = ds.frames[k].timestamp;
    placeable += t >= ds.navigation.times.front() && t <= ds.navigation.times.back();
  }
  EXPECT_EQ(st.frames_used, placeable);
  EXPECT_EQ(st.dropped_no_pose + st.frames_pending, ds.size() - placeable);
  // Batch on the frames the navigation brackets.
  Carver carver(ds.spec, carve_config());
  for (std::size_t k = 0; k < ds.size(); ++k) {
    const double t = ds.frames[k].timestamp;
    if (t < ds.navigation.times.front() || t > ds.navigation.times.back()) continue;
    carver.integrate(ds.load_frame(k), ds.T_world_sonar(k));
  }
  expect_same_cloud(map.cloud(), carver.finalize(), "online vs batch on the dataset's frames");
  EXPECT_EQ(placeable, ds.size());
  expect_same_cloud(map.cloud(), batch.cloud, "online vs reconstruct_dataset");
  const ElevationMap em = map.elevation();
  EXPECT_GT(em.num_valid(), 0u);
  fs::remove_all(dir);
}

namespace {

// The online feed's output, as a test sees it (the ROS 1 node publishes it instead).
struct RecordingSink : OnlineFeedSink {
  PointCloud last;
  std::size_t clouds = 0, diagnostics_seen = 0;
  std::vector<std::string> lines;
  void cloud(const PointCloud& c, double, const std::string&) override {
    last = c;
    ++clouds;
  }
  bool wants_elevation() const override { return false; }
  void elevation(const ElevationMap&, double, const std::string&) override {}
  void diagnostics(const std::string&) override { ++diagnostics_seen; }
  void log(const std::string& line) override { lines.push_back(line); }
};

// A dataset of the survey with a mounting and a navigation at twice the frame rate.
void write_survey_dataset(const fs::path& dir) {
  const Survey& s = Survey::get();
  SonarSpec spec = s.spec;
  spec.T_vehicle_sonar = sonar_at(0.1, 0.0, -0.05);
  DatasetWriter w(dir, spec, DatasetWriter::ImageFormat::Tiff);
  // Times start at 1 s: ROS stamps are unsigned, the navigation starts 25 ms before a frame.
  for (const auto& im : s.images) {
    SonarImage later = im;
    later.timestamp += 1.0;
    w.add_frame(later);
  }
  Trajectory nav;
  for (std::size_t k = 0; k < s.poses.size(); ++k) {
    const std::size_t next = std::min(k + 1, s.poses.size() - 1);
    for (double a : {0.0, 0.5}) {
      const Eigen::Vector3d p =
          (1 - a) * s.poses[k].translation() + a * s.poses[next].translation();
      nav.push_back(1.0 + s.times[k] - 0.025 + a * 0.1,
                    sonar_at(p.x(), p.y(), p.z(), 0.01 * std::sin(0.3 * k + a)) *
                        spec.T_vehicle_sonar.inverse());
    }
  }
  w.set_navigation(nav);
  w.commit();
}

}  // namespace

// A ROS 1 bag replayed through the online feed (the ROS-independent core of `sonar3d ros`):
// the mounting from /tf_static, the navigation from Odometry, the frames from
// ProjectedSonarImage, give the cloud that `import rosbag` + carving gives; a message that is no
// sonar message is counted and logged, not thrown; save() writes the pair under the output rule.
TEST(OnlineFeed, ReplayedBagGivesTheImportedDatasetsCloud) {
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_feed_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_survey_dataset(dir / "ds");
  RosbagExportConfig ec;
  ec.wire = RosWire::Ros1;
  export_rosbag(dir / "ds", dir / "survey.bag", ec);
  RosbagImportConfig ic;
  ic.sonar_topic = ec.sonar_topic;
  ic.nav_topic = ec.nav_topic;
  import_rosbag(dir / "survey.bag", dir / "imported", ic);
  const Dataset imported = read_dataset(dir / "imported");
  Carver carver(imported.spec, carve_config());
  for (std::size_t k = 0; k < imported.size(); ++k) {
    carver.integrate(imported.load_frame(k), imported.T_world_sonar(k));
  }
  const PointCloud expected = carver.finalize();
  ASSERT_GT(expected.size(), 100u);

  // Every message of the bag, in receive-time order, as the subscribers would hand them over.
  const auto bag = BagReader::open(dir / "survey.bag");
  struct Msg {
    std::int64_t t;
    OnlineFeed::Kind kind;
    std::string type;
    std::vector<std::uint8_t> bytes;
  };
  std::vector<Msg> msgs;
  for (const BagTopic& topic : bag->topics()) {
    const OnlineFeed::Kind kind = topic.name == ec.sonar_topic ? OnlineFeed::Kind::Sonar
                                  : topic.name == ec.nav_topic ? OnlineFeed::Kind::Nav
                                                               : OnlineFeed::Kind::Tf;
    bag->read(topic.name,
              [&](std::int64_t t, const std::uint8_t* p, std::size_t n, const std::string&) {
                msgs.push_back({t, kind, topic.type, std::vector<std::uint8_t>(p, p + n)});
              });
  }
  std::stable_sort(msgs.begin(), msgs.end(), [](const Msg& a, const Msg& b) { return a.t < b.t; });

  OnlineFeedConfig fc;
  fc.sonar_topic = ec.sonar_topic;
  fc.nav_topic = ec.nav_topic;
  fc.tf_topic = "/tf_static";
  fc.queue = msgs.size();  // a replay: nothing dropped for speed
  fc.period_s = 0.05;
  fc.map.carve = carve_config();
  RecordingSink sink;
  std::size_t sonar = 0;
  {
    OnlineFeed feed(fc, sink);
    for (const Msg& m : msgs) {
      sonar += m.kind == OnlineFeed::Kind::Sonar;
      feed.push(m.kind, m.type, m.bytes);
    }
    // Not a sonar message on the sonar topic: counted and logged.
    feed.push(OnlineFeed::Kind::Sonar, "std_msgs/String", {1, 2, 3});
    feed.drain();
    const std::string saved = feed.save((dir / "snap").string(), false);
    EXPECT_NE(saved.find("snap.ply"), std::string::npos) << saved;
    EXPECT_TRUE(fs::exists(dir / "snap.ply"));
    EXPECT_EQ(fs::exists(dir / "snap.tif"), saved.find("snap.tif") != std::string::npos) << saved;
    // A second save replaces the feed's own files; a foreign file is never replaced.
    EXPECT_NO_THROW(feed.save((dir / "snap").string(), false));
    { std::ofstream(dir / "mine.ply") << "not sonar3d's\n"; }
    EXPECT_THROW(feed.save((dir / "mine").string(), false), Error);
    feed.stop();
    const nlohmann::json st = nlohmann::json::parse(feed.stats_json());
    EXPECT_EQ(st["sonar_received"].get<std::size_t>(), sonar + 1);
    EXPECT_EQ(st["bad_sonar_messages"].get<std::size_t>(), 1u);
    EXPECT_EQ(st["dropped_node_queue_full"].get<std::size_t>(), 0u);
    EXPECT_EQ(st["map"]["frames_used"].get<std::size_t>(), imported.size());
    EXPECT_NE(st["mounting"].get<std::string>().find("/tf_static"), std::string::npos) << st.dump();
  }
  EXPECT_GE(sink.clouds, 1u);
  EXPECT_GE(sink.diagnostics_seen, 1u);
  EXPECT_FALSE(sink.lines.empty());
  expect_same_cloud(sink.last, expected, "replayed bag vs import rosbag + carving");
  fs::remove_all(dir);
}

// A query without new frames redoes nothing and returns the same cloud; queries between pushes
// stay consistent with batch (checked above) and with each other.
TEST(Online, QueriesBetweenPushesAreConsistent) {
  const Survey& s = Survey::get();
  OnlineMapConfig oc;
  oc.carve = carve_config();
  OnlineMapper map(s.spec, oc);
  EXPECT_TRUE(map.cloud().empty());
  EXPECT_TRUE(map.elevation().empty());
  for (std::size_t k = 0; k < 40; ++k) map.push_frame(s.times[k], s.images[k], s.poses[k]);
  const PointCloud a = map.cloud();
  const PointCloud b = map.cloud();
  expect_same_cloud(a, b, "two queries");
  EXPECT_EQ(map.stats().last_resolve.blocks, 0u);
  EXPECT_EQ(map.stats().last_resolve.frames, 0u);
  map.push_frame(s.times[40], s.images[40], s.poses[40]);
  const PointCloud c = map.cloud();
  EXPECT_GT(map.stats().last_resolve.blocks, 0u);
  expect_same_cloud(c, batch_of(s, oc.carve, 41), "after one more frame");
  const OnlineMapStats st = map.stats();
  EXPECT_EQ(st.points, c.size());
  EXPECT_GT(st.active_voxels, 0u);
  EXPECT_GT(st.map_bytes, 0u);
  EXPECT_GT(st.push_ms_median, 0.0);
  EXPECT_NE(st.to_json().find("\"frames_used\": 41"), std::string::npos);
}

// Late, out-of-order, NaN, wrong-size and unplaceable frames and bad navigation are counted and
// skipped; nothing throws, and the map holds only the good frames.
TEST(Online, BadInputIsCountedNotThrown) {
  const Survey& s = Survey::get();
  OnlineMapConfig oc;
  oc.carve = carve_config();
  oc.max_lateness_s = 0.5;
  oc.max_pending_images = 3;
  OnlineMapper map(s.spec, oc);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // Wrong size, NaN pose, NaN time.
  EXPECT_EQ(map.push_frame(0.0, SonarImage(10, 10), s.poses[0]), FrameDrop::WrongSize);
  Eigen::Isometry3d bad = s.poses[0];
  bad.translation().x() = nan;
  EXPECT_EQ(map.push_frame(0.0, s.images[0], bad), FrameDrop::BadPose);
  Eigen::Isometry3d skew = s.poses[0];
  skew.linear() *= 2.0;
  EXPECT_EQ(map.push_frame(0.0, s.images[0], skew), FrameDrop::BadPose);
  EXPECT_EQ(map.push_frame(nan, s.images[0], s.poses[0]), FrameDrop::BadTime);
  // Good frames, one out of order (carved: the min-filter does not care), one late (dropped).
  EXPECT_EQ(map.push_frame(s.times[5], s.images[5], s.poses[5]), FrameDrop::None);
  EXPECT_EQ(map.push_frame(s.times[6], s.images[6], s.poses[6]), FrameDrop::None);
  EXPECT_EQ(map.push_frame(s.times[4], s.images[4], s.poses[4]), FrameDrop::None);  // 0.2 s old
  EXPECT_EQ(map.push_frame(s.times[0], s.images[0], s.poses[0]), FrameDrop::Late);  // 0.6 s old
  // Images with navigation: before it (never extrapolated), after it (queued), queue overflow.
  map.push_navigation(1.0, s.poses[10]);
  map.push_navigation(1.2, s.poses[12]);
  EXPECT_FALSE(map.push_navigation(1.1, s.poses[11]));  // out of order
  EXPECT_FALSE(map.push_navigation(nan, s.poses[11]));
  EXPECT_FALSE(map.push_navigation(1.3, bad));
  EXPECT_EQ(map.push_image(0.95, s.images[9]), FrameDrop::NoPose);
  EXPECT_EQ(map.push_image(1.1, s.images[11]), FrameDrop::None);  // carved now
  EXPECT_EQ(map.push_image(1.1, SonarImage(3, 4)), FrameDrop::WrongSize);
  for (int k = 13; k <= 16; ++k) EXPECT_EQ(map.push_image(0.1 * k, s.images[k]), FrameDrop::None);
  OnlineMapStats st = map.stats();
  EXPECT_EQ(st.frames_pending, 3u);
  EXPECT_EQ(st.dropped_queue_full, 1u);   // 1.3 was pushed out
  map.push_navigation(1.6, s.poses[16]);  // brackets 1.4, 1.5, 1.6
  st = map.stats();
  EXPECT_EQ(st.frames_pending, 0u);
  EXPECT_EQ(st.frames_received, 4u + 4u + 3u + 4u);
  EXPECT_EQ(st.dropped_wrong_size, 2u);
  EXPECT_EQ(st.dropped_bad_pose, 2u);
  EXPECT_EQ(st.dropped_bad_time, 1u);
  EXPECT_EQ(st.dropped_late, 1u);
  EXPECT_EQ(st.dropped_no_pose, 1u);
  EXPECT_EQ(st.out_of_order, 1u);
  EXPECT_EQ(st.frames_used, 3u + 1u + 3u);
  EXPECT_EQ(st.navigation_received, 6u);
  EXPECT_EQ(st.navigation_rejected, 3u);
  EXPECT_EQ(st.dropped(), 2u + 2u + 1u + 1u + 1u + 1u);
  EXPECT_NO_THROW(map.cloud());
  // A memory limit: once the map is above it, frames are dropped and counted.
  OnlineMapConfig capped_cfg = oc;
  {
    OnlineMapper probe(s.spec, oc);
    for (std::size_t k = 0; k < 5; ++k) probe.push_frame(s.times[k], s.images[k], s.poses[k]);
    capped_cfg.max_memory_bytes = static_cast<double>(probe.carver().memory_bytes());
  }
  OnlineMapper capped(s.spec, capped_cfg);
  for (std::size_t k = 0; k < 20; ++k) capped.push_frame(s.times[k], s.images[k], s.poses[k]);
  EXPECT_GE(capped.stats().frames_used, 5u);
  EXPECT_GE(capped.stats().dropped_memory, 10u);
  EXPECT_EQ(capped.stats().frames_used + capped.stats().dropped_memory, 20u);
  // Config errors do throw, naming the field.
  OnlineMapConfig small = oc;
  small.window_m = 1.0;  // below r_max
  EXPECT_THROW(OnlineMapper(s.spec, small), Error);
  small.window_m = -1;
  EXPECT_THROW(OnlineMapper(s.spec, small), Error);
}

// A long stream over a flat seabed with a rolling window: the map in memory stays bounded while
// finished blocks go to disk, and what is written plus what is left is the surveyed seabed.
TEST(Online, RollingWindowBoundsMemory) {
  SonarSpec spec = small_spec();
  // A seabed strip 2 m below the sonar, 200 m long.
  Scene scene;
  SceneObject bed;
  bed.name = "seabed";
  bed.mesh_world.vertices = {{-5, -10, 0}, {205, -10, 0}, {205, 10, 0}, {-5, 10, 0}};
  bed.mesh_world.triangles = {{0, 1, 2}, {0, 2, 3}};
  bed.reflectivity = 0.5;
  scene.objects.push_back(bed);
  SimulatorConfig sc = sim_config();
  sc.elevation_step_rad = 0.1 * kDeg;
  const Simulator sim(scene, spec, sc);
  OnlineMapConfig oc;
  oc.carve.voxel_size = 0.05;
  oc.carve.min_observations = 1;
  oc.window_m = 5.0;
  oc.output_dir =
      (fs::temp_directory_path() / ("sonar3d_test_online_blocks_" + std::to_string(::getpid())))
          .string();
  fs::remove_all(oc.output_dir);
  OnlineMapper map(spec, oc);
  Carver batch(spec, oc.carve);  // the whole stream at once, for comparison
  // Looking down 40° along +x; 0.1 m per frame over 150 m: 1500 frames.
  const Eigen::Matrix3d down = Eigen::AngleAxisd(40 * kDeg, Eigen::Vector3d::UnitY()).matrix();
  std::size_t max_leaves_first = 0, max_leaves_last = 0, max_frames = 0;
  const int n = 1500;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = down;
    T.translation() = Eigen::Vector3d(0.1 * k, 0.3 * std::sin(0.05 * k), 2.0);
    const SonarImage image = sim.render(T, k);
    ASSERT_EQ(map.push_frame(0.1 * k, image, T), FrameDrop::None);
    batch.integrate(image, T);
    if (k % 50 == 49) {
      const OnlineMapStats st = map.stats();
      (k < n / 3 ? max_leaves_first : max_leaves_last) =
          std::max(k < n / 3 ? max_leaves_first : max_leaves_last, st.leaves);
      max_frames = std::max(max_frames, st.frames_kept);
      if (k % 250 == 249) map.cloud();  // queries in between
    }
  }
  const OnlineMapStats st = map.stats();
  std::printf(
      "rolling window: %zu moves, %zu blocks written, %zu points finished, leaves %zu "
      "(first third max %zu, last max %zu), frames kept %zu (max %zu), evicted %zu\n",
      st.window_moves, st.blocks_written, st.points_finished, st.leaves, max_leaves_first,
      max_leaves_last, st.frames_kept, max_frames, st.frames_evicted);
  EXPECT_GT(st.blocks_written, 10u);
  EXPECT_GT(st.points_finished, 1000u);
  // Bounded: the map of the last two thirds is no larger than a window's worth (measured in the
  // first third, once the window filled) — it does not grow with the 150 m travelled.
  EXPECT_GT(max_leaves_first, 0u);
  EXPECT_LE(max_leaves_last, max_leaves_first * 5 / 4);
  // A window of ±5 m at 0.1 m per frame keeps at most ~ (2·5 + r_max + step) / 0.1 frames.
  EXPECT_LT(max_frames, 200u);
  EXPECT_GT(st.frames_evicted, 1000u);
  std::size_t files = 0, written = 0;
  for (const auto& e : fs::directory_iterator(oc.output_dir)) {
    ++files;
    written += read_ply(e.path().string()).size();
  }
  EXPECT_EQ(files, st.blocks_written);
  EXPECT_EQ(written, st.points_finished);
  // The finished seabed lies on z = 0 (within a voxel and the elevation arc's carving).
  const PointCloud first = read_ply((fs::path(oc.output_dir) / "block_000000.ply").string());
  std::size_t near_bed = 0;
  for (const auto& p : first.points) near_bed += std::abs(p.z()) < 0.15;
  EXPECT_GT(near_bed, first.size() * 8 / 10);
  const PointCloud rest = map.flush();
  // Written blocks + the rest against batch: the track never comes back, so the same points
  // (docs/online.md).
  std::set<std::tuple<float, float, float>> online_set, batch_set;
  for (const auto& e : fs::directory_iterator(oc.output_dir))
    for (const auto& p : read_ply(e.path().string()).points)
      online_set.emplace(p.x(), p.y(), p.z());
  for (const auto& p : rest.points) online_set.emplace(p.x(), p.y(), p.z());
  for (const auto& p : batch.finalize().points) batch_set.emplace(p.x(), p.y(), p.z());
  std::size_t common = 0;
  for (const auto& q : online_set) common += batch_set.count(q);
  std::printf("rolling window vs batch: %zu online points, %zu batch, %zu in common\n",
              online_set.size(), batch_set.size(), common);
  EXPECT_EQ(common, batch_set.size());
  EXPECT_EQ(common, online_set.size());
  EXPECT_EQ(map.stats().frames_kept, 0u);
  const ElevationMap em = map.elevation();  // the finished cells
  EXPECT_GT(em.num_valid(), 1000u);
  EXPECT_GT(em.cols, 140 / 0.02 / 2);
  fs::remove_all(oc.output_dir);
}

namespace {

// A tank (the reference object, 50 cm diameter) standing on a gently rolling seabed, as a
// sonar3d map sees it from above: on a 2 cm grid, the higher of the seabed and the tank's top.
PointCloud tank_on_seabed(const Eigen::Isometry3d& T_world_tank) {
  const ModelTemplate tank = make_model_template("tank", make_reference_object("tank"),
                                                 Symmetry::Full, -1, ModelSamplingConfig());
  TopViewConfig tv;
  tv.cell_m = 0.02;
  tv.grid_anchor_xy = {-2, 2};
  const Eigen::Vector2d c =
      (T_world_tank * Eigen::Vector3d(tank.center_xy.x(), tank.center_xy.y(), 0)).head<2>();
  const ElevationMap top = render_placed_top_view(tank, T_world_tank, c, tv);
  PointCloud cloud;
  for (int r = 0; r < 200; ++r) {
    for (int col = 0; col < 200; ++col) {
      const double x = -2 + (col + 0.5) * 0.02, y = 2 - (r + 0.5) * 0.02;
      double z = 0.04 * std::sin(0.7 * x + 0.2) * std::cos(0.5 * y);
      const int tr = static_cast<int>(std::floor((top.origin_xy.y() - y) / top.cell_m));
      const int tc = static_cast<int>(std::floor((x - top.origin_xy.x()) / top.cell_m));
      if (tr >= 0 && tc >= 0 && tr < top.rows && tc < top.cols) {
        const float zt = top.at(tr, tc);
        if (zt == zt) z = std::max(z, static_cast<double>(zt));
      }
      cloud.points.emplace_back(x, y, z);
    }
  }
  return cloud;
}

}  // namespace

// The periodic recognition of `sonar3d ros --catalogue` without ROS: nothing before its period;
// at the period a recognition of the snapshot starts on its own thread and finds the tank at its
// pose; a period that comes while it still runs is skipped and counted; a period with no new
// frame starts none; the result carries the placements file and each model's mesh as a PLY.
TEST(OnlineRecognition, RunsAtItsPeriodOffTheCallersThreadAndSkipsWhenBusy) {
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_recog_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    std::ofstream(dir / "cat.yaml") << "models:\n"
                                       "  - {name: tank, reference: tank, symmetry: full}\n";
  }
  Eigen::Isometry3d T_tank = Eigen::Isometry3d::Identity();
  T_tank.translation() = Eigen::Vector3d(0.6, -0.4, 0.02);
  auto cloud = std::make_shared<const PointCloud>(tank_on_seabed(T_tank));

  std::mutex m;
  std::condition_variable cv;
  bool gate_open = false;
  std::vector<OnlinePlacements> results;
  std::vector<std::string> lines;
  OnlineRecognitionConfig oc;
  oc.period_s = 5;
  OnlineRecognizer rec(
      (dir / "cat.yaml").string(), RecognizeConfig(), oc,
      [&](const OnlinePlacements& p) {
        std::unique_lock<std::mutex> lock(m);
        results.push_back(p);
        cv.wait(lock, [&] { return gate_open; });  // the recognition "runs" until released
      },
      [&](const std::string& line) {
        std::lock_guard<std::mutex> lock(m);
        lines.push_back(line);
      },
      (dir / "meshes").string());
  ASSERT_EQ(rec.mesh_files().size(), 1u);
  EXPECT_EQ(load_mesh(rec.mesh_files()[0]).triangles.size(),
            make_reference_object("tank").triangles.size());

  using std::chrono::seconds;
  const auto t0 = OnlineRecognizer::Clock::now();
  EXPECT_FALSE(rec.tick(t0, 10, cloud, 3.5, "odom"));                // starts the clock
  EXPECT_FALSE(rec.tick(t0 + seconds(4), 10, cloud, 3.5, "odom"));   // not yet due
  EXPECT_TRUE(rec.tick(t0 + seconds(5), 10, cloud, 3.5, "odom"));    // due: starts
  EXPECT_FALSE(rec.tick(t0 + seconds(10), 12, cloud, 3.5, "odom"));  // still running: skipped
  nlohmann::json st = nlohmann::json::parse(rec.stats_json());
  EXPECT_EQ(st["started"].get<int>(), 1);
  EXPECT_EQ(st["skipped_busy"].get<int>(), 1);
  EXPECT_TRUE(st["running"].get<bool>());
  {
    std::lock_guard<std::mutex> lock(m);
    gate_open = true;
  }
  cv.notify_all();
  rec.wait();
  // The next period with the frames of the last recognition: nothing new, none started.
  EXPECT_FALSE(rec.tick(t0 + seconds(15), 10, cloud, 3.5, "odom"));
  st = nlohmann::json::parse(rec.stats_json());
  EXPECT_EQ(st["started"].get<int>(), 1);
  EXPECT_EQ(st["finished"].get<int>(), 1);
  EXPECT_EQ(st["failed"].get<int>(), 0);
  EXPECT_EQ(st["seconds"]["count"].get<int>(), 1);

  ASSERT_EQ(results.size(), 1u) << ::testing::PrintToString(lines);
  const std::optional<OnlinePlacements> last = rec.latest();
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->sequence, 1u);
  EXPECT_EQ(last->frames, 10u);
  EXPECT_EQ(last->points, cloud->size());
  EXPECT_EQ(last->frame, "odom");
  EXPECT_DOUBLE_EQ(last->stamp, 3.5);
  EXPECT_GT(last->seconds, 0);
  ASSERT_EQ(last->placements.size(), 1u) << last->json;
  const Placement& p = last->placements[0];
  EXPECT_EQ(p.model, "tank");
  EXPECT_GE(p.confidence, RecognizeConfig().two_d.verification.min_confidence);
  EXPECT_LT((p.T_world_model.translation().head<2>() - T_tank.translation().head<2>()).norm(), 0.03)
      << last->json;
  EXPECT_NEAR(p.T_world_model.translation().z(), T_tank.translation().z(), 0.04);
  ASSERT_EQ(last->mesh_files.size(), 1u);
  EXPECT_EQ(last->mesh_files[0], rec.mesh_files()[0]);
  // The label sits on the tank's top (its height: the model's top_z).
  EXPECT_NEAR(last->top_world[0].z() - p.T_world_model.translation().z(),
              rec.models()[0].top_z * p.scale, 1e-3);  // upright within a small tilt
  const nlohmann::json j = nlohmann::json::parse(last->json);
  EXPECT_EQ(j["format"], "sonar3d-placements");
  ASSERT_EQ(j["placements"].size(), 1u);
  // A reset of the map forgets the placements and recognises the next map even with as many
  // frames as the last one.
  rec.reset();
  EXPECT_FALSE(rec.latest().has_value());
  EXPECT_TRUE(rec.tick(t0 + seconds(20), 10, cloud, 4.0, "odom"));
  rec.wait();
  ASSERT_TRUE(rec.latest().has_value());
  EXPECT_EQ(rec.latest()->sequence, 2u);
  fs::remove_all(dir);
}

// A catalogue that cannot be read is one clear Error naming it; a period outside its bounds
// names the field and its flag.
TEST(OnlineRecognition, BadCatalogueAndPeriodAreClearErrors) {
  OnlineRecognitionConfig oc;
  try {
    OnlineRecognizer rec("/nonexistent/cat.yaml", RecognizeConfig(), oc, nullptr, nullptr);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/cat.yaml"), std::string::npos) << e.what();
  }
  oc.period_s = 0;
  try {
    oc.validate();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--recognition-period"), std::string::npos) << e.what();
  }
}

// Early in a dive the map is smaller than a model's search patch (the 2D method refuses such a
// model, eq. 6.8): the recognition finds nothing to search, counts it and fails nothing; the
// model is searched once the map has grown.
TEST(OnlineRecognition, AMapSmallerThanTheModelsWaitsInsteadOfFailing) {
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_small_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  { std::ofstream(dir / "cat.yaml") << "models:\n  - {name: tank, reference: tank}\n"; }
  auto small = std::make_shared<PointCloud>();
  for (int i = 0; i < 20; ++i)
    for (int k = 0; k < 20; ++k) small->points.emplace_back(0.02 * i, 0.02 * k, 0.0f);
  std::vector<std::string> lines;
  std::size_t results = 0;
  OnlineRecognitionConfig oc;
  oc.period_s = 1;
  OnlineRecognizer rec((dir / "cat.yaml").string(), RecognizeConfig(), oc,
                       [&](const OnlinePlacements&) { ++results; },
                       [&](const std::string& line) { lines.push_back(line); });
  const auto t0 = OnlineRecognizer::Clock::now();
  rec.tick(t0, 3, small, 1.0);
  EXPECT_TRUE(rec.tick(t0 + std::chrono::seconds(1), 3, small, 1.0));
  rec.wait();
  nlohmann::json st = nlohmann::json::parse(rec.stats_json());
  EXPECT_EQ(st["map_smaller_than_models"].get<int>(), 1);
  EXPECT_EQ(st["failed"].get<int>(), 0);
  EXPECT_EQ(st["finished"].get<int>(), 0);
  EXPECT_EQ(results, 0u);
  EXPECT_TRUE(lines.empty()) << lines.front();
  // The map grew: the tank is searched and found.
  Eigen::Isometry3d T_tank = Eigen::Isometry3d::Identity();
  T_tank.translation() = Eigen::Vector3d(-0.5, 0.7, 0.0);
  EXPECT_TRUE(rec.tick(t0 + std::chrono::seconds(2), 40,
                       std::make_shared<const PointCloud>(tank_on_seabed(T_tank)), 2.0));
  rec.wait();
  st = nlohmann::json::parse(rec.stats_json());
  EXPECT_EQ(st["finished"].get<int>(), 1);
  ASSERT_TRUE(rec.latest().has_value());
  ASSERT_EQ(rec.latest()->placements.size(), 1u) << rec.latest()->json;
  EXPECT_TRUE(rec.latest()->models_waiting.empty());
  fs::remove_all(dir);
}

// `sonar3d online DATASET`: the dataset replayed through the online feed (as a ROS 1 bag, without
// ROS), as fast as the map takes it, gives the cloud that `import rosbag` of the same bag +
// `reconstruct --method carve` gives with the same settings, point for point; the final JSON
// counts every frame and no drop; bad input is one clear line.
TEST(OnlineCli, ReplayedDatasetGivesTheImportedBagsReconstruction) {
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_cli_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_survey_dataset(dir / "ds");
  const std::string settings =
      " --voxel-size 0.02 --roi -0.6 -1.0 0.2 0.6 7.0 1.8 --no-explain-returns "
      "--no-auto-min-bracket -q";
  test::CliRunSplit r =
      test::run_cli_captured(dir, "export rosbag " + (dir / "ds").string() + " -o " +
                                      (dir / "ds.bag").string() + " --ros1 -q");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_cli_captured(dir, "import rosbag " + (dir / "ds.bag").string() + " -o " +
                                      (dir / "imported").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_cli_captured(dir, "reconstruct " + (dir / "imported").string() + " -o " +
                                      (dir / "batch.ply").string() + " --method carve" + settings);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_cli_captured(dir, "online " + (dir / "ds").string() +
                                      " --speed 0 --queue 100000 --save-prefix " +
                                      (dir / "online").string() + settings);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json st = nlohmann::json::parse(r.out);
  const std::size_t n = read_dataset(dir / "ds").size();
  EXPECT_EQ(st["sonar_received"].get<std::size_t>(), n);
  EXPECT_EQ(st["map"]["frames_used"].get<std::size_t>(), n);
  EXPECT_EQ(st["dropped_node_queue_full"].get<std::size_t>(), 0u);
  EXPECT_EQ(st["frames_dropped_by_map"].get<std::size_t>(), 0u);
  EXPECT_NE(st["mounting"].get<std::string>().find("/tf_static"), std::string::npos);
  const PointCloud batch = read_ply((dir / "batch.ply").string());
  ASSERT_GT(batch.size(), 100u);
  expect_same_cloud(read_ply((dir / "online.ply").string()), batch,
                    "sonar3d online vs import rosbag + reconstruct");
  // Bad input: one line naming it, exit 1; nothing written.
  { std::ofstream(dir / "notabag.bag") << "not a bag\n"; }
  r = test::run_cli_captured(dir, "online " + (dir / "notabag.bag").string() + " -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("notabag.bag"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  r = test::run_cli_captured(dir, "online " + (dir / "ds").string() + " --speed -1 -q");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--speed"), std::string::npos) << r.err;
  // The settings of `sonar3d ros`: three blocks, printed without INPUT.
  r = test::run_cli_captured(dir, "online --print-config --recognition-period 4");
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* block : {"\nreconstruct:", "\nrecognize:", "\nonline_recognition:"})
    EXPECT_NE(r.out.find(block), std::string::npos) << block << "\n" << r.out;
  EXPECT_NE(r.out.find("period_s: 4"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// `sonar3d online --catalogue`: a down-looking pass over a tank on a rolling seabed replayed
// through the feed; the recognition of the complete map at the end places the tank where the
// batch `sonar3d recognize` places it in the batch carving (within 3 cm), and the placements JSON
// is saved with the map.
TEST(OnlineCli, CatalogueRecognisesTheCompleteMapAsBatch) {
  const fs::path dir =
      fs::temp_directory_path() / ("sonar3d_test_online_cli_cat_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    std::ofstream(dir / "scene.yaml") << R"(seed: 4
sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: seabed, primitive: {type: terrain, size: [5, 4], cell: 0.05, relief: 0.1, wavelength: 6, trenches: 0, rocks: 3, seed: 4}, reflectivity: 0.3}
  - {name: tank, reference: tank, pose: {translation: [0.5, -0.3, -0.05]}, reflectivity: 0.8}
trajectory: {type: straight, start: [-1.5, 0, 4], end: [1.5, 0, 4], spacing: 0.03, period: 0.1}
)";
    std::ofstream(dir / "cat.yaml")
        << "models:\n  - {name: tank, reference: tank, symmetry: full}\n";
  }
  const std::string settings = " --voxel-size 0.02 --no-explain-returns --no-auto-min-bracket -q";
  test::CliRunSplit r = test::run_cli_captured(
      dir, "simulate " + (dir / "scene.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_cli_captured(dir, "reconstruct " + (dir / "ds").string() + " -o " +
                                      (dir / "batch.ply").string() + " --method carve" + settings);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_cli_captured(dir, "recognize " + (dir / "batch.ply").string() + " --catalogue " +
                                      (dir / "cat.yaml").string() + " -o " +
                                      (dir / "batch_placements.json").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json batch = nlohmann::json::parse(test::read_all(dir / "batch_placements.json"));
  ASSERT_EQ(batch["placements"].size(), 1u) << batch.dump(1);
  r = test::run_cli_captured(dir, "online " + (dir / "ds").string() +
                                      " --speed 0 --queue 100000 --catalogue " +
                                      (dir / "cat.yaml").string() + " --save-prefix " +
                                      (dir / "online").string() + settings);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json st = nlohmann::json::parse(r.out);
  EXPECT_GE(st["recognition"]["finished"].get<int>(), 1);
  EXPECT_EQ(st["recognition"]["failed"].get<int>(), 0);
  EXPECT_EQ(st["recognition"]["last_frames"].get<std::size_t>(), read_dataset(dir / "ds").size());
  const nlohmann::json online =
      nlohmann::json::parse(test::read_all(dir / "online.placements.json"));
  EXPECT_EQ(online["format"], "sonar3d-placements");
  ASSERT_EQ(online["placements"].size(), 1u) << online.dump(1);
  EXPECT_EQ(online["placements"][0]["model"], "tank");
  Eigen::Vector3d a, b;
  for (int k = 0; k < 3; ++k) {
    a[k] = online["placements"][0]["T_world_model"][k][3].get<double>();
    b[k] = batch["placements"][0]["T_world_model"][k][3].get<double>();
  }
  EXPECT_LT((a - b).norm(), 0.03) << a.transpose() << " vs batch " << b.transpose();
  fs::remove_all(dir);
}
