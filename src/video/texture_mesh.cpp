// Video mapping onto a mesh with Embree visibility (include/sonar3d/video/texture_mesh.hpp).
#include "sonar3d/video/texture_mesh.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <unordered_map>

#include "../core/embree_device.hpp"
#include "sonar3d/core/error.hpp"
#include "visibility_raster.hpp"

namespace sonar3d {

void MeshTextureConfig::validate() const {
  require(std::isfinite(texel_m) && texel_m >= 0, "texture mesh: texel_m must be >= 0 m");
  require(std::isfinite(max_range_m) && max_range_m > 0, "texture mesh: max_range_m must be > 0 m");
  require(max_vertices > 0, "texture mesh: max_vertices must be > 0");
  require(std::isfinite(silhouette_weight) && silhouette_weight > 0 && silhouette_weight <= 1,
          "texture mesh: silhouette_weight must be in (0, 1]");
}

namespace {

// subdivide_to_edge(), also giving for each triangle of the result the index of the given triangle
// it lies in.
TriangleMesh subdivide_with_parents(const TriangleMesh& mesh, double max_edge_m,
                                    std::size_t max_vertices, std::vector<int>& parent) {
  TriangleMesh m = mesh;
  parent.resize(m.triangles.size());
  for (std::size_t t = 0; t < parent.size(); ++t) parent[t] = static_cast<int>(t);
  if (max_edge_m <= 0) return m;
  const double max2 = max_edge_m * max_edge_m;
  for (int level = 0; level < 32; ++level) {
    bool any = false;
    for (const auto& t : m.triangles) {
      for (int k = 0; k < 3; ++k) {
        if ((m.vertices[t[k]] - m.vertices[t[(k + 1) % 3]]).squaredNorm() > max2) any = true;
      }
      if (any) break;
    }
    if (!any) return m;
    // Each level splits every triangle (uniformly: no T-junctions, no cracks). Vertices after it:
    // V + E ≤ V + 3F/2 — checked before allocating.
    const std::size_t next = m.vertices.size() + 3 * m.triangles.size() / 2 + 1;
    if (next > max_vertices) {
      throw Error("texture mesh: subdividing to " + std::to_string(max_edge_m) +
                  " m edges needs more than " + std::to_string(max_vertices) +
                  " vertices (raise the texel size)");
    }
    std::unordered_map<std::uint64_t, int> mid;
    mid.reserve(3 * m.triangles.size() / 2);
    auto midpoint = [&](int a, int b) {
      const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                                static_cast<std::uint32_t>(std::max(a, b));
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const int id = static_cast<int>(m.vertices.size());
      m.vertices.push_back(0.5f * (m.vertices[a] + m.vertices[b]));
      mid.emplace(key, id);
      return id;
    };
    std::vector<Eigen::Vector3i> tris;
    tris.reserve(4 * m.triangles.size());
    std::vector<int> parents;
    parents.reserve(4 * m.triangles.size());
    for (std::size_t j = 0; j < m.triangles.size(); ++j) {
      const Eigen::Vector3i& t = m.triangles[j];
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      tris.emplace_back(t[0], ab, ca);
      tris.emplace_back(ab, t[1], bc);
      tris.emplace_back(ca, bc, t[2]);
      tris.emplace_back(ab, bc, ca);
      parents.insert(parents.end(), 4, parent[j]);
    }
    m.triangles = std::move(tris);
    parent = std::move(parents);
  }
  return m;
}

}  // namespace

TriangleMesh subdivide_to_edge(const TriangleMesh& mesh, double max_edge_m,
                               std::size_t max_vertices) {
  std::vector<int> parent;
  return subdivide_with_parents(mesh, max_edge_m, max_vertices, parent);
}

namespace {
constexpr std::size_t kChunk = 256;  // vertices culled together against a frame's view
}  // namespace

struct MeshTexturer::Impl {
  TriangleMesh mesh;
  MeshTextureConfig config;
  RTCScene scene = nullptr;
  std::vector<Eigen::Array4d> acc;  // per vertex: Σ weight · colour (linear RGB), Σ weight
  // Chunks of kChunk consecutive vertices (in their Morton order) with their bounding boxes, and
  // those the current frame may see.
  std::vector<Eigen::AlignedBox3f> chunk_box;
  std::vector<int> chunks_in_view;
  std::vector<float> xs, ys, zs;  // the vertices' coordinates, apart (for vectorised projection)
  std::vector<std::uint32_t> views;
  std::vector<Eigen::Vector3f> normal;  // unit vertex normals (weight_by_view)
  // Per vertex, the occluder triangles it lies on (the raster's numbering; those of the
  // triangles around it) when there are one or two: those (the first repeated when one); else
  // {kManyOwners, one of them} (a corner of the given mesh, or any vertex when texel_m = 0), and
  // the raster's plane test decides (told that one, for its neighbouring-facet rule).
  static constexpr std::uint32_t kManyOwners = 0xfffffffeu;
  std::vector<std::array<std::uint32_t, 2>> owner_pair;
  std::unique_ptr<detail::VisibilityRaster> raster;
  std::size_t raster_decided = 0, rays_cast = 0;
  // Frames still to go without the raster (see add()).
  int raster_rest = 0;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

MeshTexturer::MeshTexturer(const TriangleMesh& mesh, const MeshTextureConfig& config,
                           const TriangleMesh& occluders)
    : impl_(std::make_unique<Impl>()) {
  config.validate();
  require(!mesh.empty(), "texture mesh: the mesh has no triangles");
  impl_->config = config;
  impl_->scene = rtcNewScene(detail::embree_device());
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  // The occluder is the mesh as given and the other occluders (attach_mesh validates them);
  // colours go on the mesh's subdivision.
  detail::attach_mesh(impl_->scene, mesh, "texture mesh");
  if (!occluders.empty()) detail::attach_mesh(impl_->scene, occluders, "texture mesh occluders");
  rtcCommitScene(impl_->scene);
  if (config.raster_visibility) {
    // The mesh's triangles first, so that their given indices stay theirs (owners below).
    TriangleMesh all = mesh;
    all.append(occluders);
    impl_->raster = std::make_unique<detail::VisibilityRaster>(all, mesh.triangles.size());
  }
  std::vector<int> parent;
  impl_->mesh = subdivide_with_parents(mesh, config.texel_m, config.max_vertices, parent);
  detail::sort_vertices_spatially(impl_->mesh);
  if (impl_->raster) {
    // A vertex lies on the given triangles its subdivided triangles came from (one inside a given
    // triangle, two on its edge, the fan at its corner): the raster's quick test (owned()).
    const TriangleMesh& m = impl_->mesh;
    constexpr std::uint32_t kUnset = 0xffffffffu, kMany = Impl::kManyOwners;
    std::vector<std::array<std::uint32_t, 2>>& pair = impl_->owner_pair;
    pair.assign(m.vertices.size(), {kUnset, kUnset});
    for (std::size_t j = 0; j < m.triangles.size(); ++j) {
      const std::uint32_t owner = impl_->raster->internal_triangle(parent[j]);
      for (int k = 0; k < 3; ++k) {
        std::array<std::uint32_t, 2>& p = pair[m.triangles[j][k]];
        if (p[0] == kMany || p[0] == owner || p[1] == owner) continue;
        if (p[0] == kUnset) {
          p = {owner, owner};
        } else if (p[0] == p[1]) {
          p[1] = owner;
        } else {
          p = {kMany, p[0]};  // a third: one of them kept for test()
        }
      }
    }
    for (auto& p : pair) {
      if (p[0] == kUnset) p = {kMany, kMany};  // on no triangle: the plane test
    }
  }
  impl_->acc.assign(impl_->mesh.vertices.size(), Eigen::Array4d::Zero());
  impl_->chunk_box = detail::block_boxes(impl_->mesh.vertices, kChunk);
  for (const Eigen::Vector3f& v : impl_->mesh.vertices) {
    impl_->xs.push_back(v.x());
    impl_->ys.push_back(v.y());
    impl_->zs.push_back(v.z());
  }
  if (config.weight_by_view) {
    // Area-weighted face normals summed at the vertices (the cross products' lengths are twice
    // the areas); only their direction is used.
    const TriangleMesh& m = impl_->mesh;
    impl_->normal.assign(m.vertices.size(), Eigen::Vector3f::Zero());
    for (const auto& tri : m.triangles) {
      const Eigen::Vector3f n =
          (m.vertices[tri[1]] - m.vertices[tri[0]]).cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
      for (int k = 0; k < 3; ++k) impl_->normal[tri[k]] += n;
    }
    for (auto& n : impl_->normal) n = n.stableNormalized();
  }
  impl_->views.assign(impl_->mesh.vertices.size(), 0);
}

MeshTexturer::~MeshTexturer() = default;

const TriangleMesh& MeshTexturer::mesh() const { return impl_->mesh; }
std::size_t MeshTexturer::raster_decided() const { return impl_->raster_decided; }
std::size_t MeshTexturer::rays_cast() const { return impl_->rays_cast; }

namespace {

// RgbImage::sample (bilinear between pixel centres, clamped at the edges) inlined, for a pixel
// already known to lie in the image: (r, g, b, 1), each pixel read as four floats at once (its own
// three and the next one's red, weighted but dropped) except at the very end of the image.
inline Eigen::Array4f sample_bilinear(const RgbImage& img, float x, float y) {
  x = std::clamp(x, 0.0f, static_cast<float>(img.width - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.height - 1));
  const int u0 = static_cast<int>(x), v0 = static_cast<int>(y);  // x, y ≥ 0: the floor
  const std::size_t du = u0 + 1 < img.width ? 3 : 0;
  const std::size_t dv = v0 + 1 < img.height ? 3 * static_cast<std::size_t>(img.width) : 0;
  const float a = x - static_cast<float>(u0), b = y - static_cast<float>(v0);
  const float w00 = (1 - a) * (1 - b), w10 = a * (1 - b), w01 = (1 - a) * b, w11 = a * b;
  const std::size_t at = 3 * (static_cast<std::size_t>(v0) * img.width + u0);
  const float* p = img.rgb.data() + at;
  Eigen::Array4f c;
  if (at + dv + du + 4 <= img.rgb.size()) {
    using Pixel = Eigen::Map<const Eigen::Array4f>;  // unaligned
    c = w00 * Pixel(p) + w10 * Pixel(p + du) + w01 * Pixel(p + dv) + w11 * Pixel(p + dv + du);
  } else {
    for (int k = 0; k < 3; ++k) {
      c[k] = w00 * p[k] + w10 * p[du + k] + w01 * p[dv + k] + w11 * p[dv + du + k];
    }
  }
  c[3] = 1.0f;
  return c;
}

// sample_bilinear() from the pixels of `shows` only (bit k: pixel (u0, v0), (u0 + 1, v0),
// (u0, v0 + 1), (u0 + 1, v0 + 1)), their weights renormalised; equal weights when those it keeps
// all weigh nothing (the point on the far edge of a pixel square); all four when none is kept.
inline Eigen::Array4f sample_bilinear_masked(const RgbImage& img, float x, float y,
                                             unsigned shows) {
  if (shows == 0) return sample_bilinear(img, x, y);  // (a foreign plane through the point)
  x = std::clamp(x, 0.0f, static_cast<float>(img.width - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.height - 1));
  const int u0 = static_cast<int>(x), v0 = static_cast<int>(y);
  const int u1 = std::min(u0 + 1, img.width - 1), v1 = std::min(v0 + 1, img.height - 1);
  const float a = x - static_cast<float>(u0), b = y - static_cast<float>(v0);
  float w[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
  float sum = 0;
  for (int k = 0; k < 4; ++k) sum += (w[k] *= static_cast<float>((shows >> k) & 1u));
  if (!(sum > 1e-6f)) {
    sum = 0;
    for (int k = 0; k < 4; ++k) sum += (w[k] = static_cast<float>((shows >> k) & 1u));
  }
  const int us[4] = {u0, u1, u0, u1}, vs[4] = {v0, v0, v1, v1};
  Eigen::Array4f c = Eigen::Array4f::Zero();
  for (int k = 0; k < 4; ++k) {
    if (w[k] == 0) continue;
    const float* p = img.rgb.data() + 3 * (static_cast<std::size_t>(vs[k]) * img.width + us[k]);
    c.head<3>() += (w[k] / sum) * Eigen::Array3f(p[0], p[1], p[2]);
  }
  c[3] = 1.0f;
  return c;
}

}  // namespace

std::size_t MeshTexturer::add(const CameraView& view, std::size_t f) {
  view.camera.validate();
  require(view.image != nullptr && view.image->width == view.camera.width &&
              view.image->height == view.camera.height &&
              view.image->rgb.size() == 3 * static_cast<std::size_t>(view.camera.width) *
                                            static_cast<std::size_t>(view.camera.height),
          "texture mesh: frame " + std::to_string(f) + "'s image does not match its camera's size");
  require(view.T_world_camera.matrix().allFinite(),
          "texture mesh: frame " + std::to_string(f) + "'s pose is not finite");
  const Eigen::Isometry3d T_camera_world = view.T_world_camera.inverse();
  // The vertices are stored in float; so is their way to the image (a millipixel at 100 m).
  const Eigen::Matrix3f R = T_camera_world.linear().cast<float>();
  const Eigen::Vector3f t = T_camera_world.translation().cast<float>();
  const Eigen::Vector3d origin = view.T_world_camera.translation();
  const Eigen::Vector3f origin_f = origin.cast<float>();
  const CameraIntrinsics& cam = view.camera;
  const bool distorted = cam.distorted(), pinhole = !distorted;  // pinhole: project() inline
  const float fx = static_cast<float>(cam.fx), fy = static_cast<float>(cam.fy),
              cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
  const float umax = static_cast<float>(cam.width) - 0.5f,
              vmax = static_cast<float>(cam.height) - 0.5f;
  const auto& V = impl_->mesh.vertices;
  const float max_range2 =
      static_cast<float>(impl_->config.max_range_m * impl_->config.max_range_m);
  // The raster pays when it settles most tests. When it left more than a third of a frame's to
  // rays (a curved surface seen at a slant: neighbouring triangles' planes cross the vertices'
  // rays just in front of them), the next kRasterRest frames go straight to the rays, which are
  // exact, and the one after tries the raster again (frames of a video change slowly). A third:
  // where the benchmarks' raster and ray times cross (raster + rays 2.6 times faster than rays
  // alone at 1.5 % of tests left to rays, 1.3 times slower at 49 %).
  constexpr int kRasterRest = 7;
  detail::VisibilityRaster* raster = impl_->raster_rest > 0 ? nullptr : impl_->raster.get();
  if (!raster && impl_->raster) --impl_->raster_rest;
  if (raster) raster->render(cam, T_camera_world);
  std::atomic<std::size_t> coloured{0}, decided{0}, rays{0};
  const float* const rgb = view.image->rgb.data();
  const std::size_t rgb_last = view.image->rgb.size() - 1;
  // The raster's position of a normalised image point and its cell (visibility_raster.hpp).
  const float rsx = raster ? static_cast<float>(raster->sx()) : 0.0f,
              rsy = raster ? static_cast<float>(raster->sy()) : 0.0f,
              rox = raster ? static_cast<float>(raster->ox()) : 0.0f,
              roy = raster ? static_cast<float>(raster->oy()) : 0.0f,
              rnear = raster ? static_cast<float>(raster->near_plane())
                             : std::numeric_limits<float>::infinity(),
              ru1 = raster ? static_cast<float>(raster->width() - 1) : 0.0f,
              rv1 = raster ? static_cast<float>(raster->height() - 1) : 0.0f;
  const std::int32_t rstride = raster ? raster->stride() : 0;
  const bool weighted = impl_->config.weight_by_view;
  const float silhouette_weight = static_cast<float>(impl_->config.silhouette_weight);
  const std::size_t row_floats = 3 * static_cast<std::size_t>(cam.width);
  const std::array<std::uint32_t, 2>* owner_pair = impl_->owner_pair.data();
  Eigen::Array4d* const acc = impl_->acc.data();
  std::uint32_t* const views = impl_->views.data();
  const Eigen::Vector3f* const normal = impl_->normal.data();
  // Only the chunks of vertices the camera may see (a frame of a survey sees a part of a model).
  std::vector<int>& chunks = impl_->chunks_in_view;
  detail::blocks_in_view(impl_->chunk_box, cam, T_camera_world, impl_->config.max_range_m, chunks);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, chunks.size(), 32),
      [&](const tbb::blocked_range<std::size_t>& r) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        std::size_t local = 0, local_decided = 0, local_rays = 0;
        // Blocks of vertices in three steps: all projected at once (no branches: vectorised),
        // those in the image kept (prefetching their raster and image pixels), then tested one
        // block later — so that the memory latency of one vertex overlaps the others'.
        constexpr std::size_t kBlock = 64;  // divides kChunk
        struct Candidate {
          float x, y;  // pixel
          float range;
          std::ptrdiff_t cell;
          std::size_t i;
        };
        alignas(64) float bx[kBlock], by[kBlock], br2[kBlock];
        alignas(64) std::int32_t bok[kBlock], bcell[kBlock];
        const float* const xs = impl_->xs.data();
        const float* const ys = impl_->ys.data();
        const float* const zs = impl_->zs.data();
        // The tests of one block's candidates.
        auto settle = [&](const Candidate* cs, std::size_t count) {
          for (std::size_t k = 0; k < count; ++k) {
            const Candidate& c = cs[k];
            using Verdict = detail::VisibilityRaster::Verdict;
            Verdict verdict = Verdict::Unknown;
            unsigned shows = 0xfu;  // the pixels that show the model (raster, test())
            if (raster) {
              // Its own triangles in front at the four pixel centres: visible, no arithmetic.
              const std::array<std::uint32_t, 2>& pair = owner_pair[c.i];
              verdict =
                  pair[0] != Impl::kManyOwners && raster->owned(c.cell, pair[0], pair[1], shows)
                      ? Verdict::Visible
                      : raster->test(V[c.i].cast<double>(), c.cell, c.range, shows, pair[0],
                                     pair[1]);
            }
            if (verdict == Verdict::Hidden) {
              ++local_decided;
              continue;
            }
            if (verdict == Verdict::Visible) {
              ++local_decided;
            } else {
              // Occluded when the mesh crosses the ray short of the vertex: stop a hair before it
              // (relative, for float precision at range) so its own triangles do not count.
              ++local_rays;
              const double dist = c.range;
              const Eigen::Vector3d d = (V[c.i].cast<double>() - origin) / dist;
              RTCRay ray;
              ray.org_x = static_cast<float>(origin.x());
              ray.org_y = static_cast<float>(origin.y());
              ray.org_z = static_cast<float>(origin.z());
              ray.dir_x = static_cast<float>(d.x());
              ray.dir_y = static_cast<float>(d.y());
              ray.dir_z = static_cast<float>(d.z());
              ray.tnear = 0.0f;
              ray.tfar = static_cast<float>(dist - std::max(1e-4, 1e-5 * dist));
              ray.mask = 0xFFFFFFFFu;
              ray.flags = 0;
              ray.time = 0.0f;
              rtcOccluded1(impl_->scene, &ctx, &ray);
              if (ray.tfar < 0) continue;  // Embree sets tfar to −inf on a hit
            }
            // Weight: |cos θ| / range² = |n · (p − o)| / range³, the pixel's footprint's inverse.
            const float inv_range = 1.0f / c.range;
            const float w =
                (weighted
                     ? std::max(0.01f, std::abs(normal[c.i].dot(V[c.i] - origin_f)) * inv_range) *
                           (inv_range * inv_range)
                     : 1.0f) *
                (shows != 0xfu ? silhouette_weight : 1.0f);
            // Within a pixel of the silhouette: from the pixels that show the model only (a
            // pinhole's raster pixels are the image's).
            const Eigen::Array4f colour =
                shows == 0xfu || !pinhole ? sample_bilinear(*view.image, c.x, c.y)
                                          : sample_bilinear_masked(*view.image, c.x, c.y, shows);
            acc[c.i] += (w * colour).cast<double>();
            ++views[c.i];
            ++local;
          }
        };
        Candidate cand[2][kBlock];  // this block's candidates and the previous one's
        int cur = 0;
        std::size_t pending = 0;  // candidates of the previous block
        for (std::size_t chunk = r.begin(); chunk != r.end(); ++chunk) {
          const std::size_t first = static_cast<std::size_t>(chunks[chunk]) * kChunk;
          const std::size_t last = std::min(V.size(), first + kChunk);
          for (std::size_t start = first; start < last; start += kBlock) {
            const std::size_t m = std::min(last - start, kBlock);
            for (std::size_t j = 0; j < m; ++j) {
              const float X = xs[start + j], Y = ys[start + j], Z = zs[start + j];
              const float px = R(0, 0) * X + R(0, 1) * Y + R(0, 2) * Z + t.x();
              const float py = R(1, 0) * X + R(1, 1) * Y + R(1, 2) * Z + t.y();
              const float pz = R(2, 0) * X + R(2, 1) * Y + R(2, 2) * Z + t.z();
              const float iz = 1.0f / pz;  // ±inf or negative behind the camera: rejected below
              const float xn = px * iz, yn = py * iz;
              const float x = fx * xn + cx, y = fy * yn + cy;
              bx[j] = x;
              by[j] = y;
              const float u = rsx * xn + rox, v = rsy * yn + roy;
              const bool in_raster = (pz > rnear) & (u >= 0) & (v >= 0) & (u < ru1) & (v < rv1);
              // Within the raster (u, v) ≥ 0: the integer parts are the floors. Outside: −1 (and
              // (0, 0) converted, which any float converts to safely).
              const std::int32_t keep = -static_cast<std::int32_t>(in_raster);  // all ones: inside
              const float uc = in_raster ? u : 0.0f, vc = in_raster ? v : 0.0f;
              bcell[j] =
                  ((static_cast<std::int32_t>(vc) * rstride + static_cast<std::int32_t>(uc)) &
                   keep) |
                  ~keep;
              const float r2 = px * px + py * py + pz * pz;
              br2[j] = r2;
              // in front, in range and (a pinhole's) in_image(): the pixel squares' outer edges
              bok[j] = static_cast<std::int32_t>(
                  (pz > 0) & (r2 <= max_range2) &
                  (distorted | ((x >= -0.5f) & (y >= -0.5f) & (x < umax) & (y < vmax))));
            }
            std::size_t n = 0;
            for (std::size_t j = 0; j < m; ++j) {
              if (!bok[j]) continue;
              float x = bx[j], y = by[j];
              if (!pinhole) {
                const Eigen::Vector3f p = R * V[start + j] + t;
                const auto q = project(cam, p.cast<double>());
                if (!q) continue;
                x = static_cast<float>(q->x());
                y = static_cast<float>(q->y());
                if (!(x >= -0.5f && y >= -0.5f && x < umax && y < vmax)) continue;
              }
              Candidate& c = cand[cur][n++];
              c.x = x;
              c.y = y;
              c.range = std::sqrt(br2[j]);
              c.i = start + j;
              c.cell = bcell[j];
              if (raster) raster->prefetch(c.cell);
              const std::size_t pixel = static_cast<std::size_t>(std::max(0.0f, y)) * row_floats +
                                        3 * static_cast<std::size_t>(std::max(0.0f, x));
              __builtin_prefetch(rgb + pixel);
              __builtin_prefetch(rgb + std::min(pixel + row_floats, rgb_last));
            }
            // The previous block's tests, while this block's pixels are on their way.
            settle(cand[cur ^ 1], pending);
            pending = n;
            cur ^= 1;
          }
        }
        settle(cand[cur ^ 1], pending);
        coloured.fetch_add(local, std::memory_order_relaxed);
        decided.fetch_add(local_decided, std::memory_order_relaxed);
        rays.fetch_add(local_rays, std::memory_order_relaxed);
      });
  impl_->raster_decided += decided.load();
  impl_->rays_cast += rays.load();
  if (raster && 3 * rays.load() > decided.load() + rays.load()) impl_->raster_rest = kRasterRest;
  return coloured.load();
}

TexturedMesh MeshTexturer::result() const {
  TexturedMesh out;
  out.mesh = impl_->mesh;
  out.views = impl_->views;
  out.color.assign(out.mesh.vertices.size(), Eigen::Vector3f::Zero());
  for (std::size_t i = 0; i < out.color.size(); ++i) {
    const Eigen::Array4d& a = impl_->acc[i];
    if (out.views[i] > 0) out.color[i] = (a.head<3>() / a[3]).cast<float>().matrix();
  }
  return out;
}

TexturedMesh texture_mesh(const TriangleMesh& mesh, const std::vector<CameraView>& views,
                          const MeshTextureConfig& config, const TriangleMesh& occluders) {
  MeshTexturer t(mesh, config, occluders);
  for (std::size_t f = 0; f < views.size(); ++f) t.add(views[f], f);
  return t.result();
}

}  // namespace sonar3d
