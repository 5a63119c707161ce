#pragma once
// Camera poses from COLMAP's text models (cameras.txt, images.txt), the form structure-from-motion
// results come in. Conventions (docs/video.md): COLMAP's camera frame is OpenCV's (+z forward,
// +x right, +y down), its images.txt pose is world → camera (X_cam = R·X_world + t, R from the
// quaternion QW QX QY QZ), and its pixel coordinates put the centre of the top-left pixel at
// (0.5, 0.5): the principal point is moved by −0.5 on import (+0.5 on export).
#include <Eigen/Geometry>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "sonar3d/video/camera.hpp"

namespace sonar3d {

struct PosedImage {
  int id = 0;
  int camera_id = 0;
  std::string name;  // the image file, relative to the images directory
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
};

struct PosedImages {
  std::map<int, CameraIntrinsics> cameras;  // by camera id
  std::vector<PosedImage> images;           // in file order
};

// Reads dir/cameras.txt and dir/images.txt. Camera models: SIMPLE_PINHOLE, PINHOLE,
// SIMPLE_RADIAL, RADIAL, OPENCV, and FULL_OPENCV with k4 = k5 = k6 = 0; others (fisheye, FOV,
// thin prism) are an error naming the model. Errors name the file and line.
PosedImages read_colmap_text(const std::filesystem::path& dir);

// Writes dir/cameras.txt and dir/images.txt (PINHOLE, OPENCV or FULL_OPENCV; no 2D points), each
// atomically. `dir` must exist.
void write_colmap_text(const PosedImages& posed, const std::filesystem::path& dir);

// Throws Error naming the first image that is not a file under `images_dir`.
void check_images_exist(const PosedImages& posed, const std::filesystem::path& images_dir);

}  // namespace sonar3d
