// Change detection between two surveys (include/sonar3d/world/change.hpp, docs/change.md).
#include "sonar3d/world/change.hpp"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/rgb_image.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/texture_io.hpp"
#include "sonar3d/recog/model.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

double yaw_of(const Eigen::Isometry3d& T) { return std::atan2(T(1, 0), T(0, 0)); }

// The cloud's points moved by T.
PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  PointCloud out;
  out.points.resize(cloud.size());
  const Eigen::Matrix3f R = T.linear().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), 1 << 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        out.points[i] = R * cloud.points[i] + t;
                      }
                    });
  return out;
}

// An elevation map of `cloud` on the grid of `like` (same cell, origin and size).
ElevationMap map_on_grid(const PointCloud& cloud, const ElevationMap& like) {
  ElevationMapConfig cfg;
  cfg.cell_m = like.cell_m;
  const double c = like.cell_m;
  cfg.region_min_xy = {like.origin_xy.x() + 0.5 * c, like.origin_xy.y() - (like.rows - 0.5) * c};
  cfg.region_max_xy = {like.origin_xy.x() + (like.cols - 0.5) * c, like.origin_xy.y() - 0.5 * c};
  ElevationMap m = elevation_map_from_points(cloud, cfg);
  if (m.rows != like.rows || m.cols != like.cols ||
      (m.origin_xy - like.origin_xy).norm() > 1e-6 * c) {
    throw Error("change detection: internal grid mismatch");  // cannot happen: same cell grid
  }
  return m;
}

ElevationMap map_of(const PointCloud& cloud, double cell_m, const char* which) {
  require(!cloud.empty(),
          std::string("change detection: survey ") + which + " has no points (nothing to compare)");
  ElevationMapConfig cfg;
  cfg.cell_m = cell_m;
  return elevation_map_from_points(cloud, cfg);
}

// Mean |A − B(x − dx, y − dy) − dz| over the smallest `fraction` of the overlap (nearest cell of
// B), and the overlap's size.
double registered_cost(const ElevationMap& a, const ElevationMap& b, const Eigen::Vector3d& t,
                       double fraction, std::size_t* overlap) {
  std::vector<float> d;
  d.reserve(a.z.size() / 4);
  const double c = b.cell_m;
  for (int r = 0; r < a.rows; ++r) {
    for (int col = 0; col < a.cols; ++col) {
      const float za = a.at(r, col);
      if (!(za == za)) continue;
      const Eigen::Vector2d p = a.cell_center_xy(r, col) - t.head<2>();
      const int bc = static_cast<int>(std::floor((p.x() - b.origin_xy.x()) / c));
      const int br = static_cast<int>(std::floor((b.origin_xy.y() - p.y()) / c));
      if (bc < 0 || br < 0 || bc >= b.cols || br >= b.rows) continue;
      const float zb = b.at(br, bc);
      if (!(zb == zb)) continue;
      d.push_back(std::abs(static_cast<float>(za - zb - t.z())));
    }
  }
  *overlap = d.size();
  if (d.empty()) return std::numeric_limits<double>::infinity();
  const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(fraction * d.size()));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k - 1), d.end());
  double sum = 0;
  for (std::size_t i = 0; i < k; ++i) sum += d[i];
  return sum / static_cast<double>(k);
}

// The quantile q of the values (partially reorders them).
double quantile(std::vector<float>& v, double q) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// The quantile q of the length of a standard normal vector of `dims` (1, 2 or 3) components (the
// chi distribution): P(|x| < z·sigma) = q. dims = 1 is the normal two-sided quantile.
double chi_quantile(double q, int dims) {
  auto cdf = [dims](double x) {
    if (dims == 2) return 1 - std::exp(-0.5 * x * x);
    const double p = std::erf(x / std::sqrt(2.0));
    return dims == 1 ? p : p - std::sqrt(2 / kPi) * x * std::exp(-0.5 * x * x);
  };
  double lo = 0, hi = 10;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (cdf(mid) < q ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Connected components of the cells of one non-zero sign, cells within `link` cells (Chebyshev)
// of each other linked; in the order of their first cell (row-major).
std::vector<std::vector<std::size_t>> sign_components(const std::vector<int8_t>& sign, int rows,
                                                      int cols, int link) {
  std::vector<std::vector<std::size_t>> out;
  std::vector<char> done(sign.size(), 0);
  std::vector<std::size_t> stack;
  for (std::size_t seed = 0; seed < sign.size(); ++seed) {
    if (sign[seed] == 0 || done[seed]) continue;
    std::vector<std::size_t> comp;
    done[seed] = 1;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      comp.push_back(i);
      const int row = static_cast<int>(i / static_cast<std::size_t>(cols));
      const int col = static_cast<int>(i % static_cast<std::size_t>(cols));
      for (int dr = -link; dr <= link; ++dr) {
        for (int dc = -link; dc <= link; ++dc) {
          const int rr = row + dr, cc = col + dc;
          if (rr < 0 || cc < 0 || rr >= rows || cc >= cols) continue;
          const std::size_t k = static_cast<std::size_t>(rr) * static_cast<std::size_t>(cols) + cc;
          if (sign[k] == sign[seed] && !done[k]) {
            done[k] = 1;
            stack.push_back(k);
          }
        }
      }
    }
    out.push_back(std::move(comp));
  }
  return out;
}

}  // namespace

void ChangeRegistrationConfig::validate() const {
  params::check(*this, "registration");
  require(yaw_cell_m >= cell_m, "yaw_cell_m must be at least the registration's cell_m");
  require(yaw_search_deg / yaw_step_deg <= 1000,
          "yaw_search_deg / yaw_step_deg must be at most 1000 (yaws searched)");
}

const char* colour_space_name(ColourSpace s) { return enum_name(kColourSpaceNames, s); }

void ColourChangeConfig::validate() const {
  params::check(*this, "colour");
  require(tolerance_m <= 20 * cell_m, "colour tolerance_m must be at most 20 colour cells");
  require(link_m <= 100 * cell_m, "colour link_m must be at most 100 colour cells");
}

void ChangeConfig::validate() const {
  params::check(*this, "change");
  registration.validate();
  colour.validate();
  require(tolerance_m <= 20 * cell_m, "tolerance_m must be at most 20 cells");
  require(link_m <= 100 * cell_m, "link_m must be at most 100 cells");
  require(confirm_radius_m <= 1000 * cell_m, "confirm_radius_m must be at most 1000 cells");
}

const char* object_status_name(ObjectStatus s) {
  static constexpr const char* kNames[] = {"unchanged", "moved", "added", "removed",
                                           "uncertain"};  // by ObjectStatus
  return enum_name(kNames, s);
}

namespace {

// ---------------------------------------------------------------------------------------------
// The stages of register_surveys, in the order it runs them: B's pivot, the maps of the yaw
// search, every yaw of the window on coarse maps (sec. 6.2.2.1, eq. 6.1–6.2), the shift refined
// at cell_m, then beyond the thesis a trimmed Gauss-Newton of B's heights onto A's (yaw, shift,
// height), kept only where it does better than the search.

// The turn by `yaw` about the vertical through `pivot`.
Eigen::Isometry3d turn_about(const Eigen::Vector3d& pivot, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = pivot - T.linear() * pivot;
  return T;
}

// B turns about the centre of its extent (at z = 0); every point of B must be finite.
Eigen::Vector3d survey_pivot(const PointCloud& b_world) {
  Eigen::Vector3f lo = b_world.points[0], hi = lo;
  for (const auto& p : b_world.points) {
    if (!p.allFinite()) throw Error("change detection: survey B has a point that is not finite");
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return Eigen::Vector3d(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), 0);
}

// A map's observed cells as points: each cell's centre at its height (its highest point).
std::vector<Eigen::Vector3d> cell_points(const ElevationMap& m) {
  std::vector<Eigen::Vector3d> out;
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.cols; ++c) {
      if (!m.valid(r, c)) continue;
      const Eigen::Vector2d xy = m.cell_center_xy(r, c);
      out.emplace_back(xy.x(), xy.y(), m.at(r, c));
    }
  }
  return out;
}

// The maps the yaw search works on.
struct YawSearchMaps {
  ElevationMap a_fine;    // A at cell_m
  double yaw_cell = 0;    // the yaw search's cell, m
  ElevationMap a_coarse;  // A at yaw_cell
  PointCloud b_thin;      // B's map at yaw_cell / 5, one point per cell
};

