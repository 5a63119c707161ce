#include <fmt/core.h>

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "commands.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

namespace {

struct ReconstructCliOptions {
  std::string dataset, output, vdb, json, method = "carve";
  CarveConfig carve;
  DeconvConfig deconv;
  BracketConfig bracket;
  std::string beam = "sinc";
  std::string deconv_mode = "auto";
  std::string kernel = "plain";
  std::vector<double> roi;
  bool no_occlusion = false, no_z_test = false, ascii = false, no_dering = false;
  bool allow_empty = false, overwrite = false;
  double max_memory_gb = 0;  // --max-memory (0 = the default limit)
};

// The dataset's frame poses (an error names a frame outside the navigation).
std::vector<Eigen::Isometry3d> frame_poses(const Dataset& ds) {
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(ds.size());
  for (std::size_t i = 0; i < ds.size(); ++i) poses.push_back(ds.T_world_sonar(i));
  return poses;
}

// Refuses, before the map is allocated, a carving (or the voxel mode's candidates) whose
// estimated memory exceeds --max-memory.
void check_carve_memory(const Dataset& ds, const std::vector<Eigen::Isometry3d>& poses,
                        const CarveConfig& cfg, const ReconstructCliOptions& o) {
  const std::string w = implausible_voxel_size(ds.spec, cfg.voxel_size, cfg.region, "--voxel-size");
  if (!w.empty()) print_warning(w);
  const double limit = memory_limit_bytes(o.max_memory_gb);
  check_memory(estimate_carve_memory(ds.spec, poses, cfg, limit), limit, "reconstruct");
}

// Library fields named in errors -> the flags that set them.
const FlagNames kReconstructFlags = {
    {"carve.voxel_size", "--voxel-size"},
    {"deconv.voxel.voxel_size", "--voxel-size"},
    {"carve.region", "--roi"},
    {"carve.static_threshold", "--static-threshold"},
    {"carve.carve_margin", "--carve-margin"},
    {"carve.pose_sigma_position", "--pose-sigma"},
    {"carve.pose_sigma_attitude_deg", "--attitude-sigma-deg"},
    {"carve.pose_sigma_k", "--pose-sigma-k"},
    {"carve.min_elevation_span", "--min-elevation-span"},
    {"carve.min_observations", "--min-observations"},
    {"deconv.voxel.min_observations", "--min-observations"},
    {"carve.num_threads", "--threads"},
    {"deconv.num_threads", "--threads"},
    {"bracket.num_threads", "--threads"},
    {"occlusion.num_threads", "--threads"},
    {"denoise.z_threshold", "--z-threshold"},
    {"denoise.static_threshold", "--image-threshold"},
    {"occlusion.footprint_radius", "--footprint-radius"},
    {"occlusion.range_tolerance_bins", "--range-tolerance"},
    {"occlusion.explain_pin_fraction", "--explain-pin-fraction"},
    {"bracket.min_bracket", "--min-bracket"},
    {"deconv.lambda", "--lambda"},
    {"deconv.voxel.max_iterations", "--voxel-iterations"},
    {"deconv.voxel.min_relative", "--voxel-min-relative"},
    {"deconv.voxel.min_relative_bracketed", "--voxel-min-relative-bracketed"},
    {"deconv.voxel.bracketed", "--voxel-bracketed"},
    {"deconv.voxel.support_min_bracket", "--voxel-support-bracket"},
    {"deconv.exact_range_subsamples", "--exact-range-subsamples"},
    {"deconv.max_axis_angle_deg", "--max-axis-angle-deg"},
    {"deconv.max_lateral_deviation", "--max-lateral"},
    {"deconv.kernel", "--kernel"},
    {"deconv.beam", "--beam"},
    {"deconv.mode", "--deconv-mode"},
    {"deconv.exact_lambertian", "--exact-lambertian"},
    {"deconv.exact", "--exact"},
};

// A library warning on stderr, naming flags rather than fields.
void warn(const std::string& w) { print_warning(name_flags(w, kReconstructFlags)); }

// The outputs of one run (-o, and --json, --vdb when given): checked against the output rule
// before the work starts, written under temporary names, renamed together by commit().
struct RunOutputs {
  OutputFiles files;
  std::filesystem::path ply, json, vdb;  // temporary paths ("" = not asked for)
  explicit RunOutputs(const ReconstructCliOptions& o)
      : files(output_policy(o.overwrite, {o.dataset})) {
    ply = files.add(o.output, OutputKind::PointCloud, "-o");
    if (!o.json.empty()) json = files.add(o.json, OutputKind::ReconstructionJson, "--json");
    if (!o.vdb.empty() && o.method == "carve")
      vdb = files.add(o.vdb, OutputKind::VoxelMap, "--vdb");
  }
};

// --roi: xmin ymin zmin xmax ymax zmax (checked by the library: finite, max > min).
Eigen::AlignedBox3d roi_box(const std::vector<double>& v) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(v[0], v[1], v[2]),
                                Eigen::Vector3d(v[3], v[4], v[5]));
  validate_region(box, "--roi");
  return box;
}

