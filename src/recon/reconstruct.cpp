#include "sonar3d/recon/reconstruct.hpp"

#include <chrono>
#include <nlohmann/json.hpp>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/recon/bracketing.hpp"

namespace sonar3d {

PointCloud crop_to_region(const PointCloud& cloud, const Eigen::AlignedBox3d& region) {
  PointCloud out;
  out.properties = cloud.properties;
  for (auto& p : out.properties) p.values.clear();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!region.contains(cloud.points[i].cast<double>())) continue;
    out.points.push_back(cloud.points[i]);
    if (cloud.has_intensity()) out.intensity.push_back(cloud.intensity[i]);
    for (std::size_t a = 0; a < out.properties.size(); ++a)
      out.properties[a].values.push_back(cloud.properties[a].values[i]);
  }
  return out;
}

const std::vector<std::string>& reconstruction_methods() {
  static const std::vector<std::string> m = {"carve", "deconv", "deconv-l1", "deconv-exact"};
  return m;
}

CarveConfig ReconstructConfig::effective_carve() const {
  CarveConfig c = carve;
  c.voxel_size = voxel_size;
  c.region = region;
  c.denoise = denoise;
  c.min_observations = min_observations;
  c.resolve_occlusions = resolve_occlusions;
  c.num_threads = num_threads;
  return c;
}

DeconvConfig ReconstructConfig::effective_deconv() const {
  DeconvConfig d = deconv;
  d.voxel.voxel_size = voxel_size;  // the voxel mode's candidates are a carving of the same map
  d.voxel.min_observations = min_observations;
  d.denoise = denoise;
  d.resolve_occlusions = resolve_occlusions;
  d.num_threads = num_threads;
  if (method == "deconv-l1") d.lambda_fraction = 0.5;  // Table 5.1
  if (method == "deconv-exact") d.exact = true;
  if (d.exact_lambertian) d.exact = true;  // the Lambertian term is the exact mode's
  return d;
}

BracketConfig ReconstructConfig::effective_bracket() const {
  BracketConfig b = bracket;
  b.num_threads = num_threads;
  // The automatic filter is carving's (issue 29, measured in docs/carving.md); deconvolution's
  // voxel mode leaves the unbracketed candidates out of its unknowns itself
  // (VoxelDeconvConfig::support_min_bracket) and the pass mode keeps its measured defaults.
  if (method != "carve") b.auto_min_bracket = false;
  return b;
}

ReconstructConfig ReconstructConfig::from_carve(const CarveConfig& c) {
  ReconstructConfig r;
  r.method = "carve";
  r.carve = c;
  // A carving config alone keeps the thesis' output, as c.occlusion.explain_returns says.
  r.bracket.auto_min_bracket = false;
  r.voxel_size = c.voxel_size;
  r.region = c.region;
  r.denoise = c.denoise;
  r.min_observations = c.min_observations;
  r.resolve_occlusions = c.resolve_occlusions;
  r.num_threads = c.num_threads;
  return r;
}

ReconstructConfig ReconstructConfig::from_deconv(const DeconvConfig& d, const std::string& method) {
  ReconstructConfig r;
  r.method = method;
  r.deconv = d;
  r.voxel_size = d.voxel.voxel_size;
  r.min_observations = d.voxel.min_observations;
  r.denoise = d.denoise;
  r.resolve_occlusions = d.resolve_occlusions;
  r.num_threads = d.num_threads;
  return r;
}

void ReconstructConfig::validate() const {
  params::check(*this, "");
  if (method == "carve") {
    effective_carve().validate();
  } else {
    effective_deconv().validate();
  }
  effective_bracket().validate();
}

