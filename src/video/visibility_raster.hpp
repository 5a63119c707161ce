#pragma once
// A visibility buffer for mesh texturing (internal to src/video): the occluding mesh rasterised,
// per camera frame, into a depth and triangle-id image in the camera's *undistorted* normalised
// image plane, where the projections of straight edges stay straight (so the lens distortion
// does not bend triangles). A vertex is then tested against the triangle nearest the camera at its
// four surrounding pixel centres by intersecting the vertex's own ray with those triangles' planes:
//   - a triangle the ray crosses, inside its edges, short of the vertex: Hidden (exact);
//   - four centres showing surfaces whose planes cross the ray more than 1 % of the range short of
//     the vertex (outside their triangles), none through it: Hidden (the far side of an object);
//   - a triangle whose plane, but not the triangle, crosses the ray short of the vertex (unless it
//     shares a corner with the vertex's own triangles: the next facet of a curved surface, passed
//     by), or no triangle at any of the four (outside the raster, open water): Unknown, and the
//     caller casts the exact Embree ray;
//   - otherwise, when at least one of the four planes crosses the ray at the vertex (within 1e-4 m
//     or 1e-5 of the range, the Embree ray's allowance): the vertex lies on the front surface:
//     Visible.
// So Unknown falls back to the exact test, and Visible and Hidden hold at the raster's
// resolution: an occluder that covers the vertex but none of the four pixel centres around it (a
// sliver or a wire thinner than a pixel), or a gap as thin through surfaces far in front, is
// missed. Written by hand because rasterising triangle
// ids on the CPU is ~200 lines and the alternatives in Debian (Mesa's OSMesa/llvmpipe) need a GL
// context and a driver at run time.
//
// Speed (the ≥ 100 frames/s target of issue 13): the occluder is kept in spatial (Morton) order,
// vertices and triangles, so that neighbouring pixels read neighbouring triangles, and its
// triangles are grouped in blocks of 64 with a world bounding box each: per frame the blocks (not
// the triangles) are binned to bands of raster rows by projecting their boxes, and the bands are
// rasterised in parallel, each clearing and writing its own rows, small enough to stay in the
// cache. While a band is drawn each pixel holds the nearest surface's 1/z (in the thread's own
// buffer, dropped afterwards) and its triangle (in the raster, 4 bytes a pixel, read by test());
// the depth test (ties to the larger triangle id, so the result does not depend on the order of
// the triangles) runs without branches over each row's span of the triangle, in aligned groups
// of four pixels (rows padded to a multiple of four). A textured vertex whose own
// triangles are the front surface at its four pixel centres is settled by comparing ids alone
// (owned()).
#include <tbb/enumerable_thread_specific.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/video/camera.hpp"

namespace sonar3d::detail {

// The points' indices along a Morton curve (points near in space become near in the order).
std::vector<int> morton_order(const std::vector<Eigen::Vector3f>& points);
// Renumbers the vertices along a Morton curve (vertices near in the mesh become near in memory).
void sort_vertices_spatially(TriangleMesh& mesh);

// The bounding boxes of blocks of `block_size` consecutive points (in a spatial order, e.g.
// morton_order()), so that a camera frame skips the blocks it cannot see (blocks_in_view()).
std::vector<Eigen::AlignedBox3f> block_boxes(const std::vector<Eigen::Vector3f>& points,
                                             std::size_t block_size);
// Into `out`, the blocks (block_boxes()) that may hold a point within `max_range_m` of the camera
// at T_camera_world and in its image: not wholly farther, not wholly behind it, and (when wholly
// in front) not wholly beside the image — x/z, y/z over a box in front of the camera lie within
// those of its corners (normalised_image_bounds()).
void blocks_in_view(const std::vector<Eigen::AlignedBox3f>& boxes, const CameraIntrinsics& camera,
                    const Eigen::Isometry3d& T_camera_world, double max_range_m,
                    std::vector<int>& out);

class VisibilityRaster {
 public:
  enum class Verdict : std::uint8_t { Visible, Hidden, Unknown };
  static constexpr std::uint32_t kNone = 0xffffffffu;  // no triangle

