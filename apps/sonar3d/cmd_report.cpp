#include <fmt/core.h>

#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
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
    std::string dir, output, web_dir, color = "error", placements, catalogue;
    std::vector<std::string> overlays;
    ReportConfig cfg;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("input", o->dir,
                  "plan directory (results.json), map directory (merged.ply), world directory "
                  "(graph.json), change directory (changes.json), or a PLY cloud or mesh")
      ->required();
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
  cmd->add_option("--max-points", o->cfg.max_points_per_cloud,
                  "at most this many points shown per cloud (uniform random subsample)")
      ->capture_default_str();
  cmd->add_option("--max-total-points", o->cfg.max_points_total,
                  "budget of points over all clouds of the page, shared evenly")
      ->capture_default_str();
  cmd->add_option("--max-mesh-triangles", o->cfg.max_mesh_triangles,
                  "CAD meshes above this are simplified for display (errors use the full mesh)")
      ->capture_default_str();
  cmd->add_option("--color", o->color, "initial point colouring: error (distance to CAD) or height")
      ->check(CLI::IsMember({"error", "height"}))
      ->capture_default_str();
  cmd->add_option("--error-max", o->cfg.error_color_max,
                  "top of the error colour scale in metres (0: per cloud, its 95th percentile)")
      ->capture_default_str();
  cmd->add_option("--title", o->cfg.title, "page title (default: sonar3d sweep: <dir name>)");
  cmd->add_option(
      "--web-dir", o->web_dir,
      "web assets directory (default: $SONAR3D_WEB_DIR, else <prefix>/share/sonar3d/web "
      "when installed, else the source tree's web/)");
  cmd->add_option("--seed", o->cfg.seed, "subsampling seed")->capture_default_str();
  cmd->callback([&run, &g, o] {
    run = [&g, o] {
      o->cfg.output = o->output;
      o->cfg.web_dir = o->web_dir;
      o->cfg.color = parse_report_color(o->color);
      o->cfg.progress = !g.quiet;
      o->cfg.placements = o->placements;
      o->cfg.catalogue = o->catalogue;
      o->cfg.overlays.assign(o->overlays.begin(), o->overlays.end());
      const ReportSummary s = write_report(o->dir, o->cfg);
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
