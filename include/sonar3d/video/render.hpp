#pragma once
// Camera images of a simulated scene (ground truth for video mapping): Embree ray casting through
// every pixel of a pinhole camera, each object's colour (SceneObject::color) lit by a lamp on the
// camera and dimmed by the water along the way out and back.
#include <Eigen/Geometry>
#include <algorithm>
#include <memory>
#include <vector>

#include "sonar3d/sim/scene.hpp"
#include "sonar3d/video/camera.hpp"

namespace sonar3d {

// A colour image: linear RGB in [0, 1], row-major from the top-left pixel, 3 floats per pixel;
// with the range (m) of what each pixel sees, +inf where it sees nothing.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<float> rgb;
  std::vector<float> range_m;
  Eigen::Vector3f at(int u, int v) const {
    const std::size_t k = 3 * (static_cast<std::size_t>(v) * width + u);
    return {rgb[k], rgb[k + 1], rgb[k + 2]};
  }
  // Bilinear between pixel centres (pixel coordinates as in camera.hpp), clamped at the edges.
  Eigen::Vector3f sample(const Eigen::Vector2d& pixel) const {
    const double x = std::clamp(pixel.x(), 0.0, static_cast<double>(width - 1));
    const double y = std::clamp(pixel.y(), 0.0, static_cast<double>(height - 1));
    const int u0 = static_cast<int>(x), v0 = static_cast<int>(y);  // x, y ≥ 0: the floors
    const int u1 = std::min(u0 + 1, width - 1), v1 = std::min(v0 + 1, height - 1);
    const float a = static_cast<float>(x - u0), b = static_cast<float>(y - v0);
    return (1 - a) * (1 - b) * at(u0, v0) + a * (1 - b) * at(u1, v0) + (1 - a) * b * at(u0, v1) +
           a * b * at(u1, v1);
  }
};

struct CameraRenderConfig {
  // Shading: albedo · (ambient + (1 − ambient)·|cos θ|) · exp(−2·attenuation·range), θ between
  // the ray and the surface normal (the lamp sits on the camera).
  double ambient = 0.1;
  double attenuation_per_m = 0.1;  // water's light attenuation coefficient, 1/m
  Eigen::Vector3f background = Eigen::Vector3f(0.0f, 0.05f, 0.08f);  // open water
  int num_threads = 0;                                               // 0 = all cores
  void validate() const;  // throws Error naming the field
};

class CameraRenderer {
 public:
  // Builds the scene's ray tracing structure once; throws Error on an empty scene or a bad mesh.
  CameraRenderer(const Scene& scene, const CameraRenderConfig& config = {});
  ~CameraRenderer();
  CameraRenderer(const CameraRenderer&) = delete;
  CameraRenderer& operator=(const CameraRenderer&) = delete;
  RgbImage render(const CameraIntrinsics& camera, const Eigen::Isometry3d& T_world_camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonar3d
