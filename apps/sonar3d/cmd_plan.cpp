#include <fmt/core.h>

#include <cstdlib>
#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/plan/mpi.hpp"
#include "sonar3d/plan/sweep.hpp"

namespace sonar3d::cli {

void add_plan(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "plan",
      "Pre-dive planner (thesis sec. 5.7.3): run every configuration of a sweep file "
      "(simulate → reconstruct → evaluate), in parallel, resumably, and rank them by a metric "
      "under hard constraints. Writes DIR/results.csv and DIR/results.json (docs/planner.md). "
      "Under `mpirun -np N` the points are spread over the ranks and rank 0 merges the results.");
  struct Opts {
    std::string sweep, out;
    std::unique_ptr<ConfigOptions<PlanConfig>> config;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("sweep", o->sweep, "sweep YAML file")->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->out,
                  "output directory: created, or an empty directory, or a plan directory of "
                  "sonar3d, which is resumed (finished points are kept); anything else is an "
                  "error");
  // The command's own settings (declared once, plan/sweep.hpp; the sweep file holds what the
  // points run with): --allow-empty, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<PlanConfig>>(cmd);
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->callback([&g, &run, o] {
    // The sweep and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->sweep.empty()) throw CLI::RequiredError("sweep");
      if (o->out.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [&g, o] {
      const PlanConfig cfg =
          with_flag_names(o->config->flag_names(), [&] { return o->config->resolve("plan"); });
      if (o->config->print_if_requested(cfg, "plan", "plan")) return 0;
      // Resuming is what a plan directory is for: no --overwrite needed for sonar3d's own.
      check_output(o->out, OutputKind::Plan, output_policy(true, {o->sweep}), "-o");
      const Sweep sweep = load_sweep(o->sweep);
      MpiSession mpi;  // rank 0 of 1 when not launched by mpirun
      PlanOptions opt;
      opt.out_dir = o->out;
      opt.worker_executable = std::filesystem::read_symlink("/proc/self/exe").string();
      opt.progress = !g.quiet && mpi.rank() == 0;
      opt.mpi_rank = mpi.rank();
      opt.mpi_size = mpi.size();
      opt.max_memory_bytes = memory_limit_bytes(o->max_memory_gb);
      const PlanSummary s = run_sweep(sweep, opt);
      gather_points(mpi, sweep, opt.out_dir);
      if (mpi.rank() == 0) {
        const std::size_t ok = write_sweep_results(sweep, opt.out_dir);
        fmt::print(
            "plan: {} points ({} run here, {} already done, {} excluded by constraints, "
            "{} failed) in {:.1f} s{}; results in {}/results.csv\n",
            s.points, s.ran, s.skipped_done, s.skipped_constraint, s.failed, s.seconds,
            mpi.size() > 1 ? fmt::format(" on {} ranks", mpi.size()) : "", o->out);
        if (ok == 0 && !cfg.allow_empty) {
          throw Error(std::string("no point of the sweep succeeded, nothing is ranked: the ") +
                      "reasons are in the message column of " + o->out +
                      "/results.csv (pass --allow-empty to exit with status 0 anyway)");
        }
      }
      return 0;
    };
  });

  // Internal: one point, run by the planner in a subprocess.
  auto* point = app.add_subcommand("plan-point", "(internal) run one sweep point")->group("");
  auto dir = std::make_shared<std::string>();
  auto index = std::make_shared<std::size_t>(0);
  point->add_option("dir", *dir)->required();
  point->add_option("index", *index)->required();
  point->callback([&run, dir, index] {
    run = [dir, index] {
      run_sweep_point(*dir, *index);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
