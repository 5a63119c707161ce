// `sonar3d export rosbag`: a dataset as a ROS bag, so simulations replay in ROS stacks.
#include <fmt/core.h>

#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/io/rosbag.hpp"

namespace sonar3d::cli {

void add_export(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand("export", "Write a dataset in another format: 'rosbag'.");
  cmd->require_subcommand(1);
  auto* bag = cmd->add_subcommand(
      "rosbag",
      "Write a dataset as a ROS 2 bag (sqlite3 directory; --ros1: a ROS 1 .bag): one "
      "ProjectedSonarImage per frame, the navigation as nav_msgs/Odometry, the mounting on "
      "/tf_static. See docs/import.md.");
  struct Opts {
    std::string dataset, out;
    bool ros1 = false;
    std::unique_ptr<ConfigOptions<RosbagExportConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  bag->add_option("dataset", o->dataset, "dataset directory")->check(CLI::ExistingDirectory);
  bag->add_option("-o,--output", o->out, "bag to write (must not exist)");
  bag->add_flag("--ros1", o->ros1,
                "write a ROS 1 bag (v2.0) instead of a ROS 2 bag (sets wire to ros1)");
  // Every setting (declared once, io/rosbag.hpp): its flag, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<RosbagExportConfig>>(bag);
  bag->callback([&g, &run, o] {
    // The dataset and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->dataset.empty()) throw CLI::RequiredError("dataset");
      if (o->out.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [&g, o] {
      // Errors in the settings name the user's flag (or the file, line and key).
      const RosbagExportConfig cfg = with_flag_names(o->config->flag_names(), [&] {
        RosbagExportConfig c = o->config->resolve("export");
        if (o->ros1) c.wire = RosWire::Ros1;  // a flag: over the file
        c.validate();
        return c;
      });
      if (o->config->print_if_requested(cfg, "export", "export rosbag")) return 0;
      // The output rule (core/output_dir.hpp): never the dataset, inside it, or a special
      // file; an existing path is refused by export_rosbag (a bag is always new).
      check_output_location(o->out, output_policy(false, {o->dataset}), "-o", "bag");
      const RosbagExportResult r = export_rosbag(o->dataset, o->out, cfg, !g.quiet);
      fmt::print("exported {} frames and {} navigation samples of {} to the {} bag {}\n", r.frames,
                 r.navigation_samples, o->dataset, cfg.wire == RosWire::Ros1 ? "ROS 1" : "ROS 2",
                 o->out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