  // Keeps a copy of the occluder (renumbered spatially; triangle ids are internal). Its triangles
  // from `first_foreign` on (given numbering) belong to other surfaces than the textured one
  // (occluders that take no colour; see test()'s `shows`).
  explicit VisibilityRaster(const TriangleMesh& occluder,
                            std::size_t first_foreign = static_cast<std::size_t>(-1));

  // Rasterises the occluder seen by `camera` at `T_camera_world` (OpenCV camera frame). Geometry
  // nearer than `near_m` to the camera plane is clipped away.
  void render(const CameraIntrinsics& camera, const Eigen::Isometry3d& T_camera_world,
              double near_m = 1e-3);

  // Where a point is tested, its `cell`: the index v0·stride() + u0 of the top-left of the four
  // pixel centres around its raster position (u, v) = (sx·x/z + ox, sy·y/z + oy), from its
  // normalised image coordinates (x/z, y/z) in the camera frame of the last render(); −1 (no
  // verdict) when (u, v) does not lie within the raster's outer pixel centres or z is not beyond
  // near_plane().
  double sx() const { return sx_; }
  double sy() const { return sy_; }
  double ox() const { return ox_; }
  double oy() const { return oy_; }
  double near_plane() const { return near_; }
  // Asks the processor to fetch those four pixels (the raster is too large for the caches and is
  // read in an order its prefetcher does not guess).
  void prefetch(std::ptrdiff_t cell) const {
    if (cell < 0) return;
    __builtin_prefetch(id_.data() + cell);
    __builtin_prefetch(id_.data() + cell + stride_);
  }
  // The verdict for a point on the textured mesh at `cell` (its cell), given in the world frame;
  // `range_m` is its distance from the camera centre. With Visible, bit k of `shows` (k = 0 … 3:
  // pixel centres (u0, v0), (u0 + 1, v0), (u0, v0 + 1), (u0 + 1, v0 + 1) of the cell) tells
  // whether that centre shows the textured surface (not nothing, not a foreign triangle): a
  // point whose four do not all (within a pixel of its silhouette) has the image's pixels around
  // it mixing it with what lies behind. `own_a`, `own_b`: occluder triangles the point lies on
  // (internal_triangle()), when known (else anything ≥ the triangle count): a triangle sharing a
  // vertex with one of them, whose plane but not itself crosses the ray short of the point — a
  // neighbouring facet of a curved surface — does not leave the test undecided.
  Verdict test(const Eigen::Vector3d& p_world, std::ptrdiff_t cell, double range_m, unsigned& shows,
               std::uint32_t own_a = kNone, std::uint32_t own_b = kNone) const;
  // The occluder's triangle `given` (its index in the mesh the constructor was given) in the
  // raster's own numbering, which owned() takes.
  std::uint32_t internal_triangle(std::size_t given) const { return internal_of_given_[given]; }
  // True when the front surface at each of the four pixel centres around `cell` that shows the
  // occluder at all is `a` or `b` (which may repeat `a`), the occluder triangles
  // (internal_triangle()) the point lies on: then it lies on the front surface, the Visible of
  // test() without its plane arithmetic (the planes of its own triangles pass through it). Most
  // vertices of a subdivided model lie inside one triangle or on an edge between two. False: ask
  // test(). `shows`: as test()'s (here, the centres that show anything).
  bool owned(std::ptrdiff_t cell, std::uint32_t a, std::uint32_t b, unsigned& shows) const;

  int width() const { return width_; }
  int height() const { return height_; }
  // Pixels from one row to the next: the width rounded up to a multiple of 4 (fill() writes
  // aligned groups of four; the padding columns are never read).
  int stride() const { return stride_; }

