#pragma once
// Registration of swath elevation maps (thesis sec. 6.2.2.1) and, beyond the thesis, one robust
// least-squares adjustment of all swath offsets from every overlapping pair.
//
// Frames: local ENU world (x East, y North, z up). The thesis searches a North/East shift and
// aligns depths; here the shift is (dx, dy) = (East, North) and the vertical offset dz is a height.
// A registration of a moving map B against a reference map A returns the translation
// t = (dx, dy, dz) that moves B onto A: A(x, y) ≈ B(x − dx, y − dy) + dz.
#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

struct SwathRegistrationConfig {
  double search_m = 0.5;        // ±ΔN = ±ΔE: half-width of the exhaustive search window, m
  int min_overlap_cells = 200;  // fewer overlapping defined cells than this: no tie
  // Sub-cell refinement (beyond the thesis' cell-resolution search): eq. 6.1–6.2 evaluated at
  // fractional shifts within ±½ cell of the best one, every tenth of a cell, on the reference
  // map interpolated bilinearly.
  bool subcell = true;
  // A tie's confidence is scaled down when the overlap has fewer cells than this (it reaches its
  // full value at overlap_full_cells).
  int overlap_full_cells = 5000;
  // Beyond the thesis: search the window on maps coarse_factor times coarser (each block its
  // highest cell), then ±coarse_factor cells around the winner at map resolution. 1 = the
  // thesis' exhaustive search of every cell shift. Used when the window exceeds 2·coarse_factor
  // cells.
  int coarse_factor = 4;
  int num_threads = 0;  // 0 = all cores

  void validate() const;  // throws Error naming the parameter
};

// The one declaration of SwathRegistrationConfig's fields (core/params.hpp). A config that sets
// the threads itself (field mapping) describes it as Nested<SwathRegistrationConfig>.
template <class V>
void describe_swath_registration_own(SwathRegistrationConfig& c, V& v) {
  using params::param;
  v.field(c.search_m,
          param("search_m", "m", "half-width of the searched shifts (East, North) between two maps")
              .non_negative()
              .equation("sec. 6.2.2.1, eq. 6.1-6.2")
              .flag("--search"));
  v.field(c.min_overlap_cells,
          param("min_overlap_cells", "", "fewer cells defined in both maps: no tie")
              .at_least(1)
              .flag("--min-overlap-cells"));
  v.field(c.subcell, param("subcell", "",
                           "refine the best shift to a tenth of a cell on the bilinearly "
                           "interpolated reference (beyond the thesis)"));
  v.field(c.overlap_full_cells,
          param("overlap_full_cells", "",
                "a tie's confidence is scaled down when the overlap has fewer cells than this")
              .at_least(1));
  v.field(c.coarse_factor, param("coarse_factor", "",
                                 "search on maps this many times coarser, then around the "
                                 "winner at map resolution (1 = the thesis' exhaustive search)")
                               .range(1, 64)
                               .flag("--coarse-factor"));
}
template <class V>
void describe(SwathRegistrationConfig& c, V& v) {
  describe_swath_registration_own(c, v);
  v.field(c.num_threads, params::param("num_threads", "", "worker threads (0 = all cores)")
                             .non_negative()
                             .flag("--threads"));
}
template <class V>
void describe(params::Nested<SwathRegistrationConfig>& n, V& v) {
  describe_swath_registration_own(n.c, v);
}

