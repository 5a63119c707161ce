#pragma once
// Each subcommand registers itself on the CLI11 app and runs through a library call: no
// algorithm lives here.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

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
// The output rule's policy (core/output_dir.hpp) of a command: --overwrite, its inputs (files or
// directories, none of which an output may be, contain or lie inside), notes printed on stderr.
OutputPolicy output_policy(bool overwrite, std::vector<std::filesystem::path> inputs);

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

}  // namespace sonar3d::cli
