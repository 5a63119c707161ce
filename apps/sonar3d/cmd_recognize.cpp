#include <fmt/core.h>

#include <filesystem>
#include <fstream>
#include <memory>

#include "commands.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

namespace {

// Whether `path` starts with `prefix` (an output sonar3d wrote has a recognisable header).
bool file_starts_with(const fs::path& path, const std::string& prefix, std::size_t scan = 4096) {
  std::ifstream f(path, std::ios::binary);
  std::string head(scan, '\0');
  f.read(head.data(), static_cast<std::streamsize>(scan));
  head.resize(static_cast<std::size_t>(f.gcount()));
  return head.find(prefix) != std::string::npos;
}

void check_replaceable(const fs::path& path, bool overwrite, const std::string& marker) {
  if (!fs::exists(path)) return;
  if (!overwrite) {
    throw Error("'" + path.string() +
                "' exists: pass --overwrite to replace it, or choose another -o");
  }
  if (!fs::is_regular_file(path) || !file_starts_with(path, marker)) {
    throw Error("'" + path.string() +
                "' exists and was not written by sonar3d recognize: choose another -o");
  }
}

// MAP: a cloud (.ply), a map directory (merged.ply), or a dataset (reconstructed by carving).
PointCloud read_scene(const fs::path& map, double voxel_size, bool progress, std::string* what) {
  if (fs::is_regular_file(map)) {
    *what = "cloud";
    return read_ply(map.string());
  }
  if (fs::is_directory(map) && fs::is_regular_file(map / "merged.ply")) {
    *what = "field map (merged.ply)";
    return read_ply((map / "merged.ply").string());
  }
  if (fs::is_directory(map) && fs::is_regular_file(map / "sonar.yaml")) {
    *what = "dataset, carved";
    const Dataset ds = read_dataset(map);
    ReconstructOptions o;
    o.progress = progress;
    o.carve.voxel_size = voxel_size;
    return reconstruct_dataset(ds, o).cloud;
  }
  throw Error("'" + map.string() +
              "' is neither a point cloud (.ply), a map directory (sonar3d map: merged.ply) nor "
              "a dataset (sonar.yaml)");
}

}  // namespace

