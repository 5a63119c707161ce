#pragma once
// An online map fed with serialised ROS messages (issue 25; docs/online.md "The ROS 1 node"): the
// part of `sonar3d ros` that has no ROS type in it, so that any front end (the ROS 1 node, a ROS 2
// one, a replayed bag, a test) drives it the same way.
//
//   OnlineFeed feed(config, sink);            // starts one worker thread
//   feed.push(OnlineFeed::Kind::Sonar, "sensor_msgs/Image", bytes);   // from any thread
//   ...                                        // the sink receives the map every period_s
//   feed.stop();                               // publishes once more, joins the worker
//
// Messages (ROS 1 wire bytes and their type, as a subscriber hands them over) go into a bounded
// queue; the worker decodes them with the decoders `sonar3d import rosbag` uses (io/rosbag.hpp:
// RosSonarFrames, RosStaticTransforms, decode_pose) and drives an OnlineMapper
// (mapping/online.hpp). The mounting comes from `mount`, else from the static transforms on the
// tf topic (frames wait for it up to tf_wait_s, then identity). Bad messages are skipped, counted
// and logged through the sink; nothing a message holds stops the feed.
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/online.hpp"
#include "sonar3d/pipeline/online_recognition.hpp"

namespace sonar3d {

// Where the map goes (the ROS 1 node publishes it). Called on the feed's worker thread.
struct OnlineFeedSink {
  virtual ~OnlineFeedSink() = default;
  // `stamp`: header time of the newest frame carved (s); `frame`: the navigation's frame id
  // (or the configured one, else "map").
  virtual void cloud(const PointCloud& cloud, double stamp, const std::string& frame) = 0;
  virtual bool wants_elevation() const = 0;
  virtual void elevation(const ElevationMap& map, double stamp, const std::string& frame) = 0;
  // The counters (OnlineFeed::stats_json()) once a publishing period.
  virtual void diagnostics(const std::string& stats_json) = 0;
  virtual void log(const std::string& line) = 0;
  // With a catalogue: each recognition of the map that finished (pipeline/online_recognition.hpp),
  // in the cloud's frame. Called on the recognizer's thread, not the worker's.
  virtual void placements(const OnlinePlacements& /*found*/) {}
};

struct OnlineFeedConfig {
  std::string sonar_topic, nav_topic, tf_topic, base_frame;  // for messages and the tf chain
  std::string frame_id;                    // the published frame ("" = the navigation's)
  std::optional<SonarSpec> described;      // sensor description (required for Image topics)
  std::optional<Eigen::Isometry3d> mount;  // T_vehicle_sonar; none = from the static transforms
  std::optional<NoiseImages> noise;        // per-pixel noise statistics for the Z-test
  double vertical_aperture_rad = 0;        // overrides the message's / description's; 0 = theirs
  double time_offset = 0;                  // s added to sonar stamps to reach the nav clock
  double period_s = 1.0;                   // publishing period, s
  std::size_t queue = 8;                   // sonar messages waiting for the worker
  double tf_wait_s = 2.0;  // how long frames wait for static transforms before identity, s
  OnlineMapConfig map;
  // With a catalogue (a file as `sonar3d recognize --catalogue` reads): the map is recognised
  // every recognition.period_s on a snapshot of the published cloud, on its own thread
  // (OnlineRecognizer); the sink receives placements(). "" = no recognition.
  std::string catalogue;
  RecognizeConfig recognize;
  OnlineRecognitionConfig recognition;
  std::string mesh_dir;   // where the models' meshes are written ("" = a temporary directory)
  void validate() const;  // throws Error naming the field
};

class OnlineFeed {
 public:
  enum class Kind { Sonar, Nav, Tf };

  // Starts the worker thread. Throws Error on an invalid config.
  OnlineFeed(const OnlineFeedConfig& config, OnlineFeedSink& sink);
  ~OnlineFeed();  // stop()
  OnlineFeed(const OnlineFeed&) = delete;
  OnlineFeed& operator=(const OnlineFeed&) = delete;

  // Cheap (a copy of the bytes), never blocks on carving; from any thread. A sonar message
  // beyond the queue bound pushes the oldest waiting one out (counted); navigation and
  // transforms are bounded by a larger limit.
  void push(Kind kind, const std::string& type, std::vector<std::uint8_t> bytes);

  // Waits until every message pushed so far has been handled (replays, tests).
  void drain();

  // Saves the cloud (PREFIX.ply), the elevation map (PREFIX.tif) and, with a catalogue, the last
  // recognition's placements (PREFIX.placements.json, as `sonar3d recognize -o` writes them; none
  // until one has finished), atomically and together, under the output rule (files this feed wrote
  // may be replaced by its next save; others only with `overwrite`); on the worker thread. Returns
  // a line saying what was written.
  std::string save(const std::string& prefix, bool overwrite);
  // Clears the map, the navigation and the map's counters; on the worker thread.
  std::string reset();

  // With a catalogue: publishes the cloud if frames were carved since the last one, then
  // recognises it now, waiting for a running recognition first and for this one (the end of a
  // replay: the placements of the complete map); on the worker thread. Returns a line saying
  // what was found.
  std::string recognize_now();

  // Every counter as one JSON object (received, queued, dropped, bad, latencies, the map's own).
  std::string stats_json();

  // Publishes what was carved once more and joins the worker. Idempotent.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonar3d