// Bracketing (recon/bracketing.hpp): attaches "bracket" and "views" to every point, drops the
// points below --min-bracket, prints the never-bracketed share and the passes that stop short.
BracketReport assess(PointCloud& cloud, const Dataset& ds, const std::vector<Eigen::Isometry3d>& T,
                     const ReconstructCliOptions& o,
                     const std::optional<Eigen::AlignedBox3d>& roi) {
  BracketConfig bc = o.bracket;
  bc.num_threads = o.carve.num_threads;
  const BracketReport br = assess_bracketing(cloud, T, ds.spec, bc, roi);
  fmt::print(
      "  elevation bracketing: median {:.2f} over the points; {:.1f} % of the observed region "
      "(samples every {:.2f} m{}) bracketed below {:.2f}, {:.1f} % never{} ({:.1f} s)\n",
      br.median_bracket, 100.0 * br.unbracketed_share, br.sample_step,
      roi ? " over --roi" : " over the points' box", bc.bracketed_level,
      100.0 * br.never_bracketed_share,
      bc.min_bracket > 0 ? fmt::format("; --min-bracket {:.2f} kept {} of {} points",
                                       bc.min_bracket, br.kept, br.points)
                         : std::string(),
      br.seconds);
  for (const auto& w : br.warnings()) warn(w);
  if (!br.extensions.empty() && bc.min_bracket == 0) {
    print_note(
        "--min-bracket 0.5 drops the points no frame saw from the other side of their "
        "elevation (measured: docs/carving.md, \"Elevation bracketing\")");
  }
  if (!br.extensions.empty() && o.method == "carve" && !o.carve.occlusion.explain_returns) {
    print_note(
        "on an open structure, --explain-returns with --min-bracket 0.5 also drops the "
        "ghosts inside it (measured at 20 degrees: 0-3.1 % outliers on the lattices of "
        "docs/carving.md, \"Interior ghosts\", 3.8 % on a 7 x 6 m one with "
        "--explain-pin-fraction 0.4), for an occlusion step 2 to 14 times longer");
  }
  return br;
}

