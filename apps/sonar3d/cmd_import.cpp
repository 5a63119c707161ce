#include <fmt/core.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/rosbag.hpp"

namespace sonar3d::cli {
namespace {

// What the bounds leave open and --print-config should not print: a navigation format that is
// none of tum/csv, a mounting that is not six numbers.
void check_declared(const HoloOceanImportConfig&) {}
void check_declared(const FrameImportConfig& c) {
  check_navigation_format(c.navigation_format, "navigation_format (--nav-format)");
}
void check_declared(const ArisImportConfig& c) {
  check_navigation_format(c.navigation_format, "navigation_format (--nav-format)");
  mounting_from_list(c.mount, "mount (--mount)");
}
void check_declared(const OculusImportConfig& c) {
  check_navigation_format(c.navigation_format, "navigation_format (--nav-format)");
  mounting_from_list(c.mount, "mount (--mount)");
}
void check_declared(const RosbagImportConfig& c) {
  if (!c.mount.empty()) mounting_from_list(c.mount, "mount (--mount)");  // else /tf_static
}

// What every import has: the recording (a positional, or the --images/--times/--nav of frames),
// -o, --overwrite, and its settings declared once beside the import's config (io/*.hpp): their
// flags, --print-config and --config FILE (the "import" block, as --print-config prints it).
template <class C>
struct ImportOptions {
  std::string input, output;
  bool overwrite = false;
  std::unique_ptr<ConfigOptions<C>> config;

  std::string input_name;
  // `name`: the positional recording (none for frames), checked by `check`.
  void add(CLI::App* cmd, const char* name, const char* help, const CLI::Validator& check) {
    if (name) {
      input_name = name;
      cmd->add_option(name, input, help)->check(check);
    }
    cmd->add_option("-o,--output", output,
                    "dataset directory to write (must not exist, be empty, or be a sonar3d "
                    "dataset with --overwrite; never the input or inside it)");
    add_overwrite_flag(cmd, overwrite, "an existing sonar3d dataset at --output");
    config = std::make_unique<ConfigOptions<C>>(cmd);
    // A mounting is six numbers after its flag ("x,y,z,roll,pitch,yaw" or space-separated), never
    // the positional that follows.
    if (CLI::Option* mount = cmd->get_option_no_throw("--mount")) {
      mount->expected(6)->allow_extra_args(false);
    }
  }
  // The recording and -o are required unless --print-config (a usage error, exit status 2).
  void require_inputs(bool positional) const {
    if (config->print_requested()) return;
    if (positional && input.empty()) throw CLI::RequiredError(input_name);
    if (output.empty()) throw CLI::RequiredError("-o,--output");
  }
  // The library names its fields; the user reads flags. Only names that cannot be prose words
  // ("vertical_aperture_deg", "mount (--mount)") are replaced.
  FlagNames flag_names() const {
    FlagNames out;
    for (const auto& [field, flag] : config->flag_names()) {
      if (field.find_first_of("_(.") != std::string::npos) out.emplace_back(field, flag);
    }
    return out;
  }
  // The effective settings (defaults, --config, flags), bounds checked; nullopt after printing
  // them for --print-config.
  std::optional<C> resolve(const std::string& kind) const {
    C cfg = with_flag_names(flag_names(), [&] {
      C c = config->resolve("import");
      params::check(c, "");
      check_declared(c);
      return c;
    });
    if (config->print_if_requested(cfg, "import", "import " + kind)) return std::nullopt;
    return cfg;
  }
  OutputPolicy policy(std::vector<std::filesystem::path> sources) const {
    OutputPolicy p;
    p.overwrite = overwrite;
    p.on_note = print_note;
    p.sources = std::move(sources);
    return p;
  }
};

void add_import_holoocean(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "holoocean",
      "Import a HoloOcean imaging-sonar recording as used by neusis, AONeuS and SonarSplat: "
      "DIR/Config.json (its ImagingSonar) and DIR/Data/N.pkl (ImagingSonar image, PoseSensor "
      "sensor-to-world pose). Pickles are decoded by python3 with numpy. See docs/import.md.");
  auto o = std::make_shared<ImportOptions<HoloOceanImportConfig>>();
  o->add(cmd, "dir", "HoloOcean dataset directory (Config.json, Data/)", CLI::ExistingDirectory);
  cmd->callback([&g, &run, o] {
    o->require_inputs(true);
    run = [&g, o] {
      const auto cfg = o->resolve("holoocean");
      if (!cfg) return 0;
      return with_flag_names(o->flag_names(), [&] {
        OutputDirectory dest(o->output, OutputKind::Dataset, o->policy({o->input}));
        const HoloOceanImportResult r = import_holoocean(o->input, dest.staging(), *cfg, !g.quiet);
        dest.commit();
        for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}\n", w);
        fmt::print("imported {} frames ({}, {}×{}, {} bins) from {} to {}\n", r.frames, r.dtype,
                   r.sonar.range_bins, r.sonar.azimuth_bins, holoocean_bins_name(cfg->bins),
                   o->input, o->output);
        fmt::print("sonar: {:.4f}–{:.4f} m, bearings {:.3f}° … {:.3f}°, {:.2f}° vertical (flat)\n",
                   r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                   r.spec.bearings_rad.back() * 180 / M_PI,
                   r.spec.vertical_aperture_rad * 180 / M_PI);
        return 0;
      });
    };
  });
}

