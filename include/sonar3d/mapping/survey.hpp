#pragma once
// Field mapping (thesis sec. 6.2): a survey split into swaths at its turns, each swath carved and
// mapped on its own (streaming: memory follows one swath), the swath maps registered to each
// other, the navigation corrected, and the merged cloud and elevation map built with it.
//
//   MapSurveyConfig cfg;                      // defaults: 2 cm maps, ±0.5 m search, global
//   MapSurveyResult r = map_survey(dataset, cfg, "mapdir");
//
// World frame: local ENU. A swath's offset o = (dx, dy, dz) is added to the positions of its
// frames (and of its cloud) to correct them.
#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/mpi.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/position_fixes.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "sonar3d/recon/carve.hpp"

namespace sonar3d {

enum class SwathAdjustMethod {
  Consecutive,  // the thesis: each swath against the previous one, offsets accumulated
  Global,       // every overlapping pair, one robust least-squares adjustment
  Drift         // every overlapping pair, piece by piece: a drift rate per swath as well
};

inline constexpr const char* kSwathAdjustMethodNames[] = {"consecutive", "global",
                                                          "drift"};  // by SwathAdjustMethod
const char* to_string(SwathAdjustMethod method);  // "consecutive", "global", "drift"
// Throws Error naming the choices.
SwathAdjustMethod swath_adjust_method_from_string(const std::string& name);

struct SwathSplitConfig {
  // A new swath starts where the direction of travel turns by more than this from the current
  // swath's (the turns of a lawnmower), degrees.
  double turn_threshold_deg = 30;
  // Where the track bends tighter than this radius of curvature (measured over 1 m of track
  // either side of a frame) the vehicle is turning: those frames belong to no swath, m.
  double straight_radius_m = 20.0;
  int min_frames = 10;  // shorter runs belong to no swath
  // Straight runs shorter than this fraction of the survey's longest run (the legs across the
  // lines inside wide turns) belong to no swath.
  double min_length_fraction = 0.25;
  // Alternatively, explicit swaths as time ranges t0 t1 [t0 t1 ...] (s); when set, turns are not
  // searched.
  params::List time_ranges_s;

