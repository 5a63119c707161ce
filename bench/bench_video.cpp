// Google Benchmark: video texturing of a 1 M-triangle model with 1 MP frames (GUIDE target:
// >= 100 frames/s on 2 cores). The model: a 708 × 708-quad relief grid, 10 × 10 m (1.0 M
// triangles, 0.5 M vertices); the camera 1000 × 1000 px, 8 m above it looking down, seeing it
// all, so every vertex is projected and tested for visibility per frame. texel_m = 0: the colours
// go on the model's own vertices. range(0): threads; range(1): 1 = the visibility raster with
// Embree rays where it does not decide (the default), 0 = one Embree ray per vertex.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>

#include "../tests/relief_grid.hpp"
#include "sonar3d/video/texture.hpp"
#include "sonar3d/video/texture_mesh.hpp"

namespace {

// The benchmarks' relief: z = 0.2 · sin(1.3 x) · cos(0.9 y), n × n quads over size × size m.
sonar3d::TriangleMesh relief_grid(int n, double size) {
  return sonar3d::test::relief_grid(n, size, 0.2, 1.3, 0.9);
}

// One 1000 × 1000-pixel frame, 8 m above the model looking down (it sees all of it), added
// repeatedly; counters: frames/s, the model's and the textured mesh's triangles, the vertices
// seen and the share of visibility tests decided by Embree rays rather than the raster.
void run_texture(benchmark::State& state, const sonar3d::TriangleMesh& mesh, double texel_m,
                 const Eigen::Isometry3d& T_world_camera) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  sonar3d::MeshTextureConfig cfg;
  cfg.texel_m = texel_m;
  cfg.raster_visibility = state.range(1) != 0;
  sonar3d::MeshTexturer texturer(mesh, cfg);
  sonar3d::CameraIntrinsics cam;
  cam.width = cam.height = 1000;
  cam.fx = cam.fy = 800;
  cam.cx = cam.cy = 499.5;
  sonar3d::RgbImage img;
  img.width = img.height = 1000;
  img.rgb.assign(3u * 1000 * 1000, 0.5f);
  std::size_t coloured = 0;
  for (auto _ : state) {
    coloured = texturer.add(sonar3d::CameraView{cam, T_world_camera, &img});
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  state.counters["occluder_triangles"] = static_cast<double>(mesh.triangles.size());
  state.counters["textured_triangles"] = static_cast<double>(texturer.mesh().triangles.size());
  state.counters["vertices_seen"] = static_cast<double>(coloured);
  const double tests = static_cast<double>(texturer.raster_decided() + texturer.rays_cast());
  state.counters["ray_share"] = tests > 0 ? static_cast<double>(texturer.rays_cast()) / tests : 0;
}

// 8 m above the model looking down: it sees all of it.
Eigen::Isometry3d looking_down() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();  // +z_cam = −z_world
  T.translation() = Eigen::Vector3d(0, 0, 8);
  return T;
}

// 1.5 m above the model's edge looking across it, 20° down (as from a vehicle's forward camera):
// part of the model in view, much of it behind the camera or beside the frame, triangles of the
// near part crossing the near plane or covering many pixels.
Eigen::Isometry3d oblique_low() {
  const Eigen::Vector3d eye(-5.5, 0, 1.5), forward(std::cos(0.35), 0, -std::sin(0.35));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;                 // x_cam: right
  T.linear().col(1) = forward.cross(right);  // y_cam: down in the image
  T.linear().col(2) = forward;               // z_cam: the optical axis
  T.translation() = eye;
  return T;
}

// range(0): threads 1 and 2; range(1): 0 = an Embree ray per vertex, 1 = the raster first.
void threads_and_visibility(benchmark::internal::Benchmark* b) {
  for (int raster : {0, 1}) {
    for (int threads : {1, 2}) b->Args({threads, raster});
  }
  b->Unit(benchmark::kMillisecond)->UseRealTime();
}

void BM_TextureMesh1MTriangles1MP(benchmark::State& state) {
  run_texture(state, relief_grid(708, 10.0), 0, looking_down());
}
BENCHMARK(BM_TextureMesh1MTriangles1MP)->Apply(threads_and_visibility);

// The same model from a low oblique camera: a frame of a survey rather than an overview.
void BM_TextureMesh1MTrianglesOblique1MP(benchmark::State& state) {
  run_texture(state, relief_grid(708, 10.0), 0, oblique_low());
}
BENCHMARK(BM_TextureMesh1MTrianglesOblique1MP)->Apply(threads_and_visibility);

// The registered-CAD case of thesis sec. 6.4: a coarse model (a 90 × 90-quad relief grid, 16 200
// triangles, as a CAD model has) subdivided to the texel size for its colours: 1.04 M textured
// triangles (0.52 M vertices), while visibility is tested against the model as given. Same camera
// and frame. range(0): threads; range(1): raster visibility.
void BM_TextureCadModel1MTexelTriangles1MP(benchmark::State& state) {
  // three subdivision levels (0.157 m diagonals to 2 cm): 16 200 × 64 triangles
  run_texture(state, relief_grid(90, 10.0), 0.02, looking_down());
}
BENCHMARK(BM_TextureCadModel1MTexelTriangles1MP)->Apply(threads_and_visibility);

// Colouring a sonar point cloud (texture_cloud, what `sonar3d texture CLOUD.ply` runs): 1 M points
// on a relief `size` m square (spacing size/1000), one frame. range(0): threads.
void run_texture_cloud(benchmark::State& state, double size, const sonar3d::CameraIntrinsics& cam,
                       const Eigen::Isometry3d& T_world_camera) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  sonar3d::PointCloud cloud;
  const int n = 1000;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = size * (double(i) / n - 0.5), y = size * (double(j) / n - 0.5);
      cloud.points.emplace_back(x, y, 0.2 * std::sin(1.3 * x) * std::cos(0.9 * y));
    }
  }
  sonar3d::TextureConfig cfg;
  cfg.point_spacing_m = size / n;
  sonar3d::CloudTexturer texturer(cloud, cfg);
  sonar3d::RgbImage img;
  img.width = cam.width;
  img.height = cam.height;
  img.rgb.assign(3u * cam.width * cam.height, 0.5f);
  std::size_t coloured = 0;
  for (auto _ : state) {
    coloured = texturer.add(sonar3d::CameraView{cam, T_world_camera, &img});
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  state.counters["points"] = static_cast<double>(cloud.size());
  state.counters["points_coloured"] = static_cast<double>(coloured);
}

// 1 M points 10 m square (1 cm apart) seen whole by a 1 MP camera 8 m above.
void BM_TextureCloud1MPoints1MP(benchmark::State& state) {
  sonar3d::CameraIntrinsics cam;
  cam.width = cam.height = 1000;
  cam.fx = cam.fy = 800;
  cam.cx = cam.cy = 499.5;
  run_texture_cloud(state, 10.0, cam, looking_down());
}
BENCHMARK(BM_TextureCloud1MPoints1MP)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// A survey's frame: 1 M points on a 40 m square (4 cm apart), a 640 × 480 camera 3 m above it
// seeing a 4.4 × 3.3 m patch (about 1 % of the points): the cost of the points out of view.
void BM_TextureCloudSurveyFrame(benchmark::State& state) {
  sonar3d::CameraIntrinsics cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = cam.fy = 440;
  cam.cx = 319.5;
  cam.cy = 239.5;
  Eigen::Isometry3d T = looking_down();
  T.translation() = Eigen::Vector3d(5, 3, 3);
  run_texture_cloud(state, 40.0, cam, T);
}
BENCHMARK(BM_TextureCloudSurveyFrame)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
