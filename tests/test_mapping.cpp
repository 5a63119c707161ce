// mapping: elevation maps (sec. 6.2.1), GeoTIFF round trips, swath registration (sec. 6.2.2.1,
// eq. 6.1–6.2) and the global adjustment of swath offsets.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <tuple>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "sonar3d/sim/dead_reckoning.hpp"
#include "sonar3d/sim/terrain.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using sonar3d::ElevationMap;
using sonar3d::read_text_file;
using sonar3d::SwathTie;

namespace {

fs::path temp_dir() {
  const fs::path d =
      fs::temp_directory_path() / ("sonar3d_test_mapping_" + std::to_string(getpid()));
  fs::create_directories(d);
  return d;
}

// A seabed with relief: smooth hills, a trench 30 cm deep running north-east, and rocks. Height
// z at world (x, y), m.
double terrain(double x, double y) {
  double z = 0.25 * std::sin(0.7 * x) * std::cos(0.5 * y) + 0.1 * std::sin(1.9 * x + 1.3 * y);
  const double d = (x - y) / std::sqrt(2.0);  // distance across the trench
  z -= 0.3 * std::exp(-d * d / (2 * 0.2 * 0.2));
  const double rocks[][3] = {{1.2, 0.7, 0.15}, {3.1, 2.2, 0.2}, {0.4, 3.3, 0.12}, {2.5, 0.3, 0.18}};
  for (const auto& r : rocks) {
    const double q = (x - r[0]) * (x - r[0]) + (y - r[1]) * (y - r[1]);
    z += r[2] * std::exp(-q / (2 * 0.08 * 0.08));
  }
  return z;
}

// A map of `f` over [x0, x0 + cols·c) × (y_top − rows·c, y_top], seen by a vehicle whose
// navigation is off by `nav_error`: the map lands at true position + nav_error.
template <typename F>
ElevationMap make_map(F f, double x0, double y_top, int rows, int cols, double c,
                      const Eigen::Vector3d& nav_error = Eigen::Vector3d::Zero(), double noise = 0,
                      unsigned seed = 1) {
  ElevationMap m;
  m.cell_m = c;
  m.rows = rows;
  m.cols = cols;
  m.origin_xy = {x0, y_top};
  m.z.resize(static_cast<std::size_t>(rows) * cols);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise > 0 ? noise : 1);
  for (int r = 0; r < rows; ++r) {
    for (int col = 0; col < cols; ++col) {
      const Eigen::Vector2d p = m.cell_center_xy(r, col);
      // The cell at logged position p saw the terrain at the true position p − nav_error.
      m.at(r, col) = static_cast<float>(f(p.x() - nav_error.x(), p.y() - nav_error.y()) +
                                        nav_error.z() + (noise > 0 ? n(rng) : 0.0));
    }
  }
  return m;
}

}  // namespace

