#pragma once
// An indexed triangle mesh in one frame, metres.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace sonar3d {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;  // indices into vertices, counter-clockwise = outward

  bool empty() const { return triangles.empty(); }
  // Appends `other` (its indices shifted).
  void append(const TriangleMesh& other);
  // Applies T to every vertex.
  void transform(const Eigen::Isometry3d& T);
  double surface_area() const;
  Eigen::AlignedBox3f bounding_box() const;
};

}  // namespace sonar3d
