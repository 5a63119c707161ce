#pragma once
// Camera images of a simulated scene (ground truth for video mapping): Embree ray casting through
// every pixel of a pinhole camera, each object's colour (SceneObject::color) lit by a lamp on the
// camera and dimmed by the water along the way out and back.
#include <Eigen/Geometry>
#include <algorithm>
#include <memory>
#include <vector>

#include "sonar3d/core/rgb_image.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/video/camera.hpp"

namespace sonar3d {

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