// The yaw search's cell: yaw_cell_m, but fine enough that A's map keeps ~20,000 observed cells (on
// a small site, cells of 25 cm leave too few for the yaw to show), at least cell_m. The search
// turns B's map at a fifth of its cell as points (one per cell: its highest), not every point of
// B (4.4 M on the field; the map keeps only the highest per cell anyway).
YawSearchMaps yaw_search_maps(const PointCloud& a_world, const PointCloud& b_world,
                              const ChangeRegistrationConfig& config) {
  YawSearchMaps m;
  m.a_fine = map_of(a_world, config.cell_m, "A");
  const double observed_m2 =
      static_cast<double>(m.a_fine.num_valid()) * config.cell_m * config.cell_m;
  m.yaw_cell = std::clamp(std::sqrt(observed_m2 / 20000.0), config.cell_m, config.yaw_cell_m);
  m.a_coarse = map_of(a_world, m.yaw_cell, "A");
  for (const Eigen::Vector3d& p : cell_points(map_of(b_world, m.yaw_cell / 5, "B"))) {
    m.b_thin.points.push_back(p.cast<float>());
  }
  return m;
}

// One yaw tried: its cost (infinite when the maps do not register), the total shift after the
// turn and the overlap.
struct Trial {
  double yaw = 0, cost = std::numeric_limits<double>::infinity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  // total shift after the turn
  std::size_t overlap = 0;
};

// B turned by `yaw` about the pivot, moved by `prior`, then registered onto `a` by sec. 6.2.2.1's
// search (eq. 6.1–6.2) within ±search; scored by the mean |A − B| over the inlier fraction.
// `last_error`: why the last failed trial failed.
// `subcell`: the shift searched within ±½ cell too where the maps are at cell_m (false: whole
// cells only, a yaw scan's score).
Trial shift_trial(const ElevationMap& a, const PointCloud& b, const Eigen::Vector3d& pivot,
                  double yaw, const Eigen::Vector3d& prior, double search,
                  const ChangeRegistrationConfig& config, std::string& last_error,
                  bool subcell = true) {
  Trial tr;
  tr.yaw = yaw;
  Eigen::Isometry3d T = turn_about(pivot, yaw);
  T.translation() += prior;
  const ElevationMap bm = map_of(transformed(b, T), a.cell_m, "B");
  if (!maps_may_overlap(a, bm, search)) {
    last_error = "their extents do not meet";
    return tr;
  }
  SwathRegistrationConfig sw;
  sw.search_m = search;
  sw.min_overlap_cells = config.min_overlap_cells;
  sw.coarse_factor = config.coarse_factor;
  sw.num_threads = config.num_threads;
  // Sub-cell at cell_m only: at 25 cm it changed the field's yaw winner for the worse (the
  // fine stage refines the shift); on small sites the yaw cell is cell_m.
  sw.subcell = subcell && a.cell_m <= config.cell_m;
  try {
    const SwathTie tie = register_elevation_maps(a, bm, sw);
    tr.t = prior + tie.t;
    tr.cost = registered_cost(a, bm, tie.t, config.inlier_fraction, &tr.overlap);
  } catch (const Error& e) {
    last_error = e.what();
  }
  return tr;
}

// A's height and gradient at (x, y), bilinear between the four surrounding cell centres of `a`
// (cell `cell`); false outside A or next to an unobserved cell.
bool sample_height(const ElevationMap& a, double cell, double x, double y, double* z,
                   Eigen::Vector2d* g) {
  const double u = (x - a.origin_xy.x()) / cell - 0.5;
  const double v = (a.origin_xy.y() - y) / cell - 0.5;
  const int c0 = static_cast<int>(std::floor(u)), r0 = static_cast<int>(std::floor(v));
  if (c0 < 0 || r0 < 0 || c0 + 1 >= a.cols || r0 + 1 >= a.rows) return false;
  const float z00 = a.at(r0, c0), z01 = a.at(r0, c0 + 1), z10 = a.at(r0 + 1, c0),
              z11 = a.at(r0 + 1, c0 + 1);
  if (!(z00 == z00 && z01 == z01 && z10 == z10 && z11 == z11)) return false;
  const double fu = u - c0, fv = v - r0;
  *z = (1 - fv) * ((1 - fu) * z00 + fu * z01) + fv * ((1 - fu) * z10 + fu * z11);
  const double dzdu = (1 - fv) * (z01 - z00) + fv * (z11 - z10);
  const double dzdv = (1 - fu) * (z10 - z00) + fu * (z11 - z01);
  *g = {dzdu / cell, -dzdv / cell};  // rows run southward
  return true;
}

// The Gauss-Newton's solution: yaw, shift and height, its cost and cells, its covariance.
struct HeightFit {
  double yaw = 0;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double cost = 0;
  std::size_t used = 0;
  Eigen::Matrix4d cov = Eigen::Matrix4d::Constant(std::numeric_limits<double>::quiet_NaN());
};

// Beyond the thesis: yaw, shift and height together by trimmed Gauss-Newton of B's heights onto
// A's height field (an ICP of the seabed on the elevation maps, point to surface), at half of
// cell_m, from the search's solution `best`: residual r = A(R(ψ)(p − c) + c + t) − (z + dz) over
// B's cells, the smallest inlier_fraction of |r| kept each iteration; steps bounded by the basin of
// the coarse search (a yaw cell, a yaw step).
HeightFit refine_heights(const PointCloud& a_world, const PointCloud& b_world,
                         const Eigen::Vector3d& pivot, const Trial& best, double yaw_cell,
                         const ChangeRegistrationConfig& config) {
  const double gn_cell = 0.5 * config.cell_m;
  const ElevationMap a_gn = map_of(a_world, gn_cell, "A");
  const std::vector<Eigen::Vector3d> pts = cell_points(map_of(b_world, gn_cell, "B"));
  HeightFit fit;
  double& yaw = fit.yaw;
  Eigen::Vector3d& t = fit.t;
  yaw = best.yaw;
  t = best.t;
  // B's points were turned about the pivot, then shifted: q = R(ψ)(p − c) + c + t.
  std::vector<double> absr;
  fit.cost = best.cost;
  fit.used = 0;
  for (int it = 0; it < 30; ++it) {
    const double cs = std::cos(yaw), sn = std::sin(yaw);
    struct Row {
      Eigen::Vector4d j;
      double r;
    };
    std::vector<Row> rows;
    rows.reserve(pts.size());
    for (const Eigen::Vector3d& p : pts) {
      const double dx = p.x() - pivot.x(), dy = p.y() - pivot.y();
      const double qx = cs * dx - sn * dy + pivot.x() + t.x();
      const double qy = sn * dx + cs * dy + pivot.y() + t.y();
      double za;
      Eigen::Vector2d g;
      if (!sample_height(a_gn, gn_cell, qx, qy, &za, &g)) continue;
      const double dqx = -sn * dx - cs * dy, dqy = cs * dx - sn * dy;  // ∂q/∂ψ
      rows.push_back(
          {Eigen::Vector4d(g.x() * dqx + g.y() * dqy, g.x(), g.y(), -1), za - (p.z() + t.z())});
    }
    if (rows.size() < static_cast<std::size_t>(config.min_overlap_cells)) break;
    absr.resize(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) absr[i] = std::abs(rows[i].r);
    const std::size_t keep =
        std::max<std::size_t>(1, static_cast<std::size_t>(config.inlier_fraction * rows.size()));
    std::nth_element(absr.begin(), absr.begin() + static_cast<std::ptrdiff_t>(keep - 1),
                     absr.end());
    const double cut = absr[keep - 1];
    Eigen::Matrix4d H = Eigen::Matrix4d::Zero();
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    double sum = 0, sum2 = 0;
    std::size_t used = 0;
    for (const Row& row : rows) {
      if (std::abs(row.r) > cut) continue;
      H += row.j * row.j.transpose();
      rhs -= row.j * row.r;
      sum += std::abs(row.r);
      sum2 += row.r * row.r;
      ++used;
    }
    fit.cost = sum / static_cast<double>(used);
    fit.used = used;
    // The covariance at this iterate, s²·H⁻¹ (the last one is kept: at convergence, the
    // solution's).
    if (used > 4 && H.fullPivLu().rank() == 4) {
      fit.cov = (sum2 / static_cast<double>(used - 4)) * H.inverse();
    }
    H.diagonal() += Eigen::Vector4d::Constant(1e-9 * H.trace() + 1e-12);  // a flat seabed
    const Eigen::Vector4d delta = H.ldlt().solve(rhs);
    if (!delta.allFinite()) break;
    // Steps bounded by the basin of the coarse search (a coarse cell, a yaw step).
    const double step_yaw =
        std::clamp(delta[0], -config.yaw_step_deg * kDeg, config.yaw_step_deg * kDeg);
    yaw += step_yaw;
    t += Eigen::Vector3d(std::clamp(delta[1], -yaw_cell, yaw_cell),
                         std::clamp(delta[2], -yaw_cell, yaw_cell), delta[3]);
    if (std::abs(step_yaw) < 1e-6 && delta.segment<3>(1).norm() < 1e-4) break;
  }
  return fit;
}

