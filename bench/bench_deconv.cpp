// Deconvolution (thesis ch. 5) benchmarks and a small measurement driver.
//
// Benchmarks: a 128-frame ARIS-like pass (preset aris3000: 128 beams × 341 bins, 14°, 0.67–1.66 m)
// over a 40 cm sphere and a seabed (seen by the lowest frames), 1 cm spacing, deconvolved in memory
// or from a dataset on disk (read + denoise + solve). Thesis: 15 s single-threaded (sec. 5.6.8);
// target ≤ 1 s on 2 cores.
//   bench_deconv [--benchmark_filter=...]
//
// Driver (CLI-independent quality runs, docs/deconvolution.md):
//   bench_deconv run DATASET -o cloud.ply [--lambda F] [--beam sinc|flat|sensor] [--exact]
//       [--no-dering] [--occlusion] [--kernel plain|normal|occlusion|normal+occlusion]
//       [--min-relative F] [--ignore-shadows|--keep-shadows] [--no-occlusion]
//       [--max-extrapolation M] [--max-range M] [--threads N] [--exact-lambertian]
//       [--exact-block-tolerance|--exact-plane-tolerance] [--exact-tolerance F]
//       [--exact-sweeps N] [--exact-range-subsamples N] [--subsamples N]
//       [--min-intensity F] [--layer-spacing M] [--report report.json]
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <random>
#include <string>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/sim/noise.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"

namespace {

using namespace sonar3d;
constexpr double kDeg = M_PI / 180.0;

// variant 0: noise-free; 1: stripe noise then Z-test denoising (realistic); 2: the same noise
// without denoising (every column non-empty: the worst case for the solver).
struct ArisPass {
  SonarSpec spec;
  std::vector<SonarImage> frames;
  std::vector<Eigen::Isometry3d> poses;
  std::optional<NoiseImages> noise;
  std::vector<SonarImage> raw;  // before denoising (variant 1: for the on-disk dataset)
};

const ArisPass& aris_pass(int variant) {
  static std::map<int, ArisPass> cache;
  auto it = cache.find(variant);
  if (it != cache.end()) return it->second;
  ArisPass p;
  p.spec = sonar_preset("aris3000");
  Scene scene;
  SceneObject sphere;
  sphere.name = "sphere";
  sphere.mesh_world = make_sphere(0.2, 64);
  sphere.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(1.15, 0.0, 0.0)));
  sphere.reflectivity = 0.8;
  scene.objects.push_back(sphere);
  SceneObject bed;
  bed.name = "seabed";
  bed.mesh_world = make_plane(4.0, 4.0);
  bed.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(1.5, 0.0, -0.75)));
  bed.reflectivity = 0.5;
  scene.objects.push_back(bed);
  SimulatorConfig sc;
  sc.elevation_step_rad = 0.02 * kDeg;
  Simulator sim(scene, p.spec, sc);
  std::mt19937_64 rng(17);
  if (variant > 0) p.noise = stripe_noise_images(p.spec, StripeNoiseConfig());
  for (int k = 0; k < 128; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.0, 0.0, -0.635 + 0.01 * k);
    p.poses.push_back(T);
    SonarImage im = sim.render(T, 100 + k);
    if (p.noise) add_noise(im, *p.noise, rng);
    p.raw.push_back(im);
    if (variant == 1) denoise(im, p.noise, DenoiseConfig());
    p.frames.push_back(std::move(im));
  }
  return cache.emplace(variant, std::move(p)).first->second;
}

