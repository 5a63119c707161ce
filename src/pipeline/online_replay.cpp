// A recording replayed into an OnlineFeed at its recorded rate (pipeline/online_replay.hpp).
#include "sonar3d/pipeline/online_replay.hpp"

#include <stdlib.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/rosbag.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

// A directory removed when it goes out of scope.
struct TempDir {
  fs::path path;
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "sonar3d_replay_XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
      throw Error("cannot create a temporary directory under " +
                  fs::temp_directory_path().string());
    }
    path = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

struct Message {
  std::int64_t t_ns;
  OnlineFeed::Kind kind;
  const std::string* type;
  std::vector<std::uint8_t> bytes;
};

}  // namespace

OnlineReplayResult replay_into_feed(const fs::path& input, OnlineFeed& feed,
                                    const OnlineFeedConfig& config,
                                    const OnlineReplayOptions& options) {
  require(std::isfinite(options.speed) && options.speed >= 0,
          "replay: the speed must be >= 0 (0: as fast as the feed handles the messages)");
  std::optional<TempDir> tmp;
  fs::path bag_path = input;
  if (fs::is_directory(input) && fs::is_regular_file(input / "sonar.yaml")) {
    // A dataset: the ROS 1 bag `sonar3d export rosbag --ros1` writes of it.
    tmp.emplace();
    bag_path = tmp->path / "dataset.bag";
    RosbagExportConfig ec;
    ec.wire = RosWire::Ros1;
    ec.sonar_topic = config.sonar_topic;
    if (!config.nav_topic.empty()) ec.nav_topic = config.nav_topic;
    export_rosbag(input, bag_path, ec, options.progress);
  } else if (!fs::is_regular_file(input)) {
    throw Error("'" + input.string() +
                "' is neither a ROS 1 bag (.bag) nor a dataset directory (sonar.yaml)");
  }
  const std::unique_ptr<BagReader> bag = BagReader::open(bag_path);
  if (bag->wire() != RosWire::Ros1) {
    throw Error("'" + input.string() + "' is a " + bag->format() +
                " bag: the online feed reads ROS 1 messages (give a ROS 1 bag or a dataset)");
  }
  const BagTopic* sonar = bag->find(config.sonar_topic);
  if (sonar == nullptr) {
    std::string names;
    for (const BagTopic& t : bag->topics()) names += (names.empty() ? "" : ", ") + t.name;
    throw Error("'" + input.string() + "' has no sonar topic '" + config.sonar_topic +
                "' (its topics: " + names + ")");
  }
  // Navigation and static transforms are small: read first, merged into the sonar stream by
  // time; the sonar messages stream from the bag.
  std::vector<Message> others;
  for (const auto& [topic, kind] :
       {std::pair<std::string, OnlineFeed::Kind>(config.nav_topic, OnlineFeed::Kind::Nav),
        {config.tf_topic, OnlineFeed::Kind::Tf}}) {
    const BagTopic* bt = topic.empty() ? nullptr : bag->find(topic);
    if (bt == nullptr) continue;
    bag->read(topic, [&](std::int64_t t, const std::uint8_t* p, std::size_t n, const std::string&) {
      others.push_back({t, kind, &bt->type, std::vector<std::uint8_t>(p, p + n)});
    });
  }
  std::stable_sort(others.begin(), others.end(),
                   [](const Message& a, const Message& b) { return a.t_ns < b.t_ns; });
  std::int64_t t_first = others.empty() ? 0 : others.front().t_ns;
  bool any_sonar = bag->read_first(config.sonar_topic, [&](std::int64_t t, const std::uint8_t*,
                                                           std::size_t, const std::string&) {
    if (others.empty() || t < t_first) t_first = t;
  });
  if (!any_sonar && others.empty()) throw Error("'" + input.string() + "' has no message to play");

  OnlineReplayResult result;
  const auto wall0 = std::chrono::steady_clock::now();
  std::int64_t t_last = t_first;
  auto emit = [&](std::int64_t t, OnlineFeed::Kind kind, const std::string& type,
                  std::vector<std::uint8_t> bytes) {
    if (result.stopped || (options.stop && options.stop())) {
      result.stopped = true;
      return;
    }
    if (options.speed > 0) {
      const double at_s = static_cast<double>(t - t_first) * 1e-9 / options.speed;
      std::this_thread::sleep_until(wall0 +
                                    std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        std::chrono::duration<double>(at_s)));
    }
    feed.push(kind, type, std::move(bytes));
    if (options.speed == 0) feed.drain();
    ++(kind == OnlineFeed::Kind::Sonar ? result.sonar
       : kind == OnlineFeed::Kind::Nav ? result.navigation
                                       : result.tf);
    t_last = std::max(t_last, t);
  };
  std::size_t next = 0;
  bag->read(config.sonar_topic, [&](std::int64_t t, const std::uint8_t* p, std::size_t n,
                                    const std::string&) {
    for (; next < others.size() && others[next].t_ns <= t; ++next) {
      emit(others[next].t_ns, others[next].kind, *others[next].type, std::move(others[next].bytes));
    }
    emit(t, OnlineFeed::Kind::Sonar, sonar->type, std::vector<std::uint8_t>(p, p + n));
  });
  for (; next < others.size(); ++next) {
    emit(others[next].t_ns, others[next].kind, *others[next].type, std::move(others[next].bytes));
  }
  result.recorded_s = static_cast<double>(t_last - t_first) * 1e-9;
  return result;
}

}  // namespace sonar3d
