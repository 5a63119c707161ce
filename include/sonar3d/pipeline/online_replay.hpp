#pragma once
// Replays a recording into an OnlineFeed (pipeline/online_feed.hpp) as a live vehicle would send
// it: the core of `sonar3d online` (docs/online.md "Replaying a recording"). The messages of the
// feed's sonar, navigation and tf topics go in receive-time order, each at its recorded time
// (scaled by 1/speed), so the feed's queue, drops, latencies and publishing behave as they would
// in the ROS 1 node, without ROS.
#include <cstddef>
#include <filesystem>
#include <functional>

#include "sonar3d/pipeline/online_feed.hpp"

namespace sonar3d {

struct OnlineReplayOptions {
  // 1 = the recorded rate, 2 = twice as fast; 0 = as fast as the feed handles them (each message
  // waits until the previous one was handled: nothing is dropped for speed).
  double speed = 1.0;
  std::function<bool()> stop;  // polled between messages: true ends the replay early
  bool progress = false;       // the export's progress bar (a dataset input)
};

struct OnlineReplayResult {
  std::size_t sonar = 0, navigation = 0, tf = 0;  // messages pushed
  double recorded_s = 0;                          // recorded time span of the messages pushed
  bool stopped = false;                           // ended early by options.stop
};

// `input`: a ROS 1 bag (.bag), or a dataset directory (sonar.yaml), exported first to a ROS 1 bag
// in a temporary directory (as `sonar3d export rosbag --ros1`: its topics are the feed's
// defaults, /sonar3d/image and /sonar3d/odom, and /tf_static), removed afterwards. Topics come
// from `config` (the feed's). Errors name the input: neither a bag nor a dataset, a ROS 2 bag
// (the feed decodes the ROS 1 wire), a sonar topic the bag lacks.
OnlineReplayResult replay_into_feed(const std::filesystem::path& input, OnlineFeed& feed,
                                    const OnlineFeedConfig& config,
                                    const OnlineReplayOptions& options = {});

}  // namespace sonar3d
