// The ROS-independent online node (pipeline/online_feed.hpp): bounded queue → worker thread →
// OnlineMapper → sink. Moved here from the ROS 1 command so that every front end and the tests
// drive the same code.
#include "sonar3d/pipeline/online_feed.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/rosbag.hpp"

namespace sonar3d {

namespace {

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

}  // namespace

void OnlineFeedConfig::validate() const {
  require(std::isfinite(period_s) && period_s >= 1e-3 && period_s <= 3600,
          "online feed: period_s must lie in [0.001, 3600] s");
  require(queue >= 1, "online feed: queue must be at least 1");
  require(std::isfinite(tf_wait_s) && tf_wait_s >= 0, "online feed: tf_wait_s must be >= 0 s");
  require(std::isfinite(time_offset), "online feed: time_offset must be finite");
  require(std::isfinite(vertical_aperture_rad) && vertical_aperture_rad >= 0,
          "online feed: vertical_aperture must be >= 0");
  require(!sonar_topic.empty(), "online feed: no sonar topic");
  if (mount) require(mount->matrix().allFinite(), "online feed: the mounting is not finite");
  map.validate();
  if (!catalogue.empty()) {
    recognize.validate();
    recognition.validate();
  }
}

struct OnlineFeed::Impl {
  Impl(const OnlineFeedConfig& cfg, OnlineFeedSink& sink) : cfg_(cfg), sink_(sink) {
    if (!cfg_.catalogue.empty()) {
      recognizer_ = std::make_unique<OnlineRecognizer>(
          cfg_.catalogue, cfg_.recognize, cfg_.recognition,
          [this](const OnlinePlacements& p) { sink_.placements(p); },
          [this](const std::string& line) { sink_.log(line); }, cfg_.mesh_dir);
    }
    worker_ = std::thread([this] { run(); });
  }

  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    idle_.notify_all();
    if (worker_.joinable()) worker_.join();
    // No placements reach the sink after stop().
    if (recognizer_) recognizer_->wait();
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

  bool stopped() {
    std::lock_guard<std::mutex> lock(mutex_);
    return stop_;
  }

  void drain() {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [&] { return stop_ || (events_.empty() && tasks_.empty() && !busy_); });
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
    const std::optional<OnlinePlacements> found =
        recognizer_ ? recognizer_->latest() : std::nullopt;
    // Files this run wrote may be replaced by its next save; others only with --overwrite.
    OutputPolicy policy;
    policy.overwrite = overwrite || saved_once_;
    OutputFiles out(policy);
    const PointCloud cloud = mapper_->cloud();
    const ElevationMap dem = mapper_->elevation();
    const auto ply = out.add(prefix + ".ply", OutputKind::PointCloud, "--save-prefix");
    write_ply(ply.string(), cloud);
    if (!dem.empty()) {  // an empty map: no GeoTIFF (the pair is the cloud alone)
      const auto tif = out.add(prefix + ".tif", OutputKind::GeoTiff, "--save-prefix");
      write_elevation_geotiff(tif.string(), dem);
    }
    if (found) {
      const auto json =
          out.add(prefix + ".placements.json", OutputKind::PlacementsJson, "--save-prefix");
      write_text_file(json.string(), found->json);
    }
    out.commit();
    saved_once_ = true;
    std::string placements;
    if (found) {
      placements = fmt::format("; {} placements (recognition of {} frames) to {}.placements.json",
                               found->placements.size(), found->frames, prefix);
    } else if (recognizer_) {
      placements = "; no placements yet (no recognition has finished)";
    }
    return fmt::format("wrote {} points to {}.ply{}{}", cloud.size(), prefix,
                       dem.empty() ? " (no elevation map: empty)"
                                   : fmt::format(" and a {}×{} elevation map to {}.tif", dem.cols,
                                                 dem.rows, prefix),
                       placements);
  }

  std::string reset() {
    if (mapper_) mapper_->reset();
    pending_arrivals_.clear();
    waiting_.clear();
    latency_carved_.clear();
    latency_published_.clear();
    carved_since_publish_.clear();
    last_stamp_ = 0;
    last_cloud_.reset();
    if (recognizer_) recognizer_->reset();
    return "map, navigation and map counters cleared";
  }

