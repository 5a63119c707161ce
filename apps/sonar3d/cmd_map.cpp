#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/position_fixes.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/world/known_poses.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d::cli {

namespace fs = std::filesystem;

void add_map(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "map",
      "Map a field survey (thesis sec. 6.2): split it into swaths at the turns, carve and map each "
      "swath, register the swath elevation maps (eq. 6.1-6.2), correct the navigation and merge. "
      "Under `mpirun -np N` the swaths are carved on the ranks and rank 0 does the rest.");
  struct Opts {
    std::string dataset, output;
    std::unique_ptr<ConfigOptions<MapSurveyConfig>> config;
    double max_memory_gb = 0;
    std::string fixes;
    double fix_sigma = 0;
    std::string known_poses, placements, placements_nav;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dataset", o->dataset, "dataset directory (a lawnmower survey)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", o->output, "map directory to create (must not exist)");
  cmd->add_option("--fixes", o->fixes,
                  "absolute position fixes (USBL/GNSS) of the navigation's reference point, in "
                  "its world frame (ENU, metres) and clock (seconds): a CSV with the header "
                  "time_s,x_m,y_m[,z_m],sigma_m (sigma_m: standard deviation per axis, metres) "
                  "or a TUM file (.tum/.txt, with --fix-sigma). They place the map in the world "
                  "in the global or drift adjustment, which then also estimates the navigation's "
                  "scale error and heading bias; outliers are rejected and reported "
                  "(docs/mapping.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--fix-sigma", o->fix_sigma,
                  "standard deviation of every fix of a TUM fixes file, metres");
  cmd->add_option("--known-poses", o->known_poses,
                  "known structure poses: a world model directory (sonar3d world) or a "
                  "placements JSON (a previous survey's, or written from as-built drawings). "
                  "With --placements, each structure recognised in this survey's map is matched "
                  "to the nearest known pose of its model and the adjustment brings it there "
                  "(like a fix; outliers rejected and reported; docs/mapping.md)")
      ->check(CLI::ExistingPath);
  cmd->add_option("--placements", o->placements,
                  "structures recognised in a map of this dataset (sonar3d recognize's "
                  "placements JSON), for --known-poses")
      ->check(CLI::ExistingFile);
  cmd->add_option("--placements-nav", o->placements_nav,
                  "the navigation (TUM) of the map the --placements were recognised in (default: "
                  "the navigation_corrected.tum of the map directory the placements file names)")
      ->check(CLI::ExistingFile);
  add_max_memory_option(cmd, o->max_memory_gb);
  // Every setting (declared once, mapping/survey.hpp): its flag, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<MapSurveyConfig>>(cmd);
  cmd->callback([&run, &g, o] {
    // The dataset and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->dataset.empty()) throw CLI::RequiredError("dataset");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    run = [o, &g] {
      // The carving's own checks name its fields under "carve.": the map declares them.
      FlagNames names = o->config->flag_names();
      names.insert(names.end(), {{"carve.voxel_size", "--voxel-size"},
                                 {"carve.region", "--roi"},
                                 {"carve.num_threads", "--threads"},
                                 {"registration.num_threads", "--threads"}});
      return with_flag_names(names, [&] {
        MapSurveyConfig cfg = o->config->resolve("map");
        cfg.validate();
        if (o->config->print_if_requested(cfg, "map", "map")) return 0;
        // The output rule (core/output_dir.hpp): never the dataset, inside it, or a special file;
        // an existing path is refused by map_survey (a map directory is always new).
        check_output_location(o->output, output_policy(false, {o->dataset}), "-o", "map");
        cfg.registration.num_threads = cfg.carve.num_threads;
        require(o->fixes.empty() || cfg.method != SwathAdjustMethod::Consecutive,
                "--fixes needs --method global or drift (the consecutive method has no "
                "adjustment to put them in)");
        require(o->fix_sigma == 0 || !o->fixes.empty(), "--fix-sigma: give --fixes as well");
        if (!o->fixes.empty()) {
          cfg.fixes = read_position_fixes(o->fixes, FixFormat::Auto, o->fix_sigma);
          cfg.fixes_source = o->fixes;
        }
        require(o->known_poses.empty() == o->placements.empty(),
                "--known-poses and --placements go together: the known poses, and the "
                "structures recognised in this survey's map");
        require(o->placements_nav.empty() || !o->placements.empty(),
                "--placements-nav: give --placements as well");
        require(o->known_poses.empty() || cfg.method != SwathAdjustMethod::Consecutive,
                "--known-poses needs --method global or drift (the consecutive method has no "
                "adjustment to put them in)");
        if (!o->known_poses.empty()) {
          load_known_pose_inputs(cfg, o->known_poses, o->placements, o->placements_nav);
        }
        MpiSession mpi;  // rank 0 of 1 when not launched by mpirun
        const Dataset ds = read_dataset(o->dataset);
        if (mpi.rank() == 0) {
          const std::string w = implausible_voxel_size(ds.spec, cfg.carve.voxel_size,
                                                       cfg.carve.region, "--voxel-size");
          if (!w.empty()) print_warning(w);
          // A map cell larger than the sonar's swath leaves nothing to register.
          const double swath =
              2 * ds.spec.r_max *
              std::sin(0.5 * std::min(M_PI, ds.spec.fov_max() - ds.spec.fov_min()));
          if (cfg.cell_m > swath / 10) {
            print_warning(fmt::format(
                "--resolution {:.4g} m leaves {:.0f} cell(s) across the sonar's {:.3g} m swath: "
                "the swath maps cannot be registered; is it in centimetres? (--resolution {:.4g} "
                "is {:.4g} cm)",
                cfg.cell_m, std::floor(swath / cfg.cell_m), swath, cfg.cell_m / 100, cfg.cell_m));
          }
        }
        const double limit = memory_limit_bytes(o->max_memory_gb);
        check_memory(estimate_map_survey_memory(ds, cfg, limit), limit, "map");
        const MapSurveyResult r = map_survey(ds, cfg, o->output, !g.quiet, &mpi);
        if (mpi.rank() != 0) return 0;  // rank 0 reports
        std::size_t used = 0;
        for (bool u : r.adjustment.tie_used) used += u;
        fmt::print("mapped {} swaths ({} points) into {}: {} ties ({} used, {} method){}\n",
                   r.swaths.size(), r.merged_points, o->output, r.ties.size(), used,
                   to_string(cfg.method),
                   mpi.size() > 1 ? fmt::format(", carved on {} ranks", mpi.size()) : "");
        for (std::size_t s = 0; s < r.swaths.size(); ++s) {
          const SwathInfo& w = r.swaths[s];
          fmt::print(
              "  swath {:2d}: frames {}–{}, {} points, offset E {:+.3f} N {:+.3f} U {:+.3f} m", s,
              w.first_frame, w.last_frame, w.points, w.offset.x(), w.offset.y(), w.offset.z());
          if (cfg.method == SwathAdjustMethod::Drift) {
            fmt::print(", drift E {:+.2f} N {:+.2f} cm/min", 6000 * w.rate.x(), 6000 * w.rate.y());
          }
          if (w.has_truth) {  // simulated drift: the navigation error left, mean over the swath
            fmt::print(
                " (navigation error within the map {:.3f} → {:.3f} m, absolute {:.3f} → "
                "{:.3f} m)",
                w.rigid_error_before.x(), w.rigid_error_after.x(), w.error_before.x(),
                w.error_after.x());
          }
          fmt::print("\n");
        }
        if (!cfg.known_poses.empty()) {  // known structure poses
          const SwathAdjustment& adj = r.adjustment;
          std::size_t rejected = 0;
          for (const auto& m : r.known_matches) rejected += adj.fixes.at(m.constraint).rejected;
          fmt::print(
              "  known poses: {} known ({}), {} recognised ({}), {} matched within {:g} m, {} "
              "used, {} rejected (gate {:g} σ at σ {:g} m), {} recognised unmatched\n",
              cfg.known_poses.size(), o->known_poses, cfg.recognised.size(), o->placements,
              r.known_matches.size(), cfg.known_pose_match_m, r.known_matches.size() - rejected,
              rejected, cfg.fix_gate_sigma, cfg.known_pose_sigma_m, r.recognised_unmatched.size());
          for (const auto& m : r.known_matches) {
            const FixReport& f = adj.fixes.at(m.constraint);
            fmt::print("    {} {} (placement {}): swath {}, residual {:.3f} m = {:.1f} σ{}\n",
                       f.rejected ? "rejected:" : "used:", m.id, m.recognised_index, m.swath,
                       f.residual_m, f.normalized, f.rejected ? " (the known pose disagrees)" : "");
          }
        }
        if (!cfg.fixes.empty() || !r.known_matches.empty()) {  // the absolute references
          const SwathAdjustment& adj = r.adjustment;
          std::vector<const FixReport*> rejected;
          std::size_t n_fixes = 0;
          for (const FixReport& f : adj.fixes) {
            if (!f.name.empty()) continue;  // known structure poses: above
            ++n_fixes;
            if (f.rejected) rejected.push_back(&f);
          }
          if (!cfg.fixes.empty()) {
            fmt::print(
                "  fixes: {} given, {} outside the survey's time span (ignored), {} used, {} "
                "rejected (gate {:g} σ, {} solve(s))\n",
                r.fixes_given, r.fixes_outside, n_fixes - rejected.size(), rejected.size(),
                cfg.fix_gate_sigma, adj.fix_rounds);
          }
          for (std::size_t k = 0; k < rejected.size(); ++k) {
            if (k == 10) {
              fmt::print("    ... {} more in summary.json\n", rejected.size() - k);
              break;
            }
            fmt::print("    rejected: t = {:.3f} s ({}:{}), residual {:.3f} m = {:.1f} σ\n",
                       rejected[k]->time, o->fixes, rejected[k]->line, rejected[k]->residual_m,
                       rejected[k]->normalized);
          }
          if (adj.estimated_scale_heading) {
            fmt::print(
                "  navigation model: scale error {:+.4f} % ± {:.4f} %, heading bias {:+.4f}° ± "
                "{:.4f}°; placement σ E {:.3f} N {:.3f} m\n",
                100 * adj.scale_error(), 100 * adj.scale_error_sigma,
                adj.heading_bias_rad() * 180 / M_PI, adj.heading_bias_sigma_rad * 180 / M_PI,
                adj.placement_sigma_m.x(), adj.placement_sigma_m.y());
          } else {
            fmt::print("  navigation model: shift only; placement σ E {:.3f} N {:.3f} m\n",
                       adj.placement_sigma_m.x(), adj.placement_sigma_m.y());
          }
        }
        if (r.has_alignment) {  // simulated navigation: the whole map against the truth
          const NavigationError &b = r.navigation_before, &a = r.navigation_after;
          fmt::print(
              "  navigation error (median over frames, horizontal, as logged → corrected): "
              "in the world frame {:.3f} → {:.3f} m; absolute{} {:.3f} → {:.3f} m; within the map "
              "(after a rigid placement) {:.3f} → "
              "{:.3f} m; after an affine placement {:.3f} → {:.3f} m, which hides a scale of "
              "{:.4f} → {:.4f} (docs/mapping.md)\n",
              b.world_m, a.world_m,
              r.adjustment.has_fixes ? "" : " (from where the first swath starts)", b.absolute_m,
              a.absolute_m, b.rigid_m, a.rigid_m, b.affine_m, a.affine_m,
              r.alignment_before.scale(), r.alignment_after.scale());
        }
        for (const StructureEval& e : r.structures) {  // simulated site: against the CAD
          fmt::print(
              "  {} {}: median {:.1f} → {:.1f} cm, coverage {:.0f} → {:.0f} %, outliers "
              "{:.0f} → {:.0f} % (as logged → corrected, each map placed by its affine fit)\n",
              to_string(e.kind), e.name, 100 * e.before.median_error, 100 * e.after.median_error,
              100 * e.before.coverage, 100 * e.after.coverage, 100 * e.before.outliers,
              100 * e.after.outliers);
        }
        fmt::print("  carving {:.1f} s, registration {:.2f} s, total {:.1f} s\n", r.seconds_carving,
                   r.seconds_registration, r.seconds_total);
        return 0;
      });
    };
  });
}

}  // namespace sonar3d::cli
