#pragma once
// Internal: the geometry of one frame's footprint (thesis sec. 4.4.2–4.4.3) in a form fast enough
// to classify whole cubes of the map at once. Shared by carving (carve.cpp) and occlusion
// resolution (visibility.cpp); not installed.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/recon/visibility.hpp"

namespace sonar3d::detail {

// atan2 to within 2e-6 rad (a minimax polynomial on [0, 1] after octant reduction): a hundredth of
// the narrowest beam (0.17°), at a fraction of libm's cost in the per-voxel loops.
inline double fast_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double mx = std::max(ax, ay), mn = std::min(ax, ay);
  if (mx == 0) return 0;
  const double a = mn / mx, s = a * a;
  double r =
      (((((-0.01172120 * s + 0.05265332) * s - 0.11643287) * s + 0.19354346) * s - 0.33262347) * s +
       0.99997726) *
      a;
  if (ay > ax) r = M_PI_2 - r;
  if (x < 0) r = M_PI - r;
  return y < 0 ? -r : r;
}

// O(1) minimum / maximum over an index interval, built in O(n log n) (per frame, n = beams).
class SparseTable {
 public:
  enum class Op { Min, Max };
  void build(const std::vector<double>& v, Op op) {
    op_ = op;
    const int n = static_cast<int>(v.size());
    levels_ = 1;
    while ((1 << levels_) <= n) ++levels_;
    table_.assign(static_cast<std::size_t>(levels_) * n, 0.0);
    n_ = n;
    std::copy(v.begin(), v.end(), table_.begin());
    for (int k = 1; k < levels_; ++k) {
      const double* prev = &table_[static_cast<std::size_t>(k - 1) * n];
      double* cur = &table_[static_cast<std::size_t>(k) * n];
      const int half = 1 << (k - 1);
      for (int i = 0; i + (1 << k) <= n; ++i) cur[i] = pick(prev[i], prev[i + half]);
    }
  }
  // Inclusive interval [lo, hi], lo <= hi.
  double query(int lo, int hi) const {
    const int len = hi - lo + 1;
    const int k = 31 - __builtin_clz(static_cast<unsigned>(len));
    const double* row = &table_[static_cast<std::size_t>(k) * n_];
    return pick(row[lo], row[hi - (1 << k) + 1]);
  }

 private:
  double pick(double a, double b) const { return op_ == Op::Min ? std::min(a, b) : std::max(a, b); }
  Op op_ = Op::Min;
  int n_ = 0, levels_ = 0;
  std::vector<double> table_;
};

// Per-sensor constants: beam lookup and the eq. 4.7 scale 1/B(θ)² tabulated over sin θ.
class SonarGeometry {
 public:
  explicit SonarGeometry(const SonarSpec& spec) {
    r_min = spec.r_min;
    r_max = spec.r_max;
    dr = spec.range_resolution();
    inv_dr = 1.0 / dr;
    bins = spec.range_bins;
    beams = spec.beams();
    theta3 = 0.5 * spec.vertical_aperture_rad;  // footprint = [-A_v/2, A_v/2] (sec. 4.4.2)
    sin_theta3 = std::sin(theta3);
    fov_min = spec.fov_min();
    fov_max = spec.fov_max();
    uniform = spec.uniform_bearings() && beams > 1;
    // Non-uniform tables: cell edges for a binary search (beam_of_bearing re-checks uniformity
    // on every call, far too slow per voxel).
    edges.resize(beams + 1);
    for (int j = 0; j < beams; ++j) edges[j] = spec.beam_edge_low(j);
    edges[beams] = spec.beam_edge_high(beams - 1);
    beam_width = (fov_max - fov_min) / beams;
    inv_beam_width = 1.0 / beam_width;
    // eq. 4.7 divides by B(θ)²; tabulated on sin θ (the voxel loop has z/r, not θ).
    inv_b2.resize(kTable + 1);
    asin_table.resize(kTable + 2);
    for (int k = 0; k <= kTable + 1; ++k)
      asin_table[k] = std::asin(std::clamp(-sin_theta3 + 2.0 * sin_theta3 * k / kTable, -1.0, 1.0));
    for (int k = 0; k <= kTable; ++k) {
      const double s = -sin_theta3 + 2.0 * sin_theta3 * k / kTable;
      const double b2 = spec.beam_pattern.power(std::asin(std::clamp(s, -1.0, 1.0)), theta3);
      // A pattern that vanishes inside the aperture (a measured table) bounds nothing there.
      inv_b2[k] = b2 > 1e-6 ? static_cast<float>(1.0 / b2) : std::numeric_limits<float>::infinity();
    }
    table_scale = kTable / (2.0 * sin_theta3);
    min_inv_b2 = *std::min_element(inv_b2.begin(), inv_b2.end());
  }

