// `sonar3d export rosbag`: a dataset as a ROS bag, so simulations replay in ROS stacks.
#include <fmt/core.h>

#include "commands.hpp"
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
  auto dataset = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto ros1 = std::make_shared<bool>(false);
  auto cfg = std::make_shared<RosbagExportConfig>();
  bag->add_option("dataset", *dataset, "dataset directory")
      ->required()
      ->check(CLI::ExistingDirectory);
  bag->add_option("-o,--output", *out, "bag to write (must not exist)")->required();
  bag->add_flag("--ros1", *ros1, "write a ROS 1 bag (v2.0) instead of a ROS 2 bag");
  bag->add_option("--compression", cfg->ros1_compression,
                  "ROS 1 chunk compression: none, bz2 or lz4")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "bz2", "lz4"}));
  bag->add_option("--sonar-topic", cfg->sonar_topic)->capture_default_str();
  bag->add_option("--nav-topic", cfg->nav_topic)->capture_default_str();
  bag->add_option("--package", cfg->message_package,
                  "message package of ProjectedSonarImage: marine_acoustic_msgs or acoustic_msgs")
      ->capture_default_str()
      ->check(CLI::IsMember({"marine_acoustic_msgs", "acoustic_msgs"}));
  bag->add_option("--world-frame", cfg->world_frame)->capture_default_str();
  bag->add_option("--base-frame", cfg->base_frame)->capture_default_str();
  bag->add_option("--sonar-frame", cfg->sonar_frame)->capture_default_str();
  bag->callback([&g, &run, dataset, out, ros1, cfg] {
    run = [&g, dataset, out, ros1, cfg] {
      // The output rule (core/output_dir.hpp): never the dataset, inside it, or a special file;
      // an existing path is refused by export_rosbag (a bag is always new).
      check_output_location(*out, output_policy(false, {*dataset}), "-o", "bag");
      cfg->wire = *ros1 ? RosWire::Ros1 : RosWire::Cdr;
      const RosbagExportResult r = export_rosbag(*dataset, *out, *cfg, !g.quiet);
      fmt::print("exported {} frames and {} navigation samples of {} to the {} bag {}\n", r.frames,
                 r.navigation_samples, *dataset, *ros1 ? "ROS 1" : "ROS 2", *out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
