#include <fmt/core.h>

#include <cmath>

#include "commands.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/sim/benchmark.hpp"

namespace sonar3d::cli {

void add_bench(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "bench",
      "Measure simulation speed on the thesis' pipeline scene (sec. 2.5.2: sonar 3 m from a "
      "vertical pipe). Default: P900-130-like, 130°×20°, 0.2° bearing × 0.01° elevation rays, "
      "7 m, 2 cm bins.");
  struct Opts {
    double fov_deg = 130, aperture_deg = 20, bearing_step_deg = 0.2, elevation_step_deg = 0.01;
    double r_max = 7.0, range_res = 0.02;
    int frames = 30, threads = 0;
    double pitch_deg = 0.0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--fov-deg", o->fov_deg, "horizontal field of view, degrees")
      ->capture_default_str();
  cmd->add_option("--aperture-deg", o->aperture_deg, "vertical aperture, degrees")
      ->capture_default_str();
  cmd->add_option("--bearing-step-deg", o->bearing_step_deg, "beam spacing, degrees")
      ->capture_default_str();
  cmd->add_option("--elevation-step-deg", o->elevation_step_deg,
                  "ray spacing across the aperture, degrees")
      ->capture_default_str();
  cmd->add_option("--range-max", o->r_max, "maximum range, metres")->capture_default_str();
  cmd->add_option("--range-res", o->range_res, "range bin size, metres")->capture_default_str();
  cmd->add_option("--pitch-down-deg", o->pitch_deg,
                  "tilt toward the seabed, degrees (0: level, only the pipe returns)")
      ->capture_default_str();
  cmd->add_option("--frames", o->frames, "images to render")->capture_default_str();
  cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)")->capture_default_str();
  cmd->callback([&run, o] {
    run = [o] {
      SonarSpec spec;
      spec.name = "bench";
      spec.set_uniform_bearings(o->fov_deg * kDeg,
                                static_cast<int>(std::lround(o->fov_deg / o->bearing_step_deg)));
      spec.r_min = 0.0;
      spec.r_max = o->r_max;
      spec.range_bins = static_cast<int>(std::lround(o->r_max / o->range_res));
      spec.vertical_aperture_rad = o->aperture_deg * kDeg;
      SimulatorConfig cfg;
      cfg.elevation_step_rad = o->elevation_step_deg * kDeg;
      cfg.num_threads = o->threads;
      const SimBenchResult r = benchmark_simulator(spec, cfg, o->frames, o->pitch_deg * kDeg);
      fmt::print(
          "simulate: {} beams × {} bins, {} rays/image, {} frames in {:.2f} s: {:.1f} Hz, "
          "{:.1f} Mrays/s\n",
          spec.beams(), spec.range_bins, r.rays_per_image, r.frames, r.seconds, r.hz,
          r.mrays_per_s);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
