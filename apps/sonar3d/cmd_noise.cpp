#include <fmt/core.h>

#include <filesystem>

#include "commands.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/noise.hpp"

namespace sonar3d::cli {

void add_noise(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* noise = app.add_subcommand("noise", "Sonar noise models (thesis sec. 2.5.2).");
  noise->require_subcommand(1);
  auto* est = noise->add_subcommand(
      "estimate",
      "Estimate per-pixel noise mean and std from a dataset of open-water frames (no object in "
      "view). Writes OUT/mean.tiff and OUT/std.tiff (float32, range bins × beams, linear "
      "intensity), usable as a scene's noise model 'images' or a dataset's noise/.");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  est->add_option("dataset", *in, "dataset directory of open-water frames")->required();
  est->add_option("-o,--output", *out, "directory for mean.tiff and std.tiff (created)")
      ->required();
  est->callback([&g, &run, in, out] {
    run = [&g, in, out] {
      const Dataset ds = read_dataset(*in);
      NoiseEstimator estimator;
      Progress bar("noise", ds.size(), !g.quiet);
      for (std::size_t i = 0; i < ds.size(); ++i) {
        estimator.add(ds.load_frame(i));
        bar.add();
      }
      bar.finish();
      const NoiseImages n = estimator.result();
      std::filesystem::create_directories(*out);
      write_float_image((std::filesystem::path(*out) / "mean.tiff").string(), n.mean);
      write_float_image((std::filesystem::path(*out) / "std.tiff").string(), n.std);
      fmt::print("noise statistics from {} frames written to {}\n", estimator.count(), *out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