TEST(ElevationMap, HighestPointPerCellAndNoData) {
  sonar3d::PointCloud cloud;
  cloud.points = {{0.01f, 0.01f, -1.0f}, {0.015f, 0.005f, -0.5f}, {0.09f, 0.01f, 2.0f}};
  sonar3d::ElevationMapConfig cfg;
  cfg.cell_m = 0.02;
  const ElevationMap m = sonar3d::elevation_map_from_points(cloud, cfg);
  ASSERT_EQ(m.rows, 1);
  ASSERT_EQ(m.cols, 5);                    // x from 0.01 to 0.09: cells [0, 0.02) ... [0.08, 0.1)
  EXPECT_DOUBLE_EQ(m.origin_xy.x(), 0.0);  // corners on the world grid
  EXPECT_DOUBLE_EQ(m.origin_xy.y(), 0.02);
  EXPECT_FLOAT_EQ(m.at(0, 0), -0.5f);  // the highest of the two points in the first cell
  EXPECT_FALSE(m.valid(0, 1));
  EXPECT_FALSE(m.valid(0, 2));
  EXPECT_FALSE(m.valid(0, 3));
  EXPECT_FLOAT_EQ(m.at(0, 4), 2.0f);
  EXPECT_EQ(m.num_valid(), 2u);
  // Row 0 is the northern edge: a point further north lands in a row above.
  cloud.points.push_back({0.01f, 0.2f, 0.0f});
  const ElevationMap m2 = sonar3d::elevation_map_from_points(cloud, cfg);
  EXPECT_FLOAT_EQ(m2.at(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(m2.at(m2.rows - 1, 0), -0.5f);
}

TEST(ElevationMap, BadInputsGiveClearErrors) {
  sonar3d::ElevationMapConfig cfg;
  sonar3d::PointCloud empty;
  EXPECT_THROW(sonar3d::elevation_map_from_points(empty, cfg), sonar3d::Error);
  cfg.cell_m = 0;
  sonar3d::PointCloud one;
  one.points = {{0, 0, 0}};
  try {
    sonar3d::elevation_map_from_points(one, cfg);
    FAIL() << "a resolution of 0 must be refused";
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cell_m"), std::string::npos) << e.what();
  }
  cfg.cell_m = 1e-6;  // 1 km at 1 µm: refused before allocating
  one.points.push_back({1000, 1000, 0});
  try {
    sonar3d::elevation_map_from_points(one, cfg);
    FAIL() << "an absurd map size must be refused";
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("max_cells"), std::string::npos) << e.what();
  }
  cfg.cell_m = 0.02;
  one.points.push_back({NAN, 0, 0});
  EXPECT_THROW(sonar3d::elevation_map_from_points(one, cfg), sonar3d::Error);
}

TEST(ElevationMap, GeoTiffRoundTripFloatAndUInt16) {
  ElevationMap m = make_map(terrain, 10.0, 20.0, 60, 80, 0.02);
  for (int c = 0; c < 10; ++c) m.at(5, c) = ElevationMap::kNoData;
  const fs::path dir = temp_dir();
  const std::string f32 = (dir / "map_f32.tif").string(), u16 = (dir / "map_u16.tif").string();
  sonar3d::write_elevation_geotiff(f32, m);
  sonar3d::ElevationWriteOptions q;
  q.uint16_step_m = 0.001;
  sonar3d::write_elevation_geotiff(u16, m, q);
  for (const auto& [path, tol] : {std::pair{f32, 0.0}, std::pair{u16, 0.0005 + 1e-6}}) {
    SCOPED_TRACE(path);
    const ElevationMap r = sonar3d::read_elevation_geotiff(path);
    ASSERT_EQ(r.rows, m.rows);
    ASSERT_EQ(r.cols, m.cols);
    EXPECT_DOUBLE_EQ(r.cell_m, m.cell_m);
    EXPECT_NEAR(r.origin_xy.x(), 10.0, 1e-12);
    EXPECT_NEAR(r.origin_xy.y(), 20.0, 1e-12);
    EXPECT_EQ(r.num_valid(), m.num_valid());
    double worst = 0;
    for (std::size_t i = 0; i < m.z.size(); ++i) {
      if (m.z[i] == m.z[i])
        worst = std::max(worst, std::abs(double(r.z[i]) - m.z[i]));
      else
        EXPECT_FALSE(r.z[i] == r.z[i]) << i;
    }
    EXPECT_LE(worst, tol);
  }
  // Quantised is smaller (the thesis' point: 7 MB of cloud -> 780 kB of map at 2 cm).
  EXPECT_LT(fs::file_size(u16), fs::file_size(f32));
  // A PNG with the colour bar, and no file left behind under a temporary name.
  const Eigen::Vector2f range = sonar3d::write_elevation_png((dir / "map.png").string(), m);
  EXPECT_LT(range.x(), range.y());
  EXPECT_GT(fs::file_size(dir / "map.png"), 1000u);
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 3);
  // Not a raster: one clear error naming the file.
  const std::string bad = (dir / "bad.tif").string();
  {
    std::FILE* f = std::fopen(bad.c_str(), "w");
    std::fputs("not a tiff", f);
    std::fclose(f);
  }
  try {
    sonar3d::read_elevation_geotiff(bad);
    FAIL();
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.tif"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Known shifts and depth offsets between two overlapping swaths are recovered exactly (at cell
// resolution), whatever their sign.
TEST(SwathRegistration, RecoversKnownShiftsAndDepthOffsetsExactly) {
  const double c = 0.02;
  const ElevationMap a = make_map(terrain, 0.0, 4.0, 200, 150, c);  // x 0–3 m, y 0–4 m
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.3;
  cfg.subcell = false;
  const Eigen::Vector3d errors[] = {
      {0.10, -0.06, 0.05}, {-0.2, 0.14, -0.12}, {0, 0, 0}, {0.3, 0.3, 0.3}};
  // The thesis' exhaustive search (coarse_factor 1) and the coarse-to-fine one find the same.
  for (bool subcell : {false, true})
    for (int f : {1, 4})
      for (const Eigen::Vector3d& e : errors) {
        cfg.subcell = subcell;
        cfg.coarse_factor = f;
        SCOPED_TRACE("subcell " + std::to_string(subcell) + ", coarse_factor " + std::to_string(f) +
                     ", error " + std::to_string(e.x()) + " " + std::to_string(e.y()) + " " +
                     std::to_string(e.z()));
        // Swath B overlaps half of A (x 1.5–4.5 m) and was logged with navigation error e.
        const ElevationMap b = make_map(terrain, 1.5, 4.0, 200, 150, c, e);
        const SwathTie t = sonar3d::register_elevation_maps(a, b, cfg);
        // Moving B onto A undoes the error.
        EXPECT_NEAR(t.t.x(), -e.x(), 1e-9);
        EXPECT_NEAR(t.t.y(), -e.y(), 1e-9);
        EXPECT_NEAR(t.t.z(), -e.z(), 1e-5);
        EXPECT_LT(t.score_m, 1e-5);
        EXPECT_GT(t.confidence, 0.5);
      }
}

TEST(SwathRegistration, SubCellShiftsWithNoise) {
  const double c = 0.02;
  const ElevationMap a = make_map(terrain, 0.0, 4.0, 200, 150, c, {0, 0, 0}, 0.005, 1);
  const Eigen::Vector3d e(0.071, -0.043, 0.02);  // 3.55 and −2.15 cells
  const ElevationMap b = make_map(terrain, 1.5, 4.0, 200, 150, c, e, 0.005, 2);
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.2;
  const SwathTie t = sonar3d::register_elevation_maps(a, b, cfg);
  EXPECT_NEAR(t.t.x(), -e.x(), 0.25 * c);  // integer search alone: up to 0.5 c
  EXPECT_NEAR(t.t.y(), -e.y(), 0.25 * c);
  EXPECT_NEAR(t.t.z(), -e.z(), 0.005);
}

// A flat, featureless overlap (noise only) gives a low-confidence tie, never a confident shift.
TEST(SwathRegistration, FlatOverlapGivesLowConfidence) {
  auto flat = [](double, double) { return -5.0; };
  const ElevationMap a = make_map(flat, 0.0, 4.0, 200, 150, 0.02, {0, 0, 0}, 0.01, 3);
  const ElevationMap b = make_map(flat, 1.5, 4.0, 200, 150, 0.02, {0.2, 0.1, 0}, 0.01, 4);
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.3;
  const SwathTie t = sonar3d::register_elevation_maps(a, b, cfg);
  EXPECT_LT(t.confidence, 0.1);
  cfg.coarse_factor = 1;
  EXPECT_LT(sonar3d::register_elevation_maps(a, b, cfg).confidence, 0.1);
  cfg.coarse_factor = 4;
  // The same maps with relief: confident.
  const ElevationMap a2 = make_map(terrain, 0.0, 4.0, 200, 150, 0.02, {0, 0, 0}, 0.01, 3);
  const ElevationMap b2 = make_map(terrain, 1.5, 4.0, 200, 150, 0.02, {0.2, 0.1, 0}, 0.01, 4);
  EXPECT_GT(sonar3d::register_elevation_maps(a2, b2, cfg).confidence, 0.5);
}

TEST(SwathRegistration, NoDataAndBadInputs) {
  const double c = 0.02;
  ElevationMap a = make_map(terrain, 0.0, 4.0, 200, 150, c);
  ElevationMap b = make_map(terrain, 1.5, 4.0, 200, 150, c, {0.08, 0.04, 0.01});
  // Holes in both maps (no data) are discarded, not read as heights.
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> row(0, 199), col(0, 149);
  for (int k = 0; k < 8000; ++k) {
    a.at(row(rng), col(rng)) = ElevationMap::kNoData;
    b.at(row(rng), col(rng)) = ElevationMap::kNoData;
  }
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.2;
  cfg.subcell = false;
  const SwathTie t = sonar3d::register_elevation_maps(a, b, cfg);
  EXPECT_NEAR(t.t.x(), -0.08, 1e-9);
  EXPECT_NEAR(t.t.y(), -0.04, 1e-9);
  EXPECT_NEAR(t.t.z(), -0.01, 1e-5);
  // No overlap.
  const ElevationMap far = make_map(terrain, 50.0, 4.0, 50, 50, c);
  try {
    sonar3d::register_elevation_maps(a, far, cfg);
    FAIL();
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("do not overlap"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(sonar3d::maps_may_overlap(a, far, 0.2));
  // Different resolutions, origins off the common grid, a negative window.
  ElevationMap coarse = make_map(terrain, 0.0, 4.0, 100, 75, 0.04);
  EXPECT_THROW(sonar3d::register_elevation_maps(a, coarse, cfg), sonar3d::Error);
  ElevationMap off = make_map(terrain, 1.505, 4.0, 200, 150, c);
  EXPECT_THROW(sonar3d::register_elevation_maps(a, off, cfg), sonar3d::Error);
  cfg.search_m = -1;
  EXPECT_THROW(sonar3d::register_elevation_maps(a, b, cfg), sonar3d::Error);
}

// Five swaths in a row, each overlapping the next and the one after; navigation drifts. The
// consecutive method (the thesis') and the global adjustment both recover the offsets; with one
// tie corrupted, the global adjustment's robust loss keeps the others right while the
// consecutive chain carries the error to every later swath.
TEST(SwathAdjustment, GlobalBeatsConsecutiveWithABadTie) {
  const double c = 0.02;
  const int n = 5;
  std::vector<Eigen::Vector3d> drift(n);
  std::vector<ElevationMap> maps;
  for (int i = 0; i < n; ++i) {
    drift[i] = Eigen::Vector3d(0.04 * i, -0.02 * (i * (i - 1) / 2), 0.01 * i);  // whole cells
    // Swath i covers y ∈ [0.8·i, 0.8·i + 2] (North), x ∈ [0, 3].
    maps.push_back(make_map(terrain, 0.0, 0.8 * i + 2.0, 100, 150, c, drift[i], 0.002, 10 + i));
  }
  sonar3d::SwathRegistrationConfig cfg;
  cfg.search_m = 0.3;
  cfg.subcell = false;
  cfg.overlap_full_cells = 1000;
  std::vector<SwathTie> ties;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      if (!sonar3d::maps_may_overlap(maps[i], maps[j], cfg.search_m)) continue;
      SwathTie t;
      try {
        t = sonar3d::register_elevation_maps(maps[i], maps[j], cfg);
      } catch (const sonar3d::Error&) {
        continue;  // overlap too small
      }
      t.reference = i;
      t.moving = j;
      ties.push_back(t);
    }
  }
  ASSERT_GE(ties.size(), 7u);  // 4 consecutive + at least 3 skipping one swath
  // Truth: offsets that undo the drift, relative to swath 0.
  auto truth = [&](int i) { return Eigen::Vector3d(drift[0] - drift[i]); };
  const sonar3d::SwathAdjustment cons = sonar3d::accumulate_consecutive(n, ties);
  const sonar3d::SwathAdjustment glob = sonar3d::adjust_swaths(n, ties, {});
  for (int i = 0; i < n; ++i) {
    EXPECT_NEAR((cons.offsets[i] - truth(i)).head<2>().norm(), 0, 1e-6) << i;
    EXPECT_NEAR((glob.offsets[i] - truth(i)).head<2>().norm(), 0, 0.005) << i;
  }
  // Corrupt the tie between swaths 1 and 2 by 20 cm.
  for (SwathTie& t : ties) {
    if (t.reference == 1 && t.moving == 2) t.t.x() += 0.2;
  }
  const sonar3d::SwathAdjustment cons2 = sonar3d::accumulate_consecutive(n, ties);
  const sonar3d::SwathAdjustment glob2 = sonar3d::adjust_swaths(n, ties, {});
  EXPECT_NEAR((cons2.offsets[4] - truth(4)).x(), 0.2, 1e-6);  // carried to the end
  for (int i = 0; i < n; ++i) {
    EXPECT_LT((glob2.offsets[i] - truth(i)).head<2>().norm(), 0.02) << i;
  }
  // A swath no confident tie reaches is an error naming it.
  std::vector<SwathTie> only_first = {ties.front()};
  try {
    sonar3d::adjust_swaths(n, only_first, {});
    FAIL();
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("swath(s)"), std::string::npos) << e.what();
  }
  EXPECT_THROW(sonar3d::accumulate_consecutive(n, only_first), sonar3d::Error);
}

// The drift adjustment: four lines flown east and west with turns between them, navigation that
// drifts with time (steadily, more in the turns, and the other way from line 2 on as a DVL bias
// wanders).
// Ties measured piece by piece at known times give back the correction at every piece within a
// centimetre; one offset per swath cannot follow it. (A drift that flips with the direction of
// travel — a DVL scale error or a constant bias — stretches or shears the whole map alike and
// leaves the swaths agreeing: no relative registration can see it, the thesis' neither.)
TEST(SwathAdjustment, DriftRatesFollowDeadReckoning) {
  const int n = 4;
  const double speed = 0.5, line_s = 40, turn_s = 10;  // 20 m lines
  std::vector<sonar3d::SwathTiming> timing;
  for (int k = 0; k < n; ++k) {
    sonar3d::SwathTiming w;
    w.t0 = k * (line_s + turn_s);
    w.t1 = w.t0 + line_s;
    w.speed_mps = speed;
    w.gap_to_next_m = k + 1 < n ? speed * turn_s : 0.0;
    timing.push_back(w);
  }
  // The navigation's error e(t), integrated from drift velocities; the exact correction is −e.
  auto drift_velocity = [&](double t) -> Eigen::Vector3d {
    const int k = static_cast<int>(t / (line_s + turn_s));
    const bool in_turn = t - k * (line_s + turn_s) > line_s;
    if (in_turn) return {0.0, 0.003, 0.0};
    return {0.002, k < 2 ? 0.0015 : -0.001, 0.0};
  };
  auto error_at = [&](double t) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    const double dt = 0.01;
    for (double s = 0; s < t; s += dt) e += drift_velocity(s) * std::min(dt, t - s);
    return e;
  };
  // Pieces at x = 2.5, 7.5, 12.5, 17.5 m; line k passes x at t0 + x/v (east) or t0 + (20 − x)/v.
  auto time_at = [&](int k, double x) {
    return timing[k].t0 + (k % 2 == 0 ? x : 20.0 - x) / speed;
  };
  std::vector<SwathTie> ties;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.003);
  for (int a = 0; a + 1 < n; ++a) {
    for (const double x : {2.5, 7.5, 12.5, 17.5}) {
      SwathTie t;
      t.reference = a;
      t.moving = a + 1;
      t.time_reference = time_at(a, x);
      t.time_moving = time_at(a + 1, x);
      // c_B(t_B) − c_A(t_A) with c = −e.
      t.t = error_at(t.time_reference) - error_at(t.time_moving) +
            Eigen::Vector3d(noise(rng), noise(rng), 0.0);
      t.confidence = 0.8;
      ties.push_back(t);
    }
  }
  const sonar3d::SwathAdjustment drift = sonar3d::adjust_swaths_drift(timing, ties, {});
  const sonar3d::SwathAdjustment constant = sonar3d::adjust_swaths(n, ties, {});
  double worst_drift = 0, worst_constant = 0;
  for (int k = 0; k < n; ++k) {
    for (const double x : {0.0, 2.5, 7.5, 12.5, 17.5, 20.0}) {
      const double t = time_at(k, x);
      const Eigen::Vector3d exact = -error_at(t);
      worst_drift = std::max(worst_drift, (drift.correction(k, t) - exact).head<2>().norm());
      worst_constant =
          std::max(worst_constant, (constant.correction(k, t) - exact).head<2>().norm());
    }
  }
  EXPECT_LT(worst_drift, 0.01);
  EXPECT_GT(worst_constant, 0.05);  // what the drift model is for
  // Ties without times are refused by the drift method.
  ties.front().time_moving = std::nan("");
  EXPECT_THROW(sonar3d::adjust_swaths_drift(timing, ties, {}), sonar3d::Error);
}

