#include <fmt/core.h>

#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
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
    bool overwrite = false;
    std::unique_ptr<ConfigOptions<PreviewConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dataset", o->dataset, "dataset directory");
  cmd->add_option("-o,--output", o->out,
                  "PNG file to write (an existing one only if sonar3d wrote it, with --overwrite)");
  add_overwrite_flag(cmd, o->overwrite, "a picture sonar3d wrote earlier");
  cmd->add_option("--frame", o->frame, "frame index (0-based)")->capture_default_str();
  // The picture's settings (declared once, io/preview.hpp): --polar, --grey, --width, --max,
  // --gamma, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<PreviewConfig>>(cmd);
  cmd->callback([&run, o] {
    // The dataset and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->dataset.empty()) throw CLI::RequiredError("dataset");
      if (o->out.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o] {
      const PreviewConfig cfg = with_flag_names(o->config->flag_names(), [&] {
        const PreviewConfig c = o->config->resolve("preview");
        params::check(c, "preview");
        return c;
      });
      if (o->config->print_if_requested(cfg, "preview", "preview")) return 0;
      OutputFiles out(output_policy(o->overwrite, {o->dataset}));
      const std::filesystem::path png = out.add(o->out, OutputKind::Png, "-o");
      const Dataset ds = read_dataset(o->dataset);
      if (o->frame < 0 || static_cast<std::size_t>(o->frame) >= ds.size()) {
        throw Error("--frame " + std::to_string(o->frame) + " is out of range (dataset has " +
                    std::to_string(ds.size()) + " frames)");
      }
      write_preview_png(png.string(), ds.load_frame(o->frame), ds.spec, cfg);
      out.commit();
      fmt::print("wrote {}\n", o->out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
