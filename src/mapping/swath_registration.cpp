// Swath registration (thesis sec. 6.2.2.1, eq. 6.1–6.2) and the global adjustment of all swath
// offsets (beyond the thesis).
#include "sonar3d/mapping/swath_registration.hpp"

#include <ceres/ceres.h>
#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <queue>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {

struct Cell {
  int row, col;
  float z;
};

// A float's bits as an unsigned key of the same order (finite values and ±inf; no NaN).
inline std::uint32_t order_key(float f) {
  std::uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return (b & 0x80000000u) ? ~b : (b | 0x80000000u);
}
inline float from_order_key(std::uint32_t k) {
  const std::uint32_t b = (k & 0x80000000u) ? (k & 0x7fffffffu) : ~k;
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
}

// The k-th smallest (0-based) of v, exactly, by a radix selection on the order keys: 11, 11
// and 10 bits, each pass histogramming only the values left in the bucket that holds the k-th.
// A pass over the values and one over a shrinking bucket: about 2–3 times faster than
// std::nth_element on the tens of thousands of cell differences of a registration (beyond the
// thesis; the medians of eq. 6.1–6.2 are most of the yaw search's time, docs/mapping.md).
float radix_select(const std::vector<float>& v, std::size_t k) {
  thread_local std::vector<std::uint32_t> keys;
  keys.resize(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) keys[i] = order_key(v[i]);
  std::size_t n = keys.size();
  std::uint32_t prefix = 0;
  constexpr int kShifts[3] = {21, 10, 0};
  constexpr std::uint32_t kMasks[3] = {0x7ffu, 0x7ffu, 0x3ffu};
  std::uint32_t hist[2048];
  for (int pass = 0; pass < 3; ++pass) {
    const int shift = kShifts[pass];
    const std::uint32_t mask = kMasks[pass];
    std::fill(hist, hist + mask + 1, 0u);
    for (std::size_t i = 0; i < n; ++i) ++hist[(keys[i] >> shift) & mask];
    std::uint32_t b = 0;
    for (; b <= mask; ++b) {
      if (k < hist[b]) break;
      k -= hist[b];
    }
    prefix |= b << shift;
    if (pass == 2) break;
    // Keep only the bucket's values (in place).
    std::size_t m = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (((keys[i] >> shift) & mask) == b) keys[m++] = keys[i];
    }
    n = m;
  }
  return from_order_key(prefix);
}

// Median of v (reordered in place); v must not be empty. The lower median's partner of an even
// count is the largest value below the upper one (or equal to it when it repeats).
float median_in_place(std::vector<float>& v) {
  const std::size_t half = v.size() / 2;
  if (v.size() < 2048) {  // small: nth_element's constant is lower than the histograms'
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(half);
    std::nth_element(v.begin(), mid, v.end());
    float m = *mid;
    if (v.size() % 2 == 0) {
      m = 0.5f * (m + *std::max_element(v.begin(), mid));
    }
    return m;
  }
  const float upper = radix_select(v, half);
  if (v.size() % 2 != 0) return upper;
  std::size_t below = 0;
  float lower = -std::numeric_limits<float>::infinity();
  for (const float x : v) {
    if (x < upper) {
      ++below;
      lower = std::max(lower, x);
    }
  }
  if (below < half) lower = upper;  // the (half − 1)-th value is the upper one repeated
  return 0.5f * (upper + lower);
}

struct ShiftScore {
  float score = std::numeric_limits<float>::infinity();  // eq. 6.2; inf = too little overlap
  float zeta = 0;                                        // eq. 6.1
  float mean = std::numeric_limits<float>::infinity();   // mean |A − B − ζ|: breaks ties
  std::size_t overlap = 0;
};

// Eq. 6.2 decides; where it ties (within 1e-6 m) the mean unsigned difference does. Ties are
// common on maps of a carved seabed: heights come in voxel steps, and where most of the overlap
// is flat the median is 0 for every shift that keeps it flat, however the few objects in it
// line up.
bool better(const ShiftScore& a, const ShiftScore& b) {
  if (std::abs(a.score - b.score) > 1e-6f) return a.score < b.score;
  return a.mean < b.mean;
}

// Fills ζ (eq. 6.1), the score (eq. 6.2) and the mean from the differences A − B (reordered).
void score_differences(std::vector<float>& d, ShiftScore& s) {
  s.zeta = median_in_place(d);  // eq. 6.1: the signed median aligns the depth distributions
  double sum = 0;
  for (float& v : d) {
    v = std::abs(v - s.zeta);
    sum += v;
  }
  s.mean = static_cast<float>(sum / static_cast<double>(d.size()));
  s.score = median_in_place(d);  // eq. 6.2: the median unsigned difference
}

// A reference grid: heights row-major, NaN = no data.
struct Grid {
  int rows = 0, cols = 0;
  std::vector<float> z;
  float at(int r, int c) const { return z[static_cast<std::size_t>(r) * cols + c]; }
};

// Scores the shifts (ci + di, cj + dj), |di|, |dj| <= h, of the moving cells over the reference
// grid: B moved by (i, j) cells east/north lands in the reference's row − j, column + i. Per
// shift, over the cells defined in both (undefined ones discarded): ζ = signed median of A − B
// (eq. 6.1), score = median |A − B − ζ| (eq. 6.2). Parallel over shifts.
std::vector<ShiftScore> score_window(const Grid& A, const std::vector<Cell>& cells, int ci, int cj,
                                     int h, std::size_t min_overlap) {
  const int W = 2 * h + 1;
  std::vector<ShiftScore> scores(static_cast<std::size_t>(W) * W);
  tbb::parallel_for(tbb::blocked_range<int>(0, W * W), [&](const tbb::blocked_range<int>& range) {
    std::vector<float> d;
    d.reserve(cells.size());
    for (int k = range.begin(); k != range.end(); ++k) {
      const int i = ci + k % W - h, j = cj + k / W - h;
      d.clear();
      for (const Cell& cell : cells) {
        const int ra = cell.row - j, ca = cell.col + i;
        if (ra < 0 || ca < 0 || ra >= A.rows || ca >= A.cols) continue;
        const float za = A.at(ra, ca);
        if (za == za) d.push_back(za - cell.z);
      }
      ShiftScore& s = scores[static_cast<std::size_t>(k)];
      s.overlap = d.size();
      if (d.size() < min_overlap || d.empty()) continue;
      score_differences(d, s);
    }
  });
  return scores;
}

