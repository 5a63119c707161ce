#pragma once
// Change detection between two surveys of one site (the thesis' future work, issue 13 item 4):
// survey B registered onto survey A (their maps may be offset by navigation), then compared
// object by object (placements of catalogue models) and cell by cell (a height change map with
// connected regions of significant change).
//
// Frames: each survey's world is local ENU (x East, y North, z up); T_a_b maps survey B's world
// into survey A's, and every output is in A's frame. Elevation maps follow sec. 6.2.1 (the highest
// point per cell); the registration reuses sec. 6.2.2.1's shift search (eq. 6.1–6.2) over a yaw
// search. Colour change (where both surveys have video) compares coloured clouds (sonar3d texture's
// output) cell by cell after the same registration.
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/params.hpp"
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
  double search_m = 0.6;       // ± horizontal shift searched (East, North), m
  double yaw_search_deg = 2;   // ± yaw searched, degrees
  double yaw_step_deg = 0.25;  // yaw step of the coarse search, degrees
  int coarse_factor = 4;       // the shift search's coarse-to-fine factor (swath_registration.hpp)
  // Beyond the thesis: every yaw scored first at whole-cell shifts only, then only this many of
  // the best searched again with sub-cell shifts (the sub-cell search costs more than the whole
  // window's). 0 = every yaw searched in full (exhaustive). Only where the search is sub-cell
  // (maps at cell_m).
  int yaw_refine_best = 0;
  int min_overlap_cells = 500;  // fewer cells observed in both maps: the surveys do not overlap
  // Fraction of the overlap whose height differences score a yaw (the smallest ones): the changes
  // themselves must not decide the registration.
  double inlier_fraction = 0.8;
  int num_threads = 0;  // 0 = all cores
  void validate() const;
};

// The one declaration of ChangeRegistrationConfig's fields (core/params.hpp). A config that sets
// the threads itself (relocalisation) describes it as Nested<ChangeRegistrationConfig>.
template <class V>
void describe_registration_own(ChangeRegistrationConfig& c, V& v) {
  using params::param;
  v.field(c.yaw_cell_m, param("yaw_cell_m", "m",
                              "cell of the maps of the yaw search (finer on small sites, down "
                              "to cell_m)")
                            .positive()
                            .flag("--yaw-cell"));
  v.field(c.cell_m, param("cell_m", "m",
                          "cell of the maps of the final shift search; Gauss-Newton refines at "
                          "half of it")
                        .positive()
                        .equation("sec. 6.2.2.1, eq. 6.1-6.2")
                        .flag("--registration-cell"));
  v.field(c.search_m,
          param("search_m", "m", "half-width of the searched horizontal shift (East, North)")
              .positive()
              .flag("--search"));
  v.field(c.yaw_search_deg, param("yaw_search_deg", "deg", "half-width of the searched yaw")
                                .range(0, 45)
                                .flag("--yaw-search-deg"));
  v.field(c.yaw_step_deg,
          param("yaw_step_deg", "deg", "yaw step of the coarse search (then refined)")
              .range_open_low(0, 10)
              .flag("--yaw-step-deg"));
  v.field(c.coarse_factor,
          param("coarse_factor", "", "the shift search's coarse-to-fine factor").range(1, 64));
  v.field(c.yaw_refine_best,
          param("yaw_refine_best", "",
                "every yaw scored at whole-cell shifts, then only this many of the best searched "
                "again with sub-cell shifts (0 = every yaw searched in full)")
              .non_negative()
              .flag("--yaw-refine-best"));
  v.field(
      c.min_overlap_cells,
      param("min_overlap_cells", "", "fewer cells observed in both maps: no overlap").at_least(1));
  v.field(c.inlier_fraction,
          param("inlier_fraction", "",
                "of the overlap, the fraction of smallest height differences that score a pose "
                "(the changes themselves must not decide the registration)")
              .range_open_low(0, 1));
}
template <class V>
void describe(ChangeRegistrationConfig& c, V& v) {
  describe_registration_own(c, v);
  v.field(c.num_threads, params::param("num_threads", "", "worker threads (0 = all cores)")
                             .non_negative()
                             .flag("--threads"));
}
template <class V>
void describe(params::Nested<ChangeRegistrationConfig>& n, V& v) {
  describe_registration_own(n.c, v);
}

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
  // The Gauss-Newton stage's covariance of (yaw rad, x m, y m, z m) at its last iteration,
  // s²·(JᵀJ)⁻¹ with s² the residual variance over its inliers (each a cell of cell_m / 2, taken
  // as independent); B turns about `pivot` (the centre of its extent). NaN when that stage had
  // too few cells. Relocalisation (world/relocalize.hpp) reads its σ from it.
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::size_t covariance_cells = 0;  // the inliers it was computed over
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
};

