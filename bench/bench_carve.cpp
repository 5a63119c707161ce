// Space carving speed and memory (thesis sec. 4.4.8; targets in the guide, sec. 6):
//   integrate one P900-like frame (768 beams, 0.5–7 m in 2.5 cm bins, 130° × 20°) into a 1 cm map
//   (thesis 500 ms single-threaded, target <= 66 ms on 2 cores); occlusion resolution per frame
//   (thesis 1 s, target <= 50 ms); peak memory for 1000 frames over a 3 × 3 × 3 m volume
//   (thesis up to 16 GB, target <= 1 GB and flat in the number of frames).
//
// The scene: the reference pillar (2 m base, sec. 4.5.1) 4 m in front of the sonar; the map's
// region of interest is the 3 × 3 × 3 m box around it.
//   bench_carve                       Google Benchmark timings
//   bench_carve --memory N [--no-roi] peak RSS while integrating N frames of orbits (own process)
//   bench_carve --ghosts DATASET [--roi x0 y0 z0 x1 y1 z1] [--threads T] [--out PREFIX]
//     ghost removal on a recorded dataset (issue 29: a P900-like open lattice): carves it, then
//     times the occlusion resolution (finalize) and the return explanation (drop_unexplained) per
//     frame, separately; with --out writes PREFIX_occlusion.ply and PREFIX_explained.ply.
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/visibility.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"

namespace {

using namespace sonar3d;
constexpr double kDeg = M_PI / 180.0;

Scene pillar_scene() {
  SceneObject obj;
  obj.name = "pillar";
  obj.mesh_world = make_reference_object("pillar");
  obj.reflectivity = 0.8;
  Scene s;
  s.objects.push_back(obj);
  return s;
}

Eigen::AlignedBox3d roi() {
  return Eigen::AlignedBox3d(Eigen::Vector3d(-1.5, -1.5, 0.0), Eigen::Vector3d(1.5, 1.5, 3.0));
}

SimulatorConfig sim_config() {
  SimulatorConfig c;
  c.elevation_step_rad = 0.05 * kDeg;  // coarser than the thesis' 0.01°: rendering is not timed
  return c;
}

// A vertical pass 4 m in front of the pillar, one frame per cm: 200 P900 frames, rendered once.
struct PassData {
  SonarSpec spec = sonar_preset("p900-130");
  std::vector<SonarImage> images;
  std::vector<Eigen::Isometry3d> poses;
  static const PassData& get() {
    static const PassData d = [] {
      PassData p;
      const Simulator sim(pillar_scene(), p.spec, sim_config());
      for (int k = 0; k < 200; ++k) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = Eigen::Vector3d(-4.0, 0.0, 0.3 + 0.01 * k);
        p.poses.push_back(T);
        p.images.push_back(sim.render(T, 100 + k));
      }
      return p;
    }();
    return d;
  }
};

CarveConfig config(int threads, bool use_roi) {
  CarveConfig c;
  c.voxel_size = 0.01;
  c.num_threads = threads;
  if (use_roi) c.region = roi();
  return c;
}

