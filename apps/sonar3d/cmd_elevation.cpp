#include <fmt/core.h>

#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d::cli {

void add_elevation(CLI::App& app, const GlobalOptions&, Runner& run) {
  auto* cmd = app.add_subcommand(
      "elevation",
      "Top-view elevation map of a point cloud (thesis sec. 6.2.1): the highest height z per "
      "horizontal cell, written as GeoTIFF (local ENU, metres; no-data for empty cells).");
  struct Opts {
    std::string cloud, output, png;
    ElevationMapConfig cfg;
    double uint16_step_m = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("cloud", o->cloud, "point cloud (PLY, world frame: x East, y North, z up)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "GeoTIFF to write")->required();
  cmd->add_option("--cell-m", o->cfg.cell_m, "cell size, metres")->capture_default_str();
  cmd->add_option("--uint16-step-m", o->uint16_step_m,
                  "store heights as uint16 with this step, metres (default: float32)");
  cmd->add_option("--png", o->png, "also write a viewable PNG (colour map and colour bar)");
  cmd->callback([&run, o] {
    run = [o] {
      const PointCloud cloud = read_ply(o->cloud);
      const ElevationMap map = elevation_map_from_points(cloud, o->cfg);
      ElevationWriteOptions w;
      if (o->uint16_step_m != 0) {
        w.encoding = ElevationEncoding::UInt16;
        w.uint16_step_m = o->uint16_step_m;
      }
      write_elevation_geotiff(o->output, map, w);
      fmt::print(
          "elevation map {} x {} cells of {} m ({} with data) from {} points -> {} ({} "
          "bytes; the cloud: {} bytes)\n",
          map.cols, map.rows, map.cell_m, map.num_valid(), cloud.size(), o->output,
          std::filesystem::file_size(o->output), std::filesystem::file_size(o->cloud));
      if (!o->png.empty()) {
        const Eigen::Vector2f range = write_elevation_png(o->png, map);
        fmt::print("picture {} (heights {:.3f} to {:.3f} m)\n", o->png, range.x(), range.y());
      }
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
