// Planner sweep YAML (load_sweep): axes, fixed values, constraints, and every point's parameters.
#include "fuzz_common.hpp"
#include "sonar3d/plan/sweep.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto p = sonar3d::fuzz::scratch() / "sweep.yaml";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data), size});
  sonar3d::fuzz::run([&] {
    const sonar3d::Sweep s = sonar3d::load_sweep(p.string());
    const std::size_t n = std::min<std::size_t>(s.size(), 64);
    for (std::size_t i = 0; i < n; ++i) s.point(i);
  });
  return 0;
}