// Stage 1, the yaw search: every yaw of ±yaw_search_deg every yaw_step_deg, B turned about the
// pivot and registered onto A by sec. 6.2.2.1's search over the whole ±search_m (eq. 6.1–6.2),
// scored by registered_cost; the lowest wins. Beyond the thesis, a coarse-to-fine yaw search
// (yaw_refine_best = K > 0, maps at cell_m): every yaw is scored first with the shift at whole
// cells only, then the K best are searched again from their shift (±1 cell, then sub-cell) — the
// sub-cell search (121 bilinear evaluations of eq. 6.1–6.2 per yaw) costs more than the whole
// window's search at cells. K = 0, or K not below the number of yaws: every yaw in full.
Trial yaw_search(const YawSearchMaps& maps, const Eigen::Vector3d& pivot,
                 const ChangeRegistrationConfig& config, std::string& last_error) {
  const int n = static_cast<int>(std::floor(config.yaw_search_deg / config.yaw_step_deg + 1e-9));
  const int yaws = 2 * n + 1;
  const bool subcell = maps.a_coarse.cell_m <= config.cell_m;
  const bool two_pass = subcell && config.yaw_refine_best > 0 && config.yaw_refine_best < yaws;
  std::vector<Trial> trials;
  trials.reserve(static_cast<std::size_t>(yaws));
  for (int k = -n; k <= n; ++k) {
    trials.push_back(shift_trial(maps.a_coarse, maps.b_thin, pivot, k * config.yaw_step_deg * kDeg,
                                 Eigen::Vector3d::Zero(), config.search_m, config, last_error,
                                 !two_pass));
  }
  if (two_pass) {
    // The K best of the scan (ties: the first in the window's order, as the exhaustive search's
    // strict minimum takes them).
    std::vector<int> order(static_cast<std::size_t>(yaws));
    for (int i = 0; i < yaws; ++i) order[static_cast<std::size_t>(i)] = i;
    std::stable_sort(order.begin(), order.end(), [&](int x, int y) {
      return trials[static_cast<std::size_t>(x)].cost < trials[static_cast<std::size_t>(y)].cost;
    });
    std::vector<char> refined(static_cast<std::size_t>(yaws), 0);
    for (int i = 0; i < config.yaw_refine_best; ++i) {
      const auto k = static_cast<std::size_t>(order[static_cast<std::size_t>(i)]);
      if (!std::isfinite(trials[k].cost)) break;  // the rest do not overlap either
      // From the scan's whole-cell shift: ±1 cell, then sub-cell (the window's search again).
      trials[k] = shift_trial(maps.a_coarse, maps.b_thin, pivot, trials[k].yaw, trials[k].t,
                              maps.a_coarse.cell_m, config, last_error);
      refined[k] = 1;
    }
    // Only the refined ones compete: a scan's cost at whole cells is not comparable.
    for (std::size_t k = 0; k < trials.size(); ++k) {
      if (!refined[k]) trials[k].cost = std::numeric_limits<double>::infinity();
    }
  }
  Trial best;
  for (const Trial& tr : trials) {
    if (tr.cost < best.cost) best = tr;
  }
  return best;
}

}  // namespace

// The pipeline of survey registration (stages above): pivot, yaw search on coarse maps, shift
// refined at cell_m, Gauss-Newton of the heights, the better of the last two.
ChangeRegistration register_surveys(const PointCloud& a_world, const PointCloud& b_world,
                                    const ChangeRegistrationConfig& config) {
  config.validate();
  const auto t0 = std::chrono::steady_clock::now();
  require(!b_world.empty(), "change detection: survey B has no points (nothing to compare)");
  const Eigen::Vector3d pivot = survey_pivot(b_world);
  const YawSearchMaps maps = yaw_search_maps(a_world, b_world, config);
  const double yaw_cell = maps.yaw_cell;
  std::string last_error;
  // 1. Every yaw of the window on coarse maps, the shift searched over the whole ±search_m
  // (yaw_search).
  Trial best = yaw_search(maps, pivot, config, last_error);
  require(std::isfinite(best.cost),
          "change detection: the surveys do not overlap (no yaw within ±" +
              std::to_string(config.yaw_search_deg) + " deg and shift within ±" +
              std::to_string(config.search_m) + " m leaves " +
              std::to_string(config.min_overlap_cells) + " cells observed in both; " + last_error +
              ")");
  // 2. At cell_m, the shift refined within a yaw cell of the coarse one (sub-cell).
  best = shift_trial(maps.a_fine, b_world, pivot, best.yaw, best.t, yaw_cell, config, last_error);
  require(std::isfinite(best.cost),
          "change detection: the surveys do not overlap at the fine cell (" + last_error + ")");
  // 3. Beyond the thesis: trimmed Gauss-Newton of the heights (refine_heights).
  HeightFit gn = refine_heights(a_world, b_world, pivot, best, yaw_cell, config);
  // Kept only when it stays within the coarse search's basin and lowers the shift search's own
  // cost (mean |A − B| over the inlier fraction at cell_m): on maps that are not rigidly alike
  // (dead reckoning distorts each survey differently), the least-squares optimum can sit
  // elsewhere than the robust one.
  bool refined = gn.used > 0 && std::abs(gn.yaw - best.yaw) <= 2 * config.yaw_step_deg * kDeg &&
                 (gn.t - best.t).head<2>().norm() <= yaw_cell;
  if (refined) {
    Eigen::Isometry3d T = turn_about(pivot, gn.yaw);
    T.translation() += gn.t;
    std::size_t overlap = 0;
    const double cost =
        registered_cost(maps.a_fine, map_of(transformed(b_world, T), config.cell_m, "B"),
                        Eigen::Vector3d::Zero(), config.inlier_fraction, &overlap);
    refined = cost < best.cost;
    if (refined) gn.cost = cost, gn.used = overlap;
  }
  ChangeRegistration out;
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = refined ? gn.t : best.t;
  out.T_a_b = shift * turn_about(pivot, refined ? gn.yaw : best.yaw);
  out.method = refined ? "elevation-map shift search (sec. 6.2.2.1, eq. 6.1-6.2) over yaw, then "
                         "trimmed Gauss-Newton of heights (yaw, shift, height)"
                       : "elevation-map shift search (sec. 6.2.2.1, eq. 6.1-6.2) over yaw";
  out.yaw_deg = (refined ? gn.yaw : best.yaw) / kDeg;
  out.rms_m = refined ? gn.cost : best.cost;
  out.overlap_cells = refined ? gn.used : best.overlap;
  out.covariance = gn.cov;
  out.covariance_cells = gn.used;
  out.pivot = pivot;
  out.seconds = seconds_since(t0);
  return out;
}

RegistrationFit registration_fit(const ElevationMap& a, const PointCloud& b_world,
                                 const Eigen::Isometry3d& T_a_b, double inlier_fraction) {
  RegistrationFit fit;
  if (b_world.empty() || a.empty()) return fit;
  // B's map on A's cell grid (its own extent), compared cell by cell.
  const PointCloud b = transformed(b_world, T_a_b);
  ElevationMapConfig cfg;
  cfg.cell_m = a.cell_m;
  const ElevationMap bm = elevation_map_from_points(b, cfg);
  const double c = a.cell_m;
  std::vector<float> d;
  d.reserve(bm.z.size());
  for (int r = 0; r < bm.rows; ++r) {
    for (int col = 0; col < bm.cols; ++col) {
      const float zb = bm.at(r, col);
      if (!(zb == zb)) continue;
      ++fit.b_cells;
      const Eigen::Vector2d p = bm.cell_center_xy(r, col);
      const int ac = static_cast<int>(std::floor((p.x() - a.origin_xy.x()) / c));
      const int ar = static_cast<int>(std::floor((a.origin_xy.y() - p.y()) / c));
      if (ac < 0 || ar < 0 || ac >= a.cols || ar >= a.rows) continue;
      const float za = a.at(ar, ac);
      if (!(za == za)) continue;
      d.push_back(za - zb);
    }
  }
  fit.overlap = d.size();
  if (d.empty()) return fit;
  std::vector<float> s = d;
  fit.dz = quantile(s, 0.5);  // eq. 6.1: the depth distributions aligned by their median
  for (float& x : d) x = std::abs(x - static_cast<float>(fit.dz));
  const std::size_t k =
      std::max<std::size_t>(1, static_cast<std::size_t>(inlier_fraction * d.size()));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k - 1), d.end());
  double sum = 0;
  for (std::size_t i = 0; i < k; ++i) sum += d[i];
  fit.cost_m = sum / static_cast<double>(k);
  return fit;
}