int floor_div(long a, int f) { return static_cast<int>(a >= 0 ? a / f : -((-a + f - 1) / f)); }

// The grid and cells at f times the cell size, blocks aligned on the reference grid: each block
// keeps the highest of its heights (the elevation map that would be built at that resolution).
void coarsen(const Grid& A, const std::vector<Cell>& cells, int f, Grid& A_f,
             std::vector<Cell>& cells_f) {
  A_f.rows = floor_div(A.rows - 1, f) + 1;
  A_f.cols = floor_div(A.cols - 1, f) + 1;
  A_f.z.assign(static_cast<std::size_t>(A_f.rows) * A_f.cols, ElevationMap::kNoData);
  for (int r = 0; r < A.rows; ++r) {
    for (int c = 0; c < A.cols; ++c) {
      const float v = A.at(r, c);
      float& o = A_f.z[static_cast<std::size_t>(r / f) * A_f.cols + c / f];
      if (v == v && !(o >= v)) o = v;
    }
  }
  int r0 = std::numeric_limits<int>::max(), c0 = r0, r1 = std::numeric_limits<int>::min(), c1 = r1;
  for (const Cell& cell : cells) {
    r0 = std::min(r0, floor_div(cell.row, f)), r1 = std::max(r1, floor_div(cell.row, f));
    c0 = std::min(c0, floor_div(cell.col, f)), c1 = std::max(c1, floor_div(cell.col, f));
  }
  const int nr = r1 - r0 + 1, nc = c1 - c0 + 1;
  std::vector<float> blocks(static_cast<std::size_t>(nr) * nc, ElevationMap::kNoData);
  for (const Cell& cell : cells) {
    float& o = blocks[static_cast<std::size_t>(floor_div(cell.row, f) - r0) * nc +
                      (floor_div(cell.col, f) - c0)];
    if (!(o >= cell.z)) o = cell.z;
  }
  cells_f.clear();
  for (int r = 0; r < nr; ++r) {
    for (int c = 0; c < nc; ++c) {
      const float v = blocks[static_cast<std::size_t>(r) * nc + c];
      if (v == v) cells_f.push_back({r + r0, c + c0, v});
    }
  }
}

// The best shift by `better`; -1 when none has enough overlap.
int best_of(const std::vector<ShiftScore>& scores) {
  int best = -1;
  for (int k = 0; k < static_cast<int>(scores.size()); ++k) {
    if (!std::isfinite(scores[k].score)) continue;
    if (best < 0 || better(scores[k], scores[best])) best = k;
  }
  return best;
}

// 1 − best / typical, on the mean unsigned difference (the median alone is often 0 on flat
// carved seabed): near 0 when no shift stands out, as on a flat, featureless overlap.
double distinctness(const std::vector<ShiftScore>& scores, int best) {
  std::vector<float> finite;
  for (const ShiftScore& s : scores) {
    if (std::isfinite(s.mean)) finite.push_back(s.mean);
  }
  const float typical = median_in_place(finite);
  return typical > 0 ? std::max(0.0, 1.0 - scores[best].mean / typical) : 0.0;
}

}  // namespace

void SwathRegistrationConfig::validate() const { params::check(*this, "registration"); }

void SwathAdjustmentConfig::validate() const { params::check(*this, "adjustment"); }

Eigen::Vector3d SwathAdjustment::correction(int s, double t) const {
  Eigen::Vector3d c = offsets.at(static_cast<std::size_t>(s));
  if (static_cast<std::size_t>(s) < rates.size()) {
    c.head<2>() += rates[s] * (t - rate_t0[s]);
  }
  return c;
}

Eigen::Vector3d SwathAdjustment::apply_navigation_model(const Eigen::Vector3d& p) const {
  if (nav_model.isZero()) return p;
  // p_logged − pivot = (1 + s)·R(β)·(p_true − pivot): undone by R(−β)/(1 + s).
  const double c = std::cos(nav_model.y()), sn = std::sin(nav_model.y());
  const double inv = 1.0 / (1.0 + nav_model.x());
  const Eigen::Vector2d d = (p - pivot).head<2>();
  return {pivot.x() + inv * (c * d.x() + sn * d.y()), pivot.y() + inv * (-sn * d.x() + c * d.y()),
          p.z()};
}

void AbsoluteConstraints::validate() const {
  require(std::isfinite(gate_sigma) && gate_sigma > 0, "fixes: gate_sigma must be > 0");
  require(std::isfinite(loss_sigma) && loss_sigma > 0, "fixes: loss_sigma must be > 0");
  require(max_rounds >= 1, "fixes: max_rounds must be >= 1");
  require(std::isfinite(scale_prior_sigma) && scale_prior_sigma > 0 && scale_prior_sigma < 0.5,
          "fixes: scale_prior_sigma must lie in (0, 0.5)");
  require(std::isfinite(heading_prior_sigma_rad) && heading_prior_sigma_rad > 0,
          "fixes: heading_prior_sigma must be > 0");
  require(pivot.allFinite(), "fixes: the pivot is not finite");
  require(std::isfinite(min_baseline_m) && min_baseline_m >= 0,
          "fixes: min_baseline_m must be >= 0");
  for (const AbsoluteFix& f : fixes) {
    require(std::isfinite(f.time) && f.p_world.allFinite() && f.p_logged.allFinite() &&
                std::isfinite(f.sigma_m) && f.sigma_m > 0 && std::isfinite(f.time_a) &&
                std::isfinite(f.time_b) && f.weight_b >= 0 && f.weight_b <= 1 &&
                f.lever.allFinite(),
            "fixes: the fix at t = " + std::to_string(f.time) + " s is not finite or has σ <= 0");
  }
}

