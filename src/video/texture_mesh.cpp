// Video mapping onto a mesh with Embree visibility (include/sonar3d/video/texture_mesh.hpp).
#include "sonar3d/video/texture_mesh.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <unordered_map>

#include "../core/embree_device.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/gltf.hpp"
#include "visibility_raster.hpp"

namespace sonar3d {

void MeshTextureConfig::validate() const {
  require(std::isfinite(texel_m) && texel_m >= 0, "texture mesh: texel_m must be >= 0 m");
  require(std::isfinite(max_range_m) && max_range_m > 0, "texture mesh: max_range_m must be > 0 m");
  require(max_vertices > 0, "texture mesh: max_vertices must be > 0");
}

std::size_t TexturedMesh::coloured() const {
  return static_cast<std::size_t>(
      std::count_if(views.begin(), views.end(), [](std::uint32_t v) { return v > 0; }));
}

TriangleMesh subdivide_to_edge(const TriangleMesh& mesh, double max_edge_m,
                               std::size_t max_vertices) {
  TriangleMesh m = mesh;
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
    for (const auto& t : m.triangles) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      tris.emplace_back(t[0], ab, ca);
      tris.emplace_back(ab, t[1], bc);
      tris.emplace_back(ca, bc, t[2]);
      tris.emplace_back(ab, bc, ca);
    }
    m.triangles = std::move(tris);
  }
  return m;
}