struct SwathTie {
  int reference = -1, moving = -1;              // swath indices (A, B)
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  // (dx, dy, dz) moving B onto A, m
  double score_m = 0;  // eq. 6.2 at the best shift: median |A − B − ζ| over the overlap, m
  std::size_t overlap_cells = 0;  // defined in both maps at the best shift
  // 0…1. The score surface of a featureless (flat) overlap is flat: the best shift is barely
  // better than a typical one, and confidence is near 0. Computed on the mean unsigned
  // difference m (eq. 6.2's median is often 0 on carved seabed, whose heights come in voxel
  // steps) as (1 − m_best / median of m over the searched shifts) · min(1, overlap /
  // overlap_full_cells).
  double confidence = 0;
  double seconds = 0;
  // Where the tie was measured along each swath, as navigation times (s): set by the field
  // mapping's drift method, which registers pieces of swaths; NaN otherwise.
  double time_reference = std::numeric_limits<double>::quiet_NaN();
  double time_moving = std::numeric_limits<double>::quiet_NaN();
  // The logged vehicle positions' difference (reference − moving, horizontal) where each swath
  // passed abeam of the tie's overlap: set by field mapping, used with absolute references. A
  // swath map is the vehicle's position plus the sonar's rays; the navigation model scales the
  // vehicle's displacements (a DVL scale error), not the rays (ranges carry none), so a tie
  // carried into the corrected frame reads c_B − c_A = R(−β)·(t − s/(1 + s)·nav_separation):
  // between lines 6 m apart a 1 % scale error is a 6 cm tie that the model itself explains.
  Eigen::Vector2d nav_separation = Eigen::Vector2d::Zero();
};

// Sec. 6.2.2.1: every integer cell shift (i, j) in [−S, S]² (S = search_m / cell size) is scored
// over the cells defined in both maps: ζ = the signed median of A − B (eq. 6.1: the depth
// distributions aligned), score = median |A − B − ζ| (eq. 6.2); undefined cells are discarded.
// The lowest score wins (ties, common where heights come in voxel steps, go to the lowest mean
// unsigned difference); dz = ζ there. Both maps must share the cell size and have their origins
// on a common cell grid. Parallel over shifts (TBB). Throws Error when no shift overlaps by
// min_overlap_cells.
SwathTie register_elevation_maps(const ElevationMap& reference, const ElevationMap& moving,
                                 const SwathRegistrationConfig& config);

// Whether two maps overlap at all (their extents, grown by the search window, intersect).
bool maps_may_overlap(const ElevationMap& a, const ElevationMap& b, double search_m);

struct SwathAdjustmentConfig {
  // Robust loss scale (Cauchy), m: ties that disagree with the others by much more than this
  // are down-weighted instead of pulling the solution.
  double loss_scale_m = 0.05;
  double min_confidence = 0.05;  // ties below this confidence are left out
  int max_iterations = 100;
  // The drift method's priors: the navigation drifts by about this fraction of the distance
  // travelled (the thesis: about 1 %). Sets how far a swath's drift rate may stray from 0 and how
  // much the correction may change across a turn.
  double nav_drift_fraction = 0.01;

  void validate() const;
};

// The one declaration of SwathAdjustmentConfig's fields (core/params.hpp).
template <class V>
void describe(SwathAdjustmentConfig& c, V& v) {
  using params::param;
  v.field(c.loss_scale_m,
          param("loss_scale_m", "m",
                "robust loss scale (Cauchy): ties that disagree with the others by much more "
                "than this are down-weighted")
              .positive());
  v.field(c.min_confidence,
          param("min_confidence", "", "ties below this confidence are left out").range(0, 1));
  v.field(c.max_iterations,
          param("max_iterations", "", "iterations of the least-squares solver").at_least(1));
  v.field(c.nav_drift_fraction,
          param("nav_drift_fraction", "",
                "drift method: the navigation drifts by about this fraction of the distance "
                "travelled (the thesis: about 1 %); bounds a swath's drift rate and its change "
                "across a turn")
              .range_open(0, 1));
}

