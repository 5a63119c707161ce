#pragma once
// How well a reconstruction knows each point's elevation (beyond the thesis).
//
// A sonar return fixes range and bearing but not elevation: the scatterer lies somewhere on an arc
// across the vertical aperture (thesis sec. 2.2, Fig. 4.4). Carving localises it with the
// min-filter of eq. 4.6 and the free space of Fig. 4.5, deconvolution with the layer model of
// eq. 5.25–5.28; both only where frames saw the point from both sides of its elevation — some from
// above (the point below their image plane, θ < 0) and some from below (θ > 0). Where a pass
// stops, the space beyond its last frames is seen from one side only and the returns' arcs stay
// there as ghosts (docs/experiments.md: passes must run 2·r·tan(A_v/2) past the object).
//
// For a world point p and the frames whose field of view holds it, with θ_k its elevation in
// frame k and s_k = sin θ_k / sin θ_3dB in [-1, 1]:
//   views   = the number of such frames,
//   bracket = min(max(0, −min_k s_k), max(0, max_k s_k)) in [0, 1]: 1 = seen at both edges of
//             the aperture, 0 = every frame saw it on the same side (never bracketed).
// assess_bracketing() attaches both as point properties ("bracket", "views": PLY vertex
// properties), measures the share of the observed region that is not bracketed, and, for each
// pass that sweeps the elevation (motion along the sonar's z), says how far it should have
// continued past the surface it saw (2·r·tan(A_v/2), r the surface's distance from the pass).
// Only poses and the sensor geometry are used, so it works for every method and trajectory.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

class Progress;

struct BracketConfig {
  // Drop output points whose bracket is below this (0 = keep all). A ghost arc beyond the end of
  // a pass is seen from one side only; a surface the pass covered is seen from both.
  double min_bracket = 0.0;
  // When min_bracket is 0 and a pass stops short (a PassExtension: the data shows unbracketed
  // space beyond a pass end, where ghost arcs lie), drop the points bracketed less than
  // bracketed_level anyway (issue 29); and over level frames at several heights whose top stops
  // short, the points seen from below only (level_view_above). One orbit at one height and level
  // approaches find neither and keep everything. Off here; a reconstruction's carving turns it on
  // (ReconstructConfig).
  bool auto_min_bracket = false;
  // A point (or region sample) counts as bracketed when its bracket is >= this; the summary
  // reports the share of the observed region below it.
  double bracketed_level = 0.5;
  // The pass-end rule: the extreme surface of a pass is the farthest point some frame of the pass
  // saw at |s| >= end_view_fraction on the other side; ghosts beyond a short pass are seen there
  // at most from the pass' last frames, so they do not move it far.
  double end_view_fraction = 0.9;
  // Warn when a pass stops short of the rule by more than this fraction of 2·r·tan(A_v/2).
  double end_tolerance = 0.05;
  // Level frames (outside every sweeping pass, sonar z within 30° of world up: orbits, level
  // approaches) at heights spanning at least the aperture's height at the nearest range,
  // 2·r_min·tan(A_v/2), sweep the elevation as a vertical pass does, one level after another. When
  // their top level stops short (the pass-end rule), the automatic filter drops the points above
  // the extreme surface that no frame saw from above at this fraction of the aperture or more: the
  // ghost arcs over the structure's top, seen from below only (docs/carving.md, "Orbits at several
  // heights"). Bracketed points, and a seabed seen from above only, stay.
  double level_view_above = 0.1;
  // Region samples for the never-bracketed share (a regular grid over the region).
  int region_samples = 200000;
  int num_threads = 0;    // 0 = all cores
  void validate() const;  // throws Error naming the field
};

// The one declaration of BracketConfig's fields (core/params.hpp); as part of a reconstruction
// (Nested<BracketConfig>) the thread count is the reconstruction's.
template <class V>
void describe_bracket_own(BracketConfig& c, V& v) {
  using params::param;
  v.field(c.min_bracket,
          param("min_bracket", "",
                "drop points whose elevation was bracketed less than this (1 = seen at both edges "
                "of the vertical aperture, 0 = from one side only; 0 = keep all)")
              .range(0, 1)
              .flag("--min-bracket"));
  v.field(c.auto_min_bracket,
          param("auto_min_bracket", "",
                "when min_bracket is 0 and a pass stops short, drop the points bracketed less "
                "than bracketed_level (the ghost arcs beyond its end); when orbits at several "
                "heights stop short at their top, the points above seen from below only")
              // The switch turns the default around (on in ReconstructConfig).
              .flag(c.auto_min_bracket ? "--no-auto-min-bracket" : "--auto-min-bracket"));
  v.field(c.bracketed_level,
          param("bracketed_level", "", "a point counts as bracketed from this bracket on")
              .range_open_low(0, 1));
  v.field(c.end_view_fraction,
          param("end_view_fraction", "",
                "pass-end rule: the extreme surface is the farthest point a frame saw at this "
                "fraction of the aperture on the other side")
              .range_open_low(0, 1));
  v.field(c.end_tolerance, param("end_tolerance", "",
                                 "warn when a pass stops short by more than this fraction of "
                                 "2 r tan(A_v/2)")
                               .range_open_high(0, 1));
  v.field(c.level_view_above,
          param("level_view_above", "",
                "level frames at several heights (orbits) whose top stops short: with "
                "auto_min_bracket, drop the points above the surface they saw that no frame saw "
                "from above at this fraction of the aperture")
              .range(0, 1));
  v.field(
      c.region_samples,
      param("region_samples", "", "region samples for the never-bracketed share").range(0, 1e8));
}
template <class V>
void describe(BracketConfig& c, V& v) {
  describe_bracket_own(c, v);
  v.field(c.num_threads,
          params::param("num_threads", "", "worker threads (0 = all cores)").non_negative());
}
template <class V>
void describe(params::Nested<BracketConfig>& n, V& v) {
  describe_bracket_own(n.c, v);
}

