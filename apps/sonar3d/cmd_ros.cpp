// sonar3d ros: a ROS 1 node over the online map API (issue 25, docs/online.md "The ROS 1 node").
//
// Two parts:
//   - OnlineFeed (the library's, pipeline/online_feed.hpp; no ROS type in it): serialised
//     messages in (ROS 1 wire bytes + their type, as topic_tools::ShapeShifter hands them over),
//     decoded and carved on its worker thread; the map goes out through an OnlineFeedSink.
//   - the ROS 1 adapter: subscribers with ShapeShifter (marine_acoustic_msgs is not packaged in
//     Debian: the bytes are decoded by our own decoders), publishers and services.
// Without Debian's roscpp at build time the command prints that the build has no ROS 1 support.
#include <fmt/core.h>

#include <cstring>
#include <memory>
#include <string>

#include "commands.hpp"
#include "online_node_config.hpp"
#include "params_cli.hpp"
#include "sonar3d/pipeline/online_recognition.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/recon/reconstruct.hpp"

#ifdef SONAR3D_HAVE_ROS1
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nav_msgs/MapMetaData.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <topic_tools/shape_shifter.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/online.hpp"
#include "sonar3d/pipeline/online_feed.hpp"
#endif

namespace sonar3d::cli {
namespace {

struct RosCliOptions {
  std::string sonar_topic = "/sonar3d/image", nav_topic = "/sonar3d/odom", tf_topic = "/tf_static";
  std::string base_frame, mount, sonar, noise, frame_id;
  double vertical_aperture_deg = 0, time_offset = 0;
  double rate_hz = 1.0;
  double elevation_cell_m = 0.02;
  std::size_t queue = 8;
  double window_m = 0, max_lateness_s = 1.0, tf_wait_s = 2.0, duration_s = 0;
  std::string window_dir, save_prefix, catalogue;
  bool overwrite = false;
  double max_memory_gb = 0;
  std::string node_name = "sonar3d";
  std::unique_ptr<ConfigOptions<OnlineNodeConfig>> config;
};

#ifdef SONAR3D_HAVE_ROS1

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0, Clock::time_point t1) {
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

// ------------------------------------------------------------------ the ROS 1 adapter

ros::Time ros_time(double t) {
  if (!(t > 0)) return ros::Time(0, 0);
  const RosTime r = RosTime::from_seconds(t);
  return ros::Time(static_cast<std::uint32_t>(r.sec), r.nanosec);
}

class Ros1Sink : public OnlineFeedSink {
 public:
  explicit Ros1Sink(ros::NodeHandle& nh) {
    cloud_ = nh.advertise<sensor_msgs::PointCloud2>("/sonar3d/cloud", 2, true);
    elevation_ = nh.advertise<sensor_msgs::Image>("/sonar3d/elevation", 2, true);
    elevation_info_ = nh.advertise<nav_msgs::MapMetaData>("/sonar3d/elevation_info", 2, true);
    diagnostics_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/sonar3d/diagnostics", 10);
    placements_ = nh.advertise<visualization_msgs::MarkerArray>("/sonar3d/placements", 2, true);
  }

  // visualization_msgs/MarkerArray, latched: DELETEALL (placements gone since the last
  // recognition disappear), then per placement its model's mesh (MESH_RESOURCE, file:// URL of
  // the PLY the recognizer wrote; pose T_world_model, scale the found size; coloured from red at
  // confidence 0 to green at 1; ns = the model's name) and a label with name and confidence.
  void placements(const OnlinePlacements& found) override {
    visualization_msgs::MarkerArray a;
    visualization_msgs::Marker clear;
    clear.header.frame_id = found.frame;
    clear.header.stamp = ros_time(found.stamp);
    clear.action = visualization_msgs::Marker::DELETEALL;
    a.markers.push_back(clear);
    std::map<std::string, int> ids;  // per namespace (model)
    for (std::size_t i = 0; i < found.placements.size(); ++i) {
      const Placement& p = found.placements[i];
      const int k = ids[p.model]++;
      visualization_msgs::Marker m;
      m.header = clear.header;
      m.ns = p.model;
      m.id = 2 * k;
      m.type = visualization_msgs::Marker::MESH_RESOURCE;
      m.action = visualization_msgs::Marker::ADD;
      const Eigen::Vector3d t = p.T_world_model.translation();
      const Eigen::Quaterniond q = Eigen::Quaterniond(p.T_world_model.linear()).normalized();
      m.pose.position.x = t.x();
      m.pose.position.y = t.y();
      m.pose.position.z = t.z();
      m.pose.orientation.x = q.x();
      m.pose.orientation.y = q.y();
      m.pose.orientation.z = q.z();
      m.pose.orientation.w = q.w();
      m.scale.x = m.scale.y = m.scale.z = p.scale;
      const double c = std::clamp(p.confidence, 0.0, 1.0);
      m.color.r = static_cast<float>(1 - c);
      m.color.g = static_cast<float>(c);
      m.color.b = 0.1f;
      m.color.a = 0.9f;
      m.mesh_resource = "file://" + found.mesh_files[i];
      m.mesh_use_embedded_materials = false;
      a.markers.push_back(m);
      visualization_msgs::Marker label;
      label.header = clear.header;
      label.ns = p.model;
      label.id = 2 * k + 1;
      label.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
      label.action = visualization_msgs::Marker::ADD;
      label.pose.position.x = found.top_world[i].x();
      label.pose.position.y = found.top_world[i].y();
      label.pose.position.z = found.top_world[i].z() + 0.2;
      label.pose.orientation.w = 1;
      label.scale.z = 0.15;  // text height, m
      label.color.r = label.color.g = label.color.b = label.color.a = 1.0f;
      label.text = fmt::format("{} {:.2f}", p.model, p.confidence);
      a.markers.push_back(label);
    }
    placements_.publish(a);
  }

  // sensor_msgs/PointCloud2: x y z intensity, float32, 16 bytes a point, little-endian.
  void cloud(const PointCloud& c, double stamp, const std::string& frame) override {
    sensor_msgs::PointCloud2 m;
    m.header.stamp = ros_time(stamp);
    m.header.frame_id = frame;
    m.height = 1;
    m.width = static_cast<std::uint32_t>(c.size());
    const char* names[] = {"x", "y", "z", "intensity"};
    for (std::uint32_t k = 0; k < 4; ++k) {
      sensor_msgs::PointField f;
      f.name = names[k];
      f.offset = 4 * k;
      f.datatype = sensor_msgs::PointField::FLOAT32;
      f.count = 1;
      m.fields.push_back(f);
    }
    m.is_bigendian = false;
    m.point_step = 16;
    m.row_step = m.point_step * m.width;
    m.is_dense = true;
    m.data.resize(static_cast<std::size_t>(m.row_step));
    for (std::size_t i = 0; i < c.size(); ++i) {
      const float v[4] = {c.points[i].x(), c.points[i].y(), c.points[i].z(),
                          c.has_intensity() ? c.intensity[i] : 0.0f};
      std::memcpy(&m.data[i * 16], v, 16);
    }
    cloud_.publish(m);
  }

  bool wants_elevation() const override {
    return elevation_.getNumSubscribers() > 0 || elevation_info_.getNumSubscribers() > 0;
  }

  // sensor_msgs/Image 32FC1 heights (m, NaN = no data) and nav_msgs/MapMetaData, the geometry
  // an OccupancyGrid uses: cell size, width, height and the pose of cell (0, 0)'s corner. Rows
  // are published south to north (row 0 at origin.y, as OccupancyGrid), i.e. flipped from the
  // GeoTIFF's north-up rows.
  void elevation(const ElevationMap& dem, double stamp, const std::string& frame) override {
    sensor_msgs::Image img;
    img.header.stamp = ros_time(stamp);
    img.header.frame_id = frame;
    img.height = static_cast<std::uint32_t>(dem.rows);
    img.width = static_cast<std::uint32_t>(dem.cols);
    img.encoding = "32FC1";
    img.is_bigendian = 0;
    img.step = img.width * 4;
    img.data.resize(static_cast<std::size_t>(img.step) * img.height);
    for (int r = 0; r < dem.rows; ++r) {
      std::memcpy(&img.data[static_cast<std::size_t>(dem.rows - 1 - r) * img.step],
                  &dem.z[dem.index(r, 0)], img.step);
    }
    nav_msgs::MapMetaData info;
    info.map_load_time = img.header.stamp;
    info.resolution = static_cast<float>(dem.cell_m);
    info.width = img.width;
    info.height = img.height;
    info.origin.position.x = dem.origin_xy.x();
    info.origin.position.y = dem.origin_xy.y() - dem.rows * dem.cell_m;
    info.origin.orientation.w = 1;
    elevation_.publish(img);
    elevation_info_.publish(info);
  }

  void diagnostics(const std::string& stats_json) override {
    const nlohmann::ordered_json stats = nlohmann::ordered_json::parse(stats_json);
    diagnostic_msgs::DiagnosticArray a;
    a.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus s;
    s.name = "sonar3d: online map";
    s.hardware_id = "sonar3d";
    const std::size_t dropped = stats["dropped_node_queue_full"].get<std::size_t>() +
                                stats["bad_sonar_messages"].get<std::size_t>() +
                                stats["dropped_waiting_for_mounting"].get<std::size_t>() +
                                stats["frames_dropped_by_map"].get<std::size_t>();
    s.level = dropped > 0 ? diagnostic_msgs::DiagnosticStatus::WARN
                          : diagnostic_msgs::DiagnosticStatus::OK;
    s.message = dropped > 0 ? fmt::format("{} frames dropped or bad", dropped) : "ok";
    // Every counter, flattened ("map.frames_used", "latency_arrival_to_carved_ms.p95", ...);
    // the whole object as JSON under "json".
    std::function<void(const std::string&, const nlohmann::ordered_json&)> flat =
        [&](const std::string& prefix, const nlohmann::ordered_json& j) {
          for (const auto& [k, v] : j.items()) {
            const std::string key = prefix.empty() ? k : prefix + "." + k;
            if (v.is_object()) {
              flat(key, v);
            } else {
              diagnostic_msgs::KeyValue kv;
              kv.key = key;
              kv.value = v.is_string() ? v.get<std::string>() : v.dump();
              s.values.push_back(kv);
            }
          }
        };
    flat("", stats);
    diagnostic_msgs::KeyValue kv;
    kv.key = "json";
    kv.value = stats.dump();
    s.values.push_back(kv);
    a.status.push_back(s);
    diagnostics_.publish(a);
  }

  void log(const std::string& line) override { ROS_WARN("sonar3d: %s", line.c_str()); }

 private:
  ros::Publisher cloud_, elevation_, elevation_info_, diagnostics_, placements_;
};

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal = sig; }

std::vector<std::uint8_t> shape_bytes(const topic_tools::ShapeShifter& m) {
  std::vector<std::uint8_t> bytes(m.size());
  ros::serialization::OStream s(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  m.write(s);
  return bytes;
}

int run_ros(const RosCliOptions& o, const OnlineNodeConfig& nc, const GlobalOptions& g) {
  const ReconstructConfig& rc = nc.reconstruct;
  if (rc.method != "carve") {
    throw Error("the online map carves (--method carve); '" + rc.method + "' is batch only");
  }
  OnlineFeedConfig fc;
  fc.sonar_topic = o.sonar_topic;
  fc.nav_topic = o.nav_topic;
  fc.tf_topic = o.tf_topic;
  fc.base_frame = o.base_frame;
  fc.frame_id = o.frame_id;
  if (!o.sonar.empty()) fc.described = read_sonar_description(o.sonar);
  if (!o.mount.empty()) fc.mount = parse_mounting(o.mount);
  if (!o.noise.empty()) {
    fc.noise = read_dataset(o.noise).noise;
    if (!fc.noise) throw Error("--noise " + o.noise + ": the dataset has no noise statistics");
  }
  fc.vertical_aperture_rad = o.vertical_aperture_deg * M_PI / 180;
  fc.time_offset = o.time_offset;
  if (!(o.rate_hz > 0 && o.rate_hz <= 1000)) throw Error("--rate must be in (0, 1000] Hz");
  fc.period_s = 1.0 / o.rate_hz;
  if (o.queue < 1) throw Error("--queue must be at least 1");
  fc.queue = o.queue;
  fc.tf_wait_s = o.tf_wait_s;
  fc.map.carve = rc.effective_carve();
  fc.map.window_m = o.window_m;
  fc.map.output_dir = o.window_dir;
  fc.map.max_lateness_s = o.max_lateness_s;
  fc.map.max_memory_bytes = memory_limit_bytes(o.max_memory_gb);
  fc.map.elevation.cell_m = o.elevation_cell_m;
  fc.map.validate();
  if (!o.catalogue.empty()) {
    read_catalogue(o.catalogue);  // a bad catalogue fails now, before the node starts
    fc.catalogue = o.catalogue;
    fc.recognize = nc.recognize;
    fc.recognition = nc.online_recognition;
  }
  if (!o.save_prefix.empty()) {
    // Fail now, not at the first save request.
    check_output(o.save_prefix + ".ply", OutputKind::PointCloud, output_policy(o.overwrite, {}),
                 "--save-prefix");
    check_output(o.save_prefix + ".tif", OutputKind::GeoTiff, output_policy(o.overwrite, {}),
                 "--save-prefix");
    if (!o.catalogue.empty()) {
      check_output(o.save_prefix + ".placements.json", OutputKind::PlacementsJson,
                   output_policy(o.overwrite, {}), "--save-prefix");
    }
  }

  int argc = 0;
  ros::init(argc, nullptr, o.node_name, ros::init_options::NoSigintHandler);
  if (!ros::master::check()) {
    const char* uri = std::getenv("ROS_MASTER_URI");
    throw Error(std::string("no ROS master at ") + (uri ? uri : "(ROS_MASTER_URI not set)") +
                ": start roscore (or set ROS_MASTER_URI)");
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  Ros1Sink sink(nh);
  OnlineFeed feed(fc, sink);  // reads the catalogue and prepares its models first

  // Subscribers hand the serialised bytes over; decoding happens on the worker thread. The ROS
  // queues are deep because the callbacks only copy (the bound that drops is the feed's).
  using Shape = topic_tools::ShapeShifter;
  auto sub = [&](const std::string& topic, OnlineFeed::Kind kind, std::uint32_t depth) {
    return nh.subscribe<Shape>(topic, depth,
                               [&feed, kind](const boost::shared_ptr<const Shape>& m) {
                                 feed.push(kind, m->getDataType(), shape_bytes(*m));
                               });
  };
  ros::Subscriber sonar_sub = sub(o.sonar_topic, OnlineFeed::Kind::Sonar, 100);
  ros::Subscriber nav_sub = sub(o.nav_topic, OnlineFeed::Kind::Nav, 1000);
  ros::Subscriber tf_sub;
  if (!fc.mount) tf_sub = sub(o.tf_topic, OnlineFeed::Kind::Tf, 100);

  const bool overwrite = o.overwrite;
  const std::string prefix = o.save_prefix;
  auto trigger = [&feed](std::function<std::string()> fn) {
    return [&feed, fn](std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
      try {
        res.message = fn();  // the feed runs it on its worker, between two messages
        res.success = true;
      } catch (const std::exception& e) {
        res.message = e.what();
        res.success = false;
      }
      ROS_INFO("sonar3d: %s", res.message.c_str());
      return true;
    };
  };
  ros::ServiceServer save_srv =
      pnh.advertiseService<std_srvs::Trigger::Request, std_srvs::Trigger::Response>(
          "save", trigger([&feed, prefix, overwrite] { return feed.save(prefix, overwrite); }));
  ros::ServiceServer reset_srv =
      pnh.advertiseService<std_srvs::Trigger::Request, std_srvs::Trigger::Response>(
          "reset", trigger([&feed] { return feed.reset(); }));

  if (!g.quiet) {
    fmt::print(stderr,
               "sonar3d ros: node {} listening on {} (sonar), {} (navigation){}; publishing "
               "/sonar3d/cloud at {} Hz{}; services {}/save, {}/reset\n",
               ros::this_node::getName(), o.sonar_topic, o.nav_topic,
               fc.mount ? "" : ", " + o.tf_topic + " (mounting)", o.rate_hz,
               o.catalogue.empty() ? ""
                                   : fmt::format(", /sonar3d/placements every {} s ({})",
                                                 fc.recognition.period_s, o.catalogue),
               ros::this_node::getName(), ros::this_node::getName());
  }
  ros::AsyncSpinner spinner(2);  // subscriber callbacks and services (a save waits for the worker)
  spinner.start();
  const auto t0 = Clock::now();
  while (ros::ok() && g_signal == 0 &&
         !(o.duration_s > 0 && ms_since(t0, Clock::now()) >= o.duration_s * 1e3)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  sonar_sub.shutdown();
  nav_sub.shutdown();
  tf_sub.shutdown();
  feed.stop();  // publishes a last time
  const std::string final_stats = feed.stats_json();
  spinner.stop();
  ros::shutdown();
  // The run's statistics on standard output (one JSON object), for scripts and benchmarks.
  fmt::print("{}\n", final_stats);
  return 0;
}

#endif  // SONAR3D_HAVE_ROS1

}  // namespace

void add_ros(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "ros",
      "ROS 1 node: map online while the vehicle dives (docs/online.md). Subscribes to sonar "
      "frames (marine_acoustic_msgs/ProjectedSonarImage, or sensor_msgs/Image with --sonar), "
      "navigation (nav_msgs/Odometry or geometry_msgs/PoseStamped, T_world_vehicle) and the "
      "mounting (/tf_static or --mount), read as `sonar3d import rosbag` reads them; carves as "
      "`sonar3d reconstruct --method carve` with the same settings; publishes /sonar3d/cloud "
      "(sensor_msgs/PointCloud2 x y z intensity, float32, in the navigation's frame), "
      "/sonar3d/elevation (sensor_msgs/Image 32FC1, m) + /sonar3d/elevation_info "
      "(nav_msgs/MapMetaData), /sonar3d/diagnostics (diagnostic_msgs/DiagnosticArray) and, "
      "with --catalogue, /sonar3d/placements (visualization_msgs/MarkerArray); "
      "services ~save and ~reset (std_srvs/Trigger). Runs until SIGINT/SIGTERM (or --duration), "
      "then prints its statistics as JSON. Needs a ROS master (ROS_MASTER_URI).");
  auto o = std::make_shared<RosCliOptions>();
  cmd->add_option(
         "--sonar-topic", o->sonar_topic,
         "sonar frames: ProjectedSonarImage or sensor_msgs/Image (type from the publisher)")
      ->capture_default_str();
  cmd->add_option("--nav-topic", o->nav_topic,
                  "navigation: nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                  "PoseWithCovarianceStamped (T_world_vehicle)")
      ->capture_default_str();
  cmd->add_option("--tf-topic", o->tf_topic, "static transforms (tf2_msgs/TFMessage)")
      ->capture_default_str();
  cmd->add_option("--base-frame", o->base_frame,
                  "vehicle frame of the mounting (default: the Odometry child_frame_id, else the "
                  "root of the static transforms above the sonar frame)");
  cmd->add_option("--mount", o->mount,
                  "T_vehicle_sonar as x,y,z,roll,pitch,yaw (m, degrees; our FLU sonar frame), "
                  "instead of /tf_static");
  cmd->add_option("--sonar", o->sonar,
                  "sensor YAML (sonar.yaml fields): required for sensor_msgs/Image; supplies the "
                  "vertical aperture and beam pattern a ProjectedSonarImage lacks")
      ->check(CLI::ExistingFile);
  cmd->add_option("--vertical-aperture-deg", o->vertical_aperture_deg,
                  "full vertical aperture, degrees (default: the messages' tx_beamwidths, or "
                  "--sonar)");
  cmd->add_option("--time-offset", o->time_offset,
                  "seconds added to sonar stamps to reach the navigation clock, s")
      ->capture_default_str();
  cmd->add_option("--noise", o->noise,
                  "dataset directory whose noise/ statistics the Z-test denoising uses (as "
                  "reconstruct does with a dataset's own)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--frame-id", o->frame_id,
                  "frame of the published cloud and map (default: the navigation's frame_id)");
  cmd->add_option("--rate", o->rate_hz,
                  "publishing rate of the cloud (when it changed), the elevation map (when "
                  "subscribed) and the diagnostics, Hz")
      ->capture_default_str();
  cmd->add_option("--elevation-cell-m", o->elevation_cell_m,
                  "cell size of the published elevation map, m")
      ->capture_default_str();
  cmd->add_option("--queue", o->queue,
                  "sonar messages waiting to be carved; when full the oldest is dropped and "
                  "counted (dropped_node_queue_full), frames")
      ->capture_default_str();
  cmd->add_option("--window-m", o->window_m,
                  "rolling window half-size around the sonar, m (0 = off: bound the map with "
                  "--roi); at least the sonar's r_max")
      ->capture_default_str();
  cmd->add_option("--window-dir", o->window_dir,
                  "directory for the rolling window's finished blocks (block_NNNNNN.ply)");
  cmd->add_option("--max-lateness", o->max_lateness_s,
                  "frames older than the newest by more than this are dropped as late, s")
      ->capture_default_str();
  cmd->add_option("--tf-wait", o->tf_wait_s,
                  "how long frames wait (from the first one) for the first static transform before "
                  "the mounting is "
                  "taken as identity (up to 64 frames wait meanwhile; older ones are dropped and "
                  "counted), s")
      ->capture_default_str();
  cmd->add_option("--save-prefix", o->save_prefix,
                  "the ~save service writes PREFIX.ply (cloud) and PREFIX.tif (elevation "
                  "GeoTIFF) and, with --catalogue, PREFIX.placements.json (the last "
                  "recognition), together; replaces files sonar3d wrote only with --overwrite (or "
                  "this run's earlier save)");
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue YAML (as sonar3d recognize reads it): recognise its models in the "
                  "map every --recognition-period s, off the carving thread, and publish them on "
                  "/sonar3d/placements (visualization_msgs/MarkerArray, mesh markers); the "
                  "recognition's settings: the recognize block of --config")
      ->check(CLI::ExistingFile);
  add_overwrite_flag(cmd, o->overwrite,
                     "a cloud, GeoTIFF and placements JSON at --save-prefix sonar3d wrote");
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->add_option("--duration", o->duration_s, "stop after this long (0 = until a signal), s")
      ->capture_default_str();
  cmd->add_option("--node-name", o->node_name, "ROS node name")->capture_default_str();
  // The carving settings, from ReconstructConfig's one declaration (recon/reconstruct.hpp), the
  // recognition's (recog/recognize.hpp) and its period, with --print-config and --config: a file
  // `sonar3d reconstruct --print-config` or `sonar3d recognize --print-config` wrote works here.
  o->config = std::make_unique<ConfigOptions<OnlineNodeConfig>>(cmd);
  cmd->callback([&g, &run, o] {
    const FlagNames flags = online_node_flag_names(o->config->flag_names());
    run = [&g, o, flags]() -> int {
      return with_flag_names(flags, [&]() -> int {
        const OnlineNodeConfig cfg = o->config->resolve();
        cfg.reconstruct.validate();
        if (!o->catalogue.empty()) {
          cfg.recognize.validate();
          cfg.online_recognition.validate();
        }
        if (o->config->print_if_requested(cfg, "", "ros")) return 0;
#ifdef SONAR3D_HAVE_ROS1
        return run_ros(*o, cfg, g);
#else
        (void)g;
        fmt::print(stderr,
                   "sonar3d: error: this build has no ROS 1 support (rebuild with Debian's "
                   "libroscpp-dev and the message packages: scripts/install-deps.sh)\n");
        return kExitUsage;
#endif
      });
    };
  });
}

}  // namespace sonar3d::cli