// Deconvolution (thesis ch. 5): the library splits the dataset into straight passes, checks them
// (sec. 5.6.3.1) and reconstructs each; its warnings are printed, its errors stop the run.
int run_deconv(const ReconstructCliOptions& o, const GlobalOptions& g) {
  DeconvConfig cfg = o.deconv;
  cfg.beam = DeconvConfig::parse_beam(o.beam);
  cfg.mode = DeconvConfig::parse_mode(o.deconv_mode);
  cfg.kernel = DeconvConfig::parse_kernel(o.kernel);
  cfg.voxel.voxel_size = o.carve.voxel_size;  // --voxel-size, --min-observations: the voxel mode's
  cfg.voxel.min_observations = o.carve.min_observations;  // candidates are carving's
  if (cfg.exact_lambertian) cfg.exact = true;             // --exact-lambertian implies --exact
  cfg.dering = !o.no_dering;
  cfg.resolve_occlusions = !o.no_occlusion;
  cfg.denoise = o.carve.denoise;
  cfg.denoise.z_test = !o.no_z_test;
  cfg.num_threads = o.carve.num_threads;
  cfg.validate();
  std::optional<Eigen::AlignedBox3d> roi;  // checked before the work starts
  if (!o.roi.empty()) roi = roi_box(o.roi);
  RunOutputs out(o);
  const Dataset ds = read_dataset(o.dataset);
  const std::vector<Eigen::Isometry3d> poses = frame_poses(ds);
  if (cfg.mode != DeconvConfig::Mode::Passes) {  // the voxel mode carves its candidates first
    CarveConfig cc = o.carve;
    cc.voxel_size = cfg.voxel.voxel_size;
    check_carve_memory(ds, poses, cc, o);
  }
  DeconvReport report;
  PointCloud cloud = deconvolve_dataset(ds, cfg, !g.quiet, &report);
  const std::size_t before_roi = cloud.size();
  if (roi) cloud = crop_to_region(cloud, *roi);
  if (!report.mode_note.empty()) print_note(report.mode_note);  // auto chose the voxel mode
  fmt::print("{}", report.to_text(false));  // per-pass figures; the warnings below, on stderr
  const BracketReport br = assess(cloud, ds, poses, o, roi);
  if (cloud.empty() && !o.allow_empty) {
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
      throw Error("deconvolution reconstructed no pass of the " + std::to_string(ds.size()) +
                  " frames" + (why.empty() ? "" : " (" + why + ")") +
                  ": it needs straight passes along the sonar's z axis that see something "
                  "(docs/deconvolution.md); use --deconv-mode voxel (or auto) or --method carve "
                  "for other trajectories, or pass --allow-empty to write the empty cloud");
    }
    throw Error("deconvolution produced 0 points" +
                (before_roi > 0 ? " inside --roi (" + std::to_string(before_roi) + " outside)"
                 : report.mode == "voxel"
                     ? std::string(" in voxel mode from ") +
                           std::to_string(report.voxel.candidates) + " candidate voxels"
                     : std::string(" from ") + std::to_string(report.passes.size()) + " passes") +
                "; check --roi, --image-threshold and --lambda, or pass --allow-empty");
  }
  // The passes' warnings (collapsed), on stderr; a run that fails says them in its one error line.
  for (const auto& w : summarize_pass_warnings(report.warnings)) warn(w);
  write_ply(out.ply.string(), cloud, o.ascii ? PlyFormat::Ascii : PlyFormat::Binary);
  if (!o.json.empty()) {
    nlohmann::json j;
    j["format"] = json_format_marker(OutputKind::ReconstructionJson);
    j["method"] = "deconv";
    j["mode"] = report.mode;
    if (!report.mode_note.empty()) j["mode_note"] = report.mode_note;
    j["points"] = cloud.size();
    j["report"] = report.to_text();
    j["warnings"] = report.warnings;
    j["bracketing"] = nlohmann::json::parse(br.to_json());
    write_text_file(out.json.string(), j.dump(2) + "\n");
  }
  out.files.commit();
  fmt::print("wrote {} points to {}\n", cloud.size(), o.output);
  return 0;
}

