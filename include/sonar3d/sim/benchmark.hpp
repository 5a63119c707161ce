#pragma once
// The simulation benchmark of sec. 2.5.2 (Fig. 2.18): a forward-looking sonar 3 m from a vertical
// pipeline over a seabed, images rendered back to back.
#include "sonar3d/core/scene.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/sim/simulator.hpp"

namespace sonar3d {

// A 0.5 m diameter, 6 m tall vertical pipe standing on a 20 × 20 m seabed, centred 3 m in front of
// a sonar at the origin looking along +x, 1.5 m above the seabed.
Scene make_pipeline_scene();

struct SimBenchResult {
  int frames = 0;
  double seconds = 0;
  double hz = 0;  // images per second
  double mrays_per_s = 0;
  std::size_t rays_per_image = 0;
};

// `pitch_down_rad` tilts the sonar toward the seabed: 0 is the thesis' level geometry (only the
// pipe returns); 10–15° fills the lower half of the aperture with seabed returns (a harder case).
SimBenchResult benchmark_simulator(const SonarSpec& spec, const SimulatorConfig& config, int frames,
                                   double pitch_down_rad = 0.0);

}  // namespace sonar3d
