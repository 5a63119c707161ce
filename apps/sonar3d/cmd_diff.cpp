#include <fmt/core.h>
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/world/change.hpp"
#include "sonar3d/world/relocalize.hpp"

namespace sonar3d::cli {

void add_diff(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "diff",
      "Change detection between two surveys of one site: register B onto A (elevation-map shift "
      "search, eq. 6.1-6.2, over a yaw search), compare the placed catalogue models (unchanged, "
      "moved, added, removed; uncertain when the recognitions disagree and the heights did not "
      "change) and the heights cell by cell (regions of significant change). "
      "Writes OUTPUT/changes.json, change_map.tif (B - A, metres) and change_points.ply, all in "
      "A's frame; with --colour-a/--colour-b also the colour change (colour_change_map.tif). B may "
      "be a relocalisation directory (sonar3d relocalize B_DATASET --world A_WORLD "
      "--map-resolution 0.02): B carved with its relocalised navigation, already in A's frame, "
      "is not registered again.");
  struct Opts {
    std::string a, b, output, catalogue, placements_a, placements_b, colour_a, colour_b;
    std::unique_ptr<ConfigOptions<ChangeConfig>> config;
    RecognitionConfig recog;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("a", o->a, "survey A (the reference): a map directory (sonar3d map) or a .ply")
      ->check(CLI::ExistingPath);
  cmd->add_option("b", o->b,
                  "survey B (the later one): a map directory, a .ply, or a relocalisation "
                  "directory (sonar3d relocalize --map-resolution) against A's world model")
      ->check(CLI::ExistingPath);
  cmd->add_option("-o,--output", o->output, "change directory to create (must not exist)");
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue YAML (docs/recognition.md): symmetries for the turns; without "
                  "placements, each survey is recognised with it first")
      ->check(CLI::ExistingFile);
  auto* pa = cmd->add_option("--placements-a", o->placements_a,
                             "survey A's placements.json (sonar3d recognize)")
                 ->check(CLI::ExistingFile);
  auto* pb = cmd->add_option("--placements-b", o->placements_b, "survey B's placements.json")
                 ->check(CLI::ExistingFile);
  pa->needs(pb);
  pb->needs(pa);
  add_max_memory_option(cmd, o->max_memory_gb);
  auto* ca = cmd->add_option("--colour-a", o->colour_a,
                             "survey A's coloured cloud (.ply with red/green/blue, e.g. sonar3d "
                             "texture of A's cloud) in A's world: compares colour too")
                 ->check(CLI::ExistingFile);
  auto* cb = cmd->add_option("--colour-b", o->colour_b,
                             "survey B's coloured cloud in B's world (moved by the registration)")
                 ->check(CLI::ExistingFile);
  ca->needs(cb);
  cb->needs(ca);
  // Every setting (declared once, world/change.hpp): its flag, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<ChangeConfig>>(cmd);
  cmd->callback([&run, &g, o] {
    // A, B and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->a.empty()) throw CLI::RequiredError("a");
      if (o->b.empty()) throw CLI::RequiredError("b");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o, &g] {
      const ChangeConfig cfg = o->config->resolve("diff");
      with_flag_names(o->config->flag_names(), [&] { cfg.validate(); });
      if (o->config->print_if_requested(cfg, "diff", "diff")) return 0;
      Catalogue cat;
      if (!o->catalogue.empty()) cat = read_catalogue(o->catalogue);
      const PointCloud a = read_survey_cloud(o->a);
      // B relocalised against A's world model: its map (carved with the relocalised navigation)
      // is in A's frame already and is not registered again (docs/change.md).
      PointCloud b;
      std::unique_ptr<ChangeRegistration> placed;
      if (is_relocalization_dir(o->b)) {
        RelocalizedSurvey rb = read_relocalized_survey(o->b);
        b = std::move(rb.cloud);
        if (relocalized_against(rb, o->a)) {
          placed = std::make_unique<ChangeRegistration>();
          placed->method = "relocalized against " + rb.world;
          if (!g.quiet) {
            fmt::print(
                "B relocalised against {} (A's world model): in A's frame, not "
                "registered again\n",
                rb.world);
          }
        } else {
          print_warning(fmt::format(
              "B '{}' was relocalised against the world model '{}', built from {}, not from A "
              "'{}': B is registered onto A as usual",
              o->b, rb.world, rb.world_map.empty() ? "an unknown map" : "'" + rb.world_map + "'",
              o->a));
        }
      } else {
        b = read_survey_cloud(o->b);
      }
      std::vector<SurveyPlacement> pa, pb;
      if (!o->placements_a.empty()) {
        pa = read_placements(o->placements_a).placements;
        pb = read_placements(o->placements_b).placements;
      } else if (!o->catalogue.empty()) {
        RecognitionConfig rc = o->recog;
        rc.num_threads = cfg.registration.num_threads;
        rc.scan.num_threads = rc.num_threads;
        rc.validate();
        if (!g.quiet) fmt::print("recognising the catalogue's models in A and in B...\n");
        pa = recognize_placements(a, cat, rc);
        pb = recognize_placements(b, cat, rc);
      }
      // Each placed model's symmetry and size (the match radius and the footprint the height
      // change is looked for in scale with it); without a catalogue, sizes are unknown.
      ObjectModels models;
      if (!o->catalogue.empty()) {
        std::vector<std::string> placed;
        for (const auto* list : {&pa, &pb}) {
          for (const SurveyPlacement& p : *list) placed.push_back(p.model);
        }
        models = catalogue_object_models(cat, placed);
      } else if (!pa.empty() || !pb.empty()) {
        if (!g.quiet) {
          fmt::print(
              "no --catalogue: model sizes unknown, placements paired within --match-radius "
              "{} m of each other\n",
              cfg.match_radius_m);
        }
      }
      PointCloud colour_a, colour_b;
      if (!o->colour_a.empty()) {
        colour_a = read_survey_cloud(o->colour_a);
        check_colour_cloud(colour_a, "--colour-a '" + o->colour_a + "'");
        colour_b = read_survey_cloud(o->colour_b);
        check_colour_cloud(colour_b, "--colour-b '" + o->colour_b + "'");
      }
      const bool colour = !o->colour_a.empty();
      check_memory(estimate_change_memory(a, b, cfg, colour), memory_limit_bytes(o->max_memory_gb),
                   "diff");
      const ChangeResult r = diff_surveys(a, b, pa, pb, models, cfg, colour ? &colour_a : nullptr,
                                          colour ? &colour_b : nullptr, placed.get());
      write_change_directory(o->output, r);
      const Eigen::Vector3d t = r.registration.T_a_b.translation();
      fmt::print(
          "B onto A{}: shift E {:+.3f} N {:+.3f} U {:+.3f} m, yaw {:+.2f} deg; rms {:.3f} m over "
          "{} cells\n",
          placed ? " (relocalised)" : "", t.x(), t.y(), t.z(), r.registration.yaw_deg,
          r.registration.rms_m, r.registration.overlap_cells);
      for (const ObjectChange& ob : r.objects) {
        const Eigen::Vector3d p =
            (ob.in_a ? ob.T_world_model_a : ob.T_world_model_b_in_a).translation();
        fmt::print("  {} ({}): {} at E {:.2f} N {:.2f}", ob.id, ob.model,
                   object_status_name(ob.status), p.x(), p.y());
        if (ob.in_a && ob.in_b)
          fmt::print(", shift {:.3f} m, turn {:.1f} deg", ob.shift_m, ob.turn_deg);
        if (!ob.reason.empty()) fmt::print(": {}", ob.reason);
        fmt::print("\n");
      }
      fmt::print("  threshold {:.3f} m (k {:.1f} x sigma {:.4f} m), min area {:.3f} m2\n",
                 r.thresholds.change_m, r.thresholds.k_sigma, r.thresholds.sigma_m,
                 r.thresholds.min_area_m2);
      for (const ChangeRegion& reg : r.regions) {
        fmt::print(
            "  region {}: {} at E {:.2f} N {:.2f}, {:.2f} m2, max |change| {:.3f} m, mean "
            "{:+.3f} m\n",
            reg.id, reg.raised ? "raised" : "lowered", reg.centroid.x(), reg.centroid.y(),
            reg.area_m2, reg.max_abs_change_m, reg.mean_change_m);
      }
      const ColourChange& cc = r.colour;
      if (cc.compared) {
        fmt::print("  colour ({}): threshold {:.2f} (k {:.1f} x sigma {:.3f}) over {} cells\n",
                   colour_space_name(cc.space), cc.threshold, cc.k_sigma, cc.sigma,
                   cc.compared_cells);
        for (const ColourRegion& reg : cc.regions) {
          fmt::print(
              "  colour region {}: at E {:.2f} N {:.2f}, {:.2f} m2, max delta {:.2f}, mean "
              "{:.2f}, RGB {},{},{} -> {},{},{}, {}\n",
              reg.id, reg.centroid.x(), reg.centroid.y(), reg.area_m2, reg.max_delta,
              reg.mean_delta, reg.colour_a[0], reg.colour_a[1], reg.colour_a[2], reg.colour_b[0],
              reg.colour_b[1], reg.colour_b[2],
              reg.height_change_fraction > 0 ? fmt::format("with height change ({:.0f} % of it)",
                                                           100 * reg.height_change_fraction)
                                             : std::string("surface only"));
        }
      }
      fmt::print("{} objects, {} regions of change{} in {:.1f} s -> {}\n", r.objects.size(),
                 r.regions.size(),
                 cc.compared ? fmt::format(", {} regions of colour change", cc.regions.size())
                             : std::string(),
                 r.seconds, o->output);
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
