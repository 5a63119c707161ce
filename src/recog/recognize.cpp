#include "sonar3d/recog/recognize.hpp"

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

Recognition3dConfig RecognizeConfig::effective_3d() const {
  Recognition3dConfig c = three_d;
  c.verification = two_d.verification;  // one --min-confidence for both methods
  c.num_threads = two_d.num_threads;
  return c;
}

void RecognizeConfig::validate() const {
  require(method == "2d" || method == "3d",
          "recognize: method (--method) must be '2d' or '3d', not '" + printable(method) + "'");
  if (method == "3d") {
    effective_3d().validate();
  } else {
    two_d.validate();
  }
}

RecognitionResult recognize(const PointCloud& scene_world, const std::vector<ModelTemplate>& models,
                            const RecognizeConfig& config, std::vector<Search3dRecord>* searches3,
                            bool progress) {
  config.validate();
  if (config.method == "3d") {
    return recognize_3d(scene_world, models, config.effective_3d(), searches3, progress);
  }
  RecognitionConfig c = config.two_d;
  c.scan.num_threads = c.num_threads;
  return recognize_2d(scene_world, models, c, progress);
}

std::string recognize_json(const RecognitionResult& result,
                           const std::vector<Search3dRecord>& searches3,
                           const std::string& map_source, const std::string& catalogue_source,
                           const RecognizeConfig& config) {
  if (config.method == "3d") {
    return placements_json_3d(result, searches3, map_source, catalogue_source,
                              config.effective_3d());
  }
  return placements_json(result, map_source, catalogue_source, config.two_d);
}

namespace {

// Cells of an elevation map of `scene_world` at `cell_m`, as elevation_map_from_points lays it
// out.
double map_cells(const PointCloud& scene_world, double cell_m) {
  ElevationMapConfig mc;
  mc.cell_m = cell_m;
  return elevation_map_cells(scene_world, mc);
}

}  // namespace

MemoryEstimate estimate_recognition_memory(const PointCloud& scene_world, std::size_t models,
                                           const RecognizeConfig& config) {
  config.validate();
  MemoryEstimate e;
  const double n = static_cast<double>(scene_world.size());
  if (config.method == "3d") {
    const Recognition3dConfig c = config.effective_3d();
    // recognize_3d: the fine map of the verification and its removal mask (float + byte a cell).
    const double fine = map_cells(scene_world, c.map_cell_m);
    e.add(
        grid_part("3D method: verification elevation map and its removal mask", fine, c.map_cell_m),
        fine * (sizeof(float) + 1), "three_d.map_cell_m (--config)");
    // The top map of what the survey saw (make_top_map: a float a cell at voxel_m).
    const double top = map_cells(scene_world, c.voxel_m);
    e.add(grid_part("3D method: top map of the observed surface", top, c.voxel_m),
          top * sizeof(float), "--subsample");
    // The scene's working copies: all points (12 B), those above the seabed and subsampled, with
    // normals in the search index (12 + 12 B and the index's ~8 B a point): at most the cloud.
    e.add("3D method: working copies and index of the scene's points", n * (12 + 32));
    // Subspace centres with their verdicts (12 + 2 B), bounded by max_subspaces per model.
    e.add("3D method: subspace centres (at most max_subspaces)",
          static_cast<double>(c.max_subspaces) * 14, "three_d.max_subspaces (--config)");
    return e;
  }
  const RecognitionConfig& c = config.two_d;
  // recognize_2d: the fine map (registration, support), its live copy, its levelled copy
  // (floats) and its removal mask (a byte).
  const double fine = map_cells(scene_world, c.map_cell_m);
  e.add(grid_part("2D method: fine elevation maps (the map, its live and levelled copies, the "
                  "removal mask)",
                  fine, c.map_cell_m),
        fine * (3 * sizeof(float) + 1), "--map-cell");
  // The coarse map (Δ_NE), its live and levelled copies, the relief image and the blob labels
  // (4 B each), its removal mask and one exclusion mask per model (a byte each), the point grid's
  // cell starts (8 B, twice while it is built).
  const double coarse = map_cells(scene_world, c.recog_cell_m);
  e.add(grid_part("2D method: coarse maps (copies, relief, labels, masks, point grid)", coarse,
                  c.recog_cell_m),
        coarse * (5 * 4.0 + 1 + static_cast<double>(models) + 16), "--recog-cell");
  // The point grid: a cell number (8 B) while it is built, an index (4 B) a point.
  e.add("2D method: point grid over the scene's points", n * 12);
  return e;
}

RecognitionFiles::RecognitionFiles(const std::filesystem::path& json_path,
                                   std::filesystem::path mesh_path, const OutputPolicy& policy,
                                   const std::string& json_flag, const std::string& mesh_flag)
    : json_(json_path), mesh_(std::move(mesh_path)) {
  const bool mesh_given = !mesh_.empty();
  if (!mesh_given) mesh_ = std::filesystem::path(json_).replace_extension(".ply");
  require(mesh_.extension() == ".ply", mesh_flag + ": give a .ply path");
  out_ = std::make_unique<OutputFiles>(policy);
  json_tmp_ = out_->add(json_, OutputKind::PlacementsJson, json_flag);
  mesh_tmp_ = out_->add(mesh_, OutputKind::Mesh, mesh_given ? mesh_flag : json_flag + ", its .ply");
}

void RecognitionFiles::write(const RecognitionResult& result,
                             const std::vector<Search3dRecord>& searches3,
                             const std::vector<ModelTemplate>& models,
                             const std::string& map_source, const std::string& catalogue_source,
                             const RecognizeConfig& config) {
  save_mesh(mesh_tmp_.string(), placed_models_mesh(models, result.placements));
  write_text_file(json_tmp_.string(),
                  recognize_json(result, searches3, map_source, catalogue_source, config));
  out_->commit();
}

}  // namespace sonar3d
