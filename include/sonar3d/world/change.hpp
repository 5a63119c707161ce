#pragma once
// Change detection between two surveys of one site (the thesis' future work, issue 13 item 4):
// survey B registered onto survey A (their maps may be offset by navigation), then compared
// object by object (placements of catalogue models) and cell by cell (a height change map with
// connected regions of significant change).
//
// Frames: each survey's world is local ENU (x East, y North, z up); T_a_b maps survey B's world
// into survey A's, and every output is in A's frame. Elevation maps follow sec. 6.2.1 (the highest
// point per cell); the registration reuses sec. 6.2.2.1's shift search (eq. 6.1–6.2) over a yaw
// search.
#include <Eigen/Geometry>
#include <map>
#include <string>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d {

// A survey's cloud (world frame): a point cloud file (.ply) or a map directory of `sonar3d map`
// (its merged.ply). Errors name the path.
PointCloud read_survey_cloud(const std::string& path);

// One placed model of a survey: a record of sonar3d recognize's placements.json, read by
// read_placements (world_model.hpp, the one reader of that format).
using SurveyPlacement = PlacementRecord;

// Placements per survey compared (pairs within the match radius grow as their square).
constexpr std::size_t kMaxComparedPlacements = 2000;

struct ChangeRegistrationConfig {
  // The yaw window is searched on maps of yaw_cell_m (every yaw, the shift over ±search_m), or
  // finer down to cell_m on sites too small to keep ~20,000 observed cells at yaw_cell_m; the
  // winner is refined on maps of cell_m (the shift within a yaw cell of the coarse one).
  double yaw_cell_m = 0.25;
  double cell_m = 0.1;
  double search_m = 0.6;        // ± horizontal shift searched (East, North), m
  double yaw_search_deg = 2;    // ± yaw searched, degrees
  double yaw_step_deg = 0.25;   // yaw step of the coarse search, degrees
  int coarse_factor = 4;        // the shift search's coarse-to-fine factor (swath_registration.hpp)
  int min_overlap_cells = 500;  // fewer cells observed in both maps: the surveys do not overlap
  // Fraction of the overlap whose height differences score a yaw (the smallest ones): the changes
  // themselves must not decide the registration.
  double inlier_fraction = 0.8;
  int num_threads = 0;  // 0 = all cores
  void validate() const;
};

struct ChangeRegistration {
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  std::string method;  // how T_a_b was found
  double yaw_deg = 0;  // the yaw of T_a_b, degrees
  // RMS of the height differences B − A over the change map's cells within the change threshold
  // of their median (the noise: height steps and changes left out), m. Set by diff_surveys;
  // register_surveys alone gives the mean |A − B| of its inlier fraction at its own cell.
  double rms_m = 0;
  std::size_t overlap_cells = 0;  // cells observed in both surveys (change map)
  double seconds = 0;
};

// Survey B registered onto survey A (both clouds in their own worlds) on elevation maps: (1) for
// each yaw ψ in ±yaw_search_deg every yaw_step_deg (B turned about the centre of its extent), on
// maps of the yaw cell (ChangeRegistrationConfig), the shift (dx, dy) and height offset dz come
// from sec. 6.2.2.1's search (register_elevation_maps: eq. 6.1's signed median for dz, eq. 6.2's
// score, sub-cell), and the yaw whose registered maps leave the smallest mean |A − B| over the
// inlier fraction of the overlap wins; (2) the shift again at cell_m; (3) yaw, shift and height
// by trimmed Gauss-Newton of B's heights onto A's bilinear height field at cell_m / 2, kept when
// it lowers (1)'s cost at cell_m. Throws Error when the maps do not overlap.
ChangeRegistration register_surveys(const PointCloud& a_world, const PointCloud& b_world,
                                    const ChangeRegistrationConfig& config);

struct ChangeConfig {
  ChangeRegistrationConfig registration;
  double cell_m = 0.04;  // cell of the height change map, m
  // Significant height change: |B − A| over k_sigma × the robust sigma of the differences of the
  // whole overlap (derived from both surveys' noise, below), and over the range of the other
  // survey's heights in the 3×3 cells around (a cell's worth of misregistration at a wall is
  // no change).
  double k_sigma = 5;
  // The horizontal misalignment tolerated between the two maps after registration, m: each
  // survey's dead reckoning distorts its map differently (docs/mapping.md: a 0.7 % shrink, a
  // 0.4° shear on the field), which no rigid T_a_b takes out; a height step (wall, rock edge)
  // that the maps place closer than this is no change. At least one cell.
  double tolerance_m = 0.1;
  // The robust sigma: the quantile `sigma_quantile` of |d − median d| over the overlap, divided
  // by the normal distribution's quantile there (0.8: a sigma when at most 20 % of the overlap has
  // changed); never below min_sigma_m (noise-free simulations).
  double sigma_quantile = 0.8;
  double min_sigma_m = 0.005;
  double min_area_m2 = 0.05;  // regions of significant change smaller than this are dropped, m²
  // Changed cells of one sign closer than this belong to one region (a moved frame of thin tubes
  // changes in strips), m.
  double link_m = 0.1;
  // Objects: placements of one model in A and B (B in A's frame) whose origins are within
  // match_radius_m are the same object (nearest pairs first); it is unchanged when it moved at
  // most shift_tol_m horizontally and turned at most turn_tol_deg (modulo the model's symmetry).
  double match_radius_m = 1.0;
  double shift_tol_m = 0.1;
  double turn_tol_deg = 3;
  // A moved, added or removed object must be confirmed by a region of height change within this
  // of its origin in A or B (when both surveys observed at least half of that disc); otherwise
  // the difference is the recognition's (a placement off by 15 cm, a structure missed) and the
  // object is unchanged, m.
  double confirm_radius_m = 1.5;
  void validate() const;
};

