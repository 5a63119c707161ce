// Placements JSON of `sonar3d recognize` (parse_placements, the one reader `sonar3d world` and
// `sonar3d diff` use), then the objects built from them against a one-model catalogue (unknown
// models refused) and the placements compared with themselves moved (compare_placements).
#include "fuzz_common.hpp"
#include "sonar3d/world/change.hpp"
#include "sonar3d/world/world_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sonar3d::fuzz::run([&] {
    const sonar3d::PlacementsFile p = sonar3d::parse_placements(
        std::string(reinterpret_cast<const char*>(data), size), "placements.json");
    sonar3d::fuzz::run([&] {
      sonar3d::TriangleMesh tri;
      tri.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 1}};
      tri.triangles = {{0, 1, 2}};
      sonar3d::world_objects(p, {"tank"}, {tri}, "catalogue.yaml");
    });
    sonar3d::fuzz::run([&] {
      auto moved = p.placements;
      for (auto& m : moved) m.T_world_model.translation().x() += 0.2;
      sonar3d::compare_placements(p.placements, moved, {}, sonar3d::ChangeConfig{});
    });
  });
  return 0;
}
