// sonar3d survey: a survey log to a map, placements, a world model and a report in one command
// (library: pipeline/survey_pipeline.hpp; docs/survey.md).
#include <fmt/core.h>

#include <cstdio>
#include <memory>

#include "commands.hpp"
#include "sonar3d/pipeline/survey_pipeline.hpp"

namespace sonar3d::cli {

void add_survey(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "survey",
      "Run a whole survey: import (an ARIS file, a ROS 1/2 bag, a HoloOcean recording or an "
      "Oculus stream; a dataset is used in place) -> map (carve swaths, register, correct the "
      "navigation; metres) -> recognize (with --catalogue) -> world model -> texture (when the "
      "log has camera images) -> report. Writes OUT/dataset/, map/, placements.json, world/, "
      "textured.ply, report.html and summary.json (each stage's wall time in seconds, peak "
      "memory in MB, key figures). A re-run resumes: a finished stage whose inputs and settings "
      "are unchanged is skipped. Options of every stage come from --config (docs/survey.md).");
  struct Opts {
    std::string input, output, catalogue, config;
    bool print_config = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("input", o->input,
                  "dataset directory, ARIS file (.aris), ROS 1 bag (.bag), ROS 2 bag (directory "
                  "or .db3), HoloOcean recording (directory) or Oculus ping stream");
  cmd->add_option("-o,--output", o->output,
                  "survey directory to write (new or empty), or one an earlier survey wrote "
                  "(resumed)");
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue YAML of the CAD models to recognise (docs/recognition.md); without "
                  "it the recognize stage is skipped")
      ->check(CLI::ExistingFile);
  cmd->add_option("--config", o->config,
                  "survey YAML: stage keys import, map, recognize, world, texture, report, each "
                  "its command's configuration as its --print-config prints it (import: kind "
                  "and one block per kind: aris, rosbag, oculus, holoocean); texture and report "
                  "under their flag names ('-' written '_'); units: metres, seconds, degrees in "
                  "*_deg")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--print-config", o->print_config,
                "print the whole effective configuration as YAML (every option, defaults "
                "included) and exit");
  cmd->callback([&run, &g, o] {
    if (!o->print_config) {
      if (o->input.empty()) throw CLI::RequiredError("input");
      if (o->output.empty()) throw CLI::RequiredError("--output");
    }
    run = [o, &g] {
      SurveyOptions opts;
      if (!o->config.empty()) opts.config = load_survey_config(o->config);
      if (o->print_config) {
        std::fputs(survey_config_yaml(opts.config).c_str(), stdout);
        return 0;
      }
      opts.input = o->input;
      opts.output = o->output;
      opts.catalogue = o->catalogue;
      opts.config_file = o->config;
      opts.progress = !g.quiet;
      opts.on_warning = print_warning;
      const bool quiet = g.quiet;
      opts.on_stage = [quiet](int k, int n, const std::string& stage, const std::string& status) {
        if (quiet) return;
        if (status == "start") {
          std::fprintf(stderr, "survey: stage %d/%d %s\n", k, n, stage.c_str());
        } else if (status != "ran") {
          std::fprintf(stderr, "survey: stage %d/%d %s: %s\n", k, n, stage.c_str(), status.c_str());
        }
      };
      const SurveyResult r = run_survey(opts);
      fmt::print("survey of {} -> {} ({:.1f} s)\n", o->input, o->output, r.seconds);
      for (const SurveyStageReport& s : r.stages) {
        std::string figures;
        for (const auto& [k, v] : s.figures) {
          figures += fmt::format("{}{} {:.6g}", figures.empty() ? "" : ", ", k, v);
        }
        if (s.status == "skipped") {
          fmt::print("  {:<9} skipped: {}\n", s.name, s.note);
          continue;
        }
        fmt::print("  {:<9} {:<9} {:7.2f} s {:7.0f} MB  {}{}\n", s.name, s.status, s.seconds,
                   s.peak_memory_mb, figures, s.note.empty() ? "" : "; " + s.note);
      }
      fmt::print("summary: {}/summary.json\n", o->output);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
