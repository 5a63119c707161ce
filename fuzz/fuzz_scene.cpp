// Scene YAML (load_simulation_setup): sensor block, objects (primitives, reference objects),
// trajectories (straight, orbit, lawnmower, segments), noise; the Simulator check at the end
// builds the Embree scene. A second part (after a "--8<--" line) is written as traj.tum beside
// the scene for `type: tum` segments.
#include "fuzz_common.hpp"
#include "sonar3d/sim/simulation.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = sonar3d::fuzz::split(data, size, 2);
  const auto dir = sonar3d::fuzz::scratch() / "scene";
  sonar3d::fuzz::write_file(dir / "scene.yaml", parts[0]);
  sonar3d::fuzz::write_file(dir / "traj.tum", parts[1]);
  sonar3d::fuzz::run([&] { sonar3d::load_simulation_setup((dir / "scene.yaml").string()); });
  return 0;
}
