#include "sonar3d/sim/benchmark.hpp"

#include <chrono>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/reference_objects.hpp"

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

}  // namespace sonar3d
