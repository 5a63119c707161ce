#pragma once
// Relocalisation against a world model (issue 26 item 4; the thesis' conclusion names it as what
// its semantic maps enable): a new survey, down to a single line, registered to a previous
// survey's world model (`sonar3d world`: its seabed and placed structures), giving the vehicle's
// trajectory in the world model's frame, its σ, and "not found" when the new data does not
// overlap the model.
//
//   RelocalizeConfig cfg;                              // ±1 m, ±5° searched
//   const WorldModelCloud w = read_world_model_cloud("field_world", cfg.model_spacing_m);
//   const RelocalizeResult r = relocalize(dataset, w, cfg);
//   write_relocalization(r, "out");                    // relocalization.json, navigation.tum
//
// Method. Each swath of the new survey (split at its turns as `sonar3d map` splits them;
// mapping/survey.hpp) is carved on its own (recon/carve.hpp), then registered rigidly onto the
// world model's surface — the finest seabed level and the placed structures' meshes, one cloud —
// by the change detection's registration (world/change.hpp, register_surveys): sec. 6.2.2.1's
// elevation-map shift search (eq. 6.1–6.2) over a yaw search spanning the navigation's expected
// error, then trimmed Gauss-Newton of the swath's heights onto the model's height field (yaw,
// shift, height). Each swath gets its own rigid correction T_model_survey (absolute, against the
// model; no swath-to-swath tie is needed); the trajectory's poses within a swath are moved by it,
// poses in the turns by the correction interpolated in time between the two swaths around them.
//
// Beyond a rigid correction: dead reckoning drifts along a line (a 1 % DVL scale error stretches
// a 36 m line by 36 cm), which no rigid fit takes out. Each found swath is cut into pieces of
// piece_m along its track, each piece registered again from the swath's solution (shift and
// height; yaw within a few tenths of a degree), and the pieces' displacements fitted by least
// squares as a correction linear in time, d(t) = a + b·(t − t_mid) — the drift of a steady
// scale error or heading bias on a straight line (b from 3 pieces or more, else 0).
//
// σ: from the Gauss-Newton's Hessian at the solution, cov = s²·(JᵀJ)⁻¹ (s² the residual variance
// over the inliers), its residuals counted once per registration cell (cell_m) — adjacent finer
// cells share their carved voxels and are not independent.
//
// "Found" (a swath), all of:
//   1. the registration found an overlap (min_overlap_cells cells observed in both);
//   2. overlap fraction: of the swath's cells (at cell_m), at least min_overlap_fraction lie on
//      cells the model observed, at the solution;
//   3. distinctiveness: the solution fits clearly better than the alternatives the search window
//      allows. m* = mean |model − swath − dz| over the inlier fraction at the solution, m_alt =
//      the median of the same over shifts of the solution by ±search_m/2 and ±search_m (8
//      directions each; dz re-fitted): 1 − m*/m_alt ≥ min_distinctiveness. A flat, featureless
//      overlap, or a swath beside the model whose window only grazes it, fits everywhere alike.
// The survey is found when at least one swath is; a swath not found takes the correction of the
// nearest found one in time (flagged in the result).
#include <Eigen/Geometry>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/world/change.hpp"

