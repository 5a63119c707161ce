#pragma once
// A visibility buffer for mesh texturing (internal to src/video): the occluding mesh rasterised,
// per camera frame, into a depth and triangle-id image in the camera's *undistorted* normalised
// image plane, where the projections of straight edges stay straight (so the lens distortion
// does not bend triangles). A vertex is then tested against the triangle nearest the camera at its
// four surrounding pixel centres by intersecting the vertex's own ray with those triangles' planes:
//   - a triangle the ray crosses, inside its edges, short of the vertex: Hidden (exact);
//   - a triangle whose plane, but not the triangle, crosses the ray short of the vertex, or no
//     triangle at any of the four (outside the raster, open water): Unknown, and the caller casts
//     the exact Embree ray;
//   - otherwise, when at least one of the four planes crosses the ray at the vertex (within 1e-4 m
//     or 1e-5 of the range, the Embree ray's allowance): the vertex lies on the front surface:
//     Visible.
// So Hidden is exact and Unknown falls back to the exact test; Visible holds at the raster's
// resolution: an occluder that covers the vertex but none of the four pixel centres around it (a
// sliver or a wire thinner than a pixel) is missed. Written by hand because rasterising triangle
// ids on the CPU is ~200 lines and the alternatives in Debian (Mesa's OSMesa/llvmpipe) need a GL
// context and a driver at run time.
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/video/camera.hpp"

namespace sonar3d::detail {

class VisibilityRaster {
 public:
  enum class Verdict : std::uint8_t { Visible, Hidden, Unknown };

  explicit VisibilityRaster(const TriangleMesh& occluder);

  // Rasterises the occluder seen by `camera` at `T_camera_world` (OpenCV camera frame). Geometry
  // nearer than `near_m` to the camera plane is clipped away.
  void render(const CameraIntrinsics& camera, const Eigen::Isometry3d& T_camera_world,
              double near_m = 1e-3);

  // The verdict for a point on the textured mesh, given in the world frame and in the camera
  // frame of the last render(); `range_m` is its distance from the camera centre.
  Verdict test(const Eigen::Vector3d& p_world, const Eigen::Vector3d& p_camera,
               double range_m) const;

  int width() const { return width_; }
  int height() const { return height_; }

 private:
  void setup_raster(const CameraIntrinsics& camera);
  void raster_triangle(int tri, int y0, int y1);
  void fill(const float* u, const float* v, const float* w, int tri, int y0, int y1);

  const TriangleMesh& mesh_;
  std::vector<Eigen::Vector3d> normal_world_;  // unit normals (zero for degenerate triangles)
  std::vector<double> offset_world_;           // n · a
  // Raster: pixel (i, j) centre at undistorted normalised coordinates
  // ((i − ox)/sx, (j − oy)/sy).
  CameraIntrinsics raster_for_{};
  bool have_raster_ = false;
  int width_ = 0, height_ = 0;
  double sx_ = 1, sy_ = 1, ox_ = 0, oy_ = 0;
  std::vector<float> inv_depth_;  // 1/z of the nearest surface at each pixel centre (0: none)
  std::vector<std::int32_t> id_;  // its triangle, −1: none
  // Per frame.
  std::vector<Eigen::Vector3f> p_camera_;  // occluder vertices in the camera frame
  std::vector<Eigen::Vector2f> screen_;    // their raster coordinates (valid when z > near)
  std::vector<std::vector<std::vector<std::int32_t>>> bins_;  // [chunk][band] triangle ids
  Eigen::Vector3d origin_world_ = Eigen::Vector3d::Zero();
  double near_ = 1e-3;
};

}  // namespace sonar3d::detail
