// The JSON readers of `sonar3d report`'s scene pages: the first byte picks graph.json of a world
// model (parse_world_graph), changes.json of a change directory (parse_changes_json) or
// placements.json of `sonar3d recognize` (parse_placements_json); the rest is the file.
#include "fuzz_common.hpp"
#include "sonar3d/report/scene_files.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  sonar3d::fuzz::run([&] {
    switch (data[0] % 3) {
      case 0:
        sonar3d::parse_world_graph(text, "graph.json");
        break;
      case 1:
        sonar3d::parse_changes_json(text, "changes.json");
        break;
      default: {
        std::string catalogue;
        sonar3d::parse_placements_json(text, "placements.json", &catalogue);
      }
    }
  });
  return 0;
}
