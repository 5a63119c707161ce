#include "sonar3d/core/scene.hpp"

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {
constexpr const char* kObjectKindNames[] = {"structure", "pipeline", "terrain"};  // by ObjectKind
}  // namespace

const char* to_string(ObjectKind kind) { return enum_name(kObjectKindNames, kind); }

ObjectKind object_kind_from_string(const std::string& s) {
  return parse_enum<ObjectKind>(kObjectKindNames, s, "object kind");
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
