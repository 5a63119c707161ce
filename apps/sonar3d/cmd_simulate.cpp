#include <fmt/core.h>

#include "commands.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d::cli {

void add_simulate(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "simulate",
      "Render a simulated sonar dataset from a scene file (objects, sensor, trajectory, noise; "
      "see docs/formats.md). Writes DATASET atomically, with truth/ for evaluation.");
  auto scene = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto seed = std::make_shared<long long>(-1);
  cmd->add_option("scene", *scene, "scene YAML file")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", *out, "dataset directory to write (replaced if it exists)")
      ->required();
  cmd->add_option("--seed", *seed, "random seed for jitter and noise (default: the scene's seed)");
  cmd->callback([&g, &run, scene, out, seed] {
    run = [&g, scene, out, seed] {
      SimulationSetup setup = load_simulation_setup(*scene);
      if (*seed >= 0) setup.seed = static_cast<unsigned long long>(*seed);
      const SimulationStats st = simulate_dataset(setup, *out, !g.quiet);
      fmt::print("wrote {} frames to {} ({:.1f} s, {:.1f} frames/s, {:.1f} Mrays/s)\n", st.frames,
                 *out, st.seconds, st.frames / st.seconds, st.rays / st.seconds * 1e-6);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
