// Simulate a sonar pass over a sphere, space-carve the images (thesis ch. 4) and score the cloud
// against the sphere: the library's pipeline in one file, built against an installed sonar3d.
#include <cmath>
#include <cstdio>
#include <exception>

#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/version.hpp"

int main() {
  using namespace sonar3d;
  try {
    // A 0.5 m sphere at the origin, seen by a 30° x 10° sonar looking along +x.
    Scene scene;
    scene.objects.push_back({"ball", make_sphere(0.5), 0.8});
    SonarSpec spec = sonar_preset("sim-10deg");
    spec.set_uniform_bearings(30.0 * M_PI / 180.0, 75);
    spec.r_min = 1.0;
    spec.r_max = 3.0;
    spec.range_bins = 100;
    SimulatorConfig sim_config;
    sim_config.elevation_step_rad = 0.02 * M_PI / 180.0;
    const Simulator simulator(scene, spec, sim_config);

    // A vertical pass 2 m in front of it: z from -0.7 m to 0.7 m in 2 cm steps, carved online.
    CarveConfig carve_config;
    carve_config.voxel_size = 0.02;
    carve_config.region =
        Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
    Carver carver(spec, carve_config);
    for (int k = 0; k <= 70; ++k) {
      Eigen::Isometry3d T_world_sonar = Eigen::Isometry3d::Identity();
      T_world_sonar.translation() = Eigen::Vector3d(-2.0, 0.0, -0.7 + 0.02 * k);
      carver.integrate(simulator.render(T_world_sonar, /*seed=*/k + 1), T_world_sonar);
    }
    const PointCloud cloud = carver.finalize();
    const EvalResult score = evaluate(cloud, scene.objects[0].mesh_world, EvalConfig{});
    std::printf(
        "sonar3d %s: carved %zu points from %zu frames; median distance to the sphere %.4f m\n",
        SONAR3D_VERSION, cloud.size(), carver.frames(), score.median_error);
    return cloud.size() > 100 && score.median_error < 0.03 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "carve_sphere: %s\n", e.what());
    return 1;
  }
}
