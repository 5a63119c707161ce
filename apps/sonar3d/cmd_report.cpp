#include <fmt/core.h>

#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/report/report.hpp"

namespace sonar3d::cli {

void add_report(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "report",
      "Write a self-contained HTML page for a `sonar3d plan` directory (metrics against each swept "
      "parameter, a results table, the clouds over the CAD models), a `sonar3d map` directory "
      "(with --placements: the placed models over the cloud), a `sonar3d world` directory, a "
      "`sonar3d diff` directory or a PLY cloud/mesh (e.g. textured: in its colours). The input's "
      "kind is recognised by its content. Opens offline (the JavaScript libraries are inlined).");
  struct Opts {
    std::string dir, output, web_dir, placements, catalogue;
    std::vector<std::string> overlays;
    std::unique_ptr<ConfigOptions<ReportConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("input", o->dir,
                  "plan directory (results.json), map directory (merged.ply), world directory "
                  "(graph.json), change directory (changes.json), or a PLY cloud or mesh");
  cmd->add_option("-o,--output", o->output,
                  "HTML file to write (default: INPUT/report.html; FILE.html beside a PLY)");
  cmd->add_option("--placements", o->placements,
                  "map or PLY cloud: placements.json of `sonar3d recognize`, drawn over the cloud");
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue of the placements' (or a change directory's) models (default: the "
                  "one placements.json names)");
  cmd->add_option("--overlay", o->overlays,
                  "a further PLY cloud or mesh drawn in the 3D view of a map, world, change or PLY "
                  "page (e.g. a `sonar3d texture` output); repeatable");
  cmd->add_option(
      "--web-dir", o->web_dir,
      "web assets directory (default: $SONAR3D_WEB_DIR, else <prefix>/share/sonar3d/web "
      "when installed, else the source tree's web/)");
  // Every setting (declared once, report/report.hpp): its flag, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<ReportConfig>>(cmd);
  cmd->callback([&run, &g, o] {
    // The input is required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested() && o->dir.empty()) throw CLI::RequiredError("input");
    run = [&g, o] {
      // The library's errors name its fields ("max_points_per_cloud"): the user reads the flag.
      FlagNames names = o->config->flag_names();
      names.insert(names.end(), {{"max_points_per_cloud", "--max-points"},
                                 {"max_points_total", "--max-total-points"},
                                 {"error_color_max", "--error-max"}});
      // Errors in the settings name the user's flag (or the file, line and key).
      ReportConfig cfg = with_flag_names(names, [&] {
        ReportConfig c = o->config->resolve("report");
        c.validate();
        return c;
      });
      if (o->config->print_if_requested(cfg, "report", "report")) return 0;
      cfg.output = o->output;
      cfg.web_dir = o->web_dir;
      cfg.progress = !g.quiet;
      cfg.placements = o->placements;
      cfg.catalogue = o->catalogue;
      cfg.overlays.assign(o->overlays.begin(), o->overlays.end());
      const ReportSummary s = write_report(o->dir, cfg);
      for (const auto& w : s.warnings) fmt::print(stderr, "sonar3d: warning: {}\n", w);
      if (s.input != ReportInput::Sweep) {
        fmt::print(
            "report: {} ({:.1f} MB): {} {}: {} layers ({} clouds, {} points shown; {} mesh "
            "triangles shown), {} table rows\n",
            s.output.string(), s.bytes / 1e6, report_input_name(s.input), o->dir, s.num_layers,
            s.num_clouds, s.num_cloud_points, s.num_mesh_triangles, s.num_table_rows);
        return 0;
      }
      fmt::print(
          "report: {} ({:.1f} MB): {} configurations ({} ok, {} failed), {} clouds, "
          "{} points shown\n",
          s.output.string(), s.bytes / 1e6, s.num_points, s.num_ok, s.num_failed, s.num_clouds,
          s.num_cloud_points);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