namespace {

std::vector<Eigen::Isometry3d> dataset_poses(const Dataset& ds) {
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(ds.size());
  for (std::size_t i = 0; i < ds.size(); ++i) poses.push_back(ds.T_world_sonar(i));
  return poses;
}

// The carving's statistics as the report's JSON (the one serialisation of CarveStats).
nlohmann::ordered_json carve_json(const CarveStats& st, const CarveConfig& cfg,
                                  std::size_t integrate_peak) {
  const double n = st.frames > 0 ? static_cast<double>(st.frames) : 1.0;
  nlohmann::ordered_json j;
  j["frames"] = st.frames;
  j["candidates"] = st.candidates;
  j["points"] = st.points;
  j["integrate_seconds"] = st.integrate_seconds;
  j["occlusion_seconds"] = st.occlusion_seconds;
  j["integrate_ms_per_frame"] = 1e3 * st.integrate_seconds / n;
  j["occlusion_ms_per_frame"] = 1e3 * st.occlusion_seconds / n;
  if (cfg.occlusion.explain_returns) j["ghosts_explained"] = st.ghosts;
  j["map_bytes"] = st.map_bytes;
  j["frame_bytes"] = st.frame_bytes;
  j["leaves"] = st.leaves;
  j["candidate_voxels"] = st.candidate_voxels;
  j["occlusion_bytes"] = st.occlusion_bytes;
  j["min_observations_used"] = st.min_observations_used;
  j["views_per_scatterer"] = st.views_per_scatterer;
  j["integrate_peak_rss_bytes"] = integrate_peak;
  j["voxel_size"] = cfg.voxel_size;
  return j;
}

}  // namespace

std::string check_reconstruct_memory(const Dataset& dataset, const ReconstructConfig& config,
                                     double limit_bytes, const std::string& voxel_flag) {
  if (config.method != "carve" && config.effective_deconv().mode == DeconvConfig::Mode::Passes) {
    return "";
  }
  const CarveConfig cc = config.effective_carve();
  const std::string warning =
      implausible_voxel_size(dataset.spec, cc.voxel_size, cc.region, voxel_flag);
  check_memory(estimate_carve_memory(dataset.spec, dataset_poses(dataset), cc, limit_bytes),
               limit_bytes, "reconstruct");
  return warning;
}

ReconstructResult reconstruct_dataset(const Dataset& dataset, const ReconstructConfig& config,
                                      const ReconstructRun& run) {
  const auto t0 = std::chrono::steady_clock::now();
  config.validate();
  ReconstructResult out;
  nlohmann::ordered_json report;
  std::vector<Eigen::Isometry3d> poses;  // the frames' poses, for the bracketing assessment
  if (config.method == "carve") {
    const CarveConfig cfg = config.effective_carve();
    auto carver = std::make_shared<Carver>(dataset.spec, cfg, dataset.noise);
    integrate_dataset(*carver, dataset, config.progress);
    out.integrate_peak_rss = peak_rss_bytes();  // before the occlusion resolution
    {
      Progress bar("occlusions", dataset.size(), cfg.resolve_occlusions && config.progress);
      out.cloud = carver->finalize(&bar);
    }
    for (const auto& f : carver->frame_returns()) poses.push_back(f.T_world_sonar);
    out.carve_stats = carver->stats();
    report = carve_json(*out.carve_stats, cfg, out.integrate_peak_rss);
    if (run.keep_carver) out.carver = std::move(carver);
  } else {
    const DeconvConfig cfg = config.effective_deconv();
    DeconvReport dr;
    out.cloud = deconvolve_dataset(dataset, cfg, config.progress, &dr);
    out.points_before_region = out.cloud.size();
    if (config.region) out.cloud = crop_to_region(out.cloud, *config.region);
    out.notes = dr.mode_note;  // mode auto chose the voxel mode, and why
    for (const auto& w : summarize_pass_warnings(dr.warnings))
      out.notes += (out.notes.empty() ? "" : "; ") + w;
    report = nlohmann::ordered_json::parse(dr.to_json());
    out.deconv_report = std::move(dr);
    poses = dataset_poses(dataset);
  }
  // How well each point's elevation is known, the never-bracketed share, short passes.
  out.points_before_bracket = out.cloud.size();
  out.bracketing =
      assess_bracketing(out.cloud, poses, dataset.spec, config.effective_bracket(), config.region);
  for (const auto& w : out.bracketing.warnings()) out.notes += (out.notes.empty() ? "" : "; ") + w;
  report["bracketing"] = nlohmann::ordered_json::parse(out.bracketing.to_json());
  out.report = report.dump(2);
  out.method = config.method;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace sonar3d
