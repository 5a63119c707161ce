#include "sonar3d/recon/reconstruct.hpp"

#include <chrono>
#include <nlohmann/json.hpp>

#include "sonar3d/core/error.hpp"
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

ReconstructResult reconstruct_dataset(const Dataset& dataset, const ReconstructOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  ReconstructResult out;
  if (options.region) validate_region(*options.region, "region");
  options.bracket.validate();
  std::vector<Eigen::Isometry3d> poses;  // the frames' poses, for the bracketing assessment
  if (options.method == "carve") {
    CarveConfig cfg = options.carve;
    if (options.num_threads > 0) cfg.num_threads = options.num_threads;
    if (options.region) cfg.region = options.region;
    Carver carver(dataset.spec, cfg, dataset.noise);
    integrate_dataset(carver, dataset, options.progress);
    if (cfg.resolve_occlusions) {
      Progress bar("occlusions", dataset.size(), options.progress);
      out.cloud = carver.finalize(&bar);
    } else {
      out.cloud = carver.finalize();
    }
    for (const auto& f : carver.frame_returns()) poses.push_back(f.T_world_sonar);
    const CarveStats& st = carver.stats();
    nlohmann::ordered_json j;
    j["frames"] = st.frames;
    j["candidates"] = st.candidates;
    j["points"] = st.points;
    j["integrate_seconds"] = st.integrate_seconds;
    j["occlusion_seconds"] = st.occlusion_seconds;
    if (cfg.occlusion.explain_returns) j["ghosts_explained"] = st.ghosts;
    j["map_bytes"] = st.map_bytes;
    j["frame_bytes"] = st.frame_bytes;
    j["min_observations_used"] = st.min_observations_used;
    j["views_per_scatterer"] = st.views_per_scatterer;
    out.report = j.dump(2);
  } else if (options.method.rfind("deconv", 0) == 0 &&
             (options.method == "deconv" || options.method == "deconv-l1" ||
              options.method == "deconv-exact")) {
    DeconvConfig cfg = options.deconv;
    if (options.num_threads > 0) cfg.num_threads = options.num_threads;
    if (options.method == "deconv-l1") cfg.lambda_fraction = 0.5;  // Table 5.1
    if (options.method == "deconv-exact") cfg.exact = true;
    DeconvReport report;
    out.cloud = deconvolve_dataset(dataset, cfg, options.progress, &report);
    if (options.region) out.cloud = crop_to_region(out.cloud, *options.region);
    out.notes = report.mode_note;  // mode auto chose the voxel mode, and why
    for (const auto& w : summarize_pass_warnings(report.warnings))
      out.notes += (out.notes.empty() ? "" : "; ") + w;
    out.report = report.to_json();
    poses.reserve(dataset.size());
    for (std::size_t i = 0; i < dataset.size(); ++i) poses.push_back(dataset.T_world_sonar(i));
  } else {
    std::string list;
    for (const auto& m : reconstruction_methods()) list += (list.empty() ? "" : ", ") + m;
    throw Error("unknown reconstruction method '" + options.method + "' (available: " + list + ")");
  }
  // How well each point's elevation is known, the never-bracketed share, short passes.
  BracketConfig bc = options.bracket;
  if (options.num_threads > 0) bc.num_threads = options.num_threads;
  const BracketReport br = assess_bracketing(out.cloud, poses, dataset.spec, bc, options.region);
  for (const auto& w : br.warnings()) out.notes += (out.notes.empty() ? "" : "; ") + w;
  nlohmann::ordered_json rj = nlohmann::ordered_json::parse(out.report);
  rj["bracketing"] = nlohmann::ordered_json::parse(br.to_json());
  out.report = rj.dump(2);
  out.method = options.method;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace sonar3d
