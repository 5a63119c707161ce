// The 2D recognition method (thesis sec. 6.3.2): scan, 4D search (eq. 6.9), trimmed ICP,
// acceptance, area removal.
#include "sonar3d/recog/recognition.hpp"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>

#include "recog_common.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/point_index.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/mapping/swath_registration.hpp"

namespace sonar3d {

namespace {
using namespace recog_internal;

// The block of `map` covering the square of half-width `half_m` about `center` (corners on the
// map's grid), removed cells as no data.
ElevationMap crop(const ElevationMap& map, const std::vector<uint8_t>& removed,
                  const Eigen::Vector2d& center, double half_m) {
  const double c = map.cell_m;
  const int c0 =
      std::max(0, static_cast<int>(std::floor((center.x() - half_m - map.origin_xy.x()) / c)));
  const int c1 = std::min(
      map.cols, static_cast<int>(std::ceil((center.x() + half_m - map.origin_xy.x()) / c)));
  const int r0 =
      std::max(0, static_cast<int>(std::floor((map.origin_xy.y() - center.y() - half_m) / c)));
  const int r1 = std::min(
      map.rows, static_cast<int>(std::ceil((map.origin_xy.y() - center.y() + half_m) / c)));
  ElevationMap out;
  out.cell_m = c;
  if (c1 <= c0 || r1 <= r0) return out;
  out.rows = r1 - r0;
  out.cols = c1 - c0;
  out.origin_xy = {map.origin_xy.x() + c0 * c, map.origin_xy.y() - r0 * c};
  out.z.resize(static_cast<std::size_t>(out.rows) * out.cols);
  for (int r = 0; r < out.rows; ++r) {
    for (int col = 0; col < out.cols; ++col) {
      const std::size_t i = map.index(r + r0, col + c0);
      out.at(r, col) = (!removed.empty() && removed[i]) ? ElevationMap::kNoData : map.z[i];
    }
  }
  return out;
}

struct Fit {
  double rms = std::numeric_limits<double>::infinity();
  std::size_t overlap = 0;
};

// Eq. 6.9 at one placement: ||Z_model + ζ − Z_map|| over the cells defined in both, per cell.
// The model map's cells moved by (dx, dy) land on the nearest scene cell.
Fit fit_at(const ElevationMap& scene, const ElevationMap& model_map, const Eigen::Vector3d& t) {
  Fit f;
  double sum2 = 0;
  std::size_t n = 0;
  for (int r = 0; r < model_map.rows; ++r) {
    for (int c = 0; c < model_map.cols; ++c) {
      const float zm = model_map.at(r, c);
      if (zm != zm) continue;
      const Eigen::Vector2d p = model_map.cell_center_xy(r, c) + t.head<2>();
      const int sc = static_cast<int>(std::floor((p.x() - scene.origin_xy.x()) / scene.cell_m));
      const int sr = static_cast<int>(std::floor((scene.origin_xy.y() - p.y()) / scene.cell_m));
      if (sr < 0 || sc < 0 || sr >= scene.rows || sc >= scene.cols) continue;
      const float zs = scene.at(sr, sc);
      if (zs != zs) continue;
      const double d = zm + t.z() - zs;
      sum2 += d * d;
      ++n;
    }
  }
  if (n > 0) f.rms = std::sqrt(sum2 / static_cast<double>(n));
  f.overlap = n;
  return f;
}

struct YawTrial {
  double yaw = 0;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Fit fit;
  // What ranks the yaws (lowest wins): the thesis' ||·||_2 per cell (fit.rms), or the bounded
  // search's truncated score.
  double rank = std::numeric_limits<double>::infinity();
};

// A model cell of the 4D search: its offset on the reference grid at zero shift and its height.
struct ShiftCell {
  int row, col;
  float z;
  bool structure = false;  // stands above the model's base (its relief), see below
};

float median_of(std::vector<float>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Eq. 6.9's exhaustive shift search (every cell shift within ±S cells) with the height ζ of
// eq. 6.1 taken from the model's structure and bounded by the seabed it stands on, and the
// seabed covering what lies below it (beyond the thesis). Per shift:
//   - the seabed's height s: base + the median of scene − base over the ground ring's cells;
//   - ζ: of eq. 6.1's signed median of scene − model over the compared cells, the same median
//     and upper quartile over the cells of the model's structure (standing above its base; when
//     at least a quarter of them hold data) and the model standing on the seabed, each held
//     within [s − base − below_m, s − base + above_m] (a structure stands on the seabed, at
//     most partly buried), the one whose score below is lowest;
//   - each compared cell's expected height max(model + ζ, s) (a partly buried structure shows
//     the sediment around and between its parts, not its base), and the shift's score the mean
//     of |scene − expected| truncated at `truncate_m` (ties: the plain mean). Eq. 6.2's median
//     ignores any minority of cells, and the cells that tell a structure from seabed (a frame's
//     rails, a buoy's top, what stands above the sediment of a buried block) are often the
//     minority: a model sunk to its bound or set beside the structure matches the seabed on
//     the rest. The truncated mean (a robust M-estimate) counts every cell that disagrees, and
//     no more than `truncate_m` for one.
// The thesis' median over all cells follows whichever heights are the majority: where the
// model's flat top, an open frame's rails or its ring of seabed outnumber the rest, it aligns
// them with the seabed anywhere (the frame or block then lies its own height deep: measured, a
// 1.6 m lattice frame 1.55 m and a cinder block 0.4 m too deep), and a thin upright buoy is
// seated on its ring although it is buried 20 cm. Shifts whose ground ring holds fewer than a
// quarter of its cells keep the thesis' ζ and no seabed. The winner's RMS (eq. 6.9's norm per
// cell) is over the same expected heights; the yaws are ranked by the score.
struct BoundedShift {
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  // (dx, dy, ζ), m
  Fit fit;
  double score = 0;  // the truncated mean below, m
};
std::optional<BoundedShift> bounded_shift_search(const ElevationMap& ref,
                                                 const std::vector<ShiftCell>& cells,
                                                 const std::vector<ShiftCell>& ground, float base,
                                                 int S, double below_m, double above_m,
                                                 double truncate_m, std::size_t min_overlap,
                                                 int stride, int seeds) {
  const int W = 2 * S + 1;
  struct Score {
    float score = std::numeric_limits<float>::infinity(), mean = 0, zeta = 0;
    float seabed = -std::numeric_limits<float>::infinity();
  };
  std::vector<Score> scores(static_cast<std::size_t>(W) * W);
  const std::size_t min_ground = std::max<std::size_t>(4, ground.size() / 4);
  std::size_t n_structure = 0;
  for (const ShiftCell& cell : cells) n_structure += cell.structure;
  const std::size_t min_structure = std::max<std::size_t>(1, n_structure / 4);
  // The compared cells' scene and model heights at shift (i, j).
  auto overlap = [&](int i, int j, std::vector<std::pair<float, float>>& sm) {
    sm.clear();
    for (const ShiftCell& cell : cells) {
      const int r = cell.row - j, c = cell.col + i;
      if (r < 0 || c < 0 || r >= ref.rows || c >= ref.cols) continue;
      const float zs = ref.at(r, c);
      if (zs == zs) sm.emplace_back(zs, cell.z);
    }
  };
  // Scores the shifts listed in `todo` (indices k = (j + S)·W + i + S); each task keeps its
  // buffers across the shifts it scores (one allocation per chunk).
  std::vector<uint8_t> scored(static_cast<std::size_t>(W) * W, 0);
  auto score_all = [&](const std::vector<int>& todo) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, todo.size()),
        [&](const tbb::blocked_range<std::size_t>& range) {
          std::vector<float> d, g, ds;
          std::vector<std::pair<float, float>> sm;
          d.reserve(cells.size());
          sm.reserve(cells.size());
          g.reserve(ground.size());
          for (std::size_t t = range.begin(); t < range.end(); ++t) {
            const int k = todo[t];
            const int i = k % W - S, j = k / W - S;
            sm.clear();
            d.clear();
            ds.clear();
            for (const ShiftCell& cell : cells) {
              const int r = cell.row - j, c = cell.col + i;
              if (r < 0 || c < 0 || r >= ref.rows || c >= ref.cols) continue;
              const float zs = ref.at(r, c);
              if (zs != zs) continue;
              sm.emplace_back(zs, cell.z);
              d.push_back(zs - cell.z);
              if (cell.structure) ds.push_back(zs - cell.z);
            }
            if (d.size() < min_overlap || d.empty()) continue;
            Score& s = scores[static_cast<std::size_t>(k)];
            g.clear();
            for (const ShiftCell& cell : ground) {
              const int r = cell.row - j, c = cell.col + i;
              if (r < 0 || c < 0 || r >= ref.rows || c >= ref.cols) continue;
              const float zs = ref.at(r, c);
              if (zs == zs) g.push_back(zs - cell.z);
            }
            // Height candidates: eq. 6.1's median over every compared cell; with a seabed, also the
            // median and the upper quartile over the structure (a thin part that the scene shows
            // narrower than the model: its top is the upper cells) and the model standing on the
            // seabed, each held within the bounds. The one scoring best is kept.
            std::array<double, 4> zetas;
            std::size_t nz = 0;
            zetas[nz++] = median_of(d);  // eq. 6.1
            if (g.size() >= min_ground) {
              const double zg = median_of(g);
              s.seabed = static_cast<float>(base + zg);
              zetas[nz++] = zg;
              if (ds.size() >= min_structure) {
                zetas[nz++] = median_of(ds);
                const auto q = ds.begin() + static_cast<std::ptrdiff_t>(3 * (ds.size() - 1) / 4);
                std::nth_element(ds.begin(), q, ds.end());
                zetas[nz++] = *q;
              }
              for (std::size_t z = 0; z < nz; ++z) {
                zetas[z] = std::clamp(zetas[z], zg - below_m, zg + above_m);
              }
            }
            const double n = static_cast<double>(std::max<std::size_t>(1, sm.size()));
            for (std::size_t z = 0; z < nz; ++z) {
              const float zeta = static_cast<float>(zetas[z]);
              double sum = 0, sum_t = 0;
              for (const auto& [zs, zm] : sm) {
                const double e = std::abs(zs - std::max(zm + zeta, s.seabed));
                sum += e;
                sum_t += std::min(e, truncate_m);
              }
              const float score = static_cast<float>(sum_t / n), mean = static_cast<float>(sum / n);
              if (z == 0 || score < s.score - 1e-6f ||
                  (std::abs(score - s.score) <= 1e-6f && mean < s.mean)) {
                s.zeta = zeta;
                s.mean = mean;
                s.score = score;
              }
            }
          }
        });
    for (const int k : todo) scored[static_cast<std::size_t>(k)] = 1;
  };
  auto better_k = [&](int a, int b) {  // shift a scores better than b (ties: the plain mean)
    const Score &sa = scores[static_cast<std::size_t>(a)],
                &sb = scores[static_cast<std::size_t>(b)];
    if (!std::isfinite(sa.score)) return false;
    if (!std::isfinite(sb.score)) return true;
    return std::abs(sa.score - sb.score) > 1e-6f ? sa.score < sb.score : sa.mean < sb.mean;
  };
  std::vector<int> todo;
  if (stride <= 1) {
    // Every cell shift (eq. 6.9's exhaustive search).
    for (int k = 0; k < W * W; ++k) todo.push_back(k);
    score_all(todo);
  } else {
    // Coarse to fine: the shifts on a lattice of `stride` cells (and the window's edges), then
    // every shift about the `seeds` best of them (the lattice cell around each), then a descent
    // over the 8 neighbours of the best until none scores better. The score varies over a
    // structure's width (a cell shift moves every compared cell by one cell), so the true shift's
    // basin holds a lattice shift; docs/recognition.md gives the no-loss check on the benchmark.
    auto on_lattice = [&](int i) { return i % stride == 0 || i == -S || i == S; };
    for (int j = -S; j <= S; ++j) {
      for (int i = -S; i <= S; ++i) {
        if (on_lattice(i) && on_lattice(j)) todo.push_back((j + S) * W + i + S);
      }
    }
    score_all(todo);
    std::vector<int> order = todo;
    const std::size_t n_seeds =
        std::min<std::size_t>(order.size(), static_cast<std::size_t>(seeds));
    std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n_seeds),
                      order.end(),
                      [&](int a, int b) { return better_k(a, b) || (!better_k(b, a) && a < b); });
    auto around = [&](int k, int reach, std::vector<int>& list) {
      const int i0 = k % W - S, j0 = k / W - S;
      for (int dj = -reach; dj <= reach; ++dj) {
        for (int di = -reach; di <= reach; ++di) {
          const int i = i0 + di, j = j0 + dj;
          if (i < -S || j < -S || i > S || j > S) continue;
          const int kk = (j + S) * W + i + S;
          if (!scored[static_cast<std::size_t>(kk)]) {
            scored[static_cast<std::size_t>(kk)] = 2;  // queued
            list.push_back(kk);
          }
        }
      }
    };
    todo.clear();
    for (std::size_t q = 0; q < n_seeds; ++q) {
      if (std::isfinite(scores[static_cast<std::size_t>(order[q])].score))
        around(order[q], stride - 1, todo);
    }
    score_all(todo);
    for (;;) {
      int cur = -1;
      for (int k = 0; k < W * W; ++k) {
        if (scored[static_cast<std::size_t>(k)] && (cur < 0 || better_k(k, cur))) cur = k;
      }
      if (cur < 0) break;
      todo.clear();
      around(cur, 1, todo);
      if (todo.empty()) break;
      score_all(todo);
    }
  }
  int best = -1;
  for (int k = 0; k < W * W; ++k) {
    const Score& s = scores[static_cast<std::size_t>(k)];
    if (!std::isfinite(s.score)) continue;
    if (best < 0) {
      best = k;
      continue;
    }
    const Score& b = scores[static_cast<std::size_t>(best)];
    if (std::abs(s.score - b.score) > 1e-6f ? s.score < b.score : s.mean < b.mean) best = k;
  }
  if (best < 0) return std::nullopt;
  const Score& sb = scores[static_cast<std::size_t>(best)];
  BoundedShift out;
  const int bi = best % W - S, bj = best / W - S;
  out.t = Eigen::Vector3d(bi * ref.cell_m, bj * ref.cell_m, sb.zeta);
  std::vector<std::pair<float, float>> sm;
  overlap(bi, bj, sm);
  double sum2 = 0;
  for (const auto& [zs, zm] : sm) {
    const double e = zs - std::max(zm + sb.zeta, sb.seabed);
    sum2 += e * e;
  }
  out.fit.overlap = sm.size();
  out.score = sb.score;
  out.fit.rms = std::sqrt(sum2 / static_cast<double>(std::max<std::size_t>(1, sm.size())));
  return out;
}

