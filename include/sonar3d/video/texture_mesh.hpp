#pragma once
// Video mapping onto a mesh (thesis sec. 6.4: the registered CAD models): each frame's colour
// sampled at the mesh's vertices that the camera sees, averaged over frames. Visibility comes from
// the mesh itself, so no colour reaches a surface behind another (the thesis' octree let it leak)
// and, unlike point splats, a surface seen at a grazing angle does not hide itself. Per frame the
// mesh is rasterised into a triangle-id buffer (src/video/visibility_raster.hpp); each vertex is
// tested against the front triangle at its pixel along its own ray, and where that does not decide
// (silhouettes, sub-pixel triangles) an Embree ray from the camera to the vertex does. The mesh is
// first subdivided until no edge is longer than the texel size, so that vertex colours carry the
// image's detail.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/io/texture_io.hpp"  // TexturedMesh and its writers
#include "sonar3d/video/texture.hpp"

namespace sonar3d {

struct MeshTextureConfig {
  double texel_m = 0.01;      // subdivide until every edge is at most this long (0: no subdivision)
  double max_range_m = 30.0;  // vertices farther from a camera take no colour from it
  // Subdivision refused beyond this many vertices: ~150 bytes each at the last level (mesh,
  // midpoint table, colour sums), so the default bounds it near 600 MB.
  std::size_t max_vertices = 4'000'000;
  // false: one Embree ray per vertex and frame, exact below the pixel but ~5× slower; true: the
  // visibility raster first, rays only where it does not decide (an occluder smaller than a pixel
  // that covers the vertex but no pixel centre is missed).
  bool raster_visibility = true;
  // true: each frame's colour weighted by |cos θ| / range² (θ between the view ray and the vertex
  // normal; the inverse of the surface area one pixel covers there, |cos θ| at least 0.01), so
  // near, head-on views count most; false: a plain mean over the frames.
  bool weight_by_view = true;
  // A frame in which a vertex lies within a pixel of the model's silhouette — one of the four
  // pixels its colour is read from shows no part of the model (open water, or an occluder such as
  // the seabed) — counts this many times less, as those pixels mix the model with what lies
  // behind it: where other frames see the vertex clear of its outline, their colour wins; where
  // none do, it still takes one. 1: as any other frame. With raster_visibility only (frames that
  // go to rays alone do not know the silhouette).
  double silhouette_weight = 1e-3;
  void validate() const;  // throws Error naming the field
};

// Splits every triangle into four (edge midpoints shared) until no edge exceeds `max_edge_m`.
// Throws Error when that would exceed `max_vertices`.
TriangleMesh subdivide_to_edge(const TriangleMesh& mesh, double max_edge_m,
                               std::size_t max_vertices);

// One frame at a time (memory: the mesh plus one image).
class MeshTexturer {
 public:
  // Subdivides `mesh` and builds its ray-tracing structure. `occluders`, in the same frame, hide
  // the mesh where they stand between it and a camera but take no colour themselves: e.g. the
  // seabed a placed CAD model is half buried in (world's seabed_lod0.ply), so that the buried part
  // stays uncoloured instead of taking the sand above it. Throws Error on a bad mesh or config.
  MeshTexturer(const TriangleMesh& mesh, const MeshTextureConfig& config = {},
               const TriangleMesh& occluders = {});
  ~MeshTexturer();
  MeshTexturer(const MeshTexturer&) = delete;
  MeshTexturer& operator=(const MeshTexturer&) = delete;
  // Returns how many vertices this frame coloured. Throws Error naming frame `index` when its image
  // does not match its camera or its pose is not finite.
  std::size_t add(const CameraView& view, std::size_t index = 0);
  const TriangleMesh& mesh() const;
  TexturedMesh result() const;
  // Vertex tests so far decided by the raster and by Embree rays (over all frames).
  std::size_t raster_decided() const;
  std::size_t rays_cast() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

TexturedMesh texture_mesh(const TriangleMesh& mesh, const std::vector<CameraView>& views,
                          const MeshTextureConfig& config = {}, const TriangleMesh& occluders = {});
// Written by write_textured_mesh_ply / write_textured_mesh_glb (io/texture_io.hpp).

}  // namespace sonar3d