namespace {

// ---------------------------------------------------------------------------------------------
// The stages of compare_placements: each placement's model, centre and match radius; pairs of
// one model within the radius, nearest first; then one change per placement of A (unchanged,
// moved or removed) and per unpaired placement of B (added).

// One survey's placements as compare_placements sees them: each one's catalogue model, centre
// and match radius.
struct PlacedSide {
  std::vector<ObjectModel> models;
  std::vector<Eigen::Vector2d> centres;
};

// The match radius scales with the object (ChangeConfig::match_radius_factor × r_model).
double match_radius(const ObjectModel& m, const ChangeConfig& config) {
  return m.has_size()
             ? std::max(config.min_match_radius_m, config.match_radius_factor * m.radius_m())
             : config.match_radius_m;
}

// Each placement's catalogue model (an empty model without a catalogue; a model the catalogue
// does not list is an error) and centre: its footprint's centre placed (a CAD origin may sit at a
// corner of a frame, where a turn alone would read as a shift), or its origin when the size is
// unknown.
PlacedSide placed_side(const std::vector<SurveyPlacement>& placements, const ObjectModels& models,
                       const char* which) {
  PlacedSide side;
  side.models.resize(placements.size());
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const SurveyPlacement& p = placements[i];
    if (models.empty()) continue;
    const auto it = models.find(p.model);
    require(it != models.end(), std::string("placements of survey ") + which + ": placement " +
                                    std::to_string(i) + " is a model '" + printable(p.model) +
                                    "' that the catalogue does not list");
    side.models[i] = it->second;
  }
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const SurveyPlacement& p = placements[i];
    const ObjectModel& m = side.models[i];
    if (!m.has_size()) {
      side.centres.push_back(p.T_world_model.translation().head<2>());
      continue;
    }
    const Eigen::Vector2d c = m.footprint.center();
    side.centres.push_back(
        (p.T_world_model * Eigen::Vector3d(p.scale * c.x(), p.scale * c.y(), 0)).head<2>());
  }
  return side;
}

// Identity (same model) and pose (centres within the radius): nearest pairs first, the distance
// relative to the radius (a large structure's 1 m and a small one's 10 cm weigh alike). Fills
// match_a[i] (the placement of B paired with A's i, −1 for none) and match_b alike.
void pair_placements(const std::vector<SurveyPlacement>& a, const PlacedSide& sa,
                     const std::vector<SurveyPlacement>& b_in_a, const PlacedSide& sb,
                     const ChangeConfig& config, std::vector<long>& match_a,
                     std::vector<long>& match_b) {
  struct Pair {
    double d;
    std::size_t i, j;
  };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double rad = match_radius(sa.models[i], config);
    for (std::size_t j = 0; j < b_in_a.size(); ++j) {
      if (a[i].model != b_in_a[j].model) continue;
      const double d = (sa.centres[i] - sb.centres[j]).norm();
      if (d <= rad) pairs.push_back({d / rad, i, j});
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair& x, const Pair& y) { return x.d < y.d; });
  match_a.assign(a.size(), -1);
  match_b.assign(b_in_a.size(), -1);
  for (const Pair& p : pairs) {
    if (match_a[p.i] >= 0 || match_b[p.j] >= 0) continue;
    match_a[p.i] = static_cast<long>(p.j);
    match_b[p.j] = static_cast<long>(p.i);
  }
}

// The model the other survey placed over an unpaired placement (another model, unpaired too,
// within the larger of the two radii): the recognitions disagree on what stands there.
std::string other_over(const Eigen::Vector2d& c, const std::string& model, double rad,
                       const std::vector<SurveyPlacement>& others, const PlacedSide& other_side,
                       const std::vector<long>& matched, const ChangeConfig& config) {
  std::string best;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < others.size(); ++k) {
    if (matched[k] >= 0 || others[k].model == model) continue;
    const double d = (other_side.centres[k] - c).norm();
    if (d <= std::max(rad, match_radius(other_side.models[k], config)) && d < best_d) {
      best_d = d;
      best = others[k].model;
    }
  }
  return best;
}

// A paired placement's change: the shift of its centre and the turn modulo the model's symmetry
// about the vertical (sec. 6.3.2.5's yaw ranges); unchanged within the tolerances, moved beyond.
void measure_move(const SurveyPlacement& a, const Eigen::Vector2d& ca, const ObjectModel& ma,
                  const SurveyPlacement& b, const Eigen::Vector2d& cb, const ChangeConfig& config,
                  ObjectChange& c) {
  c.in_b = true;
  c.T_world_model_b_in_a = b.T_world_model;
  c.confidence_b = b.confidence;
  c.shift_m = (cb - ca).norm();
  // The turn modulo the model's symmetry about the vertical (sec. 6.3.2.5's yaw ranges).
  const Symmetry sym = ma.symmetry;
  const double period = sym == Symmetry::Half ? 180 : 360;
  double turn =
      std::fmod(std::abs(yaw_of(b.T_world_model) - yaw_of(a.T_world_model)) / kDeg, period);
  turn = std::min(turn, period - turn);
  c.turn_deg = sym == Symmetry::Full ? 0 : turn;
  c.status = c.shift_m <= config.shift_tol_m && c.turn_deg <= config.turn_tol_deg
                 ? ObjectStatus::Unchanged
                 : ObjectStatus::Moved;
}

}  // namespace

// The pipeline of placement comparison (stages above).
std::vector<ObjectChange> compare_placements(const std::vector<SurveyPlacement>& a,
                                             const std::vector<SurveyPlacement>& b_in_a,
                                             const ObjectModels& models,
                                             const ChangeConfig& config) {
  config.validate();
  // Pairs are formed among placements of one model within the match radius: bounded by n².
  require(a.size() <= kMaxComparedPlacements && b_in_a.size() <= kMaxComparedPlacements,
          "change detection: at most " + std::to_string(kMaxComparedPlacements) +
              " placements per survey are compared");
  const PlacedSide sa = placed_side(a, models, "A");
  const PlacedSide sb = placed_side(b_in_a, models, "B");
  std::vector<long> match_a, match_b;
  pair_placements(a, sa, b_in_a, sb, config, match_a, match_b);
  std::map<std::string, int> count;
  std::vector<ObjectChange> out;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ObjectChange c;
    c.model = a[i].model;
    c.id = c.model + "_" + std::to_string(count[c.model]++);
    c.in_a = true;
    c.T_world_model_a = a[i].T_world_model;
    c.confidence_a = a[i].confidence;
    c.match_radius_m = match_radius(sa.models[i], config);
    if (match_a[i] < 0) {
      c.status = ObjectStatus::Removed;
      c.other_model =
          other_over(sa.centres[i], a[i].model, c.match_radius_m, b_in_a, sb, match_b, config);
    } else {
      const std::size_t j = static_cast<std::size_t>(match_a[i]);
      measure_move(a[i], sa.centres[i], sa.models[i], b_in_a[j], sb.centres[j], config, c);
    }
    out.push_back(c);
  }
  for (std::size_t j = 0; j < b_in_a.size(); ++j) {
    if (match_b[j] >= 0) continue;
    ObjectChange c;
    c.model = b_in_a[j].model;
    c.id = c.model + "_" + std::to_string(count[c.model]++);
    c.status = ObjectStatus::Added;
    c.in_b = true;
    c.T_world_model_b_in_a = b_in_a[j].T_world_model;
    c.confidence_b = b_in_a[j].confidence;
    c.match_radius_m = match_radius(sb.models[j], config);
    c.other_model = other_over(sb.centres[j], c.model, c.match_radius_m, a, sa, match_a, config);
    out.push_back(c);
  }
  return out;
}