// Survey B registered onto survey A (both clouds in their own worlds) on elevation maps: (1) for
// each yaw ψ in ±yaw_search_deg every yaw_step_deg (B turned about the centre of its extent), on
// maps of the yaw cell (ChangeRegistrationConfig), the shift (dx, dy) and height offset dz come
// from sec. 6.2.2.1's search (register_elevation_maps: eq. 6.1's signed median for dz, eq. 6.2's
// score, sub-cell), and the yaw whose registered maps leave the smallest mean |A − B| over the
// inlier fraction of the overlap wins (with yaw_refine_best = K > 0 on maps at cell_m, every yaw
// scored at whole-cell shifts first and only the K best searched sub-cell: the same winner as
// the exhaustive search where it is among the K, at a fraction of the cost); (2) the shift again
// at cell_m; (3) yaw, shift and height
// by trimmed Gauss-Newton of B's heights onto A's bilinear height field at cell_m / 2, kept when
// it lowers (1)'s cost at cell_m. Throws Error when the maps do not overlap.
ChangeRegistration register_surveys(const PointCloud& a_world, const PointCloud& b_world,
                                    const ChangeRegistrationConfig& config);

// How well B moved by T_a_b fits A on maps of cell `cell_m` (A's grid): the mean |A − B − ζ| over
// the smallest `inlier_fraction` of the overlap, ζ the signed median of A − B there (eq. 6.1–6.2's
// alignment of the heights, then the change detection's trimmed mean); `overlap` the cells
// observed in both, `b_cells` the cells B observes. Infinity without overlap.
struct RegistrationFit {
  double cost_m = std::numeric_limits<double>::infinity();
  double dz = 0;
  std::size_t overlap = 0, b_cells = 0;
};
RegistrationFit registration_fit(const ElevationMap& a, const PointCloud& b_world,
                                 const Eigen::Isometry3d& T_a_b, double inlier_fraction);

// The space colours are compared in (docs/change.md "Colour change" measures both):
// chromaticity — r = R/(R+G+B), g = G/(R+G+B) of linear RGB, in percentage points — ignores
// brightness, so a lamp, an altitude or a water attenuation that differs between the surveys is
// no change; CIELAB (D65, from linear RGB) also counts lightness, in ΔE*ab.
enum class ColourSpace { Chromaticity, Lab };
inline constexpr const char* kColourSpaceNames[] = {"chromaticity", "lab"};  // by ColourSpace
const char* colour_space_name(ColourSpace s);  // "chromaticity", "lab"

struct ColourChangeConfig {
  ColourSpace space = ColourSpace::Chromaticity;
  double cell_m = 0.1;  // cell of the colour comparison, m
  // A cell is compared when each survey has at least this many coloured points in it (points
  // coloured (0, 0, 0) are the ones no camera saw: sonar3d texture writes them black).
  int min_points = 4;
  // Only the coloured points within this of the highest coloured point of their cell count (the
  // top a downward camera sees; at an object's edge the mix of its side and the seabed beside it
  // differs between surveys), m. A large value: every point of the cell.
  double top_layer_m = 0.05;
  // Significant colour change: the difference, after the median offset of all compared cells
  // (a white balance or lighting shift between the surveys), beyond k_sigma × the robust sigma
  // of those differences, and beyond every colour of the other survey within tolerance_m.
  double k_sigma = 5;
  double sigma_quantile = 0.8;  // as ChangeConfig's: a sigma while at most 20 % changed
  double min_sigma = 1.0;       // floor of the sigma, in the space's units (pp or ΔE*ab)
  double tolerance_m = 0.1;     // registration/drift left between the maps (colour edges), m
  double link_m = 0.1;          // changed cells closer than this form one region, m
  // Smaller regions are dropped, m² (on the simulated pairs the false ones at colour edges were
  // 0.05–0.08 m², docs/change.md).
  double min_area_m2 = 0.1;
  int min_overlap_cells = 20;  // fewer cells compared: the colour clouds do not overlap
  void validate() const;
};

