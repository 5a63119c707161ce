// Google Benchmark: simulation rate of a P900-like image (130° × 20°, 0.2° × 0.01° rays, 7 m,
// 2 cm bins) on the thesis' pipeline scene. Thesis: 2 Hz single-threaded; target >= 15 Hz.
#include <benchmark/benchmark.h>

#include <cmath>

#include "sonar3d/sim/benchmark.hpp"

namespace {

sonar3d::SonarSpec p900_like() {
  constexpr double kDeg = M_PI / 180.0;
  sonar3d::SonarSpec s;
  s.set_uniform_bearings(130 * kDeg, 650);
  s.r_min = 0.0;
  s.r_max = 7.0;
  s.range_bins = 350;
  s.vertical_aperture_rad = 20 * kDeg;
  return s;
}

void BM_SimulateP900(benchmark::State& state) {
  const auto spec = p900_like();
  sonar3d::SimulatorConfig cfg;
  cfg.num_threads = static_cast<int>(state.range(0));
  const sonar3d::Simulator sim(sonar3d::make_pipeline_scene(), spec, cfg);
  unsigned long long seed = 0;
  // range(1): pitch down in degrees (0 = the thesis' level view of the pipe; 15 = seabed in view).
  const Eigen::Isometry3d T(
      Eigen::AngleAxisd(state.range(1) * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  for (auto _ : state) {
    benchmark::DoNotOptimize(sim.render(T, ++seed));
  }
  state.counters["Hz"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  state.counters["rays"] = static_cast<double>(sim.rays_per_image());
}
BENCHMARK(BM_SimulateP900)
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({1, 15})
    ->Args({2, 15})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