bool maps_may_overlap(const ElevationMap& a, const ElevationMap& b, double search_m) {
  const double ax1 = a.origin_xy.x() + a.cols * a.cell_m, ay0 = a.origin_xy.y() - a.rows * a.cell_m;
  const double bx1 = b.origin_xy.x() + b.cols * b.cell_m, by0 = b.origin_xy.y() - b.rows * b.cell_m;
  return a.origin_xy.x() - search_m < bx1 && b.origin_xy.x() - search_m < ax1 &&
         ay0 - search_m < b.origin_xy.y() && by0 - search_m < a.origin_xy.y();
}

SwathTie register_elevation_maps(const ElevationMap& reference, const ElevationMap& moving,
                                 const SwathRegistrationConfig& config) {
  config.validate();
  const auto start = std::chrono::steady_clock::now();
  const ElevationMap& A = reference;
  const ElevationMap& B = moving;
  require(!A.empty() && !B.empty(), "swath registration: an elevation map is empty");
  const double c = A.cell_m;
  require(std::abs(B.cell_m - c) <= 1e-9 * c,
          "swath registration: the maps have different cell sizes (" + std::to_string(A.cell_m) +
              " m and " + std::to_string(B.cell_m) + " m): map both swaths at one resolution");
  const double fc = (B.origin_xy.x() - A.origin_xy.x()) / c;
  const double fr = (A.origin_xy.y() - B.origin_xy.y()) / c;
  require(std::abs(fc - std::round(fc)) < 1e-3 && std::abs(fr - std::round(fr)) < 1e-3,
          "swath registration: the maps' origins are not on a common cell grid: map both "
          "swaths with origins on multiples of the cell size");
  const long dc0 = std::lround(fc), dr0 = std::lround(fr);
  const double search_cells_d = std::floor(config.search_m / c + 1e-9);
  require(search_cells_d <= 2000, "search_m = " + std::to_string(config.search_m) +
                                      " m is more than 2000 cells: search a smaller window");
  const int S = static_cast<int>(search_cells_d);

  // B's defined cells that can land in A for some shift of the window.
  std::vector<Cell> cells;
  for (int r = 0; r < B.rows; ++r) {
    const long ra = r + dr0;
    if (ra < -S || ra >= A.rows + S) continue;
    for (int col = 0; col < B.cols; ++col) {
      const long ca = col + dc0;
      if (ca < -S || ca >= A.cols + S || !B.valid(r, col)) continue;
      cells.push_back({static_cast<int>(ra), static_cast<int>(ca), B.at(r, col)});
    }
  }
  require(cells.size() >= static_cast<std::size_t>(config.min_overlap_cells),
          "swath registration: the maps do not overlap (" + std::to_string(cells.size()) +
              " cells of the moving map fall within the reference map's extent grown by "
              "search_m; min_overlap_cells = " +
              std::to_string(config.min_overlap_cells) + ")");

  std::optional<tbb::global_control> threads;
  if (config.num_threads > 0) {
    threads.emplace(tbb::global_control::max_allowed_parallelism,
                    static_cast<std::size_t>(config.num_threads));
  }
  Grid grid{A.rows, A.cols, A.z};
  const std::size_t min_overlap = static_cast<std::size_t>(config.min_overlap_cells);
  const std::string no_shift = "swath registration: no shift within ±" +
                               std::to_string(config.search_m) + " m overlaps by " +
                               "min_overlap_cells = " + std::to_string(config.min_overlap_cells) +
                               " defined cells";
  // Beyond the thesis: search the whole window on maps f times coarser, then every cell shift
  // within ±f cells of the coarse winner at full resolution. f = 1 is the thesis' exhaustive
  // search at map resolution.
  const int f = config.coarse_factor;
  int ci = 0, cj = 0, h = S;
  double confidence_distinct = -1;
  if (f > 1 && S > 2 * f) {
    Grid coarse;
    std::vector<Cell> coarse_cells;
    coarsen(grid, cells, f, coarse, coarse_cells);
    const int hc = (S + f - 1) / f;
    const std::vector<ShiftScore> cs = score_window(
        coarse, coarse_cells, 0, 0, hc, std::max<std::size_t>(1, min_overlap / (f * f)));
    const int cb = best_of(cs);
    require(cb >= 0, no_shift);
    ci = f * (cb % (2 * hc + 1) - hc);
    cj = f * (cb / (2 * hc + 1) - hc);
    h = f;
    confidence_distinct = distinctness(cs, cb);
  }
  const int W = 2 * h + 1;
  const std::vector<ShiftScore> scores = score_window(grid, cells, ci, cj, h, min_overlap);
  const int best = best_of(scores);
  require(best >= 0, no_shift);
  const int bi = ci + best % W - h, bj = cj + best / W - h;
  double sub_i = 0, sub_j = 0;
  ShiftScore chosen = scores[best];
  if (config.subcell) {
    // Beyond the thesis' cell resolution: eq. 6.1–6.2 evaluated directly at fractional shifts
    // within ±½ cell of the winner, every tenth of a cell, the reference map interpolated
    // bilinearly (cells whose four neighbours are not all defined are discarded). No model of
    // the score's shape is assumed, so an exact integer shift stays exact.
    const int n = 11;
    std::vector<ShiftScore> fine(static_cast<std::size_t>(n) * n);
    tbb::parallel_for(0, n * n, [&](int k) {
      const double fi = bi + 0.1 * (k % n - 5), fj = bj + 0.1 * (k / n - 5);
      std::vector<float> d;
      d.reserve(cells.size());
      for (const Cell& cell : cells) {
        const double ra = cell.row - fj, ca = cell.col + fi;
        const int r0 = static_cast<int>(std::floor(ra)), c0 = static_cast<int>(std::floor(ca));
        if (r0 < 0 || c0 < 0 || r0 >= A.rows || c0 >= A.cols) continue;
        const double wr = ra - r0, wc = ca - c0;
        const int r1 = wr > 0 ? r0 + 1 : r0, c1 = wc > 0 ? c0 + 1 : c0;
        if (r1 >= A.rows || c1 >= A.cols) continue;
        const float z00 = A.at(r0, c0), z01 = A.at(r0, c1), z10 = A.at(r1, c0), z11 = A.at(r1, c1);
        if (!(z00 == z00 && z01 == z01 && z10 == z10 && z11 == z11)) continue;
        const double za = (1 - wr) * ((1 - wc) * z00 + wc * z01) + wr * ((1 - wc) * z10 + wc * z11);
        d.push_back(static_cast<float>(za) - cell.z);
      }
      ShiftScore& s = fine[static_cast<std::size_t>(k)];
      s.overlap = d.size();
      if (d.size() < min_overlap || d.empty()) return;
      score_differences(d, s);
    });
    const int fb = best_of(fine);
    if (fb >= 0 && better(fine[fb], chosen)) {
      sub_i = 0.1 * (fb % n - 5);
      sub_j = 0.1 * (fb / n - 5);
      chosen = fine[fb];
    }
  }
  SwathTie tie;
  tie.t = {(bi + sub_i) * c, (bj + sub_j) * c, chosen.zeta};
  tie.score_m = chosen.score;
  tie.overlap_cells = scores[best].overlap;
  if (confidence_distinct < 0) confidence_distinct = distinctness(scores, best);
  tie.confidence = confidence_distinct * std::min(1.0, static_cast<double>(tie.overlap_cells) /
                                                           config.overlap_full_cells);
  tie.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return tie;
}