  // Beam containing bearing phi (caller ensures fov_min <= phi < fov_max), never -1.
  int beam(double phi) const {
    if (uniform) {
      const int j = static_cast<int>((phi - fov_min) * inv_beam_width);
      return std::clamp(j, 0, beams - 1);
    }
    const int j =
        static_cast<int>(std::upper_bound(edges.begin(), edges.end(), phi) - edges.begin()) - 1;
    return std::clamp(j, 0, beams - 1);
  }
  // θ for sin θ = s, |s| <= sin θ_3dB (linear interpolation in a fine table).
  double elevation(double s) const {
    const double u = std::clamp((s + sin_theta3) * table_scale, 0.0, static_cast<double>(kTable));
    const int k = static_cast<int>(u);
    return asin_table[k] + (u - k) * (asin_table[k + 1] - asin_table[k]);
  }
  // 1/B(θ)² for sin θ = s, |s| <= sin θ_3dB.
  float inv_power(double s) const {
    const int k = static_cast<int>((s + sin_theta3) * table_scale + 0.5);
    return inv_b2[std::clamp(k, 0, kTable)];
  }

  double r_min, r_max, dr, inv_dr, theta3, sin_theta3, fov_min, fov_max, beam_width, inv_beam_width;
  float min_inv_b2 = 1.0f;  // smallest 1/B(θ)² over the aperture: a bound is >= I · this
  int bins, beams;
  bool uniform;

 private:
  static constexpr int kTable = 8192;
  std::vector<double> edges;
  std::vector<float> inv_b2;
  std::vector<double> asin_table;
  double table_scale;
};

// What a cube of map voxels can receive from one frame.
enum class Region {
  Outside,   // no voxel centre inside the footprint
  NoUpdate,  // every voxel centre lies past the last return of its beam (shadow: Fig. 4.5, u3)
  Free,      // every voxel (with its margin) lies inside the footprint before the first return
  Mixed,     // anything else: look closer
};

// A cube's classification and, for Mixed cubes, the image window its voxel centres fall in.
struct CubeClass {
  Region region = Region::Mixed;
  bool window = false;    // i0..i1 × j0..j1 valid (the cube lies inside the range/bearing span)
  bool no_carve = false;  // every voxel centre lies at or behind its beams' first return
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;
};

// Conservative small-angle helpers: an upper bound of asin(x) (x < 1) and atan2 padded by its
// approximation error, so that cube tests never reject a voxel that the exact test would keep.
inline double asin_upper(double x) { return x / std::sqrt(1.0 - x * x); }
constexpr double kAnglePad = 1e-5;  // rad, > fast_atan2's error

// A frame's footprint in the sonar frame with per-beam free/last-return ranges.
class FrameFootprint {
 public:
  FrameFootprint(const SonarGeometry& g, const FrameReturns& f, const SonarImage* image = nullptr)
      : g_(g), f_(f), image_(image) {
    R_sonar_world = f.T_world_sonar.rotation().transpose();
    t_sonar_world = -R_sonar_world * f.T_world_sonar.translation();
    std::vector<double> free(g.beams), last(g.beams);
    for (int j = 0; j < g.beams; ++j) {
      // Conservative reprojection (Fig. 4.5): a beam is free up to the near edge of its first
      // return; past the far edge of its last return it sees nothing (a beam without return
      // carves all the way, so it has no "last").
      free[j] = g.r_min + f.first_return_bin[j] * g.dr;
      last[j] = f.last_return_bin[j] < 0 ? std::numeric_limits<double>::infinity()
                                         : g.r_min + (f.last_return_bin[j] + 1) * g.dr;
    }
    min_free_.build(free, SparseTable::Op::Min);
    max_free_.build(free, SparseTable::Op::Max);
    max_last_.build(last, SparseTable::Op::Max);
  }

  Eigen::Vector3d to_sonar(const Eigen::Vector3d& p_world) const {
    return R_sonar_world * p_world + t_sonar_world;
  }

