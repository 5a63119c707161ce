#pragma once
// Cameras for video mapping (thesis sec. 6.4): a pinhole with OpenCV's distortion model, in
// OpenCV's conventions — the camera frame has +z forward (the optical axis), +x right, +y down;
// pixel (0, 0) is the centre of the top-left pixel, u to the right, v down. A camera is mounted on
// the vehicle by T_vehicle_camera; a posed frame has T_world_camera. Importers convert other
// conventions (COLMAP's pixel centres at +0.5, OpenGL's −z forward) into these (docs/video.md).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>

namespace sonar3d {

struct CameraIntrinsics {
  int width = 0, height = 0;  // pixels
  double fx = 0, fy = 0;      // focal lengths, pixels
  double cx = 0, cy = 0;      // principal point, pixels (OpenCV: top-left pixel centre = 0)
  // OpenCV distortion (x, y normalised image coordinates, r² = x² + y²):
  //   x' = x·(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 x²), y' likewise with p1 ↔ p2.
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;

  bool distorted() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0 || k3 != 0; }
  // Throws Error naming the field: sizes within 1..100000, focal lengths > 0, everything finite,
  // and a distortion that keeps increasing with radius over the image (so that it inverts).
  void validate() const;
};

// The pixel where a point in the camera frame (m) appears; nothing when it lies behind the
// camera (z ≤ 0). The pixel may fall outside the image: check `in_image`.
std::optional<Eigen::Vector2d> project(const CameraIntrinsics& camera,
                                       const Eigen::Vector3d& p_camera);

// The unit ray (camera frame, z > 0) that projects to `pixel`: distortion inverted by Newton's
// method; nothing if it does not converge to 1e-9 px (outside where the model inverts).
std::optional<Eigen::Vector3d> unproject(const CameraIntrinsics& camera,
                                         const Eigen::Vector2d& pixel);

// Whether a pixel lies within the image (the pixel squares' outer edges: −0.5 … width − 0.5).
inline bool in_image(const CameraIntrinsics& c, const Eigen::Vector2d& px) {
  return px.x() >= -0.5 && px.y() >= -0.5 && px.x() < c.width - 0.5 && px.y() < c.height - 0.5;
}

// The bounds, in normalised image coordinates (x/z, y/z), of the rays through the image's outer
// pixel edges: exact for a pinhole; with distortion, those of the unprojected border (sampled
// every 8 pixels) widened by 2 pixels. A point in front of the camera whose x/z or y/z lies outside
// does not project into the image.
Eigen::AlignedBox2d normalised_image_bounds(const CameraIntrinsics& camera);

}  // namespace sonar3d
