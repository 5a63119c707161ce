#include <fmt/core.h>

#include "commands.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/rosbag.hpp"

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

void add_import_aris(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "aris",
      "Import a Sound Metrics ARIS recording (.aris from ARISFish/ARIScope): samples × beams per "
      "frame, range window, per-frame times, bearings from Sound Metrics' beam tables; poses from "
      "the frame headers' navigation fields, a navigation file, or a fixed sonar. See "
      "docs/import.md.");
  auto file = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto nav = std::make_shared<std::string>();
  auto nav_format = std::make_shared<std::string>();
  auto convention = std::make_shared<std::string>("enu");
  auto angles = std::make_shared<std::string>("deg");
  auto source = std::make_shared<std::string>("auto");
  auto clock = std::make_shared<std::string>("pc");
  auto mount = std::make_shared<std::string>("0,0,0,0,0,0");
  auto aperture = std::make_shared<double>(0.0);
  auto cfg = std::make_shared<ArisImportConfig>();
  auto overwrite = std::make_shared<bool>(false);
  cmd->add_option("file", *file, "ARIS recording (.aris)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite)")
      ->required();
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->add_option("--nav", *nav,
                  "navigation file: TUM (T_world_vehicle) or CSV (time,x,y,z,roll,pitch,yaw), "
                  "timed onto the frames as `import frames` does")
      ->check(CLI::ExistingFile);
  cmd->add_option("--nav-format", *nav_format, "tum or csv (default: by extension)")
      ->check(CLI::IsMember({"tum", "csv"}));
  cmd->add_option("--nav-convention", *convention, "CSV frames: 'enu' or 'ned'")
      ->capture_default_str()
      ->check(CLI::IsMember({"enu", "ned"}));
  cmd->add_option("--angles", *angles, "CSV roll/pitch/yaw unit: deg or rad")
      ->capture_default_str()
      ->check(CLI::IsMember({"deg", "rad"}));
  cmd->add_option("--nav-source", *source,
                  "'auto' (--nav when given, else the frame headers), 'header' (Latitude/"
                  "Longitude/Depth/Heading/Pitch/Roll of each frame header), 'file' (--nav) or "
                  "'static' (a fixed sonar: identity poses)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "header", "file", "static"}));
  cmd->add_option("--clock", *clock,
                  "frame times from FrameTime ('pc', the recording PC) or sonarTimeStamp "
                  "('sonar')")
      ->capture_default_str()
      ->check(CLI::IsMember({"pc", "sonar"}));
  cmd->add_option("--mount", *mount,
                  "T_vehicle_sonar as x,y,z,roll,pitch,yaw (m, degrees; vehicle x forward, y "
                  "left, z up)")
      ->capture_default_str();
  cmd->add_option("--vertical-aperture-deg", *aperture,
                  "full vertical aperture (default: the model's, 14° or 3° telephoto)");
  cmd->add_option("--time-offset", cfg->time_offset,
                  "seconds added to frame times to reach the navigation clock")
      ->capture_default_str();
  cmd->add_flag("--drop-outside", cfg->drop_outside,
                "drop (and count) frames outside the navigation span instead of failing");
  cmd->add_flag("--drop-partial", cfg->drop_partial,
                "import the complete frames of a recording whose last frame was cut");
  cmd->callback([&g, &run, file, out, nav, nav_format, convention, angles, source, clock, mount,
                 aperture, cfg, overwrite] {
    run = [&g, file, out, nav, nav_format, convention, angles, source, clock, mount, aperture, cfg,
           overwrite] {
      cfg->navigation = *nav;
      cfg->navigation_format = *nav_format;
      cfg->navigation_csv.convention = parse_nav_convention(*convention);
      cfg->navigation_csv.degrees = *angles == "deg";
      cfg->nav_source = parse_aris_nav_source(*source);
      cfg->clock = parse_aris_clock(*clock);
      cfg->T_vehicle_sonar = parse_mounting(*mount);
      cfg->vertical_aperture_rad = *aperture * M_PI / 180;
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*file};
      if (!nav->empty()) policy.sources.push_back(*nav);
      OutputDirectory dest(*out, OutputKind::Dataset, policy);
      const ArisImportResult r = import_aris(*file, dest.staging(), *cfg, !g.quiet);
      dest.commit();
      for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}: {}\n", *file, w);
      static const char* kSource[] = {"auto", "frame headers", "navigation file", "static"};
      fmt::print("imported {} frames ({} samples × {} beams, {}) from {} to {}; poses: {}",
                 r.frames, r.info.samples, r.info.beams, r.spec.name, *file, *out,
                 kSource[static_cast<int>(r.nav_source)]);
      if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
      fmt::print("\n");
      fmt::print("sonar: {:.4f}–{:.4f} m, bearings {:.3f}° … {:.3f}°, {:.2f}° vertical\n",
                 r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                 r.spec.bearings_rad.back() * 180 / M_PI,
                 r.spec.vertical_aperture_rad * 180 / M_PI);
      return 0;
    };
  });
}

