#include <fmt/core.h>

#include <filesystem>
#include <limits>
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
    bool overwrite = false;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("cloud", o->cloud, "point cloud (PLY, world frame: x East, y North, z up)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output,
                  "GeoTIFF to write (an existing one only if sonar3d wrote it, with --overwrite)")
      ->required();
  cmd->add_option("--cell-m", o->cfg.cell_m, "cell size, metres")->capture_default_str();
  cmd->add_option("--uint16-step-m", o->uint16_step_m,
                  "store heights as uint16 with this step, metres (default: float32)");
  cmd->add_option("--png", o->png,
                  "also write a viewable PNG (colour map and colour bar); the GeoTIFF and the PNG "
                  "appear together or not at all");
  add_overwrite_flag(cmd, o->overwrite, "a GeoTIFF and PNG sonar3d wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  static const FlagNames kFlags = {{"cell_m", "--cell-m"}, {"uint16_step_m", "--uint16-step-m"}};
  cmd->callback([&run, o] {
    run = [o] {
      return with_flag_names(kFlags, [&] {
        OutputFiles out(output_policy(o->overwrite, {o->cloud}));  // checked before the work
        const std::filesystem::path tif = out.add(o->output, OutputKind::GeoTiff, "-o");
        const std::filesystem::path png =
            o->png.empty() ? std::filesystem::path() : out.add(o->png, OutputKind::Png, "--png");
        const PointCloud cloud = read_ply(o->cloud);
        ElevationWriteOptions w;
        if (o->uint16_step_m != 0) {
          w.encoding = ElevationEncoding::UInt16;
          w.uint16_step_m = o->uint16_step_m;
        }
        // The memory limit replaces the library's cell cap (the map indexes rows and columns as
        // int: beyond that, the estimate exceeds any default limit).
        o->cfg.max_cells = static_cast<std::size_t>(std::numeric_limits<int>::max());
        check_memory(estimate_elevation_memory(cloud, o->cfg, w, !o->png.empty(), "--cell-m"),
                     memory_limit_bytes(o->max_memory_gb), "elevation");
        const ElevationMap map = elevation_map_from_points(cloud, o->cfg);
        write_elevation_geotiff(tif.string(), map, w);
        const auto tif_bytes = std::filesystem::file_size(tif);
        Eigen::Vector2f range(0, 0);
        if (!o->png.empty()) range = write_elevation_png(png.string(), map);
        out.commit();  // the GeoTIFF and its picture together
        fmt::print(
            "elevation map {} x {} cells of {} m ({} with data) from {} points -> {} ({} "
            "bytes; the cloud: {} bytes)\n",
            map.cols, map.rows, map.cell_m, map.num_valid(), cloud.size(), o->output, tif_bytes,
            std::filesystem::file_size(o->cloud));
        if (!o->png.empty()) {
          fmt::print("picture {} (heights {:.3f} to {:.3f} m)\n", o->png, range.x(), range.y());
        }
        return 0;
      });
    };
  });
}

}  // namespace sonar3d::cli
