// Swath registration speed (thesis sec. 6.2.2.1; target: one pair of 2 cm swath maps in <= 1 s):
// two 50 m x 8 m swaths of a synthetic seabed at 2 cm overlapping by 2 m, searched over +-0.5 m,
// by the thesis' exhaustive search (coarse_factor 1) and coarse-to-fine (4).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "sonar3d/mapping/swath_registration.hpp"

namespace {

sonar3d::ElevationMap swath(double y_top, double drift_x, double drift_y, unsigned seed) {
  sonar3d::ElevationMap m;
  m.cell_m = 0.02;
  m.cols = 2500;  // 50 m East
  m.rows = 400;   // 8 m North
  m.origin_xy = {0.0, y_top};
  m.z.resize(static_cast<std::size_t>(m.rows) * m.cols);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0, 0.01f);
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.cols; ++c) {
      const Eigen::Vector2d p = m.cell_center_xy(r, c) - Eigen::Vector2d(drift_x, drift_y);
      const double z = 0.3 * std::sin(0.31 * p.x()) * std::cos(0.23 * p.y()) +
                       0.05 * std::sin(2.1 * p.x() + 1.7 * p.y()) -
                       0.3 * std::exp(-std::pow(std::fmod(p.x() + 100, 12.0) - 6, 2) / 0.08);
      m.at(r, c) = static_cast<float>(z) + noise(rng);
    }
  }
  return m;
}

void BM_RegisterSwathPair(benchmark::State& state) {
  static const sonar3d::ElevationMap a = swath(8.0, 0, 0, 1);
  static const sonar3d::ElevationMap b = swath(14.0, 0.22, -0.14, 2);  // overlap y 6-8 m
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.5;
  cfg.coarse_factor = static_cast<int>(state.range(0));
  cfg.num_threads = static_cast<int>(state.range(1));
  sonar3d::SwathTie t;
  for (auto _ : state) {
    t = sonar3d::register_elevation_maps(a, b, cfg);
    benchmark::DoNotOptimize(t);
  }
  state.counters["err_x_cm"] = 100 * std::abs(t.t.x() + 0.22);
  state.counters["err_y_cm"] = 100 * std::abs(t.t.y() - 0.14);
  state.counters["overlap_cells"] = static_cast<double>(t.overlap_cells);
  state.counters["confidence"] = t.confidence;
}
BENCHMARK(BM_RegisterSwathPair)
    ->ArgNames({"coarse", "threads"})
    ->Args({1, 2})
    ->Args({4, 1})
    ->Args({4, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
