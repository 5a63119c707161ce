// sonar3d reconstruct: argument parsing and printing around the library's one pipeline,
// reconstruct_dataset() (recon/reconstruct.hpp), which Python's reconstruct() runs too. Every
// setting comes from ReconstructConfig's one declaration (flags, --print-config, --config).
#include <fmt/core.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

namespace {

struct ReconstructCliOptions {
  std::string dataset, output, vdb, json;
  bool ascii = false, allow_empty = false, overwrite = false;
  bool explain_returns = false;  // --explain-returns: the default since issue 29, kept for scripts
  double max_memory_gb = 0;      // --max-memory (0 = the default limit)
  std::unique_ptr<ConfigOptions<ReconstructConfig>> config;
};

// Library fields named in errors -> the flags that set them: every declared flag, and the method
// configs' own names of the shared settings (the library checks the configs it runs with).
FlagNames reconstruct_flags(const ConfigOptions<ReconstructConfig>& c) {
  FlagNames names = c.flag_names();
  const FlagNames shared = {
      {"carve.voxel_size", "--voxel-size"},
      {"deconv.voxel.voxel_size", "--voxel-size"},
      {"carve.region", "--roi"},
      {"region", "--roi"},
      {"carve.min_observations", "--min-observations"},
      {"deconv.voxel.min_observations", "--min-observations"},
      {"carve.num_threads", "--threads"},
      {"deconv.num_threads", "--threads"},
      {"bracket.num_threads", "--threads"},
      {"occlusion.num_threads", "--threads"},
      {"occlusion.footprint_radius", "--footprint-radius"},
      {"occlusion.range_tolerance_bins", "--range-tolerance"},
      {"occlusion.explain_pin_fraction", "--explain-pin-fraction"},
      {"deconv.lambda", "--lambda"},
  };
  names.insert(names.end(), shared.begin(), shared.end());
  return names;
}

// The outputs of one run (-o, and --json, --vdb when given): checked against the output rule
// before the work starts, written under temporary names, renamed together by commit().
struct RunOutputs {
  OutputFiles files;
  std::filesystem::path ply, json, vdb;  // temporary paths ("" = not asked for)
  RunOutputs(const ReconstructCliOptions& o, const std::string& method)
      : files(output_policy(o.overwrite, {o.dataset})) {
    ply = files.add(o.output, OutputKind::PointCloud, "-o");
    if (!o.json.empty()) json = files.add(o.json, OutputKind::ReconstructionJson, "--json");
    if (!o.vdb.empty() && method == "carve") vdb = files.add(o.vdb, OutputKind::VoxelMap, "--vdb");
  }
};

// The bracketing line, its warnings and the notes that suggest options.
void print_bracketing(const ReconstructResult& r, const ReconstructConfig& cfg,
                      const FlagNames& flags) {
  const BracketReport& br = r.bracketing;
  const BracketConfig bc = cfg.effective_bracket();
  {
    fmt::print(
        "  elevation bracketing: median {:.2f} over the points; {:.1f} % of the observed region "
        "(samples every {:.2f} m{}) bracketed below {:.2f}, {:.1f} % never{} ({:.1f} s)\n",
        br.median_bracket, 100.0 * br.unbracketed_share, br.sample_step,
        cfg.region ? " over --roi" : " over the points' box", bc.bracketed_level,
        100.0 * br.never_bracketed_share,
        br.min_bracket > 0
            ? fmt::format("; {} {:.2f} kept {} of {} points",
                          br.min_bracket_auto ? "a pass stops short: the bracket filter at"
                                              : "--min-bracket",
                          br.min_bracket, br.kept, br.points)
            : std::string(),
        br.seconds);
  }
  for (const auto& w : br.warnings()) print_warning(name_flags(w, flags));
  if (br.min_bracket_auto) {
    print_note(fmt::format(
        "points bracketed below {:.2f} were dropped since a pass stops short (the ghost arcs "
        "beyond its end; docs/carving.md, \"Elevation bracketing\"); --no-auto-min-bracket keeps "
        "them",
        br.min_bracket));
  }
  if (br.level_stack.dropped > 0) {
    print_note(fmt::format(
        "{} points above the level frames' top that no frame saw from above were dropped (the "
        "ghost arcs over the structure; docs/carving.md, \"Orbits at several heights\"); "
        "--no-auto-min-bracket keeps them",
        br.level_stack.dropped));
  }
  if (!br.min_bracket_auto && !br.extensions.empty() && br.min_bracket == 0) {
    print_note(
        "--min-bracket 0.5 drops the points no frame saw from the other side of their "
        "elevation (measured: docs/carving.md, \"Elevation bracketing\")");
  }
  if (!br.extensions.empty() && cfg.method == "carve" && !cfg.carve.occlusion.explain_returns) {
    print_note(
        "on an open structure, the return explanation (on unless --no-explain-returns) also "
        "drops the ghosts inside it (docs/carving.md, \"Interior ghosts\")");
  }
}

// Refuses an empty cloud unless --allow-empty, saying why it is empty.
void check_not_empty(const ReconstructResult& r, const ReconstructConfig& cfg, std::size_t frames) {
  if (!r.cloud.empty()) return;
  if (r.points_before_bracket > 0) {
    const BracketReport& br = r.bracketing;
    throw Error((br.min_bracket_auto
                     ? "the bracket filter (at " + fmt::format("{:.2f}", br.min_bracket) +
                           ", on since a pass stops short; --no-auto-min-bracket turns it off)"
                     : "--min-bracket " + fmt::format("{:.2f}", br.min_bracket)) +
                " kept none of the " + std::to_string(r.points_before_bracket) +
                " points; lower it, or pass --allow-empty to write the empty cloud");
  }
  if (r.carve_stats) {
    const CarveStats& st = *r.carve_stats;
    if (st.candidates == 0) {
      throw Error("carving found no surface: no return in any of the " + std::to_string(st.frames) +
                  " frames bounds a voxel of the map; check --roi, --image-threshold and the "
                  "frames (sonar3d preview), or pass --allow-empty to write the empty cloud");
    }
    throw Error("carving kept none of its " + std::to_string(st.candidates) +
                " candidates; relax --min-observations, --min-elevation-span or "
                "--static-threshold, try --no-occlusion, or pass --allow-empty");
  }
  const DeconvReport& report = *r.deconv_report;
  if (report.passes.empty() && report.mode == "passes") {
    std::string why;  // the passes' collapsed warnings
    for (const auto& w : summarize_pass_warnings(report.warnings)) {
      if (w != "no pass was reconstructed") why += (why.empty() ? "" : "; ") + w;
    }
    if (why.size() > 300) {  // one readable line; cut on a UTF-8 character boundary
      std::size_t n = 300;
      while (n > 0 && (static_cast<unsigned char>(why[n]) & 0xC0) == 0x80) --n;
      why = why.substr(0, n) + "…";
    }
    throw Error("deconvolution reconstructed no pass of the " + std::to_string(frames) + " frames" +
                (why.empty() ? "" : " (" + why + ")") +
                ": it needs straight passes along the sonar's z axis that see something "
                "(docs/deconvolution.md); use --deconv-mode voxel (or auto) or --method carve "
                "for other trajectories, or pass --allow-empty to write the empty cloud");
  }
  throw Error("deconvolution produced 0 points" +
              (r.points_before_region > 0
                   ? " inside --roi (" + std::to_string(r.points_before_region) + " outside)"
               : report.mode == "voxel"
                   ? std::string(" in voxel mode from ") + std::to_string(report.voxel.candidates) +
                         " candidate voxels"
                   : std::string(" from ") + std::to_string(report.passes.size()) + " passes") +
              "; check --roi, --image-threshold and --lambda, or pass --allow-empty");
}

// What the carving did, on standard output (notes on standard error).
void print_carving(const ReconstructResult& r, const ReconstructConfig& cfg,
                   const std::string& output) {
  const CarveStats& st = *r.carve_stats;
  const double n = static_cast<double>(st.frames);
  {
    fmt::print(
        "carved {} frames into {} candidates, {} points after occlusion resolution -> {}\n"
        "  integrate {:.1f} ms/frame, occlusion resolution {:.1f} ms/frame, map {:.1f} MB, "
        "frame summaries {:.1f} MB, peak RSS {:.0f} MB ({:.0f} MB while integrating)\n",
        st.frames, st.candidates, st.points, output, 1e3 * st.integrate_seconds / n,
        1e3 * st.occlusion_seconds / n, st.map_bytes / 1e6, st.frame_bytes / 1e6,
        peak_rss_bytes() / 1e6, r.integrate_peak_rss / 1e6);
  }
  if (cfg.carve.occlusion.explain_returns) {
    fmt::print("  the return explanation dropped {} points whose returns other surfaces explain\n",
               st.ghosts);
  }
  if (st.min_observations_used < cfg.min_observations) {
    print_note(
        fmt::format("a scatterer is seen by {:.0f} frame(s) of this trajectory, so candidates need "
                    "{} observation(s), not --min-observations {}",
                    st.views_per_scatterer, st.min_observations_used, cfg.min_observations));
  }
}

int run_reconstruct(const ReconstructCliOptions& o, const ReconstructConfig& cfg,
                    const GlobalOptions& g, const FlagNames& flags) {
  RunOutputs out(o, cfg.method);
  const Dataset ds = read_dataset(o.dataset);
  const std::string w =
      check_reconstruct_memory(ds, cfg, memory_limit_bytes(o.max_memory_gb), "--voxel-size");
  if (!w.empty()) print_warning(w);
  ReconstructConfig run_cfg = cfg;
  run_cfg.progress = !g.quiet;
  ReconstructRun run;
  run.keep_carver = !out.vdb.empty();
  const ReconstructResult r = reconstruct_dataset(ds, run_cfg, run);

  // Results on standard output; warnings and notes on standard error.
  if (r.deconv_report) {
    if (!r.deconv_report->mode_note.empty()) print_note(r.deconv_report->mode_note);
    fmt::print("{}", r.deconv_report->to_text(false));
  }
  print_bracketing(r, cfg, flags);
  if (!o.allow_empty) check_not_empty(r, cfg, ds.size());
  if (r.deconv_report) {
    for (const auto& wp : summarize_pass_warnings(r.deconv_report->warnings))
      print_warning(name_flags(wp, flags));
  }
  write_ply(out.ply.string(), r.cloud, o.ascii ? PlyFormat::Ascii : PlyFormat::Binary);
  if (!out.vdb.empty()) r.carver->write_vdb(out.vdb.string(), &r.cloud);
  if (r.carve_stats) print_carving(r, cfg, o.output);
  if (!o.json.empty()) {
    // The library's report (one serialisation for CLI and Python), marked as sonar3d's, with
    // the effective configuration.
    nlohmann::ordered_json j;
    j["format"] = json_format_marker(OutputKind::ReconstructionJson);
    j["method"] = cfg.method;
    j["points"] = r.cloud.size();
    j["peak_rss_bytes"] = peak_rss_bytes();
    const nlohmann::ordered_json report = nlohmann::ordered_json::parse(r.report);
    for (const auto& [k, v] : report.items()) {
      if (k != "points") j[k] = v;
    }
    if (r.deconv_report) j["report"] = r.deconv_report->to_text();
    j["settings"] = nlohmann::ordered_json::parse(params::to_json(cfg));
    write_text_file(out.json.string(), j.dump(2) + "\n");
  }
  out.files.commit();  // the cloud, its --json and --vdb together
  if (r.deconv_report) {
    fmt::print("wrote {} points to {}\n", r.cloud.size(), o.output);
  }
  return 0;
}

}  // namespace