  void validate() const;
};

// The one declaration of SwathSplitConfig's fields (core/params.hpp).
template <class V>
void describe(SwathSplitConfig& c, V& v) {
  using params::param;
  v.field(c.turn_threshold_deg, param("turn_threshold_deg", "deg",
                                      "a new swath starts where the track turns by more than this")
                                    .range_open(0, 180)
                                    .flag("--turn-deg"));
  v.field(c.straight_radius_m,
          param("straight_radius_m", "m",
                "where the track bends tighter than this radius the vehicle is turning: those "
                "frames belong to no swath")
              .positive());
  v.field(c.min_frames, param("min_frames", "", "shorter runs belong to no swath").at_least(2));
  v.field(c.min_length_fraction,
          param("min_length_fraction", "",
                "straight runs shorter than this fraction of the longest belong to no swath")
              .range(0, 1));
  v.field(c.time_ranges_s,
          param("time_ranges_s", "s",
                "explicit swaths instead of turns: t0 t1 [t0 t1 ...], each pair a swath's time "
                "range")
              .flag("--swath-times"));
}

// Known structure poses (issue 26 item 3). A structure recognised in a map of this survey
// (`sonar3d recognize`'s placements: the model frame's origin), in the frame of the map it was
// recognised in.
struct RecognisedStructure {
  std::string model;
  Eigen::Vector3d p_map = Eigen::Vector3d::Zero();
  int index = 0;  // in its placements file, for reports
};
// Where a structure is known to be, world (ENU) frame: a previous survey's world model, or an
// as-built drawing's T_world_model (its translation: the model frame's origin).
struct KnownStructurePose {
  std::string model, id;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
};

struct MapSurveyConfig {
  SwathSplitConfig split;
  CarveConfig carve = [] {
    CarveConfig c;
    c.voxel_size = 0.02;  // the thesis' field maps: 2 cm
    return c;
  }();
  double cell_m = 0.02;  // elevation map resolution, m
  SwathRegistrationConfig registration;
  SwathAdjustmentConfig adjustment;
  SwathAdjustMethod method = SwathAdjustMethod::Global;
  // The drift method registers each swath in pieces of this length along its track against the
  // swaths it overlaps, m.
  double piece_m = 10.0;
  // Absolute references (issue 26, io/position_fixes.hpp): USBL/GNSS fixes of the navigation's
  // reference point, in its world frame and clock. With them the global or drift adjustment places
  // the map in the world, estimates the navigation's scale error and heading bias
  // (fix_scale_heading) and rejects fixes beyond fix_gate_sigma. Fixes outside the frames' time
  // span are ignored and counted.
  std::vector<PositionFix> fixes;
  std::string fixes_source;  // where they came from, for the record
  bool fix_scale_heading = true;
  double fix_gate_sigma = 3.0;
  // Known structure poses (issue 26 item 3): each recognised structure is matched to the nearest
  // known pose of the same model within known_pose_match_m (horizontally, in the map's frame
  // against the world's); a match is a constraint of the same adjustment as the fixes: the point
  // the sonar saw there, corrected, at the known position, horizontally, with σ
  // known_pose_sigma_m, gated (fix_gate_sigma) and reported like a fix. `recognised_navigation`
  // is the vehicle navigation of the map the structures were recognised in (that map's
  // navigation_corrected.tum); empty: the logged navigation (a map built as logged).
  std::vector<RecognisedStructure> recognised;
  Trajectory recognised_navigation;
  std::vector<KnownStructurePose> known_poses;
  std::string recognised_source, known_poses_source;  // for the record
  double known_pose_sigma_m = 0.03;
  double known_pose_match_m = 2.0;

