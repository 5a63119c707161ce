#pragma once
// The simulation benchmark of sec. 2.5.2 (Fig. 2.18): a forward-looking sonar 3 m from a vertical
// pipeline over a seabed, images rendered back to back.
#include "sonar3d/core/params.hpp"
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

// `sonar3d bench`: the sonar and the run, by default the thesis' P900-130-like sensor (130° x
// 20°, 0.2° bearing x 0.01° elevation rays, 7 m, 2 cm bins).
struct SimBenchConfig {
  double fov_deg = 130, aperture_deg = 20, bearing_step_deg = 0.2, elevation_step_deg = 0.01;
  double range_max_m = 7.0, range_res_m = 0.02;
  double pitch_down_deg = 0.0;
  int frames = 30;
  int num_threads = 0;    // 0 = all cores
  void validate() const;  // throws Error naming the field
};
template <class V>
void describe(SimBenchConfig& c, V& v) {
  using params::param;
  v.field(
      c.fov_deg,
      param("fov_deg", "deg", "horizontal field of view").range_open_low(0, 360).flag("--fov-deg"));
  v.field(c.aperture_deg, param("aperture_deg", "deg", "vertical aperture")
                              .range_open_low(0, 180)
                              .flag("--aperture-deg"));
  v.field(c.bearing_step_deg,
          param("bearing_step_deg", "deg", "beam spacing").positive().flag("--bearing-step-deg"));
  v.field(c.elevation_step_deg,
          param("elevation_step_deg", "deg", "ray spacing across the aperture")
              .positive()
              .equation("eq. 2.13")
              .flag("--elevation-step-deg"));
  v.field(c.range_max_m, param("range_max_m", "m", "maximum range").positive().flag("--range-max"));
  v.field(c.range_res_m,
          param("range_res_m", "m", "range bin size").positive().flag("--range-res"));
  v.field(c.pitch_down_deg,
          param("pitch_down_deg", "deg", "tilt toward the seabed (0: level, only the pipe returns)")
              .range(-90, 90)
              .flag("--pitch-down-deg"));
  v.field(c.frames, param("frames", "", "images to render").at_least(1).flag("--frames"));
  v.field(
      c.num_threads,
      param("num_threads", "", "worker threads (0 = all cores)").non_negative().flag("--threads"));
}
// The sonar of `config` (uniform bearings, range from 0).
SonarSpec bench_sonar_spec(const SimBenchConfig& config);
// The benchmark as `sonar3d bench` runs it.
SimBenchResult benchmark_simulator(const SimBenchConfig& config);

}  // namespace sonar3d
