// Visibility buffer for mesh texturing (src/video/visibility_raster.hpp).
#include "visibility_raster.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "sonar3d/core/error.hpp"

namespace sonar3d::detail {

namespace {
constexpr double kMaxRasterFactor = 4.0;  // raster pixels at most this times the image's
constexpr int kBandRows = 64;  // raster rows per band (rasterised in parallel; 1/z ~256 KB at 1 MP)
constexpr int kBlock = 64;     // triangles per block (consecutive in the spatial order)

// Spreads the low 21 bits of v to every third bit (Morton code).
std::uint64_t spread3(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

}  // namespace

std::vector<int> morton_order(const std::vector<Eigen::Vector3f>& points) {
  // One scale for the three axes (a cube around the points): a flat model (a seabed, a relief)
  // then splits along its length first, so that consecutive points stay close in every direction.
  Eigen::AlignedBox3f box;
  for (const Eigen::Vector3f& p : points) box.extend(p);
  const float extent = std::max((box.max() - box.min()).maxCoeff(), 1e-6f);
  std::vector<std::pair<std::uint64_t, int>> key(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f q =
        ((points[i] - box.min()) / extent * 2097151.0f).cwiseMax(0.0f).cwiseMin(2097151.0f);
    key[i] = {spread3(static_cast<std::uint64_t>(q.x())) |
                  spread3(static_cast<std::uint64_t>(q.y())) << 1 |
                  spread3(static_cast<std::uint64_t>(q.z())) << 2,
              static_cast<int>(i)};
  }
  std::sort(key.begin(), key.end());
  std::vector<int> order(points.size());
  for (std::size_t k = 0; k < key.size(); ++k) order[k] = key[k].second;
  return order;
}

void sort_vertices_spatially(TriangleMesh& m) {
  const std::vector<int> order = morton_order(m.vertices);
  std::vector<int> new_index(m.vertices.size());
  std::vector<Eigen::Vector3f> vertices(m.vertices.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    new_index[order[k]] = static_cast<int>(k);
    vertices[k] = m.vertices[order[k]];
  }
  m.vertices = std::move(vertices);
  for (auto& t : m.triangles)
    t = Eigen::Vector3i(new_index[t[0]], new_index[t[1]], new_index[t[2]]);
}

std::vector<Eigen::AlignedBox3f> block_boxes(const std::vector<Eigen::Vector3f>& points,
                                             std::size_t block_size) {
  std::vector<Eigen::AlignedBox3f> boxes((points.size() + block_size - 1) / block_size);
  for (std::size_t k = 0; k < points.size(); ++k) boxes[k / block_size].extend(points[k]);
  return boxes;
}

void blocks_in_view(const std::vector<Eigen::AlignedBox3f>& boxes, const CameraIntrinsics& camera,
                    const Eigen::Isometry3d& T_camera_world, double max_range_m,
                    std::vector<int>& out) {
  out.clear();
  const Eigen::AlignedBox2d bounds = normalised_image_bounds(camera);
  const Eigen::Vector3d origin = T_camera_world.inverse().translation();
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    const Eigen::AlignedBox3d box = boxes[b].cast<double>();
    if (box.exteriorDistance(origin) > max_range_m) continue;
    int behind = 0;
    Eigen::AlignedBox2d seen;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d p =
          T_camera_world * box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
      if (!(p.z() > 0)) {
        ++behind;
      } else {
        seen.extend(Eigen::Vector2d(p.x() / p.z(), p.y() / p.z()));
      }
    }
    if (behind == 8) continue;
    if (behind == 0 && !seen.intersects(bounds)) continue;
    out.push_back(static_cast<int>(b));
  }
}

