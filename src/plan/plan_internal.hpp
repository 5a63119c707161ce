#pragma once
// Internal helpers shared by the planner's translation units.
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/plan/sweep.hpp"
#include "sonar3d/recon/reconstruct.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d {

// A point's simulated dataset while the point runs; renamed to "dataset" when the point finished
// and the sweep keeps datasets, so that an unfinished point never has a complete-looking dataset/.
inline constexpr const char* kPartialDatasetName = "dataset.partial";

TriangleMesh plan_object_mesh(const std::string& object, const std::filesystem::path& sweep_dir);
// The simulated inspection of one point (sensor, object at the origin, path, noise).
SimulationSetup plan_setup(const Sweep& sweep, const std::map<std::string, SweepValue>& params,
                           const std::filesystem::path& sweep_dir);
// The reconstruction one point runs: its method and voxel, its `reconstruct.*` settings, the
// object's box with a margin as the region.
ReconstructConfig plan_reconstruct_config(const SimulationSetup& setup,
                                          const std::map<std::string, SweepValue>& params);
// Memory that point's reconstruction will take (check_reconstruct_memory's estimate, from the
// setup's poses before anything is simulated); parts name `voxel_m`.
MemoryEstimate estimate_plan_point_memory(const SimulationSetup& setup,
                                          const std::map<std::string, SweepValue>& params,
                                          double limit_bytes);
// Scale of the stripe noise model that gives `snr_db` on this setup.
double plan_noise_scale(const SimulationSetup& setup, double snr_db);
// A stable text key of a point's parameters: a finished point is reused only if it matches.
std::string plan_params_key(const std::map<std::string, SweepValue>& params);
nlohmann::json plan_params_json(const std::map<std::string, SweepValue>& params);
// Threads one point may use (set by the runner for its subprocesses; 0 = all cores).
int plan_threads_per_point();

}  // namespace sonar3d