SwathAdjustment accumulate_consecutive(int num_swaths, const std::vector<SwathTie>& ties) {
  require(num_swaths >= 1, "swath adjustment: no swaths");
  SwathAdjustment out;
  out.offsets.assign(static_cast<std::size_t>(num_swaths), Eigen::Vector3d::Zero());
  std::vector<const SwathTie*> prev(static_cast<std::size_t>(num_swaths), nullptr);
  for (const SwathTie& t : ties) {
    if (t.moving >= 1 && t.moving < num_swaths && t.reference == t.moving - 1) prev[t.moving] = &t;
  }
  for (int i = 1; i < num_swaths; ++i) {
    require(prev[i] != nullptr, "consecutive registration: no tie between swath " +
                                    std::to_string(i - 1) + " and swath " + std::to_string(i));
    out.offsets[i] = out.offsets[i - 1] + prev[i]->t;
  }
  for (const SwathTie& t : ties) {
    const bool in =
        t.reference >= 0 && t.moving >= 0 && t.reference < num_swaths && t.moving < num_swaths;
    out.tie_used.push_back(in && t.reference == t.moving - 1);
    out.tie_residual_m.push_back(
        in ? (out.offsets[t.moving] - out.offsets[t.reference] - t.t).norm() : 0.0);
  }
  return out;
}