// One pass of eq. 6.9 over `yaws` at the scene's cell size. `max_buried_fraction`: the seabed
// bound of ζ (Search4dConfig::seabed_ring_m).
YawTrial best_yaw(const ModelTemplate& model, const ElevationMap& scene,
                  const Eigen::Vector2d& center, const std::vector<double>& yaws, double search_m,
                  const Search4dConfig& config, bool subcell, double max_buried_fraction) {
  const double c = scene.cell_m;
  TopViewConfig tv;
  tv.cell_m = c;
  // A ring of `background_ring_cells` cells of the base height around the footprint: enough to
  // keep a flat top off flat seabed, few enough that the structure's cells stay the majority
  // (eq. 6.2's median would otherwise follow the seabed).
  const double ring = config.background_ring_cells * c;
  const bool bounded = config.seabed_ring_m > 0;
  // The seabed ring lies beyond the compared ring: the same extent for both renders.
  const double ground_ring = bounded ? std::max(config.seabed_ring_m, c) : 0.0;
  tv.background_radius_m = model.radius_m + ring + ground_ring;
  tv.background_ring_m = ring;
  tv.grid_anchor_xy = scene.origin_xy;
  // The model is centred on a cell corner of the scene grid.
  const Eigen::Vector2d snapped(
      scene.origin_xy.x() + std::round((center.x() - scene.origin_xy.x()) / c) * c,
      scene.origin_xy.y() + std::round((center.y() - scene.origin_xy.y()) / c) * c);
  const ElevationMap ref = crop(scene, {}, snapped, tv.background_radius_m + search_m + 2 * c);
  std::vector<YawTrial> trials(yaws.size());
  tbb::parallel_for(std::size_t(0), yaws.size(), [&](std::size_t k) {
    trials[k].yaw = yaws[k];
    if (ref.empty()) return;
    const ElevationMap mm = render_top_view(model, yaws[k], snapped, tv);
    const std::size_t cells = mm.num_valid();
    if (bounded) {
      TopViewConfig tg = tv;
      tg.background_ring_m = ring + ground_ring;
      const ElevationMap wide = render_top_view(model, yaws[k], snapped, tg);
      const int dc0 = static_cast<int>(std::lround((mm.origin_xy.x() - ref.origin_xy.x()) / c));
      const int dr0 = static_cast<int>(std::lround((ref.origin_xy.y() - mm.origin_xy.y()) / c));
      float base = std::numeric_limits<float>::infinity();
      for (const float z : mm.z) {
        if (z == z) base = std::min(base, z);
      }
      const float structure_above = base + static_cast<float>(config.seabed_slack_m);
      std::vector<ShiftCell> compared, ground;
      for (int r = 0; r < mm.rows; ++r) {
        for (int col = 0; col < mm.cols; ++col) {
          if (mm.valid(r, col)) {
            compared.push_back(
                {r + dr0, col + dc0, mm.at(r, col), mm.at(r, col) > structure_above});
          } else if (wide.valid(r, col)) {
            ground.push_back({r + dr0, col + dc0, wide.at(r, col)});
          }
        }
      }
      // The seabed's median needs no more than a few hundred cells spread around the model (the
      // ring holds thousands on the fine map): every k-th, in raster order.
      constexpr std::size_t kGroundCells = 256;
      if (ground.size() > kGroundCells) {
        const std::size_t step = (ground.size() + kGroundCells - 1) / kGroundCells;
        std::size_t kept = 0;
        for (std::size_t i = 0; i < ground.size(); i += step) ground[kept++] = ground[i];
        ground.resize(kept);
      }
      const int S = static_cast<int>(std::floor(search_m / c + 1e-9));
      const double h = model.height();
      const std::optional<BoundedShift> t = bounded_shift_search(
          ref, compared, ground, base, S, max_buried_fraction * h + config.seabed_slack_m,
          config.seabed_slack_m, config.truncate_m,
          std::max<std::size_t>(1, static_cast<std::size_t>(0.5 * static_cast<double>(cells))),
          config.shift_stride, config.shift_seeds);
      if (t) {
        trials[k].t = t->t;
        trials[k].fit = t->fit;
        trials[k].rank = t->score;
      }
      return;
    }
    SwathRegistrationConfig rc;
    rc.search_m = search_m;
    rc.min_overlap_cells = std::max<int>(1, static_cast<int>(0.5 * static_cast<double>(cells)));
    rc.subcell = subcell;
    rc.num_threads = 0;
    try {
      // Eq. 6.1 (ζ) and the exhaustive shift search, reused from swath registration.
      const SwathTie tie = register_elevation_maps(ref, mm, rc);
      trials[k].t = tie.t;
      trials[k].fit = fit_at(ref, mm, tie.t);
      trials[k].rank = trials[k].fit.rms;
    } catch (const Error&) {
      // Too little of the scene under the model at every shift: this yaw cannot be judged.
    }
  });
  YawTrial best;
  for (auto& t : trials) {
    if (t.rank < best.rank) best = t;
  }
  best.t.head<2>() += snapped - center;  // relative to `center`
  return best;
}

}  // namespace