 private:
  struct Plane {  // unit normal (zero for a degenerate triangle) and n · a, one cache line half
    Eigen::Vector3d n;
    double offset;
  };
  struct Projected {  // an occluder vertex on the raster: (u, v) and 1/z (0: before the near plane)
    float u, v, w;
  };
  struct Box {  // pixel centres xa … xb, ya … yb (empty when xa > xb or ya > yb)
    int xa, xb, ya, yb;
  };
  void setup_raster(const CameraIntrinsics& camera);
  Box box(const float* u, const float* v, int y0, int y1) const;
  // Rasterises triangle `tri` within rows y0 … y1 − 1 (clipped at the near plane), which no other
  // thread writes meanwhile.
  struct Band {    // rows y0 … of a band: 1/z of the nearest surface (0: none) and its triangle
    float* inv_z;  // the thread's own cells
    std::uint32_t* id;  // the raster's rows (kNone until a triangle covers the pixel)
  };
  void raster_triangle(int tri, int y0, int y1, const Band& band);
  void prefetch_block(int block) const;
  // Into `band`, the cells of rows y0 … .
  void fill(const float* u, const float* v, const float* w, int tri, const Box& box,
            const Band& band, int y0);

  TriangleMesh mesh_;
  std::vector<std::uint32_t> internal_of_given_;  // per given triangle: its index in mesh_
  std::vector<std::uint8_t> foreign_;             // per triangle (internal): not the textured one
  std::vector<Plane> plane_;
  // Raster: pixel (i, j) centre at undistorted normalised coordinates
  // ((i − ox)/sx, (j − oy)/sy).
  CameraIntrinsics raster_for_{};
  bool have_raster_ = false;
  int width_ = 0, height_ = 0, stride_ = 0;
  double sx_ = 1, sy_ = 1, ox_ = 0, oy_ = 0;
  // Whether triangles t and u (internal ids; u may be out of range: false) share a vertex.
  bool share_vertex(std::uint32_t t, std::uint32_t u) const {
    if (u >= mesh_.triangles.size()) return false;
    const Eigen::Vector3i &a = mesh_.triangles[t], &b = mesh_.triangles[u];
    return (a.array() == b[0]).any() || (a.array() == b[1]).any() || (a.array() == b[2]).any();
  }
  std::vector<std::uint32_t> id_;  // per pixel centre: the nearest triangle, kNone: none
  // Per thread: a band's depths while it is rasterised.
  tbb::enumerable_thread_specific<std::vector<float>> band_inv_z_;
  std::vector<Projected> projected_;            // per frame, per occluder vertex
  std::vector<Eigen::AlignedBox3f> block_box_;  // world bounding box of each block of triangles
  std::vector<std::pair<int, int>> block_vertices_;  // the vertices each block uses lie in [a, b)
  std::vector<std::vector<std::int32_t>> band_blocks_;  // per frame: the blocks each band draws
  Eigen::Matrix3f R_ = Eigen::Matrix3f::Identity();     // per frame: world to camera
  Eigen::Vector3f t_ = Eigen::Vector3f::Zero();
  Eigen::Vector3d origin_world_ = Eigen::Vector3d::Zero();
  double near_ = 1e-3;
};

// Inline: called for every vertex of every frame.
inline bool VisibilityRaster::owned(std::ptrdiff_t cell, std::uint32_t a, std::uint32_t b,
                                    unsigned& shows) const {
  if (cell < 0) return false;
  // The four ids compared at once (GCC/Clang vector extensions).
  using U4 = std::uint32_t __attribute__((vector_size(16)));
  using I4 = std::int32_t __attribute__((vector_size(16)));
  const std::uint32_t* row = id_.data() + cell;
  const U4 ids = {row[0], row[1], row[stride_], row[stride_ + 1]};
  const I4 none = ids == kNone;
  const I4 own = (ids == a) | (ids == b) | none;
  // The lanes' signs as four bits (one instruction on x86: movmskps).
  unsigned own_bits, none_bits;
#if defined(__SSE2__)
  using F4 = float __attribute__((vector_size(16)));
  own_bits = static_cast<unsigned>(__builtin_ia32_movmskps((F4)own));
  none_bits = static_cast<unsigned>(__builtin_ia32_movmskps((F4)none));
#else
  std::int32_t o[4], n[4];
  std::memcpy(o, &own, sizeof o);
  std::memcpy(n, &none, sizeof n);
  own_bits = none_bits = 0;
  for (int k = 0; k < 4; ++k) {
    own_bits |= static_cast<unsigned>(o[k] != 0) << k;
    none_bits |= static_cast<unsigned>(n[k] != 0) << k;
  }
#endif
  shows = ~none_bits & 0xfu;
  return own_bits == 0xfu && none_bits != 0xfu;
}

inline VisibilityRaster::Verdict VisibilityRaster::test(const Eigen::Vector3d& p_world,
                                                        std::ptrdiff_t cell, double range_m,
                                                        unsigned& shows, std::uint32_t own_a,
                                                        std::uint32_t own_b) const {
  if (cell < 0) return Verdict::Unknown;
  // The vertex's ray: origin + s·d, the vertex at s = 1. The Embree test's allowance: a surface
  // within max(1e-4 m, 1e-5·range) of the vertex is its own.
  const Eigen::Vector3d d = p_world - origin_world_;
  const double eps = std::max(1e-4 / range_m, 1e-5);
  bool on_front_surface = false, undecided = false;
  // Whether every centre shows a surface whose plane crosses the ray more than kFar·range short
  // of the vertex (where the crossing is not on the triangle itself: the front surface there
  // continues beyond the triangle, far in front of the vertex).
  constexpr double kFar = 0.01;
  bool all_far = true;
  shows = 0;
  const std::uint32_t* row = id_.data() + cell;
  const std::uint32_t ids[4] = {row[0], row[1], row[stride_], row[stride_ + 1]};
  for (int k = 0; k < 4; ++k) {
    const std::uint32_t t = ids[k];
    if (t == kNone) {  // open water there: no occluder
      all_far = false;
      continue;
    }
    shows |= static_cast<unsigned>(foreign_[t] == 0) << k;
    if ((k > 0 && t == ids[k - 1]) || (k == 3 && t == ids[1]) || (k >= 2 && t == ids[0])) {
      continue;  // the same triangle as another of the four: the same verdict
    }
    const Plane& pl = plane_[t];
    const double denom = pl.n.dot(d);
    if (!(std::abs(denom) > 1e-12 * range_m)) {  // seen edge-on
      undecided = true;
      all_far = false;
      continue;
    }
    // The ray meets the plane at s = num / denom; compared without dividing (|denom| > 0).
    const double num = pl.offset - pl.n.dot(origin_world_);
    const double an = denom > 0 ? num : -num, ad = std::abs(denom);
    if (std::abs(an - ad) <= eps * ad) {
      on_front_surface = true;  // the front surface at this centre passes through the vertex
      continue;
    }
    if (!(an < (1.0 - eps) * ad) || !(an > 0)) {  // the front surface there lies behind it
      all_far = false;
      continue;
    }
    const double s = num / denom;
    // A front surface whose plane crosses the ray short of the vertex: hidden when the ray
    // crosses the triangle itself (exact), undecided when only its plane.
    const auto& tri = mesh_.triangles[t];
    const Eigen::Vector3d h = origin_world_ + s * d;
    const Eigen::Vector3d a = mesh_.vertices[tri[0]].cast<double>(),
                          b = mesh_.vertices[tri[1]].cast<double>(),
                          c = mesh_.vertices[tri[2]].cast<double>();
    if (pl.n.dot((b - a).cross(h - a)) >= 0 && pl.n.dot((c - b).cross(h - b)) >= 0 &&
        pl.n.dot((a - c).cross(h - c)) >= 0) {
      return Verdict::Hidden;
    }
    // A facet next to the point's own (a curved surface: its plane passes in front of the point,
    // beside the facet): the ray passes it by.
    if (share_vertex(t, own_a) || share_vertex(t, own_b)) {
      all_far = false;
      continue;
    }
    undecided = true;  // another of the four may still prove it hidden
    all_far &= an < (1.0 - kFar) * ad;
  }
  // All four centres show surfaces far in front, none of them the vertex's own: hidden, at the
  // raster's resolution (a gap narrower than a pixel between them would let it through).
  if (all_far && !on_front_surface) return Verdict::Hidden;
  return on_front_surface && !undecided ? Verdict::Visible : Verdict::Unknown;
}

}  // namespace sonar3d::detail
