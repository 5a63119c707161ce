#pragma once
// MPI for work spread over processes (the planner's sweep points, the field mapping's swaths):
// when the process was started by mpirun (OpenMPI), the session initialises MPI and exposes rank
// and size; otherwise it is a session of one rank. Built without MPI, it is always one rank.
#include <string>
#include <vector>

namespace sonar3d {

class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  // Collective: every rank sends `mine`; rank 0 gets all of them in rank order (its own first),
  // the other ranks an empty list. The ranks need not share a file system. One rank: {mine}.
  std::vector<std::string> gather_to_root(const std::string& mine) const;
  void barrier() const;     // collective; nothing with one rank
  static bool available();  // built with MPI

 private:
  int rank_ = 0, size_ = 1;
  bool initialised_ = false;
};

}  // namespace sonar3d