std::vector<double> yaw_range(Symmetry s, double step) {
  const double span = s == Symmetry::None ? 2 * M_PI : s == Symmetry::Half ? M_PI : 0;
  std::vector<double> out{0};
  for (double y = step; y < span - 1e-9; y += step) out.push_back(y);
  return out;
}

double tilt_deg(const Eigen::Isometry3d& T) {
  return std::acos(std::clamp(T.linear()(2, 2), -1.0, 1.0)) / kDeg;
}

std::unique_ptr<tbb::global_control> check_recognition_inputs(
    const PointCloud& scene, const std::vector<ModelTemplate>& models, int num_threads) {
  require(!models.empty(), "recognition: the catalogue is empty: give at least one CAD model");
  require(!scene.empty(), "recognition: the scene cloud is empty");
  if (num_threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(num_threads));
}

std::vector<const ModelTemplate*> by_decreasing_size(const std::vector<ModelTemplate>& models) {
  std::vector<const ModelTemplate*> order;
  for (const auto& m : models) order.push_back(&m);
  std::stable_sort(order.begin(), order.end(), [](const ModelTemplate* a, const ModelTemplate* b) {
    return a->radius_m > b->radius_m;
  });
  return order;
}

void Search4dConfig::validate() const {
  params::check(*this, "4D search");
  require(refine_yaw_step_deg <= yaw_step_deg,
          "4D search refine_yaw_step_deg must lie in (0, yaw_step_deg]");
}

double model_relief_m(const ModelTemplate& model, const RecognitionConfig& config, double noise_m) {
  const double relief = config.verification.relief_m;
  const double low = config.low_relief_fraction * model.height();
  if (config.low_relief_fraction <= 0 || low >= relief) return relief;
  return std::min(relief, std::max({low, config.min_relief_m, 3 * noise_m}));
}

double map_height_noise(const ElevationMap& map) {
  std::vector<float> d;
  d.reserve(map.z.size());
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c + 1 < map.cols; ++c) {
      const float a = map.at(r, c), b = map.at(r, c + 1);
      if (a == a && b == b) d.push_back(std::abs(a - b));
    }
  }
  if (d.empty()) return 0.0;
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return 1.4826 * *mid / std::sqrt(2.0);
}

void RecognitionConfig::validate() const {
  params::check(*this, "recognition");
  require(recog_cell_m >= map_cell_m, "recog_cell_m must be >= map_cell_m");
  scan.validate();
  search.validate();
  scale.validate();
}

Search4dResult search_4d(const ModelTemplate& model, const ElevationMap& scene,
                         const ElevationMap& fine, const Eigen::Vector2d& center_xy,
                         double period_m, const Search4dConfig& config,
                         double max_buried_fraction) {
  config.validate();
  require(!scene.empty(), "4D search: the scene map is empty");
  const auto start = Clock::now();
  const double step = config.yaw_step_deg * kDeg;
  const std::vector<double> yaws = yaw_range(model.symmetry, step);
  const double search = config.search_m > 0 ? config.search_m
                                            : std::sqrt(0.5) * period_m + 2 * scene.cell_m +
                                                  config.search_radius_fraction * model.radius_m;
  Search4dResult out;
  // A model whose structure covers fewer than min_coarse_cells cells of the scan's cell has no
  // shape at that cell (a 13 cm buoy on 8 cm cells is 2 × 2 cells or 3 × 3, by where it falls on
  // the grid, and its ring of seabed ties every such shift with the buoy sunk beside it): it is
  // searched on the fine map over the whole window (its cost is small: few cells).
  const ElevationMap* first = &scene;
  if (config.seabed_ring_m > 0 && !fine.empty() && fine.cell_m < scene.cell_m) {
    TopViewConfig tv;
    tv.cell_m = scene.cell_m;
    const ElevationMap view = render_top_view(model, 0.0, Eigen::Vector2d::Zero(), tv);
    const float base = static_cast<float>(model.base_z);  // the top view's heights: model frame
    int structure = 0;
    for (const float z : view.z) {
      structure += z == z && z > base + static_cast<float>(config.seabed_slack_m);
    }
    if (structure < config.min_coarse_cells) first = &fine;
  }
  YawTrial best =
      best_yaw(model, *first, center_xy, yaws, search, config, false, max_buried_fraction);
  out.yaws_tried = static_cast<int>(yaws.size());
  if (!std::isfinite(best.fit.rms)) {
    out.seconds = since(start);
    return out;
  }
  if (config.refine_cell_m > 0 && !fine.empty() && fine.cell_m < scene.cell_m) {
    // The second pass (on the fine map, whichever the first).
    std::vector<double> fine_yaws;
    const double fs = config.refine_yaw_step_deg * kDeg;
    const double half = model.symmetry == Symmetry::Full ? 0 : step;
    for (double d = -half; d <= half + 1e-9; d += fs) fine_yaws.push_back(best.yaw + d);
    const Eigen::Vector2d c2 = center_xy + best.t.head<2>();
    YawTrial b2 =
        best_yaw(model, fine, c2, fine_yaws, 1.5 * scene.cell_m, config, true, max_buried_fraction);
    out.yaws_tried += static_cast<int>(fine_yaws.size());
    if (std::isfinite(b2.fit.rms)) {
      b2.t.head<2>() += c2 - center_xy;
      best = b2;
    }
  }
  out.found = true;
  out.yaw_rad = std::remainder(best.yaw, 2 * M_PI);
  out.T_world_model = top_view_pose(model, best.yaw, center_xy, best.t);
  out.rms_m = best.fit.rms;
  out.overlap_cells = best.fit.overlap;
  out.seconds = since(start);
  return out;
}

