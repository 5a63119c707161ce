#pragma once
// Elevation maps of a surveyed field (thesis sec. 6.2.1): the highest observed height per
// horizontal cell. The thesis stores (North, East) cells and depths; sonar3d's world frame is local
// ENU (x East, y North, z up), so its North/East/Depth become y/x/−z here, and a map stores the
// height z. Rows run from the northern edge southward (image convention), columns from west to
// east: cell (row, col) covers x ∈ [x0 + col·c, x0 + (col+1)·c), y ∈ [y0 − (row+1)·c, y0 − row·c)
// with (x0, y0) = origin_xy, the north-west corner, and c = cell_m. Maps made from points put
// their corners on multiples of c, so maps at one resolution share one world grid.
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"

namespace sonar3d {

struct ElevationMap {
  Eigen::Vector2d origin_xy = Eigen::Vector2d::Zero();  // world x, y of the north-west corner, m
  double cell_m = 0.02;                                 // cell size, m
  int rows = 0, cols = 0;
  std::vector<float> z;  // rows·cols heights, row-major; NaN = no data (cell never observed)

  static constexpr float kNoData = std::numeric_limits<float>::quiet_NaN();

  bool empty() const { return rows == 0 || cols == 0; }
  bool valid(int row, int col) const { return z[index(row, col)] == z[index(row, col)]; }
  float at(int row, int col) const { return z[index(row, col)]; }
  float& at(int row, int col) { return z[index(row, col)]; }
  std::size_t index(int row, int col) const {
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(cols) +
           static_cast<std::size_t>(col);
  }
  // World x, y of a cell's centre.
  Eigen::Vector2d cell_center_xy(int row, int col) const {
    return {origin_xy.x() + (col + 0.5) * cell_m, origin_xy.y() - (row + 0.5) * cell_m};
  }
  std::size_t num_valid() const;
};

struct ElevationMapConfig {
  double cell_m = 0.02;  // cell size (the thesis maps at 2 cm), m
  // Region to map (world x/y, m). Empty (min > max) = the cloud's horizontal extent.
  Eigen::Vector2d region_min_xy{1, 1}, region_max_xy{0, 0};
  // Refuses maps with more cells than this (a cloud spread over kilometres at 2 cm would
  // otherwise allocate gigabytes): 4·10^8 cells = 1.6 GB of float32.
  std::size_t max_cells = 400'000'000;

  void validate() const;  // throws Error naming the parameter
};

// The one declaration of ElevationMapConfig's settings (core/params.hpp). The region (two 2D
// corners) and max_cells are the caller's: sonar3d elevation replaces the cell cap by its memory
// limit (--max-memory).
template <class V>
void describe(ElevationMapConfig& c, V& v) {
  v.field(c.cell_m, params::param("cell_m", "m", "cell size of the map (the thesis maps at 2 cm)")
                        .positive()
                        .equation("sec. 6.2.1")
                        .flag("--cell-m"));
}

// Sec. 6.2.1: each cell keeps the highest z of the points that fall in it (a downward-looking
// sonar sees the top of what is below it); cells without points hold no data. Non-finite points
// are an error naming their index.
ElevationMap elevation_map_from_points(const PointCloud& cloud_world,
                                       const ElevationMapConfig& config);

// How a map is stored in a GeoTIFF. Absent uint16_step_m: heights as float32, no-data = NaN
// (GDAL's no-data tag set to nan). Given: quantised to uint16, z = offset + scale·q with scale =
// uint16_step_m, q ∈ [0, 65534], q = 65535 = no data.
struct ElevationWriteOptions {
  params::Maybe uint16_step_m;  // m
};
template <class V>
void describe(ElevationWriteOptions& c, V& v) {
  v.field(c.uint16_step_m,
          params::param("uint16_step_m", "m",
                        "store heights as uint16 with this step (none: float32, NaN for no data)")
              .positive()
              .flag("--uint16-step-m"));
}

// sonar3d elevation's settings: the map, and how it is stored.
struct ElevationFileConfig {
  ElevationMapConfig map;
  ElevationWriteOptions geotiff;
  void validate() const;  // throws Error naming the parameter
};
template <class V>
void describe(ElevationFileConfig& c, V& v) {
  v.group("map", c.map);
  v.group("geotiff", c.geotiff);
}

// GeoTIFF through GDAL: geotransform (origin, cell size, north-up), the no-data value, and for
// UInt16 the band's offset and scale; the CRS is a local engineering frame (local ENU, metres).
// Written atomically (temporary name, renamed when complete).
void write_elevation_geotiff(const std::string& path, const ElevationMap& map,
                             const ElevationWriteOptions& options = {});
// Cells of the elevation map elevation_map_from_points would lay out for this cloud (its
// region, or the points' extent, at config.cell_m), before anything is allocated.
double elevation_map_cells(const PointCloud& cloud_world, const ElevationMapConfig& config);

// Memory an elevation map of this cloud will take (core/memory.hpp), before it is allocated: the
// grid's float32 heights, the uint16 band when written so, the PNG picture when asked for.
// `cell_option` names the option that sets config.cell_m (e.g. "--cell-m").
MemoryEstimate estimate_elevation_memory(const PointCloud& cloud_world,
                                         const ElevationMapConfig& config,
                                         const ElevationWriteOptions& write, bool png,
                                         const std::string& cell_option);

// Reads a single-band north-up GeoTIFF written by write_elevation_geotiff (or any such raster
// with square cells), applying offset/scale and no-data. Errors name the file.
ElevationMap read_elevation_geotiff(const std::string& path);

// A viewable PNG: heights through a colour map (turbo), no-data cells black, a colour bar with
// the height range in metres on the right. Returns the [min, max] height shown.
Eigen::Vector2f write_elevation_png(const std::string& path, const ElevationMap& map);

}  // namespace sonar3d
