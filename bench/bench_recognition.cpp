// CAD-model recognition measured against the truth of a simulated scene (docs/recognition.md):
//   bench_recognition SCENE.yaml MAP CATALOGUE.yaml [--no-icp] [--method 2d|3d] [--no-upright]
//                     [--label TEXT]
// MAP: a cloud (.ply) or a map directory (merged.ply) made from the scene's simulated survey.
// Scene objects are matched to placements by name (a catalogue model named like the object; an
// object "NAME@2" is a second instance of model NAME) and position (centres within --match-m,
// default 0.75 m). Prints one Markdown row per truth object and
// per false detection: pose error (cm, degrees, yaw modulo the object's own rotational symmetry),
// the residual median/mean after the 4D search and after ICP (Table 6.1), the same metric at the
// true pose (what the reconstruction itself leaves), then precision, recall, time and peak memory.
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognition_3d.hpp"

using namespace sonar3d;
namespace fs = std::filesystem;

namespace {

struct Truth {
  std::string name;   // the scene object's name
  std::string model;  // the catalogue model it is an instance of: the name up to an '@'
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  bool matched = false;
};

double peak_rss_mb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0;
}

// Rotational symmetry period of the reference objects about z, radians (0: any yaw).
double yaw_period(const std::string& name) {
  if (name.find("pillar") != std::string::npos) return M_PI / 2;
  if (name.find("riser") != std::string::npos) return M_PI;
  if (name.find("tank") != std::string::npos || name.find("sphere") != std::string::npos) return 0;
  return 2 * M_PI;
}