Residual structure_residual(const std::vector<Eigen::Vector3f>& scene_world,
                            const ModelTemplate& model, const Eigen::Isometry3d& T_world_model,
                            double margin_m, double above_base_m) {
  const Eigen::AlignedBox3f box = model.mesh.bounding_box();
  const Eigen::Isometry3f T_model_world = T_world_model.inverse().cast<float>();
  const float m = static_cast<float>(margin_m);
  std::vector<Eigen::Vector3f> over;
  for (const auto& p : scene_world) {
    const Eigen::Vector3f q = T_model_world * p;
    if (q.x() < box.min().x() - m || q.x() > box.max().x() + m || q.y() < box.min().y() - m ||
        q.y() > box.max().y() + m || q.z() < box.min().z() + above_base_m ||
        q.z() > box.max().z() + m) {
      continue;
    }
    over.push_back(p);
  }
  Residual r;
  r.points = over.size();
  if (over.empty()) {
    r.median_m = r.mean_m = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  TriangleMesh placed = model.mesh;
  placed.transform(T_world_model);
  const MeshDistance dist(placed);
  std::vector<double> d = dist.distances(over);
  r.mean_m = std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  r.median_m = *mid;
  return r;
}

namespace {

// The scene's points by the cells of the coarse map they fall in, to fetch the points near a
// placement: the library's index (core/point_index.hpp) finds those over a block of cells; they
// come back cell by cell (row-major, as the map's cells) and in the cloud's order within a cell.
struct ScenePoints {
  ElevationMap grid;                    // geometry only
  std::unique_ptr<PointIndex3f> index;  // over the cloud's points, read in place
  void build(const PointCloud& cloud, const ElevationMap& g) {
    grid = g;
    grid.z.clear();
    index = std::make_unique<PointIndex3f>(PointIndex3f::borrow(cloud.points));
  }
  // The points of the cells overlapping the square of half-width h about (x, y), skipping
  // removed cells.
  std::vector<Eigen::Vector3f> near(const PointCloud& cloud, const Eigen::Vector2d& c, double h,
                                    const std::vector<uint8_t>& removed) const {
    std::vector<Eigen::Vector3f> out;
    const int c0 =
        std::max(0, static_cast<int>(std::floor((c.x() - h - grid.origin_xy.x()) / grid.cell_m)));
    const int c1 =
        std::min(grid.cols - 1,
                 static_cast<int>(std::floor((c.x() + h - grid.origin_xy.x()) / grid.cell_m)));
    const int r0 =
        std::max(0, static_cast<int>(std::floor((grid.origin_xy.y() - c.y() - h) / grid.cell_m)));
    const int r1 =
        std::min(grid.rows - 1,
                 static_cast<int>(std::floor((grid.origin_xy.y() - c.y() + h) / grid.cell_m)));
    if (r0 > r1 || c0 > c1) return out;
    // The block's extent grown by a cell (the box is float); the cell of each point decides.
    const float inf = std::numeric_limits<float>::infinity();
    const Eigen::AlignedBox3f box(
        Eigen::Vector3f(static_cast<float>(grid.origin_xy.x() + (c0 - 1) * grid.cell_m),
                        static_cast<float>(grid.origin_xy.y() - (r1 + 2) * grid.cell_m), -inf),
        Eigen::Vector3f(static_cast<float>(grid.origin_xy.x() + (c1 + 2) * grid.cell_m),
                        static_cast<float>(grid.origin_xy.y() - (r0 - 1) * grid.cell_m), inf));
    std::vector<std::pair<std::size_t, std::size_t>> found;  // (cell, point)
    for (const std::size_t i : index->in_box(box)) {
      const auto& p = cloud.points[i];
      const int col = static_cast<int>(std::floor((p.x() - grid.origin_xy.x()) / grid.cell_m));
      const int r = static_cast<int>(std::floor((grid.origin_xy.y() - p.y()) / grid.cell_m));
      if (r < r0 || r > r1 || col < c0 || col > c1) continue;
      const std::size_t k = grid.index(r, col);
      if (!removed.empty() && removed[k]) continue;
      found.emplace_back(k, i);
    }
    std::sort(found.begin(), found.end());
    out.reserve(found.size());
    for (const auto& [k, i] : found) out.push_back(cloud.points[i]);
    return out;
  }
};

// A connected blob of relief on the recognition map (relief proposals).
struct ReliefBlob {
  int row = 0, col = 0;  // the cell nearest the blob's centroid
  Eigen::Vector2d center_xy{0, 0};
  double area_m2 = 0, relief_m = 0;  // its area and its highest relief above the seabed
};

// Blobs of cells standing more than relief_m above the local seabed, the seabed being the
// grey-scale opening (erosion then dilation, a square of window_m) of the map: anything narrower
// than the window is lifted off it, slopes are followed within window_m · slope / 2. Cells
// without data take no part.
// `relief` (optional): every cell's height above that seabed (0 without data); `labels`
// (optional): each cell's blob, 1 + its index in the result, 0 for none.
std::vector<ReliefBlob> relief_blobs(const ElevationMap& map, double window_m, double relief_m,
                                     cv::Mat* relief = nullptr, cv::Mat* labels_out = nullptr) {
  std::vector<ReliefBlob> out;
  if (map.empty()) return out;
  const float big = std::numeric_limits<float>::max();
  cv::Mat z(map.rows, map.cols, CV_32F);
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const float v = map.at(r, c);
      z.at<float>(r, c) = v == v ? v : big;  // no data: never the minimum
    }
  }
  const int k = std::max(3, 2 * static_cast<int>(std::lround(0.5 * window_m / map.cell_m)) + 1);
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
  cv::Mat low, ground;
  cv::erode(z, low, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  low.setTo(-big, low >= big);  // no data within the window: never the maximum
  cv::dilate(low, ground, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::Mat mask = cv::Mat::zeros(map.rows, map.cols, CV_8U);
  if (relief) *relief = cv::Mat::zeros(map.rows, map.cols, CV_32F);
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const float v = map.at(r, c), g = ground.at<float>(r, c);
      if (v == v && g > -big && v - g > relief_m) mask.at<uint8_t>(r, c) = 1;
      if (relief && v == v && g > -big) relief->at<float>(r, c) = std::max(0.0f, v - g);
    }
  }
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  out.resize(static_cast<std::size_t>(std::max(0, n - 1)));
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const int l = labels.at<int>(r, c);
      if (l <= 0) continue;
      ReliefBlob& b = out[static_cast<std::size_t>(l - 1)];
      b.relief_m = std::max(b.relief_m, static_cast<double>(map.at(r, c) - ground.at<float>(r, c)));
    }
  }
  for (int l = 1; l < n; ++l) {
    ReliefBlob& b = out[static_cast<std::size_t>(l - 1)];
    b.area_m2 = stats.at<int>(l, cv::CC_STAT_AREA) * map.cell_m * map.cell_m;
    b.col = std::clamp(static_cast<int>(std::lround(centroids.at<double>(l, 0))), 0, map.cols - 1);
    b.row = std::clamp(static_cast<int>(std::lround(centroids.at<double>(l, 1))), 0, map.rows - 1);
    b.center_xy = map.cell_center_xy(b.row, b.col);
  }
  if (labels_out) *labels_out = labels;
  return out;
}

// Blobs split by the model's footprint (recog28f): within a blob too large for the model (a
// partly buried shell whose relief merged with a pipeline beside it), the centres where the
// model's footprint best fits the relief — the local maxima of a footprint-sized matched filter:
// per yaw of the symmetry's range, the mean relief (capped at the model's height) under the
// footprint minus the mean relief in a ring one cell outside it (a pipeline running on past the
// model's ends fills the ring; a model-sized body does not), the best yaw's — at least
// r_model/2 apart, best first. `fp`: the model's footprint on the map's cells (yaw 0), its centre
// at (cr, cc).
std::vector<std::pair<double, ReliefBlob>> split_blob_centres(
    const ElevationMap& map, const cv::Mat& relief, const cv::Mat& labels, int label,
    const cv::Mat& fp, int cr, int cc, const std::vector<double>& yaws, double height,
    double radius_m, std::size_t max_out) {
  std::vector<std::pair<double, ReliefBlob>> out;
  cv::Mat capped;
  cv::min(relief, height, capped);
  cv::Mat best(relief.size(), CV_32F, cv::Scalar(-1e9));
  // The kernel square and large enough to hold the footprint turned about (cr, cc) and its ring.
  const int half = std::max({cr, cc, fp.rows - 1 - cr, fp.cols - 1 - cc}) + 3;
  const int n = 2 * half + 1;
  cv::Mat base = cv::Mat::zeros(n, n, CV_8U);
  fp.copyTo(base(cv::Rect(half - cc, half - cr, fp.cols, fp.rows)));
  for (const double yaw : yaws) {
    cv::Mat turned;
    // Map rows grow southwards: a counter-clockwise turn of the model is clockwise on the image.
    const cv::Mat rot = cv::getRotationMatrix2D(cv::Point2f(half, half), yaw / kDeg, 1.0);
    cv::warpAffine(base, turned, rot, base.size(), cv::INTER_NEAREST);
    cv::Mat grown1, grown2;
    const cv::Mat k3 = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
    cv::dilate(turned, grown1, k3);
    cv::dilate(grown1, grown2, k3);
    const cv::Mat ring = grown2 - grown1;
    const int nf = cv::countNonZero(turned), nr = cv::countNonZero(ring);
    if (nf == 0 || nr == 0) continue;
    cv::Mat kernel;
    turned.convertTo(kernel, CV_32F, 1.0 / nf);
    cv::Mat kring;
    ring.convertTo(kring, CV_32F, 1.0 / nr);
    kernel -= kring;
    cv::Mat response;
    cv::filter2D(capped, response, CV_32F, kernel, cv::Point(half, half), 0, cv::BORDER_CONSTANT);
    best = cv::max(best, response);
  }
  // Local maxima inside the blob, r_model/2 apart.
  const int w = std::max(3, 2 * static_cast<int>(std::lround(0.5 * radius_m / map.cell_m)) + 1);
  cv::Mat inside = labels == label;
  cv::Mat masked = cv::Mat(best.size(), CV_32F, cv::Scalar(-1e9));
  best.copyTo(masked, inside);
  cv::Mat peak;
  cv::dilate(masked, peak, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(w, w)));
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const float v = masked.at<float>(r, c);
      if (!inside.at<uint8_t>(r, c) || v <= 0 || v < peak.at<float>(r, c)) continue;
      ReliefBlob b;
      b.row = r;
      b.col = c;
      b.center_xy = map.cell_center_xy(r, c);
      b.relief_m = v;
      out.emplace_back(v, b);
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (out.size() > max_out) out.resize(max_out);
  return out;
}

// One model's search state in the competition between hypotheses (docs/recognition.md,
// "Competing hypotheses").
struct ModelSearch {
  const ModelTemplate* m = nullptr;
  RingLayout layout;
  RingDescriptor desc;
  int wanted = 0, found = 0, rejected = 0;
  bool done = false;
  // Relief proposals (RecognitionConfig::max_relief_proposals): the model's footprint area above
  // relief_m (m²), the blobs that fit it, best first, the next one to try, and whether the scan
  // has given up (then proposals are tried).
  double footprint_m2 = 0;
  std::vector<std::size_t> proposals;
  std::size_t next_proposal = 0;
  int proposals_rejected = 0;
  bool scan_over = false;
  std::vector<uint8_t> excluded;        // coarse cells this model's scan skips
  std::unique_ptr<ModelIndex> index;    // the model's KD-tree, built at its first registration
  std::optional<SearchRecord> pending;  // a registered, verified candidate awaiting the decision
  // The verification's settings for this model: relief_m is model_relief_m's.
  VerificationConfig verification;
};

