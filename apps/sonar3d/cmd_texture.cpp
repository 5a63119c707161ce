// sonar3d texture: colour a point cloud from posed camera images (thesis sec. 6.4).
#include <fmt/core.h>

#include <cstdlib>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/video/texture_files.hpp"

namespace sonar3d::cli {

void add_texture(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "texture",
      "Colour a point cloud from posed camera images (thesis sec. 6.4): every image projected "
      "onto the points it sees, colours averaged in linear RGB; points hidden behind others in a "
      "frame take no colour from it. Poses from a COLMAP text model or an IDR/NeuS cameras .npz "
      "in the cloud's frame, or from a dataset's camera frames placed on its navigation.");
  auto job = std::make_shared<TextureFilesJob>();
  auto cloud = std::make_shared<std::string>(), colmap = std::make_shared<std::string>(),
       images = std::make_shared<std::string>(), output = std::make_shared<std::string>(),
       neus = std::make_shared<std::string>(), dataset = std::make_shared<std::string>(),
       sonar_navigation = std::make_shared<std::string>();
  cmd->add_option("cloud", *cloud,
                  "point cloud to colour (PLY), or with --mesh a mesh (any Assimp format); in the "
                  "poses' frame")
      ->check(CLI::ExistingFile);
  auto* colmap_opt = cmd->add_option("--colmap", *colmap,
                                     "COLMAP text model directory (cameras.txt, images.txt; "
                                     "colmap model_converter --output_type TXT)")
                         ->check(CLI::ExistingDirectory);
  auto* neus_opt =
      cmd->add_option("--neus", *neus,
                      "IDR/NeuS cameras_*.npz instead of --colmap: world_mat_i for the i-th image "
                      "of --images in name order")
          ->check(CLI::ExistingFile)
          ->excludes(colmap_opt);
  auto* dataset_opt =
      cmd->add_option("--dataset", *dataset,
                      "a dataset with camera frames (camera/ in docs/formats.md) instead: images "
                      "and intrinsics from camera/, poses from its navigation · T_vehicle_camera")
          ->check(CLI::ExistingDirectory)
          ->excludes(colmap_opt)
          ->excludes(neus_opt);
  auto navigation = std::make_shared<std::string>();
  cmd->add_option("--navigation", *navigation,
                  "with --dataset: place its camera frames on this navigation (TUM) instead of "
                  "its own, e.g. MAP/navigation_corrected.tum of sonar3d map, so that the video "
                  "lands where the corrected map is")
      ->check(CLI::ExistingFile)
      ->needs(dataset_opt);
  colmap_opt->excludes(neus_opt)->excludes(dataset_opt);
  neus_opt->excludes(dataset_opt);
  cmd->add_option("--sonar-navigation", *sonar_navigation,
                  "with --neus or --colmap: the sonar's navigation (TUM) in the cloud's world, to "
                  "warn when the camera centres lie far from it (the two worlds disagree)")
      ->check(CLI::ExistingFile)
      ->excludes(dataset_opt);
  cmd->add_option("--images", *images,
                  "with --colmap or --neus: the images: those named in images.txt, or with --neus "
                  "all of the directory in name order (8/16-bit: sRGB; float: linear)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", *output,
                  "coloured point cloud (PLY with uchar red green blue, sRGB); with --mesh a PLY "
                  "mesh with vertex colours, or a glTF 2.0 binary if it ends in .glb");
  // The colouring's and the poses' settings (declared once, video/texture_files.hpp): their
  // flags, --print-config, --config.
  auto config = std::make_shared<ConfigOptions<TextureFilesConfig>>(cmd);
  cmd->add_flag(
      "--mesh", job->is_mesh,
      "CLOUD is a mesh (any format Assimp reads, e.g. a registered CAD model): colour its "
      "vertices, visibility by ray casting the mesh itself; writes a PLY mesh");
  cmd->add_option("--texel", job->mesh.texel_m,
                  "with --mesh: subdivide until every edge is at most this long, m (0: as is)")
      ->capture_default_str();
  cmd->add_option("--occluder", job->occluders,
                  "with --mesh: a mesh in the same frame (any Assimp format; repeatable) that "
                  "hides CLOUD where it is in front but takes no colour, e.g. the seabed_lod0.ply "
                  "of `sonar3d world` under a half-buried model")
      ->check(CLI::ExistingFile);
  cmd->add_flag_callback(
      "--plain-mean", [job] { job->mesh.weight_by_view = false; },
      "with --mesh: average the frames' colours plainly (default: each weighted by "
      "|cos θ| / range², near head-on views counting most)");
  auto* silhouette_opt =
      cmd->add_option("--silhouette-weight", job->mesh.silhouette_weight,
                      "with --mesh: a frame in which a vertex lies within a pixel of the model's "
                      "outline (open water or an occluder among the pixels its colour is read "
                      "from) counts this many times less, and only the pixels showing the model "
                      "are read; 1: as any other frame")
          ->check(CLI::Validator(
              [](std::string& value) -> std::string {
                char* end = nullptr;
                const double w = std::strtod(value.c_str(), &end);
                return end != value.c_str() && *end == '\0' && w > 0 && w <= 1
                           ? ""
                           : "must be a number > 0 and <= 1, not " + value;
              },
              "in (0, 1]"))
          ->capture_default_str();
  cmd->add_flag("--drop-uncoloured", job->drop_uncoloured,
                "leave out the points no image saw (default: kept, black)");
  add_overwrite_flag(cmd, job->overwrite, "a point cloud sonar3d wrote at --output");
  cmd->callback([&g, &run, job, cloud, colmap, neus, images, output, dataset, navigation,
                 sonar_navigation, silhouette_opt, config] {
    if (config->print_requested()) {
      run = [config] {
        const TextureFilesConfig c = config->resolve("texture");
        with_flag_names(config->flag_names(), [&] {
          params::check(c, "texture");
          c.texture.validate();
          c.poses.validate();
        });
        config->print_if_requested(c, "texture", "texture");
        return 0;
      };
      return;
    }
    if (cloud->empty()) throw CLI::RequiredError("cloud");
    if (output->empty()) throw CLI::RequiredError("-o,--output");
    if (colmap->empty() && neus->empty() && dataset->empty()) {
      throw CLI::ValidationError("--colmap, --neus or --dataset", "camera poses are required");
    }
    if (dataset->empty() && images->empty()) {
      throw CLI::ValidationError("--images", "required with --colmap or --neus");
    }
    if (!dataset->empty() && !images->empty()) {
      throw CLI::ValidationError("--images",
                                 "does not apply to --dataset (its camera/ holds them)");
    }
    if (job->is_mesh && job->drop_uncoloured) {
      throw CLI::ValidationError("--drop-uncoloured", "does not apply to --mesh");
    }
    if (!job->is_mesh && !job->mesh.weight_by_view) {
      throw CLI::ValidationError("--plain-mean", "applies to --mesh only");
    }
    if (!job->is_mesh && silhouette_opt->count() > 0) {
      throw CLI::ValidationError("--silhouette-weight", "applies to --mesh only");
    }
    if (!job->is_mesh && !job->occluders.empty()) {
      throw CLI::ValidationError("--occluder", "applies to --mesh only");
    }
    run = [&g, job, cloud, colmap, neus, images, output, dataset, navigation, sonar_navigation,
           config] {
      const TextureFilesConfig c = config->resolve("texture");
      with_flag_names(config->flag_names(), [&] {
        params::check(c, "texture");
        c.texture.validate();
        c.poses.validate();
      });
      job->config = c.texture;
      job->poses = c.poses;
      job->sonar_navigation_file = *sonar_navigation;
      job->cloud = *cloud;
      job->mesh.max_range_m = job->config.max_range_m;
      job->colmap_dir = *colmap;
      job->neus_file = *neus;
      job->dataset_dir = *dataset;
      job->navigation_file = *navigation;
      job->images_dir = *images;
      job->output = *output;
      job->progress = !g.quiet;
      const TextureFilesResult r =
          with_flag_names(config->flag_names(), [&] { return texture_cloud_files(*job); });
      for (const auto& w : r.warnings) fmt::print(stderr, "sonar3d: warning: {}\n", w);
      const char* what = job->is_mesh ? "vertices" : "points";
      fmt::print("coloured {} of {} {} from {} images; wrote {} {} to {}\n", r.coloured, r.points,
                 what, r.frames, r.written, what, job->output.string());
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