namespace {

// The height change map, its threshold and regions (fills the geometry part of `r`).
void compare_geometry(const PointCloud& a_world, const PointCloud& b_in_a,
                      const ChangeConfig& config, ChangeResult* r) {
  const ElevationMap a = map_of(a_world, config.cell_m, "A");
  const ElevationMap b = map_on_grid(b_in_a, a);
  ElevationMap d = a;
  std::vector<float> values;
  for (std::size_t i = 0; i < a.z.size(); ++i) {
    const bool both = a.z[i] == a.z[i] && b.z[i] == b.z[i];
    d.z[i] = both ? b.z[i] - a.z[i] : ElevationMap::kNoData;
    if (both) values.push_back(d.z[i]);
  }
  r->registration.overlap_cells = values.size();
  require(values.size() >= static_cast<std::size_t>(config.registration.min_overlap_cells),
          "change detection: the registered surveys overlap on " + std::to_string(values.size()) +
              " cells of " + std::to_string(config.cell_m) + " m only (min_overlap_cells = " +
              std::to_string(config.registration.min_overlap_cells) + ")");
  // The noise of both surveys and what registration left, from the differences themselves: a
  // robust sigma about their median (changes are outliers of it).
  ChangeThresholds& th = r->thresholds;
  th.cell_m = config.cell_m;
  th.median_m = quantile(values, 0.5);
  for (float& v : values) v = std::abs(v - static_cast<float>(th.median_m));
  th.sigma_m = std::max(config.min_sigma_m, quantile(values, config.sigma_quantile) /
                                                chi_quantile(config.sigma_quantile, 1));
  th.k_sigma = config.k_sigma;
  th.change_m = config.k_sigma * th.sigma_m;
  th.min_area_m2 = config.min_area_m2;
  th.shift_tol_m = config.shift_tol_m;
  th.turn_tol_deg = config.turn_tol_deg;
  th.match_radius_m = config.match_radius_m;
  th.match_radius_factor = config.match_radius_factor;
  th.min_match_radius_m = config.min_match_radius_m;

  // A cell changed when B's height lies beyond the range of A's heights in the cells within
  // tolerance_m around it (at least the 3×3), or A's beyond B's, by more than the threshold: a
  // wall that the two maps place less than that apart is no change. (The two tests cannot
  // disagree in sign.)
  const int rows = a.rows, cols = a.cols;
  std::vector<int8_t> sign(a.z.size(), 0);
  const float med = static_cast<float>(th.median_m), thr = static_cast<float>(th.change_m);
  const int reach = std::max(1, static_cast<int>(std::lround(config.tolerance_m / config.cell_m)));
  tbb::parallel_for(0, rows, [&](int row) {
    for (int col = 0; col < cols; ++col) {
      const std::size_t i = a.index(row, col);
      if (!(d.z[i] == d.z[i])) continue;
      float alo = std::numeric_limits<float>::infinity(), ahi = -alo, blo = alo, bhi = -alo;
      for (int dr = -reach; dr <= reach; ++dr) {
        for (int dc = -reach; dc <= reach; ++dc) {
          const int rr = row + dr, cc = col + dc;
          if (rr < 0 || cc < 0 || rr >= rows || cc >= cols) continue;
          const std::size_t k = a.index(rr, cc);
          if (a.z[k] == a.z[k]) alo = std::min(alo, a.z[k]), ahi = std::max(ahi, a.z[k]);
          if (b.z[k] == b.z[k])
            blo = std::min(blo, b.z[k] - med), bhi = std::max(bhi, b.z[k] - med);
        }
      }
      const float zb = b.z[i] - med, za = a.z[i];
      // Raised: B above all of A around, or A below all of B around (a thin tube, a cell or two
      // wide, passes one of the two); a sub-cell shift of a wall passes neither.
      if (zb - ahi > thr || blo - za > thr) sign[i] = 1;
      if (alo - zb > thr || za - bhi > thr) sign[i] = -1;
    }
  });
  // Regions: changed cells of one sign linked when within link_m of each other (a moved frame of
  // thin tubes changes in strips that the 3×3 test above breaks apart).
  const int link = std::max(1, static_cast<int>(std::lround(config.link_m / config.cell_m)));
  const double cell_area = config.cell_m * config.cell_m;
  r->region_cell.assign(a.z.size(), -1);
  for (const std::vector<std::size_t>& comp : sign_components(sign, rows, cols, link)) {
    ChangeRegion reg;
    reg.raised = sign[comp[0]] > 0;
    double sx = 0, sy = 0, sz = 0, sd = 0;
    for (const std::size_t i : comp) {
      const int row = static_cast<int>(i / static_cast<std::size_t>(cols));
      const int col = static_cast<int>(i % static_cast<std::size_t>(cols));
      const Eigen::Vector2d c = a.cell_center_xy(row, col);
      sx += c.x();
      sy += c.y();
      sz += 0.5 * (a.z[i] + b.z[i]);
      sd += d.z[i];
      reg.max_abs_change_m = std::max(reg.max_abs_change_m, std::abs(static_cast<double>(d.z[i])));
    }
    reg.cells = comp.size();
    r->significant_cells += reg.cells;
    const double n = static_cast<double>(reg.cells);
    reg.area_m2 = n * cell_area;
    if (reg.area_m2 < config.min_area_m2) continue;
    reg.centroid = {sx / n, sy / n, sz / n};
    reg.mean_change_m = sd / n;
    reg.id = static_cast<int>(r->regions.size());
    for (const std::size_t i : comp) r->region_cell[i] = reg.id;
    r->regions.push_back(reg);
  }
  // The registration's residual: the RMS of B − A over the cells within the threshold of the
  // median (the noise; steps at walls and the changes left out).
  double ss = 0;
  std::size_t m = 0;
  for (std::size_t i = 0; i < d.z.size(); ++i) {
    if (d.z[i] == d.z[i] && std::abs(d.z[i] - med) <= thr) {
      ss += static_cast<double>(d.z[i]) * d.z[i], ++m;
    }
  }
  r->registration.rms_m = m > 0 ? std::sqrt(ss / static_cast<double>(m)) : 0;
  r->change_map = std::move(d);
  r->height_b = b;
}

nlohmann::json matrix_json(const Eigen::Isometry3d& T) {
  nlohmann::json j = nlohmann::json::array();
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 4; ++col) j.push_back(T.matrix()(row, col));
  }
  return j;
}

}  // namespace

namespace {

// Linear RGB (sRGB primaries, D65) to CIELAB (D65 white).
Eigen::Vector3d linear_rgb_to_lab(const Eigen::Vector3d& rgb) {
  Eigen::Matrix3d M;
  M << 0.4124564, 0.3575761, 0.1804375, 0.2126729, 0.7151522, 0.0721750, 0.0193339, 0.1191920,
      0.9503041;
  const Eigen::Vector3d xyz = (M * rgb).cwiseQuotient(Eigen::Vector3d(0.95047, 1.0, 1.08883));
  auto f = [](double t) {
    constexpr double d = 6.0 / 29;
    return t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29;
  };
  const double fx = f(xyz.x()), fy = f(xyz.y()), fz = f(xyz.z());
  return {116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)};
}

constexpr std::size_t kMaxColourCells = 5'000'000;

// A coloured cloud binned on a grid: per cell the mean linear RGB and z of its coloured points.
struct ColourGrid {
  std::vector<Eigen::Vector3d> rgb;
  std::vector<double> z;
  std::vector<int> count;
};

// Only the coloured points within `top_layer_m` of the highest coloured point of their cell count:
// the top a camera looking down sees, not the sides of an object and the seabed beside it, whose
// mix in a cell at an edge differs between two surveys.
ColourGrid bin_colours(const PointCloud& cloud, const ElevationMap& grid, double top_layer_m) {
  ColourGrid g;
  g.rgb.assign(grid.z.size(), Eigen::Vector3d::Zero());
  g.z.assign(grid.z.size(), 0);
  g.count.assign(grid.z.size(), 0);
  float lut[256];
  for (int v = 0; v < 256; ++v) lut[v] = srgb_to_linear(static_cast<float>(v) / 255.0f);
  // The cell of each coloured point (or none), and the top of each cell.
  std::vector<std::int64_t> cell(cloud.size(), -1);
  std::vector<float> top(grid.z.size(), -std::numeric_limits<float>::infinity());
  const std::vector<std::uint8_t> seen = video_coloured(cloud);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!seen[i]) continue;  // no camera saw it (sonar3d texture)
    const Eigen::Vector3f& p = cloud.points[i];
    const double u = std::floor((p.x() - grid.origin_xy.x()) / grid.cell_m);
    const double v = std::floor((grid.origin_xy.y() - p.y()) / grid.cell_m);
    if (!(u >= 0 && v >= 0 && u < grid.cols && v < grid.rows)) continue;
    const std::size_t k = grid.index(static_cast<int>(v), static_cast<int>(u));
    cell[i] = static_cast<std::int64_t>(k);
    top[k] = std::max(top[k], p.z());
  }
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cell[i] < 0) continue;
    const std::size_t k = static_cast<std::size_t>(cell[i]);
    const Eigen::Vector3f& p = cloud.points[i];
    if (p.z() < top[k] - top_layer_m) continue;
    const auto& c = cloud.color[i];
    g.rgb[k] += Eigen::Vector3d(lut[c[0]], lut[c[1]], lut[c[2]]);
    g.z[k] += p.z();
    ++g.count[k];
  }
  for (std::size_t k = 0; k < g.count.size(); ++k) {
    if (g.count[k] > 0) g.rgb[k] /= g.count[k], g.z[k] /= g.count[k];
  }
  return g;
}

// ---------------------------------------------------------------------------------------------
// The stages of compare_colour, in the order it runs them: both clouds binned on A's colour grid,
// each cell's colour in the space, the survey-wide offset and the robust sigma, the cells that
// changed beyond the threshold, and their connected regions.

// A survey's cells in the colour space (chromaticity in percentage points, or CIELAB), and which
// are valid: min_points coloured points and, for chromaticity, any light at all.
struct SpaceColours {
  std::vector<Eigen::Vector3d> v;
  std::vector<char> ok;
};

