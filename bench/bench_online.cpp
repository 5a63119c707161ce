// Online map latency (issue 25 item 4, docs/online.md): P900-like frames (768 beams, 0.5–7 m in
// 2.5 cm bins, 130° × 20°) pushed at 15 Hz from a vehicle moving at 1 m/s, 3 m above a seabed
// with the reference objects laid along the track, looking forward and down 30°; a 2 cm map above
// the seabed (region z in [-0.05, 2.5] m, as the demo's seabed prior). Frames are rendered first
// (not timed); then each frame is pushed (denoise + carve) and, every --query-every frames, the
// cloud is queried (incremental occlusion resolution + assembly). Per frame: the push time, plus
// the query time on the frames that query. Reports median / p95 / max and whether 15 Hz is kept (a
// frame's work within 1/15 s).
//   bench_online [--frames N] [--query-every Q] [--voxel V] [--window W] [--threads T]
//                [--speed M_PER_S] [--rate HZ]
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/mapping/online.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/sim/simulator.hpp"

namespace {

using namespace sonar3d;
constexpr double kDeg = M_PI / 180.0;

// CPU time of the process (all threads), ms: on a shared machine the wall time depends on the
// other jobs, the CPU time much less.
double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(
      std::min<double>(static_cast<double>(v.size() - 1), std::ceil(q * v.size()) - 1));
  return v[k];
}

