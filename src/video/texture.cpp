// Video mapping onto a point cloud with depth-buffer visibility.
#include "sonar3d/video/texture.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "sonar3d/core/error.hpp"
#include "visibility_raster.hpp"

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

namespace {
constexpr std::size_t kBlock = 256;  // points per block (consecutive in the Morton order)
}  // namespace

CloudTexturer::CloudTexturer(const PointCloud& cloud, const TextureConfig& config)
    : config_(config) {
  config_.validate();
  const std::size_t n = cloud.size();
  order_ = detail::morton_order(cloud.points);
  points_.resize(n);
  for (std::size_t k = 0; k < n; ++k) points_[k] = cloud.points[order_[k]];
  block_box_ = detail::block_boxes(points_, kBlock);
  sum_.assign(n, Eigen::Vector3d::Zero());
  views_.assign(n, 0);
  pixel_.resize(n);
  depth_.resize(n);
}

std::size_t CloudTexturer::add(const CameraView& view, std::size_t f) {
  const std::size_t n = points_.size();
  const TextureConfig& config = config_;
  const CameraIntrinsics& cam = view.camera;
  cam.validate();
  require(view.image != nullptr && view.image->width == cam.width &&
              view.image->height == cam.height &&
              view.image->rgb.size() ==
                  3 * static_cast<std::size_t>(cam.width) * static_cast<std::size_t>(cam.height),
          "texture: frame " + std::to_string(f) + "'s image does not match its camera's size");
  require(view.T_world_camera.matrix().allFinite(),
          "texture: frame " + std::to_string(f) + "'s pose is not finite");
  const Eigen::Isometry3d T_camera_world = view.T_world_camera.inverse();
  // The blocks that may hold a point in view.
  detail::blocks_in_view(block_box_, cam, T_camera_world, config.max_range_m, blocks_in_view_);
  auto points_of = [&](int b) {
    return std::make_pair(static_cast<std::size_t>(b) * kBlock,
                          std::min(n, static_cast<std::size_t>(b + 1) * kBlock));
  };
  const std::size_t nb = blocks_in_view_.size();
  const bool pinhole = !cam.distorted();
  // The pixel nearest a point's (in_image: x, y ≥ −0.5, so truncating x + 0.5 is its floor).
  auto nearest = [](double x) { return static_cast<int>(x + 0.5); };
  // Where each of their points falls (NaN depth: not in this frame), and the rows each block's
  // splats may reach.
  const int w = cam.width, h = cam.height;
  const double f_px = std::max(cam.fx, cam.fy);
  auto splat_radius = [&](float depth) {
    return std::min(config.max_splat_px,
                    static_cast<int>(std::ceil(0.5 * f_px * config.point_spacing_m / depth)));
  };
  block_rows_.assign(nb, {h, -1});
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nb), [&](const auto& r) {
    for (std::size_t j = r.begin(); j != r.end(); ++j) {
      const auto [first, last] = points_of(blocks_in_view_[j]);
      auto& rows = block_rows_[j];
      for (std::size_t k = first; k < last; ++k) {
        depth_[k] = std::numeric_limits<float>::quiet_NaN();
        const Eigen::Vector3d p = T_camera_world * points_[k].cast<double>();
        if (!(p.z() > 0) || p.norm() > config.max_range_m) continue;
        Eigen::Vector2d px;
        if (pinhole) {  // project() without distortion, inline
          px = {cam.fx * (p.x() / p.z()) + cam.cx, cam.fy * (p.y() / p.z()) + cam.cy};
        } else {
          const auto q = project(cam, p);
          if (!q) continue;
          px = *q;
        }
        if (!in_image(cam, px)) continue;
        pixel_[k] = px;
        depth_[k] = static_cast<float>(p.z());
        const int v0 = nearest(px.y()), rad = splat_radius(depth_[k]);
        rows.first = std::min(rows.first, v0 - rad);
        rows.second = std::max(rows.second, v0 + rad);
      }
    }
  });
  // The depth buffer: each point a square of its spacing's size around its pixel. In bands of
  // rows, in parallel, each band splatting the blocks that reach it within its own rows: the
  // nearest depth wins, whatever the order.
  zbuf_.assign(static_cast<std::size_t>(w) * h, std::numeric_limits<float>::infinity());
  constexpr int kBandRows = 32;
  tbb::parallel_for(0, (h + kBandRows - 1) / kBandRows, [&](int band) {
    const int y0 = band * kBandRows, y1 = std::min(h, y0 + kBandRows) - 1;
    for (std::size_t j = 0; j < nb; ++j) {
      if (block_rows_[j].second < y0 || block_rows_[j].first > y1) continue;
      const auto [first, last] = points_of(blocks_in_view_[j]);
      for (std::size_t k = first; k < last; ++k) {
        if (std::isnan(depth_[k])) continue;
        const int r = splat_radius(depth_[k]);
        const int u0 = nearest(pixel_[k].x()), v0 = nearest(pixel_[k].y());
        for (int v = std::max(y0, v0 - r); v <= std::min(y1, v0 + r); ++v) {
          for (int u = std::max(0, u0 - r); u <= std::min(w - 1, u0 + r); ++u) {
            float& z = zbuf_[static_cast<std::size_t>(v) * w + u];
            z = std::min(z, depth_[k]);
          }
        }
      }
    }
  });
  std::atomic<std::size_t> coloured{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nb), [&](const auto& r) {
    std::size_t local = 0;
    for (std::size_t j = r.begin(); j != r.end(); ++j) {
      const auto [first, last] = points_of(blocks_in_view_[j]);
      for (std::size_t k = first; k < last; ++k) {
        if (std::isnan(depth_[k])) continue;
        const int u = std::clamp(nearest(pixel_[k].x()), 0, w - 1);
        const int v = std::clamp(nearest(pixel_[k].y()), 0, h - 1);
        if (depth_[k] > zbuf_[static_cast<std::size_t>(v) * w + u] + config.depth_tolerance_m) {
          continue;
        }
        sum_[k] += view.image->sample(pixel_[k]).cast<double>();
        ++views_[k];
        ++local;
      }
    }
    coloured.fetch_add(local, std::memory_order_relaxed);
  });
  return coloured.load();
}

TexturedCloud CloudTexturer::result() const {
  const std::size_t n = points_.size();
  TexturedCloud out;
  out.color.assign(n, Eigen::Vector3f::Zero());
  out.views.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const int i = order_[k];
    out.views[i] = views_[k];
    if (views_[k] > 0) out.color[i] = (sum_[k] / views_[k]).cast<float>();
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