namespace {

constexpr double kTieSigma = 0.02;  // m: a tie's residual is measured in map cells of 2 cm

// √w · (o_B − o_A − t): the tie's translation between the two swaths' offsets.
struct TieResidual {
  Eigen::Vector3d t;
  double sqrt_w;
  template <typename T>
  bool operator()(const T* o_a, const T* o_b, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = T(sqrt_w) * (o_b[k] - o_a[k] - T(t[k]));
    return true;
  }
};

// The navigation model's linear part R(−β)/(1 + s) applied to (dx, dy); nav = (s, β).
template <typename T>
void nav_linear(const T* nav, const T& dx, const T& dy, T* out) {
  using std::cos;
  using std::sin;
  const T c = cos(nav[1]), sn = sin(nav[1]), inv = T(1) / (T(1) + nav[0]);
  out[0] = inv * (c * dx + sn * dy);
  out[1] = inv * (-sn * dx + c * dy);
}

// A tie t measured between the logged swath maps, carried into the corrected frame:
// R(−β)·(t − s/(1 + s)·sep) = R(−β)·t + R(−β)·sep/(1 + s) − R(−β)·sep (the maps are vehicle
// positions, which the model scales, plus the sonar's rays, which it only turns).
template <typename T>
void nav_tie(const T* nav, const Eigen::Vector3d& t, const Eigen::Vector2d& sep, T* out) {
  using std::cos;
  using std::sin;
  const T c = cos(nav[1]), sn = sin(nav[1]);
  T scaled[2];
  nav_linear(nav, T(sep.x()), T(sep.y()), scaled);
  const T dx = T(t.x() - sep.x()), dy = T(t.y() - sep.y());
  out[0] = c * dx + sn * dy + scaled[0];
  out[1] = -sn * dx + c * dy + scaled[1];
}

// With fixes, a tie between pieces at (t_A, t_B) in the corrected frame:
// √w · (c_B(t_B) − c_A(t_A) − R(−β)·t/(1 + s)) / σ. Both methods (the global one's rates are held
// at zero).
struct NavTieResidual {
  Eigen::Vector3d t;
  double sqrt_w, dt_a, dt_b;
  Eigen::Vector2d sep = Eigen::Vector2d::Zero();  // SwathTie::nav_separation
  template <typename T>
  bool operator()(const T* o_a, const T* r_a, const T* o_b, const T* r_b, const T* nav,
                  T* res) const {
    T lt[2];
    nav_tie(nav, t, sep, lt);
    const T w(sqrt_w / kTieSigma);
    for (int k = 0; k < 2; ++k) {
      res[k] = w * (o_b[k] + r_b[k] * T(dt_b) - o_a[k] - r_a[k] * T(dt_a) - lt[k]);
    }
    res[2] = w * (o_b[2] - o_a[2] - T(t.z()));
    return true;
  }
};

// A fix: (corrected navigation at its time − fix) / σ; the corrected navigation is the
// navigation model applied to the logged position plus the swath correction there (one swath, or
// two across a turn).
struct FixResidual {
  AbsoluteFix f;
  Eigen::Vector3d pivot;
  double dt_a, dt_b;  // from each swath's rate_t0
  template <typename T>
  void predict(const T* nav, T* p) const {
    using std::cos;
    using std::sin;
    T d[2];
    nav_linear(nav, T(f.p_logged.x() - pivot.x()), T(f.p_logged.y() - pivot.y()), d);
    // A known structure: the point the sonar saw, the lever turned by R(−β) (ranges carry no
    // DVL scale); zero for a fix.
    const T c = cos(nav[1]), sn = sin(nav[1]);
    p[0] = T(pivot.x()) + d[0] + c * T(f.lever.x()) + sn * T(f.lever.y());
    p[1] = T(pivot.y()) + d[1] - sn * T(f.lever.x()) + c * T(f.lever.y());
    p[2] = T(f.p_logged.z() + f.lever.z());
  }
  template <typename T>
  void finish(const T* p, T* res) const {
    for (int k = 0; k < 3; ++k) res[k] = (p[k] - T(f.p_world[k])) / T(f.sigma_m);
    if (!f.has_z) res[2] = T(0);
  }
  template <typename T>
  bool operator()(const T* o, const T* r, const T* nav, T* res) const {
    T p[3];
    predict(nav, p);
    for (int k = 0; k < 3; ++k) p[k] += o[k] + (k < 2 ? r[k] * T(dt_a) : T(0));
    finish(p, res);
    return true;
  }
  template <typename T>
  bool operator()(const T* o_a, const T* r_a, const T* o_b, const T* r_b, const T* nav,
                  T* res) const {
    T p[3];
    predict(nav, p);
    const double w = f.weight_b;
    for (int k = 0; k < 3; ++k) {
      const T ca = o_a[k] + (k < 2 ? r_a[k] * T(dt_a) : T(0));
      const T cb = o_b[k] + (k < 2 ? r_b[k] * T(dt_b) : T(0));
      p[k] += T(1 - w) * ca + T(w) * cb;
    }
    finish(p, res);
    return true;
  }
};

// The radius a 2-D or 3-D standard normal residual exceeds with the probability a 1-D one
// exceeds `gate` σ (erfc(gate/√2)): the tails of the χ distribution with `dof` degrees,
// Q2(x) = exp(−x²/2), Q3(x) = erfc(x/√2) + √(2/π)·x·exp(−x²/2).
double gate_radius(double gate, int dof) {
  const double q = std::erfc(gate / std::sqrt(2.0));
  if (dof <= 1) return gate;
  if (q <= 0) return gate * 2;  // beyond double precision: any gate that large is "never"
  if (dof == 2) return std::sqrt(-2.0 * std::log(q));
  auto tail = [](double x) {
    return std::erfc(x / std::sqrt(2.0)) + std::sqrt(2.0 / M_PI) * x * std::exp(-0.5 * x * x);
  };
  double lo = 0, hi = gate + 10;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (tail(mid) > q ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The navigation model's plausibility prior: (s/σ_s, β/σ_β).
struct NavModelPrior {
  double sigma_s, sigma_b;
  template <typename T>
  bool operator()(const T* nav, T* res) const {
    res[0] = nav[0] / T(sigma_s);
    res[1] = nav[1] / T(sigma_b);
    return true;
  }
};

// R(−β)·lever (the heading correction only), nav = (s, β).
Eigen::Vector3d turned_lever(const Eigen::Vector2d& nav, const Eigen::Vector3d& lever) {
  const double c = std::cos(nav.y()), sn = std::sin(nav.y());
  return {c * lever.x() + sn * lever.y(), -sn * lever.x() + c * lever.y(), lever.z()};
}

Eigen::Vector2d nav_tie_d(const Eigen::Vector2d& nav, const SwathTie& tie) {
  Eigen::Vector2d out;
  nav_tie(nav.data(), tie.t, tie.nav_separation, out.data());
  return out;
}

}  // namespace

namespace {

// Solves an adjustment problem: dense QR for a few swaths, sparse Cholesky for many when a sparse
// library is there; silent; the iterations and cost into `out`.
void solve(ceres::Problem& problem, const SwathAdjustmentConfig& config, int num_swaths,
           SwathAdjustment& out) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  if (num_swaths > 100 && (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ||
                           ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE))) {
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  }
  options.max_num_iterations = config.max_iterations;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  require(summary.IsSolutionUsable(), "swath adjustment: the solver failed: " + summary.message);
  out.iterations = static_cast<int>(summary.iterations.size());
  out.final_cost = summary.final_cost;
}

// The solve with absolute fixes, shared by both methods. `out` holds the initial offsets (from
// the ties, swath 0 at 0), the rates (held at zero for the global method) and rate_t0; `problem`
// holds every offset and rate block (the gauge not held) and the tie and prior residuals.
// Adds the navigation model and the fixes, places the survey by the fixes' median, then solves
// and gates until the rejected set settles; the navigation model's and placement's σ from the
// covariance at the solution.
void solve_with_fixes(ceres::Problem& problem, const AbsoluteConstraints& abs,
                      const SwathAdjustmentConfig& config, int num_swaths, SwathAdjustment& out) {
  abs.validate();
  require(!abs.fixes.empty(), "fixes: none to adjust with");
  const std::size_t nf = abs.fixes.size();
  for (const AbsoluteFix& f : abs.fixes) {
    require(f.swath_a >= 0 && f.swath_a < num_swaths && f.swath_b >= 0 && f.swath_b < num_swaths,
            "fixes: the fix at t = " + std::to_string(f.time) + " s names a swath out of range");
  }
  out.has_fixes = true;
  out.pivot = abs.pivot;
  out.nav_model.setZero();
  auto swath_corr = [&](const AbsoluteFix& f) {
    return Eigen::Vector3d((1 - f.weight_b) * out.correction(f.swath_a, f.time_a) +
                           f.weight_b * out.correction(f.swath_b, f.time_b));
  };
  // The survey placed where the fixes' median puts it (a common shift leaves ties, continuity
  // and rate priors as they are): the robust losses start near the answer however far the
  // navigation's origin is from the fixes'.
  bool any_z = false;
  {
    std::vector<double> dx, dy, dz;
    for (const AbsoluteFix& f : abs.fixes) {
      const Eigen::Vector3d d = f.p_world - f.p_logged - f.lever - swath_corr(f);
      dx.push_back(d.x());
      dy.push_back(d.y());
      if (f.has_z) dz.push_back(d.z());
    }
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    const Eigen::Vector3d shift(median(dx), median(dy), dz.empty() ? 0.0 : median(dz));
    any_z = !dz.empty();
    for (Eigen::Vector3d& o : out.offsets) o += shift;
  }
  problem.AddParameterBlock(out.nav_model.data(), 2);
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<NavModelPrior, 2, 2>(new NavModelPrior{
                               abs.scale_prior_sigma, abs.heading_prior_sigma_rad}),
                           nullptr, out.nav_model.data());
  // Without a fix's height, the heights keep the ties' gauge: swath 0's held.
  if (!any_z) problem.SetManifold(out.offsets[0].data(), new ceres::SubsetManifold(3, {2}));