VisibilityRaster::VisibilityRaster(const TriangleMesh& occluder, std::size_t first_foreign)
    : mesh_(occluder) {
  if (mesh_.triangles.size() >= kNone / 2) {  // ids are compared as signed 32-bit integers
    throw Error("texture mesh: the occluder has more than 2³¹ triangles");
  }
  // Spatial order: vertices along the Morton curve, triangles by their first vertex in it.
  sort_vertices_spatially(mesh_);
  {
    // Ties in the first vertex keep the given order, so the numbering is deterministic.
    std::vector<std::pair<int, int>> key(mesh_.triangles.size());
    for (std::size_t t = 0; t < key.size(); ++t) {
      key[t] = {mesh_.triangles[t].minCoeff(), static_cast<int>(t)};
    }
    std::sort(key.begin(), key.end());
    std::vector<Eigen::Vector3i> sorted(key.size());
    internal_of_given_.resize(key.size());
    foreign_.resize(key.size());
    for (std::size_t k = 0; k < key.size(); ++k) {
      sorted[k] = mesh_.triangles[key[k].second];
      internal_of_given_[key[k].second] = static_cast<std::uint32_t>(k);
      foreign_[k] = static_cast<std::size_t>(key[k].second) >= first_foreign;
    }
    mesh_.triangles = std::move(sorted);
  }
  const auto& V = mesh_.vertices;
  plane_.resize(mesh_.triangles.size());
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    const auto& tri = mesh_.triangles[t];
    const Eigen::Vector3d a = V[tri[0]].cast<double>(), b = V[tri[1]].cast<double>(),
                          c = V[tri[2]].cast<double>();
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    n = len > 0 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
    plane_[t] = {n, n.dot(a)};
  }
  const std::size_t blocks = (mesh_.triangles.size() + kBlock - 1) / kBlock;
  block_box_.resize(blocks);
  block_vertices_.assign(blocks, {std::numeric_limits<int>::max(), 0});
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    auto& range = block_vertices_[t / kBlock];
    for (int k = 0; k < 3; ++k) {
      const int i = mesh_.triangles[t][k];
      block_box_[t / kBlock].extend(V[i]);
      range.first = std::min(range.first, i);
      range.second = std::max(range.second, i + 1);
    }
  }
}

