#include <fmt/core.h>

#include <filesystem>

#include "commands.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/noise.hpp"

namespace fs = std::filesystem;

namespace sonar3d::cli {
namespace {

// Writes `image` completely under `out`'s temporary name (renamed by out.commit()).
void write_float_image_to(const AtomicPath& out, const SonarImage& image) {
  const std::string tmp = out.temp().string() + ".tiff";  // the extension picks the encoder
  write_float_image(tmp, image);
  fs::rename(tmp, out.temp());
}

}  // namespace

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
                  "are left alone)")
      ->required();
  add_overwrite_flag(est, *overwrite, "existing mean.tiff and std.tiff in --output");
  est->callback([&g, &run, in, out, overwrite] {
    run = [&g, in, out, overwrite] {
      const fs::path dir = *out;
      if (fs::exists(dir) && !fs::is_directory(dir)) {
        throw Error("'" + dir.string() + "' exists and is not a directory; choose another -o");
      }
      for (const char* name : {"mean.tiff", "std.tiff"}) {
        if (fs::exists(dir / name) && !*overwrite) {
          throw Error("'" + (dir / name).string() +
                      "' exists: pass --overwrite to replace it, or choose another -o");
        }
      }
      const Dataset ds = read_dataset(*in);
      NoiseEstimator estimator;
      Progress bar("noise", ds.size(), !g.quiet);
      for (std::size_t i = 0; i < ds.size(); ++i) {
        estimator.add(ds.load_frame(i));
        bar.add();
      }
      bar.finish();
      const NoiseImages n = estimator.result();
      fs::create_directories(dir);
      // Both images are written completely (and flushed) before either gets its final name, and
      // std.tiff is renamed first: a final-named mean.tiff always has its std.tiff beside it,
      // whatever fails (a full disk) or stops the run.
      AtomicPath mean(dir / "mean.tiff"), std_dev(dir / "std.tiff");
      write_float_image_to(mean, n.mean);
      write_float_image_to(std_dev, n.std);
      std_dev.commit();
      mean.commit();
      fmt::print("noise statistics from {} frames written to {}\n", estimator.count(), *out);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
