#include "sonar3d/plan/mpi.hpp"

#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

void gather_points(const MpiSession& mpi, const Sweep& sweep, const fs::path& out_dir) {
  if (mpi.size() == 1) return;
  // Each rank packs the result files of its own points (round-robin by index).
  nlohmann::json mine = nlohmann::json::array();
  for (std::size_t i = static_cast<std::size_t>(mpi.rank()); i < sweep.size();
       i += static_cast<std::size_t>(mpi.size())) {
    const fs::path dir = out_dir / "points" / point_id(i);
    nlohmann::json item = {{"id", point_id(i)}};
    for (const char* f : {"status.json", "metrics.json"}) {
      if (fs::exists(dir / f)) item[f] = read_text_file((dir / f).string());
    }
    mine.push_back(item);
  }
  const std::vector<std::string> all = mpi.gather_to_root(mine.dump());
  if (mpi.rank() == 0) {
    for (std::size_t r = 1; r < all.size(); ++r) {
      for (const auto& item : nlohmann::json::parse(all[r])) {
        const fs::path dir = out_dir / "points" / item["id"].get<std::string>();
        fs::create_directories(dir);
        for (const char* f : {"status.json", "metrics.json"}) {
          if (item.contains(f)) write_text_file((dir / f).string(), item[f].get<std::string>());
        }
      }
    }
  }
  mpi.barrier();
}

}  // namespace sonar3d