int run_carve(const ReconstructCliOptions& o, const GlobalOptions& g) {
  CarveConfig cfg = o.carve;
  cfg.resolve_occlusions = !o.no_occlusion;
  cfg.denoise.z_test = !o.no_z_test;
  if (!o.roi.empty()) cfg.region = roi_box(o.roi);
  cfg.validate();
  RunOutputs out(o);
  const Dataset ds = read_dataset(o.dataset);
  check_carve_memory(ds, frame_poses(ds), cfg, o);
  Carver carver(ds.spec, cfg, ds.noise);
  integrate_dataset(carver, ds, !g.quiet);
  const std::size_t integrate_peak = peak_rss_bytes();  // before finalize's occlusion resolution
  PointCloud cloud;
  {
    Progress bar("occlusions", ds.size(), cfg.resolve_occlusions && !g.quiet);
    cloud = carver.finalize(&bar);
  }
  std::vector<Eigen::Isometry3d> poses;
  for (const auto& f : carver.frame_returns()) poses.push_back(f.T_world_sonar);
  const std::size_t before_bracket = cloud.size();
  const BracketReport br = assess(cloud, ds, poses, o, cfg.region);
  const CarveStats& st = carver.stats();
  if (cloud.empty() && before_bracket > 0 && !o.allow_empty) {
    throw Error("--min-bracket " + std::to_string(o.bracket.min_bracket) + " kept none of the " +
                std::to_string(before_bracket) +
                " points; lower it, or pass --allow-empty to write the empty cloud");
  }
  if (cloud.empty() && !o.allow_empty) {
    if (st.candidates == 0) {
      throw Error("carving found no surface: no return in any of the " + std::to_string(st.frames) +
                  " frames bounds a voxel of the map; check --roi, --image-threshold and the "
                  "frames (sonar3d preview), or pass --allow-empty to write the empty cloud");
    }
    throw Error("carving kept none of its " + std::to_string(st.candidates) +
                " candidates; relax --min-observations, --min-elevation-span or "
                "--static-threshold, try --no-occlusion, or pass --allow-empty");
  }
  write_ply(out.ply.string(), cloud, o.ascii ? PlyFormat::Ascii : PlyFormat::Binary);
  if (!out.vdb.empty()) carver.write_vdb(out.vdb.string(), &cloud);

  const double n = static_cast<double>(st.frames);
  fmt::print(
      "carved {} frames into {} candidates, {} points after occlusion resolution -> {}\n"
      "  integrate {:.1f} ms/frame, occlusion resolution {:.1f} ms/frame, map {:.1f} MB, "
      "frame summaries {:.1f} MB, peak RSS {:.0f} MB ({:.0f} MB while integrating)\n",
      st.frames, st.candidates, st.points, o.output, 1e3 * st.integrate_seconds / n,
      1e3 * st.occlusion_seconds / n, st.map_bytes / 1e6, st.frame_bytes / 1e6,
      peak_rss_bytes() / 1e6, integrate_peak / 1e6);
  if (cfg.occlusion.explain_returns) {
    fmt::print("  --explain-returns dropped {} points whose returns other surfaces explain\n",
               st.ghosts);
  }
  if (st.min_observations_used < cfg.min_observations) {
    print_note(
        fmt::format("a scatterer is seen by {:.0f} frame(s) of this trajectory, so candidates need "
                    "{} observation(s), not --min-observations {}",
                    st.views_per_scatterer, st.min_observations_used, cfg.min_observations));
  }
  if (!o.json.empty()) {
    nlohmann::json j;
    j["format"] = json_format_marker(OutputKind::ReconstructionJson);
    j["method"] = "carve";
    j["frames"] = st.frames;
    j["candidates"] = st.candidates;
    j["points"] = st.points;
    j["integrate_ms_per_frame"] = 1e3 * st.integrate_seconds / n;
    j["occlusion_ms_per_frame"] = 1e3 * st.occlusion_seconds / n;
    j["map_bytes"] = st.map_bytes;
    j["frame_bytes"] = st.frame_bytes;
    j["min_observations_used"] = st.min_observations_used;
    j["views_per_scatterer"] = st.views_per_scatterer;
    j["peak_rss_bytes"] = peak_rss_bytes();
    j["integrate_peak_rss_bytes"] = integrate_peak;
    j["leaves"] = st.leaves;
    j["candidate_voxels"] = st.candidate_voxels;
    j["occlusion_bytes"] = st.occlusion_bytes;
    if (cfg.occlusion.explain_returns) j["ghosts_explained"] = st.ghosts;
    j["voxel_size"] = cfg.voxel_size;
    j["bracketing"] = nlohmann::json::parse(br.to_json());
    write_text_file(out.json.string(), j.dump(2) + "\n");
  }
  out.files.commit();  // the cloud, its --json and --vdb together
  return 0;
}

}  // namespace

