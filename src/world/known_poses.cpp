// Known structure poses for the map's adjustment (include/sonar3d/world/known_poses.hpp).
#include "sonar3d/world/known_poses.hpp"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

std::vector<KnownStructurePose> read_known_poses(const std::string& path) {
  std::vector<KnownStructurePose> out;
  const fs::path graph = fs::path(path) / "graph.json";
  if (!fs::is_directory(path)) {
    const PlacementsFile f = read_placements(path);
    std::vector<std::string> seen;
    for (const PlacementRecord& p : f.placements) {
      int n = 0;
      for (const std::string& m : seen) n += m == p.model;
      seen.push_back(p.model);
      out.push_back({p.model, p.model + "_" + std::to_string(n), p.T_world_model.translation()});
    }
    return out;
  }
  require(fs::is_regular_file(graph), "--known-poses: '" + path +
                                          "' is a directory without graph.json: give a world "
                                          "model directory (sonar3d world) or a placements JSON");
  std::error_code ec;
  const auto bytes = fs::file_size(graph, ec);
  require(!ec && bytes <= (256u << 20), "--known-poses: " + graph.string() +
                                            " is not a world model's graph.json (unreadable or "
                                            "larger than 256 MB)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_text_file(graph.string()));
  } catch (const nlohmann::json::exception& e) {
    throw Error("--known-poses: " + graph.string() + " is not JSON: " + e.what());
  }
  require(j.is_object() && j.value("format", "") == "sonar3d-world" && j.contains("objects") &&
              j["objects"].is_array(),
          "--known-poses: " + graph.string() + " is not a sonar3d-world graph with 'objects'");
  for (std::size_t k = 0; k < j["objects"].size(); ++k) {
    const nlohmann::json& o = j["objects"][k];
    const std::string at = graph.string() + ": objects[" + std::to_string(k) + "]";
    require(o.is_object() && o.contains("model") && o["model"].is_string() &&
                o.contains("T_world_model") && o["T_world_model"].is_array() &&
                o["T_world_model"].size() == 16,
            at + ": needs 'model' and 'T_world_model' (16 numbers, row-major)");
    if (o.contains("confirmed") && o["confirmed"].is_boolean() && !o["confirmed"].get<bool>()) {
      continue;  // below the world's confidence threshold: not one of its structures
    }
    Eigen::Vector3d t;
    for (int r = 0; r < 3; ++r) {
      const nlohmann::json& v = o["T_world_model"][static_cast<std::size_t>(4 * r + 3)];
      require(v.is_number() && std::isfinite(v.get<double>()),
              at + ": T_world_model holds a value that is not a finite number");
      t[r] = v.get<double>();
    }
    const std::string id =
        o.contains("id") && o["id"].is_string() ? o["id"].get<std::string>() : std::string();
    out.push_back({o["model"].get<std::string>(), id, t});
  }
  return out;
}

std::string placements_navigation(const PlacementsFile& f, const std::string& given) {
  if (!given.empty()) return given;
  std::vector<fs::path> candidates;
  if (!f.map.empty()) {
    for (const fs::path& base : {fs::path(), fs::path(f.path).parent_path()}) {
      const fs::path m = base / f.map;
      candidates.push_back(m / "navigation_corrected.tum");
      candidates.push_back(m.parent_path() / "navigation_corrected.tum");
    }
  }
  for (const fs::path& c : candidates) {
    if (fs::is_regular_file(c)) return c.string();
  }
  throw Error("--placements: '" + f.path + "' names the map '" + f.map +
              "', where no navigation_corrected.tum was found: give --placements-nav (the "
              "navigation_corrected.tum of the map the structures were recognised in)");
}

void load_known_pose_inputs(MapSurveyConfig& config, const std::string& known_poses,
                            const std::string& placements, const std::string& placements_nav) {
  config.known_poses = read_known_poses(known_poses);
  config.known_poses_source = known_poses;
  const PlacementsFile f = read_placements(placements);
  config.recognised.clear();
  for (std::size_t k = 0; k < f.placements.size(); ++k) {
    config.recognised.push_back(
        {f.placements[k].model, f.placements[k].T_world_model.translation(), static_cast<int>(k)});
  }
  config.recognised_source = placements;
  config.recognised_navigation = read_tum(placements_navigation(f, placements_nav));
}

}  // namespace sonar3d