void add_recognize(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "recognize",
      "Find the CAD models of a catalogue in a map and place them in 6D (thesis sec. 6.3.2): "
      "ring-histogram descriptors on the elevation map, exhaustive 4D search (eq. 6.9), trimmed "
      "ICP. Writes the placements as JSON and the placed models as one PLY mesh.");
  struct Opts {
    std::string map, catalogue, output, mesh, method = "2d";
    RecognitionConfig cfg;
    bool overwrite = false, no_icp = false;
    double voxel_size = 0.02;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("map", o->map,
                  "point cloud (.ply, world frame), map directory (sonar3d map) or dataset")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--catalogue", o->catalogue, "catalogue YAML (docs/recognition.md)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "placements JSON to write")->required();
  cmd->add_option("--mesh", o->mesh, "placed models as one PLY mesh (default: OUTPUT with .ply)");
  cmd->add_option("--method", o->method,
                  "2d: elevation-map recognition (sec. 6.3.2); the 3D method of sec. 6.3.1 is "
                  "not built")
      ->check(CLI::IsMember({"2d"}))
      ->capture_default_str();
  cmd->add_option("--map-cell", o->cfg.map_cell_m, "fine elevation map cell (registration), m")
      ->capture_default_str();
  cmd->add_option("--recog-cell", o->cfg.recog_cell_m, "scan cell Δ_NE, m")->capture_default_str();
  cmd->add_option("--period", o->cfg.scan.period_m, "candidate patch period T_NE, m")
      ->capture_default_str();
  cmd->add_option("--ring-width", o->cfg.descriptor.ring_width_m, "descriptor ring width, m")
      ->capture_default_str();
  cmd->add_option("--bin", o->cfg.descriptor.bin_m, "histogram depth resolution, m")
      ->capture_default_str();
  cmd->add_option("--min-valid-fraction", o->cfg.descriptor.min_valid_fraction,
                  "score a patch only when each ring has at least this fraction of its cells "
                  "observed")
      ->capture_default_str();
  cmd->add_option("--voxel-size", o->voxel_size, "when MAP is a dataset: carving voxel edge, m")
      ->capture_default_str();
  cmd->add_option("--yaw-step-deg", o->cfg.search.yaw_step_deg, "4D search yaw step, degrees")
      ->capture_default_str();
  cmd->add_option("--max-relative-score", o->cfg.max_relative_score,
                  "accept patches scoring at most this times the model's height")
      ->capture_default_str();
  cmd->add_option("--max-residual", o->cfg.max_residual_median_m,
                  "accept placements whose residual median is at most this, m")
      ->capture_default_str();
  cmd->add_option("--min-support", o->cfg.min_support,
                  "accept placements whose footprint agrees with the map on at least this "
                  "fraction of its observed cells")
      ->capture_default_str();
  cmd->add_flag("--no-icp", o->no_icp, "stop after the 4D search (step 1 of Table 6.1)");
  cmd->add_option("--threads", o->cfg.num_threads, "worker threads (0 = all cores)")
      ->capture_default_str();
  add_overwrite_flag(cmd, o->overwrite, "placements and mesh written by an earlier recognize");
  cmd->callback([&run, &g, o] {
    run = [o, &g] {
      RecognitionConfig cfg = o->cfg;
      cfg.run_icp = !o->no_icp;
      cfg.scan.num_threads = cfg.num_threads;
      cfg.validate();
      const fs::path json_path = o->output;
      const fs::path mesh_path =
          o->mesh.empty() ? fs::path(json_path).replace_extension(".ply") : fs::path(o->mesh);
      require(fs::path(mesh_path).extension() == ".ply", "--mesh: give a .ply path");
      require(fs::absolute(json_path) != fs::absolute(mesh_path),
              "-o and --mesh name the same file");
      check_replaceable(json_path, o->overwrite, "\"format\": \"sonar3d-placements\"");
      check_replaceable(mesh_path, o->overwrite, "comment sonar3d mesh");
      const Catalogue cat = read_catalogue(o->catalogue);
      std::vector<ModelTemplate> models;
      for (const auto& m : cat.models) {
        models.push_back(make_model_template(m.name, load_catalogue_mesh(cat, m), m.symmetry,
                                             m.expected, cfg.sampling));
      }
      std::string what;
      const PointCloud scene = read_scene(o->map, o->voxel_size, !g.quiet, &what);
      const RecognitionResult r = recognize_2d(scene, models, cfg, !g.quiet);
      fmt::print("scene: {} ({} points); catalogue: {} models\n", what, scene.size(),
                 models.size());
      // Mesh first, JSON last: a placements file always has its mesh beside it.
      save_mesh(mesh_path.string(), placed_models_mesh(models, r.placements));
      write_text_file(json_path.string(), placements_json(r, o->map, o->catalogue, cfg));
      for (const Placement& p : r.placements) {
        const Eigen::Vector3d t = p.T_world_model.translation();
        const Eigen::Matrix3d R = p.T_world_model.linear();
        fmt::print(
            "  {}: at E {:.3f} N {:.3f} U {:.3f} m, yaw {:.1f} deg; score {:.3f} m; residual "
            "median {:.3f} m, mean {:.3f} m (4D step: {:.3f}, {:.3f}); support {:.2f}; {:.2f} s\n",
            p.model, t.x(), t.y(), t.z(), std::atan2(R(1, 0), R(0, 0)) * 180 / M_PI, p.score_m,
            p.residual.median_m, p.residual.mean_m, p.residual_4d.median_m, p.residual_4d.mean_m,
            p.support, p.seconds);
      }
      std::size_t rejected = 0;
      for (const auto& s : r.searches) rejected += !s.accepted && s.scan.found;
      fmt::print("{} placements ({} candidates rejected) in {:.2f} s -> {}, {}\n",
                 r.placements.size(), rejected, r.seconds, json_path.string(), mesh_path.string());
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
