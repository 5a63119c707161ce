// The JSON readers of `sonar3d report`'s scene pages: the first byte picks graph.json of a world
// model (parse_world_graph) or changes.json of a change directory (parse_changes_json); the rest
// is the file. (placements.json has one reader for world, diff and report: fuzz_placements.)
#include "fuzz_common.hpp"
#include "sonar3d/report/scene_files.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  sonar3d::fuzz::run([&] {
    if (data[0] % 2 == 0) {
      sonar3d::parse_world_graph(text, "graph.json");
    } else {
      sonar3d::parse_changes_json(text, "changes.json");
    }
  });
  return 0;
}
