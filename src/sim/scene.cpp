#include "sonar3d/sim/scene.hpp"

namespace sonar3d {

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
