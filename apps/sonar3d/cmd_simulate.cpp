#include <fmt/core.h>

#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
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
  struct Opts {
    std::string scene, out;
    bool overwrite = false;
    std::unique_ptr<ConfigOptions<SimulateConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("scene", o->scene, "scene YAML file")->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite)");
  add_overwrite_flag(cmd, o->overwrite, "an existing sonar3d dataset at --output");
  // The settings beside the scene file (declared once, sim/simulation.hpp): --seed,
  // --allow-empty, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<SimulateConfig>>(cmd);
  cmd->callback([&g, &run, o] {
    // The scene and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->scene.empty()) throw CLI::RequiredError("scene");
      if (o->out.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [&g, o] {
      // Errors in the settings name the user's flag (or the file, line and key).
      const SimulateConfig cfg = with_flag_names(o->config->flag_names(), [&] {
        SimulateConfig c = o->config->resolve("simulate");
        c.validate();
        return c;
      });
      if (o->config->print_if_requested(cfg, "simulate", "simulate")) return 0;
      OutputPolicy policy;
      policy.overwrite = o->overwrite;
      policy.on_note = print_note;
      policy.sources = {o->scene};
      OutputDirectory dir(o->out, OutputKind::Dataset, policy);
      SimulationSetup setup = load_simulation_setup(o->scene);
      if (cfg.seed) setup.seed = static_cast<unsigned long long>(*cfg.seed);
      const SimulationStats st = simulate_dataset(setup, dir.staging(), !g.quiet);
      if (!cfg.allow_empty) {
        // A return: a pixel above the noise floor (Z > 6 with a noise model: a false alarm
        // from the noise itself is then below one in a billion pixels).
        DenoiseConfig returns;
        returns.z_threshold = 6.0;
        const Dataset ds = read_dataset(dir.staging());
        if (!first_frame_with_return(ds, returns)) {
          throw Error("'" + o->scene + "': no object is in view in any of the " +
                      std::to_string(st.frames) + " frames" +
                      (ds.noise ? " (above the noise)" : "") +
                      "; check the trajectory, the sonar mounting (T_vehicle_sonar) and r_min/"
                      "r_max against the objects' positions, or pass --allow-empty");
        }
      }
      dir.commit();
      fmt::print("wrote {} frames to {} ({:.1f} s, {:.1f} frames/s, {:.1f} Mrays/s)\n", st.frames,
                 o->out, st.seconds, st.frames / st.seconds, st.rays / st.seconds * 1e-6);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