// One frame into an empty map: the worst case (every voxel of the wedge is new).
void BM_IntegrateColdP900(benchmark::State& state) {
  const PassData& d = PassData::get();
  const int threads = static_cast<int>(state.range(0));
  const bool use_roi = state.range(1) != 0;
  std::size_t k = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto carver = std::make_unique<Carver>(d.spec, config(threads, use_roi));
    state.ResumeTiming();
    carver->integrate(d.images[k % d.images.size()], d.poses[k % d.images.size()]);
    ++k;
    state.PauseTiming();
    carver.reset();
    state.ResumeTiming();
  }
  state.counters["ms/frame"] =
      benchmark::Counter(static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// Frames of a pass one after the other (the online case): the map already holds the free space
// that earlier frames carved.
void BM_IntegratePassP900(benchmark::State& state) {
  const PassData& d = PassData::get();
  const int threads = static_cast<int>(state.range(0));
  const bool use_roi = state.range(1) != 0;
  auto carver = std::make_unique<Carver>(d.spec, config(threads, use_roi));
  std::size_t k = 0;
  for (auto _ : state) {
    if (k == d.images.size()) {
      state.PauseTiming();
      carver = std::make_unique<Carver>(d.spec, config(threads, use_roi));
      k = 0;
      state.ResumeTiming();
    }
    carver->integrate(d.images[k], d.poses[k]);
    ++k;
  }
  state.counters["map_MB"] = carver->stats().map_bytes / 1e6;
}

// Occlusion resolution of the whole pass, reported per frame.
void BM_OcclusionPerFrameP900(benchmark::State& state) {
  const PassData& d = PassData::get();
  const int threads = static_cast<int>(state.range(0));
  Carver carver(d.spec, config(threads, true));
  for (std::size_t k = 0; k < d.images.size(); ++k) carver.integrate(d.images[k], d.poses[k]);
  std::size_t points = 0;
  for (auto _ : state) points = carver.finalize().size();
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * d.images.size()));
  state.counters["frames"] = static_cast<double>(d.images.size());
  state.counters["candidates"] = static_cast<double>(carver.stats().candidates);
  state.counters["points"] = static_cast<double>(points);
  state.counters["ms/frame"] =
      benchmark::Counter(static_cast<double>(state.iterations() * d.images.size()),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_IntegrateColdP900)
    ->ArgsProduct({{1, 2}, {1, 0}})
    ->ArgNames({"threads", "roi"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_IntegratePassP900)
    ->ArgsProduct({{1, 2}, {1, 0}})
    ->ArgNames({"threads", "roi"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_OcclusionPerFrameP900)
    ->Arg(1)
    ->Arg(2)
    ->ArgNames({"threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

// Peak memory: N frames of orbits around the pillar (radius 4 m, 100 frames a turn, heights
// 0.3–2.3 m), rendered on the fly so that only the carver keeps anything per frame.
int run_memory(int frames, bool use_roi) {
  const SonarSpec spec = sonar_preset("p900-130");
  const Simulator sim(pillar_scene(), spec, sim_config());
  Carver carver(spec, config(0, use_roi));
  const std::size_t rss0 = peak_rss_bytes();
  std::printf("frames  peak_RSS_MB  map_MB  frame_summaries_MB  integrate_ms/frame\n");
  const int per_turn = 100;
  double seconds = 0;
  for (int k = 0; k < frames; ++k) {
    const int turn = k / per_turn;
    const double z = 0.3 + 0.2 * (turn % 11);
    const Trajectory t = orbit(Eigen::Vector3d(0, 0, z), 4.0, per_turn, 0.0, 2 * M_PI, 0.0, 0.1);
    const Eigen::Isometry3d T = t.poses[k % per_turn];
    const SonarImage img = sim.render(T, 7 + k);
    const auto t0 = std::chrono::steady_clock::now();
    carver.integrate(img, T);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if ((k + 1) % 125 == 0 || k + 1 == frames) {
      const CarveStats& st = carver.stats();
      std::printf("%6d  %11.0f  %6.1f  %18.1f  %18.1f\n", k + 1, peak_rss_bytes() / 1e6,
                  st.map_bytes / 1e6, st.frame_bytes / 1e6, 1e3 * seconds / (k + 1));
      std::fflush(stdout);
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  const PointCloud cloud = carver.finalize();
  const double occ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf(
      "baseline RSS before carving %.0f MB (scene, simulator); after finalize: peak RSS "
      "%.0f MB, %zu candidates -> %zu points, occlusion %.1f ms/frame\n",
      rss0 / 1e6, peak_rss_bytes() / 1e6, carver.stats().candidates, cloud.size(),
      1e3 * occ / frames);
  return 0;
}

// Ghost removal on a dataset: integration, then occlusion resolution and return explanation
// timed apart (explanation off in the carver, then drop_unexplained() over its cloud with the
// carver's own occlusion settings, as finalize() runs it).
int run_ghosts(int argc, char** argv) {
  std::string dataset, out;
  CarveConfig c;
  c.voxel_size = 0.01;
  c.occlusion.explain_returns = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--ghosts" && a + 1 < argc) dataset = argv[++a];
    if (arg == "--out" && a + 1 < argc) out = argv[++a];
    if (arg == "--threads" && a + 1 < argc) c.num_threads = std::atoi(argv[++a]);
    if (arg == "--voxel" && a + 1 < argc) c.voxel_size = std::atof(argv[++a]);
    if (arg == "--roi" && a + 6 < argc) {
      double v[6];
      for (double& x : v) x = std::atof(argv[++a]);
      c.region =
          Eigen::AlignedBox3d(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
    }
  }
  const Dataset ds = read_dataset(dataset);
  Carver carver(ds.spec, c, ds.noise);
  auto now = [] { return std::chrono::steady_clock::now(); };
  // CPU time of the process (all threads): on a shared machine, wall time measures the others.
  auto cpu = [] {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  };
  auto t0 = now();
  double c0 = cpu();
  integrate_dataset(carver, ds, false);
  const double integrate = std::chrono::duration<double>(now() - t0).count();
  const double integrate_cpu = cpu() - c0;
  const double n = static_cast<double>(carver.frame_returns().size());
  t0 = now();
  c0 = cpu();
  const PointCloud resolved = carver.finalize();
  const double occlusion = std::chrono::duration<double>(now() - t0).count();
  const double occlusion_cpu = cpu() - c0;
  OcclusionConfig occ = c.occlusion;
  occ.voxel_size = c.voxel_size;
  occ.num_threads = c.num_threads;
  occ.min_intensity = std::max(occ.min_intensity, c.static_threshold);
  occ.explain_returns = true;
  std::size_t removed = 0;
  t0 = now();
  c0 = cpu();
  const PointCloud explained =
      drop_unexplained(resolved, carver.frame_returns(), ds.spec, occ, &removed);
  const double explain = std::chrono::duration<double>(now() - t0).count();
  const double explain_cpu = cpu() - c0;
  std::printf(
      "%s: %.0f frames, %zu candidates -> %zu points -> %zu after the explanation (%zu removed)\n"
      "wall, ms/frame: integrate %.1f; occlusion resolution %.1f; explanation %.1f; occlusion + "
      "explanation %.1f\n"
      "CPU (all threads), ms/frame: integrate %.1f; occlusion resolution %.1f; explanation %.1f; "
      "occlusion + explanation %.1f\npeak RSS %.0f MB\n",
      dataset.c_str(), n, carver.stats().candidates, resolved.size(), explained.size(), removed,
      1e3 * integrate / n, 1e3 * occlusion / n, 1e3 * explain / n, 1e3 * (occlusion + explain) / n,
      1e3 * integrate_cpu / n, 1e3 * occlusion_cpu / n, 1e3 * explain_cpu / n,
      1e3 * (occlusion_cpu + explain_cpu) / n, peak_rss_bytes() / 1e6);
  if (!out.empty()) {
    write_ply(out + "_occlusion.ply", resolved);
    write_ply(out + "_explained.ply", explained);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--ghosts") == 0) return run_ghosts(argc, argv);
    if (std::strcmp(argv[a], "--memory") == 0 && a + 1 < argc) {
      bool use_roi = true;
      for (int b = 1; b < argc; ++b) use_roi &= std::strcmp(argv[b], "--no-roi") != 0;
      return run_memory(std::atoi(argv[a + 1]), use_roi);
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
