#pragma once
// The ROS messages sonar3d reads and writes, decoded from and encoded to their wire formats by
// hand from the message definitions (docs/import.md, "ROS bags"):
//   - ROS 2: CDR (little-endian XCDR1 as rmw/Fast-CDR write it: 4-byte encapsulation header,
//     primitives aligned to their size relative to the end of that header, strings and sequences
//     prefixed by a uint32 count);
//   - ROS 1: the ROS serialization (packed little-endian, uint32 counts, Header with seq).
// Every decoder checks each count against the bytes left before allocating and throws Error
// naming `where` (bag file, topic, message number) and the byte offset.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace sonar3d {

enum class RosWire { Cdr, Ros1 };

// Message types by their package/Name (ROS 2's "pkg/msg/Name" and ROS 1's "pkg/Name" both map
// here).
std::string ros_type_name(const std::string& type);  // "pkg/msg/Name" -> "pkg/Name"

struct RosTime {
  std::int64_t sec = 0;
  std::uint32_t nanosec = 0;
  double seconds() const { return static_cast<double>(sec) + nanosec * 1e-9; }
  static RosTime from_seconds(double t);  // nearest nanosecond
  std::int64_t ns() const { return sec * 1000000000LL + nanosec; }
};

// marine_acoustic_msgs/ProjectedSonarImage and acoustic_msgs/ProjectedSonarImage (same layout).
// Message frame (its definition): z forward in the plane of the fan, x up, y to starboard; a
// beam direction d has bearing atan2(−d.y, d.z) in our FLU sonar frame and elevation asin(d.x).
struct RosSonarImage {
  RosTime stamp;
  std::string frame_id;
  float frequency = 0, sound_speed = 0;
  std::vector<float> tx_beamwidths, rx_beamwidths;  // rad
  std::vector<Eigen::Vector3d> beam_directions;
  std::vector<float> ranges;  // m, centre of each range bin
  bool is_bigendian = false;
  std::uint32_t dtype = 0;  // SonarImageData.DTYPE_*: 0 uint8, 2 uint16, 8 float32 read here
  std::uint32_t beam_count = 0;
  std::vector<std::uint8_t> data;  // range-major: (range · beam_count + beam) · size
};
inline constexpr std::uint32_t kRosDtypeUint8 = 0, kRosDtypeUint16 = 2, kRosDtypeFloat32 = 8;

// sensor_msgs/Image (mono8, mono16, 32FC1 read here).
struct RosImage {
  RosTime stamp;
  std::string frame_id;
  std::uint32_t height = 0, width = 0, step = 0;
  std::string encoding;
  std::uint8_t is_bigendian = 0;
  std::vector<std::uint8_t> data;
};

// A pose from nav_msgs/Odometry, geometry_msgs/PoseStamped or PoseWithCovarianceStamped.
struct RosPose {
  RosTime stamp;
  std::string frame_id;        // the world frame
  std::string child_frame_id;  // Odometry only: the body frame
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // as stored (x, y, z, w)
};

// One geometry_msgs/TransformStamped of a tf2_msgs/TFMessage: T_parent_child.
struct RosTransform {
  RosTime stamp;
  std::string parent, child;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

RosSonarImage decode_sonar_image(const std::uint8_t* p, std::size_t n, RosWire wire,
                                 const std::string& where);
RosImage decode_image(const std::uint8_t* p, std::size_t n, RosWire wire, const std::string& where);
// `type` is one of nav_msgs/Odometry, geometry_msgs/PoseStamped,
// geometry_msgs/PoseWithCovarianceStamped (either naming).
RosPose decode_pose(const std::string& type, const std::uint8_t* p, std::size_t n, RosWire wire,
                    const std::string& where);
std::vector<RosTransform> decode_tf(const std::uint8_t* p, std::size_t n, RosWire wire,
                                    const std::string& where);

std::vector<std::uint8_t> encode_sonar_image(const RosSonarImage& m, RosWire wire);
std::vector<std::uint8_t> encode_image(const RosImage& m, RosWire wire);
std::vector<std::uint8_t> encode_odometry(const RosPose& m, RosWire wire);
std::vector<std::uint8_t> encode_pose_stamped(const RosPose& m, RosWire wire);
std::vector<std::uint8_t> encode_tf(const std::vector<RosTransform>& m, RosWire wire);

}  // namespace sonar3d
