// Procedural seabed: smooth relief (a few random plane waves), straight trenches with a Gaussian
// profile, and rocks as Gaussian bumps.
#include "sonar3d/sim/terrain.hpp"

#include <fmt/core.h>

#include <cmath>
#include <random>
#include <string>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void TerrainConfig::validate() const {
  require_positive(size.x(), "terrain.size[0]", "m");
  require_positive(size.y(), "terrain.size[1]", "m");
  require_positive(cell_m, "terrain.cell", "m");
  require_non_negative(relief_m, "terrain.relief", "m");
  require_positive(wavelength_m, "terrain.wavelength", "m");
  require(trenches >= 0 && trenches <= 1000, "terrain.trenches: must be within 0-1000");
  require_non_negative(trench_depth_m, "terrain.trench_depth", "m");
  require_positive(trench_width_m, "terrain.trench_width", "m");
  require(rocks >= 0 && rocks <= 1000000, "terrain.rocks: must be within 0-1000000");
  require_positive(rock_radius_m, "terrain.rock_radius", "m");
  const double nx = std::ceil(size.x() / cell_m) + 1, ny = std::ceil(size.y() / cell_m) + 1;
  require(nx * ny <= static_cast<double>(max_vertices),
          // Printed as a double: the count may exceed every integer type (a size of 1e90 m).
          "terrain: " + fmt::format("{:.4g}", nx * ny) +
              " vertices at terrain.cell = " + std::to_string(cell_m) + " m exceed " +
              std::to_string(max_vertices) + ": use a larger cell");
}

Terrain::Terrain(const TerrainConfig& config) : config_(config) {
  config_.validate();
  std::mt19937_64 rng(config_.seed ^ 0x7E55A1Dull);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double two_pi = 2 * M_PI;
  // Relief: four plane waves, wavelengths 0.6–1.6× the typical one, amplitudes summing to the
  // relief amplitude.
  for (int i = 0; i < 4; ++i) {
    const double dir = two_pi * u01(rng);
    const double lambda = config_.wavelength_m * (0.6 + u01(rng));
    waves_.push_back({Eigen::Vector2d(std::cos(dir), std::sin(dir)) * (two_pi / lambda),
                      two_pi * u01(rng), config_.relief_m / 4});
  }
  const Eigen::Vector2d half = 0.5 * config_.size;
  auto inside = [&] {
    return Eigen::Vector2d((2 * u01(rng) - 1) * half.x(), (2 * u01(rng) - 1) * half.y());
  };
  for (int i = 0; i < config_.trenches; ++i) {
    const double dir = M_PI * u01(rng);
    trenches_.push_back({inside(), Eigen::Vector2d(-std::sin(dir), std::cos(dir))});
  }
  for (int i = 0; i < config_.rocks; ++i) {
    rocks_.push_back({inside(), config_.rock_radius_m * (0.5 + u01(rng))});
  }
}

double Terrain::height(double x, double y) const {
  const Eigen::Vector2d p(x, y);
  double z = 0;
  for (const Wave& w : waves_) z += w.amplitude * std::sin(w.k.dot(p) + w.phase);
  const double s = 0.5 * config_.trench_width_m;
  for (const Trench& t : trenches_) {
    const double d = (p - t.point).dot(t.normal);
    z -= config_.trench_depth_m * std::exp(-d * d / (2 * s * s));
  }
  for (const Rock& r : rocks_) {
    const double q = (p - r.center).squaredNorm();
    if (q < 16 * r.radius * r.radius)
      z += 0.6 * r.radius * std::exp(-q / (2 * 0.25 * r.radius * r.radius));
  }
  return z;
}

TriangleMesh Terrain::mesh() const {
  const int nx = static_cast<int>(std::ceil(config_.size.x() / config_.cell_m));
  const int ny = static_cast<int>(std::ceil(config_.size.y() / config_.cell_m));
  const double x0 = -0.5 * config_.size.x(), y0 = -0.5 * config_.size.y();
  const double dx = config_.size.x() / nx, dy = config_.size.y() / ny;
  TriangleMesh m;
  m.vertices.reserve(static_cast<std::size_t>(nx + 1) * (ny + 1));
  m.triangles.reserve(static_cast<std::size_t>(nx) * ny * 2);
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const double x = x0 + i * dx, y = y0 + j * dy;
      m.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y),
                              static_cast<float>(height(x, y)));
    }
  }
  auto v = [&](int i, int j) { return j * (nx + 1) + i; };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {  // counter-clockwise seen from +z
      m.triangles.emplace_back(v(i, j), v(i + 1, j), v(i + 1, j + 1));
      m.triangles.emplace_back(v(i, j), v(i + 1, j + 1), v(i, j + 1));
    }
  }
  return m;
}

}  // namespace sonar3d