template <class V>
void describe(ColourChangeConfig& c, V& v) {
  using params::param;
  v.field(c.space, param("space", "",
                         "colours compared as chromaticity (brightness ignored, percentage "
                         "points) or lab (CIELAB, Delta E*ab)")
                       .choices(kColourSpaceNames)
                       .flag("--colour-space"));
  v.field(c.cell_m,
          param("cell_m", "m", "cell of the colour comparison").positive().flag("--colour-cell"));
  v.field(c.min_points, param("min_points", "",
                              "coloured points a cell needs in each survey to be compared "
                              "(black points are the ones no camera saw)")
                            .at_least(1)
                            .flag("--colour-min-points"));
  v.field(c.top_layer_m, param("top_layer_m", "m",
                               "only the coloured points within this of their cell's highest "
                               "coloured point count (the top a downward camera sees)")
                             .non_negative()
                             .flag("--colour-top-layer"));
  v.field(c.k_sigma, param("k_sigma", "",
                           "significant colour change: beyond this many robust sigmas of the "
                           "differences (after their median offset)")
                         .positive()
                         .flag("--colour-k-sigma"));
  v.field(c.sigma_quantile,
          param("sigma_quantile", "",
                "the robust sigma's quantile of |d - median d| (0.8: a sigma while at most 20 % "
                "changed)")
              .range_open(0.5, 1));
  v.field(c.min_sigma,
          param("min_sigma", "", "floor of the sigma, in the space's units (pp or Delta E*ab)")
              .non_negative());
  v.field(c.tolerance_m, param("tolerance_m", "m",
                               "registration and drift left between the maps: a colour of the "
                               "other survey within this is no change (at most 20 colour cells)")
                             .non_negative());
  v.field(c.link_m, param("link_m", "m",
                          "changed cells closer than this form one region (at most 100 colour "
                          "cells)")
                        .non_negative());
  v.field(c.min_area_m2, param("min_area_m2", "m2", "smallest region of colour change reported")
                             .non_negative()
                             .flag("--colour-min-area"));
  v.field(c.min_overlap_cells,
          param("min_overlap_cells", "", "fewer cells compared: the colour clouds do not overlap")
              .at_least(1));
}

struct ChangeConfig {
  ChangeRegistrationConfig registration;
  ColourChangeConfig colour;
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
  // Objects: placements of one model in A and B (B in A's frame) are the same object when their
  // centres (the centre of the model's footprint, placed; the origin when its size is unknown)
  // lie within its match radius, nearest pairs (relative to that radius) first. The radius
  // scales with the object: match_radius_factor × r_model (r_model: half the diagonal of the
  // model's footprint, ObjectModel), at least min_match_radius_m; match_radius_m for a model of
  // unknown size. At factor 1 two placements pair when their footprints overlap: a 7 × 6 m
  // frame moved 1 m is one object moved, a 0.5 m crate 1 m away is another crate.
  double match_radius_factor = 1.0;
  double min_match_radius_m = 0.25;
  double match_radius_m = 1.0;
  // A paired object is unchanged when it moved at most shift_tol_m horizontally and turned at
  // most turn_tol_deg (modulo the model's symmetry).
  double shift_tol_m = 0.1;
  double turn_tol_deg = 3;
  // The height evidence behind an object change: the reported regions of height change inside
  // the object's footprint in A or in B (grown by tolerance_m; for a model of unknown size, the
  // disc of confirm_radius_m about its origin) must cover at least min_area_m2. A moved object
  // without it is unchanged (the recognition's pose differs, not the site); an object recognised
  // in one survey only (or as another model in the other) without it is uncertain, never added
  // or removed — and so is one whose footprint both surveys did not observe (less than half of
  // its cells in the change map).
  double confirm_radius_m = 1.5;
  void validate() const;
};

