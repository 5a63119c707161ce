// Camera images of a simulated scene by Embree ray casting (video mapping's ground truth).
#include "sonar3d/video/render.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "../core/embree_device.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {

void CameraRenderConfig::validate() const {
  require(std::isfinite(ambient) && ambient >= 0 && ambient <= 1,
          "camera render: ambient must lie in [0, 1]");
  require(std::isfinite(attenuation_per_m) && attenuation_per_m >= 0,
          "camera render: attenuation_per_m must be >= 0 (1/m)");
  require(
      background.allFinite() && (background.array() >= 0).all() && (background.array() <= 1).all(),
      "camera render: the background colour must lie in [0, 1]");
  require(num_threads >= 0, "camera render: num_threads must be >= 0");
}

struct CameraRenderer::Impl {
  RTCScene scene = nullptr;
  std::vector<Eigen::Vector3f> color;  // by geometry id
  CameraRenderConfig config;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

CameraRenderer::CameraRenderer(const Scene& scene, const CameraRenderConfig& config)
    : impl_(std::make_unique<Impl>()) {
  config.validate();
  impl_->config = config;
  if (scene.empty()) throw Error("camera render: the scene has no object with triangles");
  impl_->scene = rtcNewScene(detail::embree_device());
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  for (const SceneObject& o : scene.objects) {
    if (o.mesh_world.empty()) continue;
    const unsigned id = detail::attach_mesh(impl_->scene, o.mesh_world, "object '" + o.name + "'");
    if (impl_->color.size() <= id) impl_->color.resize(id + 1, Eigen::Vector3f::Zero());
    impl_->color[id] = o.color;
  }
  rtcCommitScene(impl_->scene);
}

CameraRenderer::~CameraRenderer() = default;

RgbImage CameraRenderer::render(const CameraIntrinsics& camera,
                                const Eigen::Isometry3d& T_world_camera) const {
  camera.validate();
  require(T_world_camera.matrix().allFinite(), "camera render: the camera pose is not finite");
  const CameraRenderConfig& cfg = impl_->config;
  RgbImage img;
  img.width = camera.width;
  img.height = camera.height;
  const std::size_t n = static_cast<std::size_t>(camera.width) * camera.height;
  img.rgb.assign(3 * n, 0.0f);
  img.range_m.assign(n, std::numeric_limits<float>::infinity());
  const Eigen::Vector3d origin = T_world_camera.translation();
  const Eigen::Matrix3d R = T_world_camera.linear();
  auto row = [&](int v) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (int u = 0; u < camera.width; ++u) {
      const std::size_t k = static_cast<std::size_t>(v) * camera.width + u;
      Eigen::Vector3f out = cfg.background;
      const auto ray_c = unproject(camera, Eigen::Vector2d(u, v));
      if (ray_c) {
        const Eigen::Vector3d d = R * *ray_c;
        RTCRayHit rh;
        rh.ray.org_x = static_cast<float>(origin.x());
        rh.ray.org_y = static_cast<float>(origin.y());
        rh.ray.org_z = static_cast<float>(origin.z());
        rh.ray.dir_x = static_cast<float>(d.x());
        rh.ray.dir_y = static_cast<float>(d.y());
        rh.ray.dir_z = static_cast<float>(d.z());
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = std::numeric_limits<float>::infinity();
        rh.ray.mask = 0xFFFFFFFFu;
        rh.ray.flags = 0;
        rh.ray.time = 0.0f;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(impl_->scene, &ctx, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
          const Eigen::Vector3d ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
          const double cos_t = ng.norm() > 0 ? std::abs(ng.normalized().dot(d)) : 1.0;
          const double r = rh.ray.tfar;  // d is a unit vector: tfar is the range
          const double light = (cfg.ambient + (1 - cfg.ambient) * cos_t) *
                               std::exp(-2.0 * cfg.attenuation_per_m * r);
          out = impl_->color[rh.hit.geomID] * static_cast<float>(light);
          img.range_m[k] = static_cast<float>(r);
        }
      }
      img.rgb[3 * k] = out.x();
      img.rgb[3 * k + 1] = out.y();
      img.rgb[3 * k + 2] = out.z();
    }
  };
  std::unique_ptr<tbb::global_control> limit;
  if (cfg.num_threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(cfg.num_threads));
  }
  tbb::parallel_for(0, camera.height, row);
  return img;
}

}  // namespace sonar3d
