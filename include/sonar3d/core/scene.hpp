#pragma once
// A simulation scene: objects (meshes from files or procedural), each with a pose and a
// reflectivity μ (eq. 2.6), placed in the world frame (z up).
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

// What an object is on a site; evaluation scores structures and pipelines against their CAD and
// treats terrain as the background they stand on.
enum class ObjectKind { Structure, Pipeline, Terrain };
const char* to_string(ObjectKind kind);
// "structure", "pipeline" or "terrain"; throws Error otherwise.
ObjectKind object_kind_from_string(const std::string& s);

struct SceneObject {
  std::string name;
  TriangleMesh mesh_world;    // already transformed into the world frame
  double reflectivity = 0.5;  // μ in [0, 1]
  ObjectKind kind = ObjectKind::Structure;
  // What a camera sees (video mapping): linear RGB albedo, each in [0, 1].
  Eigen::Vector3f color = Eigen::Vector3f::Constant(0.6f);
};

struct Scene {
  std::vector<SceneObject> objects;
  bool empty() const;
  TriangleMesh merged_world() const;  // all objects in one mesh
};

}  // namespace sonar3d
