// Connections YAML of `sonar3d world --connections` (read_given_connections), then
// add_given_connections against a world of two placed objects (ids box_0 and box_1).
#include <memory>

#include "fuzz_common.hpp"
#include "sonar3d/world/world_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = sonar3d::fuzz::scratch() / "connections";
  sonar3d::fuzz::write_file(dir / "c.yaml",
                            std::string_view(reinterpret_cast<const char*>(data), size));
  sonar3d::fuzz::run([&] {
    auto mesh = std::make_shared<sonar3d::TriangleMesh>();
    mesh->vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh->triangles = {{0, 1, 2}};
    sonar3d::WorldModel w;
    for (int i = 0; i < 2; ++i) {
      sonar3d::WorldObject o;
      o.id = "box_" + std::to_string(i);
      o.model = "box";
      o.T_world_model.translation() = Eigen::Vector3d(3.0 * i, 0, 0);
      o.mesh_model = mesh;
      w.objects.push_back(o);
    }
    const std::string path = (dir / "c.yaml").string();
    sonar3d::add_given_connections(w, sonar3d::read_given_connections(path), path, 0.1);
  });
  return 0;
}