  std::string recognize_now() {
    if (!recognizer_) throw Error("no --catalogue: the feed recognises nothing");
    if (!mapper_) throw Error("nothing to recognise yet: no frame has been carved");
    publish();  // the cloud of every frame carved so far (when it changed)
    const std::string frame = !cfg_.frame_id.empty() ? cfg_.frame_id
                              : !nav_frame_.empty()  ? nav_frame_
                                                     : "map";
    recognizer_->run_now(frames_in_cloud_, last_cloud_, cloud_stamp_, frame);
    const std::optional<OnlinePlacements> found = recognizer_->latest();
    if (!found) return "no recognition finished (see the log)";
    std::string line = fmt::format("{} placements in the map of {} frames ({:.2f} s)",
                                   found->placements.size(), found->frames, found->seconds);
    for (const Placement& p : found->placements) {
      const Eigen::Vector3d t = p.T_world_model.translation();
      line += fmt::format("; {} at {:.3f} {:.3f} {:.3f} m, confidence {:.2f}", p.model, t.x(),
                          t.y(), t.z(), p.confidence);
    }
    return line;
  }

  std::string stats_json() { return stats().dump(); }

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
    if (recognizer_) j["recognition"] = nlohmann::ordered_json::parse(recognizer_->stats_json());
    return j;
  }

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
        busy_ = !events_.empty() || !tasks_.empty();
        tasks.swap(tasks_);
        if (!events_.empty()) {
          e = std::move(events_.front());
          events_.pop_front();
          if (e->kind == Kind::Sonar) --sonar_queued_;
        }
      }
      for (auto& t : tasks) t();
      if (e) handle(*e);
      {
        std::lock_guard<std::mutex> lock(mutex_);
        busy_ = false;
      }
      idle_.notify_all();
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
      const std::string frame = !cfg_.frame_id.empty() ? cfg_.frame_id
                                : !nav_frame_.empty()  ? nav_frame_
                                                       : "map";
      if (used != frames_in_cloud_ || clouds_published_ == 0) {
        auto snapshot = std::make_shared<const PointCloud>(mapper_->cloud());
        const PointCloud& cloud = *snapshot;
        sink_.cloud(cloud, last_stamp_, frame);
        if (sink_.wants_elevation()) sink_.elevation(mapper_->elevation(), last_stamp_, frame);
        const auto now = Clock::now();
        for (const auto& a : carved_since_publish_)
          add_latency(latency_published_, ms_since(a, now));
        carved_since_publish_.clear();
        frames_in_cloud_ = used;
        cloud_points_ = cloud.size();
        ++clouds_published_;
        // Kept for the recognition (an immutable snapshot it shares while carving goes on).
        if (recognizer_) {
          last_cloud_ = std::move(snapshot);
          cloud_stamp_ = last_stamp_;
        }
      }
      // Starts a recognition of the last published cloud when its period has come.
      if (recognizer_) {
        recognizer_->tick(Clock::now(), frames_in_cloud_, last_cloud_, cloud_stamp_, frame);
      }
    }
    sink_.diagnostics(stats_json());
  }

  OnlineFeedConfig cfg_;
  OnlineFeedSink& sink_;
  Clock::time_point first_frame_;
  std::thread worker_;
  std::mutex mutex_;  // guards what the callbacks touch: events_, tasks_, the arrival counters
  std::condition_variable cv_;
  std::deque<Event> events_;
  std::vector<std::function<void()>> tasks_;
  bool stop_ = false;
  bool busy_ = false;  // the worker is handling an event or a task (drain())
  std::condition_variable idle_;
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
  std::unique_ptr<OnlineRecognizer> recognizer_;  // with a catalogue
  std::shared_ptr<const PointCloud> last_cloud_;  // the last published cloud, for recognition
  double cloud_stamp_ = 0;
};

OnlineFeed::OnlineFeed(const OnlineFeedConfig& config, OnlineFeedSink& sink) {
  config.validate();
  impl_ = std::make_unique<Impl>(config, sink);
}
OnlineFeed::~OnlineFeed() { stop(); }
void OnlineFeed::push(Kind kind, const std::string& type, std::vector<std::uint8_t> bytes) {
  impl_->push(kind, type, std::move(bytes));
}
void OnlineFeed::drain() { impl_->drain(); }
std::string OnlineFeed::save(const std::string& prefix, bool overwrite) {
  return impl_->call([&] { return impl_->save(prefix, overwrite); });
}
std::string OnlineFeed::reset() {
  return impl_->call([&] { return impl_->reset(); });
}
std::string OnlineFeed::recognize_now() {
  return impl_->call([&] { return impl_->recognize_now(); });
}
std::string OnlineFeed::stats_json() {
  // Once stopped, the worker is joined: the counters are read here.
  if (impl_->stopped()) return impl_->stats_json();
  return impl_->call([&] { return impl_->stats_json(); });
}
void OnlineFeed::stop() {
  if (impl_) impl_->stop();
}

}  // namespace sonar3d