void BM_DeconvAris(benchmark::State& state) {
  const ArisPass& p = aris_pass(static_cast<int>(state.range(0)));
  DeconvConfig cfg;
  cfg.num_threads = static_cast<int>(state.range(1));
  cfg.exact = state.range(2) != 0;
  cfg.lambda_fraction = state.range(3) / 100.0;
  DeconvReport rep;
  for (auto _ : state) {
    benchmark::DoNotOptimize(deconvolve_frames(p.frames, p.poses, p.spec, cfg, &rep));
  }
  state.counters["points"] = static_cast<double>(rep.points);
  state.counters["columns"] = static_cast<double>(rep.passes.at(0).columns_solved);
  state.counters["solve_s"] = rep.seconds_solve;
  state.counters["dering_s"] = rep.seconds_dering;
}
// Args: noise variant, threads, exact, λ in % of λ_max.
BENCHMARK(BM_DeconvAris)
    ->ArgNames({"noise", "threads", "exact", "lambda%"})
    ->Args({0, 1, 0, 0})
    ->Args({0, 2, 0, 0})
    ->Args({1, 1, 0, 0})
    ->Args({1, 2, 0, 0})
    ->Args({1, 2, 0, 50})
    ->Args({2, 2, 0, 0})
    ->Args({1, 2, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

// End to end from disk: read 128 PNG frames, Z-test denoise, deconvolve.
void BM_DeconvArisDataset(benchmark::State& state) {
  static std::filesystem::path dir;
  if (dir.empty()) {
    const ArisPass& p = aris_pass(1);
    dir = std::filesystem::temp_directory_path() / "sonar3d_bench_deconv_aris";
    std::filesystem::remove_all(dir);
    DatasetWriter w(dir, p.spec);
    Trajectory nav;
    for (std::size_t k = 0; k < p.raw.size(); ++k) {
      SonarImage im = p.raw[k];
      im.timestamp = 0.1 * k;  // on the navigation clock
      w.add_frame(im);
      nav.push_back(0.1 * k, p.poses[k]);
    }
    w.set_navigation(nav);
    w.set_noise(*p.noise);
    w.commit();
  }
  const Dataset ds = read_dataset(dir);
  DeconvConfig cfg;
  cfg.num_threads = static_cast<int>(state.range(0));
  DeconvReport rep;
  for (auto _ : state) {
    benchmark::DoNotOptimize(deconvolve_dataset(ds, cfg, false, &rep));
  }
  state.counters["points"] = static_cast<double>(rep.points);
  state.counters["load_s"] = rep.seconds_load;
  state.counters["solve_s"] = rep.seconds_solve;
}
BENCHMARK(BM_DeconvArisDataset)
    ->ArgNames({"threads"})
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

// ---------------------------------------------------------------------------------------------
// SonarSpec::beam_of_bearing, called per point and frame by de-ringing and occlusion resolution
// (seen_free). Arg: beams of a uniform table (128: aris3000, 768: p900-130). The reference is
// the previous implementation, which tested uniform_bearings() (O(beams)) on every call.

int beam_of_bearing_scan(const SonarSpec& s, double phi) {
  const int n = s.beams();
  if (n == 0 || !(phi >= s.fov_min()) || !(phi < s.fov_max())) return -1;
  if (s.uniform_bearings() && n > 1) {
    const double lo = s.fov_min();
    const double w = (s.fov_max() - lo) / n;
    return std::clamp(static_cast<int>((phi - lo) / w), 0, n - 1);
  }
  const auto it = std::lower_bound(s.bearings_rad.begin(), s.bearings_rad.end(), phi);
  int j = static_cast<int>(it - s.bearings_rad.begin());
  if (j == n) return n - 1;
  if (j > 0 && phi - s.bearings_rad[j - 1] < s.bearings_rad[j] - phi) --j;
  return j;
}

template <bool kScan>
void BM_BeamOfBearing(benchmark::State& state) {
  SonarSpec s;
  s.set_uniform_bearings(60 * kDeg, static_cast<int>(state.range(0)));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(s.fov_min(), s.fov_max());
  std::vector<double> phis(4096);
  for (double& p : phis) p = u(rng);
  std::size_t i = 0;
  for (auto _ : state) {
    const double phi = phis[i++ & 4095];
    benchmark::DoNotOptimize(kScan ? beam_of_bearing_scan(s, phi) : s.beam_of_bearing(phi));
  }
}
BENCHMARK(BM_BeamOfBearing<false>)->Name("BM_BeamOfBearing")->Arg(128)->Arg(768);
BENCHMARK(BM_BeamOfBearing<true>)->Name("BM_BeamOfBearing_PreviousScan")->Arg(128)->Arg(768);

// ---------------------------------------------------------------------------------------------
// Driver

int run_driver(int argc, char** argv) {
  std::string dataset, out, report;
  DeconvConfig cfg;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw Error("option " + a + " needs a value");
      return argv[++i];
    };
    if (a == "-o") {
      out = next();
    } else if (a == "--lambda") {
      cfg.lambda_fraction = std::stod(next());
    } else if (a == "--beam") {
      cfg.beam = DeconvConfig::parse_beam(next());
    } else if (a == "--exact") {
      cfg.exact = true;
    } else if (a == "--no-dering") {
      cfg.dering = false;
    } else if (a == "--occlusion") {
      cfg.resolve_occlusions = true;
    } else if (a == "--no-occlusion") {
      cfg.resolve_occlusions = false;
    } else if (a == "--kernel") {
      cfg.kernel = DeconvConfig::parse_kernel(next());
    } else if (a == "--min-relative") {
      cfg.min_relative_intensity = std::stod(next());
    } else if (a == "--ignore-shadows") {
      cfg.ignore_shadowed_zeros = true;
    } else if (a == "--keep-shadows") {
      cfg.ignore_shadowed_zeros = false;
    } else if (a == "--max-extrapolation") {
      cfg.max_extrapolation = std::stod(next());
    } else if (a == "--max-range") {
      cfg.max_range = std::stod(next());
    } else if (a == "--exact-lambertian") {
      cfg.exact = true;
      cfg.exact_lambertian = true;
    } else if (a == "--exact-block-tolerance") {
      cfg.exact_block_tolerance = true;
    } else if (a == "--exact-plane-tolerance") {
      cfg.exact_block_tolerance = false;
    } else if (a == "--exact-tolerance") {
      cfg.exact_tolerance = std::stod(next());
    } else if (a == "--exact-sweeps") {
      cfg.exact_max_sweeps = std::stoi(next());
    } else if (a == "--exact-range-subsamples") {
      cfg.exact_range_subsamples = std::stoi(next());
    } else if (a == "--subsamples") {
      cfg.subsamples = std::stoi(next());
    } else if (a == "--min-intensity") {
      cfg.min_intensity = std::stod(next());
    } else if (a == "--layer-spacing") {
      cfg.layer_spacing = std::stod(next());
    } else if (a == "--threads") {
      cfg.num_threads = std::stoi(next());
    } else if (a == "--report") {
      report = next();
    } else if (!a.empty() && a[0] != '-' && dataset.empty()) {
      dataset = a;
    } else {
      throw Error("unknown option '" + a + "'");
    }
  }
  if (dataset.empty() || out.empty())
    throw Error("usage: bench_deconv run DATASET -o cloud.ply [options]");
  const Dataset ds = read_dataset(dataset);
  DeconvReport rep;
  const PointCloud cloud = deconvolve_dataset(ds, cfg, true, &rep);
  write_ply(out, cloud);
  std::cout << rep.to_text();
  if (!report.empty()) write_text_file(report, rep.to_json() + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "run") == 0) {
    try {
      return run_driver(argc, argv);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
      return 1;
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