void add_import_rosbag(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "rosbag",
      "Import a ROS 2 bag (directory with metadata.yaml and .db3 files, or a .db3) or a ROS 1 "
      "bag (v2.0 .bag): marine_acoustic_msgs/ProjectedSonarImage (or acoustic_msgs/…) or "
      "sensor_msgs/Image + --sonar, navigation from nav_msgs/Odometry or "
      "geometry_msgs/PoseStamped(WithCovarianceStamped), mounting from --mount or /tf_static. "
      "See docs/import.md.");
  auto bag = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto mount = std::make_shared<std::string>();
  auto sonar = std::make_shared<std::string>();
  auto aperture = std::make_shared<double>(0.0);
  auto cfg = std::make_shared<RosbagImportConfig>();
  auto overwrite = std::make_shared<bool>(false);
  cmd->add_option("bag", *bag, "ROS 2 bag directory or .db3 file, or ROS 1 .bag file")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite)")
      ->required();
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->add_option("--sonar-topic", cfg->sonar_topic,
                  "topic of ProjectedSonarImage or sensor_msgs/Image messages (default: the one "
                  "topic of such a type)");
  cmd->add_option("--nav-topic", cfg->nav_topic,
                  "topic of nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                  "PoseWithCovarianceStamped (T_world_vehicle; default: the one topic of such a "
                  "type)");
  cmd->add_flag("--static", cfg->static_sonar, "a fixed sonar: no navigation, identity poses");
  cmd->add_option("--tf-topic", cfg->tf_topic, "static transforms (tf2_msgs/TFMessage)")
      ->capture_default_str();
  cmd->add_option("--base-frame", cfg->base_frame,
                  "vehicle frame of the mounting (default: the Odometry child_frame_id, else the "
                  "root of the static transforms above the sonar frame)");
  cmd->add_option("--mount", *mount,
                  "T_vehicle_sonar as x,y,z,roll,pitch,yaw (m, degrees; our FLU sonar frame), "
                  "instead of /tf_static");
  cmd->add_option("--sonar", *sonar,
                  "sensor YAML (sonar.yaml fields): required for sensor_msgs/Image; supplies the "
                  "vertical aperture and beam pattern a ProjectedSonarImage lacks")
      ->check(CLI::ExistingFile);
  cmd->add_option("--vertical-aperture-deg", *aperture,
                  "full vertical aperture (default: the messages' tx_beamwidths, or --sonar)");
  cmd->add_option("--time-offset", cfg->time_offset,
                  "seconds added to sonar stamps to reach the navigation clock")
      ->capture_default_str();
  cmd->add_flag("--drop-outside", cfg->drop_outside,
                "drop (and count) frames outside the navigation span instead of failing");
  cmd->callback([&g, &run, bag, out, mount, sonar, aperture, cfg, overwrite] {
    run = [&g, bag, out, mount, sonar, aperture, cfg, overwrite] {
      if (!mount->empty()) cfg->T_vehicle_sonar = parse_mounting(*mount);
      cfg->sonar_description = *sonar;
      cfg->vertical_aperture_rad = *aperture * M_PI / 180;
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*bag};
      if (!sonar->empty()) policy.sources.push_back(*sonar);
      OutputDirectory dest(*out, OutputKind::Dataset, policy);
      for (const auto& line : choose_rosbag_topics(*bag, *cfg)) print_note(line);
      const RosbagImportResult r = import_rosbag(*bag, dest.staging(), *cfg, !g.quiet);
      dest.commit();
      for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}: {}\n", *bag, w);
      fmt::print("imported {} frames ({} × {}, {}) from {} {} to {}", r.frames, r.spec.range_bins,
                 r.spec.beams(), r.sonar_type, r.format, *bag, *out);
      if (r.navigation_samples) {
        fmt::print("; {} navigation samples ({})", r.navigation_samples, r.nav_type);
      }
      if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
      fmt::print("\nmounting: {}\n", r.mounting_source);
      fmt::print("sonar: {:.4f}–{:.4f} m, bearings {:.3f}° … {:.3f}°, {:.2f}° vertical\n",
                 r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                 r.spec.bearings_rad.back() * 180 / M_PI,
                 r.spec.vertical_aperture_rad * 180 / M_PI);
      return 0;
    };
  });
}

