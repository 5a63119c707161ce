// Memory estimates of the world model and of the change detection (issue 29 item 5,
// core/memory.hpp): made from the options and the clouds' extent before either allocates its
// grids, so that a cell size given in the wrong unit is refused with the estimate and the flag
// to change instead of ending in std::bad_alloc.
#include <algorithm>
#include <cmath>
#include <limits>

#include "sonar3d/world/change.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d {

namespace {

// Cells of a north-up grid of `cell_m` over the horizontal extent of the clouds' points (NaN
// points skipped); 0 for no finite point.
double extent_cells(const std::vector<const PointCloud*>& clouds, double cell_m) {
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const PointCloud* c : clouds) {
    for (const auto& p : c->points) {
      if (!std::isfinite(p.x()) || !std::isfinite(p.y())) continue;
      x0 = std::min(x0, static_cast<double>(p.x()));
      x1 = std::max(x1, static_cast<double>(p.x()));
      y0 = std::min(y0, static_cast<double>(p.y()));
      y1 = std::max(y1, static_cast<double>(p.y()));
    }
  }
  if (!(x1 >= x0)) return 0;
  return (std::floor((x1 - x0) / cell_m) + 2) * (std::floor((y1 - y0) / cell_m) + 2);
}

}  // namespace

MemoryEstimate estimate_world_model_memory(const PointCloud& cloud_world,
                                           const WorldModelConfig& config) {
  config.validate();
  MemoryEstimate e;
  const bool colours = cloud_world.has_color();
  for (std::size_t k = 0; k < config.seabed.lod_cells_m.size(); ++k) {
    const double c = config.seabed.lod_cells_m[k];
    const double cells = extent_cells({&cloud_world}, c);
    // Per cell, at most: its height (4 B) and fill mask (1 B), a mesh vertex (12 B), two
    // triangles (24 B), the vertex colour and its count when the cloud is coloured (16 B), and
    // the copies the PLY and glTF writers make of the vertices and triangles (36 B).
    const double per_cell = 4 + 1 + 12 + 24 + (colours ? 16 : 0) + 36;
    e.add(grid_part("seabed level of detail " + std::to_string(k) + " (heights, mesh, writers)",
                    cells, c),
          cells * per_cell, "--lod-cells");
  }
  // The seabed's points (those no placed model explains) and the explained flags.
  e.add("the cloud's seabed copy and flags",
        static_cast<double>(cloud_world.size()) * (sizeof(Eigen::Vector3f) + 1));
  return e;
}

MemoryEstimate estimate_change_memory(const PointCloud& a_world, const PointCloud& b_world,
                                      const ChangeConfig& config, bool colour) {
  config.validate();
  MemoryEstimate e;
  const double na = static_cast<double>(a_world.size()), nb = static_cast<double>(b_world.size());
  // The registration (register_surveys): each survey's elevation map at the yaw search's cell and
  // at the final cell (4 B a cell), B's map turned for each yaw tried and the shift search's
  // cost buffers (as much again): over both clouds' extent, which holds B's turned map too.
  const auto& r = config.registration;
  const double yaw_cells = extent_cells({&a_world, &b_world}, r.yaw_cell_m);
  e.add(grid_part("registration maps of the yaw search", yaw_cells, r.yaw_cell_m),
        yaw_cells * 4 * 4.0, "--yaw-cell");
  const double reg_cells = extent_cells({&a_world, &b_world}, r.cell_m);
  e.add(grid_part("registration maps of the final shift search", reg_cells, r.cell_m),
        reg_cells * 4 * 4.0, "--registration-cell");
  // The height change map: A's and B's heights, their 3x3 ranges, the difference (4 B each), the
  // significance mask (1 B) and region labels (4 B).
  const double change_cells = extent_cells({&a_world, &b_world}, config.cell_m);
  e.add(grid_part("height change map (heights, ranges, differences, labels)", change_cells,
                  config.cell_m),
        change_cells * (5 * 4.0 + 1 + 4), "--cell");
  if (colour) {
    // Colour sums (3 doubles) and counts (4 B) per survey, the compared colours and labels.
    const double cc = extent_cells({&a_world, &b_world}, config.colour.cell_m);
    e.add(grid_part("colour change maps", cc, config.colour.cell_m), cc * (2 * 28.0 + 16),
          "--colour-cell");
  }
  e.add("survey B moved into A's frame, and both surveys' working copies",
        (na + nb) * 12 + nb * 12);
  return e;
}

}  // namespace sonar3d