// One end of one elevation-sweeping pass that stops short of the rule.
struct PassExtension {
  std::size_t pass = 0;                         // index among the dataset's passes
  std::size_t first_frame = 0, last_frame = 0;  // frame indices (inclusive), recording order
  bool upper = true;        // true: the end toward the sonar's +z (up for a level sonar)
  double range = 0;         // m, distance of the extreme surface from the pass axis
  double rule = 0;          // m, 2·r·tan(A_v/2)
  double past_surface = 0;  // m, how far the pass went past the extreme surface it saw
  double extend = 0;        // m, rule − past_surface: how much farther the pass should go
  // True when the pass ends too close to the surface to tell how far the surface goes (it saw
  // the surface from beyond at less than end_view_fraction of the aperture): `extend` is then a
  // lower bound (at least 1.1·r·tan(A_v/2) with the default fraction).
  bool lower_bound = false;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // world: the way to extend
  std::string message() const;
};

// The level frames (orbits, level approaches) when their heights sweep the elevation, and
// whether their top level stops short of the pass-end rule.
struct LevelStack {
  std::size_t frames = 0;       // level frames (outside every sweeping pass, sonar z near up)
  double z_min = 0, z_max = 0;  // m, world heights of their sonars
  bool sweeps = false;          // z_max − z_min >= 2·r_min·tan(A_v/2)
  bool stops_short = false;     // the top level stops short of 2·r·tan(A_v/2) over its surface
  double surface_z = 0;         // m, the extreme surface seen from above (if stops_short)
  double range = 0;             // m, its distance from the frame that saw it
  double rule = 0;              // m, 2·r·tan(A_v/2)
  double past_surface = 0;      // m, z_max − surface_z
  double extend = 0;            // m, rule − past_surface
  bool lower_bound = false;     // as PassExtension::lower_bound
  std::size_t dropped = 0;      // points the automatic filter dropped above it
  std::string message() const;  // the warning when stops_short
};

struct BracketReport {
  std::size_t points = 0;                     // points assessed
  std::size_t kept = 0;                       // after min_bracket
  double min_bracket = 0;                     // the filter applied (0 = none)
  bool min_bracket_auto = false;              // applied by auto_min_bracket (a pass stops short)
  std::size_t region_samples = 0;             // samples of the region seen by at least one frame
  double sample_step = 0;                     // m, spacing of the region samples
  double unbracketed_share = 0;               // of those: bracket < bracketed_level
  double never_bracketed_share = 0;           // of those: bracket == 0
  double median_bracket = 0;                  // over the points (before min_bracket)
  std::optional<Eigen::AlignedBox3d> region;  // what the shares were measured over
  std::size_t passes = 0;                     // passes that sweep the elevation
  std::vector<PassExtension> extensions;      // passes that stop short
  LevelStack level_stack;                     // orbits at several heights
  double seconds = 0;                         // wall time of assess_bracketing()
  std::vector<std::string> warnings() const;  // one line per extension (and the level stack)
  std::string to_json() const;                // a JSON object
};

// Bracket and views of arbitrary world points under frames at T_world_sonar (spec's geometry).
struct PointBracket {
  float bracket = 0;
  int views = 0;
};
std::vector<PointBracket> bracket_points(const std::vector<Eigen::Vector3f>& points_world,
                                         const std::vector<Eigen::Isometry3d>& T_world_sonar,
                                         const SonarSpec& spec, int num_threads = 0);

// Attaches the properties "bracket" and "views" to `cloud` (world frame), drops the points below
// config.min_bracket (or, with auto_min_bracket and a pass that stops short, below
// bracketed_level), and measures the region (`region`, or the cloud's bounding box) and the
// passes. Throws Error on an invalid config or spec.
BracketReport assess_bracketing(PointCloud& cloud,
                                const std::vector<Eigen::Isometry3d>& T_world_sonar,
                                const SonarSpec& spec, const BracketConfig& config,
                                const std::optional<Eigen::AlignedBox3d>& region = std::nullopt);

}  // namespace sonar3d