void add_import_oculus(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "oculus",
      "Import a Blueprint Subsea Oculus raw ping stream (SimplePingResult v1/v2 messages one after "
      "another, as the sonar sends them): the bearing table, range lines, 8/16-bit samples and "
      "per-line gains of each ping; vertical aperture from the published specifications of the "
      "model the frequency identifies; poses from a navigation file or a fixed sonar. See "
      "docs/import.md.");
  auto file = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto nav = std::make_shared<std::string>();
  auto nav_format = std::make_shared<std::string>();
  auto convention = std::make_shared<std::string>("enu");
  auto angles = std::make_shared<std::string>("deg");
  auto clock = std::make_shared<std::string>("ping");
  auto gains = std::make_shared<std::string>("keep");
  auto mount = std::make_shared<std::string>("0,0,0,0,0,0");
  auto aperture = std::make_shared<double>(0.0);
  auto cfg = std::make_shared<OculusImportConfig>();
  auto overwrite = std::make_shared<bool>(false);
  cmd->add_option("file", *file, "raw Oculus ping stream")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", *out,
                  "dataset directory to write (must not exist, be empty, or be a sonar3d dataset "
                  "with --overwrite)")
      ->required();
  add_overwrite_flag(cmd, *overwrite, "an existing sonar3d dataset at --output");
  cmd->add_option("--nav", *nav,
                  "navigation file: TUM (T_world_vehicle) or CSV (time,x,y,z,roll,pitch,yaw), "
                  "timed onto the pings as `import frames` does")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--static", cfg->static_sonar, "a fixed sonar: no navigation, identity poses");
  cmd->add_option("--nav-format", *nav_format, "tum or csv (default: by extension)")
      ->check(CLI::IsMember({"tum", "csv"}));
  cmd->add_option("--nav-convention", *convention, "CSV frames: 'enu' or 'ned'")
      ->capture_default_str()
      ->check(CLI::IsMember({"enu", "ned"}));
  cmd->add_option("--angles", *angles, "CSV roll/pitch/yaw unit: deg or rad")
      ->capture_default_str()
      ->check(CLI::IsMember({"deg", "rad"}));
  cmd->add_option("--clock", *clock,
                  "ping times from pingStartTime ('ping': v2 seconds since power-up, v1 "
                  "nanosecond counter) or from the ping order ('rate', with --rate)")
      ->capture_default_str()
      ->check(CLI::IsMember({"ping", "rate"}));
  cmd->add_option("--rate", cfg->rate_hz, "pings per second for --clock rate");
  cmd->add_option("--gains", *gains,
                  "per-line gains of pings that carry them: 'keep' the samples as sent, or "
                  "'divide' each line by its gain (float32 TIFF frames)")
      ->capture_default_str()
      ->check(CLI::IsMember({"keep", "divide"}));
  cmd->add_flag("--mirror", cfg->mirror,
                "the stream's bearings are positive to starboard: mirror them (default: positive "
                "to port, docs/import.md §8)");
  cmd->add_option("--mount", *mount,
                  "T_vehicle_sonar as x,y,z,roll,pitch,yaw (m, degrees; vehicle x forward, y "
                  "left, z up)")
      ->capture_default_str();
  cmd->add_option("--vertical-aperture-deg", *aperture,
                  "full vertical aperture (default: the published one of the model and mode the "
                  "ping frequency identifies: 20° or 12°)");
  cmd->add_option("--time-offset", cfg->time_offset,
                  "seconds added to ping times to reach the navigation clock")
      ->capture_default_str();
  cmd->add_flag("--drop-outside", cfg->drop_outside,
                "drop (and count) pings outside the navigation span instead of failing");
  cmd->callback([&g, &run, file, out, nav, nav_format, convention, angles, clock, gains, mount,
                 aperture, cfg, overwrite] {
    run = [&g, file, out, nav, nav_format, convention, angles, clock, gains, mount, aperture, cfg,
           overwrite] {
      cfg->navigation = *nav;
      cfg->navigation_format = *nav_format;
      cfg->navigation_csv.convention = parse_nav_convention(*convention);
      cfg->navigation_csv.degrees = *angles == "deg";
      cfg->clock = parse_oculus_clock(*clock);
      cfg->gains = parse_oculus_gains(*gains);
      cfg->T_vehicle_sonar = parse_mounting(*mount);
      cfg->vertical_aperture_rad = *aperture * M_PI / 180;
      cfg->validate();
      OutputPolicy policy;
      policy.overwrite = *overwrite;
      policy.on_note = print_note;
      policy.sources = {*file};
      if (!nav->empty()) policy.sources.push_back(*nav);
      OutputDirectory dest(*out, OutputKind::Dataset, policy);
      const OculusImportResult r = import_oculus(*file, dest.staging(), *cfg, !g.quiet);
      dest.commit();
      for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}: {}\n", *file, w);
      fmt::print(
          "imported {} of {} pings (SimplePingResult v{}, {} lines × {} beams, {}-bit{}) "
          "from {} to {}; poses: {}",
          r.frames, r.pings, r.version, r.spec.range_bins, r.spec.beams(), r.spec.bit_depth,
          r.has_gains ? ", per-line gains" : "", *file, *out,
          cfg->static_sonar ? "static" : "navigation file");
      if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
      if (r.dropped_bytes) fmt::print("; dropped {} bytes of a cut last message", r.dropped_bytes);
      fmt::print("\n");
      fmt::print("sonar: {}, {:.4f}–{:.4f} m, bearings {:.2f}° … {:.2f}°, {:.1f}° vertical\n",
                 r.model, r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                 r.spec.bearings_rad.back() * 180 / M_PI,
                 r.spec.vertical_aperture_rad * 180 / M_PI);
      if (r.has_gains) fmt::print("gains: {:.6g} … {:.6g}\n", r.gain_min, r.gain_max);
      return 0;
    };
  });
}

}  // namespace

void add_import(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd =
      app.add_subcommand("import",
                         "Convert recordings into a sonar3d dataset: 'holoocean' (HoloOcean/neusis "
                         "pickles), 'frames' (images + timestamps + a navigation log), 'aris' "
                         "(Sound Metrics ARIS files), 'rosbag' (ROS 1 and ROS 2 bags), 'oculus' "
                         "(Blueprint Oculus ping "
                         "streams).");
  cmd->require_subcommand(1);
  add_import_holoocean(*cmd, g, run);
  add_import_frames(*cmd, g, run);
  add_import_aris(*cmd, g, run);
  add_import_rosbag(*cmd, g, run);
  add_import_oculus(*cmd, g, run);
}

}  // namespace sonar3d::cli