// Through the command-line tool: `elevation` maps two clouds of the same seabed, the second
// logged 6 cm east, 4 cm south and 3 cm up of the truth; `register` finds the shift back.
TEST(MappingCli, ElevationAndRegister) {
  const fs::path dir = temp_dir();
  auto cloud = [](const Eigen::Vector3d& err) {
    sonar3d::PointCloud c;
    for (int i = 0; i < 300; ++i) {
      for (int j = 0; j < 200; ++j) {
        const double x = 0.01 * i + 0.005, y = 0.01 * j + 0.005;
        c.points.emplace_back(float(x + err.x()), float(y + err.y()),
                              float(terrain(x, y) + err.z()));
      }
    }
    return c;
  };
  sonar3d::write_ply((dir / "a.ply").string(), cloud({0, 0, 0}));
  sonar3d::write_ply((dir / "b.ply").string(), cloud({0.06, -0.04, 0.03}));
  auto run = [&](const std::string& args) {
    const std::string log = (dir / "log.txt").string();
    const int rc =
        std::system((std::string(SONAR3D_CLI) + " " + args + " > " + log + " 2>&1").c_str());
    std::ifstream in(log);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return std::pair{WEXITSTATUS(rc), text};
  };
  const std::string d = dir.string() + "/";
  auto [rc, out] = run("elevation " + d + "a.ply -o " + d + "a.tif --png " + d + "a.png");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("elevation map 150 x 100 cells"), std::string::npos) << out;
  std::tie(rc, out) = run("elevation " + d + "b.ply -o " + d + "b.tif --uint16-step-m 0.0005");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) =
      run("register " + d + "a.tif " + d + "b.tif --search 0.2 --json " + d + "tie.json");
  ASSERT_EQ(rc, 0) << out;
  std::ifstream tie(dir / "tie.json");
  const std::string j((std::istreambuf_iterator<char>(tie)), std::istreambuf_iterator<char>());
  auto value = [&](const std::string& key) {
    const auto p = j.find("\"" + key + "\":");
    EXPECT_NE(p, std::string::npos) << key << " in " << j;
    return std::stod(j.substr(p + key.size() + 3));
  };
  EXPECT_NEAR(value("shift_east_m"), -0.06, 0.005);
  EXPECT_NEAR(value("shift_north_m"), 0.04, 0.005);
  EXPECT_NEAR(value("shift_up_m"), -0.03, 0.003);
  EXPECT_GT(value("confidence"), 0.5);
  // Bad input: one line naming the file, exit 1.
  std::tie(rc, out) = run("register " + d + "a.ply " + d + "b.tif");
  EXPECT_EQ(rc, 1);
  EXPECT_NE(out.find("a.ply"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  fs::remove_all(dir);
}

namespace {

// A small field: seabed, a box, a half-buried pipe and a rock, surveyed by a downward-looking
// 1° × 80° sonar (MB2250-like) on four East–West lines 3 m above the seabed.
const std::string kFieldScene = std::string(R"(seed: 3
)") + sonar3d::test::kDownwardSonarYaml +
                                R"(objects:
  - {name: seabed, primitive: {type: plane, size: [20, 20]}, pose: {translation: [0, 0, 0.013]}, reflectivity: 0.3, kind: terrain}
  - {name: box, primitive: {type: box, size: [1.0, 0.6, 0.4]}, pose: {translation: [2.0, 1.5, 0], rpy_deg: [0, 0, 30]}, reflectivity: 0.8}
  - {name: pipe, primitive: {type: cylinder, radius: 0.15, height: 5}, pose: {translation: [3, 2.0, 0.05], rpy_deg: [0, 90, 20]}, reflectivity: 0.8}
  - {name: rock, primitive: {type: sphere, radius: 0.3}, pose: {translation: [4.5, 3.2, -0.1]}, reflectivity: 0.6}
trajectory: {type: lawnmower, x: [0, 6], y: [0, 4.5], z: 3.0, line_spacing: 1.5, spacing: 0.04, period: 0.1}
)";

using sonar3d::test::CliRun;
using sonar3d::test::run_cli;

}  // namespace

