#include <fmt/core.h>

#include <filesystem>
#include <limits>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
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
    std::unique_ptr<ConfigOptions<ElevationFileConfig>> config;
    bool overwrite = false;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("cloud", o->cloud, "point cloud (PLY, world frame: x East, y North, z up)")
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output,
                  "GeoTIFF to write (an existing one only if sonar3d wrote it, with --overwrite)");
  cmd->add_option("--png", o->png,
                  "also write a viewable PNG (colour map and colour bar); the GeoTIFF and the PNG "
                  "appear together or not at all");
  add_overwrite_flag(cmd, o->overwrite, "a GeoTIFF and PNG sonar3d wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  // Every setting (declared once, mapping/elevation_map.hpp): its flag, --print-config, --config.
  o->config = std::make_unique<ConfigOptions<ElevationFileConfig>>(cmd);
  cmd->callback([&run, o] {
    // The cloud and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->cloud.empty()) throw CLI::RequiredError("cloud");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o] {
      // The library's errors name its fields ("cell_m"): the user reads the flag.
      FlagNames names = o->config->flag_names();
      names.insert(names.end(), {{"cell_m", "--cell-m"}, {"uint16_step_m", "--uint16-step-m"}});
      return with_flag_names(names, [&] {
        ElevationFileConfig cfg = o->config->resolve("elevation");
        cfg.validate();
        if (o->config->print_if_requested(cfg, "elevation", "elevation")) return 0;
        OutputFiles out(output_policy(o->overwrite, {o->cloud}));  // checked before the work
        const std::filesystem::path tif = out.add(o->output, OutputKind::GeoTiff, "-o");
        const std::filesystem::path png =
            o->png.empty() ? std::filesystem::path() : out.add(o->png, OutputKind::Png, "--png");
        const PointCloud cloud = read_ply(o->cloud);
        const ElevationWriteOptions& w = cfg.geotiff;
        // The memory limit replaces the library's cell cap (the map indexes rows and columns as
        // int: beyond that, the estimate exceeds any default limit).
        cfg.map.max_cells = static_cast<std::size_t>(std::numeric_limits<int>::max());
        check_memory(estimate_elevation_memory(cloud, cfg.map, w, !o->png.empty(), "--cell-m"),
                     memory_limit_bytes(o->max_memory_gb), "elevation");
        const ElevationMap map = elevation_map_from_points(cloud, cfg.map);
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
