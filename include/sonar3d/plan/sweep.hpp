#pragma once
// The pre-dive planner (thesis sec. 5.7.3): a grid of simulated inspections over sensor,
// trajectory and method parameters for given CAD objects; each point runs
// simulate → reconstruct → evaluate and the configurations are ranked by a chosen metric under
// hard constraints. The directory layout it writes is documented in docs/planner.md.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

// A swept value: a number, a string (object, method, path) or none (e.g. snr_db: none = no noise).
using SweepValue = std::variant<std::monostate, double, std::string>;
std::string to_string(const SweepValue& v);

struct SweepConstraint {
  std::string parameter;
  std::string op;  // >=, <=, >, <, ==, !=
  double value = 0;
  std::string text;  // as written
  bool satisfied_by(const std::map<std::string, SweepValue>& params) const;
};

// Parameters a sweep may vary, with their units (docs/planner.md):
//   object (reference name or mesh path), aperture_deg, range_res_m, bearing_res_deg, fov_deg,
//   snr_db (number or none), spacing_m (sampling period along the path), standoff_m,
//   path (vertical | orbit), method (carve | deconv | deconv-l1 | deconv-exact), voxel_m.
const std::vector<std::string>& sweep_parameter_names();

struct Sweep {
  std::string source;  // file
  // Axes in file order; every point takes one value per axis. Parameters not swept take the
  // defaults below (the `fixed:` block of the file may override them).
  std::vector<std::pair<std::string, std::vector<SweepValue>>> axes;
  std::map<std::string, SweepValue> fixed;
  std::vector<SweepConstraint> constraints;
  std::string rank_by = "median_to_coverage";  // a metric name
  int workers = 0;                   // parallel points on this machine; 0 = number of cores
  bool keep_datasets = false;        // keep each point's simulated dataset
  double elevation_step_deg = 0.01;  // simulator ray spacing (θ_res), the thesis' 0.01°
  unsigned long long seed = 1;

  std::size_t size() const;  // number of grid points
  // Point `index` (row-major over the axes, last axis fastest): fixed values, then the axes'.
  std::map<std::string, SweepValue> point(std::size_t index) const;
};

// Parses a sweep file. An unknown key, an unknown parameter, an empty axis, a value of the wrong
// type or an unparsable constraint is an Error naming file, line and key.
Sweep load_sweep(const std::string& path);

// The metrics that can rank configurations, and whether larger is better.
bool metric_higher_is_better(const std::string& metric);

struct PlanOptions {
  std::filesystem::path out_dir;
  std::string worker_executable;  // the sonar3d binary that runs single points (subprocesses)
  bool progress = true;
  int mpi_rank = 0, mpi_size = 1;  // set by the CLI when launched under mpirun
  // Memory limit of the points running at once (core/memory.hpp), bytes; 0: the default limit.
  // run_sweep refuses, before anything runs, a sweep whose largest point times the workers
  // running together is estimated beyond it.
  double max_memory_bytes = 0;
};

// sonar3d plan's own settings (the sweep file holds everything the points run with).
struct PlanConfig {
  bool allow_empty = false;  // exit status 0 even when no point succeeded
};
template <class V>
void describe(PlanConfig& c, V& v) {
  v.field(c.allow_empty, params::param("allow_empty", "",
                                       "exit with status 0 even when no point of the sweep "
                                       "succeeded (else an error: nothing is ranked)")
                             .flag("--allow-empty"));
}

struct PlanSummary {
  std::size_t points = 0, ran = 0, skipped_done = 0, skipped_constraint = 0, failed = 0;
  double seconds = 0;
};

// Runs (or resumes) the sweep: points already finished with the same parameters are skipped;
// points run as subprocesses `worker_executable plan-point DIR ID` (so that a crash or an error
// is recorded as that point's failure and the sweep goes on, and each point's peak memory is
// measured), `workers` at a time; rank 0 writes results.json and results.csv.
// A worker that dies (signal, non-zero exit) fails its point whatever it wrote. SIGINT/SIGTERM
// are forwarded to the running workers; their points are recorded as failed and Interrupted is
// thrown once they have exited.
PlanSummary run_sweep(const Sweep& sweep, const PlanOptions& options);

// Runs one point in this process and writes DIR/points/<id>/status.json (+ cloud.ply,
// metrics.json). Never throws for a failure of the configuration itself: it is recorded.
void run_sweep_point(const std::filesystem::path& out_dir, std::size_t index);

// Rebuilds results.json / results.csv from the points' status files (ranking included). Returns
// the number of points whose status is "ok".
std::size_t write_sweep_results(const Sweep& sweep, const std::filesystem::path& out_dir);

std::string point_id(std::size_t index);

}  // namespace sonar3d