struct MeshTexturer::Impl {
  TriangleMesh mesh;
  MeshTextureConfig config;
  RTCScene scene = nullptr;
  std::vector<Eigen::Vector3d> sum;  // Σ weight · colour
  std::vector<double> weight;        // Σ weight
  std::vector<std::uint32_t> views;
  std::vector<Eigen::Vector3f> normal;  // unit vertex normals (weight_by_view)
  std::unique_ptr<detail::VisibilityRaster> raster;
  std::size_t raster_decided = 0, rays_cast = 0;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

MeshTexturer::MeshTexturer(const TriangleMesh& mesh, const MeshTextureConfig& config)
    : impl_(std::make_unique<Impl>()) {
  config.validate();
  require(!mesh.empty(), "texture mesh: the mesh has no triangles");
  impl_->config = config;
  impl_->scene = rtcNewScene(detail::embree_device());
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  // The occluder is the mesh as given (attach_mesh validates it); colours go on its subdivision.
  detail::attach_mesh(impl_->scene, mesh, "texture mesh");
  rtcCommitScene(impl_->scene);
  if (config.raster_visibility) impl_->raster = std::make_unique<detail::VisibilityRaster>(mesh);
  impl_->mesh = subdivide_to_edge(mesh, config.texel_m, config.max_vertices);
  detail::sort_vertices_spatially(impl_->mesh);
  impl_->sum.assign(impl_->mesh.vertices.size(), Eigen::Vector3d::Zero());
  impl_->weight.assign(impl_->mesh.vertices.size(), 0.0);
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
// already known to lie in the image.
inline Eigen::Vector3f sample_bilinear(const RgbImage& img, double x, double y) {
  x = std::clamp(x, 0.0, static_cast<double>(img.width - 1));
  y = std::clamp(y, 0.0, static_cast<double>(img.height - 1));
  const int u0 = static_cast<int>(x), v0 = static_cast<int>(y);  // x, y ≥ 0: the floor
  const int du = u0 + 1 < img.width ? 3 : 0;
  const std::size_t dv = v0 + 1 < img.height ? 3 * static_cast<std::size_t>(img.width) : 0;
  const float a = static_cast<float>(x - u0), b = static_cast<float>(y - v0);
  const float w00 = (1 - a) * (1 - b), w10 = a * (1 - b), w01 = (1 - a) * b, w11 = a * b;
  const float* p = img.rgb.data() + 3 * (static_cast<std::size_t>(v0) * img.width + u0);
  Eigen::Vector3f c;
  for (int k = 0; k < 3; ++k) {
    c[k] = w00 * p[k] + w10 * p[du + k] + w01 * p[dv + k] + w11 * p[dv + du + k];
  }
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
  const Eigen::Matrix3d R = T_camera_world.linear();
  const Eigen::Vector3d t = T_camera_world.translation();
  const Eigen::Vector3d origin = view.T_world_camera.translation();
  const CameraIntrinsics& cam = view.camera;
  const bool pinhole = !cam.distorted();  // then project() is x/z, y/z scaled: done inline
  const double umax = cam.width - 0.5, vmax = cam.height - 0.5;
  const auto& V = impl_->mesh.vertices;
  const double max_range = impl_->config.max_range_m, max_range2 = max_range * max_range;
  detail::VisibilityRaster* raster = impl_->raster.get();
  if (raster) raster->render(cam, T_camera_world);
  std::atomic<std::size_t> coloured{0}, decided{0}, rays{0};
  const float* const rgb = view.image->rgb.data();
  const bool weighted = impl_->config.weight_by_view;
  const std::size_t row_floats = 3 * static_cast<std::size_t>(cam.width);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, V.size(), 8192),
      [&](const tbb::blocked_range<std::size_t>& r) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        std::size_t local = 0, local_decided = 0, local_rays = 0;
        // Blocks of vertices in two passes: first where each falls (prefetching its raster pixels
        // and image pixels), then the tests — so that the memory latency of one vertex overlaps the
        // others'.
        constexpr std::size_t kBlock = 64;
        struct Candidate {
          Eigen::Vector3d p_world;
          Eigen::Vector2d px;
          double range;
          std::ptrdiff_t cell;
          std::size_t i;
        };
        Candidate cand[kBlock];
        for (std::size_t start = r.begin(); start < r.end(); start += kBlock) {
          const std::size_t stop = std::min(r.end(), start + kBlock);
          std::size_t n = 0;
          for (std::size_t i = start; i != stop; ++i) {
            const Eigen::Vector3d p_world = V[i].cast<double>();
            const Eigen::Vector3d p = R * p_world + t;
            if (!(p.z() > 0)) continue;
            const double range2 = p.squaredNorm();
            if (!(range2 <= max_range2)) continue;
            const double iz = 1.0 / p.z(), xn = p.x() * iz, yn = p.y() * iz;
            Eigen::Vector2d px;
            if (pinhole) {
              px = {cam.fx * xn + cam.cx, cam.fy * yn + cam.cy};
            } else {
              const auto q = project(cam, p);
              if (!q) continue;
              px = *q;
            }
            // in_image(): the pixel squares' outer edges
            if (!(px.x() >= -0.5 && px.y() >= -0.5 && px.x() < umax && px.y() < vmax)) continue;
            Candidate& c = cand[n++];
            c.p_world = p_world;
            c.px = px;
            c.range = std::sqrt(range2);
            c.cell = raster ? raster->locate(xn, yn, p.z()) : -1;
            if (raster) raster->prefetch(c.cell);
            const std::size_t pixel = static_cast<std::size_t>(std::max(0.0, px.y())) * row_floats +
                                      3 * static_cast<std::size_t>(std::max(0.0, px.x()));
            __builtin_prefetch(rgb + pixel);
            __builtin_prefetch(rgb + std::min(pixel + row_floats, view.image->rgb.size() - 1));
            c.i = i;
          }
          for (std::size_t k = 0; k < n; ++k) {
            const Candidate& c = cand[k];
            const auto verdict = raster ? raster->test(c.p_world, c.cell, c.range)
                                        : detail::VisibilityRaster::Verdict::Unknown;
            if (verdict == detail::VisibilityRaster::Verdict::Hidden) {
              ++local_decided;
              continue;
            }
            if (verdict == detail::VisibilityRaster::Verdict::Visible) {
              ++local_decided;
            } else {
              // Occluded when the mesh crosses the ray short of the vertex: stop a hair before it
              // (relative, for float precision at range) so its own triangles do not count.
              ++local_rays;
              const double dist = c.range;
              const Eigen::Vector3d d = (c.p_world - origin) / dist;
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
            const double inv_range = 1.0 / c.range;
            const double w =
                weighted
                    ? std::max(0.01,
                               std::abs(impl_->normal[c.i].cast<double>().dot(c.p_world - origin)) *
                                   inv_range) *
                          (inv_range * inv_range)
                    : 1.0;
            impl_->sum[c.i] += w * sample_bilinear(*view.image, c.px.x(), c.px.y()).cast<double>();
            impl_->weight[c.i] += w;
            ++impl_->views[c.i];
            ++local;
          }
        }
        coloured.fetch_add(local, std::memory_order_relaxed);
        decided.fetch_add(local_decided, std::memory_order_relaxed);
        rays.fetch_add(local_rays, std::memory_order_relaxed);
      });
  impl_->raster_decided += decided.load();
  impl_->rays_cast += rays.load();
  return coloured.load();
}