  // Classifies the ball of centre c (sonar frame) holding every voxel centre of a cube within
  // `r_centres`, and every voxel's carving margin within `r_free` >= r_centres.
  CubeClass classify(const Eigen::Vector3d& c, double r_centres, double r_free) const {
    CubeClass out;
    const double d = c.norm();
    if (d + r_centres < g_.r_min || d - r_centres >= g_.r_max) return {Region::Outside};
    const double rho = std::sqrt(c.x() * c.x() + c.y() * c.y());
    if (d <= 1.01 * r_free || rho <= 1.01 * r_free) return out;  // holds the apex or the z axis
    const double alpha = asin_upper(r_free / d) + kAnglePad;
    const double theta_c = fast_atan2(c.z(), rho);
    if (theta_c + alpha < -g_.theta3 || theta_c - alpha > g_.theta3) return {Region::Outside};
    const double beta = asin_upper(r_free / rho) + kAnglePad;  // bearing half-width of the ball
    const double phi_c = fast_atan2(c.y(), c.x());
    const double lo = phi_c - beta, hi = phi_c + beta;
    if (lo < -M_PI || hi > M_PI) {
      // The ball straddles the -x axis (behind the sonar): outside unless the field of view
      // reaches around there.
      const double a = lo < -M_PI ? lo + 2 * M_PI : lo;  // the interval is [a, π] ∪ [-π, b]
      const double b = hi > M_PI ? hi - 2 * M_PI : hi;
      if (a >= g_.fov_max && b < g_.fov_min) return {Region::Outside};
      return out;
    }
    if (hi < g_.fov_min || lo >= g_.fov_max) return {Region::Outside};
    const int j0 = g_.beam(std::max(lo, g_.fov_min));
    const int j1 = g_.beam(std::min(hi, std::nextafter(g_.fov_max, g_.fov_min)));
    if (d - r_centres >= max_last_.query(j0, j1)) return {Region::NoUpdate};
    const bool inside = d - r_free >= g_.r_min && d + r_free < g_.r_max &&
                        theta_c - alpha >= -g_.theta3 && theta_c + alpha <= g_.theta3 &&
                        lo >= g_.fov_min && hi < g_.fov_max;
    if (inside && d + r_free < min_free_.query(j0, j1)) return {Region::Free};
    out.window = true;
    out.j0 = j0;
    out.j1 = j1;
    out.i0 = std::clamp(static_cast<int>((d - r_centres - g_.r_min) * g_.inv_dr), 0, g_.bins - 1);
    out.i1 = std::clamp(static_cast<int>((d + r_centres - g_.r_min) * g_.inv_dr), 0, g_.bins - 1);
    out.no_carve = d - r_centres >= max_free_.query(j0, j1);
    return out;
  }

  // Over the window of a Mixed cube: whether a return pixel lies in it and the smallest return
  // intensity there (eq. 4.7: no voxel of the cube can get a bound below it · min 1/B²).
  bool window_returns(const CubeClass& w, float* min_intensity) const {
    bool any = false;
    float m = std::numeric_limits<float>::infinity();
    for (int j = w.j0; j <= w.j1; ++j) {
      if (!f_.any_return(j, w.i0, w.i1)) continue;
      for (int i = w.i0; i <= w.i1; ++i) {
        if (!f_.has_return(i, j)) continue;
        any = true;
        if (image_) m = std::min(m, image_->at(i, j));
      }
    }
    *min_intensity = m;
    return any;
  }

  // True when no voxel centre of the ball can sit in a return pixel: all of it lies before the
  // first return of the beams it spans, or past their last one, or outside the footprint.
  bool no_return_possible(const Eigen::Vector3d& c, double radius) const {
    const double d = c.norm();
    if (d + radius < g_.r_min || d - radius >= g_.r_max) return true;
    const double rho = std::sqrt(c.x() * c.x() + c.y() * c.y());
    if (d <= 1.01 * radius || rho <= 1.01 * radius) return false;
    const double alpha = asin_upper(radius / d) + kAnglePad;
    const double theta_c = fast_atan2(c.z(), rho);
    if (theta_c + alpha < -g_.theta3 || theta_c - alpha > g_.theta3) return true;
    const double beta = asin_upper(radius / rho) + kAnglePad;
    const double phi_c = fast_atan2(c.y(), c.x());
    const double lo = phi_c - beta, hi = phi_c + beta;
    if (lo < -M_PI || hi > M_PI) return false;
    if (hi < g_.fov_min || lo >= g_.fov_max) return true;
    const int j0 = g_.beam(std::max(lo, g_.fov_min));
    const int j1 = g_.beam(std::min(hi, std::nextafter(g_.fov_max, g_.fov_min)));
    if (d - radius >= max_last_.query(j0, j1)) return true;
    if (d + radius < min_free_.query(j0, j1)) return true;
    // Gaps between returns: no return pixel in the ball's range × bearing window.
    const int i0 = static_cast<int>(std::floor((d - radius - g_.r_min) * g_.inv_dr));
    const int i1 = static_cast<int>((d + radius - g_.r_min) * g_.inv_dr);
    for (int j = j0; j <= j1; ++j)
      if (f_.any_return(j, i0, i1)) return false;
    return true;
  }