void add_reconstruct(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "reconstruct",
      "3D reconstruction of a sonar dataset. carve: space carving (thesis ch. 4): min-filter of "
      "the per-elevation bounds I/B(θ)² over frames, conservative free-space carving, occlusion "
      "resolution. deconv: deconvolution along straight passes (thesis ch. 5): per (range, "
      "bearing) column non-negative least squares with optional L1, de-ringing, occlusion "
      "resolution. Writes a PLY point cloud (world frame, intensity = reflectivity).");
  auto o = std::make_shared<ReconstructCliOptions>();
  cmd->add_option("dataset", o->dataset, "dataset directory")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--method", o->method, "reconstruction method")
      ->check(CLI::IsMember({"carve", "deconv"}))
      ->capture_default_str();
  cmd->add_option("-o,--output", o->output,
                  "point cloud to write (.ply; an existing one only if sonar3d wrote it, with "
                  "--overwrite; never inside the dataset)")
      ->required();
  cmd->add_option("--vdb", o->vdb,
                  "also write an OpenVDB file: grids carve_map (0 = free, > 0 = bound, inactive "
                  "= unknown) and surface (the output points)");
  cmd->add_option("--voxel-size", o->carve.voxel_size, "map voxel edge in metres")
      ->capture_default_str();
  cmd->add_option("--roi", o->roi,
                  "region of interest, world frame: xmin ymin zmin xmax ymax zmax (metres); "
                  "carving maps only inside it, deconvolution keeps the points inside it (e.g. "
                  "zmin at the seabed: nothing below it)")
      ->expected(6);
  cmd->add_option("--z-threshold", o->carve.denoise.z_threshold,
                  "Z-test threshold T (eq. 4.8), used when the dataset has noise statistics")
      ->capture_default_str();
  cmd->add_flag("--no-z-test", o->no_z_test, "skip the Z-test even with noise statistics");
  cmd->add_option("--image-threshold", o->carve.denoise.static_threshold,
                  "static threshold on denoised image intensities (sec. 4.4.7)")
      ->capture_default_str();
  cmd->add_option("--static-threshold", o->carve.static_threshold,
                  "static threshold on the carved bound: keep map points whose bound is > I "
                  "(sec. 4.4.7)")
      ->capture_default_str();
  cmd->add_option("--carve-margin", o->carve.carve_margin,
                  "carve a voxel only when this fraction of its half-diagonal around its centre "
                  "is free (0 = centre only, 1 = whole voxel)")
      ->capture_default_str();
  cmd->add_option("--pose-sigma", o->carve.pose_sigma_position,
                  "carving: standard deviation of each frame's position (m); a voxel is carved "
                  "only when free for every pose within --pose-sigma-k standard deviations "
                  "(navigation uncertainty; 0 = exact poses)")
      ->capture_default_str();
  cmd->add_option("--attitude-sigma-deg", o->carve.pose_sigma_attitude_deg,
                  "carving: standard deviation of each frame's attitude (degrees), as --pose-sigma")
      ->capture_default_str();
  cmd->add_option("--pose-sigma-k", o->carve.pose_sigma_k,
                  "carving: margin of the pose uncertainty, in standard deviations")
      ->capture_default_str();
  cmd->add_option("--min-elevation-span", o->carve.min_elevation_span,
                  "keep candidates observed over at least this fraction of the vertical aperture "
                  "(drops the unbracketed arcs at the ends of a pass; 0 = off)")
      ->capture_default_str();
  cmd->add_option("--min-observations", o->carve.min_observations,
                  "keep candidates bounded by at least this many frames (removes isolated noise "
                  "returns; 1 = off); lowered automatically to the number of frames that see a "
                  "point when the trajectory is sparser")
      ->capture_default_str();
  cmd->add_option("--min-bracket", o->bracket.min_bracket,
                  "drop points whose elevation was bracketed less than this (0-1: 1 = frames saw "
                  "the point at both edges of the vertical aperture, 0 = from one side only, as "
                  "beyond the end of a pass; 0 = keep all). Every point carries its bracket and "
                  "views as PLY properties either way")
      ->capture_default_str();
  cmd->add_flag("--no-occlusion", o->no_occlusion,
                "skip occlusion resolution (output every carved candidate)");
  cmd->add_option("--footprint-radius", o->carve.occlusion.footprint_radius,
                  "occlusion: angular footprint of a candidate, in voxels")
      ->capture_default_str();
  cmd->add_option("--range-tolerance", o->carve.occlusion.range_tolerance_bins,
                  "occlusion: a candidate is shadowed only by one more than this many range bins "
                  "nearer")
      ->capture_default_str();
  cmd->add_flag("--no-refute-free{false}", o->carve.occlusion.refute_free,
                "carving: keep the thesis' occlusion rule only (by default, beyond the thesis, "
                "candidates that a frame saw in an empty pixel with nothing mapped nearer on their "
                "own line of sight are dropped as free space, not shadow)");
  cmd->add_flag("--explain-returns,!--no-explain-returns", o->carve.occlusion.explain_returns,
                "carving, beyond the thesis: after occlusion resolution, drop the points whose "
                "every return another surface explains (one alone in its pixel in a share "
                "--explain-pin-fraction of the frames that see it), then refute again the free "
                "space they hid: interior ghosts of open structures (docs/carving.md)");
  cmd->add_option("--explain-pin-fraction", o->carve.occlusion.explain_pin_fraction,
                  "with --explain-returns: a point whose surface is alone in its pixel in at least "
                  "this fraction of its return frames is pinned (kept, explains others); higher "
                  "keeps fewer ghosts and less true surface, in (0, 1] (docs/carving.md)")
      ->capture_default_str();
  cmd->add_option("--lambda", o->deconv.lambda_fraction,
                  "deconv: L1 weight λ as a fraction of λ_max, in [0, 1] (eq. 5.28; 0.5 = "
                  "Table 5.1)")
      ->capture_default_str();
  cmd->add_option("--beam", o->beam,
                  "deconv: kernel beam pattern: sinc (eq. 2.8), flat (sec. 5.6.6) or sensor "
                  "(sonar.yaml's pattern)")
      ->check(CLI::IsMember({"sinc", "flat", "sensor"}))
      ->capture_default_str();
  cmd->add_option("--kernel", o->kernel,
                  "deconv: a second solve whose kernel is scaled by Lambert's cosine at the "
                  "normals of the first (normal, sec. 5.6.7.1), zeroed where the first occludes "
                  "the view (occlusion, passes mode; the voxel mode has its own occlusion model), "
                  "both (normal+occlusion), or none (plain)")
      ->check(CLI::IsMember({"plain", "normal", "occlusion", "normal+occlusion"}))
      ->capture_default_str();
  cmd->add_option(
         "--deconv-mode", o->deconv_mode,
         "deconv: passes (the thesis: per column of straight passes along the sonar z "
         "axis), voxel (any trajectory and spacing: orbits, lawnmowers, irregular passes; "
         "non-negative least squares over carving's candidate voxels, --voxel-size) or "
         "auto (passes when the frames form regular passes; voxel, with a note on stderr, when "
         "frames lie in no pass or a pass is irregular in spacing or attitude)")
      ->capture_default_str();
  cmd->add_option("--voxel-iterations", o->deconv.voxel.max_iterations,
                  "deconv, voxel mode: projected-gradient iterations at most")
      ->capture_default_str();
  cmd->add_option("--voxel-min-relative", o->deconv.voxel.min_relative,
                  "deconv, voxel mode: keep voxels whose reflectivity is at least this fraction of "
                  "the largest (0 = every non-zero voxel)")
      ->capture_default_str();
  cmd->add_option("--voxel-min-relative-bracketed", o->deconv.voxel.min_relative_bracketed,
                  "deconv, voxel mode: the same fraction for voxels whose elevation is bracketed "
                  "at least --voxel-bracketed: keeps faint surfaces seen at grazing incidence "
                  "(e.g. 0.0001; 0 = off; it also keeps the ghosts in a structure's voids, "
                  "docs/deconvolution.md sec. 9)")
      ->capture_default_str();
  cmd->add_option("--voxel-bracketed", o->deconv.voxel.bracketed,
                  "deconv, voxel mode: bracket (0-1, as --min-bracket) from which a voxel is kept "
                  "down to --voxel-min-relative-bracketed")
      ->capture_default_str();
  cmd->add_flag("--no-voxel-occlusion{false}", o->deconv.voxel.occlusion_aware,
                "deconv, voxel mode: keep every candidate in every frame's model, also where "
                "another candidate lies nearer on its ray (by default such a hidden candidate is "
                "left out of that frame: sound does not cross a surface)");
  cmd->add_option("--voxel-support-bracket", o->deconv.voxel.support_min_bracket,
                  "deconv, voxel mode: leave out of the unknowns the candidates whose elevation "
                  "was bracketed less than this (0-1, as --min-bracket; 0 = keep all): arcs "
                  "beyond where the trajectory swept the vertical aperture")
      ->capture_default_str();
  cmd->add_flag("--no-voxel-refute{false}", o->deconv.voxel.support_refute,
                "deconv, voxel mode: keep as unknowns the front candidates a frame saw in an empty "
                "pixel with nothing nearer on their line of sight (by default they are left out: "
                "free space, as carving's occlusion rule without --no-refute-free)");
  cmd->add_flag("--exact", o->deconv.exact,
                "deconv: exact slant-range geometry on a (horizontal distance × height) grid per "
                "bearing plane, for wide apertures (beyond the thesis' rectilinear model)");
  cmd->add_flag("--exact-lambertian", o->deconv.exact_lambertian,
                "deconv: exact mode (implies --exact) with the Lambertian term modelled: three "
                "normal classes per cell (facing the sonar path, up, down) instead of one; fewer "
                "ghosts above horizontal surfaces at wide apertures, 5-30x slower");
  cmd->add_flag("--exact-block-tolerance", o->deconv.exact_block_tolerance,
                "deconv: exact mode: stop when each range block's KKT violation is small against "
                "its own data, not the bearing plane's brightest return, so that weak (grazing) "
                "returns are solved too (better at 10°, more ghosts at 30°)");
  cmd->add_option("--exact-range-subsamples", o->deconv.exact_range_subsamples,
                  "deconv: exact mode: integration points per cell across its 1-bin horizontal "
                  "extent (1-16; more: lower median error, slower)")
      ->capture_default_str();
  cmd->add_flag("--no-dering", o->no_dering,
                "deconv: keep layers seen as free space (skip de-ringing, sec. 5.5.4)");
  cmd->add_option("--max-axis-angle-deg", o->deconv.max_axis_angle_deg,
                  "deconv: refuse passes whose motion is farther than this from the sonar z axis, "
                  "degrees")
      ->capture_default_str();
  cmd->add_option("--max-lateral", o->deconv.max_lateral_deviation,
                  "deconv: refuse passes whose frames lie farther than this from a straight line, "
                  "metres")
      ->capture_default_str();
  cmd->add_option("--threads", o->carve.num_threads, "worker threads (0 = all cores)")
      ->capture_default_str();
  cmd->add_flag("--ascii", o->ascii, "write an ASCII PLY");
  cmd->add_flag("--allow-empty", o->allow_empty,
                "write the cloud even when it has no point (by default an error, exit status 1)");
  cmd->add_option("--json", o->json, "also write run statistics (timings, memory) as JSON");
  add_overwrite_flag(cmd, o->overwrite, "a cloud, --json and --vdb sonar3d wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  cmd->callback([&g, &run, o] {
    run = [&g, o]() -> int {
      return with_flag_names(kReconstructFlags, [&] {
        return o->method == "deconv" ? run_deconv(*o, g) : run_carve(*o, g);
      });
    };
  });
}

}  // namespace sonar3d::cli
