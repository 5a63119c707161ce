// sonar3d ros: a ROS 1 node over the online map API (issue 25, docs/online.md "The ROS 1 node").
//
// Two parts:
//   - OnlineFeed (no ROS type in it): serialised messages in (ROS 1 wire bytes + their type, as
//     topic_tools::ShapeShifter hands them over), a bounded queue, one worker thread that decodes
//     them with the same decoders `sonar3d import rosbag` uses (io/rosbag.hpp: RosSonarFrames,
//     RosStaticTransforms, decode_pose) and drives an OnlineMapper; the map goes out through a
//     Sink at the publishing rate. A ROS 2 front end would feed it CDR bytes the same way.
//   - the ROS 1 adapter: subscribers with ShapeShifter (marine_acoustic_msgs is not packaged in
//     Debian: the bytes are decoded by our own decoders), publishers and services.
// Without Debian's roscpp at build time the command prints that the build has no ROS 1 support.
#include <fmt/core.h>

#include <memory>
#include <string>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/recon/reconstruct.hpp"

#ifdef SONAR3D_HAVE_ROS1
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nav_msgs/MapMetaData.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <topic_tools/shape_shifter.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
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
  std::string window_dir, save_prefix;
  bool overwrite = false;
  double max_memory_gb = 0;
  std::string node_name = "sonar3d";
  std::unique_ptr<ConfigOptions<ReconstructConfig>> config;
};

#ifdef SONAR3D_HAVE_ROS1

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0, Clock::time_point t1) {
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

// Median, 95th percentile and maximum of a sample (ms); zeros when empty.
nlohmann::ordered_json latency_json(std::vector<double> v) {
  nlohmann::ordered_json j;
  j["count"] = v.size();
  if (v.empty()) {
    j["median"] = j["p95"] = j["max"] = 0.0;
    return j;
  }
  std::sort(v.begin(), v.end());
  j["median"] = v[v.size() / 2];
  j["p95"] =
      v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(v.size())))];
  j["max"] = v.back();
  return j;
}

// Where the map goes: the ROS 1 adapter publishes it; a ROS 2 one would too.
struct Sink {
  virtual ~Sink() = default;
  // `stamp`: header time of the newest frame carved (s); `frame`: the navigation's frame id.
  virtual void cloud(const PointCloud& cloud, double stamp, const std::string& frame) = 0;
  virtual bool wants_elevation() const = 0;
  virtual void elevation(const ElevationMap& map, double stamp, const std::string& frame) = 0;
  virtual void diagnostics(const nlohmann::ordered_json& stats) = 0;
  virtual void log(const std::string& line) = 0;
};

struct FeedConfig {
  std::string sonar_topic, nav_topic, tf_topic, base_frame, frame_id;
  std::optional<SonarSpec> described;
  std::optional<Eigen::Isometry3d> mount;
  std::optional<NoiseImages> noise;
  double vertical_aperture_rad = 0, time_offset = 0;
  double period_s = 1.0;   // publishing period
  std::size_t queue = 8;   // sonar messages waiting for the worker
  double tf_wait_s = 2.0;  // how long frames wait for /tf_static before the mounting is identity
  OnlineMapConfig map;
};

// The ROS-independent node: bounded queue → worker thread → OnlineMapper → Sink.
class OnlineFeed {
 public:
  enum class Kind { Sonar, Nav, Tf };

  OnlineFeed(FeedConfig cfg, Sink& sink) : cfg_(std::move(cfg)), sink_(sink) {
    worker_ = std::thread([this] { run(); });
  }
  ~OnlineFeed() { stop(); }

  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

