#pragma once
// Internal to src/io: the two bag storages behind BagReader and the writers used by
// export_rosbag.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sonar3d/io/rosbag.hpp"

namespace sonar3d::bag {

std::unique_ptr<BagReader> open_ros2(const std::filesystem::path& bag);
std::unique_ptr<BagReader> open_ros1(const std::filesystem::path& bag);

using OutMessage = BagOutMessage;
using OutTopic = BagOutTopic;

// Messages are pulled one at a time (in time order) so that a bag is never held in memory:
// next(m) fills m and returns true, or returns false at the end.
using NextMessage = std::function<bool(OutMessage&)>;

// ROS 2: `dir` (must not exist) gets metadata.yaml and <name>_0.db3.
void write_ros2(const std::filesystem::path& dir, const std::string& name,
                const std::vector<OutTopic>& topics, const NextMessage& next);
// ROS 1: a v2.0 .bag file with one chunk per ~768 KB (compression none, bz2 or lz4), connection and
// chunk info records and an index.
void write_ros1(const std::filesystem::path& file, const std::vector<OutTopic>& topics,
                const NextMessage& next, const std::string& compression = "none");

}  // namespace sonar3d::bag
