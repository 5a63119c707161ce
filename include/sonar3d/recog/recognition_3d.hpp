#pragma once
// CAD-model recognition in the 3D scene (thesis sec. 6.3.1): the scene split into spherical
// subspaces (eq. 6.3), each kept only if it could hold the model (oriented bounding box, volume,
// point count, voxel occupancy: eq. 6.4-6.7), then direct 3D matching of the subsampled model in
// every surviving subspace: a yaw sweep and trimmed ICP when the model is known to stand upright
// on the seabed (the thesis' "prior information about the most likely orientation"), a global
// registration when nothing is known of its orientation (the thesis used Go-ICP); a residual
// threshold decides "found" (sec. 6.3.1.3), non-maximum suppression keeps one placement per
// instance, and models are searched in decreasing size, each detection removing its points.
//
// Frames: local ENU world (x East, y North, z up). Placements are T_world_model.
#include <Eigen/Geometry>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/icp.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/verify.hpp"

namespace sonar3d {

struct Recognition3dConfig {
  // Subsampling of model and scene (sec. 6.3.1.2: "typically 3 cm"), voxel edge, m.
  double voxel_m = 0.03;
  // Subspace grid period T as a fraction of r_model (the thesis: T = 0.5·r_model); the subspace
  // radius is r_model + √3/2·T (eq. 6.3), r_model the radius of the model's bounding sphere.
  // T is at least voxel_m (no finer than the scene's sampling).
  double period_fraction = 0.5;
  // Bound on the subspaces per model (the thesis' grid grows as 1/r_model³: 112 k for a 0.69 m
  // panel on a 40 × 30 m field, a 0.13 m tool never finished). Centres are only placed near the
  // scene's occupied cells (within the subspace radius of a point): with the upright prior on a
  // horizontal lattice at the height the model's bounding-sphere centre has when it stands on the
  // local seabed (2D: the count grows with the occupied area / T²), otherwise on the 3D lattice
  // (occupied volume / T³). When more than max_subspaces remain, T is raised by steps of 1.25
  // until they fit (reported as period_m and period_raised).
  std::size_t max_subspaces = 100000;
  // Eq. 6.4-6.7 (the thesis' values).
  double alpha_fit = 1.2;        // eq. 6.4: l_model[i] <= alpha_fit · l_subspace[i]
  double alpha_volume = 0.6;     // eq. 6.5: V_subspace >= alpha_volume · V_model
  int n_min = 10;                // eq. 6.6: N_subspace >= N_min
  double alpha_occupancy = 0.6;  // eq. 6.7: O_subspace >= alpha_occupancy · O_model
  // Voxel edge of the occupancy count of eq. 6.7, m; for a model with r_model < 4 × this, the
  // edge is r_model / 4 (at least voxel_m): a 0.1 m tool would otherwise fill one voxel.
  double occupancy_voxel_m = 0.1;
  // Orientation prior: structures stand upright on the seabed (yaw unknown). When true, each
  // subspace is matched by a yaw sweep and trimmed ICP from the best yaws; when false, by the
  // global registration (rotation unknown).
  bool upright = true;
  double yaw_step_deg = 15;  // yaw sweep step (range from the catalogue's symmetry), degrees
  // Seabed: points lower than the local seabed plus this are dropped from the subspaces and the
  // matching (as the 2D method's ground_clearance_m), and the model's own base below its base
  // plus this is dropped likewise; 0 keeps the seabed (the thesis kept it: its OBBs then grow
  // with the seabed, sec. 6.3.1.4). Used with `upright` only.
  double seabed_clearance_m = 0.05;
  // Local seabed: per ground_cell_m cell, a plane fitted to the lowest point per cell within
  // ground_window_m, refitted to the lower half of the cells (slopes followed, structures over
  // less than half the window ignored); where fewer than 6 cells hold points, the
  // ground_quantile of their lowest points. m.
  double ground_cell_m = 0.25;
  double ground_window_m = 2.0;
  double ground_quantile = 0.25;
  // Matching. Survivors whose points' centroids lie within dedup_fraction · r_model (with the
  // upright prior at least coarse_gate_m, the start sites' step) of a survivor holding more
  // points are not matched (they hold nearly the same points).
  double dedup_fraction = 0.5;
  int starts = 2;                  // ICP starts per subspace (best yaws / rotations)
  double coarse_gate_m = 0.4;      // first ICP pass: correspondences within this, m
  int coarse_iterations = 15;      // first ICP pass iterations
  std::size_t max_points = 1500;   // scene points per subspace used in the matching
  std::size_t sweep_points = 300;  // scene points scoring each yaw-sweep start (upright)
  // Coarse to fine over the start sites (upright): when a survivor has more than coarse_sites
  // start sites, each is first scored on coarse_points points (every coarse_yaw_stride-th yaw)
  // and only the coarse_sites best are swept at every yaw on sweep_points; 0 sweeps every site
  // (the exhaustive search).
  std::size_t coarse_sites = 8;
  std::size_t coarse_points = 75;
  std::size_t coarse_yaw_stride = 1;
  double max_start_score_m = 0.2;  // early rejection: a start whose trimmed mean distance (or
                                   // 0.1·r_model when larger: see match_subspace)
                                   // exceeds this is not refined, m
  TrimmedIcpConfig icp;            // fine ICP pass
  // Decision ("found"): the thesis' threshold on the error to the CAD model after matching
  // (sec. 6.3.1.3: the median distance from the scene points over the placed model to its
  // samples, max_residual_median_m), then the hypothesis verification shared with the 2D method
  // (verify.hpp, docs/recognition.md "Verification") on the field's elevation map of
  // map_cell_m: seen, explained, free-space violation, unexplained relief, spill and the
  // calibrated confidence (at least verification.min_confidence), no more than
  // max_buried_fraction of the model below the seabed ring around it, no more than max_overlap
  // of its footprint on accepted placements.
  double max_residual_median_m = 0.04;
  double map_cell_m = 0.02;
  VerificationConfig verification;
  double max_buried_fraction = 0.5;
  // With the upright prior a structure stands on the seabed: its base at most this above the
  // seabed ring around it (verify.hpp's ground_z). A model standing on another object's top
  // (a BOP panel laid 0.25 m up on a debris plate, mixed_buried field) is refused. m.
  double max_lift_m = 0.1;
  // A model elongated in the top view (footprint length ≥ elongation_min × width) whose relief
  // continues beyond both ends (Verification3d::end_continuation above this) lies on a section
  // of a longer structure and is refused: a torpedo shell on a half-buried pipeline of its
  // diameter (clutter_only field) is explained by the pipe's top, passes every other term, and
  // its burial against the 0.5 limit is a matter of 1-2 % of its height.
  double max_end_continuation = 0.5;
  double elongation_min = 2.0;
  double max_overlap = 0.25;
  // The net explanation, verify.hpp's score_m3 (relief explained − contradicted − left
  // unexplained) over the model's relief relief_m3, at least this: a model with no relief of its
  // own (a 5 cm valve) or one laid on a wreck explains little net of what it contradicts
  // (measured on the issue-28-like field, docs/recognition.md: true 0.70-0.75, false -inf-0.17).
  double min_net_explained = 0.4;
  // Diagnostics of the 3D point cloud (Verification3d, reported per placement, not deciding):
  //  - coverage: of the model's samples a downward survey sees (visible from above along the
  //    vertical or view_tilt_deg off it) that stand at least relief_m above its base, the
  //    fraction with a scene point within coverage_tol_m;
  //  - violation: of its samples seen straight from above and standing relief_m above its base,
  //    the fraction over which the survey saw the surface lower than the sample by more than
  //    coverage_tol_m in every column within coverage_tol_m; unobserved columns do not count;
  //  - unexplained: of the scene points standing unexplained_height_m above the seabed in the
  //    model's footprint grown by max(context_min_m, context_fraction · r_model) and up to that
  //    above its top, the fraction farther than coverage_tol_m from the model.
  // min_coverage also bounds non-maximum suppression: a candidate must still cover that
  // fraction with scene points no accepted placement took.
  double min_coverage = 0.5;
  double coverage_tol_m = 0.06;
  double relief_m = 0.1;
  double view_tilt_deg = 30;
  double context_min_m = 0.2;
  double context_fraction = 0.25;
  // Scene points count as unexplained only when standing this high above the local seabed (the
  // seabed plane leaves 10-20 cm of relief texture on the 25 cm relief), m.
  double unexplained_height_m = 0.2;
  double max_tilt_deg = 10;  // upright: a placement tilted more than this is refused
  // Non-maximum suppression: two placements of one model whose centres are closer than this
  // fraction of its horizontal radius are one instance (the better kept).
  double nms_fraction = 1.0;
  double removal_margin_m = 0.1;  // scene points this close to a placed model are removed
  int max_instances = 20;         // per model whose count is not given
  ModelSamplingConfig sampling;
  int num_threads = 0;  // 0 = all cores
  void validate() const;
};
// The 3D method's fields (the `three_d:` block of `recognize --print-config`, Python's
// Recognition3dConfig). Not declared here: verification and num_threads (the recognition's, shared
// by both methods).
template <class V>
void describe(Recognition3dConfig& c, V& v) {
  using params::param;
  v.field(c.voxel_m, param("voxel_m", "m", "model and scene subsampling voxel")
                         .positive()
                         .flag("--subsample")
                         .equation("sec. 6.3.1.2"));
  v.field(c.period_fraction,
          param("period_fraction", "", "subspace grid period T as a fraction of r_model")
              .range_open_low(0.05, 4)
              .flag("--period-fraction")
              .equation("eq. 6.3"));
  v.field(c.max_subspaces,
          param("max_subspaces", "",
                "at most this many subspaces per model (T is raised until they fit)")
              .range(1, 50'000'000)
              .flag("--max-subspaces"));
  v.field(c.alpha_fit, param("alpha_fit", "", "OBB fit margin")
                           .range_open_low(0, 100)
                           .flag("--alpha-fit")
                           .equation("eq. 6.4"));
  v.field(c.alpha_volume, param("alpha_volume", "", "volume margin")
                              .range(0, 100)
                              .flag("--alpha-volume")
                              .equation("eq. 6.5"));
  v.field(c.n_min, param("n_min", "", "minimum points per subspace")
                       .at_least(3)
                       .flag("--n-min")
                       .equation("eq. 6.6"));
  v.field(c.alpha_occupancy, param("alpha_occupancy", "", "occupancy margin")
                                 .range(0, 100)
                                 .flag("--alpha-occupancy")
                                 .equation("eq. 6.7"));
  v.field(c.occupancy_voxel_m, param("occupancy_voxel_m", "m", "occupancy voxel edge")
                                   .positive()
                                   .flag("--occupancy-voxel")
                                   .equation("eq. 6.7"));
  v.field(c.upright, param("upright", "",
                           "structures stand upright: yaw sweep + ICP per subspace (else the "
                           "global registration, slower)")
                         .flag("--no-upright"));
  v.field(c.yaw_step_deg, param("yaw_step_deg", "deg", "yaw sweep step").range_open_low(0, 180));
  v.field(c.seabed_clearance_m,
          param("seabed_clearance_m", "m",
                "drop points lower than the local seabed plus this (0: keep the seabed)")
              .non_negative()
              .flag("--seabed-clearance"));
  v.field(c.ground_cell_m, param("ground_cell_m", "m", "local seabed cell").positive());
  v.field(c.ground_window_m,
          param("ground_window_m", "m", "local seabed plane window").non_negative());
  v.field(
      c.ground_quantile,
      param("ground_quantile", "", "seabed quantile where too few cells hold points").range(0, 1));
  v.field(c.dedup_fraction, param("dedup_fraction", "",
                                  "survivors this close (× r_model; upright: at least "
                                  "coarse_gate_m) to a fuller one are not matched")
                                .range(0, 10));
  v.field(c.starts, param("starts", "", "ICP starts per subspace").range(1, 100).flag("--starts"));
  v.field(c.coarse_gate_m,
          param("coarse_gate_m", "m", "first ICP pass: correspondences within this").positive());
  v.field(c.coarse_iterations,
          param("coarse_iterations", "", "first ICP pass iterations").range(1, 10000));
  v.field(c.max_points,
          param("max_points", "", "scene points per subspace used in the matching").at_least(10));
  v.field(c.sweep_points,
          param("sweep_points", "", "scene points scoring each yaw-sweep start").at_least(10));
  v.field(c.coarse_sites, param("coarse_sites", "",
                                "start sites swept in full after a coarse scoring of all (0: "
                                "every site, exhaustive)")
                              .range(0, 100000)
                              .flag("--coarse-sites"));
  v.field(c.coarse_points,
          param("coarse_points", "", "points scoring each start in the coarse pass").at_least(10));
  v.field(c.coarse_yaw_stride,
          param("coarse_yaw_stride", "", "the coarse pass scores every this-th yaw").range(1, 360));
  v.field(c.max_start_score_m,
          param("max_start_score_m", "m", "a start scoring worse is not refined").positive());
  v.group("icp", c.icp);
  v.field(c.max_residual_median_m,
          param("max_residual_median_m", "m", "error to the CAD model after matching, at most")
              .positive()
              .equation("sec. 6.3.1.3"));
  v.field(c.map_cell_m,
          param("map_cell_m", "m", "elevation map cell of the verification").positive());
  v.field(c.max_buried_fraction,
          param("max_buried_fraction", "", "at most this fraction of the model below the seabed")
              .range(0, 1));
  v.field(c.max_lift_m,
          param("max_lift_m", "m", "an upright model's base at most this above the seabed ring")
              .non_negative());
  v.field(c.max_end_continuation,
          param("max_end_continuation", "",
                "an elongated model whose relief continues beyond both ends on more than this "
                "fraction of each end strip is refused")
              .range(0, 1));
  v.field(c.elongation_min,
          param("elongation_min", "",
                "a model whose footprint is at least this many times as long as wide is "
                "elongated (end continuation)")
              .range(1, 1000));
  v.field(c.max_overlap,
          param("max_overlap", "", "at most this fraction of the footprint on accepted placements")
              .range(0, 1));
  v.field(c.min_net_explained,
          param("min_net_explained", "", "net explanation over the model's relief, at least")
              .range(-10, 1));
  v.field(c.min_coverage,
          param("min_coverage", "",
                "a placement must have a scene point near at least this fraction of the model's "
                "samples seen from above")
              .range(0, 1)
              .flag("--min-coverage"));
  v.field(
      c.coverage_tol_m,
      param("coverage_tol_m", "m", "a sample is covered by a scene point this close").positive());
  v.field(
      c.relief_m,
      param("relief_m", "m", "samples this far above the model's base are relief").non_negative());
  v.field(c.view_tilt_deg, param("view_tilt_deg", "deg",
                                 "samples visible from above along the vertical or this "
                                 "off it")
                               .range_open_high(0, 90));
  v.field(c.context_min_m,
          param("context_min_m", "m", "unexplained points counted in a ring at least this wide")
              .non_negative());
  v.field(c.context_fraction,
          param("context_fraction", "", "else this fraction of the model's radius").range(0, 10));
  v.field(c.unexplained_height_m,
          param("unexplained_height_m", "m",
                "scene points count as unexplained only this high above the seabed")
              .non_negative());
  v.field(
      c.max_tilt_deg,
      param("max_tilt_deg", "deg", "an upright placement tilted more is refused").range(0, 180));
  v.field(c.nms_fraction, param("nms_fraction", "",
                                "placements of one model closer than this × its radius are "
                                "one instance")
                              .range(0, 10));
  v.field(c.removal_margin_m,
          param("removal_margin_m", "m", "scene points this close to a placed model are removed")
              .non_negative());
  v.field(c.max_instances,
          param("max_instances", "", "instances per model whose count the catalogue does not give")
              .range(1, 1000));
  v.group("sampling", c.sampling);
}

// Shape statistics of a point set (sec. 6.3.1.1): the side lengths of its oriented bounding box
// (principal axes of the points' covariance, extent along each, sorted decreasing), its volume,
// its point count and its occupancy (voxels of occupancy_voxel_m holding a point). The
// recognition computes the same from one point per occupied voxel (docs/recognition.md).
struct ShapeStats {
  Eigen::Vector3d sides = Eigen::Vector3d::Zero();  // l[1] >= l[2] >= l[3], m
  double volume = 0;                                // m³
  std::size_t points = 0;
  std::size_t occupancy = 0;
};
ShapeStats shape_stats(const std::vector<Eigen::Vector3f>& points, double occupancy_voxel_m);

// Eq. 6.4-6.7: which test a subspace fails (None: kept).
enum class SubspaceTest { None, Fit, Volume, Points, Occupancy };
const char* subspace_test_name(SubspaceTest t);  // "kept", "obb_fit", "volume", ...
SubspaceTest subspace_test(const ShapeStats& subspace, const ShapeStats& model,
                           const Recognition3dConfig& config);

// Voxel-grid subsampling: the centroid of the points in each voxel of edge voxel_m.
std::vector<Eigen::Vector3f> voxel_subsample(const std::vector<Eigen::Vector3f>& points,
                                             double voxel_m);

// Global registration of a model onto scene points when no orientation is known (the role
// Go-ICP plays in sec. 6.3.1.2): rotation hypotheses aligning the principal axes of the model's
// samples with the scene's under each of the 24 rotations of the cube (axis order and signs
// unknown), each scored by the trimmed mean nearest-sample distance, then a coarse and a fine
// trimmed ICP from the `starts` best. Not a branch and bound: it trusts the principal axes to
// within ICP's basin (docs/recognition.md says where it breaks).
IcpResult global_registration(const ModelIndex& model, const std::vector<Eigen::Vector3f>& scene,
                              const Recognition3dConfig& config, double* score_m = nullptr);

// The acceptance terms of one matched placement (see Recognition3dConfig, "Decision"). NaN when
// not measured (nothing matched).
struct Verification3d {
  double residual_median_m = std::numeric_limits<double>::quiet_NaN();
  double coverage = std::numeric_limits<double>::quiet_NaN();
  double violation = std::numeric_limits<double>::quiet_NaN();
  double unexplained = std::numeric_limits<double>::quiet_NaN();
  double observed = std::numeric_limits<double>::quiet_NaN();  // of the top samples, observed
  double tilt_deg = std::numeric_limits<double>::quiet_NaN();
  // End continuation (issue 28, beyond the thesis): for a model elongated in the top view (its
  // footprint at least elongation_min times as long as wide), the smaller over its two ends of
  // the fraction of observed cells in a strip beyond the end (along the model's axis, the
  // central half of its width) where the surveyed surface stands at least half the model's
  // exposed height above the seabed: the relief continues beyond both ends, the model lies on a
  // section of a longer structure (a shell on a pipeline). An end not observed (beyond the
  // survey's edge) is left out. NaN: not elongated, or neither end observed.
  double end_continuation = std::numeric_limits<double>::quiet_NaN();
};

// A matched candidate the method did not accept (its pose, the test that rejected it, its
// terms): written to the JSON's "candidates" list so that every rejection can be labelled
// against the truth (bench/recognition_fields.sh calib).
struct Candidate3dRecord {
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  std::string reason;
  Verification3d terms;
  double confidence = std::numeric_limits<double>::quiet_NaN();  // NaN: not verified
  double start_score_m = std::numeric_limits<double>::quiet_NaN();
};

// Per model: what the subspace analysis and the matching did.
struct Search3dRecord {
  std::string model;
  double r_model_m = 0, r_subspace_m = 0, period_m = 0;
  bool period_raised = false;  // T raised above period_fraction · r_model by max_subspaces
  bool planar = false;         // centres on the horizontal lattice (upright prior)
  std::size_t model_samples = 0, model_visible = 0;  // subsampled model, of which seen from above
  std::size_t subspaces = 0;                // centres with at least one point within r_subspace
  std::size_t kept = 0;                     // passed eq. 6.4-6.7
  std::size_t failed[5] = {0, 0, 0, 0, 0};  // per SubspaceTest (index 0 unused)
  std::size_t registered = 0;   // survivors matched (one per group with nearly the same points)
  std::size_t sites = 0;        // start sites of the matched survivors (upright)
  std::size_t sites_swept = 0;  // of which swept at every yaw (coarse to fine: coarse_sites each)
  std::size_t passed = 0;       // survivors whose match passed the residual and coverage
  std::size_t suppressed = 0;   // passed but overlapping a better placement
  std::size_t accepted = 0;
  // Why nothing (more) was accepted: the matched survivor that came nearest to passing (highest
  // confidence, else highest coverage) with the test it failed, or, when no survivor was matched,
  // the subspace test that rejected most subspaces. The figures are NaN when no match was made
  // (never a "perfect" 0).
  std::string nearest_miss;  // e.g. "coverage 0.31 < 0.5", "all 812 subspaces failed: obb_fit 790"
  double best_rejected_coverage = std::numeric_limits<double>::quiet_NaN();
  double best_rejected_residual_m = std::numeric_limits<double>::quiet_NaN();
  Verification3d nearest_miss_terms;
  double best_rejected_confidence = std::numeric_limits<double>::quiet_NaN();
  std::vector<Verification3d> accepted_terms;  // per accepted placement, in output order
  std::vector<Candidate3dRecord> rejected;     // matched candidates not accepted
  double seconds_subspaces = 0, seconds_matching = 0;
};

// The 3D method's acceptance terms of `model` placed at T_world_model in a world-frame cloud
// (the seabed estimated and removed as in recognize_3d). For tests and for judging a placement
// found otherwise. Errors: an empty cloud.
Verification3d verify_placement_3d(const ModelTemplate& model,
                                   const Eigen::Isometry3d& T_world_model,
                                   const PointCloud& scene_world,
                                   const Recognition3dConfig& config);

// The whole 3D method on a world-frame cloud: placements with method "3d" (score_m: the start's
// trimmed mean distance; support: the coverage). Errors: an empty catalogue or cloud, a model
// larger than the scene.
RecognitionResult recognize_3d(const PointCloud& scene_world,
                               const std::vector<ModelTemplate>& models,
                               const Recognition3dConfig& config,
                               std::vector<Search3dRecord>* searches = nullptr,
                               bool progress = false);

// Placements of the 3D method as JSON (the format of placements_json, method "3d", with the 3D
// settings and the subspace analysis per model).
std::string placements_json_3d(const RecognitionResult& result,
                               const std::vector<Search3dRecord>& searches,
                               const std::string& map_source, const std::string& catalogue_source,
                               const Recognition3dConfig& config);

}  // namespace sonar3d
