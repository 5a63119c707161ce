// Evaluation metrics (thesis sec. 4.5.2.1) against analytic cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/eval/metrics.hpp"

namespace sonar3d {
namespace {

constexpr double kPi = 3.14159265358979323846;

TriangleMesh single_triangle() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  return m;
}

// Square [0, s]² at z = 0, two triangles.
TriangleMesh square(float s) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {s, 0, 0}, {s, s, 0}, {0, s, 0}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

// UV sphere of radius R, vertices on the sphere (so the mesh lies inside it). Its largest gap to
// the true sphere (chordal error) is below R·(1 − cos(Δ/√2)) with Δ the angular step.
TriangleMesh uv_sphere(double R, int stacks, int slices) {
  TriangleMesh m;
  for (int i = 0; i <= stacks; ++i) {
    const double theta = kPi * i / stacks;  // from the north pole
    for (int j = 0; j < slices; ++j) {
      const double phi = 2 * kPi * j / slices;
      m.vertices.emplace_back(static_cast<float>(R * std::sin(theta) * std::cos(phi)),
                              static_cast<float>(R * std::sin(theta) * std::sin(phi)),
                              static_cast<float>(R * std::cos(theta)));
    }
  }
  const auto id = [slices](int i, int j) { return i * slices + (j % slices); };
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      if (i > 0) m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i, j + 1));
      if (i < stacks - 1) m.triangles.emplace_back(id(i, j + 1), id(i + 1, j), id(i + 1, j + 1));
    }
  }
  return m;
}

Eigen::Vector3d random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

TEST(MeshDistance, SingleTriangleVoronoiRegions) {
  const MeshDistance md(single_triangle());
  struct Case {
    Eigen::Vector3f p;
    double expected;
    const char* region;
  };
  const Case cases[] = {
      {{0.25f, 0.25f, 0.5f}, 0.5, "face, above"},
      {{0.2f, 0.3f, -0.7f}, 0.7, "face, below"},
      {{0.1f, 0.1f, 0.0f}, 0.0, "on the face"},
      {{-1.0f, -1.0f, 0.0f}, std::sqrt(2.0), "vertex a"},
      {{2.0f, -1.0f, 1.0f}, std::sqrt(3.0), "vertex b"},
      {{-0.5f, 2.0f, 0.0f}, std::sqrt(1.25), "vertex c"},
      {{0.5f, -2.0f, 0.0f}, 2.0, "edge ab"},
      {{-3.0f, 0.5f, 4.0f}, 5.0, "edge ac"},
      {{1.0f, 1.0f, 0.0f}, std::sqrt(0.5), "edge bc"},
      {{1.0f, 1.0f, 1.0f}, std::sqrt(1.5), "edge bc, off plane"},
  };
  for (const Case& c : cases) {
    EXPECT_NEAR(md.distance(c.p), c.expected, 1e-6) << c.region;
  }
  EXPECT_TRUE(std::isnan(md.distance(Eigen::Vector3f(NAN, 0, 0))));
}

TEST(MeshDistance, DegenerateTriangleIsItsEdges) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {0, 0, 0}, {2, 0, 0}};  // repeated vertex: a segment
  m.triangles = {{0, 1, 2}};
  const MeshDistance md(m);
  EXPECT_NEAR(md.distance({1, 3, 4}), 5.0, 1e-6);
  EXPECT_NEAR(md.distance({-3, 0, 4}), 5.0, 1e-6);
}

TEST(MeshDistance, ParallelMatchesSerialAndBruteForce) {
  const TriangleMesh m = uv_sphere(0.5, 8, 16);
  const MeshDistance md(m);
  // Brute force: the minimum over every triangle on its own.
  std::vector<std::unique_ptr<MeshDistance>> singles;
  for (const auto& t : m.triangles) {
    TriangleMesh one;
    one.vertices = {m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]};
    one.triangles = {{0, 1, 2}};
    singles.push_back(std::make_unique<MeshDistance>(one));
  }
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts(2000);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  const std::vector<double> d = md.distances(pts);
  ASSERT_EQ(d.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); i += 37) {
    double best = INFINITY;
    for (const auto& s : singles) best = std::min(best, s->distance(pts[i]));
    EXPECT_NEAR(d[i], best, 1e-12);
    EXPECT_EQ(d[i], md.distance(pts[i]));
  }
}

