#include <fmt/core.h>

#include <cmath>

#include "commands.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"

namespace sonar3d::cli {

void add_info(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "info",
      "Describe a dataset: sensor, frames, time span, trajectory length; checks that "
      "every frame has a pose and the first and last frames decode at the declared size.");
  auto dir = std::make_shared<std::string>();
  cmd->add_option("dataset", *dir, "dataset directory")->required();
  cmd->callback([&run, dir] {
    run = [dir] {
      const Dataset ds = read_dataset(*dir);
      const SonarSpec& s = ds.spec;
      fmt::print("dataset      {}\n", ds.root.string());
      fmt::print("sensor       {}\n", s.name);
      fmt::print("beams        {} over [{:.2f}°, {:.2f}°]{}\n", s.beams(), s.fov_min() / kDeg,
                 s.fov_max() / kDeg, s.uniform_bearings() ? " (uniform)" : " (table)");
      fmt::print("range        {:.3f} – {:.3f} m in {} bins of {:.2f} cm\n", s.r_min, s.r_max,
                 s.range_bins, s.range_resolution() * 100);
      fmt::print("aperture     {:.2f}° vertical, {} beam pattern\n", s.vertical_aperture_rad / kDeg,
                 BeamPattern::kind_name(s.beam_pattern.kind));
      fmt::print("intensity    {}-bit, scale {:.6g}\n", s.bit_depth, s.intensity_scale);
      fmt::print("frames       {}\n", ds.size());
      if (!ds.frames.empty()) {
        fmt::print("time span    {:.3f} – {:.3f} s\n", ds.frames.front().timestamp,
                   ds.frames.back().timestamp);
        double length = 0;
        Eigen::Vector3d prev = ds.T_world_sonar(0).translation();
        for (std::size_t i = 1; i < ds.size(); ++i) {
          const Eigen::Vector3d p = ds.T_world_sonar(i).translation();  // throws if no pose
          length += (p - prev).norm();
          prev = p;
        }
        fmt::print("sonar path   {:.3f} m\n", length);
        ds.load_frame(0);
        ds.load_frame(ds.size() - 1);
      }
      fmt::print("noise model  {}\n", ds.noise ? "noise/mean.tiff, noise/std.tiff" : "none");
      fmt::print("ground truth {}\n", ds.has_truth() ? "truth/scene.yaml" : "none");
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
