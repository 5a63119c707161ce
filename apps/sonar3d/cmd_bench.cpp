#include <fmt/core.h>

#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/sim/benchmark.hpp"

namespace sonar3d::cli {

void add_bench(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "bench",
      "Measure simulation speed on the thesis' pipeline scene (sec. 2.5.2: sonar 3 m from a "
      "vertical pipe). Default: P900-130-like, 130°×20°, 0.2° bearing × 0.01° elevation rays, "
      "7 m, 2 cm bins.");
  // Every setting (declared once, sim/benchmark.hpp): its flag, --print-config, --config FILE.
  auto config = std::make_shared<ConfigOptions<SimBenchConfig>>(cmd);
  cmd->callback([&run, config] {
    run = [config] {
      const ConfigOptions<SimBenchConfig>& o = *config;
      const SimBenchConfig cfg = with_flag_names(o.flag_names(), [&] {
        const SimBenchConfig c = o.resolve("bench");
        c.validate();
        return c;
      });
      if (o.print_if_requested(cfg, "bench", "bench")) return 0;
      const SonarSpec spec = bench_sonar_spec(cfg);
      const SimBenchResult r = benchmark_simulator(cfg);
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
