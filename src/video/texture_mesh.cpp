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

namespace {

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

// Renumbers the vertices along a Morton curve, so that vertices near in the mesh are near in
// memory and in every image: the per-frame loop then reads the raster and the image with few cache
// misses (subdivision appends midpoints in an order scattered over the model).
void sort_vertices_spatially(TriangleMesh& m) {
  const Eigen::AlignedBox3f box = m.bounding_box();
  const Eigen::Vector3f extent = (box.max() - box.min()).cwiseMax(1e-6f);
  std::vector<std::pair<std::uint64_t, int>> key(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Eigen::Vector3f q = (m.vertices[i] - box.min()).cwiseQuotient(extent) * 2097151.0f;
    key[i] = {spread3(static_cast<std::uint64_t>(q.x())) |
                  spread3(static_cast<std::uint64_t>(q.y())) << 1 |
                  spread3(static_cast<std::uint64_t>(q.z())) << 2,
              static_cast<int>(i)};
  }
  std::sort(key.begin(), key.end());
  std::vector<int> new_index(m.vertices.size());
  std::vector<Eigen::Vector3f> vertices(m.vertices.size());
  for (std::size_t k = 0; k < key.size(); ++k) {
    new_index[key[k].second] = static_cast<int>(k);
    vertices[k] = m.vertices[key[k].second];
  }
  m.vertices = std::move(vertices);
  for (auto& t : m.triangles)
    t = Eigen::Vector3i(new_index[t[0]], new_index[t[1]], new_index[t[2]]);
}

}  // namespace

struct MeshTexturer::Impl {
  TriangleMesh mesh;
  MeshTextureConfig config;
  RTCScene scene = nullptr;
  std::vector<Eigen::Vector3d> sum;
  std::vector<std::uint32_t> views;
  TriangleMesh occluder;  // the mesh as given
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
  if (config.raster_visibility) {
    impl_->occluder = mesh;
    impl_->raster = std::make_unique<detail::VisibilityRaster>(impl_->occluder);
  }
  impl_->mesh = subdivide_to_edge(mesh, config.texel_m, config.max_vertices);
  sort_vertices_spatially(impl_->mesh);
  impl_->sum.assign(impl_->mesh.vertices.size(), Eigen::Vector3d::Zero());
  impl_->views.assign(impl_->mesh.vertices.size(), 0);
}

MeshTexturer::~MeshTexturer() = default;

const TriangleMesh& MeshTexturer::mesh() const { return impl_->mesh; }
std::size_t MeshTexturer::raster_decided() const { return impl_->raster_decided; }
std::size_t MeshTexturer::rays_cast() const { return impl_->rays_cast; }

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
  const Eigen::Vector3d origin = view.T_world_camera.translation();
  const auto& V = impl_->mesh.vertices;
  const double max_range = impl_->config.max_range_m;
  detail::VisibilityRaster* raster = impl_->raster.get();
  if (raster) raster->render(view.camera, T_camera_world);
  std::atomic<std::size_t> coloured{0}, decided{0}, rays{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, V.size(), 4096),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      RTCIntersectContext ctx;
                      rtcInitIntersectContext(&ctx);
                      std::size_t local = 0, local_decided = 0, local_rays = 0;
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const Eigen::Vector3d p_world = V[i].cast<double>();
                        const Eigen::Vector3d p = T_camera_world * p_world;
                        if (!(p.z() > 0)) continue;
                        const double dist = p.norm();
                        if (dist > max_range) continue;
                        const auto px = project(view.camera, p);
                        if (!px || !in_image(view.camera, *px)) continue;
                        const auto verdict = raster ? raster->test(p_world, p, dist)
                                                    : detail::VisibilityRaster::Verdict::Unknown;
                        if (verdict == detail::VisibilityRaster::Verdict::Hidden) {
                          ++local_decided;
                          continue;
                        }
                        if (verdict == detail::VisibilityRaster::Verdict::Visible) {
                          ++local_decided;
                        } else {
                          // Occluded when the mesh crosses the ray short of the vertex: stop a hair
                          // before it (relative, for float precision at range) so its own triangles
                          // do not count.
                          ++local_rays;
                          const Eigen::Vector3d d = (p_world - origin) / dist;
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
                        impl_->sum[i] += view.image->sample(*px).cast<double>();
                        ++impl_->views[i];
                        ++local;
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
    if (out.views[i] > 0) out.color[i] = (impl_->sum[i] / out.views[i]).cast<float>();
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
      for (int k = 0; k < 3; ++k) {
        *p++ = static_cast<char>(tm.views[i] ? std::lround(255.0f * linear_to_srgb(tm.color[i][k]))
                                             : 0);
      }
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
    for (int k = 0; k < 3; ++k) {
      mesh.colors[i][k] = static_cast<std::uint8_t>(
          tm.views[i] ? std::lround(255.0f * linear_to_srgb(tm.color[i][k])) : 0);
    }
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
