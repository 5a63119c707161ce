// sonar3d world: a semantic world model from a map and its placements (thesis sec. 6.3.3).
#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

void add_world(CLI::App& app, const GlobalOptions& /*g*/, Runner& run) {
  auto* cmd = app.add_subcommand(
      "world",
      "Build a semantic world model (thesis sec. 6.3.3, Fig. 6.18) from a map and the placements "
      "of `sonar3d recognize`: the seabed (points no placed model explains) as height-field "
      "meshes at several levels of detail, the placed CAD models, and a graph of objects and "
      "pipelines between them. Writes OUTPUT/world.glb (glTF 2.0), seabed_lod<k>.ply, "
      "models/<id>.ply and graph.json (docs/world.md).");
  struct Opts {
    std::string map, placements, catalogue, output, truth;
    std::unique_ptr<ConfigOptions<WorldModelConfig>> config;
    bool glb_all_lods = false;
    std::string connections, colours;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("map", o->map,
                  "map directory (sonar3d map: merged.ply) or point cloud (.ply, "
                  "world frame)")
      ->check(CLI::ExistingPath);
  cmd->add_option("--placements", o->placements, "placements JSON from sonar3d recognize")
      ->check(CLI::ExistingFile);
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue YAML the placements were made with (docs/recognition.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "world model directory to create (must not exist)");
  // Every setting (declared once, world/world_model.hpp): its flag, --print-config, --config.
  o->config = std::make_unique<ConfigOptions<WorldModelConfig>>(cmd);
  cmd->add_option("--connections", o->connections,
                  "connections you know, YAML: 'connections: [{from: riser_0, to: tank_0, kind: "
                  "pipeline}]' (ids as graph.json names the objects: <model>_<n>)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--colours", o->colours,
                  "the map's cloud as coloured by sonar3d texture (same points): its video "
                  "colours go onto the seabed")
      ->check(CLI::ExistingFile);
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->add_flag("--glb-all-lods", o->glb_all_lods,
                "world.glb carries every seabed level of detail (default: the coarsest)");
  cmd->add_option("--truth", o->truth,
                  "simulated dataset whose truth terrain measures the seabed's error (default: "
                  "the map's dataset when it has truth/)")
      ->check(CLI::ExistingDirectory);
  cmd->callback([&run, o] {
    // The map, placements, catalogue and -o are required unless --print-config (usage error).
    if (!o->config->print_requested()) {
      if (o->map.empty()) throw CLI::RequiredError("map");
      if (o->placements.empty()) throw CLI::RequiredError("--placements");
      if (o->catalogue.empty()) throw CLI::RequiredError("--catalogue");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o] {
      WorldModelConfig cfg = o->config->resolve("world");
      with_flag_names(o->config->flag_names(), [&] { cfg.validate(); });
      if (o->config->print_if_requested(cfg, "world", "world")) return 0;
      const fs::path map = o->map;
      fs::path cloud_path = map;
      if (fs::is_directory(map)) {
        cloud_path = map / "merged.ply";
        require(fs::is_regular_file(cloud_path),
                "'" + map.string() +
                    "' is a directory without merged.ply: give a map directory "
                    "from sonar3d map or a point cloud (.ply)");
      }
      const fs::path out = o->output;
      require(!fs::exists(out) || (fs::is_directory(out) && fs::is_empty(out)),
              "'" + out.string() +
                  "' exists: sonar3d world writes a new directory; choose "
                  "another output (-o) or remove it yourself");
      std::vector<GivenConnection> given;
      if (!o->connections.empty()) given = read_given_connections(o->connections);
      const PlacementsFile placements = read_placements(o->placements);
      cfg.min_confidence = world_confidence_threshold(placements, cfg.min_confidence);
      std::vector<WorldObject> objects = world_objects(placements, read_catalogue(o->catalogue));
      PointCloud cloud = read_ply(cloud_path.string());
      require(!cloud.empty(), "map '" + cloud_path.string() + "' holds no points");
      if (!o->colours.empty()) take_video_colours(cloud, read_ply(o->colours), o->colours);
      check_memory(estimate_world_model_memory(cloud, cfg), memory_limit_bytes(o->max_memory_gb),
                   "world");
      WorldModel w = build_world_model(cloud, std::move(objects), cfg);
      std::size_t unconfirmed = 0;
      for (const WorldObject& ob : w.objects) unconfirmed += !ob.confirmed;
      add_given_connections(w, given, o->connections, cfg.seabed.margin_m);

      WorldWriteInfo info;
      info.map = o->map;
      info.placements = o->placements;
      info.catalogue = o->catalogue;
      info.cloud_bytes = fs::file_size(cloud_path);
      info.glb_all_lods = o->glb_all_lods;
      const std::optional<SeabedTruth> truth = find_seabed_truth(map, o->truth);
      std::vector<SeabedError> errors;
      if (truth) {
        for (const SeabedLod& lod : w.seabed) {
          errors.push_back(seabed_error(lod.mesh, *truth));
          info.seabed_error_m.push_back(errors.back().median_m);
        }
      }
      const WorldWriteResult r = write_world_model(out, w, info);

      fmt::print("map: {} points, {} on the seabed; {} placed models; {} cells filled under them\n",
                 w.cloud_points, w.seabed_points, w.objects.size() - unconfirmed, w.filled_cells);
      for (const WorldObject& ob : w.objects) {
        if (ob.confirmed) continue;
        fmt::print(
            "  unconfirmed: {} (confidence {:.2f} < {:.2f}): listed and drawn grey, not "
            "connected, its points left in the seabed\n",
            ob.id, ob.confidence, w.min_confidence);
      }
      if (w.coloured_seabed_points > 0) {
        fmt::print("  {} seabed points carry a video colour: the seabed meshes are coloured\n",
                   w.coloured_seabed_points);
      }
      for (std::size_t k = 0; k < w.seabed.size(); ++k) {
        const SeabedLod& lod = w.seabed[k];
        std::string err;
        if (truth) {
          err = fmt::format("; median error {:.3f} m ({:.3f} m as mapped{})", errors[k].median_m,
                            errors[k].median_as_mapped_m,
                            truth->has_alignment ? ", before taking out the map's placement" : "");
        }
        if (!lod.color.empty()) {
          err += fmt::format("; video colour on {:.1f} % of its vertices",
                             100.0 * static_cast<double>(lod.coloured_vertices()) /
                                 static_cast<double>(std::max<std::size_t>(1, lod.color.size())));
        }
        fmt::print(
            "  seabed lod{}: {} m cells, {} triangles, {} bytes ({:.0f}x smaller than the "
            "cloud){}\n",
            lod.lod, lod.cell_m, lod.mesh.triangles.size(), r.seabed_bytes[k],
            static_cast<double>(info.cloud_bytes) / static_cast<double>(r.seabed_bytes[k]), err);
      }
      for (const Connection& c : w.connections) {
        if (c.found) {
          fmt::print("  {} {} -> {}: {:.2f} m ({:.0f} % of the cross-sections{})\n", c.kind, c.from,
                     c.to, c.length_m, 100 * c.fraction, c.given ? "; given too" : "");
        } else {
          fmt::print(
              "  {} {} -> {}: {:.2f} m between the footprints (given; not found in the map)\n",
              c.kind, c.from, c.to, c.length_m);
        }
      }
      fmt::print(
          "world.glb {} bytes; all files {} bytes against the cloud's {} ({:.0f}x); "
          "{:.2f} s -> {}\n",
          r.glb_bytes, r.bytes_total, info.cloud_bytes,
          static_cast<double>(info.cloud_bytes) / static_cast<double>(r.bytes_total), w.seconds,
          out.string());
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
