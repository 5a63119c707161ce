#include <fmt/core.h>

#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/noise.hpp"

namespace fs = std::filesystem;

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
  auto overwrite = std::make_shared<bool>(false);
  est->add_option("dataset", *in, "dataset directory of open-water frames")->required();
  est->add_option("-o,--output", *out,
                  "directory for mean.tiff and std.tiff (created if missing; other files in it "
                  "are left alone; never inside the dataset)")
      ->required();
  add_overwrite_flag(est, *overwrite, "existing mean.tiff and std.tiff in --output");
  est->callback([&g, &run, in, out, overwrite] {
    run = [&g, in, out, overwrite] {
      const fs::path dir = *out;
      const OutputPolicy policy = output_policy(*overwrite, {*in});
      check_output_location(dir, policy, "-o", "noise statistics");
      if (fs::exists(dir) && !fs::is_directory(dir)) {
        throw Error("'" + dir.string() + "' (-o) exists and is not a directory; choose another -o");
      }
      // mean.tiff and std.tiff: sonar3d's own only, with --overwrite; appear together or not at
      // all. A missing directory is created when the statistics are ready.
      std::unique_ptr<OutputFiles> files;
      fs::path mean_tmp, std_tmp;
      auto open_outputs = [&] {
        files = std::make_unique<OutputFiles>(policy);
        mean_tmp = files->add(dir / "mean.tiff", OutputKind::Tiff, "-o");
        std_tmp = files->add(dir / "std.tiff", OutputKind::Tiff, "-o");
      };
      if (fs::is_directory(dir)) open_outputs();  // fail fast
      const Dataset ds = read_dataset(*in);
      NoiseEstimator estimator;
      Progress bar("noise", ds.size(), !g.quiet);
      for (std::size_t i = 0; i < ds.size(); ++i) {
        estimator.add(ds.load_frame(i));
        bar.add();
      }
      bar.finish();
      const NoiseImages n = estimator.result();
      if (!files) {
        fs::create_directories(dir);
        open_outputs();
      }
      write_float_image(mean_tmp.string(), n.mean);
      write_float_image(std_tmp.string(), n.std);
      files->commit();
      fmt::print("noise statistics from {} frames written to {}\n", estimator.count(), *out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