void add_reconstruct(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "reconstruct",
      "3D reconstruction of a sonar dataset. carve: space carving (thesis ch. 4): min-filter of "
      "the per-elevation bounds I/B(θ)² over frames, conservative free-space carving, occlusion "
      "resolution. deconv: deconvolution along straight passes (thesis ch. 5) or, for any other "
      "trajectory, over carving's candidate voxels (--deconv-mode). Writes a PLY point cloud "
      "(world frame, intensity = reflectivity). Every setting: docs/reference.md.");
  auto o = std::make_shared<ReconstructCliOptions>();
  cmd->add_option("dataset", o->dataset, "dataset directory")->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", o->output,
                  "point cloud to write (.ply; an existing one only if sonar3d wrote it, with "
                  "--overwrite; never inside the dataset)");
  cmd->add_option("--vdb", o->vdb,
                  "carving: also write an OpenVDB file: grids carve_map (0 = free, > 0 = bound, "
                  "inactive = unknown) and surface (the output points)");
  // Every setting, from ReconstructConfig's one declaration (recon/reconstruct.hpp), with
  // --print-config and --config.
  o->config = std::make_unique<ConfigOptions<ReconstructConfig>>(cmd);
  cmd->add_flag("--ascii", o->ascii, "write an ASCII PLY");
  cmd->add_flag("--explain-returns", o->explain_returns,
                "sets carve.occlusion.explain_returns to true: the default since issue 29 "
                "(--no-explain-returns turns it off); kept for scripts, and over a --config file");
  cmd->add_flag("--allow-empty", o->allow_empty,
                "write the cloud even when it has no point (by default an error, exit status 1)");
  cmd->add_option("--json", o->json,
                  "also write the run's report (statistics, timings, memory, settings) as JSON");
  add_overwrite_flag(cmd, o->overwrite, "a cloud, --json and --vdb sonar3d wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->callback([&g, &run, o] {
    // The dataset and -o are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->dataset.empty()) throw CLI::RequiredError("dataset");
      if (o->output.empty()) throw CLI::RequiredError("-o,--output");
    }
    const FlagNames flags = reconstruct_flags(*o->config);
    run = [&g, o, flags]() -> int {
      return with_flag_names(flags, [&] {
        ReconstructConfig cfg = o->config->resolve("reconstruct");
        if (o->explain_returns) cfg.carve.occlusion.explain_returns = true;
        cfg.validate();  // a printed configuration is one that runs
        if (o->config->print_if_requested(cfg, "reconstruct", "reconstruct")) return 0;
        return run_reconstruct(*o, cfg, g, flags);
      });
    };
  });
}

}  // namespace sonar3d::cli
