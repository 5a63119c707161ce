#include <fmt/core.h>

#include <memory>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/mapping/swath_registration.hpp"

namespace sonar3d::cli {

void add_register(CLI::App& app, const GlobalOptions&, Runner& run) {
  auto* cmd = app.add_subcommand(
      "register",
      "Register two overlapping swath elevation maps (thesis sec. 6.2.2.1, eq. 6.1-6.2): the "
      "East/North shift and height offset that move MOVING onto REFERENCE, with its score and "
      "confidence.");
  struct Opts {
    std::string reference, moving, json;
    std::unique_ptr<ConfigOptions<SwathRegistrationConfig>> config;
    bool overwrite = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("reference", o->reference, "elevation map GeoTIFF (sonar3d elevation)")
      ->check(CLI::ExistingFile);
  cmd->add_option("moving", o->moving, "elevation map GeoTIFF at the same cell size")
      ->check(CLI::ExistingFile);
  cmd->add_option("--json", o->json,
                  "also write the result as JSON to this file (an existing one only if sonar3d "
                  "register wrote it, with --overwrite)");
  add_overwrite_flag(cmd, o->overwrite, "a result JSON sonar3d register wrote earlier");
  // Every setting (declared once, mapping/swath_registration.hpp): its flag, --print-config,
  // --config FILE.
  o->config = std::make_unique<ConfigOptions<SwathRegistrationConfig>>(cmd);
  cmd->callback([&run, o] {
    // Both maps are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->reference.empty()) throw CLI::RequiredError("reference");
      if (o->moving.empty()) throw CLI::RequiredError("moving");
    }
    run = [o] {
      const SwathRegistrationConfig cfg = o->config->resolve("register");
      with_flag_names(o->config->flag_names(), [&] { cfg.validate(); });
      if (o->config->print_if_requested(cfg, "register", "register")) return 0;
      OutputFiles out(output_policy(o->overwrite, {o->reference, o->moving}));
      const std::filesystem::path json =
          o->json.empty() ? std::filesystem::path()
                          : out.add(o->json, OutputKind::RegistrationJson, "--json");
      const ElevationMap a = read_elevation_geotiff(o->reference);
      const ElevationMap b = read_elevation_geotiff(o->moving);
      const SwathTie t = register_elevation_maps(a, b, cfg);
      fmt::print(
          "shift East {:+.3f} m, North {:+.3f} m, height {:+.3f} m; score (median |dz|) {:.4f} "
          "m over {} cells; confidence {:.2f}; {:.2f} s\n",
          t.t.x(), t.t.y(), t.t.z(), t.score_m, t.overlap_cells, t.confidence, t.seconds);
      if (!o->json.empty()) {
        const nlohmann::json j = {{"format", json_format_marker(OutputKind::RegistrationJson)},
                                  {"reference", o->reference},
                                  {"moving", o->moving},
                                  {"shift_east_m", t.t.x()},
                                  {"shift_north_m", t.t.y()},
                                  {"shift_up_m", t.t.z()},
                                  {"score_m", t.score_m},
                                  {"overlap_cells", t.overlap_cells},
                                  {"confidence", t.confidence},
                                  {"seconds", t.seconds}};
        write_text_file(json.string(), j.dump(2) + "\n");
        out.commit();
      }
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
