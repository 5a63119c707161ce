#include "sonar3d/plan/mpi.hpp"

#include <cstdlib>
#include <string>

#include "sonar3d/core/error.hpp"

#ifdef SONAR3D_HAVE_MPI
#include <mpi.h>

#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#endif

namespace fs = std::filesystem;

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

void MpiSession::gather_points(const Sweep& sweep, const fs::path& out_dir) {
#ifdef SONAR3D_HAVE_MPI
  if (!initialised_ || size_ == 1) return;
  // Each rank packs the result files of its own points (round-robin by index).
  nlohmann::json mine = nlohmann::json::array();
  for (std::size_t i = rank_; i < sweep.size(); i += size_) {
    const fs::path dir = out_dir / "points" / point_id(i);
    nlohmann::json item = {{"id", point_id(i)}};
    for (const char* f : {"status.json", "metrics.json"}) {
      if (fs::exists(dir / f)) item[f] = read_text_file((dir / f).string());
    }
    mine.push_back(item);
  }
  const std::string text = mine.dump();
  int len = static_cast<int>(text.size());
  std::vector<int> lens(size_), offs(size_);
  MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::string all;
  if (rank_ == 0) {
    int total = 0;
    for (int r = 0; r < size_; ++r) {
      offs[r] = total;
      total += lens[r];
    }
    all.resize(total);
  }
  MPI_Gatherv(text.data(), len, MPI_CHAR, all.data(), lens.data(), offs.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
  if (rank_ == 0) {
    for (int r = 1; r < size_; ++r) {
      const auto items = nlohmann::json::parse(all.substr(offs[r], lens[r]));
      for (const auto& item : items) {
        const fs::path dir = out_dir / "points" / item["id"].get<std::string>();
        fs::create_directories(dir);
        for (const char* f : {"status.json", "metrics.json"}) {
          if (item.contains(f)) write_text_file((dir / f).string(), item[f].get<std::string>());
        }
      }
    }
  }
  MPI_Barrier(MPI_COMM_WORLD);
#else
  (void)sweep;
  (void)out_dir;
#endif
}

}  // namespace sonar3d