enum class ObjectStatus { Unchanged, Moved, Added, Removed };
const char* object_status_name(ObjectStatus s);  // "unchanged", "moved", "added", "removed"

struct ObjectChange {
  std::string id;  // "<model>_<n>": n counts the model's placements of A, then those added in B
  std::string model;
  ObjectStatus status = ObjectStatus::Unchanged;
  bool in_a = false, in_b = false;
  Eigen::Isometry3d T_world_model_a = Eigen::Isometry3d::Identity();       // when in_a
  Eigen::Isometry3d T_world_model_b_in_a = Eigen::Isometry3d::Identity();  // when in_b: T_a_b·T_b
  double shift_m = 0;   // horizontal distance between the origins (both present), m
  double turn_deg = 0;  // yaw difference modulo the symmetry, in [0, 180] (both present)
};

struct ChangeRegion {
  int id = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // x, y: mean cell centre; z: mean of A, B
  std::size_t cells = 0;
  double area_m2 = 0;
  double max_abs_change_m = 0;  // largest |B − A| of its cells, m
  double mean_change_m = 0;     // mean B − A of its cells, m
  bool raised = true;           // B higher than A (something added or grown), else lowered
};

struct ChangeThresholds {
  double cell_m = 0;
  double median_m = 0;  // median of B − A over the overlap (a height offset left), m
  double sigma_m = 0;   // the robust sigma of B − A, m
  double k_sigma = 0;
  double change_m = 0;  // the height change threshold: k_sigma · sigma_m, m
  double min_area_m2 = 0;
  double shift_tol_m = 0, turn_tol_deg = 0, match_radius_m = 0;
};

struct ChangeResult {
  ChangeRegistration registration;
  std::vector<ObjectChange> objects;
  std::vector<ChangeRegion> regions;
  ChangeThresholds thresholds;
  // B − A on A's grid at cell_m, no data where either survey saw nothing.
  ElevationMap change_map;
  // The later survey's height (B in A's frame) on the same grid, for the change points.
  ElevationMap height_b;
  std::size_t significant_cells = 0;  // before the minimum area
  double seconds = 0;
};

// Placements compared (B's already in A's frame). `symmetries`: per model name its symmetry
// (turns are compared modulo it); empty = every model without symmetry. A placement of a model
// that `symmetries` (when not empty) does not list is an Error naming it.
std::vector<ObjectChange> compare_placements(const std::vector<SurveyPlacement>& a,
                                             const std::vector<SurveyPlacement>& b_in_a,
                                             const std::map<std::string, Symmetry>& symmetries,
                                             const ChangeConfig& config);

// The whole comparison: B registered onto A, its placements (if any) moved into A's frame and
// compared with A's, the height change map with its regions, and each object change confirmed by
// a region near it (ChangeConfig::confirm_radius_m). `pa`, `pb` may both be empty
// (geometry only).
ChangeResult diff_surveys(const PointCloud& a_world, const PointCloud& b_world,
                          const std::vector<SurveyPlacement>& pa,
                          const std::vector<SurveyPlacement>& pb,
                          const std::map<std::string, Symmetry>& symmetries,
                          const ChangeConfig& config);

// changes.json (docs/formats.md, "Change directory").
std::string changes_json(const ChangeResult& result);

// The cells observed in both surveys as points (x, y of the cell centre, z = B's height in A's
// frame) with the float property `change_m` (B − A).
PointCloud change_points(const ChangeResult& result);

// Writes the change directory `dir` (must not exist; written under a temporary name and renamed
// when complete): changes.json, change_map.tif (float32 GeoTIFF), change_points.ply.
void write_change_directory(const std::string& dir, const ChangeResult& result);

// Per catalogue model its symmetry (for compare_placements).
std::map<std::string, Symmetry> catalogue_symmetries(const Catalogue& catalogue);

// A survey's placements found by the 2D recognition (recog/recognition.hpp) with the
// catalogue's models.
std::vector<SurveyPlacement> recognize_placements(const PointCloud& cloud_world,
                                                  const Catalogue& catalogue,
                                                  const RecognitionConfig& config);

}  // namespace sonar3d