  std::vector<bool> rejected(nf, false);
  std::vector<ceres::ResidualBlockId> ids;
  out.fixes.assign(nf, FixReport{});
  bool estimate = false;
  for (int round = 1; round <= abs.max_rounds; ++round) {
    for (ceres::ResidualBlockId id : ids) problem.RemoveResidualBlock(id);
    ids.clear();
    const std::size_t used =
        static_cast<std::size_t>(std::count(rejected.begin(), rejected.end(), false));
    if (used == 0) {
      throw Error(fmt::format(
          "fixes: all {} fixes disagree with the navigation and the swath ties by more than "
          "{:g} σ: are they in the navigation's world frame (ENU, metres) and on its clock?",
          nf, abs.gate_sigma));
    }
    // A scale and a turn need two constraints apart: 3 in use, or 2 at least min_baseline_m
    // apart (two known structures).
    double baseline = 0;
    for (std::size_t a = 0; a < nf; ++a) {
      for (std::size_t b = a + 1; b < nf && used == 2; ++b) {
        if (!rejected[a] && !rejected[b]) {
          baseline = (abs.fixes[a].p_world - abs.fixes[b].p_world).head<2>().norm();
        }
      }
    }
    estimate =
        abs.estimate_scale_heading && (used >= 3 || (used == 2 && baseline >= abs.min_baseline_m));
    if (!estimate) out.nav_model.setZero();
    if (estimate) {
      problem.SetParameterBlockVariable(out.nav_model.data());
    } else {
      problem.SetParameterBlockConstant(out.nav_model.data());
    }
    for (std::size_t k = 0; k < nf; ++k) {
      if (rejected[k]) continue;
      const AbsoluteFix& f = abs.fixes[k];
      const double dt_a = f.time_a - out.rate_t0[f.swath_a];
      const double dt_b = f.time_b - out.rate_t0[f.swath_b];
      auto* loss = new ceres::CauchyLoss(abs.loss_sigma);
      if (f.weight_b == 0 || f.swath_a == f.swath_b) {
        AbsoluteFix one = f;
        one.weight_b = 0;
        ids.push_back(
            problem.AddResidualBlock(new ceres::AutoDiffCostFunction<FixResidual, 3, 3, 2, 2>(
                                         new FixResidual{one, abs.pivot, dt_a, dt_b}),
                                     loss, out.offsets[f.swath_a].data(),
                                     out.rates[f.swath_a].data(), out.nav_model.data()));
      } else {
        ids.push_back(problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<FixResidual, 3, 3, 2, 3, 2, 2>(
                new FixResidual{f, abs.pivot, dt_a, dt_b}),
            loss, out.offsets[f.swath_a].data(), out.rates[f.swath_a].data(),
            out.offsets[f.swath_b].data(), out.rates[f.swath_b].data(), out.nav_model.data()));
      }
    }
    solve(problem, config, num_swaths, out);
    out.fix_rounds = round;
    std::vector<bool> now(nf, false);
    for (std::size_t k = 0; k < nf; ++k) {
      const AbsoluteFix& f = abs.fixes[k];
      Eigen::Vector3d r = out.apply_navigation_model(f.p_logged) + swath_corr(f) +
                          turned_lever(out.nav_model, f.lever) - f.p_world;
      if (!f.has_z) r.z() = 0;
      FixReport& rep = out.fixes[k];
      rep.time = f.time;
      rep.line = f.line;
      rep.name = f.name;
      rep.residual_m = r.norm();
      rep.normalized = rep.residual_m / f.sigma_m;
      now[k] = rep.normalized > gate_radius(abs.gate_sigma, f.has_z ? 3 : 2);
    }
    const bool settled = now == rejected;
    rejected = now;
    if (settled) break;
  }
  for (std::size_t k = 0; k < nf; ++k) out.fixes[k].rejected = rejected[k];
  out.estimated_scale_heading = estimate;
  // σ from the covariance of the solution (Ceres; the residuals are in units of their σ, the
  // ties' 2 cm a cell's worth).
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks = {
      {out.offsets[0].data(), out.offsets[0].data()}};
  if (estimate) blocks.emplace_back(out.nav_model.data(), out.nav_model.data());
  if (cov.Compute(blocks, &problem)) {
    double c0[9];
    if (cov.GetCovarianceBlock(out.offsets[0].data(), out.offsets[0].data(), c0)) {
      out.placement_sigma_m = {std::sqrt(std::max(0.0, c0[0])), std::sqrt(std::max(0.0, c0[4]))};
    }
    double cn[4];
    if (estimate && cov.GetCovarianceBlock(out.nav_model.data(), out.nav_model.data(), cn)) {
      out.scale_error_sigma = std::sqrt(std::max(0.0, cn[0]));
      out.heading_bias_sigma_rad = std::sqrt(std::max(0.0, cn[3]));
    }
  }
}

}  // namespace