void VisibilityRaster::setup_raster(const CameraIntrinsics& c) {
  // The raster covers the image's field of view in the undistorted normalised plane: the bounds
  // of the rays through the image's border (for a pinhole, exactly the image).
  const Eigen::AlignedBox2d bounds = normalised_image_bounds(c);
  const double xmin = bounds.min().x(), xmax = bounds.max().x();
  const double ymin = bounds.min().y(), ymax = bounds.max().y();
  double scale = 1.0;
  if (c.distorted()) {
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
  stride_ = (width_ + 3) & ~3;
  id_.assign(static_cast<std::size_t>(stride_) * height_, kNone);
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

// The pixel centres of rows y0 … y1 − 1 inside the triangle's bounding box.
inline VisibilityRaster::Box VisibilityRaster::box(const float* u, const float* v, int y0,
                                                   int y1) const {
  const float lo_x = -1.0f, hi_x = static_cast<float>(width_);
  const float lo_y = static_cast<float>(y0) - 1.0f, hi_y = static_cast<float>(y1);
  const float umin = std::clamp(std::min(u[0], std::min(u[1], u[2])), lo_x, hi_x);
  const float umax = std::clamp(std::max(u[0], std::max(u[1], u[2])), lo_x, hi_x);
  const float vmin = std::clamp(std::min(v[0], std::min(v[1], v[2])), lo_y, hi_y);
  const float vmax = std::clamp(std::max(v[0], std::max(v[1], v[2])), lo_y, hi_y);
  return {std::max(0, ceil_small(umin)), std::min(width_ - 1, floor_small(umax)),
          std::max(y0, ceil_small(vmin)), std::min(y1 - 1, floor_small(vmax))};
}

inline void VisibilityRaster::fill(const float* u, const float* v, const float* w, int tri,
                                   const Box& b, const Band& band, int y0) {
  if (b.xa > b.xb || b.ya > b.yb) return;
  // Edge functions (barycentric weights) over those centres, affine in x along a row; w = 1/z is
  // affine in screen space, so it interpolates with the same weights.
  const float area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
  if (!(std::abs(area) > 1e-12f)) return;  // edge-on: covers no area
  const float inv_area = 1.0f / area;
  const float dx0 = (v[1] - v[2]) * inv_area, dx1 = (v[2] - v[0]) * inv_area;
  // Wide triangles: per row, only the span where the three weights can be ≥ 0 (b_k = r_k + dx_k·x
  // bounds x on one side each), widened by a pixel for rounding; the test below stays the judge,
  // so the pixels written are the same as over the whole box. Up to 17 pixels wide, the whole
  // row of the box: finding the span (~25 operations, branches on the edges' directions) costs
  // about what the groups of four it would skip cost (measured: 14–20 best on a CAD-like model
  // of ~11-pixel triangles, 6 was 5 % slower).
  const bool spans = b.xb - b.xa > 16;
  const float dx[3] = {dx0, dx1, -dx0 - dx1};
  float inv_dx[3] = {0, 0, 0};
  if (spans) {
    for (int k = 0; k < 3; ++k) inv_dx[k] = dx[k] != 0 ? 1.0f / dx[k] : 0.0f;
  }
  using F4 = float __attribute__((vector_size(16)));
  using I4 = std::int32_t __attribute__((vector_size(16)));
  using U4 = std::uint32_t __attribute__((vector_size(16)));
  const F4 lane = {0.0f, 1.0f, 2.0f, 3.0f};
  const std::uint32_t t = static_cast<std::uint32_t>(tri);
  const U4 t4 = {t, t, t, t};
  // Ids < 2³¹ (the constructor checks), and kNone is −1 signed: compared signed, one instruction.
  const I4 t4s = (I4)t4;
  for (int y = b.ya; y <= b.yb; ++y) {
    const float py = static_cast<float>(y);
    // b0, b1 at x = 0 of this row.
    const float r0 = (u[1] * (v[2] - py) - u[2] * (v[1] - py)) * inv_area;
    const float r1 = (u[2] * (v[0] - py) - u[0] * (v[2] - py)) * inv_area;
    const std::size_t row = static_cast<std::size_t>(y - y0) * stride_;
    float* const depth = band.inv_z + row;
    std::uint32_t* const id = band.id + row;
    int xa = b.xa, xb = b.xb;
    if (spans) {
      const float r[3] = {r0, r1, 1.0f - r0 - r1};
      float lo = static_cast<float>(xa), hi = static_cast<float>(xb);
      for (int k = 0; k < 3; ++k) {
        if (dx[k] > 0) {
          lo = std::max(lo, -r[k] * inv_dx[k] - 1.0f);
        } else if (dx[k] < 0) {
          hi = std::min(hi, -r[k] * inv_dx[k] + 1.0f);
        }
      }
      if (!(lo <= hi)) continue;
      // 0 ≤ xa ≤ lo ≤ hi ≤ xb here: truncation is the floor, and the ceiling one more if short.
      const int hi_int = static_cast<int>(hi);
      xa = std::max(xa, static_cast<int>(lo));
      xb = std::min(xb, hi_int + (static_cast<float>(hi_int) < hi));
    }
    // Without branches, in aligned groups of four pixels, as vectors (GCC/Clang vector
    // extensions: SSE2 on x86-64, NEON on ARM; spans are short, so a compiler-vectorised loop's
    // remainder would dominate): the nearest surface wins, ties going to the larger triangle id,
    // so the result does not depend on the order of the triangles. The pixels a group adds beyond
    // the span lie outside the triangle, and the test leaves them as they are; the rows' stride
    // is a multiple of four, so a group never leaves its row (beyond the width: padding, never
    // read).
    for (int x = xa & ~3; x <= xb; x += 4) {
      const F4 px = static_cast<float>(x) + lane;
      const F4 b0 = r0 + dx0 * px, b1 = r1 + dx1 * px, b2 = 1.0f - b0 - b1;
      const F4 iz = b0 * w[0] + b1 * w[1] + b2 * w[2];
      F4 d;
      U4 i;
      std::memcpy(&d, depth + x, sizeof d);
      std::memcpy(&i, id + x, sizeof i);
      const I4 take =
          (b0 >= 0) & (b1 >= 0) & (b2 >= 0) & (iz > 0) & ((iz > d) | ((iz == d) & (t4s > (I4)i)));
      // (casts between vector types of one size keep the bits)
      const I4 dn = ((I4)iz & take) | ((I4)d & ~take);
      const U4 in = (t4 & (U4)take) | (i & ~(U4)take);
      std::memcpy(depth + x, &dn, sizeof dn);
      std::memcpy(id + x, &in, sizeof in);
    }
  }
}

void VisibilityRaster::raster_triangle(int t, int y0, int y1, const Band& band) {
  const auto& tri = mesh_.triangles[t];
  const Projected& a = projected_[tri[0]];
  const Projected& b = projected_[tri[1]];
  const Projected& c = projected_[tri[2]];
  if (a.w > 0 && b.w > 0 && c.w > 0) {  // all in front of the near plane
    const float u[3] = {a.u, b.u, c.u}, v[3] = {a.v, b.v, c.v}, w[3] = {a.w, b.w, c.w};
    fill(u, v, w, t, box(u, v, y0, y1), band, y0);
    return;
  }
  const float nz = static_cast<float>(near_);
  const Eigen::Vector3f p[3] = {R_ * mesh_.vertices[tri[0]] + t_, R_ * mesh_.vertices[tri[1]] + t_,
                                R_ * mesh_.vertices[tri[2]] + t_};
  // Crossing the near plane: clip the polygon to z ≥ near (Sutherland–Hodgman, one plane), then
  // fan it into triangles.
  Eigen::Vector3f poly[4];
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3f& pa = p[k];
    const Eigen::Vector3f& pb = p[(k + 1) % 3];
    const bool ina = pa.z() > nz, inb = pb.z() > nz;
    if (ina) poly[n++] = pa;
    if (ina != inb) {
      const float s = (nz - pa.z()) / (pb.z() - pa.z());
      poly[n++] = pa + s * (pb - pa);
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
    fill(tu, tv, tw, t, box(tu, tv, y0, y1), band, y0);
  }
}

void VisibilityRaster::prefetch_block(int blk) const {
  const char* tris = reinterpret_cast<const char*>(mesh_.triangles.data() + blk * kBlock);
  const std::size_t tri_bytes =
      sizeof(Eigen::Vector3i) *
      static_cast<std::size_t>(std::min<std::ptrdiff_t>(
          kBlock, static_cast<std::ptrdiff_t>(mesh_.triangles.size()) - blk * kBlock));
  for (std::size_t o = 0; o < tri_bytes; o += 64) __builtin_prefetch(tris + o);
  const auto [first, last] = block_vertices_[blk];
  if (last - first > 4 * kBlock) return;  // scattered: not worth it
  const char* verts = reinterpret_cast<const char*>(projected_.data() + first);
  for (std::size_t o = 0; o < sizeof(Projected) * static_cast<std::size_t>(last - first); o += 64) {
    __builtin_prefetch(verts + o);
  }
}

void VisibilityRaster::render(const CameraIntrinsics& camera,
                              const Eigen::Isometry3d& T_camera_world, double near_m) {
  if (!have_raster_ || camera.width != raster_for_.width || camera.height != raster_for_.height ||
      camera.fx != raster_for_.fx || camera.fy != raster_for_.fy || camera.cx != raster_for_.cx ||
      camera.cy != raster_for_.cy || camera.k1 != raster_for_.k1 || camera.k2 != raster_for_.k2 ||
      camera.p1 != raster_for_.p1 || camera.p2 != raster_for_.p2 || camera.k3 != raster_for_.k3) {
    setup_raster(camera);
  }
  near_ = near_m;
  origin_world_ = T_camera_world.inverse().translation();
  const auto& V = mesh_.vertices;
  projected_.resize(V.size());
  R_ = T_camera_world.linear().cast<float>();
  t_ = T_camera_world.translation().cast<float>();
  const Eigen::Matrix3f& R = R_;
  const Eigen::Vector3f& t = t_;
  const float nz = static_cast<float>(near_);
  const float sx = static_cast<float>(sx_), sy = static_cast<float>(sy_),
              ox = static_cast<float>(ox_), oy = static_cast<float>(oy_);
  // Vertices to the camera frame and the raster.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, V.size(), 16384),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const Eigen::Vector3f p = R * V[i] + t;
                        const float w = p.z() > nz ? 1.0f / p.z() : 0.0f;
                        projected_[i] = {sx * p.x() * w + ox, sy * p.y() * w + oy, w};
                      }
                    });
  // Blocks of triangles (consecutive in the spatial order, so compact) binned by raster band by
  // the projection of their world bounding box; then the bands rasterised in parallel, each
  // clearing and writing only its own rows (no atomics; a band's depths ~256 KB at 1 MP, so
  // they stay in the cache).
  const int bands = (height_ + kBandRows - 1) / kBandRows;
  band_blocks_.resize(bands);
  for (auto& b : band_blocks_) b.clear();
  for (std::size_t blk = 0; blk < block_box_.size(); ++blk) {
    const Eigen::AlignedBox3f& bb = block_box_[blk];
    float umin = 1e30f, umax = -1e30f, vmin = 1e30f, vmax = -1e30f;
    int behind = 0;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3f p = R * bb.corner(static_cast<Eigen::AlignedBox3f::CornerType>(c)) + t;
      if (!(p.z() > nz)) {
        ++behind;
        continue;
      }
      const float u = sx * p.x() / p.z() + ox, v = sy * p.y() / p.z() + oy;
      umin = std::min(umin, u);
      umax = std::max(umax, u);
      vmin = std::min(vmin, v);
      vmax = std::max(vmax, v);
    }
    if (behind == 8) continue;       // wholly behind the near plane
    int ba = 0, bb_end = bands - 1;  // crossing it: its clipped triangles may reach any band
    if (behind == 0) {
      // A pixel centre inside a triangle lies inside the projection of the box (margin: 1 px).
      if (!(vmax >= -1.0f && vmin <= height_ && umax >= -1.0f && umin <= width_)) continue;
      ba = std::clamp(static_cast<int>(std::floor(std::max(vmin - 1.0f, 0.0f))) / kBandRows, 0,
                      bands - 1);
      bb_end = std::clamp(
          static_cast<int>(std::ceil(std::min(vmax + 1.0f, static_cast<float>(height_)))) /
              kBandRows,
          0, bands - 1);
    }
    for (int b = ba; b <= bb_end; ++b) band_blocks_[b].push_back(static_cast<std::int32_t>(blk));
  }
  const int T = static_cast<int>(mesh_.triangles.size());
  tbb::parallel_for(0, bands, [&](int band) {
    const int y0 = band * kBandRows, y1 = std::min(height_, y0 + kBandRows);
    // The band's depths in the thread's own cells, its triangle ids straight into the raster
    // (kNone where no triangle takes a pixel: a triangle takes a pixel only with 1/z > 0).
    const std::size_t n = static_cast<std::size_t>(y1 - y0) * stride_;
    std::vector<float>& inv_z = band_inv_z_.local();
    inv_z.assign(n, 0.0f);
    std::uint32_t* const ids = id_.data() + static_cast<std::size_t>(y0) * stride_;
    std::fill(ids, ids + n, kNone);
    const Band out{inv_z.data(), ids};
    const auto& blocks = band_blocks_[band];
    for (std::size_t j = 0; j < blocks.size(); ++j) {
      if (j + 1 < blocks.size()) prefetch_block(blocks[j + 1]);  // hide its memory latency
      const int blk = blocks[j];
      const int end = std::min(T, (blk + 1) * kBlock);
      for (int tri = blk * kBlock; tri < end; ++tri) raster_triangle(tri, y0, y1, out);
    }
  });
}

}  // namespace sonar3d::detail