double yaw_of(const Eigen::Isometry3d& T) { return std::atan2(T.linear()(1, 0), T.linear()(0, 0)); }

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(
        stderr,
        "usage: %s SCENE.yaml MAP CATALOGUE.yaml [--no-icp] [--method 2d|3d] [--no-upright] "
        "[--max-relief-proposals N] [--label TEXT] [--match-m M]\n",
        argv[0]);
    return 2;
  }
  try {
    RecognitionConfig cfg;
    Recognition3dConfig cfg3;
    std::string label = argv[1], method = "2d";
    double match_m = 0.75;
    for (int i = 4; i < argc; ++i) {
      if (!std::strcmp(argv[i], "--no-icp")) cfg.run_icp = false;
      if (!std::strcmp(argv[i], "--no-upright")) cfg3.upright = false;
      if (!std::strcmp(argv[i], "--method") && i + 1 < argc) method = argv[++i];
      if (!std::strcmp(argv[i], "--max-residual-3d") && i + 1 < argc) {
        cfg3.max_residual_median_m = std::atof(argv[++i]);
      }
      if (!std::strcmp(argv[i], "--min-coverage") && i + 1 < argc) {
        cfg3.min_coverage = std::atof(argv[++i]);
      }
      if (!std::strcmp(argv[i], "--max-relief-proposals") && i + 1 < argc) {
        cfg.max_relief_proposals = std::atoi(argv[++i]);
      }
      if (!std::strcmp(argv[i], "--label") && i + 1 < argc) label = argv[++i];
      if (!std::strcmp(argv[i], "--match-m") && i + 1 < argc) match_m = std::atof(argv[++i]);
    }
    const std::string scene_path = argv[1];
    const YAML::Node scene = yaml::load_file(scene_path);
    std::vector<Truth> truth;
    for (const auto& o : scene["objects"]) {
      if (!o["pose"] || !(o["reference"] || o["mesh"])) continue;
      Truth t;
      t.name = o["name"].as<std::string>();
      t.model = t.name.substr(0, t.name.find('@'));
      t.T = yaml::get_pose(o["pose"], scene_path, "pose");
      truth.push_back(t);
    }
    const Catalogue cat = read_catalogue(argv[3]);
    std::vector<ModelTemplate> models;
    for (const auto& m : cat.models) {
      models.push_back(make_catalogue_template(cat, m, cfg.sampling));
    }
    fs::path map = argv[2];
    if (fs::is_directory(map)) map /= "merged.ply";
    const PointCloud cloud = read_ply(map.string());
    const auto t0 = std::chrono::steady_clock::now();
    require(method == "2d" || method == "3d", "--method: 2d or 3d");
    std::vector<Search3dRecord> searches3;
    const RecognitionResult r = method == "3d" ? recognize_3d(cloud, models, cfg3, &searches3)
                                               : recognize_2d(cloud, models, cfg, false);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    auto model_of = [&](const std::string& name) -> const ModelTemplate* {
      for (const auto& m : models) {
        if (m.name == name) return &m;
      }
      return nullptr;
    };
    std::printf("\n%s: %zu points, %zu models, %zu placements, %.1f s, peak RSS %.0f MB\n\n",
                label.c_str(), cloud.size(), models.size(), r.placements.size(), seconds,
                peak_rss_mb());
    std::printf(
        "| object | found | position error cm (horizontal) | yaw error deg | tilt deg | step 1 "
        "median (mean) cm "
        "| "
        "step 2 median (mean) cm | at true pose median (mean) cm | support | time s |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n");
    int tp = 0, fp = 0;
    std::vector<bool> used(r.placements.size(), false);
    for (Truth& t : truth) {
      const ModelTemplate* m = model_of(t.model);
      if (!m) continue;  // not in the catalogue (seabed, pipelines)
      const Eigen::Vector3d c(m->center_xy.x(), m->center_xy.y(), 0.5 * (m->base_z + m->top_z));
      int best = -1;
      double best_d = match_m;
      for (std::size_t k = 0; k < r.placements.size(); ++k) {
        const Placement& p = r.placements[k];
        if (used[k] || p.model != t.model) continue;
        const double d = (p.T_world_model * c - t.T * c).head<2>().norm();
        if (d < best_d) best = static_cast<int>(k), best_d = d;
      }
      // The metric at the true pose, on the points above the local seabed.
      double ground = best >= 0 ? r.placements[best].ground_z : t.T.translation().z();
      if (!std::isfinite(ground)) ground = t.T.translation().z();
      std::vector<Eigen::Vector3f> near;
      const Eigen::Vector3d ct = t.T * c;
      for (const auto& q : cloud.points) {
        if ((q.head<2>().cast<double>() - ct.head<2>()).norm() < m->radius_m + 0.3 &&
            q.z() > ground + cfg.ground_clearance_m) {
          near.push_back(q);
        }
      }
      const Residual at_truth = structure_residual(near, *m, t.T);
      if (best < 0) {
        std::printf("| %s | no | | | | | | %.1f (%.1f) | | |\n", t.name.c_str(),
                    100 * at_truth.median_m, 100 * at_truth.mean_m);
        continue;
      }
      used[best] = true;
      ++tp;
      const Placement& p = r.placements[best];
      // The catalogue's symmetry where it declares one, else the reference objects' own.
      double period = yaw_period(t.model);
      for (const auto& cm : cat.models) {
        if (cm.name != t.model) continue;
        if (cm.symmetry == Symmetry::Half) period = std::min(period, M_PI);
        if (cm.symmetry == Symmetry::Full) period = 0;
      }
      const double yaw_err =
          period > 0
              ? std::abs(std::remainder(yaw_of(p.T_world_model) - yaw_of(t.T), period)) * 180 / M_PI
              : std::nan("");
      const double tilt =
          std::acos(
              std::clamp((p.T_world_model.linear().col(2)).dot(t.T.linear().col(2)), -1.0, 1.0)) *
          180 / M_PI;
      std::printf(
          "| %s | yes | %.1f (%.1f) | %.1f | %.1f | %.1f (%.1f) | %.1f (%.1f) | %.1f (%.1f) | %.2f "
          "| %.2f "
          "|\n",
          t.name.c_str(), 100 * (p.T_world_model * c - t.T * c).norm(),
          100 * (p.T_world_model * c - t.T * c).head<2>().norm(), yaw_err, tilt,
          100 * p.residual_4d.median_m, 100 * p.residual_4d.mean_m, 100 * p.residual.median_m,
          100 * p.residual.mean_m, 100 * at_truth.median_m, 100 * at_truth.mean_m, p.support,
          p.seconds);
    }
    for (std::size_t k = 0; k < r.placements.size(); ++k) {
      if (used[k]) continue;
      ++fp;
      const Placement& p = r.placements[k];
      const Eigen::Vector3d t = p.T_world_model.translation();
      std::printf(
          "| %s (false) | at (%.2f, %.2f, %.2f) | | | | %.1f (%.1f) | %.1f (%.1f) | | %.2f "
          "| %.2f |\n",
          p.model.c_str(), t.x(), t.y(), t.z(), 100 * p.residual_4d.median_m,
          100 * p.residual_4d.mean_m, 100 * p.residual.median_m, 100 * p.residual.mean_m, p.support,
          p.seconds);
    }
    int n_truth = 0;
    for (const Truth& t : truth) n_truth += model_of(t.model) != nullptr;
    std::printf("\nprecision %d/%d, recall %d/%d; maps %.2f s, total %.1f s; peak RSS %.0f MB\n",
                tp, tp + fp, tp, n_truth, r.seconds_maps, seconds, peak_rss_mb());
    for (const auto& s : r.searches) {
      std::printf("  search %s: %s%s (scan %.2f s, %zu candidates, %zu aborted early)\n",
                  s.model.c_str(), s.accepted ? "accepted" : "rejected: ", s.reason.c_str(),
                  s.scan.seconds, s.scan.candidates, s.scan.aborted);
    }
    for (const auto& s : searches3) {
      std::printf(
          "  search %s (3d): %zu subspaces (r %.2f m, T %.2f m), failed fit %zu, volume %zu, "
          "points %zu, occupancy %zu; %zu kept, %zu matched, %zu passed, %zu accepted (subspaces "
          "%.2f s, matching %.2f s); nearest miss: coverage %.2f, residual median %.1f cm\n",
          s.model.c_str(), s.subspaces, s.r_subspace_m, s.period_m, s.failed[1], s.failed[2],
          s.failed[3], s.failed[4], s.kept, s.registered, s.passed, s.accepted, s.seconds_subspaces,
          s.seconds_matching, s.best_rejected_coverage, 100 * s.best_rejected_residual_m);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_recognition: error: %s\n", e.what());
    return 1;
  }
}