// Not this patch again for this model: its neighbourhood (r_model/2) is excluded from the scan.
void exclude_patch(ModelSearch& s, const ScanResult& scan, const ElevationMap& coarse) {
  const int g = static_cast<int>(std::ceil(0.5 * s.m->radius_m / coarse.cell_m));
  for (int dr = -g; dr <= g; ++dr) {
    for (int dc = -g; dc <= g; ++dc) {
      const int rr = scan.row + dr, cc = scan.col + dc;
      if (rr >= 0 && cc >= 0 && rr < coarse.rows && cc < coarse.cols) {
        s.excluded[coarse.index(rr, cc)] = 1;
      }
    }
  }
}

// The verification's verdict on a registered candidate: empty when found, else why not.
std::string verdict(const Placement& p, const ModelTemplate& m, const RecognitionConfig& config) {
  const Verification& v = p.verification;
  if (!v.valid) return "nothing observed around the model's footprint (no seabed to stand on)";
  if (v.overlap > config.max_overlap) return "overlaps an accepted placement";
  if (buried_fraction(*ModelAtScale(m, p.scale), p.T_world_model, v.ground_z) >
      config.max_buried_fraction) {
    return "more of the model below the seabed than max_buried_fraction";
  }
  if (!(p.residual.median_m <= config.max_residual_median_m)) {
    return "residual median above max_residual_median_m";
  }
  if (v.evidence < config.verification.min_evidence) return "relief evidence below min_evidence";
  if (v.confidence < config.verification.min_confidence) return "confidence below min_confidence";
  return "";
}

}  // namespace

