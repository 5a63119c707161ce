// Visibility buffer for mesh texturing (src/video/visibility_raster.hpp).
#include "visibility_raster.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace sonar3d::detail {

namespace {
constexpr int kChunks = 64;    // triangle chunks binned in parallel
constexpr int kBandRows = 16;  // raster rows per band (the unit of parallel rasterisation)
constexpr double kMaxRasterFactor = 4.0;  // raster pixels at most this times the image's
}  // namespace

VisibilityRaster::VisibilityRaster(const TriangleMesh& occluder) : mesh_(occluder) {
  const auto& V = mesh_.vertices;
  normal_world_.resize(mesh_.triangles.size());
  offset_world_.resize(mesh_.triangles.size());
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    const auto& tri = mesh_.triangles[t];
    const Eigen::Vector3d a = V[tri[0]].cast<double>(), b = V[tri[1]].cast<double>(),
                          c = V[tri[2]].cast<double>();
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    n = len > 0 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
    normal_world_[t] = n;
    offset_world_[t] = n.dot(a);
  }
  bins_.assign(kChunks, {});
}

void VisibilityRaster::setup_raster(const CameraIntrinsics& c) {
  // The raster covers the image's field of view in the undistorted normalised plane: the bounds
  // of the rays through the image's border (for a pinhole, exactly the image).
  double xmin = (-0.5 - c.cx) / c.fx, xmax = (c.width - 0.5 - c.cx) / c.fx;
  double ymin = (-0.5 - c.cy) / c.fy, ymax = (c.height - 0.5 - c.cy) / c.fy;
  double scale = 1.0;
  if (c.distorted()) {
    xmin = ymin = 1e300;
    xmax = ymax = -1e300;
    auto take = [&](double u, double v) {
      const auto ray = unproject(c, Eigen::Vector2d(u, v));
      if (!ray || !(ray->z() > 0)) return;
      xmin = std::min(xmin, ray->x() / ray->z());
      xmax = std::max(xmax, ray->x() / ray->z());
      ymin = std::min(ymin, ray->y() / ray->z());
      ymax = std::max(ymax, ray->y() / ray->z());
    };
    const int step = 8;
    for (int i = 0; i <= c.width; i += step) {
      take(std::min(i, c.width) - 0.5, -0.5);
      take(std::min(i, c.width) - 0.5, c.height - 0.5);
    }
    for (int j = 0; j <= c.height; j += step) {
      take(-0.5, std::min(j, c.height) - 0.5);
      take(c.width - 0.5, std::min(j, c.height) - 0.5);
    }
    take(c.width - 0.5, c.height - 0.5);
    // A margin of two pixels for the border sampling's step.
    xmin -= 2 / c.fx;
    xmax += 2 / c.fx;
    ymin -= 2 / c.fy;
    ymax += 2 / c.fy;
    const double area = (xmax - xmin) * c.fx * (ymax - ymin) * c.fy;
    const double limit = kMaxRasterFactor * c.width * c.height;
    if (area > limit) scale = std::sqrt(limit / area);
  }
  sx_ = c.fx * scale;
  sy_ = c.fy * scale;
  ox_ = -xmin * sx_ - 0.5;
  oy_ = -ymin * sy_ - 0.5;
  width_ = std::max(1, static_cast<int>(std::ceil((xmax - xmin) * sx_)));
  height_ = std::max(1, static_cast<int>(std::ceil((ymax - ymin) * sy_)));
  inv_depth_.assign(static_cast<std::size_t>(width_) * height_, 0.0f);
  id_.assign(inv_depth_.size(), -1);
  raster_for_ = c;
  have_raster_ = true;
}

// ⌈x⌉ and ⌊x⌋ for x already clamped to a small range (no libm call on the hot path).
inline int ceil_small(float x) {
  const int i = static_cast<int>(x);
  return i + (static_cast<float>(i) < x);
}
inline int floor_small(float x) {
  const int i = static_cast<int>(x);
  return i - (static_cast<float>(i) > x);
}

