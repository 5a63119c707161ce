#include "sonar3d/sim/benchmark.hpp"

#include <chrono>
#include <cmath>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/units.hpp"

namespace sonar3d {

Scene make_pipeline_scene() {
  Scene scene;
  SceneObject pipe;
  pipe.name = "pipeline";
  pipe.mesh_world = make_cylinder(0.25, 6.0);
  pipe.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(3.0, 0.0, -1.5)));
  pipe.reflectivity = 0.8;
  SceneObject seabed;
  seabed.name = "seabed";
  seabed.mesh_world = make_plane(20.0, 20.0);
  seabed.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, -1.5)));
  seabed.reflectivity = 0.3;
  scene.objects = {pipe, seabed};
  return scene;
}

SimBenchResult benchmark_simulator(const SonarSpec& spec, const SimulatorConfig& config, int frames,
                                   double pitch_down_rad) {
  require(frames > 0, "benchmark: frames must be > 0");
  const Simulator sim(make_pipeline_scene(), spec, config);
  sim.render(Eigen::Isometry3d(Eigen::AngleAxisd(pitch_down_rad, Eigen::Vector3d::UnitY())),
             0);  // warm-up: first-touch allocations
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < frames; ++k) {
    // Move 1 cm up per frame, as in a vertical inspection.
    // Positive pitch about +y turns +x (boresight) down toward -z.
    Eigen::Isometry3d T(Eigen::AngleAxisd(pitch_down_rad, Eigen::Vector3d::UnitY()));
    T.translation().z() = 0.01 * k;
    sim.render(T, static_cast<unsigned long long>(k) + 1);
  }
  SimBenchResult r;
  r.frames = frames;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.hz = frames / r.seconds;
  r.rays_per_image = sim.rays_per_image();
  r.mrays_per_s = r.rays_per_image * r.hz * 1e-6;
  return r;
}

void SimBenchConfig::validate() const {
  params::check(*this, "bench");
  require(std::lround(fov_deg / bearing_step_deg) >= 1,
          "bench: bearing_step_deg is wider than fov_deg: no beam");
  require(std::lround(range_max_m / range_res_m) >= 1,
          "bench: range_res_m is longer than range_max_m: no range bin");
}

SonarSpec bench_sonar_spec(const SimBenchConfig& c) {
  c.validate();
  SonarSpec spec;
  spec.name = "bench";
  spec.set_uniform_bearings(c.fov_deg * kDeg,
                            static_cast<int>(std::lround(c.fov_deg / c.bearing_step_deg)));
  spec.r_min = 0.0;
  spec.r_max = c.range_max_m;
  spec.range_bins = static_cast<int>(std::lround(c.range_max_m / c.range_res_m));
  spec.vertical_aperture_rad = c.aperture_deg * kDeg;
  return spec;
}

SimBenchResult benchmark_simulator(const SimBenchConfig& c) {
  const SonarSpec spec = bench_sonar_spec(c);
  SimulatorConfig sim;
  sim.elevation_step_rad = c.elevation_step_deg * kDeg;
  sim.num_threads = c.num_threads;
  return benchmark_simulator(spec, sim, c.frames, c.pitch_down_deg * kDeg);
}

}  // namespace sonar3d
