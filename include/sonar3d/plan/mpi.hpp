#pragma once
// MPI for the planner: when the process was started by mpirun (OpenMPI), the session initialises
// MPI and exposes rank and size; otherwise it is a session of one rank. Built without MPI, it is
// always one rank.
#include <filesystem>

#include "sonar3d/plan/sweep.hpp"

namespace sonar3d {

class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  // Sends every rank's point results (status.json, metrics.json) to rank 0, which writes them
  // into its own output directory: the ranks need not share a file system. Collective.
  void gather_points(const Sweep& sweep, const std::filesystem::path& out_dir);
  static bool available();  // built with MPI

 private:
  int rank_ = 0, size_ = 1;
  bool initialised_ = false;
};

}  // namespace sonar3d