SpaceColours space_colours(const ColourGrid& g, const ColourChangeConfig& config) {
  SpaceColours s;
  s.v.assign(g.rgb.size(), Eigen::Vector3d::Zero());
  s.ok.assign(g.rgb.size(), 0);
  for (std::size_t k = 0; k < g.rgb.size(); ++k) {
    if (g.count[k] < config.min_points) continue;
    const Eigen::Vector3d& c = g.rgb[k];
    if (config.space == ColourSpace::Lab) {
      s.v[k] = linear_rgb_to_lab(c);
    } else {
      const double sum = c.sum();
      if (!(sum > 1e-6)) continue;
      s.v[k] = Eigen::Vector3d(100 * c.x() / sum, 100 * c.y() / sum, 0);
    }
    s.ok[k] = 1;
  }
  return s;
}

// The offset: the median of B − A per component over the cells both observed (a lighting or white
// balance shift of the whole survey); the sigma: robust, of the length of what is left (chi with
// `dims` components); the threshold k_sigma·sigma. Fills `out`; returns the offset.
Eigen::Vector3d colour_offset(const SpaceColours& a, const SpaceColours& b,
                              const std::vector<std::size_t>& both, int dims,
                              const ColourChangeConfig& config, ColourChange& out) {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  std::vector<float> values(both.size());
  for (int c = 0; c < dims; ++c) {
    for (std::size_t n = 0; n < both.size(); ++n) {
      values[n] = static_cast<float>(b.v[both[n]][c] - a.v[both[n]][c]);
    }
    offset[c] = quantile(values, 0.5);
    out.offset.push_back(offset[c]);
  }
  for (std::size_t n = 0; n < both.size(); ++n) {
    values[n] = static_cast<float>((b.v[both[n]] - offset - a.v[both[n]]).norm());
  }
  out.sigma = std::max(config.min_sigma, quantile(values, config.sigma_quantile) /
                                             chi_quantile(config.sigma_quantile, dims));
  out.threshold = config.k_sigma * out.sigma;
  return offset;
}

// The cells that changed: B's colour (offset removed) differs from every colour of A within
// tolerance_m (at least the 3×3 cells) by more than the threshold, or A's from every one of B's —
// a colour edge that the maps place less than that apart is no change. Writes |B − A − offset| of
// the cells both observed into `delta` (no data elsewhere).
std::vector<int8_t> changed_colour_cells(const ElevationMap& grid, const SpaceColours& a,
                                         const SpaceColours& b,
                                         const std::vector<std::size_t>& both,
                                         const Eigen::Vector3d& offset, double threshold,
                                         const ColourChangeConfig& config, ElevationMap& delta) {
  std::fill(delta.z.begin(), delta.z.end(), ElevationMap::kNoData);
  const int rows = grid.rows, cols = grid.cols;
  const int reach = std::max(1, static_cast<int>(std::lround(config.tolerance_m / config.cell_m)));
  std::vector<int8_t> changed(a.v.size(), 0);
  for (const std::size_t k : both) {
    delta.z[k] = static_cast<float>((b.v[k] - offset - a.v[k]).norm());
    const int row = static_cast<int>(k / static_cast<std::size_t>(cols));
    const int col = static_cast<int>(k % static_cast<std::size_t>(cols));
    double to_a = std::numeric_limits<double>::infinity(), to_b = to_a;
    for (int dr = -reach; dr <= reach; ++dr) {
      for (int dc = -reach; dc <= reach; ++dc) {
        const int rr = row + dr, cc = col + dc;
        if (rr < 0 || cc < 0 || rr >= rows || cc >= cols) continue;
        const std::size_t j = grid.index(rr, cc);
        if (a.ok[j]) to_a = std::min(to_a, (b.v[k] - offset - a.v[j]).norm());
        if (b.ok[j]) to_b = std::min(to_b, (a.v[k] + offset - b.v[j]).norm());
      }
    }
    if (to_a > threshold || to_b > threshold) changed[k] = 1;
  }
  return changed;
}

// The changed cells linked within link_m into regions; those of at least min_area_m2 reported
// with their centroid, mean and largest change and both surveys' mean colours. Fills `out`.
void colour_regions(const ElevationMap& grid, const ColourGrid& ga, const ColourGrid& gb,
                    const ElevationMap& delta, const std::vector<int8_t>& changed,
                    const ColourChangeConfig& config, ColourChange& out) {
  const int rows = grid.rows, cols = grid.cols;
  const int link = std::max(1, static_cast<int>(std::lround(config.link_m / config.cell_m)));
  const double cell_area = config.cell_m * config.cell_m;
  for (const std::vector<std::size_t>& comp : sign_components(changed, rows, cols, link)) {
    out.significant_cells += comp.size();
    ColourRegion reg;
    reg.cells = comp.size();
    reg.area_m2 = static_cast<double>(comp.size()) * cell_area;
    if (reg.area_m2 < config.min_area_m2) continue;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), rgb_a = sum, rgb_b = sum;
    double sd = 0;
    for (const std::size_t k : comp) {
      const Eigen::Vector2d c =
          grid.cell_center_xy(static_cast<int>(k / static_cast<std::size_t>(cols)),
                              static_cast<int>(k % static_cast<std::size_t>(cols)));
      sum += Eigen::Vector3d(c.x(), c.y(), 0.5 * (ga.z[k] + gb.z[k]));
      rgb_a += ga.rgb[k];
      rgb_b += gb.rgb[k];
      sd += delta.z[k];
      reg.max_delta = std::max(reg.max_delta, static_cast<double>(delta.z[k]));
    }
    const double n = static_cast<double>(comp.size());
    reg.centroid = sum / n;
    reg.mean_delta = sd / n;
    reg.colour_a = linear_to_srgb8((rgb_a / n).cast<float>());
    reg.colour_b = linear_to_srgb8((rgb_b / n).cast<float>());
    reg.cell_indices = comp;
    reg.id = static_cast<int>(out.regions.size());
    out.regions.push_back(reg);
  }
}

}  // namespace

void check_colour_cloud(const PointCloud& cloud, const std::string& name) {
  for (const char* channel : {"red", "green", "blue"}) {
    const PointProperty* p = cloud.property(channel);
    if (p == nullptr) continue;
    for (std::size_t i = 0; i < p->values.size(); ++i) {
      for (const char* ch : {"red", "green", "blue"}) {
        const PointProperty* q = cloud.property(ch);
        if (q != nullptr && i < q->values.size() && !std::isfinite(q->values[i])) {
          throw Error(name + ": vertex " + std::to_string(i) +
                      " has a colour that is not finite (" + ch + " = " +
                      std::to_string(q->values[i]) + ")");
        }
      }
    }
    throw Error(name + ": its colours are not uchar red/green/blue (as sonar3d texture writes)");
  }
  require(!cloud.empty(), name + " has no points");
  require(cloud.has_color(),
          name + " has no colour (uchar red, green, blue): colour it with sonar3d texture first");
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!cloud.points[i].allFinite()) {
      throw Error(name + ": point " + std::to_string(i) + " is not finite");
    }
  }
  const std::vector<std::uint8_t> seen = video_coloured(cloud);
  require(std::find(seen.begin(), seen.end(), 1) != seen.end(),
          name + " has no coloured point (all black or views 0: no camera saw any)");
}

// Colour change (issue 13 item 4, beyond the thesis, whose sec. 6.4 maps video onto the sonar
// cloud; here the two surveys' mapped colours are compared like the heights of compare_geometry):
// the pipeline of the stages above.
ColourChange compare_colour(const PointCloud& colour_a, const PointCloud& colour_b_in_a,
                            const ColourChangeConfig& config) {
  config.validate();
  check_colour_cloud(colour_a, "colour cloud A");
  check_colour_cloud(colour_b_in_a, "colour cloud B");
  ColourChange out;
  out.compared = true;
  out.space = config.space;
  out.cell_m = config.cell_m;
  out.k_sigma = config.k_sigma;
  out.min_area_m2 = config.min_area_m2;
  // The grid: A's extent at the colour cell, at most kMaxColourCells (~130 bytes each below:
  // a 220 × 220 m site at 10 cm).
  ElevationMapConfig gc;
  gc.cell_m = config.cell_m;
  gc.max_cells = kMaxColourCells;
  ElevationMap grid;
  try {
    grid = elevation_map_from_points(colour_a, gc);
  } catch (const Error& e) {
    throw Error(std::string("change detection: colour cell_m too small for the site (") + e.what() +
                ")");
  }
  const ColourGrid ga = bin_colours(colour_a, grid, config.top_layer_m),
                   gb = bin_colours(colour_b_in_a, grid, config.top_layer_m);
  const int dims = config.space == ColourSpace::Lab ? 3 : 2;
  const SpaceColours a = space_colours(ga, config), b = space_colours(gb, config);
  std::vector<std::size_t> both;
  for (std::size_t k = 0; k < a.v.size(); ++k) {
    if (a.ok[k] && b.ok[k]) both.push_back(k);
  }
  out.compared_cells = both.size();
  require(both.size() >= static_cast<std::size_t>(config.min_overlap_cells),
          "change detection: the colour clouds overlap on " + std::to_string(both.size()) +
              " cells of " + std::to_string(config.cell_m) + " m with at least " +
              std::to_string(config.min_points) + " coloured points in each (colour " +
              "min_overlap_cells = " + std::to_string(config.min_overlap_cells) +
              "): do they cover the same site, each in its own survey's world frame?");
  const Eigen::Vector3d offset = colour_offset(a, b, both, dims, config, out);
  ElevationMap delta = grid;
  const std::vector<int8_t> changed =
      changed_colour_cells(grid, a, b, both, offset, out.threshold, config, delta);
  colour_regions(grid, ga, gb, delta, changed, config, out);
  out.delta_map = std::move(delta);
  return out;
}