SwathAdjustment adjust_swaths(int num_swaths, const std::vector<SwathTie>& ties,
                              const SwathAdjustmentConfig& config, int fixed_swath,
                              const AbsoluteConstraints* absolute) {
  config.validate();
  require(num_swaths >= 1, "swath adjustment: no swaths");
  require(fixed_swath >= 0 && fixed_swath < num_swaths,
          "swath adjustment: fixed swath " + std::to_string(fixed_swath) + " out of range");
  SwathAdjustment out;
  out.offsets.assign(static_cast<std::size_t>(num_swaths), Eigen::Vector3d::Zero());
  // adjacent[s]: (neighbour swath, tie index) over confident ties.
  std::vector<std::vector<std::pair<int, std::size_t>>> adjacent(
      static_cast<std::size_t>(num_swaths));
  for (std::size_t k = 0; k < ties.size(); ++k) {
    const SwathTie& t = ties[k];
    require(t.reference >= 0 && t.moving >= 0 && t.reference < num_swaths &&
                t.moving < num_swaths && t.reference != t.moving,
            "swath adjustment: a tie joins swaths " + std::to_string(t.reference) + " and " +
                std::to_string(t.moving) + " of " + std::to_string(num_swaths));
    require(t.t.allFinite() && std::isfinite(t.confidence) && t.nav_separation.allFinite(),
            "swath adjustment: a tie between swaths " + std::to_string(t.reference) + " and " +
                std::to_string(t.moving) + " is not finite");
    const bool used = t.confidence >= config.min_confidence && t.confidence > 0;
    out.tie_used.push_back(used);
    if (used) {
      adjacent[t.reference].emplace_back(t.moving, k);
      adjacent[t.moving].emplace_back(t.reference, k);
    }
  }
  // Every swath must be tied, through confident ties, to the fixed one. The breadth-first walk
  // also gives the initial guess: offsets accumulated along its tree (o_B = o_A + t).
  std::vector<bool> reached(static_cast<std::size_t>(num_swaths), false);
  std::queue<int> q;
  q.push(fixed_swath);
  reached[fixed_swath] = true;
  while (!q.empty()) {
    const int s = q.front();
    q.pop();
    for (const auto& [n, k] : adjacent[s]) {
      if (reached[n]) continue;
      reached[n] = true;
      const SwathTie& t = ties[k];
      out.offsets[n] = t.moving == n ? Eigen::Vector3d(out.offsets[s] + t.t)
                                     : Eigen::Vector3d(out.offsets[s] - t.t);
      q.push(n);
    }
  }
  std::string lonely;
  for (int i = 0; i < num_swaths; ++i) {
    if (!reached[i]) lonely += (lonely.empty() ? "" : ", ") + std::to_string(i);
  }
  require(lonely.empty(),
          "swath adjustment: swath(s) " + lonely + " have no confident tie (min_confidence " +
              std::to_string(config.min_confidence) + ") linking them to swath " +
              std::to_string(fixed_swath) + ": widen search_m, or the overlaps are featureless");

  if (absolute) {
    // Offsets relative to swath 0 (the fixes place it), rates held at zero, ties carried
    // into the corrected frame.
    const Eigen::Vector3d o0 = out.offsets[0];
    for (Eigen::Vector3d& o : out.offsets) o -= o0;
    out.rates.assign(static_cast<std::size_t>(num_swaths), Eigen::Vector2d::Zero());
    out.rate_t0.assign(static_cast<std::size_t>(num_swaths), 0.0);
    ceres::Problem problem;
    for (int i = 0; i < num_swaths; ++i) {
      problem.AddParameterBlock(out.offsets[i].data(), 3);
      problem.AddParameterBlock(out.rates[i].data(), 2);
      problem.SetParameterBlockConstant(out.rates[i].data());
    }
    problem.AddParameterBlock(out.nav_model.data(), 2);
    for (std::size_t k = 0; k < ties.size(); ++k) {
      if (!out.tie_used[k]) continue;
      const SwathTie& t = ties[k];
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<NavTieResidual, 3, 3, 2, 3, 2, 2>(
              new NavTieResidual{t.t, std::sqrt(t.confidence), 0.0, 0.0, t.nav_separation}),
          new ceres::CauchyLoss(config.loss_scale_m / kTieSigma), out.offsets[t.reference].data(),
          out.rates[t.reference].data(), out.offsets[t.moving].data(), out.rates[t.moving].data(),
          out.nav_model.data());
    }
    solve_with_fixes(problem, *absolute, config, num_swaths, out);
    for (const SwathTie& t : ties) {
      Eigen::Vector3d lt = t.t;
      lt.head<2>() = nav_tie_d(out.nav_model, t);
      out.tie_residual_m.push_back((out.offsets[t.moving] - out.offsets[t.reference] - lt).norm());
    }
    return out;
  }
  ceres::Problem problem;
  for (int i = 0; i < num_swaths; ++i) problem.AddParameterBlock(out.offsets[i].data(), 3);
  problem.SetParameterBlockConstant(out.offsets[fixed_swath].data());
  for (std::size_t k = 0; k < ties.size(); ++k) {
    if (!out.tie_used[k]) continue;
    const SwathTie& t = ties[k];
    auto* cost = new ceres::AutoDiffCostFunction<TieResidual, 3, 3, 3>(
        new TieResidual{t.t, std::sqrt(t.confidence)});
    problem.AddResidualBlock(cost, new ceres::CauchyLoss(config.loss_scale_m),
                             out.offsets[t.reference].data(), out.offsets[t.moving].data());
  }
  solve(problem, config, num_swaths, out);
  for (const SwathTie& t : ties) {
    out.tie_residual_m.push_back((out.offsets[t.moving] - out.offsets[t.reference] - t.t).norm());
  }
  return out;
}

