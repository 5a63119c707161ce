#include "sonar3d/core/mpi.hpp"

#include <algorithm>
#include <cstdlib>
#include <limits>

#include "sonar3d/core/error.hpp"

#ifdef SONAR3D_HAVE_MPI
#include <mpi.h>
#endif

namespace sonar3d {

bool MpiSession::available() {
#ifdef SONAR3D_HAVE_MPI
  return true;
#else
  return false;
#endif
}

MpiSession::MpiSession() {
#ifdef SONAR3D_HAVE_MPI
  // Only when launched by a process manager: a plain run stays a single, MPI-free process.
  if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK")) {
    MPI_Init(nullptr, nullptr);
    initialised_ = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
#endif
}

MpiSession::~MpiSession() {
#ifdef SONAR3D_HAVE_MPI
  if (initialised_) MPI_Finalize();
#endif
}

std::vector<std::string> MpiSession::gather_to_root(const std::string& mine) const {
  if (!initialised_ || size_ == 1) return {mine};
#ifdef SONAR3D_HAVE_MPI
  // MPI counts are ints: 2 GiB or more cannot go in one message. Every rank still takes part in
  // both collectives (a rank that left them would hang the others); the error comes after.
  const long long limit = std::numeric_limits<int>::max();
  const bool fits = static_cast<long long>(mine.size()) < limit;
  int len = fits ? static_cast<int>(mine.size()) : -1;
  std::vector<int> lens(static_cast<std::size_t>(size_)), offs(static_cast<std::size_t>(size_));
  MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::string all;
  std::string error;
  if (rank_ == 0) {
    long long total = 0;
    for (int r = 0; r < size_; ++r) {
      if (lens[r] < 0 || total + lens[r] >= limit) {
        if (error.empty()) error = "MPI: rank " + std::to_string(r) + "'s results";
        lens[r] = 0;
      }
      offs[r] = static_cast<int>(total);
      total += lens[r];
    }
    all.resize(static_cast<std::size_t>(total));
  }
  MPI_Gatherv(mine.data(), std::max(len, 0), MPI_CHAR, all.data(), lens.data(), offs.data(),
              MPI_CHAR, 0, MPI_COMM_WORLD);
  require(fits, "MPI: rank " + std::to_string(rank_) + " has " + std::to_string(mine.size()) +
                    " bytes to send, more than one message carries (2 GiB): use more ranks");
  require(error.empty(), error +
                             " (with the others') exceed what one message carries (2 GiB): "
                             "use more ranks");
  std::vector<std::string> out;
  if (rank_ == 0) {
    for (int r = 0; r < size_; ++r) out.push_back(all.substr(offs[r], lens[r]));
  }
  return out;
#else
  return {mine};
#endif
}

void MpiSession::barrier() const {
#ifdef SONAR3D_HAVE_MPI
  if (initialised_ && size_ > 1) MPI_Barrier(MPI_COMM_WORLD);
#endif
}

}  // namespace sonar3d
