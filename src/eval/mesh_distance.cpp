// Exact unsigned point-to-mesh distance (thesis sec. 4.5.2.1: the error of a reconstructed point
// is its distance to the CAD model). Embree finds candidate triangles with a BVH point query; the
// distance itself is computed here in double precision so it does not depend on Embree's float
// arithmetic.
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "../core/embree_device.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/eval/metrics.hpp"

namespace sonar3d {
namespace {

using Eigen::Vector3d;

Vector3d closest_point_on_segment(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 == 0.0) return a;
  return a + std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) * ab;
}

// Closest point to p on triangle abc: Ericson, Real-Time Collision Detection, sec. 5.1.5. Tests
// the Voronoi regions of the vertices, then of the edges, else projects onto the face, so every
// division is by a strictly positive squared length or area.
Vector3d closest_point_on_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b,
                                   const Vector3d& c) {
  const Vector3d ab = b - a;
  const Vector3d ac = c - a;
  // Degenerate (zero-area, e.g. repeated or collinear vertices, common in CAD exports): the
  // region tests would divide 0 by 0, and the triangle is just its three edges.
  if (ab.cross(ac).squaredNorm() <= 1e-24 * ab.squaredNorm() * ac.squaredNorm()) {
    const Vector3d candidates[3] = {closest_point_on_segment(p, a, b),
                                    closest_point_on_segment(p, b, c),
                                    closest_point_on_segment(p, c, a)};
    return *std::min_element(std::begin(candidates), std::end(candidates),
                             [&p](const Vector3d& u, const Vector3d& v) {
                               return (u - p).squaredNorm() < (v - p).squaredNorm();
                             });
  }
  const Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;  // vertex region a

  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;  // vertex region b

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + (d1 / (d1 - d3)) * ab;  // edge ab

  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;  // vertex region c

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + (d2 / (d2 - d6)) * ac;  // edge ac

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {  // edge bc
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);  // inside the face: barycentric (u, v, w)
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

struct MeshDistance::Impl {
  std::vector<Vector3d> vertices;  // double copies: the callback runs millions of times
  std::vector<Eigen::Vector3i> triangles;
  RTCScene scene = nullptr;

  // Per-query state handed to Embree as the user pointer, so concurrent queries share nothing.
  struct Query {
    const Impl* impl;
    Vector3d p;
    double best_d2;
  };

  // Called by Embree for every triangle whose BVH box meets the current query sphere. Shrinking
  // the radius to the best distance so far prunes the rest of the traversal.
  static bool closest_point_callback(RTCPointQueryFunctionArguments* args) {
    auto* q = static_cast<Query*>(args->userPtr);
    const Eigen::Vector3i& t = q->impl->triangles[args->primID];
    const auto& v = q->impl->vertices;
    const double d2 =
        (closest_point_on_triangle(q->p, v[t[0]], v[t[1]], v[t[2]]) - q->p).squaredNorm();
    if (d2 >= q->best_d2) return false;
    q->best_d2 = d2;
    // Round the float radius up so float rounding never culls a box holding an equally close
    // triangle.
    args->query->radius =
        std::nextafter(static_cast<float>(std::sqrt(d2)), std::numeric_limits<float>::infinity());
    return true;
  }

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

MeshDistance::MeshDistance(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>()) {
  require(!mesh.empty(), "cannot measure distances to an empty mesh (no triangles)");
  const std::size_t nv = mesh.vertices.size();
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const int idx = mesh.triangles[i][k];
      if (idx < 0 || static_cast<std::size_t>(idx) >= nv) {
        throw Error("mesh triangle " + std::to_string(i) + " refers to vertex " +
                    std::to_string(idx) + " but the mesh has " + std::to_string(nv) + " vertices");
      }
    }
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (!mesh.vertices[i].allFinite()) {
      throw Error("mesh vertex " + std::to_string(i) + " is not finite (NaN or infinity)");
    }
  }
  impl_->vertices.reserve(nv);
  for (const auto& v : mesh.vertices) impl_->vertices.push_back(v.cast<double>());
  impl_->triangles = mesh.triangles;

  RTCDevice device = detail::embree_device();
  impl_->scene = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                         RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                            RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                            mesh.triangles.size()));
  if (!vb || !ib) {
    rtcReleaseGeometry(geom);
    throw Error("Embree could not allocate the buffers of a " +
                std::to_string(mesh.triangles.size()) + "-triangle mesh (error " +
                std::to_string(static_cast<int>(rtcGetDeviceError(device))) + ")");
  }
  for (std::size_t i = 0; i < nv; ++i) std::memcpy(vb + 3 * i, mesh.vertices[i].data(), 12);
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = static_cast<unsigned>(mesh.triangles[i][k]);
  }
  rtcSetGeometryUserData(geom, impl_.get());
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);  // the scene holds its own reference
  rtcCommitScene(impl_->scene);
  const RTCError err = rtcGetDeviceError(device);
  if (err != RTC_ERROR_NONE) {
    throw Error("Embree failed to build the distance BVH of a " +
                std::to_string(mesh.triangles.size()) + "-triangle mesh (error " +
                std::to_string(static_cast<int>(err)) + ")");
  }
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const Eigen::Vector3f& p) const {
  if (!p.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  Impl::Query q{impl_.get(), p.cast<double>(), std::numeric_limits<double>::infinity()};
  RTCPointQuery query;
  query.x = p.x();
  query.y = p.y();
  query.z = p.z();
  query.time = 0.0f;
  query.radius = std::numeric_limits<float>::infinity();
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(impl_->scene, &query, &context, &Impl::closest_point_callback, &q);
  return std::sqrt(q.best_d2);
}

std::vector<double> MeshDistance::distances(const std::vector<Eigen::Vector3f>& points) const {
  std::vector<double> out(points.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size()),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        out[i] = distance(points[i]);
                      }
                    });
  return out;
}

}  // namespace sonar3d
