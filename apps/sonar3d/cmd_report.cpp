#include <fmt/core.h>

#include <memory>

#include "commands.hpp"
#include "sonar3d/report/report.hpp"

namespace sonar3d::cli {

void add_report(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "report",
      "Write a self-contained HTML page for a `sonar3d plan` directory: metrics against each swept "
      "parameter, a sortable results table and a 3D viewer of the clouds over the CAD models. "
      "Opens offline (the JavaScript libraries are inlined).");
  struct Opts {
    std::string dir, output, web_dir, color = "error";
    ReportConfig cfg;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dir", o->dir, "plan directory (holds results.json)")->required();
  cmd->add_option("-o,--output", o->output, "HTML file to write (default: DIR/report.html)");
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
      const ReportSummary s = write_report(o->dir, o->cfg);
      for (const auto& w : s.warnings) fmt::print(stderr, "sonar3d: warning: {}\n", w);
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