RecognitionResult recognize_2d(const PointCloud& scene_world,
                               const std::vector<ModelTemplate>& models_in,
                               const RecognitionConfig& config, bool progress) {
  config.validate();
  const auto threads = check_recognition_inputs(scene_world, models_in, config.num_threads);
  const auto start = Clock::now();
  RecognitionResult out;
  out.scene_points = scene_world.size();

  // The field's elevation maps (sec. 6.2.1): fine for registration, coarse (Δ_NE) for the scan.
  ElevationMapConfig mc;
  mc.cell_m = config.map_cell_m;
  const ElevationMap fine = elevation_map_from_points(scene_world, mc);
  mc.cell_m = config.recog_cell_m;
  const ElevationMap coarse = elevation_map_from_points(scene_world, mc);
  out.map_rows = coarse.rows;
  out.map_cols = coarse.cols;
  ScenePoints points;
  points.build(scene_world, coarse);
  out.seconds_maps = since(start);

  const std::vector<const ModelTemplate*> order = by_decreasing_size(models_in);
  const double period = config.scan.period_m;
  const double width = coarse.cols * coarse.cell_m, height = coarse.rows * coarse.cell_m;
  for (const ModelTemplate* m : order) {
    const double r_patch = m->radius_m + std::sqrt(0.5) * period;  // eq. 6.8
    if (2 * r_patch > std::min(width, height)) {
      throw Error("recognition: model '" + m->name + "' (patch diameter " +
                  std::to_string(2 * r_patch) + " m) is larger than the map (" +
                  std::to_string(width) + " x " + std::to_string(height) +
                  " m): check the model's unit and the map");
    }
  }
  // Relief proposals: the blobs of the scene as it was given, offered to the models they fit;
  // one set per relief threshold (model_relief_m: low models have their own). `blobs` holds
  // the proposals, the models' indices point into it.
  struct BlobSet {
    double relief_m = 0;
    std::vector<ReliefBlob> blobs;
    cv::Mat relief_image, labels;
  };
  std::deque<BlobSet> blob_sets;  // references stay valid as sets are added
  auto blob_set = [&](double relief) -> const BlobSet& {
    for (const BlobSet& b : blob_sets) {
      if (b.relief_m == relief) return b;
    }
    BlobSet b;
    b.relief_m = relief;
    b.blobs = relief_blobs(coarse, config.relief_window_m, relief, &b.relief_image, &b.labels);
    blob_sets.push_back(std::move(b));
    return blob_sets.back();
  };
  std::vector<ReliefBlob> blobs;
  const double noise_m = map_height_noise(fine);
  std::vector<ModelSearch> states(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    ModelSearch& s = states[k];
    s.m = order[k];
    s.verification = config.verification;
    s.verification.relief_m = model_relief_m(*s.m, config, noise_m);
    const double relief = s.verification.relief_m;
    const double r_patch = s.m->radius_m + std::sqrt(0.5) * period;  // eq. 6.8
    s.layout = make_ring_layout(coarse.cell_m, r_patch, config.descriptor.ring_width_m);
    // The model's descriptor: its top view with the seabed it stands on around it, centred on
    // a cell centre as the patches are.
    TopViewConfig tv;
    tv.cell_m = coarse.cell_m;
    tv.background_radius_m = r_patch + coarse.cell_m;
    const double h = 0.5 * coarse.cell_m;
    const ElevationMap view = render_top_view(*s.m, 0.0, {h, h}, tv);
    const int vr = static_cast<int>(std::floor((view.origin_xy.y() - h) / view.cell_m));
    const int vc = static_cast<int>(std::floor((h - view.origin_xy.x()) / view.cell_m));
    s.desc = describe_model(view, vr, vc, s.layout, config.descriptor);
    // The model's footprint standing `relief` above its base (the top view's lowest height),
    // and the blobs that fit it, best first (area and height ratios nearest 1).
    float base = std::numeric_limits<float>::infinity();
    for (float zv : view.z) {
      if (zv == zv) base = std::min(base, zv);
    }
    cv::Mat fp_mask = cv::Mat::zeros(view.rows, view.cols, CV_8U);
    for (int r = 0; r < view.rows; ++r) {
      for (int c = 0; c < view.cols; ++c) {
        const float zv = view.at(r, c);
        if (zv == zv && zv > base + relief) fp_mask.at<uint8_t>(r, c) = 1;
      }
    }
    s.footprint_m2 = cv::countNonZero(fp_mask) * view.cell_m * view.cell_m;
    // The opening lifts the model off the seabed only when its footprint holds no square of the
    // window (a 2.6 m torpedo 0.3 m wide does; a 2 m wide frame does not).
    bool isolated = s.footprint_m2 > 0;
    if (isolated) {
      const int kw = std::max(
          3, 2 * static_cast<int>(std::lround(0.5 * config.relief_window_m / view.cell_m)) + 1);
      cv::Mat core;
      cv::erode(fp_mask, core, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kw, kw)),
                cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
      isolated = cv::countNonZero(core) == 0;
    }
    // A model standing less than its relief threshold cannot have raised a blob, and the
    // verification sees no relief of it: no proposals (with low_relief_fraction > 0 every model
    // stands above its own threshold unless min_relief_m or the map's noise exceeds its height).
    // A low model's blobs are those of its own threshold (blob_set).
    const BlobSet* set = config.max_relief_proposals > 0 && isolated && s.m->height() >= relief
                             ? &blob_set(relief)
                             : nullptr;
    if (set && !set->blobs.empty()) {
      const std::vector<ReliefBlob>& fitting = set->blobs;
      const double hm = s.m->height();
      const double h_lo = 0.5 * (1 - config.max_buried_fraction) * hm, h_hi = 1.5 * hm + 0.1;
      std::vector<std::pair<double, std::size_t>> fits;
      for (std::size_t b = 0; b < fitting.size(); ++b) {
        const double ratio = fitting[b].area_m2 / s.footprint_m2;
        if (fitting[b].relief_m < h_lo || fitting[b].relief_m > h_hi || ratio < 0.25 || ratio > 3) {
          continue;
        }
        fits.emplace_back(std::abs(std::log(ratio)) + std::abs(std::log(fitting[b].relief_m / hm)),
                          b);
      }
      std::sort(fits.begin(), fits.end());
      for (const auto& f : fits) {
        blobs.push_back(fitting[f.second]);
        s.proposals.push_back(blobs.size() - 1);
      }
      // Then the blobs too large for the model, split by its footprint (split_blob_centres),
      // when config.split_relief_blobs: their best centres, best first, after the blobs that fit.
      if (config.split_relief_blobs) {
        std::vector<std::pair<double, ReliefBlob>> split;
        const std::vector<double> yaws =
            yaw_range(s.m->symmetry, config.search.yaw_step_deg * 3 * kDeg);
        for (std::size_t b = 0; b < fitting.size(); ++b) {
          const double ratio = fitting[b].area_m2 / s.footprint_m2;
          if (ratio <= 3 || fitting[b].relief_m < h_lo) continue;
          for (auto& c :
               split_blob_centres(coarse, set->relief_image, set->labels, static_cast<int>(b) + 1,
                                  fp_mask, vr, vc, yaws, hm, s.m->radius_m,
                                  static_cast<std::size_t>(config.max_relief_proposals))) {
            split.push_back(std::move(c));
          }
        }
        std::stable_sort(split.begin(), split.end(),
                         [](const auto& a, const auto& b) { return a.first > b.first; });
        if (split.size() > static_cast<std::size_t>(config.max_relief_proposals)) {
          split.resize(static_cast<std::size_t>(config.max_relief_proposals));
        }
        for (auto& c : split) {
          blobs.push_back(c.second);
          s.proposals.push_back(blobs.size() - 1);
        }
      }
    }
    s.wanted = s.m->expected >= 0 ? s.m->expected : config.max_instances;
    s.done = s.wanted == 0;
    s.excluded.assign(coarse.z.size(), 0);
  }
  std::vector<uint8_t> removed_coarse(coarse.z.size(), 0), removed_fine(fine.z.size(), 0);

  // 4D search (eq. 6.9), trimmed ICP (sec. 6.3.2.5) and verification of model `s` about
  // rec.scan.center_xy on the scene as it stands (accepted placements removed); fills
  // rec.placement.
  auto register_at = [&](ModelSearch& s, SearchRecord& rec, Clock::time_point t0) {
    const ModelTemplate* m = s.m;
    Placement& p = rec.placement;
    p.model = m->name;
    const auto t1 = Clock::now();
    // Step 1: exhaustive 4D search (eq. 6.9) about the winning patch.
    ElevationMap coarse_live = coarse;
    for (std::size_t i = 0; i < coarse_live.z.size(); ++i) {
      if (removed_coarse[i]) coarse_live.z[i] = ElevationMap::kNoData;
    }
    const ElevationMap fine_live =
        crop(fine, removed_fine, rec.scan.center_xy, m->radius_m + period + 6 * coarse.cell_m);
    // Two searches: the seabed-bounded one (Search4dConfig::seabed_ring_m) and, when it is on,
    // the thesis' (eq. 6.1's median over every cell, coarse-to-fine). Neither wins everywhere:
    // the bounded one places open frames, blocks and buoys the median sinks; on a map blurred
    // by navigation drift (the 4.2 m spool of the drift field, its pipe seen twice) the median's
    // placement was right and the bounded one sank the spool 1.5 m away. The verification
    // judges: of the placements below, the one that explains the scene best is step 1.
    std::vector<Search4dResult> runs;
    runs.push_back(search_4d(*m, coarse_live, fine_live, rec.scan.center_xy, period, config.search,
                             config.max_buried_fraction));
    if (config.search.seabed_ring_m > 0) {
      Search4dConfig thesis = config.search;
      thesis.seabed_ring_m = 0;
      runs.push_back(search_4d(*m, coarse_live, fine_live, rec.scan.center_xy, period, thesis,
                               config.max_buried_fraction));
    }
    // Step 1's height: each search's ζ, or the model standing on the local seabed, whichever
    // explains the scene better (verify.hpp's score). The median aligns an open frame's top
    // with the seabed seen through it (measured: a 1.6 m lattice frame placed 1.55 m deep and
    // refused as buried); standing on the seabed is the prior of every catalogue structure,
    // and a partly buried one keeps the search's height.
    Eigen::Isometry3d T4 = Eigen::Isometry3d::Identity();
    Verification v4;
    bool have4 = false;
    double rms4 = 0;
    // A pose and the same pose standing on the verification's seabed, kept when either explains
    // the scene better than the best so far.
    auto consider = [&](const Eigen::Isometry3d& T, double rms) {
      std::vector<std::pair<Eigen::Isometry3d, Verification>> poses;
      poses.emplace_back(T, verify_placement(*m, T, fine, removed_fine, s.verification));
      const Verification& vr = poses.front().second;
      if (std::isfinite(vr.ground_z)) {
        Eigen::Isometry3d T_seated = T;
        T_seated.translation().z() +=
            vr.ground_z -
            (T_seated * Eigen::Vector3d(m->center_xy.x(), m->center_xy.y(), m->base_z)).z();
        poses.emplace_back(T_seated,
                           verify_placement(*m, T_seated, fine, removed_fine, s.verification));
      }
      for (const auto& [Tp, v] : poses) {
        if (have4 && !(v.valid && v.score_m3 > v4.score_m3)) continue;
        T4 = Tp;
        v4 = v;
        rms4 = rms;
        have4 = true;
      }
    };
    for (const Search4dResult& run : runs) {
      if (run.found) consider(run.T_world_model, run.rms_m);
    }
    // The tilt (beyond the thesis' upright eq. 6.9, RecognitionConfig::level_by_seabed): for a
    // plane of normal n through `pivot` (z = pivot.z + a·(x − pivot.x) + b·(y − pivot.y), a =
    // −n.x/n.z, b = −n.y/n.z) the scene maps are levelled by it (its height subtracted, a shear:
    // the tilts allowed are small), the bounded search (eq. 6.9) runs again on them about the
    // same patch, and its upright placement is turned onto the plane (the rotation taking the
    // vertical to n, about the pivot). Returns the placement, or nothing.
    auto level_search = [&](const Eigen::Vector3d& n,
                            const Eigen::Vector3d& pivot) -> std::vector<Search4dResult> {
      const double a = -n.x() / n.z(), b = -n.y() / n.z();
      auto level = [&](const ElevationMap& map) {
        ElevationMap out = map;
        for (int r = 0; r < out.rows; ++r) {
          for (int col = 0; col < out.cols; ++col) {
            float& z = out.at(r, col);
            if (z != z) continue;
            const Eigen::Vector2d d = out.cell_center_xy(r, col) - pivot.head<2>();
            z -= static_cast<float>(a * d.x() + b * d.y());
          }
        }
        return out;
      };
      const ElevationMap coarse_lev = level(coarse_live), fine_lev = level(fine_live);
      const Eigen::Matrix3d R =
          Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n).toRotationMatrix();
      Eigen::Isometry3d tilt = Eigen::Isometry3d::Identity();
      tilt.linear() = R;
      tilt.translation() = pivot - R * pivot;
      // Both of step 1's searches, as on the scene as given (neither wins everywhere).
      std::vector<Search4dResult> out;
      Search4dConfig thesis = config.search;
      thesis.seabed_ring_m = 0;
      for (int k = 0; k < (config.search.seabed_ring_m > 0 ? 2 : 1); ++k) {
        Search4dResult lev = search_4d(*m, coarse_lev, fine_lev, rec.scan.center_xy, period,
                                       k == 0 ? config.search : thesis, config.max_buried_fraction);
        if (!lev.found) continue;
        lev.T_world_model = tilt * lev.T_world_model;
        out.push_back(lev);
      }
      return out;
    };
    // A tilt matters when it lifts or sinks the model's rim more than the verification's
    // tolerance (its radius · tan(tilt) > tol_m), and is searched only within max_tilt_deg (the
    // tilt ICP may keep).
    auto tilt_matters = [&](double tan_tilt) {
      return tan_tilt * m->radius_m > config.verification.tol_m &&
             std::atan(tan_tilt) <= config.max_tilt_deg * kDeg;
    };
    auto footprint_center = [&](const Eigen::Isometry3d& T) -> Eigen::Vector2d {
      return (T * Eigen::Vector3d(m->center_xy.x(), m->center_xy.y(), 0)).head<2>();
    };
    // First the seabed's tilt: the plane the verification fitted around the footprint of the
    // best upright placement (a structure stands on the seabed); the verification judges the
    // tilted placement against the upright ones.
    if (config.level_by_seabed && have4 && v4.valid) {
      const double a = v4.ground_dzdx, b = v4.ground_dzdy;
      if (tilt_matters(std::hypot(a, b))) {
        const Eigen::Vector2d c = footprint_center(T4);
        for (const Search4dResult& lev : level_search(Eigen::Vector3d(-a, -b, 1).normalized(),
                                                      Eigen::Vector3d(c.x(), c.y(), v4.ground_z))) {
          consider(lev.T_world_model, lev.rms_m);
        }
      }
    }
    if (!have4) {
      rec.reason = "the 4D search found no placement with enough scene under the model";
      p.seconds = since(t0);
      return;
    }
    const double reach = m->radius_m * m->scale_max + config.icp.max_distance_m + 0.1;
    std::vector<Eigen::Vector3f> local;
    // Step 2 from step 1's placement (T4, v4): fills p.
    auto step2 = [&]() {
      p.T_world_model_4d = T4;
      p.rms_4d_m = rms4;
      p.icp_kept = false;
      p.icp_iterations = 0;
      const Eigen::Vector2d c4 = footprint_center(T4);
      local = points.near(scene_world, c4, reach, removed_coarse);
      // The structure's points only: those standing above the local seabed. Seabed points beside
      // a wall or a footing would otherwise pull the model sideways and tilt it. The seabed is
      // the verification's plane about the footprint's centre c4 (on a slope a level cut would
      // keep the uphill seabed).
      if (std::isfinite(v4.ground_z)) {
        const double a = v4.ground_dzdx, b = v4.ground_dzdy,
                     g = v4.ground_z + config.ground_clearance_m;
        local.erase(std::remove_if(local.begin(), local.end(),
                                   [&](const Eigen::Vector3f& q) {
                                     return q.z() < g + a * (q.x() - c4.x()) + b * (q.y() - c4.y());
                                   }),
                    local.end());
      }
      p.residual_4d = structure_residual(local, *m, T4);
      p.T_world_model = T4;
      p.residual = p.residual_4d;
      p.set_verification(v4);
      if (config.run_icp && local.size() >= 6 &&
          buried_fraction(*m, T4, v4.ground_z) <= config.max_buried_fraction) {
        // Step 2: trimmed ICP for the full 6D pose, kept when the verification does not drop.
        try {
          if (!s.index) s.index = std::make_unique<ModelIndex>(m->points, m->normals);
          const IcpResult icp = trimmed_icp(*s.index, local, T4, config.icp);
          p.icp_iterations = icp.iterations;
          const Eigen::Vector3d c_model(m->center_xy.x(), m->center_xy.y(),
                                        0.5 * (m->base_z + m->top_z));
          const double shift = (icp.T_world_model * c_model - T4 * c_model).norm();
          if (tilt_deg(icp.T_world_model) <= config.max_tilt_deg &&
              shift <= config.max_icp_shift_m) {
            const Verification vi =
                verify_placement(*m, icp.T_world_model, fine, removed_fine, s.verification);
            if (vi.confidence >= v4.confidence - 0.05) {
              p.T_world_model = icp.T_world_model;
              p.residual = structure_residual(local, *m, icp.T_world_model);
              p.set_verification(vi);
              p.icp_kept = true;
            }
          }
        } catch (const Error&) {
          // No scene point near the model: keep the 4D placement (judged below).
        }
      }
    };
    step2();
    // Then the structure's own tilt: when ICP turned the model away from step 1's tilt (a
    // structure settled unevenly, not parallel to the seabed around it), the search runs again
    // on the scene levelled by the plane of the model's base as ICP left it, and step 2 restarts
    // from that placement when it explains the scene better than step 2's result (a search with
    // the wrong tilt can slide a structure by one repeat of its parts).
    if (config.level_by_seabed && p.icp_kept) {
      const Eigen::Vector3d n = p.T_world_model.linear().col(2), n4 = T4.linear().col(2);
      const double cos_d = std::clamp(n.dot(n4), -1.0, 1.0);
      if (n.z() > 0 && tilt_matters(std::tan(std::acos(cos_d)))) {
        const Eigen::Vector3d pivot =
            p.T_world_model * Eigen::Vector3d(m->center_xy.x(), m->center_xy.y(), m->base_z);
        if (const std::vector<Search4dResult> levs = level_search(n, pivot); !levs.empty()) {
          const Placement before = p;
          const Eigen::Isometry3d T4_before = T4;
          const Verification v4_before = v4;
          const double rms4_before = rms4;
          const std::vector<Eigen::Vector3f> local_before = local;
          have4 = false;
          for (const Search4dResult& lev : levs) consider(lev.T_world_model, lev.rms_m);
          if (have4 && v4.valid && v4.score_m3 > before.verification.score_m3) {
            step2();
          } else {
            p = before;
            T4 = T4_before;
            v4 = v4_before;
            rms4 = rms4_before;
            local = local_before;
          }
        }
      }
    }
    if (m->scale_searched()) {
      refine_placement_scale(*m, p, fine, removed_fine, local, config);  // scale.cpp
    }
    p.seconds_registration = since(t1);
    p.seconds = since(t0);
  };
  // The model's next candidate: scan (sec. 6.3.2.4), then register_at the winning patch; once
  // the scan has given up, the next relief proposal that fits the model (its centre neither
  // taken by a placement nor tried by this model). A record whose scan is not `found` ends the
  // model's search.
  auto search = [&](ModelSearch& s) {
    SearchRecord rec;
    rec.model = s.m->name;
    const auto t0 = Clock::now();
    if (!s.scan_over) {
      rec.scan = scan_patches(coarse, removed_coarse, s.excluded, s.layout, s.desc,
                              config.descriptor.min_valid_fraction,
                              config.max_relative_score * s.m->height(), config.scan);
      if (rec.scan.found) {
        rec.placement.score_m = rec.scan.score_m;
        rec.placement.seconds_scan = since(t0);
        register_at(s, rec, t0);
        return rec;
      }
      s.scan_over = true;
    }
    while (s.proposals_rejected < config.max_relief_proposals &&
           s.next_proposal < s.proposals.size()) {
      const ReliefBlob& b = blobs[s.proposals[s.next_proposal++]];
      const std::size_t i = coarse.index(b.row, b.col);
      if (removed_coarse[i] || s.excluded[i]) continue;
      rec.proposal = "relief";
      rec.scan = ScanResult{};
      rec.scan.found = true;
      rec.scan.row = b.row;
      rec.scan.col = b.col;
      rec.scan.center_xy = b.center_xy;
      rec.scan.score_m = std::numeric_limits<double>::quiet_NaN();  // no descriptor score
      rec.placement.score_m = rec.scan.score_m;
      register_at(s, rec, t0);
      return rec;
    }
    rec.scan = ScanResult{};
    rec.reason = "no patch scores below max_relative_score x model height, no relief proposal left";
    return rec;
  };
  // Does candidate a explain its region better than b? The larger explanation score wins; within
  // `compete_margin` of each other (look-alikes: a plain cylinder and an ordnance shell of its
  // size explain the same relief within the tolerance), the finer fit, the lower residual median.
  auto better = [&](const Placement& a, const Placement& b) {
    const double sa = a.verification.score_m3, sb = b.verification.score_m3;
    if (std::abs(sa - sb) > config.compete_margin * std::max(std::abs(sa), std::abs(sb))) {
      return sa > sb;
    }
    const double ra = std::isfinite(a.residual.median_m) ? a.residual.median_m : 1e9;
    const double rb = std::isfinite(b.residual.median_m) ? b.residual.median_m : 1e9;
    return ra < rb;
  };

  auto reject = [&](ModelSearch& s, SearchRecord rec) {
    rec.accepted = false;
    if (rec.proposal == "relief") {
      ++s.proposals_rejected;  // search() stops at max_relief_proposals
    } else if (++s.rejected >= config.max_rejections) {
      s.scan_over = true;  // then the relief proposals, if any fit
      s.done = config.max_relief_proposals == 0 || s.next_proposal >= s.proposals.size();
    }
    if (rec.scan.found) exclude_patch(s, rec.scan, coarse);
    out.searches.push_back(std::move(rec));
  };

  // Competing hypotheses (beyond the thesis' fixed order of sec. 6.3.2.6): every model proposes
  // its best candidate on the scene as it stands; of the candidates the verification finds, the
  // one that explains the scene best (Verification::score_m3) is accepted and its area removed;
  // the others are verified again on what is left. A region is therefore claimed by the model
  // that explains it, whatever the catalogue's order, and never by two models.
  Progress bar("recognize", order.size(), progress);
  std::size_t finished = 0;
  for (;;) {
    for (ModelSearch& s : states) {
      while (!s.done && !s.pending) {
        SearchRecord rec = search(s);
        if (!rec.scan.found) {
          s.done = true;
          out.searches.push_back(std::move(rec));
        } else if (!rec.reason.empty()) {
          reject(s, std::move(rec));
        } else {
          s.pending = std::move(rec);
        }
      }
    }
    ModelSearch* best = nullptr;
    bool any_pending = false;
    for (ModelSearch& s : states) {
      if (!s.pending) continue;
      any_pending = true;
      s.pending->reason = verdict(s.pending->placement, *s.m, config);
      if (!s.pending->reason.empty()) continue;
      if (!best || s.pending->placement.verification.score_m3 >
                       best->pending->placement.verification.score_m3) {
        best = &s;
      }
    }
    if (!any_pending) break;
    if (!best) {
      // No pending candidate is found on the scene as it now stands: each is rejected.
      for (ModelSearch& s : states) {
        if (!s.pending) continue;
        SearchRecord rec = std::move(*s.pending);
        s.pending.reset();
        reject(s, std::move(rec));
      }
    } else {
      // The region's competitors: every other model that may still place an instance is
      // registered about the same patch and verified; the best explanation takes the region
      // (the others' own candidates are judged again below, without it).
      for (ModelSearch& s : states) {
        if (&s == best || s.found >= s.wanted) continue;
        SearchRecord rival;
        rival.model = s.m->name;
        rival.scan = best->pending->scan;
        rival.scan.score_m = std::numeric_limits<double>::quiet_NaN();  // not its descriptor's
        rival.placement.score_m = rival.scan.score_m;
        register_at(s, rival, Clock::now());
        rival.reason = verdict(rival.placement, *s.m, config);
        if (!rival.reason.empty() || !better(rival.placement, best->pending->placement)) {
          continue;
        }
        // The rival wins: the previous holder's candidate returns to its own search.
        SearchRecord lost = std::move(*best->pending);
        best->pending.reset();
        lost.reason = "a better explanation of its region: " + s.m->name;
        reject(*best, std::move(lost));
        // The rival's own pending candidate elsewhere, if any, is replaced: it is searched
        // again later.
        s.pending = std::move(rival);
        best = &s;
      }
      SearchRecord rec = std::move(*best->pending);
      best->pending.reset();
      rec.accepted = true;
      if (best->m->symmetry == Symmetry::None) {
        // Would the model turned 180° explain the region as well?
        Placement& p = rec.placement;
        const ModelAtScale mb(*best->m, p.scale);
        const Eigen::Vector3d axis =
            p.T_world_model * Eigen::Vector3d(mb->center_xy.x(), mb->center_xy.y(), 0);
        Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
        turn.translation() = axis;
        turn.rotate(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
        turn.translate(-axis);
        const Verification vt =
            verify_placement(*mb, turn * p.T_world_model, fine, removed_fine, best->verification);
        p.turned_confidence = vt.confidence;
        p.yaw_ambiguous = vt.confidence >= config.verification.min_confidence &&
                          vt.score_m3 >= (1 - config.compete_margin) * p.verification.score_m3;
      }
      out.placements.push_back(rec.placement);
      ++best->found;
      if (best->found >= best->wanted) best->done = true;
      exclude_patch(*best, rec.scan, coarse);
      const ModelAtScale placed(*best->m, rec.placement.scale);
      mark_placed(*placed, rec.placement.T_world_model, coarse, config.removal_margin_m,
                  removed_coarse);
      mark_placed(*placed, rec.placement.T_world_model, fine, config.removal_margin_m,
                  removed_fine);
      out.searches.push_back(std::move(rec));
      // The other candidates, judged again without the accepted placement's area.
      for (ModelSearch& s : states) {
        if (!s.pending) continue;
        Placement& p = s.pending->placement;
        p.set_verification(verify_placement(*ModelAtScale(*s.m, p.scale), p.T_world_model, fine,
                                            removed_fine, s.verification));
      }
    }
    std::size_t now_done = 0;
    for (const ModelSearch& s : states) now_done += s.done && !s.pending;
    if (now_done > finished) bar.add(now_done - finished);
    finished = now_done;
  }
  bar.finish();
  out.seconds = since(start);
  return out;
}

