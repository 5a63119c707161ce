// Placements JSON of `sonar3d recognize` as `sonar3d world` reads it (read_placements), then the
// objects built from them against a one-model catalogue (unknown models refused).
#include "fuzz_common.hpp"
#include "sonar3d/world/world_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = sonar3d::fuzz::scratch() / "placements";
  sonar3d::fuzz::write_file(dir / "placements.json",
                            std::string_view(reinterpret_cast<const char*>(data), size));
  sonar3d::fuzz::run([&] {
    const sonar3d::PlacementsFile p = sonar3d::read_placements((dir / "placements.json").string());
    sonar3d::TriangleMesh tri;
    tri.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 1}};
    tri.triangles = {{0, 1, 2}};
    sonar3d::world_objects(p, {"tank"}, {tri}, "catalogue.yaml");
  });
  return 0;
}