TEST(Evaluate, MedianOfPointsOffsetFromSphere) {
  const double R = 1.0, d = 0.02;
  const int stacks = 128, slices = 256;
  const TriangleMesh sphere = uv_sphere(R, stacks, slices);
  const double chordal = R * (1.0 - std::cos(2.0 * kPi / slices / std::sqrt(2.0)));
  ASSERT_LT(chordal, 2e-4);
  std::mt19937_64 rng(42);
  PointCloud cloud;
  for (int i = 0; i < 20000; ++i) {
    cloud.points.push_back(((R + d) * random_direction(rng)).cast<float>());
  }
  const std::vector<double> dist = MeshDistance(sphere).distances(cloud.points);
  for (const double e : dist) {
    ASSERT_GE(e, d - 1e-6);  // float rounding of the points and vertices
    ASSERT_LE(e, d + chordal + 1e-6);
  }
  const EvalResult r = evaluate(cloud, sphere, EvalConfig{});
  EXPECT_EQ(r.num_points, cloud.size());
  EXPECT_GE(r.median_error, d - 1e-6);
  EXPECT_LE(r.median_error, d + chordal + 1e-6);
  EXPECT_NEAR(r.mean_error, r.median_error, chordal);
  EXPECT_EQ(r.outliers, 0.0);
  // A surface sample is covered when one of the N random points on the radius-(R + d) sphere
  // falls in the cap within r_c of it: cos α = ((R + d)² + R² − r_c²) / (2R(R + d)), cap fraction
  // (1 − cos α) / 2, so the expected coverage is 1 − (1 − (1 − cos α) / 2)^N (≈ 91.4 % here).
  const double rc = EvalConfig{}.coverage_radius;
  const double cos_a = ((R + d) * (R + d) + R * R - rc * rc) / (2 * R * (R + d));
  const double expected = 1.0 - std::pow(1.0 - (1.0 - cos_a) / 2.0, cloud.size());
  EXPECT_NEAR(r.coverage, expected, 0.01);
  EXPECT_NEAR(r.median_to_coverage, (r.median_error * 100) / (r.coverage * 100), 1e-12);
  // 4π m² at 1 sample per cm².
  EXPECT_NEAR(static_cast<double>(r.num_surface_samples), 4 * kPi * 1e4, 0.01 * 4 * kPi * 1e4);
}

TEST(Evaluate, UpperHemisphereCoversHalf) {
  const TriangleMesh sphere = uv_sphere(1.0, 64, 128);
  PointCloud cloud;
  for (const auto& p : sample_surface(sphere, 100000, 3)) {
    if (p.z() > 0) cloud.points.push_back(p);
  }
  EvalConfig config;
  const EvalResult r = evaluate(cloud, sphere, config);
  // Half the sphere, plus the band below the equator within r_c: r_c / (2R) = 1.5 %.
  EXPECT_NEAR(r.coverage, 0.5 + config.coverage_radius / 2.0, 0.02);
  EXPECT_NEAR(r.coverage, 0.5, 0.05);
  EXPECT_LT(r.median_error, 1e-3);
  EXPECT_EQ(r.outliers, 0.0);

  // A cloud far from the mesh covers nothing: the ratio is infinite.
  PointCloud far;
  far.points = {{10, 10, 10}};
  const EvalResult rf = evaluate(far, sphere, config);
  EXPECT_EQ(rf.coverage, 0.0);
  EXPECT_EQ(rf.outliers, 1.0);
  EXPECT_TRUE(std::isinf(rf.median_to_coverage));
}

TEST(Evaluate, OutliersMedianMeanHistogramExact) {
  const TriangleMesh plane = square(10.0f);
  PointCloud cloud;
  const float heights[] = {0.01f, 0.06f, 0.09f, -0.11f, 0.5f};  // unsigned: 0.11 counts
  for (int i = 0; i < 5; ++i) cloud.points.push_back({1.0f + i, 5.0f, heights[i]});
  EvalConfig config;
  config.outlier_radius = 0.10;
  config.histogram_max = 0.20;
  config.histogram_bins = 4;
  config.samples_per_cm2 = 0.01;  // 100 m² plane: coverage is not under test here
  const EvalResult r = evaluate(cloud, plane, config);
  EXPECT_EQ(r.num_points, 5u);
  EXPECT_DOUBLE_EQ(r.outliers, 0.4);
  EXPECT_NEAR(r.median_error, 0.09, 1e-7);
  EXPECT_NEAR(r.mean_error, (0.01 + 0.06 + 0.09 + 0.11 + 0.5) / 5, 1e-7);
  ASSERT_EQ(r.histogram_edges.size(), 5u);
  EXPECT_DOUBLE_EQ(r.histogram_edges.back(), 0.20);
  EXPECT_EQ(r.histogram, (std::vector<std::size_t>{1, 2, 1, 1}));  // 0.5 overflows into the last
  EXPECT_EQ(r.coverage_radius, config.coverage_radius);
  EXPECT_EQ(r.outlier_radius, 0.10);

  // Even count: the median averages the two middle errors.
  cloud.points.pop_back();
  EXPECT_NEAR(evaluate(cloud, plane, config).median_error, (0.06 + 0.09) / 2, 1e-7);
}