TexturedMesh MeshTexturer::result() const {
  TexturedMesh out;
  out.mesh = impl_->mesh;
  out.views = impl_->views;
  out.color.assign(out.mesh.vertices.size(), Eigen::Vector3f::Zero());
  for (std::size_t i = 0; i < out.color.size(); ++i) {
    if (out.views[i] > 0) out.color[i] = (impl_->sum[i] / impl_->weight[i]).cast<float>();
  }
  return out;
}

TexturedMesh texture_mesh(const TriangleMesh& mesh, const std::vector<CameraView>& views,
                          const MeshTextureConfig& config) {
  MeshTexturer t(mesh, config);
  for (std::size_t f = 0; f < views.size(); ++f) t.add(views[f], f);
  return t.result();
}

void write_textured_mesh_ply(const std::filesystem::path& path, const TexturedMesh& tm) {
  const TriangleMesh& m = tm.mesh;
  require(tm.color.size() == m.vertices.size(),
          "cannot write '" + path.string() + "': colour count differs from vertex count");
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path.string() + "' for writing");
    f << "ply\nformat binary_little_endian 1.0\ncomment sonar3d textured mesh, world frame, "
         "metres, sRGB vertex colours\nelement vertex "
      << m.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
         "property uchar green\nproperty uchar blue\nelement face "
      << m.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    std::vector<char> buf(m.vertices.size() * 15 + m.triangles.size() * 13);
    char* p = buf.data();
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      std::memcpy(p, m.vertices[i].data(), 12);
      p += 12;
      const std::array<std::uint8_t, 3> c =
          tm.views[i] ? linear_to_srgb8(tm.color[i]) : std::array<std::uint8_t, 3>{0, 0, 0};
      std::memcpy(p, c.data(), 3);
      p += 3;
    }
    for (const auto& t : m.triangles) {
      *p++ = 3;
      std::memcpy(p, t.data(), 12);
      p += 12;
    }
    f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    f.close();
    if (!f) throw Error("failed writing '" + path.string() + "' (disk full?)");
  }
  out.commit();
}

void write_textured_mesh_glb(const std::filesystem::path& path, const TexturedMesh& tm) {
  require(tm.color.size() == tm.mesh.vertices.size(),
          "cannot write '" + path.string() + "': colour count differs from vertex count");
  GltfScene scene;
  GltfMesh mesh;
  mesh.name = "textured";
  mesh.mesh = tm.mesh;
  mesh.base_color = Eigen::Vector4f(1, 1, 1, 1);  // the vertex colours as they are
  mesh.colors.resize(tm.color.size());
  for (std::size_t i = 0; i < tm.color.size(); ++i) {
    if (tm.views[i]) mesh.colors[i] = linear_to_srgb8(tm.color[i]);  // else black (resize)
  }
  scene.meshes.push_back(std::move(mesh));
  GltfNode node;
  node.name = "textured (world frame, ENU)";
  node.mesh = 0;
  node.matrix = enu_to_gltf();
  scene.nodes.push_back(node);
  scene.roots = {0};
  write_glb(path, scene);
}

}  // namespace sonar3d
