// Whole bag imports (import_rosbag): the first byte picks ROS 1 (.bag) or ROS 2 (.db3, the sqlite3
// storage) and a fixed sonar or the navigation topic; the rest is the bag file. Topics are the
// ones `sonar3d export rosbag` writes (/sonar3d/image, /sonar3d/odom, /tf_static).
#include "fuzz_common.hpp"
#include "sonar3d/io/rosbag.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto dir = sonar3d::fuzz::scratch();
  const auto p = dir / ((data[0] & 1) ? "in.bag" : "in.db3");
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  sonar3d::RosbagImportConfig c;
  c.sonar_topic = "/sonar3d/image";
  c.nav_topic = "/sonar3d/odom";
  c.static_sonar = (data[0] & 2) != 0;
  c.drop_outside = (data[0] & 4) != 0;
  sonar3d::fuzz::run([&] { sonar3d::import_rosbag(p, dir / "out", c); });
  std::error_code ec;
  std::filesystem::remove_all(dir / "out", ec);
  std::filesystem::remove(p, ec);
  return 0;
}