// Swaths of a survey that turns as a vehicle does: one swath per line along any heading, the
// frames of the turns (quarter circles and the leg across) in none; the idealised survey that
// jumps between lines splits the same way.
TEST(SwathSplit, TurnsOfAnyHeadingBelongToNoSwath) {
  for (const double radius : {0.0, 2.0, 5.0}) {
    SCOPED_TRACE(radius);
    sonar3d::LawnmowerConfig c;
    c.x0 = -15;
    c.x1 = 15;
    c.y0 = -10;
    c.y1 = 10;
    c.z = 5;
    c.line_spacing = 10;
    c.spacing = 0.04;
    c.heading = -55.0 * M_PI / 180;
    c.turn_radius = radius;
    sonar3d::Dataset ds;
    ds.navigation = sonar3d::lawnmower(c, 0, 0.1);
    for (std::size_t k = 0; k < ds.navigation.size(); ++k) {
      ds.frames.push_back({static_cast<int>(k), ds.navigation.times[k], ""});
    }
    const auto swaths = sonar3d::split_swaths(ds, {});
    ASSERT_EQ(swaths.size(), 3u);
    const Eigen::Rotation2Dd back(-c.heading);
    for (const auto& [first, last] : swaths) {
      // Every frame of a swath lies on a line, and the swath covers all but its ends.
      for (int i = first; i <= last; ++i) {
        const Eigen::Vector2d s = back * ds.navigation.poses[i].translation().head<2>();
        EXPECT_LE(std::abs(s.x()), 15 + 1e-9) << "frame " << i;
      }
      const double length =
          (ds.navigation.poses[last].translation() - ds.navigation.poses[first].translation())
              .norm();
      EXPECT_GT(length, 30 - 2.5);
    }
  }
}