namespace {

// The height evidence behind each object change (ChangeConfig::confirm_radius_m's comment): the
// cells of its footprint(s) — the model's footprint grown by tolerance_m where it was in A and
// where it is in B, or the disc of confirm_radius_m about each origin for a model of unknown
// size — that belong to a reported region of height change, and the share both surveys
// observed. A moved pair without it is unchanged; a one-survey recognition without it, or whose
// footprint the surveys did not both observe, is uncertain.
void weigh_object_changes(const ObjectModels& models, const ChangeConfig& config, ChangeResult* r) {
  const ElevationMap& d = r->change_map;
  const double cell = d.cell_m;
  for (ObjectChange& o : r->objects) {
    const auto it = models.find(o.model);
    const ObjectModel m = it == models.end() ? ObjectModel{} : it->second;
    struct Shape {
      Eigen::Isometry3d T_model_world;
      Eigen::Vector2d origin;
      double z = 0;  // the placement's height: a footprint is a vertical prism
    };
    std::vector<Shape> shapes;
    Eigen::AlignedBox2d window;
    Eigen::AlignedBox2d grown = m.footprint;
    if (m.has_size()) {
      grown.min() -= Eigen::Vector2d::Constant(config.tolerance_m);
      grown.max() += Eigen::Vector2d::Constant(config.tolerance_m);
    }
    for (int k = 0; k < 2; ++k) {
      if (!(k == 0 ? o.in_a : o.in_b)) continue;
      const Eigen::Isometry3d& T = k == 0 ? o.T_world_model_a : o.T_world_model_b_in_a;
      shapes.push_back({T.inverse(), T.translation().head<2>(), T.translation().z()});
      if (m.has_size()) {
        for (int corner = 0; corner < 4; ++corner) {
          const Eigen::Vector2d q =
              grown.corner(static_cast<Eigen::AlignedBox2d::CornerType>(corner));
          window.extend((T * Eigen::Vector3d(q.x(), q.y(), 0)).head<2>());
        }
      } else {
        window.extend(shapes.back().origin - Eigen::Vector2d::Constant(config.confirm_radius_m));
        window.extend(shapes.back().origin + Eigen::Vector2d::Constant(config.confirm_radius_m));
      }
    }
    auto inside = [&](const Eigen::Vector2d& xy) {
      for (const Shape& sh : shapes) {
        if (m.has_size()) {
          const Eigen::Vector3d q = sh.T_model_world * Eigen::Vector3d(xy.x(), xy.y(), sh.z);
          if (grown.contains(q.head<2>())) return true;
        } else if ((xy - sh.origin).norm() <= config.confirm_radius_m) {
          return true;
        }
      }
      return false;
    };
    const int c0 = static_cast<int>(std::floor((window.min().x() - d.origin_xy.x()) / cell));
    const int c1 = static_cast<int>(std::floor((window.max().x() - d.origin_xy.x()) / cell));
    const int r0 = static_cast<int>(std::floor((d.origin_xy.y() - window.max().y()) / cell));
    const int r1 = static_cast<int>(std::floor((d.origin_xy.y() - window.min().y()) / cell));
    // A footprint of a few hundred metres (a mesh in millimetres read as metres) is sampled every
    // `stride` cells rather than cell by cell: at most ~4 M samples per object.
    const double window_cells =
        (static_cast<double>(r1) - r0 + 1) * (static_cast<double>(c1) - c0 + 1);
    const int stride = std::max(1, static_cast<int>(std::ceil(std::sqrt(window_cells / 4e6))));
    std::size_t in_shape = 0, seen = 0, changed = 0;
    for (int rr = r0; rr <= r1; rr += stride) {
      for (int cc = c0; cc <= c1; cc += stride) {
        const Eigen::Vector2d xy(d.origin_xy.x() + (cc + 0.5) * cell,
                                 d.origin_xy.y() - (rr + 0.5) * cell);
        if (!inside(xy)) continue;
        ++in_shape;
        if (rr < 0 || cc < 0 || rr >= d.rows || cc >= d.cols || !d.valid(rr, cc)) continue;
        ++seen;
        changed += r->region_cell[d.index(rr, cc)] >= 0;
      }
    }
    o.change_area_m2 = static_cast<double>(changed) * (stride * cell) * (stride * cell);
    o.observed_fraction = in_shape > 0 ? static_cast<double>(seen) / in_shape : 0.0;
    const bool observed = 2 * seen >= in_shape && in_shape > 0;
    const bool confirmed = changed > 0 && o.change_area_m2 >= config.min_area_m2;
    if (o.status == ObjectStatus::Moved && observed && !confirmed) {
      o.status = ObjectStatus::Unchanged;  // the recognition's pose moved, not the object
    }
    if ((o.status == ObjectStatus::Added || o.status == ObjectStatus::Removed) &&
        !(observed && confirmed)) {
      const char* here = o.in_a ? "A" : "B";
      const char* there = o.in_a ? "B" : "A";
      std::string why = o.other_model.empty()
                            ? std::string("recognised in ") + here + " only"
                            : std::string("recognised in ") + here + " as " + o.model + ", in " +
                                  there + " as " + o.other_model;
      why += observed ? fmt::format(
                            "; no height change within its footprint ({:.2f} m² of "
                            "change, {:.0f} % of it observed in both surveys)",
                            o.change_area_m2, 100 * o.observed_fraction)
                      : fmt::format("; its footprint was not observed by both surveys ({:.0f} %)",
                                    100 * o.observed_fraction);
      o.reason = why;
      o.status = ObjectStatus::Uncertain;
    }
  }
}

}  // namespace

ChangeResult diff_surveys(const PointCloud& a_world, const PointCloud& b_world,
                          const std::vector<SurveyPlacement>& pa,
                          const std::vector<SurveyPlacement>& pb, const ObjectModels& models,
                          const ChangeConfig& config, const PointCloud* colour_a,
                          const PointCloud* colour_b, const ChangeRegistration* registration) {
  config.validate();
  const auto t0 = std::chrono::steady_clock::now();
  require((colour_a == nullptr) == (colour_b == nullptr),
          "change detection: colour needs a coloured cloud of each survey (A and B), not one");
  if (colour_a != nullptr) {
    check_colour_cloud(*colour_a, "colour cloud A");
    check_colour_cloud(*colour_b, "colour cloud B");
  }
  ChangeResult r;
  r.registration =
      registration ? *registration : register_surveys(a_world, b_world, config.registration);
  std::vector<SurveyPlacement> pb_in_a = pb;
  for (SurveyPlacement& p : pb_in_a) p.T_world_model = r.registration.T_a_b * p.T_world_model;
  r.objects = compare_placements(pa, pb_in_a, models, config);
  compare_geometry(a_world, transformed(b_world, r.registration.T_a_b), config, &r);
  weigh_object_changes(models, config, &r);
  const ElevationMap& d = r.change_map;
  if (colour_a != nullptr) {
    PointCloud b_in_a = transformed(*colour_b, r.registration.T_a_b);
    b_in_a.color = colour_b->color;
    b_in_a.properties = colour_b->properties;  // `views` (video_coloured)
    r.colour = compare_colour(*colour_a, b_in_a, config.colour);
    // Each colour region's share of cells with a region of height change within the colour
    // tolerance: 0 = the surface itself changed (growth, paint), not the geometry.
    const ElevationMap& cm = r.colour.delta_map;
    const double reach = 0.5 * cm.cell_m + config.colour.tolerance_m;
    for (ColourRegion& g : r.colour.regions) {
      std::size_t with = 0;
      for (const std::size_t k : g.cell_indices) {
        const Eigen::Vector2d c =
            cm.cell_center_xy(static_cast<int>(k / static_cast<std::size_t>(cm.cols)),
                              static_cast<int>(k % static_cast<std::size_t>(cm.cols)));
        const int c0 = static_cast<int>(std::floor((c.x() - reach - d.origin_xy.x()) / d.cell_m));
        const int c1 = static_cast<int>(std::floor((c.x() + reach - d.origin_xy.x()) / d.cell_m));
        const int r0 = static_cast<int>(std::floor((d.origin_xy.y() - c.y() - reach) / d.cell_m));
        const int r1 = static_cast<int>(std::floor((d.origin_xy.y() - c.y() + reach) / d.cell_m));
        bool found = false;
        for (int rr = std::max(0, r0); rr <= std::min(d.rows - 1, r1) && !found; ++rr) {
          for (int cc = std::max(0, c0); cc <= std::min(d.cols - 1, c1) && !found; ++cc) {
            found = r.region_cell[d.index(rr, cc)] >= 0;
          }
        }
        with += found;
      }
      g.height_change_fraction =
          g.cell_indices.empty() ? 0 : static_cast<double>(with) / g.cell_indices.size();
    }
  }
  r.seconds = seconds_since(t0);
  return r;
}