namespace sonar3d {

struct Dataset;  // io/dataset.hpp

// The registration's defaults for relocalisation: the navigation's whole expected error searched
// (±1 m, ±5°), a smaller overlap accepted (one line).
inline ChangeRegistrationConfig relocalize_registration_defaults() {
  ChangeRegistrationConfig r;
  r.cell_m = 0.1;
  r.yaw_cell_m = 0.25;
  r.search_m = 1.0;
  r.yaw_search_deg = 5;
  r.yaw_step_deg = 0.25;
  r.inlier_fraction = 0.8;
  r.min_overlap_cells = 300;
  r.yaw_refine_best = 3;  // coarse-to-fine yaw search (docs/mapping.md "Faster registration")
  return r;
}

struct RelocalizeConfig {
  double voxel_m = 0.05;  // carving voxel of the new survey (the world's seabed is 5 cm), m
  // Each swath registered onto the model as sonar3d diff registers survey B onto A
  // (world/change.hpp); num_threads is this config's.
  ChangeRegistrationConfig registration = relocalize_registration_defaults();
  double min_overlap_fraction = 0.5;  // found: of the swath's cells, this fraction on the model
  double min_distinctiveness = 0.3;   // found: 1 − m*/m_alt at least this
  double model_spacing_m = 0.03;      // structures' meshes sampled at this spacing, m
  // Each found swath is cut along its track into pieces of about this length, each registered
  // again: the drift of the navigation along the line (a DVL scale error, a heading bias) is
  // fitted to them as a correction linear in time, and their agreement gives σ. 0: no pieces.
  double piece_m = 6;
  SwathSplitConfig split;  // the new survey's swaths (as sonar3d map splits them)
  // > 0: the survey is also carved again with its relocalised navigation, swath by swath at this
  // voxel size, into one cloud in the model's frame (RelocalizeResult::map, OUTPUT/merged.ply):
  // survey B of a change detection (sonar3d diff A RELOC_DIR). 0: not carved.
  double map_voxel_m = 0;
  int num_threads = 0;    // 0 = all cores
  void validate() const;  // throws Error naming the parameter
};

template <class V>
void describe(RelocalizeConfig& c, V& v) {
  using params::param;
  v.field(c.voxel_m,
          param("voxel_m", "m", "carving voxel of the new survey").positive().flag("--voxel-size"));
  params::Nested<ChangeRegistrationConfig> registration{c.registration};
  v.group("registration", registration);
  v.field(c.min_overlap_fraction,
          param("min_overlap_fraction", "",
                "found: of the swath's cells, at least this fraction lie on the model")
              .range_open_low(0, 1)
              .flag("--min-overlap"));
  v.field(c.min_distinctiveness,
          param("min_distinctiveness", "",
                "found: 1 - m*/m_alt at least this (m*: the fit at the solution, m_alt: at "
                "shifts of the search window)")
              .range(0, 1)
              .flag("--min-distinctiveness"));
  v.field(c.model_spacing_m,
          param("model_spacing_m", "m", "the structures' meshes are sampled at this spacing")
              .positive());
  v.field(c.piece_m, param("piece_m", "m",
                           "swaths are cut into pieces of about this length, each registered "
                           "again: the drift along the line and sigma (0: no pieces)")
                         .non_negative()
                         .flag("--piece"));
  v.group("split", c.split);
  v.field(c.map_voxel_m,
          param("map_voxel_m", "m",
                "also carve the survey with its relocalised navigation at this voxel size into "
                "OUTPUT/merged.ply, in the model's frame (survey B of sonar3d diff; 0: not "
                "written)")
              .non_negative()
              .flag("--map-resolution"));
  v.field(
      c.num_threads,
      param("num_threads", "", "worker threads (0 = all cores)").non_negative().flag("--threads"));
}

// A world model directory (`sonar3d world`) as one cloud: the vertices of its finest seabed level
// (cell centres) and samples of its confirmed structures' meshes (models/<id>.ply, world frame).
struct WorldModelCloud {
  std::string dir;
  PointCloud cloud;  // world frame
  double seabed_cell_m = 0;
  std::size_t seabed_points = 0, structure_points = 0, structures = 0;
};
// Errors (one line, naming the path): not a directory, no graph.json of format sonar3d-world, no
// seabed level or an empty one, a model file missing.
WorldModelCloud read_world_model_cloud(const std::filesystem::path& world_dir, double spacing_m);

struct RelocalizedSwath {
  int first_frame = 0, last_frame = 0;  // inclusive, dataset frame indices
  double t0 = 0, t1 = 0;                // s
  std::size_t points = 0;               // carved
  bool found = false;
  std::string reason;  // why not found (empty when found)
  // The correction, survey world → world model (T_model_survey): a pose logged as T is T_ms·T.
  // A swath not found carries the nearest found swath's (borrowed = true) or the identity.
  Eigen::Isometry3d T_model_survey = Eigen::Isometry3d::Identity();
  // The drift along the swath from its pieces: after T_model_survey, positions move by
  // drift_offset + drift_rate·(t − t_mid) (t clamped to [t0, t1]); zero without pieces.
  Eigen::Vector3d drift_offset = Eigen::Vector3d::Zero();
  Eigen::Vector3d drift_rate = Eigen::Vector3d::Zero();  // m/s
  double t_mid = 0;
  int pieces = 0, pieces_used = 0;  // cut, and registered (found) among them
  double piece_rms_m = std::numeric_limits<double>::quiet_NaN();  // horizontal, the fit's
  // The correction of a pose logged at time t of this swath.
  Eigen::Isometry3d correction(double t) const;
  bool borrowed = false;
  double yaw_deg = 0;
  // The larger of the Gauss-Newton's σ (sigma_hessian_m) and the pieces' agreement
  // (sigma_pieces_m: the linear fit's residual, as its standard error at the worst time; with 3
  // pieces or more) sets sigma_horizontal_m.
  // 1σ of the correction (East, North, Up at the swath's centre, m; yaw, degrees) and the largest
  // horizontal 1σ of a pose of the swath (the yaw's lever arm included), m. NaN when not found.
  Eigen::Vector3d sigma_m = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double sigma_yaw_deg = std::numeric_limits<double>::quiet_NaN();
  double sigma_horizontal_m = std::numeric_limits<double>::quiet_NaN();
  double sigma_hessian_m = std::numeric_limits<double>::quiet_NaN();
  double sigma_pieces_m = std::numeric_limits<double>::quiet_NaN();
  std::size_t overlap_cells = 0, swath_cells = 0;
  double overlap_fraction = 0;
  double residual_m = std::numeric_limits<double>::quiet_NaN();     // m*
  double alternative_m = std::numeric_limits<double>::quiet_NaN();  // m_alt
  double distinctiveness = 0;
  double seconds_carving = 0, seconds_registration = 0;
};

struct RelocalizeResult {
  std::vector<RelocalizedSwath> swaths;
  bool found = false;  // at least one swath found
  // The vehicle's navigation (T_world_vehicle) moved into the world model's frame; empty when
  // not found.
  Trajectory navigation;
  double sigma_horizontal_m = std::numeric_limits<double>::quiet_NaN();  // max over found swaths
  std::string dataset, world;
  std::size_t world_points = 0;
  // With map_voxel_m > 0 and found: the survey carved with the relocalised navigation (each
  // swath alone, as sonar3d map carves them, the clouds put together), in the model's frame.
  PointCloud map;
  double map_voxel_m = 0;
  double seconds_carving = 0, seconds_registration = 0, seconds_map = 0, seconds_total = 0;
};

// Relocalises `dataset` against the world model's cloud. Errors: a dataset without frames or
// whose swaths carve to no point (naming the swath). A progress bar over the frames carved.
RelocalizeResult relocalize(const Dataset& dataset, const WorldModelCloud& world,
                            const RelocalizeConfig& config, bool progress = false);

// relocalization.json ("format": "sonar3d-relocalization", version 1) and, when found,
// navigation.tum (the corrected vehicle navigation, TUM) and with a map merged.ply (binary PLY,
// the model's frame) into `dir` (written by the caller's OutputDirectory; docs/formats.md).
void write_relocalization(const std::filesystem::path& dir, const RelocalizeResult& result,
                          const RelocalizeConfig& config);
std::string relocalization_json(const RelocalizeResult& result, const RelocalizeConfig& config);

// A relocalisation directory read back as survey B of a change detection (sonar3d diff).
struct RelocalizedSurvey {
  std::string dir;
  std::string world;      // the world model it was relocalised against (as recorded)
  std::string world_map;  // the map that world model was built from (its graph.json), or empty
  PointCloud cloud;       // merged.ply: the survey in the world model's frame
};
// True when `path` is a directory holding relocalization.json.
bool is_relocalization_dir(const std::filesystem::path& path);
// Errors (one line, naming the directory): not of format sonar3d-relocalization, the survey not
// found in its model, no merged.ply (relocalised without --map-resolution).
RelocalizedSurvey read_relocalized_survey(const std::filesystem::path& dir);
// Whether the world model B was relocalised against was built from survey A (`a`: a map
// directory or its merged.ply; the world's graph.json records its map as given to sonar3d
// world, resolved here against the current directory): then B is already in A's frame.
bool relocalized_against(const RelocalizedSurvey& b, const std::string& a);

}  // namespace sonar3d
