#pragma once
// Camera frames in a dataset (docs/formats.md, "Camera frames"): the optional `camera/` part of a
// dataset directory, placed on the dataset's navigation like the sonar frames.
//
//   camera/camera.yaml   format, version, the intrinsics (OpenCV pinhole + distortion, pixel
//                        (0, 0) the top-left pixel's centre) and T_vehicle_camera
//   camera/frames.csv    index,timestamp,file (file relative to the dataset root)
//   camera/frames/NNNNNN.png   colour images, sRGB-encoded (8- or 16-bit; the simulator writes 16)
//
// A frame's pose is T_world_camera = navigation(t) · T_vehicle_camera, interpolated at its
// timestamp (linear + slerp) like a sonar frame's; a timestamp outside the navigation is an error.
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/video/camera.hpp"
#include "sonar3d/video/render.hpp"

namespace sonar3d {

inline constexpr int kCameraFramesVersion = 1;

// A camera on the vehicle.
struct CameraRig {
  CameraIntrinsics intrinsics;
  Eigen::Isometry3d T_vehicle_camera = Eigen::Isometry3d::Identity();
};

// Reads the rig's keys from a YAML mapping (camera.yaml, or a scene's `camera:` block):
// width, height (pixels), fx, fy, cx, cy (pixels), optional k1 k2 p1 p2 k3, and
// T_vehicle_camera {translation: [m], rpy_deg: [...]} or {translation, quaternion}. `extra`: other
// keys the caller reads. Validates the intrinsics (a distortion that does not invert is refused).
CameraRig parse_camera_rig(const YAML::Node& node, const std::string& file, const std::string& ctx,
                           const std::vector<std::string>& extra = {});
void emit_camera_rig(YAML::Emitter& out, const CameraRig& rig);

struct CameraDataset {
  std::filesystem::path root;  // the dataset directory
  CameraRig rig;
  std::vector<FrameRecord> frames;
  Trajectory navigation;  // the dataset's T_world_vehicle
  std::size_t size() const { return frames.size(); }
  // navigation(t_i) · T_vehicle_camera; throws Error naming the frame when t_i is outside it.
  Eigen::Isometry3d T_world_camera(std::size_t i) const;
  std::filesystem::path image_path(std::size_t i) const { return root / frames.at(i).file; }
};

bool has_camera_frames(const std::filesystem::path& dataset_dir);
// Reads camera/camera.yaml, camera/frames.csv and the dataset's navigation.tum. Errors name the
// file, line and key; images are read on demand (read_rgb_image).
CameraDataset read_camera_dataset(const std::filesystem::path& dataset_dir);

// Writes the camera part into `camera_dir` (a DatasetWriter's part_dir("camera")): add() each
// frame (written at once as a 16-bit sRGB PNG), then finish() writes camera.yaml and frames.csv.
class CameraFramesWriter {
 public:
  CameraFramesWriter(const std::filesystem::path& camera_dir, const CameraRig& rig);
  void add(double timestamp, const RgbImage& image);
  void finish();
  std::size_t size() const { return frames_.size(); }

 private:
  std::filesystem::path dir_;
  CameraRig rig_;
  std::vector<FrameRecord> frames_;
};

}  // namespace sonar3d
