// Carving memory is bounded by what was observed, not by the number of frames (issue 15): over an
// open structure, a second orbit adds frame summaries but no map leaves and no candidates, and
// occlusion resolution works per map leaf, not per candidate.
#include <gtest/gtest.h>

#include <cstdio>

#include "sonar3d/recon/carve.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"

using namespace sonar3d;

namespace {

constexpr double kDeg = M_PI / 180.0;

// An open frame 0.8 × 0.8 × 0.8 m of 5 cm members: four legs and a top ring.
Scene open_frame() {
  Scene scene;
  auto add = [&](double sx, double sy, double sz, double x, double y, double z) {
    SceneObject o;
    o.name = "member" + std::to_string(scene.objects.size());
    o.mesh_world = make_box(sx, sy, sz);
    o.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(x, y, z)));
    o.reflectivity = 0.8;
    scene.objects.push_back(o);
  };
  for (double x : {-0.375, 0.375})
    for (double y : {-0.375, 0.375}) add(0.05, 0.05, 0.8, x, y, 0.4);
  for (double x : {-0.375, 0.375}) add(0.05, 0.8, 0.05, x, 0, 0.775);
  for (double y : {-0.375, 0.375}) add(0.8, 0.05, 0.05, 0, y, 0.775);
  return scene;
}

SonarSpec spec20() {
  SonarSpec s;
  s.name = "test-20deg";
  s.set_uniform_bearings(40 * kDeg, 80);
  s.r_min = 1.0;
  s.r_max = 4.0;
  s.range_bins = 150;
  s.vertical_aperture_rad = 20 * kDeg;
  return s;
}

}  // namespace

TEST(CarveMemory, StaysFlatAsFramesAreAddedOverAnOpenStructure) {
  const SonarSpec spec = spec20();
  SimulatorConfig sc;
  sc.elevation_step_rad = 0.05 * kDeg;
  sc.gain = 2.0;
  const Simulator sim(open_frame(), spec, sc);
  CarveConfig cfg;
  cfg.voxel_size = 0.02;  // no region: only what the frames observe is stored
  Carver carver(spec, cfg);
  // Two orbits 2.5 m around the frame at mid height, the second shifted by half a step: new
  // views of the same volume.
  const int per_orbit = 48;
  std::vector<CarveStats> after;
  for (int loop = 0; loop < 2; ++loop) {
    const Trajectory orbit_t = sonar3d::orbit(Eigen::Vector3d(0, 0, 0.4), 2.5, per_orbit,
                                              loop * M_PI / per_orbit, 2 * M_PI, 0.0, 0.1);
    for (int k = 0; k < per_orbit; ++k) {
      carver.integrate(sim.render(orbit_t.poses[k], 10 + loop * per_orbit + k), orbit_t.poses[k]);
      if ((k + 1) % (per_orbit / 2) == 0) after.push_back(carver.stats());
    }
  }
  ASSERT_EQ(after.size(), 4u);
  for (const auto& s : after) {
    std::printf("%zu frames: %zu leaves, %zu candidate voxels, map %.2f MB, frames %.2f MB\n",
                s.frames, s.leaves, s.candidate_voxels, s.map_bytes / 1e6, s.frame_bytes / 1e6);
  }
  const CarveStats& one = after[1];  // one orbit
  const CarveStats& two = after[3];  // two orbits
  ASSERT_GT(one.candidate_voxels, 1000u);
  // The second orbit sees the same volume: (almost) no leaf and no candidate more (a new view
  // bounds a few voxels no earlier one had in its footprint: +0.3 % measured).
  EXPECT_LE(two.leaves, one.leaves + one.leaves / 50);
  EXPECT_LE(two.candidate_voxels, one.candidate_voxels + one.candidate_voxels / 50);
  EXPECT_LE(two.map_bytes, one.map_bytes + one.map_bytes / 20);
  // Frames cost their summary only.
  EXPECT_NEAR(static_cast<double>(two.frame_bytes) / two.frames,
              static_cast<double>(one.frame_bytes) / one.frames,
              0.05 * static_cast<double>(one.frame_bytes) / one.frames);

  // Occlusion resolution: a block (mask) per leaf holding candidates, not a point and a sort
  // entry per candidate (56+ bytes each before).
  const PointCloud cloud = carver.finalize();
  const CarveStats& fin = carver.stats();
  std::printf(
      "finalize: %zu candidates -> %zu points, occlusion working memory %.2f MB "
      "(%.1f B per candidate)\n",
      fin.candidates, fin.points, fin.occlusion_bytes / 1e6,
      static_cast<double>(fin.occlusion_bytes) / fin.candidates);
  EXPECT_GT(fin.points, 500u);
  EXPECT_LE(fin.occlusion_bytes, 400 * fin.leaves);
  EXPECT_LT(fin.occlusion_bytes, 16 * fin.candidates);
}