  // Point rule with a margin: the ball (range r, sin θ = s, distance rho from the z axis,
  // bearing phi; radius delta) lies inside the footprint before the first return of every beam
  // it spans.
  bool ball_free(double r, double s, double rho, double phi, double delta) const {
    if (r - delta < g_.r_min || r + delta >= g_.r_max) return false;
    if (rho <= 1.01 * delta) return false;
    const double alpha = asin_upper(delta / r) + kAnglePad;
    const double theta = std::asin(s);
    if (theta - alpha < -g_.theta3 || theta + alpha > g_.theta3) return false;
    const double beta = asin_upper(delta / rho) + kAnglePad;
    const double lo = phi - beta, hi = phi + beta;
    if (lo < g_.fov_min || hi >= g_.fov_max) return false;
    return r + delta < min_free_.query(g_.beam(lo), g_.beam(hi));
  }

  const FrameReturns& frame() const { return f_; }
  Eigen::Matrix3d R_sonar_world;
  Eigen::Vector3d t_sonar_world;

 private:
  const SonarGeometry& g_;
  const FrameReturns& f_;
  const SonarImage* image_;
  SparseTable min_free_, max_free_, max_last_;
};

// World-frame axis-aligned box around the footprint wedge of a sonar at T_world_sonar.
inline Eigen::AlignedBox3d footprint_bounds_world(const SonarGeometry& g,
                                                  const Eigen::Isometry3d& T_world_sonar) {
  Eigen::AlignedBox3d box;
  // The wedge's extreme points lie on its boundary; a dense sample of the outer and inner
  // spherical caps (edges included) plus a pad for the chord sag bounds it.
  const int nphi = 64, nth = 16;
  double max_step = 0;
  for (int a = 0; a <= nphi; ++a) {
    const double phi = g.fov_min + (g.fov_max - g.fov_min) * a / nphi;
    for (int b = 0; b <= nth; ++b) {
      const double th = -g.theta3 + 2 * g.theta3 * b / nth;
      const Eigen::Vector3d u(std::cos(th) * std::cos(phi), std::cos(th) * std::sin(phi),
                              std::sin(th));
      box.extend(T_world_sonar * (g.r_max * u));
      box.extend(T_world_sonar * (g.r_min * u));
    }
  }
  max_step = std::max((g.fov_max - g.fov_min) / nphi, 2 * g.theta3 / nth);
  const double pad = g.r_max * (1 - std::cos(max_step)) + 1e-6;
  box.min().array() -= pad;
  box.max().array() += pad;
  return box;
}

// Candidates grouped by 8³ voxel block for occlusion resolution (sec. 4.4.5): the carver hands
// its map's leaves over as they are, without making a point per candidate.
using BlockMask = std::array<std::uint64_t, 8>;  // bit x << 6 | y << 3 | z of an 8³ block
struct CandidateBlock {
  // Index of the block's voxel (0, 0, 0); a voxel's world position is float(index · voxel_size),
  // as Carver::snapshot() gives it.
  std::array<int, 3> origin_index{};
  Eigen::Vector3d centre_world = Eigen::Vector3d::Zero();  // centre of a ball holding them all
  double radius = 0;                                       // m
  BlockMask mask{};                                        // the candidates
};
// Pointers to the frames, in order (the resolutions below take a subset of a carver's frames).
std::vector<const FrameReturns*> frame_pointers(const std::vector<FrameReturns>& frames);
// Occlusion resolution of blocks whose candidates lie at (origin_index + (x, y, z))·voxel_size
// (config.voxel_size); returns per block the mask of the candidates kept (observed in a frame
// and, with refute_free, never seen as free space). The same rule as resolve_occlusions().
std::vector<BlockMask> resolve_occlusion_blocks(const std::vector<CandidateBlock>& blocks,
                                                const std::vector<FrameReturns>& frames,
                                                const SonarSpec& spec,
                                                const OcclusionConfig& config,
                                                Progress* progress = nullptr);
std::vector<BlockMask> resolve_occlusion_blocks(const std::vector<CandidateBlock>& blocks,
                                                const std::vector<const FrameReturns*>& frames,
                                                const SonarSpec& spec,
                                                const OcclusionConfig& config,
                                                Progress* progress = nullptr);
// resolve_occlusions() without the explanation, where every point shields the whole of its
// voxel — half its diagonal, √3/2 voxel, around its centre, which any line of sight crossing the
// voxel passes within — from the free-space test (config.refute_free); the occlusion test keeps
// config.footprint_radius. For the points kept by a first resolution (drop_unexplained()): the
// members' interiors are gone and their faces are a shell one voxel thick, through whose gaps a
// back face would otherwise be seen as free space and refuted.
PointCloud resolve_occlusions_solid(const PointCloud& points_world,
                                    const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                                    const OcclusionConfig& config);

}  // namespace sonar3d::detail