void VisibilityRaster::fill(const float* u, const float* v, const float* w, int tri, int y0,
                            int y1) {
  // The pixel centres inside the triangle's bounding box, clipped to the band; most triangles of
  // a fine mesh cover at most one, many none (checked before any other work).
  const float lo_x = -1.0f, hi_x = static_cast<float>(width_);
  const float lo_y = static_cast<float>(y0) - 1.0f, hi_y = static_cast<float>(y1);
  const float umin = std::clamp(std::min(u[0], std::min(u[1], u[2])), lo_x, hi_x);
  const float umax = std::clamp(std::max(u[0], std::max(u[1], u[2])), lo_x, hi_x);
  const float vmin = std::clamp(std::min(v[0], std::min(v[1], v[2])), lo_y, hi_y);
  const float vmax = std::clamp(std::max(v[0], std::max(v[1], v[2])), lo_y, hi_y);
  const int xa = std::max(0, ceil_small(umin)), xb = std::min(width_ - 1, floor_small(umax));
  const int ya = std::max(y0, ceil_small(vmin)), yb = std::min(y1 - 1, floor_small(vmax));
  if (xa > xb || ya > yb) return;
  // Edge functions (barycentric weights) over those centres; w = 1/z is affine in screen space,
  // so it interpolates with the same weights.
  const float area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
  if (!(std::abs(area) > 1e-12f)) return;  // edge-on: covers no area
  const float inv_area = 1.0f / area;
  for (int y = ya; y <= yb; ++y) {
    const float py = static_cast<float>(y);
    float* depth = inv_depth_.data() + static_cast<std::size_t>(y) * width_;
    std::int32_t* ids = id_.data() + static_cast<std::size_t>(y) * width_;
    for (int x = xa; x <= xb; ++x) {
      const float px = static_cast<float>(x);
      const float b0 = ((u[1] - px) * (v[2] - py) - (u[2] - px) * (v[1] - py)) * inv_area;
      const float b1 = ((u[2] - px) * (v[0] - py) - (u[0] - px) * (v[2] - py)) * inv_area;
      const float b2 = 1.0f - b0 - b1;
      if (b0 < 0 || b1 < 0 || b2 < 0) continue;
      const float iz = b0 * w[0] + b1 * w[1] + b2 * w[2];
      if (iz > depth[x]) {
        depth[x] = iz;
        ids[x] = tri;
      }
    }
  }
}

void VisibilityRaster::raster_triangle(int t, int y0, int y1) {
  const auto& tri = mesh_.triangles[t];
  const Eigen::Vector3f* p[3] = {&p_camera_[tri[0]], &p_camera_[tri[1]], &p_camera_[tri[2]]};
  const float nz = static_cast<float>(near_);
  if (p[0]->z() > nz && p[1]->z() > nz && p[2]->z() > nz) {
    const float u[3] = {screen_[tri[0]].x(), screen_[tri[1]].x(), screen_[tri[2]].x()};
    const float v[3] = {screen_[tri[0]].y(), screen_[tri[1]].y(), screen_[tri[2]].y()};
    const float w[3] = {1.0f / p[0]->z(), 1.0f / p[1]->z(), 1.0f / p[2]->z()};
    fill(u, v, w, t, y0, y1);
    return;
  }
  // Crossing the near plane: clip the polygon to z ≥ near (Sutherland–Hodgman, one plane), then
  // fan it into triangles.
  Eigen::Vector3f poly[4];
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3f& a = *p[k];
    const Eigen::Vector3f& b = *p[(k + 1) % 3];
    const bool ina = a.z() > nz, inb = b.z() > nz;
    if (ina) poly[n++] = a;
    if (ina != inb) {
      const float s = (nz - a.z()) / (b.z() - a.z());
      poly[n++] = a + s * (b - a);
      poly[n - 1].z() = nz;
    }
  }
  if (n < 3) return;
  float u[4], v[4], w[4];
  for (int k = 0; k < n; ++k) {
    w[k] = 1.0f / poly[k].z();
    u[k] = static_cast<float>(sx_ * poly[k].x() * w[k] + ox_);
    v[k] = static_cast<float>(sy_ * poly[k].y() * w[k] + oy_);
  }
  for (int k = 1; k + 1 < n; ++k) {
    const float tu[3] = {u[0], u[k], u[k + 1]}, tv[3] = {v[0], v[k], v[k + 1]},
                tw[3] = {w[0], w[k], w[k + 1]};
    fill(tu, tv, tw, t, y0, y1);
  }
}

