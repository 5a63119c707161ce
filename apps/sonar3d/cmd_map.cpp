#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "commands.hpp"
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
    std::string dataset, output, method = "global";
    MapSurveyConfig cfg;
    std::vector<double> roi, swath_times;
    double turn_deg = 30;
    double max_memory_gb = 0;
    std::string fixes;
    double fix_sigma = 0;
    bool fixes_shift_only = false;
    std::string known_poses, placements, placements_nav;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("dataset", o->dataset, "dataset directory (a lawnmower survey)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", o->output, "map directory to create (must not exist)")->required();
  cmd->add_option("--resolution", o->cfg.cell_m, "elevation map cell size, metres")
      ->capture_default_str();
  cmd->add_option("--voxel-size", o->cfg.carve.voxel_size, "carving voxel edge, metres")
      ->capture_default_str();
  cmd->add_option("--roi", o->roi,
                  "region to carve, world frame: xmin ymin zmin xmax ymax zmax (metres); "
                  "default: all the sonar sees")
      ->expected(6);
  cmd->add_option("--search", o->cfg.registration.search_m,
                  "half-width of the searched swath shifts, metres")
      ->capture_default_str();
  cmd->add_option("--method", o->method,
                  "consecutive (the thesis: each swath against the previous), global (every "
                  "overlapping pair, one robust adjustment of swath offsets) or drift (every "
                  "overlapping pair piece by piece, a drift rate per swath as well)")
      ->check(CLI::IsMember({"consecutive", "global", "drift"}))
      ->capture_default_str();
  cmd->add_option("--piece", o->cfg.piece_m,
                  "drift method: length of the swath pieces registered, metres")
      ->capture_default_str();
  cmd->add_option("--turn-deg", o->turn_deg,
                  "a new swath starts where the track turns by more than this, degrees")
      ->capture_default_str();
  cmd->add_option("--swath-times", o->swath_times,
                  "explicit swaths instead of turns: t0 t1 [t0 t1 ...] (seconds)");
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
  cmd->add_option("--fix-gate", o->cfg.fix_gate_sigma,
                  "a fix whose residual after the adjustment exceeds this many standard "
                  "deviations (1-D equivalent probability) is rejected and reported")
      ->capture_default_str();
  cmd->add_flag("--fixes-shift-only", o->fixes_shift_only,
                "with --fixes: place the map by a shift only, no scale error or heading bias "
                "estimated");
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
  cmd->add_option("--known-pose-sigma", o->cfg.known_pose_sigma_m,
                  "standard deviation of a recognised structure against its known pose, per "
                  "horizontal axis, metres")
      ->capture_default_str();
  cmd->add_option("--known-pose-radius", o->cfg.known_pose_match_m,
                  "a recognised structure matches a known pose of its model within this "
                  "horizontal distance, metres")
      ->capture_default_str();
  cmd->add_option("--threads", o->cfg.carve.num_threads, "worker threads (0 = all cores)")
      ->capture_default_str();
  add_max_memory_option(cmd, o->max_memory_gb);
  // Library fields named in errors -> the flags that set them.
  static const FlagNames kFlags = {{"cell_m", "--resolution"},
                                   {"carve.voxel_size", "--voxel-size"},
                                   {"carve.region", "--roi"},
                                   {"search_m", "--search"},
                                   {"registration.search_m", "--search"},
                                   {"piece_m", "--piece"},
                                   {"carve.num_threads", "--threads"},
                                   {"num_threads", "--threads"},
                                   {"fix_gate_sigma", "--fix-gate"},
                                   {"known_pose_sigma_m", "--known-pose-sigma"},
                                   {"known_pose_match_m", "--known-pose-radius"}};
  cmd->callback([&run, &g, o] {
    run = [o, &g] {
      return with_flag_names(kFlags, [&] {
        // The output rule (core/output_dir.hpp): never the dataset, inside it, or a special file;
        // an existing path is refused by map_survey (a map directory is always new).
        check_output_location(o->output, output_policy(false, {o->dataset}), "-o", "map");
        MapSurveyConfig cfg = o->cfg;
        cfg.method = swath_adjust_method_from_string(o->method);
        cfg.registration.num_threads = cfg.carve.num_threads;
        cfg.split.turn_threshold_rad = o->turn_deg * 3.14159265358979323846 / 180.0;
        if (!o->roi.empty()) {
          const Eigen::AlignedBox3d box(Eigen::Vector3d(o->roi[0], o->roi[1], o->roi[2]),
                                        Eigen::Vector3d(o->roi[3], o->roi[4], o->roi[5]));
          validate_region(box, "--roi");
          cfg.carve.region = box;
        }
        require(o->swath_times.size() % 2 == 0,
                "--swath-times: give pairs of times (t0 t1 per swath)");
        for (std::size_t k = 0; k + 1 < o->swath_times.size(); k += 2) {
          cfg.split.time_ranges.emplace_back(o->swath_times[k], o->swath_times[k + 1]);
        }
        require(o->fixes.empty() || cfg.method != SwathAdjustMethod::Consecutive,
                "--fixes needs --method global or drift (the consecutive method has no "
                "adjustment to put them in)");
        require(o->fix_sigma == 0 || !o->fixes.empty(), "--fix-sigma: give --fixes as well");
        if (!o->fixes.empty()) {
          cfg.fixes = read_position_fixes(o->fixes, FixFormat::Auto, o->fix_sigma);
          cfg.fixes_source = o->fixes;
          cfg.fix_scale_heading = !o->fixes_shift_only;
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
          cfg.known_poses = read_known_poses(o->known_poses);
          cfg.known_poses_source = o->known_poses;
          const PlacementsFile f = read_placements(o->placements);
          for (std::size_t k = 0; k < f.placements.size(); ++k) {
            cfg.recognised.push_back({f.placements[k].model,
                                      f.placements[k].T_world_model.translation(),
                                      static_cast<int>(k)});
          }
          cfg.recognised_source = o->placements;
          cfg.recognised_navigation = read_tum(placements_navigation(f, o->placements_nav));
          cfg.fix_scale_heading = !o->fixes_shift_only;
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
                   r.swaths.size(), r.merged_points, o->output, r.ties.size(), used, o->method,
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
