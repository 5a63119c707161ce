#include <fmt/core.h>

#include "commands.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"

namespace sonar3d::cli {
namespace {

void add_import_holoocean(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "holoocean",
      "Import a HoloOcean imaging-sonar recording as used by neusis, AONeuS and SonarSplat: "
      "DIR/Config.json (its ImagingSonar) and DIR/Data/N.pkl (ImagingSonar image, PoseSensor "
      "sensor-to-world pose). Pickles are decoded by python3 with numpy. See docs/import.md.");
  auto dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto bins = std::make_shared<std::string>("sample");
  auto cfg = std::make_shared<HoloOceanImportConfig>();
  auto overwrite = std::make_shared<bool>(false);
  cmd->add_option("dir", *dir, "HoloOcean dataset directory (Config.json, Data/)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite; never the input or inside it)")
      ->required();
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->add_option("--bins", *bins,
                  "pixel convention: 'sample' (neusis/AONeuS: row i at RangeMin + i·Δr, column j "
                  "at −Azimuth/2 + j·Δa) or 'cell' (HoloOcean's renderer: row i is the cell "
                  "[RangeMin + i·Δr, RangeMin + (i+1)·Δr))")
      ->capture_default_str()
      ->check(CLI::IsMember({"sample", "cell"}));
  cmd->add_option("--sensor", cfg->sensor,
                  "sensor_name of the ImagingSonar when Config.json has several");
  cmd->add_option("--image-key", cfg->image_key,
                  "pickle key of the image (default: the sensor's name, 'ImagingSonar')");
  cmd->add_option("--pose-key", cfg->pose_key, "pickle key of the 4×4 sensor-to-world pose")
      ->capture_default_str();
  cmd->add_option("--rate", cfg->frame_rate_hz,
                  "frames per second for the timestamps t = N / rate of Data/N.pkl (default: the "
                  "sensor's Hz, else 1)");
  cmd->add_option("--python", cfg->python,
                  "Python interpreter with numpy (default: $SONAR3D_PYTHON, /usr/bin/python3)");
  cmd->callback([&g, &run, dir, out, bins, cfg, overwrite] {
    run = [&g, dir, out, bins, cfg, overwrite] {
      cfg->bins = parse_holoocean_bins(*bins);
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*dir};
      OutputDirectory dest(*out, OutputKind::Dataset, policy);
      const HoloOceanImportResult r = import_holoocean(*dir, dest.staging(), *cfg, !g.quiet);
      dest.commit();
      for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}\n", w);
      fmt::print("imported {} frames ({}, {}×{}, {} bins) from {} to {}\n", r.frames, r.dtype,
                 r.sonar.range_bins, r.sonar.azimuth_bins, holoocean_bins_name(cfg->bins), *dir,
                 *out);
      fmt::print("sonar: {:.4f}–{:.4f} m, bearings {:.3f}° … {:.3f}°, {:.2f}° vertical (flat)\n",
                 r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                 r.spec.bearings_rad.back() * 180 / M_PI,
                 r.spec.vertical_aperture_rad * 180 / M_PI);
      return 0;
    };
  });
}

void add_import_frames(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "frames",
      "Import sonar frames recorded with their own timestamps plus a navigation log: each frame "
      "gets the navigation pose interpolated at its time (linear + slerp) times the sonar "
      "mounting T_vehicle_sonar of --sonar. See docs/import.md.");
  auto images = std::make_shared<std::string>();
  auto times = std::make_shared<std::string>();
  auto nav = std::make_shared<std::string>();
  auto nav_format = std::make_shared<std::string>();
  auto convention = std::make_shared<std::string>("enu");
  auto angles = std::make_shared<std::string>("deg");
  auto sonar = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto offset = std::make_shared<double>(0.0);
  auto drop = std::make_shared<bool>(false);
  auto overwrite = std::make_shared<bool>(false);
  cmd->add_option("--images", *images, "directory of frame images (PNG or float32 TIFF)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--times", *times, "CSV 'timestamp,file' (file relative to --images)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--nav", *nav,
                  "navigation: TUM (t tx ty tz qx qy qz qw, T_world_vehicle) or CSV "
                  "(time,x,y,z,roll,pitch,yaw)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--nav-format", *nav_format, "tum or csv (default: by extension)")
      ->check(CLI::IsMember({"tum", "csv"}));
  cmd->add_option("--nav-convention", *convention,
                  "CSV frames: 'enu' (x east, y north, z up; FLU vehicle, yaw CCW from east) or "
                  "'ned' (x north, y east, z down; FRD vehicle, heading CW from north)")
      ->capture_default_str()
      ->check(CLI::IsMember({"enu", "ned"}));
  cmd->add_option("--angles", *angles, "CSV roll/pitch/yaw unit: deg or rad")
      ->capture_default_str()
      ->check(CLI::IsMember({"deg", "rad"}));
  cmd->add_option("--sonar", *sonar,
                  "sensor YAML (sonar.yaml fields, may start from 'preset:'; T_vehicle_sonar is "
                  "the mounting)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--time-offset", *offset,
                  "seconds added to frame timestamps to reach the navigation clock")
      ->capture_default_str();
  cmd->add_flag("--drop-outside", *drop,
                "drop (and count) frames outside the navigation span instead of failing");
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite; never the input or inside it)")
      ->required();
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->callback([&g, &run, images, times, nav, nav_format, convention, angles, sonar, out, offset,
                 drop, overwrite] {
    run = [&g, images, times, nav, nav_format, convention, angles, sonar, out, offset, drop,
           overwrite] {
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*images, *times, *nav, *sonar};
      OutputDirectory dest(*out, OutputKind::Dataset, policy);
      FrameImportConfig cfg;
      cfg.images_dir = *images;
      cfg.times_csv = *times;
      cfg.navigation = *nav;
      cfg.navigation_format = *nav_format;
      cfg.navigation_csv.convention = parse_nav_convention(*convention);
      cfg.navigation_csv.degrees = *angles == "deg";
      cfg.spec = read_sonar_description(*sonar);
      cfg.time_offset = *offset;
      cfg.drop_outside = *drop;
      const FrameImportResult r = import_frames(cfg, dest.staging(), !g.quiet);
      dest.commit();
      fmt::print("imported {} frames ({:.3f} – {:.3f} s) with {} navigation samples to {}",
                 r.frames, r.first_time, r.last_time, r.navigation_samples, *out);
      if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
      fmt::print("\n");
      return 0;
    };
  });
}

}  // namespace

void add_import(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd =
      app.add_subcommand("import",
                         "Convert recordings into a sonar3d dataset: 'holoocean' (HoloOcean/neusis "
                         "pickles) or 'frames' (images + timestamps + a navigation log).");
  cmd->require_subcommand(1);
  add_import_holoocean(*cmd, g, run);
  add_import_frames(*cmd, g, run);
}

}  // namespace sonar3d::cli