  void validate() const;
};

// The one declaration of MapSurveyConfig's settings (core/params.hpp): `sonar3d map`'s flags,
// --print-config and --config, the survey's `map:` block and Python's MapSurveyConfig. The
// inputs (fixes, recognised structures, known poses) are files the command reads, not settings.
// The carving's voxel size, region and threads are the map's; the registration runs on the
// carving's threads.
template <class V>
void describe(MapSurveyConfig& c, V& v) {
  using params::param;
  v.field(c.cell_m, param("cell_m", "m", "elevation map cell").positive().flag("--resolution"));
  v.field(c.carve.voxel_size,
          param("voxel_size", "m", "carving voxel edge").range(1e-5, 1e3).flag("--voxel-size"));
  v.field(c.carve.region,
          param("region", "m", "world-frame region to carve (none = all the sonar sees)")
              .flag("--roi"));
  v.field(c.method, param("method", "",
                          "consecutive (the thesis: each swath against the previous), global "
                          "(every overlapping pair, one robust adjustment of swath offsets) or "
                          "drift (every overlapping pair piece by piece, a drift rate per swath "
                          "as well)")
                        .choices(kSwathAdjustMethodNames)
                        .equation("sec. 6.2.2")
                        .flag("--method"));
  v.field(c.piece_m, param("piece_m", "m", "drift method: length of the swath pieces registered")
                         .positive()
                         .flag("--piece"));
  v.field(
      c.carve.num_threads,
      param("num_threads", "", "worker threads (0 = all cores)").non_negative().flag("--threads"));
  v.field(c.fix_scale_heading,
          param("fix_scale_heading", "",
                "with fixes or known poses: estimate the navigation's scale error and heading "
                "bias (else the map is placed by a shift only)")
              .flag("--fixes-shift-only"));
  v.field(c.fix_gate_sigma,
          param("fix_gate_sigma", "",
                "a fix or known pose whose residual after the adjustment exceeds this many "
                "standard deviations (1-D equivalent probability) is rejected and reported")
              .positive()
              .flag("--fix-gate"));
  v.field(c.known_pose_sigma_m,
          param("known_pose_sigma_m", "m",
                "standard deviation of a recognised structure against its known pose, per "
                "horizontal axis")
              .range_open_low(0, kMaxFixSigma)
              .flag("--known-pose-sigma"));
  v.field(c.known_pose_match_m,
          param("known_pose_match_m", "m",
                "a recognised structure matches a known pose of its model within this "
                "horizontal distance")
              .positive()
              .flag("--known-pose-radius"));
  v.group("split", c.split);
  params::Nested<SwathRegistrationConfig> registration{c.registration};
  v.group("registration", registration);
  v.group("adjustment", c.adjustment);
  params::Nested<CarveConfig> carve{c.carve};
  v.group("carve", carve);
}

struct SwathInfo {
  int first_frame = 0, last_frame = 0;  // inclusive, dataset frame indices
  double t0 = 0, t1 = 0;                // time span, s
  std::size_t points = 0, map_cells = 0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // the correction at t0, m
  Eigen::Vector2d rate = Eigen::Vector2d::Zero();    // its horizontal drift rate (drift), m/s
  double seconds = 0;                                // carving + mapping
  // Simulated datasets with truth/navigation.tum: the correction that would be exact (the mean
  // over the swath's frames of true − logged position, relative to swath 0's), and the mean
  // over its frames of the navigation's error (true − logged − correction, relative to the error
  // where swath 0 starts — the gauge), horizontal and vertical, before and after correction.
  bool has_truth = false;
  Eigen::Vector3d true_offset = Eigen::Vector3d::Zero();
  Eigen::Vector2d error_before = Eigen::Vector2d::Zero(), error_after = Eigen::Vector2d::Zero();
  // The same after the map's best rigid placement in the world (turn and shift, fitted to the
  // true navigation) is taken out: the error within the map, in metres — a scale error of the
  // navigation stays in it.
  Eigen::Vector2d rigid_error_before = Eigen::Vector2d::Zero();
  Eigen::Vector2d rigid_error_after = Eigen::Vector2d::Zero();
  // The same after the best affine placement (MapAlignment) is taken out: what registration
  // between swaths can see (the map's local shape). It also absorbs a uniform scale, shear and
  // stretch of the whole map, so it is never the map's error in metres.
  Eigen::Vector2d affine_error_before = Eigen::Vector2d::Zero();
  Eigen::Vector2d affine_error_after = Eigen::Vector2d::Zero();
};

// How a whole map sits in the world: a stretch, shear, turn and shift of (x, y) and a height
// offset — what a DVL scale error, a steady velocity bias, a heading bias, a depth sensor offset
// and the start position do to every swath alike, leaving the swaths agreeing with each other.
// No registration between swaths can observe it (the thesis' neither); with a simulated truth it
// is fitted (least squares over the swaths' frames) and taken out before the map's internal
// errors are scored.
struct MapAlignment {
  Eigen::Matrix2d M = Eigen::Matrix2d::Identity();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double dz = 0;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d xy = M * p.head<2>() + b;
    return {xy.x(), xy.y(), p.z() + dz};
  }
  // The uniform scale M applies, √|det M| (1 for a rigid placement; 1/(1 + s) for a navigation
  // whose velocities are scaled by 1 + s), and its stretch, the ratio of M's singular values.
  double scale() const { return std::sqrt(std::abs(M.determinant())); }
  double stretch() const;
};

// The navigation's error over a whole survey (simulated datasets): medians over the frames of
// the horizontal error, absolute (relative to the error where the first swath starts), after the
// best rigid placement (turn + shift: the map's error in metres) and after the best affine
// placement (local shape only), as logged or corrected.
//
// world_m: the horizontal error in the world frame itself, no gauge taken out — what absolute
// fixes are for. With fixes, absolute_m is measured the same way (the fixes, not swath 0's start,
// are the gauge).
struct NavigationError {
  double absolute_m = 0, rigid_m = 0, affine_m = 0, world_m = 0;
};

