// Video mapping onto a point cloud with depth-buffer visibility.
#include "sonar3d/video/texture.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void TextureConfig::validate() const {
  require(std::isfinite(point_spacing_m) && point_spacing_m > 0,
          "texture: point_spacing_m must be > 0 m");
  require(std::isfinite(depth_tolerance_m) && depth_tolerance_m >= 0,
          "texture: depth_tolerance_m must be >= 0 m");
  require(std::isfinite(max_range_m) && max_range_m > 0, "texture: max_range_m must be > 0 m");
  require(max_splat_px >= 0 && max_splat_px <= 256, "texture: max_splat_px must be 0 … 256");
}

std::size_t TexturedCloud::coloured() const {
  return static_cast<std::size_t>(
      std::count_if(views.begin(), views.end(), [](std::uint32_t v) { return v > 0; }));
}

CloudTexturer::CloudTexturer(const PointCloud& cloud, const TextureConfig& config)
    : cloud_(cloud), config_(config) {
  config_.validate();
  const std::size_t n = cloud.size();
  sum_.assign(n, Eigen::Vector3d::Zero());
  views_.assign(n, 0);
  pixel_.resize(n);
  depth_.resize(n);
}

std::size_t CloudTexturer::add(const CameraView& view, std::size_t f) {
  const std::size_t n = cloud_.size();
  const TextureConfig& config = config_;
  view.camera.validate();
  require(view.image != nullptr && view.image->width == view.camera.width &&
              view.image->height == view.camera.height &&
              view.image->rgb.size() == 3 * static_cast<std::size_t>(view.camera.width) *
                                            static_cast<std::size_t>(view.camera.height),
          "texture: frame " + std::to_string(f) + "'s image does not match its camera's size");
  require(view.T_world_camera.matrix().allFinite(),
          "texture: frame " + std::to_string(f) + "'s pose is not finite");
  const Eigen::Isometry3d T_camera_world = view.T_world_camera.inverse();
  auto& pixel = pixel_;
  auto& depth = depth_;
  // Where each point falls (NaN depth: not in this frame).
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    depth[i] = std::numeric_limits<float>::quiet_NaN();
    const Eigen::Vector3d p = T_camera_world * cloud_.points[i].cast<double>();
    if (!(p.z() > 0) || p.norm() > config.max_range_m) return;
    const auto px = project(view.camera, p);
    if (!px || !in_image(view.camera, *px)) return;
    pixel[i] = *px;
    depth[i] = static_cast<float>(p.z());
  });
  // The depth buffer: each point a square of its spacing's size around its pixel.
  const int w = view.camera.width, h = view.camera.height;
  std::vector<float> zbuf(static_cast<std::size_t>(w) * h, std::numeric_limits<float>::infinity());
  const double f_px = std::max(view.camera.fx, view.camera.fy);
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(depth[i])) continue;
    const int r =
        std::min(config.max_splat_px,
                 static_cast<int>(std::ceil(0.5 * f_px * config.point_spacing_m / depth[i])));
    const int u0 = static_cast<int>(std::lround(pixel[i].x())),
              v0 = static_cast<int>(std::lround(pixel[i].y()));
    for (int v = std::max(0, v0 - r); v <= std::min(h - 1, v0 + r); ++v) {
      for (int u = std::max(0, u0 - r); u <= std::min(w - 1, u0 + r); ++u) {
        float& z = zbuf[static_cast<std::size_t>(v) * w + u];
        z = std::min(z, depth[i]);
      }
    }
  }
  std::atomic<std::size_t> coloured{0};
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    if (std::isnan(depth[i])) return;
    const int u = std::clamp(static_cast<int>(std::lround(pixel[i].x())), 0, w - 1);
    const int v = std::clamp(static_cast<int>(std::lround(pixel[i].y())), 0, h - 1);
    if (depth[i] > zbuf[static_cast<std::size_t>(v) * w + u] + config.depth_tolerance_m) return;
    sum_[i] += view.image->sample(pixel[i]).cast<double>();
    ++views_[i];
    coloured.fetch_add(1, std::memory_order_relaxed);
  });
  return coloured.load();
}

TexturedCloud CloudTexturer::result() const {
  const std::size_t n = cloud_.size();
  TexturedCloud out;
  out.color.assign(n, Eigen::Vector3f::Zero());
  out.views = views_;
  for (std::size_t i = 0; i < n; ++i) {
    if (views_[i] > 0) out.color[i] = (sum_[i] / views_[i]).cast<float>();
  }
  return out;
}

TexturedCloud texture_cloud(const PointCloud& cloud, const std::vector<CameraView>& views,
                            const TextureConfig& config) {
  CloudTexturer t(cloud, config);
  for (std::size_t f = 0; f < views.size(); ++f) t.add(views[f], f);
  return t.result();
}

}  // namespace sonar3d