// End to end: a four-line survey whose logged navigation is off by a different amount on each
// line (the drift a vehicle accumulates between lines); `sonar3d map` recovers each line's offset
// within one map cell, by the global adjustment and by the thesis' consecutive registration.
TEST(MappingCli, FieldSurveyWithDriftIsCorrected) {
  const fs::path dir = temp_dir() / "field";
  fs::create_directories(dir);
  { std::ofstream(dir / "field.yaml") << kFieldScene; }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "field.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  // The drift: line k's navigation is off by e_k (swath 0 exact).
  const sonar3d::Dataset ds = sonar3d::read_dataset(dir / "ds");
  const auto swaths = sonar3d::split_swaths(ds, {});
  ASSERT_EQ(swaths.size(), 4u);
  const Eigen::Vector3d e[4] = {
      {0, 0, 0}, {0.08, -0.06, 0.02}, {0.14, -0.02, 0.04}, {0.2, 0.04, 0.02}};
  sonar3d::Trajectory nav = sonar3d::read_tum((dir / "ds/navigation.tum").string());
  for (std::size_t k = 0; k < nav.size(); ++k) {
    for (int s = 0; s < 4; ++s) {
      if (nav.times[k] >= ds.frames[swaths[s].first].timestamp - 1e-9 &&
          nav.times[k] <= ds.frames[swaths[s].second].timestamp + 1e-9) {
        nav.poses[k].translation() += e[s];
      }
    }
  }
  sonar3d::write_tum((dir / "ds/navigation.tum").string(), nav);

  for (const std::string method : {"global", "consecutive"}) {
    SCOPED_TRACE(method);
    const fs::path out = dir / ("map_" + method);
    r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + out.string() +
                         " --roi -1 -1 -0.6 7 6 0.8 --search 0.3 --method " + method + " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    std::ifstream f(out / "summary.json");
    const nlohmann::json summary = nlohmann::json::parse(f);
    ASSERT_EQ(summary["swaths"].size(), 4u);
    for (int s = 0; s < 4; ++s) {
      const auto& o = summary["swaths"][s]["offset_m"];
      // The correction undoes the error: o_s = e_0 − e_s.
      EXPECT_NEAR(o[0].get<double>(), -e[s].x(), 0.02) << "swath " << s;
      EXPECT_NEAR(o[1].get<double>(), -e[s].y(), 0.02) << "swath " << s;
      EXPECT_NEAR(o[2].get<double>(), -e[s].z(), 0.01) << "swath " << s;
    }
    for (const char* file : {"merged.ply", "merged.tif", "merged.png", "merged_uncorrected.png",
                             "navigation_corrected.tum", "ties.json", "swaths/swath_03.tif"}) {
      EXPECT_TRUE(fs::exists(out / file)) << file;
    }
    // The corrected navigation of a frame of line 2 is back on the truth.
    const sonar3d::Trajectory corrected =
        sonar3d::read_tum((out / "navigation_corrected.tum").string());
    const double t = ds.frames[(swaths[2].first + swaths[2].second) / 2].timestamp;
    const sonar3d::Trajectory truth_nav = ds.navigation;  // read before the drift was added
    EXPECT_LT((corrected.interpolate(t).translation() - truth_nav.interpolate(t).translation())
                  .head<2>()
                  .norm(),
              0.02);
  }
  // An existing output is refused; a survey of one straight line has nothing to register.
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "map_global").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("already exists"), std::string::npos) << r.out;
  r = run_cli(
      dir, "map " + (dir / "ds").string() + " -o " + (dir / "one").string() + " --swath-times 0 5");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("one swath"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "one"));
  r = run_cli(dir,
              "map " + (dir / "ds").string() + " -o " + (dir / "x").string() + " --resolution 0");
  EXPECT_EQ(r.code, 1);
  // The hint names the flag, not the library's field (issue 29).
  EXPECT_NE(r.out.find("--resolution must be"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("cell_m"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// The dead-reckoning model: a 100 m straight line logged with a 1 % velocity scale error ends
// 1 m long; a 0.5° heading bias puts it 100·sin(0.5°) = 0.87 m to the side; the depth sensor's
// offset shifts z; the bias random walk is seeded.
TEST(DeadReckoning, DriftsLikeAVehicle) {
  sonar3d::Trajectory truth;
  for (int k = 0; k <= 1000; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.1 * k, 0, -20);
    truth.push_back(0.1 * k, T);
  }
  sonar3d::DeadReckoningConfig cfg;
  cfg.velocity_scale_error = 0.01;
  cfg.velocity_bias_walk = 0;
  cfg.heading_bias_deg = 0;
  cfg.depth_offset_m = 0.05;
  sonar3d::Trajectory dr = sonar3d::dead_reckoning(truth, cfg, 1);
  EXPECT_NEAR(dr.poses.back().translation().x(), 101.0, 1e-9);
  EXPECT_NEAR(dr.poses.back().translation().y(), 0.0, 1e-9);
  EXPECT_NEAR(dr.poses.back().translation().z(), -20.05, 1e-12);
  EXPECT_EQ(dr.poses.front().translation(),
            truth.poses.front().translation() - Eigen::Vector3d(0, 0, 0.05));
  cfg.velocity_scale_error = 0;
  cfg.heading_bias_deg = 0.5;
  dr = sonar3d::dead_reckoning(truth, cfg, 1);
  EXPECT_NEAR(dr.poses.back().translation().y(), 100 * std::sin(0.5 * M_PI / 180), 1e-9);
  cfg.velocity_bias_walk = 0.001;
  const sonar3d::Trajectory a = sonar3d::dead_reckoning(truth, cfg, 7);
  const sonar3d::Trajectory b = sonar3d::dead_reckoning(truth, cfg, 7);
  const sonar3d::Trajectory c = sonar3d::dead_reckoning(truth, cfg, 8);
  EXPECT_EQ(a.poses.back().translation(), b.poses.back().translation());
  EXPECT_NE(a.poses.back().translation(), c.poses.back().translation());
  cfg.velocity_scale_error = 2;  // absurd: refused, naming the key
  try {
    sonar3d::dead_reckoning(truth, cfg, 1);
    FAIL();
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("velocity_scale"), std::string::npos) << e.what();
  }
}

// Under mpirun the swaths are carved on two ranks and rank 0 writes the same map as one process
// does; a failure on the ranks is one error from rank 0, no hang, no output.
TEST(MappingCli, TwoMpiRanksCarveTheSwaths) {
  if (std::system("command -v mpirun > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "mpirun not installed";
  }
  const fs::path dir = temp_dir() / "mpi";
  fs::create_directories(dir);
  { std::ofstream(dir / "field.yaml") << kFieldScene; }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "field.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string args = " --roi -1 -1 -0.6 7 6 0.8 --search 0.3 -q";
  r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + (dir / "one").string() + args);
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string mpirun =
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "OMPI_MCA_btl_vader_single_copy_mechanism=none timeout 300 mpirun --oversubscribe "
      "--bind-to none -np 2 ";
  const std::string log = (dir / "mpi.log").string();
  int rc = std::system((mpirun + SONAR3D_CLI + " map " + (dir / "ds").string() + " -o " +
                        (dir / "two").string() + args + " > " + log + " 2>&1")
                           .c_str());
  ASSERT_EQ(WEXITSTATUS(rc), 0) << read_text_file(log);
  EXPECT_NE(read_text_file(log).find("carved on 2 ranks"), std::string::npos)
      << read_text_file(log);
  std::ifstream fa(dir / "one/summary.json"), fb(dir / "two/summary.json");
  const nlohmann::json a = nlohmann::json::parse(fa), b = nlohmann::json::parse(fb);
  ASSERT_EQ(a["swaths"].size(), 4u);
  EXPECT_EQ(a["merged_points"], b["merged_points"]);
  for (std::size_t s = 0; s < 4; ++s)
    EXPECT_EQ(a["swaths"][s]["offset_m"], b["swaths"][s]["offset_m"]);
  EXPECT_EQ(read_text_file((dir / "one/merged.ply").string()),
            read_text_file((dir / "two/merged.ply").string()));
  // A region with nothing in it: every rank fails; one error, exit 1, nothing written.
  rc = std::system((mpirun + SONAR3D_CLI + " map " + (dir / "ds").string() + " -o " +
                    (dir / "none").string() + " --roi 50 50 50 51 51 51 -q > " + log + " 2>&1")
                       .c_str());
  EXPECT_NE(WEXITSTATUS(rc), 0);
  EXPECT_NE(WEXITSTATUS(rc), 124) << "timed out: a rank hung";
  EXPECT_NE(read_text_file(log).find("reconstructs to no point"), std::string::npos)
      << read_text_file(log);
  EXPECT_FALSE(fs::exists(dir / "none"));
  fs::remove_all(dir);
}

// Dead-reckoned navigation with a wandering DVL bias: the error after the map's affine placement
// in the world (which no registration between swaths can see) is reduced by the drift method;
// the summary's navigation figures (absolute, within the map after a rigid placement, the scale
// the affine fit absorbs) agree with an independent computation from the true navigation; the
// structures are scored against their CAD.
TEST(MappingCli, SimulatedDeadReckoningDriftIsReducedAndMeasured) {
  const fs::path dir = temp_dir() / "dr";
  fs::create_directories(dir);
  std::string scene = kFieldScene;
  scene.replace(scene.find("seed: 3\n"), 8,
                "seed: 3\nnavigation_error: {velocity_scale: 0.02, heading_bias_deg: 0.3, "
                "bias_walk: 0.002}\n");
  { std::ofstream(dir / "f.yaml") << scene; }
  CliRun r = run_cli(
      dir, "simulate " + (dir / "f.yaml").string() + " -o " + (dir / "ds").string() + " -q");
  ASSERT_EQ(r.code, 0) << r.out;
  const sonar3d::Trajectory logged = sonar3d::read_tum((dir / "ds/navigation.tum").string());
  const sonar3d::Trajectory truth = sonar3d::read_tum((dir / "ds/truth/navigation.tum").string());
  ASSERT_EQ(logged.size(), truth.size());
  EXPECT_GT((logged.poses.back().translation() - truth.poses.back().translation()).head<2>().norm(),
            0.05);
  double global_after = 0;
  for (const std::string method : {"global", "drift"}) {
    SCOPED_TRACE(method);
    const fs::path out = dir / ("m_" + method);
    r = run_cli(dir, "map " + (dir / "ds").string() + " -o " + out.string() +
                         " --roi -1 -1 -0.6 7 6 0.8 --search 0.3 --piece 2 --method " + method +
                         " -q");
    ASSERT_EQ(r.code, 0) << r.out;
    std::ifstream f(out / "summary.json");
    const nlohmann::json summary = nlohmann::json::parse(f);
    double before = 0, after = 0;
    for (const auto& w : summary["swaths"]) {
      ASSERT_TRUE(w.contains("affine_error_after_m")) << w.dump();
      before += w["affine_error_before_m"][0].get<double>();
      after += w["affine_error_after_m"][0].get<double>();
      // A rigid placement leaves at least what an affine one does.
      EXPECT_GE(w["rigid_error_before_m"][0].get<double>(),
                w["affine_error_before_m"][0].get<double>() - 1e-9);
    }
    // The logged navigation against the truth, computed here over the swaths' frames: the
    // median absolute error (relative to the error where swath 0 starts), the median after the
    // best rigid 2D placement (Eigen's Umeyama in 3D on z = 0) and the affine fit's scale (a
    // least-squares solve of its own).
    {
      const sonar3d::Dataset ds = sonar3d::read_dataset(dir / "ds");
      std::vector<Eigen::Vector3d> nav, tru;
      for (const auto& w : summary["swaths"]) {
        for (int i = w["frames"][0].get<int>(); i <= w["frames"][1].get<int>(); ++i) {
          const double t = ds.frames[static_cast<std::size_t>(i)].timestamp;
          nav.push_back(logged.interpolate(t).translation());
          tru.push_back(truth.interpolate(t).translation());
        }
      }
      const double t0 = summary["swaths"][0]["time_s"][0].get<double>();
      const Eigen::Vector3d e0 =
          truth.interpolate(t0).translation() - logged.interpolate(t0).translation();
      const std::size_t n = nav.size();
      Eigen::Matrix3Xd src(3, n), dst(3, n);
      Eigen::MatrixXd A(n, 3);
      Eigen::MatrixXd B(n, 2);
      std::vector<double> absolute;
      for (std::size_t k = 0; k < n; ++k) {
        const auto c = static_cast<Eigen::Index>(k);
        src.col(c) << nav[k].x(), nav[k].y(), 0;
        dst.col(c) << tru[k].x(), tru[k].y(), 0;
        A.row(c) << nav[k].x(), nav[k].y(), 1;
        B.row(c) << tru[k].x(), tru[k].y();
        absolute.push_back((tru[k] - nav[k] - e0).head<2>().norm());
      }
      const Eigen::Matrix4d T = Eigen::umeyama(src, dst, false);
      std::vector<double> rigid;
      for (std::size_t k = 0; k < n; ++k) {
        const Eigen::Vector3d p = T.topLeftCorner<3, 3>() * src.col(static_cast<Eigen::Index>(k)) +
                                  T.topRightCorner<3, 1>();
        rigid.push_back((p - dst.col(static_cast<Eigen::Index>(k))).norm());
      }
      auto median = [](std::vector<double> v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
      };
      const Eigen::MatrixXd X = A.colPivHouseholderQr().solve(B);
      const double scale = std::sqrt(std::abs(X.topRows<2>().determinant()));
      const auto& nb = summary["navigation_error"]["before"];
      EXPECT_NEAR(nb["absolute_m"].get<double>(), median(absolute), 1e-6);
      EXPECT_NEAR(nb["within_map_m"].get<double>(), median(rigid), 1e-6);
      EXPECT_NEAR(summary["alignment"]["before"]["scale"].get<double>(), scale, 1e-9);
      // The DVL's 2 % scale error (with its bias walk, measured 0.954): the affine fit absorbs
      // a shrink of more than 1 %.
      EXPECT_LT(scale, 0.99);
      // The within-map error keeps what the affine figure hides.
      EXPECT_GT(nb["within_map_m"].get<double>(), nb["after_affine_m"].get<double>());
    }
    // Constant swath offsets cannot follow a drift that changes along a line; the drift
    // method's rates do (measured: global 0.149 -> 0.144 m, drift 0.149 -> 0.086 m).
    EXPECT_GT(before, 0.1);
    if (method == "global") {
      EXPECT_LT(after, 1.05 * before);
      global_after = after;
    } else {
      EXPECT_LT(after, 0.7 * before);
      EXPECT_LT(after, 0.8 * global_after);
    }
    // The structures against their CAD, as logged and corrected; the seabed (terrain) unscored.
    ASSERT_TRUE(summary.contains("structures")) << summary.dump();
    ASSERT_TRUE(summary.contains("alignment")) << summary.dump();
    ASSERT_EQ(summary["structures"].size(), 3u);
    for (const auto& s : summary["structures"]) {
      SCOPED_TRACE(s.dump());
      EXPECT_NE(s["name"], "seabed");
      EXPECT_GT(s["after"]["points"].get<int>(), 50);
      EXPECT_GT(s["after"]["coverage"].get<double>(), 0.05);
      EXPECT_LT(s["after"]["median_error_m"].get<double>(), 0.05);
    }
  }
  fs::remove_all(dir);
}

// The procedural seabed: a height field meshed at its cell size, upward facing, seeded, with its
// trenches reaching about their depth below the relief, and absurd sizes refused.
TEST(Terrain, HeightFieldWithTrenchesAndRocks) {
  sonar3d::TerrainConfig cfg;
  cfg.size = {10, 6};
  cfg.cell_m = 0.1;
  cfg.relief_m = 0.2;
  cfg.trenches = 1;
  cfg.trench_depth_m = 0.3;
  cfg.rocks = 5;
  cfg.seed = 4;
  const sonar3d::Terrain t(cfg);
  const sonar3d::TriangleMesh m = t.mesh();
  EXPECT_EQ(m.vertices.size(), 101u * 61u);
  EXPECT_EQ(m.triangles.size(), 2u * 100u * 60u);
  const Eigen::AlignedBox3f box = m.bounding_box();
  EXPECT_NEAR(box.min().x(), -5, 1e-5);
  EXPECT_NEAR(box.max().y(), 3, 1e-5);
  EXPECT_LT(box.min().z(), -0.3);  // a trench below the relief's mean
  EXPECT_GT(box.max().z(), 0.0);
  EXPECT_LT(box.max().z(), 0.2 + 0.6 * 0.375 + 1e-3);  // relief + the tallest rock
  for (const Eigen::Vector3i& tri : m.triangles) {     // counter-clockwise seen from +z
    const Eigen::Vector3f n =
        (m.vertices[tri[1]] - m.vertices[tri[0]]).cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
    ASSERT_GT(n.z(), 0);
  }
  EXPECT_EQ(sonar3d::Terrain(cfg).height(1.23, -0.7), t.height(1.23, -0.7));
  cfg.seed = 5;
  EXPECT_NE(sonar3d::Terrain(cfg).height(1.23, -0.7), t.height(1.23, -0.7));
  cfg.cell_m = 1e-4;  // 6e9 vertices: refused before allocating
  EXPECT_THROW(sonar3d::Terrain{cfg}, sonar3d::Error);
}
