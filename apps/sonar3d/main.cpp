// sonar3d: 3D maps from 2D imaging-sonar images. One file per subcommand in this directory.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <exception>
#include <filesystem>
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

void print_warning(const std::string& line) {
  std::fprintf(stderr, "sonar3d: warning: %s\n", line.c_str());
}

void add_max_memory_option(CLI::App* cmd, double& gb) {
  char def[32];
  std::snprintf(def, sizeof def, "%.3g", default_memory_limit_bytes() / 1e9);
  cmd->add_option("--max-memory", gb,
                  std::string("refuse to start when the memory estimated from the options and the "
                              "data exceeds this many GB (default on this machine: ") +
                      def + " GB: 8 GB, or 75 % of the physical memory when less)")
      ->check(CLI::PositiveNumber);
}

double memory_limit_bytes(double gb) { return gb > 0 ? gb * 1e9 : default_memory_limit_bytes(); }

std::string name_flags(const std::string& message, const FlagNames& names) {
  FlagNames sorted = names;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const auto& a, const auto& b) { return a.first.size() > b.first.size(); });
  auto word = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-';
  };
  std::string out;
  for (std::size_t i = 0; i < message.size();) {
    bool replaced = false;
    if (i == 0 || !word(message[i - 1])) {
      for (const auto& [field, flag] : sorted) {
        const std::size_t end = i + field.size();
        if (message.compare(i, field.size(), field) == 0 &&
            (end == message.size() || !word(message[end]) ||
             (message[end] == '.' && (end + 1 == message.size() || message[end + 1] == ' ')))) {
          // "parameter 'carve.voxel_size'" becomes "--voxel-size", not "parameter '--voxel-size'"
          if (i >= 11 && message.compare(i - 11, 11, "parameter '") == 0 && end < message.size() &&
              message[end] == '\'') {
            out.erase(out.size() - 11);
            out += flag;
            i = end + 1;
          } else {
            out += flag;
            i = end;
          }
          replaced = true;
          break;
        }
      }
    }
    if (!replaced) out += message[i++];
  }
  return out;
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
  add_survey(app, g, run);
  add_relocalize(app, g, run);
  add_ros(app, g, run);
  add_online(app, g, run);
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
  } catch (const std::filesystem::filesystem_error& e) {
    // The library's words ("filesystem error: cannot ...: File name too long [PATH]") become
    // the path and the reason.
    std::string what = "'" + sonar3d::printable(e.path1().string(), 200) + "'";
    if (!e.path2().empty()) what += " -> '" + sonar3d::printable(e.path2().string(), 200) + "'";
    std::string reason = e.code().message();
    if (!reason.empty()) reason[0] = static_cast<char>(std::tolower(reason[0]));
    std::fprintf(stderr, "sonar3d: error: %s: %s\n", what.c_str(), reason.c_str());
    return kExitFailure;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sonar3d: error: %s\n", one_line(e.what()).c_str());
    return kExitFailure;
  }
}
