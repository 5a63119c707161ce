// ROS message decoders (CDR and ROS 1 wire): the first byte picks the message type and the wire,
// the rest is one serialised message. ProjectedSonarImage also goes through
// sonar_spec_from_message.
#include "fuzz_common.hpp"
#include "sonar3d/io/ros_msgs.hpp"
#include "sonar3d/io/rosbag.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const sonar3d::RosWire wire = (data[0] & 1) ? sonar3d::RosWire::Ros1 : sonar3d::RosWire::Cdr;
  const uint8_t* p = data + 1;
  const size_t n = size - 1;
  sonar3d::fuzz::run([&] {
    switch ((data[0] >> 1) % 6) {
      case 0: {
        const auto m = sonar3d::decode_sonar_image(p, n, wire, "msg");
        sonar3d::sonar_spec_from_message(m, "msg");
        break;
      }
      case 1:
        sonar3d::decode_image(p, n, wire, "msg");
        break;
      case 2:
        sonar3d::decode_pose("nav_msgs/msg/Odometry", p, n, wire, "msg");
        break;
      case 3:
        sonar3d::decode_pose("geometry_msgs/PoseStamped", p, n, wire, "msg");
        break;
      case 4:
        sonar3d::decode_pose("geometry_msgs/msg/PoseWithCovarianceStamped", p, n, wire, "msg");
        break;
      default:
        sonar3d::decode_tf(p, n, wire, "msg");
    }
  });
  return 0;
}
