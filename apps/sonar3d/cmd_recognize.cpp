#include <fmt/core.h>

#include <filesystem>
#include <fstream>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

namespace {

// MAP: a cloud (.ply), a map directory (merged.ply), or a dataset (reconstructed by carving).
PointCloud read_scene(const fs::path& map, double voxel_size, bool progress, double limit_bytes,
                      std::string* what) {
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
    ReconstructConfig o;
    o.progress = progress;
    o.voxel_size = voxel_size;
    // The carving's memory, estimated before it allocates (core/memory.hpp).
    const std::string warning = check_reconstruct_memory(ds, o, limit_bytes, "--voxel-size");
    if (!warning.empty()) print_warning(warning);
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
    std::string map, catalogue, output, mesh;
    bool overwrite = false;
    double voxel_size = 0.02;
    double max_memory_gb = 0;
    std::unique_ptr<ConfigOptions<RecognizeConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("map", o->map,
                  "point cloud (.ply, world frame), map directory (sonar3d map) or dataset")
      ->check(CLI::ExistingPath);
  cmd->add_option("--catalogue", o->catalogue, "catalogue YAML (docs/recognition.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "placements JSON to write");
  cmd->add_option("--mesh", o->mesh, "placed models as one PLY mesh (default: OUTPUT with .ply)");
  cmd->add_option("--voxel-size", o->voxel_size, "when MAP is a dataset: carving voxel edge, m")
      ->capture_default_str();
  // Every setting of both methods, from their one declaration (recog/recognize.hpp; the flags
  // and the YAML keys: docs/reference.md), with --print-config and --config.
  o->config = std::make_unique<ConfigOptions<RecognizeConfig>>(cmd);
  add_overwrite_flag(cmd, o->overwrite, "placements and mesh written by an earlier recognize");
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->callback([&run, &g, o, cmd] {
    // A flag of the 2D method that, given, also sets the 3D method's own default.
    const bool yaw_given = cmd->get_option("--yaw-step-deg")->count() > 0;
    const bool residual_given = cmd->get_option("--max-residual")->count() > 0;
    run = [o, &g, yaw_given, residual_given] {
      RecognizeConfig cfg = o->config->resolve("recognize");
      if (yaw_given) cfg.three_d.yaw_step_deg = cfg.two_d.search.yaw_step_deg;
      if (residual_given) cfg.three_d.max_residual_median_m = cfg.two_d.max_residual_median_m;
      cfg.validate();
      if (o->config->print_if_requested(cfg, "recognize", "recognize")) return 0;
      require(!o->map.empty(), "recognize: give MAP (a cloud, a map directory or a dataset)");
      require(!o->catalogue.empty(), "recognize: give --catalogue CATALOGUE.yaml");
      require(!o->output.empty(), "recognize: give -o PLACEMENTS.json");
      const bool three_d = cfg.method == "3d";
      // The output rule (core/output_dir.hpp): checked before the work; the placements and
      // their mesh appear together or not at all.
      RecognitionFiles files(o->output, o->mesh,
                             output_policy(o->overwrite, {o->map, o->catalogue}), "-o", "--mesh");
      const Catalogue cat = read_catalogue(o->catalogue);
      std::vector<ModelTemplate> models;
      for (const auto& m : cat.models) {
        models.push_back(
            make_catalogue_template(cat, m, three_d ? cfg.three_d.sampling : cfg.two_d.sampling));
      }
      std::string what;
      const double limit = memory_limit_bytes(o->max_memory_gb);
      const PointCloud scene = read_scene(o->map, o->voxel_size, !g.quiet, limit, &what);
      check_memory(estimate_recognition_memory(scene, models.size(), cfg), limit, "recognize");
      std::vector<Search3dRecord> searches3;
      const RecognitionResult r = recognize(scene, models, cfg, &searches3, !g.quiet);
      fmt::print("scene: {} ({} points); catalogue: {} models\n", what, scene.size(),
                 models.size());
      files.write(r, searches3, models, o->map, o->catalogue, cfg);
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
                 files.json_path().string(), files.mesh_path().string());
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