// Simulated datasets with truth/scene.yaml: a structure or pipeline scored against its CAD in
// the merged cloud as logged (before) and corrected (after), each aligned to the world first
// (MapAlignment), thesis sec. 4.5.2.1 metrics.
struct StructureEval {
  std::string name;
  ObjectKind kind = ObjectKind::Structure;
  EvalResult before, after;
};

struct MapSurveyResult {
  std::vector<SwathInfo> swaths;
  std::vector<StructureEval> structures;  // empty without ground truth
  // With truth/navigation.tum: the map's placement, as logged and corrected.
  bool has_alignment = false;
  MapAlignment alignment_before, alignment_after;  // affine (structures are scored after it)
  MapAlignment rigid_before, rigid_after;          // rigid (M a rotation)
  NavigationError navigation_before, navigation_after;
  std::vector<SwathTie> ties;
  SwathAdjustment adjustment;
  std::size_t merged_points = 0;
  // With fixes: how many were given, and how many fell outside the frames' time span (ignored);
  // the others are in adjustment.fixes (rejected ones flagged).
  std::size_t fixes_given = 0, fixes_outside = 0;
  // With known structure poses: each recognised structure matched to a known pose, where the
  // sonar saw it (swath, time), and its entry in adjustment.fixes (FixReport::name = the known
  // pose's id); the recognised structures no known pose matched.
  struct KnownPoseMatch {
    std::string model, id;
    int recognised_index = 0;
    Eigen::Vector3d p_map = Eigen::Vector3d::Zero(), p_world = Eigen::Vector3d::Zero();
    int swath = 0;
    double time = 0;
    std::size_t constraint = 0;  // index into adjustment.fixes
  };
  std::vector<KnownPoseMatch> known_matches;
  std::vector<int> recognised_unmatched;  // RecognisedStructure::index
  double seconds_carving = 0, seconds_registration = 0, seconds_total = 0;
};

// Swaths of a dataset as [first, last] frame index ranges (validated: at least one).
std::vector<std::pair<int, int>> split_swaths(const Dataset& dataset,
                                              const SwathSplitConfig& config);

// Memory map_survey() will take (core/memory.hpp), before it allocates: the carving of the
// largest swath (swaths are carved one at a time) and the elevation maps (each swath's, the merged
// and the uncorrected one) over the area the footprints cover. With `limit_bytes` > 0 the advice
// names the voxel size that fits.
MemoryEstimate estimate_map_survey_memory(const Dataset& dataset, const MapSurveyConfig& config,
                                          double limit_bytes = 0);

// Runs the whole field mapping and writes into `out_dir` (which must not exist; written under a
// temporary name and renamed when complete):
//   swaths/swath_NN.ply, .tif, .png   per-swath cloud and elevation map (as logged)
//   ties.json                         every registered pair: shift, score, overlap, confidence
//   navigation_corrected.tum          the vehicle navigation with the swath offsets applied
//                                     (interpolated in time across turns)
//   merged.ply, merged.tif, merged.png      the field with the correction
//   merged_uncorrected.png                  the field as logged, for comparison
//   summary.json                      swaths, offsets, ties, timings; with truth/navigation.tum
//                                     (simulated drift) each swath's offset error before and
//                                     after the correction; with truth/scene.yaml each
//                                     structure's and pipeline's median error, coverage and
//                                     outliers against its CAD before and after
// Progress: one bar over the frames.
//
// With an MPI session of several ranks (`mpirun -np N sonar3d map ...`), rank r carves the swaths
// s ≡ r (mod N) and sends their clouds to rank 0, which registers, merges and alone writes
// `out_dir` (the ranks need not share a file system, but each reads the dataset); the other
// ranks return an empty result. Rank 0 then holds every swath's cloud at once.
MapSurveyResult map_survey(const Dataset& dataset, const MapSurveyConfig& config,
                           const std::filesystem::path& out_dir, bool progress = true,
                           const MpiSession* mpi = nullptr);

}  // namespace sonar3d