// Absolute references (issue 26): a position fix as the adjustment sees it. mapping/survey.cpp
// builds these from io's PositionFix and the navigation.
struct AbsoluteFix {
  double time = 0;                                     // s
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();   // the fix, world (ENU), m
  Eigen::Vector3d p_logged = Eigen::Vector3d::Zero();  // the navigation's position then, m
  bool has_z = false;                                  // else only x, y constrain
  double sigma_m = 1;                                  // per axis, m
  int line = 0;                                        // in its file, for reports
  // The swath correction at `time`: (1 − w)·c_a(t_a) + w·c_b(t_b) (w = 0: swath a alone; a
  // fix in a turn is tied to both swaths, as the corrected navigation interpolates there).
  int swath_a = 0, swath_b = 0;
  double time_a = 0, time_b = 0, weight_b = 0;
  // A known structure pose (issue 26 item 3) is the same constraint on a point the sonar saw
  // rather than on the vehicle: the recognised structure's position relative to the vehicle when
  // it passed over it, in the logged frame. The sonar's ranges carry no DVL scale, so the
  // corrected point is the corrected vehicle position + R(−β)·lever (turned by the heading
  // correction, not scaled). Zero for a fix.
  Eigen::Vector3d lever = Eigen::Vector3d::Zero();
  std::string name;  // a known structure's name for reports; empty for a fix
};

struct AbsoluteConstraints {
  std::vector<AbsoluteFix> fixes;
  // Where dead reckoning started (the navigation's first position): the navigation model's
  // scale and turn act about it.
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  // Estimate the navigation's scale error and heading bias as well (with at least 3 constraints
  // in use, or 2 at least min_baseline_m apart horizontally: two known structures fix a scale and
  // a turn); else only the absolute placement (a shift).
  bool estimate_scale_heading = true;
  double min_baseline_m = 1.0;
  // A fix whose residual after the solve exceeds this many σ (as the 1-D gate: the same
  // probability, 99.73 % at 3, for the 2-D or 3-D residual) is rejected; solve and gate repeat
  // until the rejected set no longer changes (at most max_rounds solves).
  double gate_sigma = 3.0;
  // Cauchy loss scale on a fix's residual in σ: a gross outlier pulls little even before it is
  // rejected.
  double loss_sigma = 2.0;
  int max_rounds = 10;
  // Plausibility priors on the navigation model, centred on 0: they only keep it bounded where
  // the fixes hardly constrain it (a few fixes close together); informative fixes give σ far
  // below them (the field: 0.3–0.7 %, 0.2–0.4°). A DVL's scale error is about 1 %, a compass's
  // bias under a degree or two.
  double scale_prior_sigma = 0.05;
  double heading_prior_sigma_rad = 5.0 * 3.14159265358979323846 / 180.0;

  void validate() const;
};

struct FixReport {
  double time = 0;
  int line = 0;
  std::string name;       // AbsoluteFix::name: a known structure's; empty for a fix
  double residual_m = 0;  // |corrected navigation − fix| at the solution (horizontal without z)
  double normalized = 0;  // residual_m / σ
  bool rejected = false;
};

struct SwathAdjustment {
  std::vector<Eigen::Vector3d> offsets;  // per swath (dx, dy, dz) to add to its positions, m
  // The drift method: per swath a horizontal drift rate r (m/s) from the time rate_t0: the
  // correction at time t is offsets + (r, 0)·(t − rate_t0). Zero for the other methods.
  std::vector<Eigen::Vector2d> rates;
  std::vector<double> rate_t0;
  std::vector<double> tie_residual_m;  // per tie, |o_B − o_A − t| at the solution
  std::vector<bool> tie_used;          // per tie: confident enough to take part
  int iterations = 0;
  double final_cost = 0;

  // With absolute fixes: the navigation model. Dead reckoning logs displacements turned by the
  // heading bias β (counter-clockwise about z) and scaled by 1 + s (a DVL scale error):
  //   p_logged − pivot = (1 + s)·R(β)·(p_true − pivot)  (horizontal),
  // so the corrected position is pivot + R(−β)·(p_logged − pivot)/(1 + s) plus the swath
  // correction. nav_model = (s, β); zero and held without fixes. σ from the solution's
  // covariance (NaN when not estimated).
  bool has_fixes = false;
  bool estimated_scale_heading = false;
  Eigen::Vector2d nav_model = Eigen::Vector2d::Zero();
  double scale_error_sigma = std::numeric_limits<double>::quiet_NaN();
  double heading_bias_sigma_rad = std::numeric_limits<double>::quiet_NaN();
  // σ of the absolute horizontal placement (swath 0's correction), m.
  Eigen::Vector2d placement_sigma_m =
      Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  std::vector<FixReport> fixes;  // per fix given, in order
  int fix_rounds = 0;            // solves of the rejection loop

