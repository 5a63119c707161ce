#pragma once
// Each subcommand registers itself on the CLI11 app and runs through a library call: no
// algorithm lives here.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/output_dir.hpp"

namespace sonar3d::cli {

struct GlobalOptions {
  bool quiet = false;  // no progress bars
};

// Exit statuses (README.md, "Command-line reference").
inline constexpr int kExitFailure = 1;  // the command failed: one line `sonar3d: error: ...`
inline constexpr int kExitUsage = 2;    // the command line is wrong: same one-line format

// --overwrite, with the same meaning on every command that replaces an output.
void add_overwrite_flag(CLI::App* cmd, bool& flag, const std::string& what);
// Prints `sonar3d: note: LINE` on stderr (e.g. an interrupted run cleaned up).
void print_note(const std::string& line);
// Prints `sonar3d: warning: LINE` on stderr: warnings and notes never reach standard output,
// which carries only results.
void print_warning(const std::string& line);
// --max-memory GB, with the same meaning on every command that allocates from its options and
// data (core/memory.hpp): `gb` stays 0 unless given; memory_limit_bytes() turns it into the limit
// (the default: 8 GB or 75 % of the machine's memory, whichever is less).
void add_max_memory_option(CLI::App* cmd, double& gb);
double memory_limit_bytes(double gb);
// The output rule's policy (core/output_dir.hpp) of a command: --overwrite, its inputs (files or
// directories, none of which an output may be, contain or lie inside), notes printed on stderr.
OutputPolicy output_policy(bool overwrite, std::vector<std::filesystem::path> inputs);

// Hints name the user's flags, never a library field: the library's errors name its config
// fields ("parameter 'carve.voxel_size' ...", "widen search_m"); a command lists which flag sets
// which field, and with_flag_names() rethrows an Error with each field (a whole word) replaced by
// its flag. Longer field names are replaced first ("carve.voxel_size" before "voxel_size").
using FlagNames = std::vector<std::pair<std::string, std::string>>;
std::string name_flags(const std::string& message, const FlagNames& names);
template <class F>
auto with_flag_names(const FlagNames& names, F&& fn) -> decltype(fn()) {
  try {
    return fn();
  } catch (const Interrupted&) {
    throw;
  } catch (const Error& e) {
    throw Error(name_flags(e.what(), names));
  }
}

// Registers the subcommand and returns the function that runs it once parsed.
using Runner = std::function<int()>;
void add_simulate(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_noise(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_evaluate(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_info(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_bench(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_preview(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_reconstruct(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_plan(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_import(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_export(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_report(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_elevation(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_register(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_map(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_recognize(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_texture(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_world(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_diff(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_survey(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_relocalize(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_ros(CLI::App& app, const GlobalOptions& g, Runner& run);
void add_online(CLI::App& app, const GlobalOptions& g, Runner& run);

}  // namespace sonar3d::cli
