// sonar3d relocalize: a new survey registered to a previous world model (library:
// world/relocalize.hpp; docs/mapping.md "Relocalisation").
#include <fmt/core.h>

#include <cmath>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/world/relocalize.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

void add_relocalize(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "relocalize",
      "Relocalise a new survey (down to a single line) against a world model of sonar3d world: "
      "each swath carved and registered onto the model's seabed and structures (elevation-map "
      "shift search, eq. 6.1-6.2, over a yaw search spanning the navigation's error, then "
      "Gauss-Newton of the heights). Writes OUTPUT/relocalization.json (per swath: correction, "
      "sigma, overlap, residual, found or why not) and OUTPUT/navigation.tum (the vehicle "
      "navigation in the world model's frame); with --map-resolution also OUTPUT/merged.ply, the "
      "survey carved with that navigation (survey B of sonar3d diff). Exit status 3 when the "
      "survey is not found in "
      "the model.");
  struct Opts {
    std::string dataset, world, output;
    bool overwrite = false;
    std::unique_ptr<ConfigOptions<RelocalizeConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dataset", o->dataset, "dataset directory of the new survey");
  cmd->add_option("--world", o->world, "world model directory (sonar3d world)");
  cmd->add_option("-o,--output", o->output, "relocalisation directory to write (new or empty)");
  o->config = std::make_unique<ConfigOptions<RelocalizeConfig>>(cmd);
  add_overwrite_flag(cmd, o->overwrite, "a relocalisation directory of an earlier relocalize");
  cmd->callback([&run, &g, o] {
    // The dataset, --world and -o are required unless --print-config: a usage error (exit 2).
    if (!o->config->print_requested()) {
      if (o->dataset.empty()) throw CLI::RequiredError("dataset");
      if (o->world.empty()) throw CLI::RequiredError("--world");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o, &g] {
      // The library's errors name its fields ("registration.search_m"): the user reads the flag.
      return with_flag_names(o->config->flag_names(), [&] {
        RelocalizeConfig cfg = o->config->resolve("relocalize");
        cfg.validate();
        if (o->config->print_if_requested(cfg, "relocalize", "relocalize")) return 0;
        require(fs::is_directory(o->dataset),
                "relocalize: dataset '" + o->dataset + "' is not a directory");
        OutputDirectory out(o->output, OutputKind::Relocalization,
                            output_policy(o->overwrite, {o->dataset, o->world}));
        for (const std::string& n : out.notes()) print_note(n);
        const WorldModelCloud world = read_world_model_cloud(o->world, cfg.model_spacing_m);
        const Dataset ds = read_dataset(o->dataset);
        RelocalizeResult r = relocalize(ds, world, cfg, !g.quiet);
        r.dataset = o->dataset;
        write_relocalization(out.staging(), r, cfg);
        out.commit();
        std::size_t found = 0;
        for (const RelocalizedSwath& s : r.swaths) found += s.found;
        if (!r.found) {
          const std::string why = r.swaths.empty() ? "" : r.swaths.front().reason;
          fmt::print(
              "relocalize: NOT FOUND in {} ({} swath(s), none found: {}); {}/relocalization."
              "json, {:.1f} s\n",
              o->world, r.swaths.size(), why, o->output, r.seconds_total);
          return 3;
        }
        const RelocalizedSwath* first = nullptr;
        for (const RelocalizedSwath& s : r.swaths) {
          if (s.found) {
            first = &s;
            break;
          }
        }
        const Eigen::Vector3d t = first->T_model_survey.translation();
        fmt::print(
            "relocalize: found in {} ({}/{} swaths): shift E {:+.3f} N {:+.3f} U {:+.3f} m, yaw "
            "{:+.2f} deg, sigma {:.3f} m horizontal, overlap {:.0f} %, residual {:.3f} m, "
            "distinctiveness {:.2f}; {:.1f} s (carving {:.1f} s, registration {:.1f} s) -> "
            "{}/navigation.tum\n",
            o->world, found, r.swaths.size(), t.x(), t.y(), t.z(), first->yaw_deg,
            r.sigma_horizontal_m, 100 * first->overlap_fraction, first->residual_m,
            first->distinctiveness, r.seconds_total, r.seconds_carving, r.seconds_registration,
            o->output);
        if (!r.map.empty()) {
          fmt::print(
              "  the survey carved with the relocalised navigation at {:g} m: {} points, {:.1f} s "
              "-> {}/merged.ply (survey B of sonar3d diff)\n",
              r.map_voxel_m, r.map.size(), r.seconds_map, o->output);
        }
        return 0;
      });
    };
  });
}

}  // namespace sonar3d::cli