TriangleMesh placed_models_mesh(const std::vector<ModelTemplate>& models,
                                const std::vector<Placement>& placements) {
  TriangleMesh out;
  for (const Placement& p : placements) {
    for (const auto& m : models) {
      if (m.name != p.model) continue;
      TriangleMesh placed = m.mesh;
      for (auto& v : placed.vertices) v *= static_cast<float>(p.scale);  // T · S(scale) · model
      placed.transform(p.T_world_model);
      out.append(placed);
    }
  }
  return out;
}

namespace {
nlohmann::json pose_json(const Eigen::Isometry3d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    rows.push_back({T.matrix()(r, 0), T.matrix()(r, 1), T.matrix()(r, 2), T.matrix()(r, 3)});
  }
  return rows;
}
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }
nlohmann::json verification_json(const Verification& v) {
  return {{"valid", v.valid},         {"seen", v.seen},
          {"explained", v.explained}, {"violation", v.violation},
          {"intrusion", v.intrusion}, {"unexplained", v.unexplained},
          {"spill", v.spill},         {"overlap", v.overlap},
          {"relief_m3", v.relief_m3}, {"scene_relief_m3", v.scene_relief_m3},
          {"score_m3", v.score_m3},   {"evidence", v.evidence}};
}
}  // namespace