TEST(SampleSurface, DeterministicAndUniform) {
  // Unit square as a fan of four unequal triangles around an off-centre point.
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.8f, 0.3f, 0}};
  m.triangles = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
  const std::size_t n = 200000;
  const auto a = sample_surface(m, n, 11);
  const auto b = sample_surface(m, n, 11);
  const auto c = sample_surface(m, n, 12);
  ASSERT_EQ(a.size(), n);
  EXPECT_TRUE(a == b);
  EXPECT_FALSE(a == c);
  std::size_t left = 0, low = 0, corner = 0;
  for (const auto& p : a) {
    ASSERT_GE(p.x(), 0.0f);
    ASSERT_LE(p.x(), 1.0f);
    ASSERT_GE(p.y(), 0.0f);
    ASSERT_LE(p.y(), 1.0f);
    ASSERT_EQ(p.z(), 0.0f);
    left += p.x() < 0.5f;
    low += p.y() < 0.25f;
    corner += p.x() > 0.7f && p.y() > 0.7f;
  }
  // Binomial standard deviations are below 0.0012: 0.006 is five of them.
  EXPECT_NEAR(left / static_cast<double>(n), 0.5, 0.006);
  EXPECT_NEAR(low / static_cast<double>(n), 0.25, 0.006);
  EXPECT_NEAR(corner / static_cast<double>(n), 0.09, 0.006);
  EXPECT_TRUE(sample_surface(m, 0, 1).empty());
}

TEST(Evaluate, ErrorsAndEmptyCloud) {
  const TriangleMesh plane = square(1.0f);
  PointCloud cloud;
  cloud.points = {{0.5f, 0.5f, 0.01f}};
  EXPECT_THROW(evaluate(cloud, TriangleMesh{}, EvalConfig{}), Error);
  EXPECT_THROW(MeshDistance{TriangleMesh{}}, Error);
  EXPECT_THROW(sample_surface(TriangleMesh{}, 10, 1), Error);

  const auto expect_names = [&](EvalConfig c, const char* field) {
    try {
      evaluate(cloud, plane, c);
      ADD_FAILURE() << "no error for bad " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  EvalConfig c;
  c.coverage_radius = 0;
  expect_names(c, "coverage_radius");
  c = EvalConfig{};
  c.outlier_radius = -1;
  expect_names(c, "outlier_radius");
  c = EvalConfig{};
  c.samples_per_cm2 = NAN;
  expect_names(c, "samples_per_cm2");
  c = EvalConfig{};
  c.histogram_bins = 0;
  expect_names(c, "histogram_bins");
  c = EvalConfig{};
  c.histogram_max = 0;
  expect_names(c, "histogram_max");

  TriangleMesh bad = plane;
  bad.triangles.push_back({0, 1, 7});
  EXPECT_THROW(MeshDistance{bad}, Error);
  PointCloud nan_cloud;
  nan_cloud.points = {{NAN, 0, 0}};
  EXPECT_THROW(evaluate(nan_cloud, plane, EvalConfig{}), Error);

  const EvalResult r = evaluate(PointCloud{}, plane, EvalConfig{});
  EXPECT_EQ(r.num_points, 0u);
  EXPECT_EQ(r.coverage, 0.0);
  EXPECT_TRUE(std::isnan(r.outliers));
  EXPECT_TRUE(std::isnan(r.median_error));
  EXPECT_TRUE(std::isnan(r.mean_error));
  EXPECT_TRUE(std::isnan(r.median_to_coverage));
  EXPECT_EQ(r.num_surface_samples, 10000u);  // 1 m² at 1 per cm²

  const auto j = nlohmann::json::parse(to_json(r));
  EXPECT_TRUE(j["median_error_m"].is_null());
  EXPECT_TRUE(j["median_to_coverage_cm_per_pct"].is_null());
  EXPECT_EQ(j["coverage"], 0.0);
  EXPECT_EQ(j["histogram"]["counts"].size(), 40u);
  EXPECT_NE(to_table(r).find("n/a"), std::string::npos);
}

TEST(Evaluate, JsonAndTable) {
  const TriangleMesh plane = square(1.0f);
  PointCloud cloud;
  cloud.points = {{0.5f, 0.5f, 0.02f}, {0.2f, 0.2f, 0.2f}};
  const EvalResult r = evaluate(cloud, plane, EvalConfig{});
  const auto j = nlohmann::json::parse(to_json(r));
  for (const char* key :
       {"num_points", "num_surface_samples", "median_error_m", "mean_error_m", "coverage",
        "outliers", "median_to_coverage_cm_per_pct", "coverage_radius_m", "outlier_radius_m"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["num_points"], 2);
  EXPECT_NEAR(j["median_error_m"].get<double>(), 0.11, 1e-6);
  EXPECT_DOUBLE_EQ(j["outliers"].get<double>(), 0.5);
  EXPECT_EQ(j["histogram"]["edges_m"].size(), 41u);
  EXPECT_EQ(j["histogram"]["counts"].size(), 40u);
  const std::string table = to_table(r, "plane");
  EXPECT_EQ(table.rfind("plane\n", 0), 0u);
  EXPECT_NE(table.find("11.00 cm"), std::string::npos) << table;
  EXPECT_NE(table.find("50.00 %"), std::string::npos) << table;
}

}  // namespace
}  // namespace sonar3d