void VisibilityRaster::render(const CameraIntrinsics& camera,
                              const Eigen::Isometry3d& T_camera_world, double near_m) {
  if (!have_raster_ || camera.width != raster_for_.width || camera.height != raster_for_.height ||
      camera.fx != raster_for_.fx || camera.fy != raster_for_.fy || camera.cx != raster_for_.cx ||
      camera.cy != raster_for_.cy || camera.k1 != raster_for_.k1 || camera.k2 != raster_for_.k2 ||
      camera.p1 != raster_for_.p1 || camera.p2 != raster_for_.p2 || camera.k3 != raster_for_.k3) {
    setup_raster(camera);
  } else {
    std::fill(inv_depth_.begin(), inv_depth_.end(), 0.0f);
    std::fill(id_.begin(), id_.end(), -1);
  }
  near_ = near_m;
  origin_world_ = T_camera_world.inverse().translation();
  const auto& V = mesh_.vertices;
  p_camera_.resize(V.size());
  screen_.resize(V.size());
  const Eigen::Matrix3f R = T_camera_world.linear().cast<float>();
  const Eigen::Vector3f t = T_camera_world.translation().cast<float>();
  const float sx = static_cast<float>(sx_), sy = static_cast<float>(sy_),
              ox = static_cast<float>(ox_), oy = static_cast<float>(oy_);
  // Vertices to the camera frame and the raster.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, V.size(), 16384),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const Eigen::Vector3f p = R * V[i] + t;
                        p_camera_[i] = p;
                        const float w = p.z() > 0 ? 1.0f / p.z() : 0.0f;
                        screen_[i] = Eigen::Vector2f(sx * p.x() * w + ox, sy * p.y() * w + oy);
                      }
                    });
  // Triangles binned by raster band, per chunk in parallel (no locks: each chunk its own bins).
  const int bands = (height_ + kBandRows - 1) / kBandRows;
  const std::size_t T = mesh_.triangles.size();
  const float nz = static_cast<float>(near_);
  tbb::parallel_for(0, kChunks, [&](int chunk) {
    auto& bins = bins_[chunk];
    bins.resize(bands);
    for (auto& b : bins) b.clear();
    const std::size_t begin = T * chunk / kChunks, end = T * (chunk + 1) / kChunks;
    for (std::size_t k = begin; k < end; ++k) {
      const auto& tri = mesh_.triangles[k];
      const float z0 = p_camera_[tri[0]].z(), z1 = p_camera_[tri[1]].z(),
                  z2 = p_camera_[tri[2]].z();
      if (z0 <= nz && z1 <= nz && z2 <= nz) continue;  // wholly behind the near plane
      float vmin = 0, vmax = static_cast<float>(height_);
      float umin = 0, umax = static_cast<float>(width_);
      if (z0 > nz && z1 > nz && z2 > nz) {
        const float v0 = screen_[tri[0]].y(), v1 = screen_[tri[1]].y(), v2 = screen_[tri[2]].y();
        const float u0 = screen_[tri[0]].x(), u1 = screen_[tri[1]].x(), u2 = screen_[tri[2]].x();
        vmin = std::min({v0, v1, v2});
        vmax = std::max({v0, v1, v2});
        umin = std::min({u0, u1, u2});
        umax = std::max({u0, u1, u2});
        if (!(vmax >= -0.5f && vmin <= height_ - 0.5f && umax >= -0.5f && umin <= width_ - 0.5f)) {
          continue;  // off the raster (or not finite)
        }
      }
      // (A triangle crossing the near plane may reach anywhere: all bands.)
      const int ba =
          std::clamp(static_cast<int>(std::floor(std::max(vmin, 0.0f))) / kBandRows, 0, bands - 1);
      const int bb = std::clamp(
          static_cast<int>(std::ceil(std::min(vmax, static_cast<float>(height_)))) / kBandRows, 0,
          bands - 1);
      for (int b = ba; b <= bb; ++b) bins[b].push_back(static_cast<std::int32_t>(k));
    }
  });
  // Bands rasterised in parallel; each takes its triangles chunk by chunk, in mesh order.
  tbb::parallel_for(0, bands, [&](int band) {
    const int y0 = band * kBandRows, y1 = std::min(height_, y0 + kBandRows);
    for (int chunk = 0; chunk < kChunks; ++chunk) {
      for (const std::int32_t tri : bins_[chunk][band]) raster_triangle(tri, y0, y1);
    }
  });
}

