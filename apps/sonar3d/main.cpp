// sonar3d: 3D maps from 2D imaging-sonar images. One file per subcommand in this directory.
#include <cstdio>
#include <exception>
#include <string>

#include "commands.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/version.hpp"

namespace sonar3d::cli {

void add_overwrite_flag(CLI::App* cmd, bool& flag, const std::string& what) {
  cmd->add_flag("--overwrite", flag,
                "replace " + what +
                    " (sonar3d never replaces what it did not write: anything else at that path "
                    "is an error)");
}

void print_note(const std::string& line) {
  std::fprintf(stderr, "sonar3d: note: %s\n", line.c_str());
}

OutputPolicy output_policy(bool overwrite, std::vector<std::filesystem::path> inputs) {
  OutputPolicy policy;
  policy.overwrite = overwrite;
  policy.sources = std::move(inputs);
  policy.on_note = print_note;
  return policy;
}

namespace {

// One line: newlines of multi-line messages become spaces.
std::string one_line(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

}  // namespace
}  // namespace sonar3d::cli

int main(int argc, char** argv) {
  using namespace sonar3d::cli;
  CLI::App app{
      "sonar3d: simulate 2D imaging sonars, reconstruct 3D scenes and measure them against CAD.\n"
      "Units: metres, seconds, degrees where an option name ends in _deg.\n"
      "Exit status: 0 success, 1 failure, 2 usage error, 128+N interrupted by signal N."};
  app.set_version_flag("--version", std::string("sonar3d ") + SONAR3D_VERSION);
  app.require_subcommand(1);
  app.fallthrough();  // global flags (--quiet) may follow the subcommand
  GlobalOptions g;
  app.add_flag("-q,--quiet", g.quiet, "no progress bars");
  Runner run;
  add_simulate(app, g, run);
  add_noise(app, g, run);
  add_evaluate(app, g, run);
  add_info(app, g, run);
  add_bench(app, g, run);
  add_preview(app, g, run);
  add_reconstruct(app, g, run);
  add_plan(app, g, run);
  add_import(app, g, run);
  add_export(app, g, run);
  add_report(app, g, run);
  add_elevation(app, g, run);
  add_register(app, g, run);
  add_map(app, g, run);
  add_recognize(app, g, run);
  add_texture(app, g, run);
  add_world(app, g, run);
  add_diff(app, g, run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version are "errors" with exit code 0: CLI11 prints them.
    if (e.get_exit_code() == 0) return app.exit(e);
    std::string help = "sonar3d";  // the (sub)command whose --help lists the options
    for (CLI::App* sub = &app; !sub->get_subcommands().empty();) {
      sub = sub->get_subcommands().front();
      help += " " + sub->get_name();
    }
    std::fprintf(stderr, "sonar3d: error: %s (see '%s --help')\n", one_line(e.what()).c_str(),
                 help.c_str());
    return kExitUsage;
  }
  try {
    return run ? run() : 0;
  } catch (const sonar3d::Interrupted& e) {
    std::fprintf(stderr, "sonar3d: error: %s\n", one_line(e.what()).c_str());
    return 128 + e.signal();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sonar3d: error: %s\n", one_line(e.what()).c_str());
    return kExitFailure;
  }
}
