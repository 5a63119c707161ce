#include <fmt/core.h>

#include "commands.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/preview.hpp"

namespace sonar3d::cli {

void add_preview(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "preview",
      "Save a dataset frame as a viewable PNG: the fan-shaped Cartesian view (sonar at "
      "the bottom, port on the left) or the polar image, colour-mapped.");
  struct Opts {
    std::string dataset, out;
    int frame = 0;
    bool polar = false, grey = false, overwrite = false;
    PreviewConfig cfg;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dataset", o->dataset, "dataset directory")->required();
  cmd->add_option("-o,--output", o->out,
                  "PNG file to write (an existing one only if sonar3d wrote it, with --overwrite)")
      ->required();
  add_overwrite_flag(cmd, o->overwrite, "a picture sonar3d wrote earlier");
  cmd->add_option("--frame", o->frame, "frame index (0-based)")->capture_default_str();
  cmd->add_flag("--polar", o->polar,
                "save the polar image (range bins × beams) instead of the fan");
  cmd->add_flag("--grey", o->grey, "grey levels instead of the JET colour map");
  cmd->add_option("--width", o->cfg.width, "fan picture width, pixels")->capture_default_str();
  cmd->add_option("--max", o->cfg.max_value,
                  "intensity at the top of the colour map (linear units; 0 = frame maximum)")
      ->capture_default_str();
  cmd->add_option("--gamma", o->cfg.gamma, "display gamma")->capture_default_str();
  cmd->callback([&run, o] {
    run = [o] {
      OutputFiles out(output_policy(o->overwrite, {o->dataset}));
      const std::filesystem::path png = out.add(o->out, OutputKind::Png, "-o");
      const Dataset ds = read_dataset(o->dataset);
      if (o->frame < 0 || static_cast<std::size_t>(o->frame) >= ds.size()) {
        throw Error("--frame " + std::to_string(o->frame) + " is out of range (dataset has " +
                    std::to_string(ds.size()) + " frames)");
      }
      o->cfg.fan = !o->polar;
      o->cfg.colormap = !o->grey;
      write_preview_png(png.string(), ds.load_frame(o->frame), ds.spec, o->cfg);
      out.commit();
      fmt::print("wrote {}\n", o->out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
