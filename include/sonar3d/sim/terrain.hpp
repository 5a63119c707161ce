#pragma once
// A procedural seabed for field scenes (thesis sec. 6.2.2.2: mud and rock, trenches): a height
// field z(x, y) over a rectangle centred on the origin, meshed at a chosen cell size.
#include <Eigen/Core>
#include <vector>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

struct TerrainConfig {
  Eigen::Vector2d size{50, 34};           // x, y extent, m
  double cell_m = 0.05;                   // mesh cell, m
  double relief_m = 0.3;                  // amplitude of the smooth relief, m
  double wavelength_m = 8.0;              // typical wavelength of the relief, m
  int trenches = 2;                       // straight trenches across the area
  double trench_depth_m = 0.3;            // m
  double trench_width_m = 0.6;            // m (between the inflexion points of the profile)
  int rocks = 30;                         // scattered rocks
  double rock_radius_m = 0.25;            // typical rock radius, m (each 0.5–1.5× this)
  unsigned long long seed = 1;            // same seed, same seabed
  std::size_t max_vertices = 20'000'000;  // refuses larger meshes before allocating

  void validate() const;  // throws Error naming the field
};

// The height field: deterministic in (config, x, y).
class Terrain {
 public:
  explicit Terrain(const TerrainConfig& config);
  double height(double x, double y) const;
  TriangleMesh mesh() const;  // counter-clockwise seen from +z (upward normals)
  const TerrainConfig& config() const { return config_; }

 private:
  TerrainConfig config_;
  struct Wave {
    Eigen::Vector2d k;
    double phase, amplitude;
  };
  struct Trench {
    Eigen::Vector2d point, normal;
  };
  struct Rock {
    Eigen::Vector2d center;
    double radius;
  };
  std::vector<Wave> waves_;
  std::vector<Trench> trenches_;
  std::vector<Rock> rocks_;
};

}  // namespace sonar3d
