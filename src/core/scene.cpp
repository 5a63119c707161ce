#include "sonar3d/core/scene.hpp"

#include "sonar3d/core/error.hpp"

namespace sonar3d {

const char* to_string(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::Pipeline:
      return "pipeline";
    case ObjectKind::Terrain:
      return "terrain";
    case ObjectKind::Structure:
      break;
  }
  return "structure";
}

ObjectKind object_kind_from_string(const std::string& s) {
  if (s == "structure") return ObjectKind::Structure;
  if (s == "pipeline") return ObjectKind::Pipeline;
  if (s == "terrain") return ObjectKind::Terrain;
  throw Error("unknown object kind '" + s + "' (structure, pipeline, terrain)");
}

bool Scene::empty() const {
  for (const auto& o : objects) {
    if (!o.mesh_world.empty()) return false;
  }
  return true;
}

TriangleMesh Scene::merged_world() const {
  TriangleMesh m;
  for (const auto& o : objects) m.append(o.mesh_world);
  return m;
}

}  // namespace sonar3d