  // Called from the subscriber callbacks: cheap (a copy of the bytes), never blocks on carving.
  // A sonar message beyond the queue bound pushes the oldest waiting one out (counted); navigation
  // and transforms are small and bounded by a larger limit.
  void push(Kind kind, const std::string& type, std::vector<std::uint8_t> bytes) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      Event e{kind, type, std::move(bytes), Clock::now()};
      if (kind == Kind::Sonar) {
        ++sonar_received_;
        if (sonar_queued_ >= cfg_.queue) {
          const auto it = std::find_if(events_.begin(), events_.end(),
                                       [](const Event& x) { return x.kind == Kind::Sonar; });
          events_.erase(it);
          --sonar_queued_;
          ++dropped_node_queue_;
        }
        ++sonar_queued_;
      } else {
        ++(kind == Kind::Nav ? nav_received_ : tf_received_);
        if (events_.size() >= kMaxEvents) {
          // Only navigation/transforms can fill it (sonar messages are bounded by cfg_.queue).
          const auto it = std::find_if(events_.begin(), events_.end(),
                                       [](const Event& x) { return x.kind != Kind::Sonar; });
          events_.erase(it);
          ++dropped_nav_queue_;
        }
      }
      events_.push_back(std::move(e));
    }
    cv_.notify_one();
  }

  // Runs `fn` on the worker thread between two messages and waits for it (services).
  std::string call(std::function<std::string()> fn) {
    auto task = std::make_shared<std::packaged_task<std::string()>>(std::move(fn));
    std::future<std::string> result = task->get_future();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return "the node is shutting down";
      tasks_.push_back([task] { (*task)(); });
    }
    cv_.notify_one();
    return result.get();  // rethrows what fn threw
  }

  // Saves the cloud (PLY) and the elevation map (GeoTIFF) as PREFIX.ply, PREFIX.tif, atomically
  // and together, under the output rule; on the worker thread (call()).
  std::string save(const std::string& prefix, bool overwrite) {
    if (prefix.empty()) throw Error("no --save-prefix: the node was started without a save path");
    if (!mapper_) throw Error("nothing to save yet: no frame has been carved");
    // Files this run wrote may be replaced by its next save; others only with --overwrite.
    OutputFiles out(output_policy(overwrite || saved_once_, {}));
    const auto ply = out.add(prefix + ".ply", OutputKind::PointCloud, "--save-prefix");
    const auto tif = out.add(prefix + ".tif", OutputKind::GeoTiff, "--save-prefix");
    const PointCloud cloud = mapper_->cloud();
    write_ply(ply.string(), cloud);
    const ElevationMap dem = mapper_->elevation();
    if (!dem.empty()) write_elevation_geotiff(tif.string(), dem);
    out.commit();
    saved_once_ = true;
    return fmt::format("wrote {} points to {}.ply{}", cloud.size(), prefix,
                       dem.empty() ? " (no elevation map: empty)"
                                   : fmt::format(" and a {}×{} elevation map to {}.tif", dem.cols,
                                                 dem.rows, prefix));
  }

  std::string reset() {
    if (mapper_) mapper_->reset();
    pending_arrivals_.clear();
    waiting_.clear();
    latency_carved_.clear();
    latency_published_.clear();
    carved_since_publish_.clear();
    last_stamp_ = 0;
    return "map, navigation and map counters cleared";
  }

  nlohmann::ordered_json stats() {
    nlohmann::ordered_json j;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      j["sonar_received"] = sonar_received_;
      j["navigation_received"] = nav_received_;
      j["tf_received"] = tf_received_;
      j["queued"] = sonar_queued_;
      j["dropped_node_queue_full"] = dropped_node_queue_;
      j["dropped_navigation_queue_full"] = dropped_nav_queue_;
    }
    j["bad_sonar_messages"] = bad_sonar_;
    j["bad_navigation_messages"] = bad_nav_;
    j["bad_tf_messages"] = bad_tf_;
    j["dropped_waiting_for_mounting"] = dropped_mounting_;
    j["clouds_published"] = clouds_published_;
    j["cloud_points"] = cloud_points_;
    j["frames_in_cloud"] = frames_in_cloud_;
    j["mounting"] = mounting_source_;
    j["latency_arrival_to_carved_ms"] = latency_json(latency_carved_);
    j["latency_arrival_to_published_ms"] = latency_json(latency_published_);
    if (mapper_) {
      const OnlineMapStats ms = mapper_->stats();  // walks the map: once a publishing period
      j["frames_dropped_by_map"] = ms.dropped();
      j["map"] = nlohmann::ordered_json::parse(ms.to_json());
    } else {
      j["frames_dropped_by_map"] = 0;
      j["map"] = nlohmann::ordered_json::object();
    }
    return j;
  }

 private:
  struct Event {
    Kind kind;
    std::string type;
    std::vector<std::uint8_t> bytes;
    Clock::time_point arrived;
  };
  static constexpr std::size_t kMaxEvents = 100000;
  static constexpr std::size_t kMaxLatencies = 10000;

  void run() {
    auto next_publish = Clock::now() + period();
    for (;;) {
      std::optional<Event> e;
      std::vector<std::function<void()>> tasks;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait_until(lock, next_publish,
                       [&] { return stop_ || !events_.empty() || !tasks_.empty(); });
        if (stop_) break;
        tasks.swap(tasks_);
        if (!events_.empty()) {
          e = std::move(events_.front());
          events_.pop_front();
          if (e->kind == Kind::Sonar) --sonar_queued_;
        }
      }
      for (auto& t : tasks) t();
      if (e) handle(*e);
      if (Clock::now() >= next_publish) {
        try {
          try_start();  // the wait for /tf_static may have run out (identity mounting)
        } catch (const std::exception& err) {
          sink_.log(std::string("no mounting: ") + err.what());
        }
        publish_or_log();
        next_publish = Clock::now() + period();
      }
    }
    // Shutting down: what was carved goes out once more.
    publish_or_log();
  }

  void publish_or_log() {
    try {
      publish();
    } catch (const std::exception& err) {
      sink_.log(std::string("publishing failed: ") + err.what());
    }
  }

  Clock::duration period() const {
    return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(cfg_.period_s));
  }

  void handle(const Event& e) {
    const std::string& topic = e.kind == Kind::Sonar ? cfg_.sonar_topic
                               : e.kind == Kind::Nav ? cfg_.nav_topic
                                                     : cfg_.tf_topic;
    const std::string where = topic + " (" + e.type + ")";
    try {
      switch (e.kind) {
        case Kind::Tf:
          if (ros_type_name(e.type) != "tf2_msgs/TFMessage") {
            throw Error(where + ": not tf2_msgs/TFMessage");
          }
          statics_.add(decode_tf(e.bytes.data(), e.bytes.size(), RosWire::Ros1, where));
          try_start();
          return;
        case Kind::Nav:
          handle_nav(e, where);
          return;
        case Kind::Sonar:
          handle_sonar(e, where);
          return;
      }
    } catch (const std::exception& err) {
      ++(e.kind == Kind::Sonar ? bad_sonar_ : e.kind == Kind::Nav ? bad_nav_ : bad_tf_);
      sink_.log(std::string("skipped a bad message: ") + err.what());
    }
  }

  void handle_nav(const Event& e, const std::string& where) {
    if (!is_ros_nav_type(e.type)) {
      throw Error(where +
                  ": not nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                  "PoseWithCovarianceStamped");
    }
    const RosPose m = decode_pose(e.type, e.bytes.data(), e.bytes.size(), RosWire::Ros1, where);
    if (body_frame_.empty()) body_frame_ = ros_tf_frame(m.child_frame_id);
    if (nav_frame_.empty()) nav_frame_ = m.frame_id;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = m.orientation.normalized().toRotationMatrix();
    T.translation() = m.position;
    const double t = m.stamp.seconds();
    if (!mapper_) {
      // Kept until the first frame gives the sensor (bounded: the newest ones).
      early_nav_.emplace_back(t, T);
      if (early_nav_.size() > 10000) early_nav_.pop_front();
      return;
    }
    const std::size_t used = mapper_->frames_used();
    if (!mapper_->push_navigation(t, T)) {
      sink_.log(
          fmt::format("{}: navigation sample at {:.6f} s rejected (not finite, not rigid or "
                      "not after the previous one)",
                      where, t));
    }
    carved(mapper_->frames_used() - used, Clock::now());
  }

  // Frames carved: the oldest arrivals waiting for navigation (FIFO: pending images are carved in
  // time order).
  void carved(std::size_t k, Clock::time_point now) {
    for (; k > 0 && !pending_arrivals_.empty(); --k) {
      add_latency(latency_carved_, ms_since(pending_arrivals_.front(), now));
      carved_since_publish_.push_back(pending_arrivals_.front());
      pending_arrivals_.pop_front();
    }
  }
  static void add_latency(std::vector<double>& v, double ms) {
    if (v.size() >= kMaxLatencies) v.erase(v.begin(), v.begin() + kMaxLatencies / 2);
    v.push_back(ms);
  }

  // The mapper is made on the first frame whose mounting is known.
  bool make_mapper(const std::string& where) {
    std::string source = "identity (no static transform)";
    Eigen::Isometry3d T_vehicle_frame = Eigen::Isometry3d::Identity();
    bool from_tf = false;
    if (cfg_.mount) {
      source = "--mount";
    } else if (!statics_.empty()) {
      const std::string base =
          !cfg_.base_frame.empty() ? ros_tf_frame(cfg_.base_frame) : body_frame_;
      std::string chain;
      int depth = 0;
      T_vehicle_frame = statics_.chain(base, frames_->frame_id(), cfg_.tf_topic, &chain, &depth);
      if (depth > 0) {
        source = cfg_.tf_topic + ": " + chain;
        from_tf = true;
      }
    } else if (ms_since(first_frame_, Clock::now()) < cfg_.tf_wait_s * 1e3) {
      return false;  // no static transform yet: wait (frames dropped, counted)
    }
    const SonarSpec spec = frames_->set_mounting(cfg_.mount, T_vehicle_frame, from_tf, where);
    mapper_ = std::make_unique<OnlineMapper>(spec, cfg_.map, cfg_.noise);
    mounting_source_ = source;
    sink_.log(fmt::format("sonar {} range bins × {} beams, {:.3f}–{:.3f} m; mounting: {}",
                          spec.range_bins, spec.beams(), spec.r_min, spec.r_max, source));
    for (const auto& [t, T] : early_nav_) mapper_->push_navigation(t, T);
    early_nav_.clear();
    return true;
  }

  void handle_sonar(const Event& e, const std::string& where) {
    if (!frames_) {
      frames_.emplace(e.type, RosWire::Ros1, e.bytes.data(), e.bytes.size(), where, cfg_.described,
                      cfg_.vertical_aperture_rad);
      first_frame_ = e.arrived;  // --tf-wait counts from here
    }
    if (!mapper_) {
      // Frames wait (bounded: max_pending_images, the oldest dropped and counted) until the
      // mounting is known: /tf_static and the first frames come on different connections, in no
      // set order.
      waiting_.push_back(e);
      if (waiting_.size() > cfg_.map.max_pending_images) {
        waiting_.pop_front();
        if (dropped_mounting_++ == 0) {
          sink_.log("frames wait for the mounting on " + cfg_.tf_topic +
                    "; the oldest are dropped (counted)");
        }
      }
      try_start();
      return;
    }
    carve(e, where);
  }

  // Makes the mapper when the mounting is known and carves the frames that waited for it.
  void try_start() {
    if (mapper_ || !frames_ || waiting_.empty()) return;
    if (!make_mapper(cfg_.sonar_topic)) return;
    std::deque<Event> waiting;
    waiting.swap(waiting_);
    for (const Event& w : waiting) {
      const std::string where = cfg_.sonar_topic + " (" + w.type + ")";
      try {
        carve(w, where);
      } catch (const std::exception& err) {
        ++bad_sonar_;
        sink_.log(std::string("skipped a bad message: ") + err.what());
      }
    }
  }

  void carve(const Event& e, const std::string& where) {
    const double t = frames_->decode(e.bytes.data(), e.bytes.size(), where, image_);
    image_.timestamp = t + cfg_.time_offset;
    const std::size_t used = mapper_->frames_used();
    const FrameDrop d = mapper_->push_image(image_.timestamp, image_);
    const std::size_t now_used = mapper_->frames_used(), pending = mapper_->frames_pending();
    if (d != FrameDrop::None) {
      sink_.log(fmt::format("{}: frame at {:.6f} s dropped ({})", where, image_.timestamp,
                            frame_drop_name(d)));
    } else {
      pending_arrivals_.push_back(e.arrived);
      // Bounded by the mapper's own pending queue (max_pending_images).
      while (pending_arrivals_.size() > pending + (now_used - used)) {
        pending_arrivals_.pop_front();
      }
    }
    last_stamp_ = std::max(last_stamp_, image_.timestamp);
    carved(now_used - used, Clock::now());
  }

  void publish() {
    if (mapper_) {
      const std::size_t used = mapper_->frames_used();
      if (used != frames_in_cloud_ || clouds_published_ == 0) {
        const PointCloud cloud = mapper_->cloud();
        const std::string frame = !cfg_.frame_id.empty() ? cfg_.frame_id
                                  : !nav_frame_.empty()  ? nav_frame_
                                                         : "map";
        sink_.cloud(cloud, last_stamp_, frame);
        if (sink_.wants_elevation()) sink_.elevation(mapper_->elevation(), last_stamp_, frame);
        const auto now = Clock::now();
        for (const auto& a : carved_since_publish_)
          add_latency(latency_published_, ms_since(a, now));
        carved_since_publish_.clear();
        frames_in_cloud_ = used;
        cloud_points_ = cloud.size();
        ++clouds_published_;
      }
    }
    sink_.diagnostics(stats());
  }

  FeedConfig cfg_;
  Sink& sink_;
  Clock::time_point first_frame_;
  std::thread worker_;
  std::mutex mutex_;  // guards what the callbacks touch: events_, tasks_, the arrival counters
  std::condition_variable cv_;
  std::deque<Event> events_;
  std::vector<std::function<void()>> tasks_;
  bool stop_ = false;
  std::size_t sonar_queued_ = 0, sonar_received_ = 0, nav_received_ = 0, tf_received_ = 0;
  std::size_t dropped_node_queue_ = 0, dropped_nav_queue_ = 0;
  // Worker thread only.
  std::optional<RosSonarFrames> frames_;
  RosStaticTransforms statics_;
  std::unique_ptr<OnlineMapper> mapper_;
  SonarImage image_;
  std::deque<std::pair<double, Eigen::Isometry3d>> early_nav_;
  std::deque<Clock::time_point> pending_arrivals_;
  std::deque<Event> waiting_;  // frames that came before the mounting
  std::vector<Clock::time_point> carved_since_publish_;
  std::vector<double> latency_carved_, latency_published_;
  std::string body_frame_, nav_frame_, mounting_source_ = "not yet known";
  std::size_t bad_sonar_ = 0, bad_nav_ = 0, bad_tf_ = 0, dropped_mounting_ = 0;
  std::size_t clouds_published_ = 0, cloud_points_ = 0, frames_in_cloud_ = 0;
  double last_stamp_ = 0;
  bool saved_once_ = false;
};

