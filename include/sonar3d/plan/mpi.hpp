#pragma once
// The planner under MPI: points are spread over the ranks round-robin by index.
#include <filesystem>

#include "sonar3d/core/mpi.hpp"
#include "sonar3d/plan/sweep.hpp"

namespace sonar3d {

// Sends every rank's point results (status.json, metrics.json) to rank 0, which writes them into
// its own output directory: the ranks need not share a file system. Collective.
void gather_points(const MpiSession& mpi, const Sweep& sweep, const std::filesystem::path& out_dir);

}  // namespace sonar3d
