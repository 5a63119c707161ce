// A dataset's camera frames (read_camera_dataset, CameraDataset::T_world_camera): the input is
// three parts separated by "--8<--" lines: camera/camera.yaml, camera/frames.csv and
// navigation.tum. Every listed frame (up to 4) is posed.
#include "fuzz_common.hpp"
#include "sonar3d/video/camera_dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = sonar3d::fuzz::split(data, size, 3);
  const auto dir = sonar3d::fuzz::scratch() / "camera_dataset";
  sonar3d::fuzz::write_file(dir / "camera/camera.yaml", parts[0]);
  sonar3d::fuzz::write_file(dir / "camera/frames.csv", parts[1]);
  sonar3d::fuzz::write_file(dir / "navigation.tum", parts[2]);
  sonar3d::fuzz::run([&] {
    const sonar3d::CameraDataset ds = sonar3d::read_camera_dataset(dir);
    for (std::size_t i = 0; i < std::min<std::size_t>(ds.size(), 4); ++i) {
      sonar3d::fuzz::run([&] { ds.T_world_camera(i); });
    }
  });
  return 0;
}