// ------------------------------------------------------------------ the ROS 1 adapter

ros::Time ros_time(double t) {
  if (!(t > 0)) return ros::Time(0, 0);
  const RosTime r = RosTime::from_seconds(t);
  return ros::Time(static_cast<std::uint32_t>(r.sec), r.nanosec);
}

class Ros1Sink : public Sink {
 public:
  explicit Ros1Sink(ros::NodeHandle& nh) {
    cloud_ = nh.advertise<sensor_msgs::PointCloud2>("/sonar3d/cloud", 2, true);
    elevation_ = nh.advertise<sensor_msgs::Image>("/sonar3d/elevation", 2, true);
    elevation_info_ = nh.advertise<nav_msgs::MapMetaData>("/sonar3d/elevation_info", 2, true);
    diagnostics_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/sonar3d/diagnostics", 10);
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

  void diagnostics(const nlohmann::ordered_json& stats) override {
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
  ros::Publisher cloud_, elevation_, elevation_info_, diagnostics_;
};

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal = sig; }

std::vector<std::uint8_t> shape_bytes(const topic_tools::ShapeShifter& m) {
  std::vector<std::uint8_t> bytes(m.size());
  ros::serialization::OStream s(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  m.write(s);
  return bytes;
}

int run_ros(const RosCliOptions& o, const ReconstructConfig& rc, const GlobalOptions& g) {
  if (rc.method != "carve") {
    throw Error("the online map carves (--method carve); '" + rc.method + "' is batch only");
  }
  FeedConfig fc;
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
  if (!o.save_prefix.empty()) {
    // Fail now, not at the first save request.
    check_output(o.save_prefix + ".ply", OutputKind::PointCloud, output_policy(o.overwrite, {}),
                 "--save-prefix");
    check_output(o.save_prefix + ".tif", OutputKind::GeoTiff, output_policy(o.overwrite, {}),
                 "--save-prefix");
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
  OnlineFeed feed(fc, sink);

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
        res.message = feed.call(fn);
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
               "/sonar3d/cloud at {} Hz; services {}/save, {}/reset\n",
               ros::this_node::getName(), o.sonar_topic, o.nav_topic,
               fc.mount ? "" : ", " + o.tf_topic + " (mounting)", o.rate_hz,
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
  const nlohmann::ordered_json final_stats = feed.stats();
  spinner.stop();
  ros::shutdown();
  // The run's statistics on standard output (one JSON object), for scripts and benchmarks.
  fmt::print("{}\n", final_stats.dump());
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
      "(nav_msgs/MapMetaData) and /sonar3d/diagnostics (diagnostic_msgs/DiagnosticArray); "
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
                  "GeoTIFF), together; replaces files sonar3d wrote only with --overwrite (or "
                  "this run's earlier save)");
  add_overwrite_flag(cmd, o->overwrite, "a cloud and GeoTIFF at --save-prefix sonar3d wrote");
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->add_option("--duration", o->duration_s, "stop after this long (0 = until a signal), s")
      ->capture_default_str();
  cmd->add_option("--node-name", o->node_name, "ROS node name")->capture_default_str();
  // The carving settings, from ReconstructConfig's one declaration (recon/reconstruct.hpp), with
  // --print-config and --config: a file `sonar3d reconstruct --print-config` wrote works here.
  o->config = std::make_unique<ConfigOptions<ReconstructConfig>>(cmd);
  cmd->callback([&g, &run, o] {
    const FlagNames flags = o->config->flag_names();
    run = [&g, o, flags]() -> int {
      return with_flag_names(flags, [&]() -> int {
        const ReconstructConfig cfg = o->config->resolve("reconstruct");
        cfg.validate();
        if (o->config->print_if_requested(cfg, "reconstruct", "ros")) return 0;
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