// The one declaration of the change detection's settings (sonar3d diff's flags, its
// --print-config keys, Python's ChangeConfig; docs/reference.md).
template <class V>
void describe(ChangeConfig& c, V& v) {
  using params::param;
  v.group("registration", c.registration);
  v.group("colour", c.colour);
  v.field(c.cell_m,
          param("cell_m", "m", "cell of the height change map").positive().flag("--cell"));
  v.field(c.k_sigma, param("k_sigma", "",
                           "significant height change: |B - A| beyond this many robust sigmas "
                           "of the differences and beyond the other survey's 3x3 heights")
                         .positive()
                         .flag("--k-sigma"));
  v.field(c.tolerance_m, param("tolerance_m", "m",
                               "horizontal misalignment of the maps tolerated at height steps "
                               "(at least one cell, at most 20)")
                             .non_negative()
                             .flag("--tolerance"));
  v.field(c.sigma_quantile,
          param("sigma_quantile", "",
                "the robust sigma's quantile of |d - median d| over the overlap (0.8: a sigma "
                "while at most 20 % of it changed)")
              .range_open(0.5, 1));
  v.field(c.min_sigma_m,
          param("min_sigma_m", "m", "floor of the robust sigma (noise-free simulations)")
              .non_negative());
  v.field(c.min_area_m2, param("min_area_m2", "m2", "smallest region of change reported")
                             .non_negative()
                             .flag("--min-area"));
  v.field(c.link_m, param("link_m", "m",
                          "changed cells of one sign closer than this form one region (at most "
                          "100 cells)")
                        .non_negative());
  v.field(c.match_radius_factor,
          param("match_radius_factor", "",
                "placements of one model whose centres lie within this many times the model's "
                "radius (half its footprint's diagonal) are one object")
              .range_open_low(0, 10)
              .flag("--match-factor"));
  v.field(c.min_match_radius_m,
          param("min_match_radius_m", "m", "the smallest match radius of a model of known size")
              .non_negative()
              .flag("--min-match-radius"));
  v.field(c.match_radius_m, param("match_radius_m", "m",
                                  "without a catalogue (model sizes unknown): placements of one "
                                  "model closer than this are one object")
                                .positive()
                                .flag("--match-radius"));
  v.field(c.shift_tol_m, param("shift_tol_m", "m", "an object moved by at most this is unchanged")
                             .non_negative()
                             .flag("--shift-tol"));
  v.field(c.turn_tol_deg,
          param("turn_tol_deg", "deg",
                "an object turned by at most this (modulo its symmetry) is unchanged")
              .range(0, 180)
              .flag("--turn-tol-deg"));
  v.field(c.confirm_radius_m,
          param("confirm_radius_m", "m",
                "without a catalogue: an object change needs height change within this of the "
                "object (with one: within its footprint); at most 1000 cells")
              .non_negative()
              .flag("--confirm-radius"));
}

// What change detection knows of a catalogue model: its symmetry (turns are compared modulo it)
// and its size (the radius objects are paired over, the footprint a change must show in).
struct ObjectModel {
  Symmetry symmetry = Symmetry::None;
  // The model's horizontal footprint in its own frame (x, y extent of its mesh), m; empty when
  // its size is unknown.
  Eigen::AlignedBox2d footprint{};
  bool has_size() const { return !footprint.isEmpty(); }
  // r_model in 2D: half the footprint's diagonal (the horizontal radius about its centre), m.
  double radius_m() const { return has_size() ? 0.5 * footprint.diagonal().norm() : 0.0; }
};
using ObjectModels = std::map<std::string, ObjectModel>;

enum class ObjectStatus { Unchanged, Moved, Added, Removed, Uncertain };
// "unchanged", "moved", "added", "removed", "uncertain"
const char* object_status_name(ObjectStatus s);