  double scale_error() const { return nav_model.x(); }
  double heading_bias_rad() const { return nav_model.y(); }
  // The correction of swath s at time t (s), m (the navigation model not included).
  Eigen::Vector3d correction(int s, double t) const;
  // The navigation model applied to a logged position (identity without fixes).
  Eigen::Vector3d apply_navigation_model(const Eigen::Vector3d& p_logged) const;
  // The corrected position of swath s's navigation at time t, logged at p_logged.
  Eigen::Vector3d corrected(int s, double t, const Eigen::Vector3d& p_logged) const {
    return apply_navigation_model(p_logged) + correction(s, t);
  }
};

// The thesis' method: each swath registered to the previous one, offsets accumulated along the
// survey (swath 0 fixed). `ties` must hold (i−1, i) for every i ≥ 1.
SwathAdjustment accumulate_consecutive(int num_swaths, const std::vector<SwathTie>& ties);

// Beyond the thesis: all ties at once. Unknowns o_i ∈ R³ per swath (swath `fixed_swath` held at
// 0, the gauge); each tie (A, B, t, confidence w) contributes the residual
// √w · (o_B − o_A − t) under a Cauchy loss; solved by Ceres. Swaths that no usable tie connects to
// the fixed one are an error naming them.
//
// With `absolute` fixes (issue 26): each fix adds (corrected navigation at its time − fix) / σ
// under a Cauchy loss (AbsoluteConstraints::loss_sigma), the gauge is released (swath 0 is placed
// by the fixes; its height stays held when no fix has z), the navigation model (scale error,
// heading bias) is estimated, ties then read c_B − c_A = R(−β)·(t − s/(1 + s)·nav_separation) (a
// tie measured between logged maps, carried into the corrected one) with residuals in units of
// 2 cm, and fixes
// beyond the gate are rejected and reported (SwathAdjustment::fixes). An error when every fix is
// rejected.
SwathAdjustment adjust_swaths(int num_swaths, const std::vector<SwathTie>& ties,
                              const SwathAdjustmentConfig& config, int fixed_swath = 0,
                              const AbsoluteConstraints* absolute = nullptr);

// Beyond the thesis and its consecutive registration: the drift of dead reckoning within each
// swath. A swath's correction varies linearly in time, c_s(t) = o_s + (r_s, 0)·(t − t0_s), and
// ties measured between pieces of swaths at times (t_A, t_B) (SwathTie::time_reference,
// time_moving) give the residual √w · (c_B(t_B) − c_A(t_A) − t) / 2 cm under a Cauchy loss.
// Priors from the navigation's drift fraction f: the correction is continuous across each turn
// within max(1 cm, f · the turn's length), and each drift rate stays within f · the swath's
// speed of 0. The gauge: the navigation is exact where swath 0 starts (c_0(t0_0) = 0). The
// constant-offset adjustment (adjust_swaths) gives the initial guess.
struct SwathTiming {
  double t0 = 0, t1 = 0;     // the swath's time span, s
  double speed_mps = 0;      // its mean speed over ground, m/s
  double gap_to_next_m = 0;  // track length of the turn to the next swath, m
};
// With `absolute` fixes: as adjust_swaths (the gauge released, the navigation model estimated,
// outliers rejected).
SwathAdjustment adjust_swaths_drift(const std::vector<SwathTiming>& swaths,
                                    const std::vector<SwathTie>& ties,
                                    const SwathAdjustmentConfig& config,
                                    const AbsoluteConstraints* absolute = nullptr);

// A copy of `map` with its origin moved by (dx, dy) and heights by dz.
ElevationMap shifted(const ElevationMap& map, const Eigen::Vector3d& t);

}  // namespace sonar3d
