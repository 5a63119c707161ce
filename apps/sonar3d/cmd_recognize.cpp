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
#include "sonar3d/recog/recognition_3d.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

namespace {

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
      "Find the CAD models of a catalogue in a map and place them in 6D (thesis sec. 6.3). "
      "--method 2d (sec. 6.3.2): ring-histogram descriptors on the elevation map, exhaustive 4D "
      "search (eq. 6.9), trimmed ICP. --method 3d (sec. 6.3.1): spherical subspaces (eq. 6.3) "
      "filtered by eq. 6.4-6.7, yaw sweep + trimmed ICP in each (global registration with "
      "--no-upright). Writes the placements as JSON and the placed models as one PLY mesh.");
  struct Opts {
    std::string map, catalogue, output, mesh, method = "2d";
    RecognitionConfig cfg;
    Recognition3dConfig cfg3;
    bool overwrite = false, no_icp = false, no_upright = false;
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
                  "2d: elevation-map recognition (sec. 6.3.2); 3d: subspaces and direct 3D "
                  "matching (sec. 6.3.1)")
      ->check(CLI::IsMember({"2d", "3d"}))
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
  auto* yaw_opt = cmd->add_option("--yaw-step-deg", o->cfg.search.yaw_step_deg,
                                  "yaw step, degrees: 4D search (2d; default 5) or yaw sweep (3d; "
                                  "default 15)");
  cmd->add_option("--max-relative-score", o->cfg.max_relative_score,
                  "accept patches scoring at most this times the model's height")
      ->capture_default_str();
  auto* residual_opt =
      cmd->add_option("--max-residual", o->cfg.max_residual_median_m,
                      "accept placements whose residual median is at most this, m (2d default "
                      "0.1, 3d default 0.04)");
  cmd->add_option("--min-confidence", o->cfg.verification.min_confidence,
                  "a candidate is found at or above this calibrated confidence, 0-1 "
                  "(docs/recognition.md, Verification)")
      ->capture_default_str();
  cmd->add_option("--max-rejections", o->cfg.max_rejections,
                  "2d: rejected scan candidates per model before its scan gives up")
      ->capture_default_str();
  cmd->add_option("--max-relief-proposals", o->cfg.max_relief_proposals,
                  "2d: then at most this many blobs of relief that fit the model are tried "
                  "(partly buried or small structures the scan ranks low; 0: none, the default; "
                  "docs/recognition.md)")
      ->capture_default_str();
  cmd->add_option("--relief-window", o->cfg.relief_window_m,
                  "2d: seabed window of the relief proposals, m (models wider are left to the "
                  "scan)")
      ->capture_default_str();
  cmd->add_flag("--no-icp", o->no_icp, "2d: stop after the 4D search (step 1 of Table 6.1)");
  // The 3D method (Recognition3dConfig).
  Recognition3dConfig& c3 = o->cfg3;
  cmd->add_option("--subsample", c3.voxel_m, "3d: model and scene subsampling voxel, m")
      ->capture_default_str();
  cmd->add_option("--period-fraction", c3.period_fraction,
                  "3d: subspace grid period T as a fraction of r_model (eq. 6.3)")
      ->capture_default_str();
  cmd->add_option("--alpha-fit", c3.alpha_fit, "3d: OBB fit margin (eq. 6.4)")
      ->capture_default_str();
  cmd->add_option("--alpha-volume", c3.alpha_volume, "3d: volume margin (eq. 6.5)")
      ->capture_default_str();
  cmd->add_option("--n-min", c3.n_min, "3d: minimum points per subspace (eq. 6.6)")
      ->capture_default_str();
  cmd->add_option("--alpha-occupancy", c3.alpha_occupancy, "3d: occupancy margin (eq. 6.7)")
      ->capture_default_str();
  cmd->add_option("--occupancy-voxel", c3.occupancy_voxel_m, "3d: occupancy voxel edge, m")
      ->capture_default_str();
  cmd->add_option("--seabed-clearance", c3.seabed_clearance_m,
                  "3d: drop points lower than the local seabed plus this, m (0: keep the seabed)")
      ->capture_default_str();
  cmd->add_option("--min-coverage", c3.min_coverage,
                  "3d: a placement must have a scene point near at least this fraction of the "
                  "model's samples seen from above, and keep it after suppression, 0-1")
      ->capture_default_str();
  cmd->add_option("--max-subspaces", c3.max_subspaces,
                  "3d: at most this many subspaces per model (the grid period is raised until "
                  "they fit)")
      ->capture_default_str();
  cmd->add_option("--starts", c3.starts, "3d: ICP starts per subspace")->capture_default_str();
  cmd->add_flag("--no-upright", o->no_upright,
                "3d: no orientation prior: global registration in each subspace instead of the "
                "yaw sweep (slower)");
  cmd->add_option("--threads", o->cfg.num_threads, "worker threads (0 = all cores)")
      ->capture_default_str();
  add_overwrite_flag(cmd, o->overwrite, "placements and mesh written by an earlier recognize");
  cmd->callback([&run, &g, o, yaw_opt, residual_opt] {
    const bool yaw_given = yaw_opt->count() > 0, residual_given = residual_opt->count() > 0;
    run = [o, &g, yaw_given, residual_given] {
      RecognitionConfig cfg = o->cfg;
      cfg.run_icp = !o->no_icp;
      cfg.scan.num_threads = cfg.num_threads;
      cfg.validate();
      Recognition3dConfig cfg3 = o->cfg3;
      cfg3.upright = !o->no_upright;
      cfg3.num_threads = cfg.num_threads;
      cfg3.verification = cfg.verification;  // one --min-confidence for both methods
      if (yaw_given) cfg3.yaw_step_deg = cfg.search.yaw_step_deg;
      if (residual_given) cfg3.max_residual_median_m = cfg.max_residual_median_m;
      const bool three_d = o->method == "3d";
      if (three_d) cfg3.validate();
      const fs::path json_path = o->output;
      const fs::path mesh_path =
          o->mesh.empty() ? fs::path(json_path).replace_extension(".ply") : fs::path(o->mesh);
      require(fs::path(mesh_path).extension() == ".ply", "--mesh: give a .ply path");
      // The output rule (core/output_dir.hpp): checked before the work; the placements and
      // their mesh appear together or not at all.
      OutputFiles out(output_policy(o->overwrite, {o->map, o->catalogue}));
      const fs::path json_tmp = out.add(json_path, OutputKind::PlacementsJson, "-o");
      const fs::path mesh_tmp =
          out.add(mesh_path, OutputKind::Mesh, o->mesh.empty() ? "-o, its .ply" : "--mesh");
      const Catalogue cat = read_catalogue(o->catalogue);
      std::vector<ModelTemplate> models;
      for (const auto& m : cat.models) {
        models.push_back(make_catalogue_template(cat, m, cfg.sampling));
      }
      std::string what;
      const PointCloud scene = read_scene(o->map, o->voxel_size, !g.quiet, &what);
      std::vector<Search3dRecord> searches3;
      const RecognitionResult r = three_d ? recognize_3d(scene, models, cfg3, &searches3, !g.quiet)
                                          : recognize_2d(scene, models, cfg, !g.quiet);
      fmt::print("scene: {} ({} points); catalogue: {} models\n", what, scene.size(),
                 models.size());
      save_mesh(mesh_tmp.string(), placed_models_mesh(models, r.placements));
      write_text_file(json_tmp.string(),
                      three_d ? placements_json_3d(r, searches3, o->map, o->catalogue, cfg3)
                              : placements_json(r, o->map, o->catalogue, cfg));
      out.commit();
      for (const Placement& p : r.placements) {
        const Eigen::Vector3d t = p.T_world_model.translation();
        const Eigen::Matrix3d R = p.T_world_model.linear();
        fmt::print(
            "  {}: at E {:.3f} N {:.3f} U {:.3f} m, yaw {:.1f} deg, scale {:.3f}; score {:.3f} m; "
            "residual median {:.3f} m, mean {:.3f} m (step 1: {:.3f}, {:.3f}); {}; {:.2f} s\n",
            p.model, t.x(), t.y(), t.z(), std::atan2(R(1, 0), R(0, 0)) * 180 / M_PI, p.scale,
            p.score_m, p.residual.median_m, p.residual.mean_m, p.residual_4d.median_m,
            p.residual_4d.mean_m,
            three_d ? fmt::format("coverage {:.2f}", p.support)
                    : fmt::format("confidence {:.2f} (seen {:.2f}, explained {:.2f}, violation "
                                  "{:.2f}, unexplained {:.2f})",
                                  p.confidence, p.verification.seen, p.verification.explained,
                                  p.verification.violation, p.verification.unexplained) +
                          (p.yaw_ambiguous ? "; yaw ambiguous: turned 180 deg fits as well" : ""),
            p.seconds);
      }
      std::size_t rejected = 0;
      for (const auto& s : r.searches) rejected += !s.accepted && s.scan.found;
      for (const auto& s : searches3) {
        fmt::print(
            "  {}: {} subspaces of radius {:.2f} m, {} kept by eq. 6.4-6.7, {} matched, {} "
            "passed, {} accepted, {} suppressed ({:.2f} s subspaces, {:.2f} s matching)\n",
            s.model, s.subspaces, s.r_subspace_m, s.kept, s.registered, s.passed, s.accepted,
            s.suppressed, s.seconds_subspaces, s.seconds_matching);
        if (!s.nearest_miss.empty()) fmt::print("    nearest miss: {}\n", s.nearest_miss);
      }
      fmt::print("{} placements{} in {:.2f} s -> {}, {}\n", r.placements.size(),
                 three_d ? "" : fmt::format(" ({} candidates rejected)", rejected), r.seconds,
                 json_path.string(), mesh_path.string());
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
