// Placements JSON of `sonar3d recognize` as `sonar3d diff` reads them (parse_placements), then
// the placements compared with themselves moved (compare_placements).
#include "fuzz_common.hpp"
#include "sonar3d/world/change.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sonar3d::fuzz::run([&] {
    const auto p = sonar3d::parse_placements(std::string(reinterpret_cast<const char*>(data), size),
                                             "placements.json");
    auto moved = p;
    for (auto& m : moved) m.T_world_model.translation().x() += 0.2;
    sonar3d::compare_placements(p, moved, {}, sonar3d::ChangeConfig{});
  });
  return 0;
}