VisibilityRaster::Verdict VisibilityRaster::test(const Eigen::Vector3d& p_world,
                                                 const Eigen::Vector3d& p_camera,
                                                 double range_m) const {
  if (!(p_camera.z() > near_)) return Verdict::Unknown;
  const double u = sx_ * p_camera.x() / p_camera.z() + ox_;
  const double v = sy_ * p_camera.y() / p_camera.z() + oy_;
  // The four pixel centres around the vertex's raster position.
  if (!(u >= 0 && v >= 0 && u < width_ - 1 && v < height_ - 1)) return Verdict::Unknown;
  const int i0 = static_cast<int>(u), j0 = static_cast<int>(v);
  // The vertex's ray: origin + s·d, the vertex at s = 1. The Embree test's allowance: a surface
  // within max(1e-4 m, 1e-5·range) of the vertex is its own.
  const Eigen::Vector3d d = p_world - origin_world_;
  const double dnorm = d.norm();
  const double eps = std::max(1e-4, 1e-5 * range_m) / range_m;
  bool on_front_surface = false, undecided = false;
  const std::int32_t* row = id_.data() + static_cast<std::size_t>(j0) * width_ + i0;
  const std::int32_t ids[4] = {row[0], row[1], row[width_], row[width_ + 1]};
  for (int k = 0; k < 4; ++k) {
    const std::int32_t t = ids[k];
    if (t < 0) continue;  // open water there: no occluder
    if ((k > 0 && t == ids[k - 1]) || (k == 3 && t == ids[1]) || (k >= 2 && t == ids[0])) {
      continue;  // the same triangle as another of the four: the same verdict
    }
    const Eigen::Vector3d& n = normal_world_[t];
    const double denom = n.dot(d);
    if (!(std::abs(denom) > 1e-12 * dnorm)) {  // seen edge-on
      undecided = true;
      continue;
    }
    const double s = (offset_world_[t] - n.dot(origin_world_)) / denom;
    if (std::abs(s - 1.0) <= eps) {
      on_front_surface = true;  // the front surface at this centre passes through the vertex
      continue;
    }
    if (!(s < 1.0 - eps) || !(s > 0)) continue;  // the front surface there lies behind it
    // A front surface whose plane crosses the ray short of the vertex: hidden when the ray
    // crosses the triangle itself (exact), undecided when only its plane.
    const auto& tri = mesh_.triangles[t];
    const Eigen::Vector3d h = origin_world_ + s * d;
    const Eigen::Vector3d a = mesh_.vertices[tri[0]].cast<double>(),
                          b = mesh_.vertices[tri[1]].cast<double>(),
                          c = mesh_.vertices[tri[2]].cast<double>();
    if (n.dot((b - a).cross(h - a)) >= 0 && n.dot((c - b).cross(h - b)) >= 0 &&
        n.dot((a - c).cross(h - c)) >= 0) {
      return Verdict::Hidden;
    }
    undecided = true;  // another of the four may still prove it hidden
  }
  return on_front_surface && !undecided ? Verdict::Visible : Verdict::Unknown;
}

}  // namespace sonar3d::detail