void add_import_frames(CLI::App& parent, const GlobalOptions& g, Runner& run) {
  auto* cmd = parent.add_subcommand(
      "frames",
      "Import sonar frames recorded with their own timestamps plus a navigation log: each frame "
      "gets the navigation pose interpolated at its time (linear + slerp) times the sonar "
      "mounting T_vehicle_sonar of --sonar. See docs/import.md.");
  auto o = std::make_shared<ImportOptions<FrameImportConfig>>();
  auto sonar = std::make_shared<std::string>();
  cmd->add_option("--sonar", *sonar,
                  "sensor YAML (sonar.yaml fields, may start from 'preset:'; T_vehicle_sonar is "
                  "the mounting)")
      ->check(CLI::ExistingFile);
  o->add(cmd, nullptr, nullptr, CLI::ExistingFile);
  cmd->callback([&g, &run, o, sonar] {
    o->require_inputs(false);
    if (!o->config->print_requested() && sonar->empty()) throw CLI::RequiredError("--sonar");
    run = [&g, o, sonar] {
      auto cfg = o->resolve("frames");
      if (!cfg) return 0;
      return with_flag_names(o->flag_names(), [&] {
        cfg->spec = read_sonar_description(*sonar);
        cfg->validate();
        OutputDirectory dest(o->output, OutputKind::Dataset,
                             o->policy({cfg->images_dir, cfg->times_csv, cfg->navigation, *sonar}));
        const FrameImportResult r = import_frames(*cfg, dest.staging(), !g.quiet);
        dest.commit();
        fmt::print("imported {} frames ({:.3f} – {:.3f} s) with {} navigation samples to {}",
                   r.frames, r.first_time, r.last_time, r.navigation_samples, o->output);
        if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
        fmt::print("\n");
        return 0;
      });
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
  auto o = std::make_shared<ImportOptions<ArisImportConfig>>();
  o->add(cmd, "file", "ARIS recording (.aris)", CLI::ExistingFile);
  cmd->callback([&g, &run, o] {
    o->require_inputs(true);
    run = [&g, o] {
      const auto cfg = o->resolve("aris");
      if (!cfg) return 0;
      return with_flag_names(o->flag_names(), [&] {
        cfg->validate();
        std::vector<std::filesystem::path> sources = {o->input};
        if (!cfg->navigation.empty()) sources.push_back(cfg->navigation);
        OutputDirectory dest(o->output, OutputKind::Dataset, o->policy(sources));
        const ArisImportResult r = import_aris(o->input, dest.staging(), *cfg, !g.quiet);
        dest.commit();
        for (const auto& w : r.warnings) {
          fmt::print(stderr, "sonar3d: warning: {}: {}\n", o->input, w);
        }
        static const char* kSource[] = {"auto", "frame headers", "navigation file", "static"};
        fmt::print("imported {} frames ({} samples × {} beams, {}) from {} to {}; poses: {}",
                   r.frames, r.info.samples, r.info.beams, r.spec.name, o->input, o->output,
                   kSource[static_cast<int>(r.nav_source)]);
        if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
        fmt::print("\n");
        fmt::print("sonar: {:.4f}–{:.4f} m, bearings {:.3f}° … {:.3f}°, {:.2f}° vertical\n",
                   r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                   r.spec.bearings_rad.back() * 180 / M_PI,
                   r.spec.vertical_aperture_rad * 180 / M_PI);
        return 0;
      });
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
  auto o = std::make_shared<ImportOptions<RosbagImportConfig>>();
  o->add(cmd, "bag", "ROS 2 bag directory or .db3 file, or ROS 1 .bag file", CLI::ExistingPath);
  cmd->callback([&g, &run, o] {
    o->require_inputs(true);
    run = [&g, o] {
      auto cfg = o->resolve("rosbag");
      if (!cfg) return 0;
      return with_flag_names(o->flag_names(), [&] {
        std::vector<std::filesystem::path> sources = {o->input};
        if (!cfg->sonar_description.empty()) sources.push_back(cfg->sonar_description);
        OutputDirectory dest(o->output, OutputKind::Dataset, o->policy(sources));
        for (const auto& line : choose_rosbag_topics(o->input, *cfg)) print_note(line);
        const RosbagImportResult r = import_rosbag(o->input, dest.staging(), *cfg, !g.quiet);
        dest.commit();
        for (const auto& w : r.warnings) {
          fmt::print(stderr, "sonar3d: warning: {}: {}\n", o->input, w);
        }
        fmt::print("imported {} frames ({} × {}, {}) from {} {} to {}", r.frames, r.spec.range_bins,
                   r.spec.beams(), r.sonar_type, r.format, o->input, o->output);
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
      });
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
  auto o = std::make_shared<ImportOptions<OculusImportConfig>>();
  o->add(cmd, "file", "raw Oculus ping stream", CLI::ExistingFile);
  cmd->callback([&g, &run, o] {
    o->require_inputs(true);
    run = [&g, o] {
      const auto cfg = o->resolve("oculus");
      if (!cfg) return 0;
      return with_flag_names(o->flag_names(), [&] {
        cfg->validate();
        std::vector<std::filesystem::path> sources = {o->input};
        if (!cfg->navigation.empty()) sources.push_back(cfg->navigation);
        OutputDirectory dest(o->output, OutputKind::Dataset, o->policy(sources));
        const OculusImportResult r = import_oculus(o->input, dest.staging(), *cfg, !g.quiet);
        dest.commit();
        for (const auto& w : r.warnings) {
          fmt::print(stderr, "sonar3d: warning: {}: {}\n", o->input, w);
        }
        fmt::print(
            "imported {} of {} pings (SimplePingResult v{}, {} lines × {} beams, {}-bit{}) "
            "from {} to {}; poses: {}",
            r.frames, r.pings, r.version, r.spec.range_bins, r.spec.beams(), r.spec.bit_depth,
            r.has_gains ? ", per-line gains" : "", o->input, o->output,
            cfg->static_sonar ? "static" : "navigation file");
        if (r.dropped) fmt::print("; dropped {} outside the navigation span", r.dropped);
        if (r.dropped_bytes) {
          fmt::print("; dropped {} bytes of a cut last message", r.dropped_bytes);
        }
        fmt::print("\n");
        fmt::print("sonar: {}, {:.4f}–{:.4f} m, bearings {:.2f}° … {:.2f}°, {:.1f}° vertical\n",
                   r.model, r.spec.r_min, r.spec.r_max, r.spec.bearings_rad.front() * 180 / M_PI,
                   r.spec.bearings_rad.back() * 180 / M_PI,
                   r.spec.vertical_aperture_rad * 180 / M_PI);
        if (r.has_gains) fmt::print("gains: {:.6g} … {:.6g}\n", r.gain_min, r.gain_max);
        return 0;
      });
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
