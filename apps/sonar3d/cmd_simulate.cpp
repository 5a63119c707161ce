#include <fmt/core.h>

#include "commands.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/denoise.hpp"
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
  auto overwrite = std::make_shared<bool>(false);
  auto allow_empty = std::make_shared<bool>(false);
  cmd->add_option("scene", *scene, "scene YAML file")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite)")
      ->required();
  cmd->add_option("--seed", *seed, "random seed for jitter and noise (default: the scene's seed)");
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->add_flag("--allow-empty", *allow_empty,
                "write the dataset even when no object is ever in view (by default an error)");
  cmd->callback([&g, &run, scene, out, seed, overwrite, allow_empty] {
    run = [&g, scene, out, seed, overwrite, allow_empty] {
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*scene};
      OutputDirectory dir(*out, OutputKind::Dataset, policy);
      SimulationSetup setup = load_simulation_setup(*scene);
      if (*seed >= 0) setup.seed = static_cast<unsigned long long>(*seed);
      const SimulationStats st = simulate_dataset(setup, dir.staging(), !g.quiet);
      if (!*allow_empty) {
        // A return: a pixel above the noise floor (Z > 6 with a noise model: a false alarm
        // from the noise itself is then below one in a billion pixels).
        DenoiseConfig returns;
        returns.z_threshold = 6.0;
        const Dataset ds = read_dataset(dir.staging());
        if (!first_frame_with_return(ds, returns)) {
          throw Error("'" + *scene + "': no object is in view in any of the " +
                      std::to_string(st.frames) + " frames" +
                      (ds.noise ? " (above the noise)" : "") +
                      "; check the trajectory, the sonar mounting (T_vehicle_sonar) and r_min/"
                      "r_max against the objects' positions, or pass --allow-empty");
        }
      }
      dir.commit();
      fmt::print("wrote {} frames to {} ({:.1f} s, {:.1f} frames/s, {:.1f} Mrays/s)\n", st.frames,
                 *out, st.seconds, st.frames / st.seconds, st.rays / st.seconds * 1e-6);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