std::string verification_json_text(const Verification& v) { return verification_json(v).dump(); }

nlohmann::json rpy_deg_json(const Eigen::Isometry3d& T) {
  // R = Rz(yaw)·Ry(pitch)·Rx(roll), as scene files give poses.
  const Eigen::Matrix3d R = T.linear();
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2)), yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll / kDeg, pitch / kDeg, yaw / kDeg};
}

nlohmann::json placements_list_json(const std::vector<Placement>& placements) {
  nlohmann::json list = nlohmann::json::array();
  for (const Placement& p : placements) {
    list.push_back({{"model", p.model},
                    {"method", p.method},
                    {"T_world_model", pose_json(p.T_world_model)},
                    {"scale", p.scale},
                    {"translation",
                     {p.T_world_model.translation().x(), p.T_world_model.translation().y(),
                      p.T_world_model.translation().z()}},
                    {"rpy_deg", rpy_deg_json(p.T_world_model)},
                    {"score_m", num(p.score_m)},
                    {"residual_median_m", num(p.residual.median_m)},
                    {"residual_mean_m", num(p.residual.mean_m)},
                    {"residual_points", p.residual.points},
                    {"support", p.support},
                    {"observed", p.observed},
                    {"ground_z", num(p.ground_z)},
                    {"step1_T_world_model", pose_json(p.T_world_model_4d)},
                    {"step1_residual_median_m", num(p.residual_4d.median_m)},
                    {"step1_residual_mean_m", num(p.residual_4d.mean_m)},
                    {"icp_iterations", p.icp_iterations},
                    {"icp_kept", p.icp_kept},
                    {"seconds_scan", p.seconds_scan},
                    {"seconds_registration", p.seconds_registration},
                    {"seconds_scale", p.seconds_scale},
                    {"seconds", p.seconds}});
    // The verified methods' confidence (a method that does not verify writes none).
    if (p.method == "2d" || p.verification.valid) {
      list.back()["confidence"] = p.confidence;
      list.back()["turned_confidence"] = num(p.turned_confidence);
      list.back()["yaw_ambiguous"] = p.yaw_ambiguous;
      list.back()["verification"] = verification_json(p.verification);
    }
  }
  return list;
}

std::string placements_json(const RecognitionResult& result, const std::string& map_source,
                            const std::string& catalogue_source, const RecognitionConfig& config) {
  nlohmann::json j;
  j["format"] = "sonar3d-placements";
  j["version"] = 1;
  j["map"] = map_source;
  j["catalogue"] = catalogue_source;
  j["frame"] = "world: local ENU (x East, y North, z up), metres";
  j["settings"] = {{"map_cell_m", config.map_cell_m},
                   {"recog_cell_m", config.recog_cell_m},
                   {"period_m", config.scan.period_m},
                   {"ring_width_m", config.descriptor.ring_width_m},
                   {"bin_m", config.descriptor.bin_m},
                   {"yaw_step_deg", config.search.yaw_step_deg},
                   {"icp", config.run_icp},
                   {"max_relative_score", config.max_relative_score},
                   {"max_residual_median_m", config.max_residual_median_m},
                   {"min_confidence", config.verification.min_confidence},
                   {"max_overlap", config.max_overlap},
                   {"compete_margin", config.compete_margin},
                   {"max_rejections", config.max_rejections},
                   {"max_relief_proposals", config.max_relief_proposals},
                   {"low_relief_fraction", config.low_relief_fraction},
                   {"min_relief_m", config.min_relief_m},
                   {"relief_window_m", config.relief_window_m},
                   {"split_relief_blobs", config.split_relief_blobs},
                   {"level_by_seabed", config.level_by_seabed},
                   {"scale_search",
                    {{"coarse_step", config.scale.coarse_step},
                     {"tolerance", config.scale.tolerance},
                     {"rounds", config.scale.rounds},
                     {"cap_m", config.scale.cap_m}}},
                   {"verification",
                    {{"tol_m", config.verification.tol_m},
                     {"slip_m", config.verification.slip_m},
                     {"relief_m", config.verification.relief_m},
                     {"ground_ring_m", config.verification.ground_ring_m},
                     {"context_min_m", config.verification.context_min_m},
                     {"context_fraction", config.verification.context_fraction},
                     {"spill_band_m", config.verification.spill_band_m},
                     {"evidence_min_m", config.verification.evidence_min_m},
                     {"evidence_ratio", config.verification.evidence_ratio},
                     {"evidence_slip_m", config.verification.evidence_slip_m},
                     {"min_evidence", config.verification.min_evidence},
                     {"confidence_model",
                      {{"bias", config.verification.bias},
                       {"w_seen", config.verification.w_seen},
                       {"w_explained", config.verification.w_explained},
                       {"w_violation", config.verification.w_violation},
                       {"w_unexplained", config.verification.w_unexplained},
                       {"w_spill", config.verification.w_spill},
                       {"w_evidence", config.verification.w_evidence}}}}}};
  nlohmann::json list = placements_list_json(result.placements);
  j["placements"] = list;
  nlohmann::json searches = nlohmann::json::array();
  for (const SearchRecord& s : result.searches) {
    nlohmann::json e = {{"model", s.model},
                        {"accepted", s.accepted},
                        {"candidates", s.scan.candidates},
                        {"scored", s.scan.scored},
                        {"aborted_early", s.scan.aborted},
                        {"seconds_scan", s.scan.seconds}};
    if (!s.accepted) e["reason"] = s.reason;
    e["proposal"] = s.proposal;
    if (s.scan.found) {
      e["score_m"] = num(s.scan.score_m);
      e["patch_center_xy"] = {s.scan.center_xy.x(), s.scan.center_xy.y()};
    }
    if (!s.accepted && s.scan.found) {
      e["residual_median_m"] = num(s.placement.residual.median_m);
      const Eigen::Vector3d t = s.placement.T_world_model.translation();
      e["step1_translation"] = {s.placement.T_world_model_4d.translation().x(),
                                s.placement.T_world_model_4d.translation().y(),
                                s.placement.T_world_model_4d.translation().z()};
      e["translation"] = {t.x(), t.y(), t.z()};
      e["scale"] = s.placement.scale;
      e["rpy_deg"] = rpy_deg_json(s.placement.T_world_model);
      e["support"] = s.placement.support;
      e["observed"] = s.placement.observed;
      e["confidence"] = s.placement.confidence;
      e["verification"] = verification_json(s.placement.verification);
      e["rms_4d_m"] = num(s.placement.rms_4d_m);
      e["icp_kept"] = s.placement.icp_kept;
    }
    searches.push_back(e);
  }
  j["searches"] = searches;
  j["map_cells"] = {result.map_cols, result.map_rows};
  j["scene_points"] = result.scene_points;
  j["seconds"] = result.seconds;
  return j.dump(2) + "\n";
}

}  // namespace sonar3d
