// sonar3d: 3D maps from 2D imaging-sonar images. One file per subcommand in this directory.
#include <cstdio>
#include <exception>
#include <string>

#include "commands.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/version.hpp"

int main(int argc, char** argv) {
  using namespace sonar3d::cli;
  CLI::App app{
      "sonar3d: simulate 2D imaging sonars, reconstruct 3D scenes and measure them against CAD.\n"
      "Units: metres, seconds, degrees where an option name ends in _deg."};
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
  add_report(app, g, run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return run ? run() : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sonar3d: error: %s\n", e.what());
    return 1;
  }
}