std::string changes_json(const ChangeResult& r) {
  auto num_or_null = [](bool has, double v) { return has ? nlohmann::json(v) : nlohmann::json(); };
  nlohmann::json j;
  j["format"] = "sonar3d-changes";
  j["version"] = 1;
  j["T_a_b"] = matrix_json(r.registration.T_a_b);
  j["registration"] = {{"method", r.registration.method},
                       {"rms_m", r.registration.rms_m},
                       {"overlap_cells", r.registration.overlap_cells}};
  nlohmann::json objects = nlohmann::json::array();
  for (const ObjectChange& o : r.objects) {
    const bool both = o.in_a && o.in_b;
    objects.push_back(
        {{"id", o.id},
         {"model", o.model},
         {"status", object_status_name(o.status)},
         {"T_world_model_a", o.in_a ? matrix_json(o.T_world_model_a) : nlohmann::json()},
         {"T_world_model_b_in_a", o.in_b ? matrix_json(o.T_world_model_b_in_a) : nlohmann::json()},
         {"shift_m", num_or_null(both, o.shift_m)},
         {"turn_deg", num_or_null(both, o.turn_deg)},
         {"match_radius_m", o.match_radius_m},
         {"change_area_m2", num_or_null(std::isfinite(o.change_area_m2), o.change_area_m2)},
         {"observed_fraction",
          num_or_null(std::isfinite(o.observed_fraction), o.observed_fraction)},
         {"confidence_a", num_or_null(std::isfinite(o.confidence_a), o.confidence_a)},
         {"confidence_b", num_or_null(std::isfinite(o.confidence_b), o.confidence_b)},
         {"other_model", o.other_model.empty() ? nlohmann::json() : nlohmann::json(o.other_model)},
         {"reason", o.reason.empty() ? nlohmann::json() : nlohmann::json(o.reason)}});
  }
  j["objects"] = objects;
  nlohmann::json regions = nlohmann::json::array();
  for (const ChangeRegion& g : r.regions) {
    regions.push_back({{"id", g.id},
                       {"centroid", {g.centroid.x(), g.centroid.y(), g.centroid.z()}},
                       {"area_m2", g.area_m2},
                       {"max_abs_change_m", g.max_abs_change_m},
                       {"mean_change_m", g.mean_change_m},
                       {"kind", g.raised ? "raised" : "lowered"}});
  }
  j["regions"] = regions;
  const ChangeThresholds& t = r.thresholds;
  j["thresholds"] = {{"cell_m", t.cell_m},
                     {"median_change_m", t.median_m},
                     {"sigma_m", t.sigma_m},
                     {"k_sigma", t.k_sigma},
                     {"change_m", t.change_m},
                     {"min_area_m2", t.min_area_m2},
                     {"significant_cells", r.significant_cells},
                     {"shift_tol_m", t.shift_tol_m},
                     {"turn_tol_deg", t.turn_tol_deg},
                     {"match_radius_m", t.match_radius_m},
                     {"match_radius_factor", t.match_radius_factor},
                     {"min_match_radius_m", t.min_match_radius_m},
                     {"yaw_deg", r.registration.yaw_deg},
                     {"registration_seconds", r.registration.seconds}};
  j["colour"] = nullptr;
  if (r.colour.compared) {
    const ColourChange& c = r.colour;
    auto rgb = [](const std::array<std::uint8_t, 3>& v) {
      return nlohmann::json{v[0], v[1], v[2]};
    };
    nlohmann::json cregions = nlohmann::json::array();
    for (const ColourRegion& g : c.regions) {
      cregions.push_back({{"id", g.id},
                          {"centroid", {g.centroid.x(), g.centroid.y(), g.centroid.z()}},
                          {"area_m2", g.area_m2},
                          {"cells", g.cells},
                          {"max_delta", g.max_delta},
                          {"mean_delta", g.mean_delta},
                          {"height_change_fraction", g.height_change_fraction},
                          {"colour_a", rgb(g.colour_a)},
                          {"colour_b", rgb(g.colour_b)}});
    }
    j["colour"] = {{"space", colour_space_name(c.space)},
                   {"cell_m", c.cell_m},
                   {"offset", c.offset},
                   {"sigma", c.sigma},
                   {"k_sigma", c.k_sigma},
                   {"threshold", c.threshold},
                   {"min_area_m2", c.min_area_m2},
                   {"compared_cells", c.compared_cells},
                   {"significant_cells", c.significant_cells},
                   {"regions", cregions}};
  }
  j["seconds"] = r.seconds;
  return j.dump(1) + "\n";
}

PointCloud change_points(const ChangeResult& r) {
  PointCloud cloud;
  PointProperty change{"change_m", {}};
  const ElevationMap& d = r.change_map;
  for (int row = 0; row < d.rows; ++row) {
    for (int col = 0; col < d.cols; ++col) {
      if (!d.valid(row, col)) continue;
      const Eigen::Vector2d c = d.cell_center_xy(row, col);
      cloud.points.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                r.height_b.at(row, col));
      change.values.push_back(d.at(row, col));
    }
  }
  cloud.properties.push_back(std::move(change));
  return cloud;
}

void write_change_directory(const std::string& dir, const ChangeResult& result) {
  require(!fs::exists(dir),
          "change detection: '" + dir + "' already exists: choose a new output directory");
  require(!result.change_map.empty(), "change detection: no change map to write");
  AtomicPath out(dir);
  fs::create_directories(out.temp());
  write_elevation_geotiff((out.temp() / "change_map.tif").string(), result.change_map);
  write_ply((out.temp() / "change_points.ply").string(), change_points(result));
  if (result.colour.compared) {
    write_elevation_geotiff((out.temp() / "colour_change_map.tif").string(),
                            result.colour.delta_map);
  }
  write_text_file((out.temp() / "changes.json").string(), changes_json(result));
  out.commit();
}

PointCloud read_survey_cloud(const std::string& path) {
  if (fs::is_regular_file(path)) return read_ply(path);
  if (fs::is_directory(path) && fs::is_regular_file(fs::path(path) / "merged.ply")) {
    return read_ply((fs::path(path) / "merged.ply").string());
  }
  throw Error("survey '" + path +
              "': neither a point cloud (.ply) nor a map directory of sonar3d map (merged.ply)");
}

ObjectModels catalogue_object_models(const Catalogue& catalogue,
                                     const std::vector<std::string>& placed) {
  ObjectModels out;
  for (const CatalogueModel& m : catalogue.models) {
    ObjectModel& om = out[m.name];
    om.symmetry = m.symmetry;
    if (std::find(placed.begin(), placed.end(), m.name) == placed.end()) continue;
    const TriangleMesh mesh = load_catalogue_mesh(catalogue, m);
    const Eigen::AlignedBox3f b = mesh.bounding_box();
    if (!b.isEmpty()) {
      om.footprint =
          Eigen::AlignedBox2d(b.min().head<2>().cast<double>(), b.max().head<2>().cast<double>());
    }
  }
  return out;
}

std::vector<SurveyPlacement> recognize_placements(const PointCloud& cloud_world,
                                                  const Catalogue& catalogue,
                                                  const RecognitionConfig& config) {
  std::vector<ModelTemplate> models;
  for (const CatalogueModel& m : catalogue.models) {
    models.push_back(make_catalogue_template(catalogue, m, config.sampling));
  }
  const RecognitionResult r = recognize_2d(cloud_world, models, config);
  std::vector<SurveyPlacement> out;
  for (const Placement& p : r.placements) {
    SurveyPlacement rec;
    rec.model = p.model;
    rec.T_world_model = p.T_world_model;
    rec.scale = p.scale;
    rec.score_m = p.score_m;
    rec.residual_median_m = p.residual.median_m;
    rec.residual_mean_m = p.residual.mean_m;
    rec.method = "2d";
    rec.confidence = p.confidence;
    out.push_back(rec);
  }
  return out;
}

}  // namespace sonar3d