struct ObjectChange {
  std::string id;  // "<model>_<n>": n counts the model's placements of A, then those added in B
  std::string model;
  ObjectStatus status = ObjectStatus::Unchanged;
  bool in_a = false, in_b = false;
  Eigen::Isometry3d T_world_model_a = Eigen::Isometry3d::Identity();       // when in_a
  Eigen::Isometry3d T_world_model_b_in_a = Eigen::Isometry3d::Identity();  // when in_b: T_a_b·T_b
  double shift_m = 0;         // horizontal distance between the centres (both present), m
  double turn_deg = 0;        // yaw difference modulo the symmetry, in [0, 180] (both present)
  double match_radius_m = 0;  // the radius it was paired over (ChangeConfig), m
  // Recognition's confidence of each survey's placement (PlacementRecord); NaN: unknown/absent.
  double confidence_a = std::numeric_limits<double>::quiet_NaN();
  double confidence_b = std::numeric_limits<double>::quiet_NaN();
  // Set when the other survey placed another model over it (its footprint overlapping): that
  // model's name. Empty otherwise.
  std::string other_model;
  // Set by diff_surveys: the area of reported height change inside its footprint(s), m², and
  // the fraction of those footprints' cells both surveys observed. NaN: not measured
  // (compare_placements alone).
  double change_area_m2 = std::numeric_limits<double>::quiet_NaN();
  double observed_fraction = std::numeric_limits<double>::quiet_NaN();
  std::string reason;  // why an object is uncertain; empty otherwise
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

// A connected region of significant colour change.
struct ColourRegion {
  int id = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // x, y: mean cell centre; z: mean point z
  std::size_t cells = 0;
  double area_m2 = 0;
  double max_delta = 0;   // largest colour difference of its cells (offset removed), space units
  double mean_delta = 0;  // mean colour difference of its cells
  // Mean colour of its cells before (A) and after (B), 8-bit sRGB (B's with the offset left in:
  // as its camera saw it).
  std::array<std::uint8_t, 3> colour_a{0, 0, 0}, colour_b{0, 0, 0};
  // Share of its cells with a reported region of height change within the colour tolerance
  // (set by diff_surveys): 0 = the surface itself changed (growth, paint, corrosion), not the
  // geometry; a moved, added or removed object changes both.
  double height_change_fraction = 0;
  std::vector<std::size_t> cell_indices;  // its cells on delta_map's grid
};

struct ColourChange {
  bool compared = false;  // false: no colour clouds given (then nothing below is set)
  ColourSpace space = ColourSpace::Chromaticity;
  double cell_m = 0;
  std::vector<double> offset;  // median of B − A per component of the space (2 or 3)
  double sigma = 0;            // robust sigma of |B − A − offset|, space units
  double k_sigma = 0;
  double threshold = 0;  // k_sigma · sigma
  double min_area_m2 = 0;
  std::size_t compared_cells = 0, significant_cells = 0;
  std::vector<ColourRegion> regions;
  // |B − A − offset| per cell on A's colour grid, no data where either lacks colour.
  ElevationMap delta_map;
};

struct ChangeThresholds {
  double cell_m = 0;
  double median_m = 0;  // median of B − A over the overlap (a height offset left), m
  double sigma_m = 0;   // the robust sigma of B − A, m
  double k_sigma = 0;
  double change_m = 0;  // the height change threshold: k_sigma · sigma_m, m
  double min_area_m2 = 0;
  double shift_tol_m = 0, turn_tol_deg = 0, match_radius_m = 0;
  double match_radius_factor = 0, min_match_radius_m = 0;
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
  // Per cell of change_map: the id of the reported height region it belongs to, or −1.
  std::vector<int> region_cell;
  ColourChange colour;  // colour change, when both surveys' colour clouds were given
  double seconds = 0;
};

// Checks a coloured cloud for the colour comparison (`name` names it in errors, e.g. the file):
// it must have uchar red/green/blue (float colour properties, finite or not, are an error naming
// the first bad vertex) and finite points.
void check_colour_cloud(const PointCloud& cloud, const std::string& name);

// Colour change between coloured clouds of A (A's world) and B (already moved into A's frame by
// T_a_b), per cell of config.cell_m over the cells where both have min_points coloured points:
// the mean linear RGB of each cell in the space, the median offset B − A removed, the robust
// sigma of the differences, cells changed beyond k_sigma × sigma (and beyond every colour of the
// other survey within tolerance_m), connected regions. Throws Error when fewer than
// min_overlap_cells cells can be compared.
ColourChange compare_colour(const PointCloud& colour_a, const PointCloud& colour_b_in_a,
                            const ColourChangeConfig& config);

// Placements compared (B's already in A's frame) by identity (the model) and pose (centres
// within the match radius, ChangeConfig): paired ones are unchanged or moved, the others removed
// (A only) or added (B only), each with the model the other survey placed over it if any
// (other_model). diff_surveys then weighs them against the height change. `models`: per model
// name its symmetry and size (empty = every model without symmetry, of unknown size). A
// placement of a model that `models` (when not empty) does not list is an Error naming it.
std::vector<ObjectChange> compare_placements(const std::vector<SurveyPlacement>& a,
                                             const std::vector<SurveyPlacement>& b_in_a,
                                             const ObjectModels& models,
                                             const ChangeConfig& config);

// Memory diff_surveys will take for these clouds (core/memory.hpp), before anything is
// allocated: the registration's maps at --yaw-cell and --registration-cell, the height change
// map at --cell and, with `colour`, the colour maps at --colour-cell, over both clouds' extent.
MemoryEstimate estimate_change_memory(const PointCloud& a_world, const PointCloud& b_world,
                                      const ChangeConfig& config, bool colour);

// The whole comparison: B registered onto A, its placements (if any) moved into A's frame and
// compared with A's, the height change map with its regions, and each object change weighed
// against the height change inside its footprint (ChangeConfig: moved, added and removed need
// it; without it a pair is unchanged and a one-survey recognition uncertain). `pa`, `pb` may both
// be empty (geometry only). `colour_a`, `colour_b` (both or neither): coloured clouds of each
// survey in its own world (sonar3d texture's output, e.g. of the survey's own cloud), compared by
// compare_colour after B's is moved by T_a_b. `registration` (optional): B's placement in A's
// frame known already — survey B relocalised against A's world model (world/relocalize.hpp,
// its map carved with the relocalised navigation) — taken as is (its T_a_b, method), and
// register_surveys is not run.
ChangeResult diff_surveys(const PointCloud& a_world, const PointCloud& b_world,
                          const std::vector<SurveyPlacement>& pa,
                          const std::vector<SurveyPlacement>& pb, const ObjectModels& models,
                          const ChangeConfig& config, const PointCloud* colour_a = nullptr,
                          const PointCloud* colour_b = nullptr,
                          const ChangeRegistration* registration = nullptr);

// changes.json (docs/formats.md, "Change directory").
std::string changes_json(const ChangeResult& result);

// The cells observed in both surveys as points (x, y of the cell centre, z = B's height in A's
// frame) with the float property `change_m` (B − A).
PointCloud change_points(const ChangeResult& result);

// Writes the change directory `dir` (must not exist; written under a temporary name and renamed
// when complete): changes.json, change_map.tif (float32 GeoTIFF), change_points.ply, and with
// colour compared colour_change_map.tif (float32, the colour difference per colour cell).
void write_change_directory(const std::string& dir, const ChangeResult& result);

// Per catalogue model its symmetry and size (for compare_placements): the footprint of its mesh
// for the models `placed` names (the meshes of the others are not loaded; their size stays
// unknown), symmetry only for the rest. Mesh errors name the catalogue and model.
ObjectModels catalogue_object_models(const Catalogue& catalogue,
                                     const std::vector<std::string>& placed);

// A survey's placements found by the 2D recognition (recog/recognition.hpp) with the
// catalogue's models.
std::vector<SurveyPlacement> recognize_placements(const PointCloud& cloud_world,
                                                  const Catalogue& catalogue,
                                                  const RecognitionConfig& config);

}  // namespace sonar3d