Scene survey_scene(double length) {
  Scene s;
  SceneObject bed;
  bed.name = "seabed";
  bed.kind = ObjectKind::Terrain;
  bed.mesh_world.vertices = {{-10.0f, -15.0f, 0.0f},
                             {static_cast<float>(length + 10), -15.0f, 0.0f},
                             {static_cast<float>(length + 10), 15.0f, 0.0f},
                             {-10.0f, 15.0f, 0.0f}};
  bed.mesh_world.triangles = {{0, 1, 2}, {0, 2, 3}};
  bed.reflectivity = 0.3;
  s.objects.push_back(bed);
  // The reference objects every 4 m along the track, alternating sides.
  const auto names = reference_object_names();
  int k = 0;
  for (double x = 4; x < length; x += 4, ++k) {
    SceneObject o;
    o.name = names[static_cast<std::size_t>(k) % names.size()];
    o.mesh_world = make_reference_object(o.name);
    o.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(x, (k % 2 ? 1.5 : -1.5), 0.0)));
    o.reflectivity = 0.8;
    s.objects.push_back(o);
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 300, query_every = 15, threads = 0;
  double voxel = 0.02, window = 0, speed = 1.0, rate = 15.0;
  for (int a = 1; a + 1 < argc; a += 2) {
    const std::string k = argv[a];
    const char* v = argv[a + 1];
    if (k == "--frames") {
      frames = std::atoi(v);
    } else if (k == "--query-every") {
      query_every = std::atoi(v);
    } else if (k == "--voxel") {
      voxel = std::atof(v);
    } else if (k == "--window") {
      window = std::atof(v);
    } else if (k == "--threads") {
      threads = std::atoi(v);
    } else if (k == "--speed") {
      speed = std::atof(v);
    } else if (k == "--rate") {
      rate = std::atof(v);
    } else {
      std::fprintf(stderr, "unknown option %s\n", k.c_str());
      return 2;
    }
  }
  const SonarSpec spec = sonar_preset("p900-130");
  const double step = speed / rate;
  const double length = frames * step + 8;
  SimulatorConfig sc;
  sc.elevation_step_rad = 0.05 * kDeg;  // rendering is not timed
  sc.gain = 2.0;
  const Simulator sim(survey_scene(length), spec, sc);
  std::vector<SonarImage> images;
  std::vector<Eigen::Isometry3d> poses;
  const Eigen::Matrix3d down = Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitY()).matrix();
  std::fprintf(stderr, "rendering %d frames...\n", frames);
  for (int k = 0; k < frames; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = down;
    T.translation() = Eigen::Vector3d(k * step, 0.2 * std::sin(0.02 * k), 3.0);
    poses.push_back(T);
    images.push_back(sim.render(T, 11 + k));
  }
  OnlineMapConfig oc;
  oc.carve.voxel_size = voxel;
  oc.carve.num_threads = threads;
  oc.carve.region =
      Eigen::AlignedBox3d(Eigen::Vector3d(-20, -20, -0.05), Eigen::Vector3d(length + 20, 20, 2.5));
  oc.window_m = window;
  OnlineMapper map(spec, oc);
  std::vector<double> push_ms, query_ms, frame_ms, push_cpu, query_cpu;
  std::size_t redone = 0, context = 0, used_frames = 0, queries = 0;
  for (int k = 0; k < frames; ++k) {
    const double c0 = cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    map.push_frame(k / rate, images[static_cast<std::size_t>(k)],
                   poses[static_cast<std::size_t>(k)]);
    const auto t1 = std::chrono::steady_clock::now();
    const double c1 = cpu_ms();
    push_cpu.push_back(c1 - c0);
    double q = 0;
    if (query_every > 0 && (k + 1) % query_every == 0) {
      const PointCloud c = map.cloud();
      q = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
      query_cpu.push_back(cpu_ms() - c1);
      query_ms.push_back(q);
      const OnlineMapStats st = map.stats();
      redone += st.last_resolve.blocks;
      context += st.last_resolve.context;
      used_frames += st.last_resolve.frames;
      ++queries;
    }
    const double p = std::chrono::duration<double, std::milli>(t1 - t0).count();
    push_ms.push_back(p);
    frame_ms.push_back(p + q);
  }
  const OnlineMapStats st = map.stats();
  double push_cpu_sum = 0, query_cpu_sum = 0;
  for (double v : push_cpu) push_cpu_sum += v;
  for (double v : query_cpu) query_cpu_sum += v;
  double push_sum = 0, query_sum = 0;
  for (double v : push_ms) push_sum += v;
  for (double v : query_ms) query_sum += v;
  const double budget = 1000.0 / rate;
  std::size_t over = 0;
  for (double v : frame_ms) over += v > budget;
  std::printf(
      "P900-like frames at %.0f Hz, %.2f m/frame, voxel %.3f m, threads %d, window %.1f m, "
      "query every %d frames, %d frames\n",
      rate, step, voxel, threads, window, query_every, frames);
  std::printf("push_frame (denoise + carve): median %.1f ms, p95 %.1f ms, max %.1f ms\n",
              quantile(push_ms, 0.5), quantile(push_ms, 0.95), quantile(push_ms, 1.0));
  if (!query_ms.empty()) {
    std::printf(
        "cloud() (incremental resolution + assembly): median %.1f ms, p95 %.1f ms, max "
        "%.1f ms; per query on average %.0f blocks redone of %.0f projected, against %.0f "
        "frames\n",
        quantile(query_ms, 0.5), quantile(query_ms, 0.95), quantile(query_ms, 1.0),
        static_cast<double>(redone) / queries, static_cast<double>(context) / queries,
        static_cast<double>(used_frames) / queries);
  }
  std::printf(
      "per frame (push + its query): median %.1f ms, p95 %.1f ms, max %.1f ms; "
      "%zu of %d frames over the %.1f ms budget; mean work %.1f ms/frame (%.0f %% of "
      "real time)\n",
      quantile(frame_ms, 0.5), quantile(frame_ms, 0.95), quantile(frame_ms, 1.0), over, frames,
      budget, (push_sum + query_sum) / frames, 100 * (push_sum + query_sum) / frames / budget);
  std::printf(
      "CPU time (all threads): push median %.1f ms, p95 %.1f ms; query median %.1f ms; "
      "mean %.1f ms of CPU per frame\n",
      quantile(push_cpu, 0.5), quantile(push_cpu, 0.95), quantile(query_cpu, 0.5),
      (push_cpu_sum + query_cpu_sum) / frames);
  std::printf("map: %zu points, %zu leaves, %.1f MB grids + %.1f MB frames, %zu frames kept\n",
              st.points, st.leaves, st.map_bytes / 1e6, st.frame_bytes / 1e6, st.frames_kept);
  return 0;
}