namespace {

// √w · (c_B(t_B) − c_A(t_A) − t) / σ, c(t) = o + (r, 0)·dt.
struct DriftTieResidual {
  Eigen::Vector3d t;
  double sqrt_w, dt_a, dt_b;
  template <typename T>
  bool operator()(const T* o_a, const T* r_a, const T* o_b, const T* r_b, T* res) const {
    for (int k = 0; k < 3; ++k) {
      T cb = o_b[k], ca = o_a[k];
      if (k < 2) {
        cb += r_b[k] * T(dt_b);
        ca += r_a[k] * T(dt_a);
      }
      res[k] = T(sqrt_w / kTieSigma) * (cb - ca - T(t[k]));
    }
    return true;
  }
};

// Continuity across the turn from A's end (dt_end after its t0) to B's start: c_B(t0_B) −
// c_A(t1_A).
struct ContinuityResidual {
  double dt_end, sigma_h, sigma_v;
  template <typename T>
  bool operator()(const T* o_a, const T* r_a, const T* o_b, T* res) const {
    for (int k = 0; k < 3; ++k) {
      T end_a = o_a[k];
      if (k < 2) end_a += r_a[k] * T(dt_end);
      res[k] = (o_b[k] - end_a) / T(k < 2 ? sigma_h : sigma_v);
    }
    return true;
  }
};

struct RatePrior {
  double sigma;
  template <typename T>
  bool operator()(const T* r, T* res) const {
    res[0] = r[0] / T(sigma);
    res[1] = r[1] / T(sigma);
    return true;
  }
};

}  // namespace

SwathAdjustment adjust_swaths_drift(const std::vector<SwathTiming>& swaths,
                                    const std::vector<SwathTie>& ties,
                                    const SwathAdjustmentConfig& config,
                                    const AbsoluteConstraints* absolute) {
  config.validate();
  const int n = static_cast<int>(swaths.size());
  for (int i = 0; i < n; ++i) {
    const SwathTiming& w = swaths[i];
    require(std::isfinite(w.t0) && std::isfinite(w.t1) && w.t1 >= w.t0 &&
                std::isfinite(w.speed_mps) && w.speed_mps >= 0 && std::isfinite(w.gap_to_next_m) &&
                w.gap_to_next_m >= 0,
            "swath adjustment: swath " + std::to_string(i) +
                " has a bad time span, speed or turn length");
  }
  for (const SwathTie& t : ties) {
    require(std::isfinite(t.time_reference) && std::isfinite(t.time_moving),
            "swath adjustment: the drift method needs each tie's times (swaths " +
                std::to_string(t.reference) + " and " + std::to_string(t.moving) + ")");
  }
  // Constant offsets first: the connectivity check and the initial guess.
  SwathAdjustment out = adjust_swaths(n, ties, config, 0);
  out.rates.assign(static_cast<std::size_t>(n), Eigen::Vector2d::Zero());
  for (const SwathTiming& w : swaths) out.rate_t0.push_back(w.t0);
  out.offsets[0].setZero();

  ceres::Problem problem;
  for (int i = 0; i < n; ++i) {
    problem.AddParameterBlock(out.offsets[i].data(), 3);
    problem.AddParameterBlock(out.rates[i].data(), 2);
    // Rates near 0: the navigation drifts by f of the distance travelled.
    const double sigma_rate = std::max(1e-4, config.nav_drift_fraction * swaths[i].speed_mps);
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<RatePrior, 2, 2>(new RatePrior{sigma_rate}), nullptr,
        out.rates[i].data());
  }
  // The gauge: c_0(t0_0) = 0, unless fixes place the survey.
  if (!absolute) problem.SetParameterBlockConstant(out.offsets[0].data());
  for (std::size_t k = 0; k < ties.size(); ++k) {
    if (!out.tie_used[k]) continue;
    const SwathTie& t = ties[k];
    if (absolute) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<NavTieResidual, 3, 3, 2, 3, 2, 2>(new NavTieResidual{
              t.t, std::sqrt(t.confidence), t.time_reference - swaths[t.reference].t0,
              t.time_moving - swaths[t.moving].t0, t.nav_separation}),
          new ceres::CauchyLoss(config.loss_scale_m / kTieSigma), out.offsets[t.reference].data(),
          out.rates[t.reference].data(), out.offsets[t.moving].data(), out.rates[t.moving].data(),
          out.nav_model.data());
      continue;
    }
    auto* cost =
        new ceres::AutoDiffCostFunction<DriftTieResidual, 3, 3, 2, 3, 2>(new DriftTieResidual{
            t.t, std::sqrt(t.confidence), t.time_reference - swaths[t.reference].t0,
            t.time_moving - swaths[t.moving].t0});
    problem.AddResidualBlock(cost, new ceres::CauchyLoss(config.loss_scale_m / kTieSigma),
                             out.offsets[t.reference].data(), out.rates[t.reference].data(),
                             out.offsets[t.moving].data(), out.rates[t.moving].data());
  }
  for (int i = 0; i + 1 < n; ++i) {
    const double sigma_h = std::max(0.01, config.nav_drift_fraction * swaths[i].gap_to_next_m);
    auto* cost = new ceres::AutoDiffCostFunction<ContinuityResidual, 3, 3, 2, 3>(
        new ContinuityResidual{swaths[i].t1 - swaths[i].t0, sigma_h, 0.01});
    problem.AddResidualBlock(cost, nullptr, out.offsets[i].data(), out.rates[i].data(),
                             out.offsets[i + 1].data());
  }
  if (absolute) {
    solve_with_fixes(problem, *absolute, config, n, out);
  } else {
    solve(problem, config, n, out);
  }
  out.tie_residual_m.clear();
  for (const SwathTie& t : ties) {
    Eigen::Vector3d lt = t.t;
    lt.head<2>() = nav_tie_d(out.nav_model, t);
    out.tie_residual_m.push_back((out.correction(t.moving, t.time_moving) -
                                  out.correction(t.reference, t.time_reference) - lt)
                                     .norm());
  }
  return out;
}

ElevationMap shifted(const ElevationMap& map, const Eigen::Vector3d& t) {
  ElevationMap out = map;
  out.origin_xy += t.head<2>();
  for (float& v : out.z) {
    if (v == v) v = static_cast<float>(v + t.z());
  }
  return out;
}

}  // namespace sonar3d
