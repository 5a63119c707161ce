#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

void TriangleMesh::append(const TriangleMesh& other) {
  const int offset = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  triangles.reserve(triangles.size() + other.triangles.size());
  for (const auto& t : other.triangles) triangles.push_back(t + Eigen::Vector3i::Constant(offset));
}

void TriangleMesh::transform(const Eigen::Isometry3d& T) {
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (auto& v : vertices) v = Tf * v;
}

double TriangleMesh::surface_area() const {
  double area = 0.0;
  for (const auto& t : triangles) {
    const Eigen::Vector3d a = vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = vertices[t[2]].cast<double>();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area;
}

Eigen::AlignedBox3f TriangleMesh::bounding_box() const {
  Eigen::AlignedBox3f box;
  for (const auto& v : vertices) box.extend(v);
  return box;
}

}  // namespace sonar3d
