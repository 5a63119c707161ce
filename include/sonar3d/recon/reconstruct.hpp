#pragma once
// One entry point for every reconstruction method, used by the planner and the bindings:
// dataset in, world-frame point cloud out.
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"

namespace sonar3d {

// The reconstruction of a dataset, whatever the method: the one configuration the command line
// (`sonar3d reconstruct`), YAML (--print-config / --config), Python (ReconstructConfig) and the
// planner read. What every method shares (voxel size, region, denoising, observation filter,
// occlusion resolution, threads) is declared here once; the method groups hold the rest, and
// reconstruct_dataset() gives each method the shared values (the deconvolution's voxel mode
// carves its candidates on the same map as carving would).
struct ReconstructConfig {
  // "carve" (ch. 4), "deconv" (ch. 5 with the DeconvConfig defaults, see docs/deconvolution.md),
  // "deconv-l1" (L1 with λ = 0.5·λ_max, Table 5.1), "deconv-exact" (exact slant-range geometry).
  static constexpr const char* kMethods[] = {"carve", "deconv", "deconv-l1", "deconv-exact"};
  std::string method = "carve";
  double voxel_size = 0.01;  // m: carving's map, the voxel mode's candidates
  // World-frame region of interest for every method (e.g. a seabed prior: nothing below the
  // seabed). Carving maps only the voxels inside it; the other methods reconstruct as usual and
  // keep the points inside it.
  std::optional<Eigen::AlignedBox3d> region;
  DenoiseConfig denoise;
  int min_observations = 2;        // carving's observation filter (CarveConfig)
  bool resolve_occlusions = true;  // sec. 4.4.5 / 5.6.7.3
  int num_threads = 0;             // 0 = all cores; every step
  // Its shared fields are replaced by the above. A reconstruction's carving drops interior ghosts
  // by default (occlusion.explain_returns, issue 29; docs/carving.md, "Interior ghosts"); a
  // CarveConfig alone (online maps, Python's carve()) keeps the thesis' rule.
  CarveConfig carve = [] {
    CarveConfig c;
    c.occlusion.explain_returns = true;
    return c;
  }();
  DeconvConfig deconv;  // likewise; "deconv-l1"/"deconv-exact" set lambda / exact
  // Every method's points get the properties "bracket" and "views" (recon/bracketing.hpp); the
  // report gains "bracketing" (never-bracketed share of the region, passes that stop short) and
  // the notes a warning per short pass. bracket.min_bracket > 0 drops unbracketed points; so does
  // bracket.auto_min_bracket, for carving, when a pass stops short (issue 29).
  BracketConfig bracket = [] {
    BracketConfig b;
    b.auto_min_bracket = true;
    return b;
  }();
  bool progress = false;  // terminal bars (not a setting: how the caller shows work)

  // The configs each step runs with: the method group with the shared fields filled in.
  CarveConfig effective_carve() const;
  DeconvConfig effective_deconv() const;
  BracketConfig effective_bracket() const;
  // The configuration a carving config alone stands for (Python's carve(), the planner).
  static ReconstructConfig from_carve(const CarveConfig& c);
  static ReconstructConfig from_deconv(const DeconvConfig& c, const std::string& method = "deconv");
  void validate() const;  // throws Error naming the dotted key
};
using ReconstructOptions = ReconstructConfig;  // the former name

// The one declaration of ReconstructConfig's fields (core/params.hpp).
template <class V>
void describe(ReconstructConfig& c, V& v) {
  using params::param;
  v.field(c.method, param("method", "",
                          "carve: space carving (ch. 4); deconv: deconvolution (ch. 5); "
                          "deconv-l1: with lambda = 0.5 lambda_max (Table 5.1); deconv-exact: "
                          "exact slant-range geometry")
                        .choices(ReconstructConfig::kMethods)
                        .flag("--method"));
  v.field(c.voxel_size,
          param("voxel_size", "m",
                "edge of a map voxel (carving's map; the deconvolution's voxel-mode candidates)")
              .range(1e-5, 1e3)
              .flag("--voxel-size"));
  v.field(c.region, param("region", "m",
                          "world-frame region of interest: carving maps only inside it, "
                          "deconvolution keeps the points inside it (none = everything in view)")
                        .flag("--roi"));
  v.group("denoise", c.denoise);
  v.field(c.min_observations,
          param("min_observations", "",
                "keep candidates bounded by at least this many frames (1 = off; lowered "
                "automatically when the trajectory is sparser)")
              .range(1, 255)
              .flag("--min-observations"));
  v.field(c.resolve_occlusions,
          param("resolve_occlusions", "", "occlusion resolution: keep the front surfaces")
              .equation("sec. 4.4.5, 5.6.7.3")
              .flag("--no-occlusion"));
  v.field(
      c.num_threads,
      param("num_threads", "", "worker threads (0 = all cores)").non_negative().flag("--threads"));
  params::Nested<CarveConfig> carve{c.carve};
  v.group("carve", carve);
  params::Nested<DeconvConfig> deconv{c.deconv};
  v.group("deconv", deconv);
  params::Nested<BracketConfig> bracket{c.bracket};
  v.group("bracket", bracket);
}

// The same result whatever the method (the Python carve(), deconvolve() and reconstruct() all
// return it).
struct ReconstructResult {
  // world frame; intensity: carved reflectivity bound or deconvolved layer b; properties
  // "bracket" and "views" (recon/bracketing.hpp)
  PointCloud cloud;
  std::string method;  // the method that ran
  double seconds = 0;
  std::string notes;  // warnings the method reported (e.g. a pass that is not straight)
  // What the method measured, as a JSON object: for carving the Carver's statistics (frames,
  // candidates, points, timings, map memory, min_observations_used, views_per_scatterer), for
  // deconvolution DeconvReport::to_json() (passes, geometry, timings, warnings).
  std::string report = "{}";
  // The same, typed (for printing): the carving's statistics (method carve), the
  // deconvolution's report (deconv methods), and the bracketing assessment (every method).
  std::optional<CarveStats> carve_stats;
  std::optional<DeconvReport> deconv_report;
  BracketReport bracketing;
  std::size_t points_before_bracket = 0;  // before bracket.min_bracket
  std::size_t points_before_region = 0;   // deconvolution: before cropping to the region
  std::size_t integrate_peak_rss = 0;     // carving: peak RSS before occlusion resolution
  std::shared_ptr<Carver> carver;         // carving, when asked for (keep_carver): the map
};

// Options of a run that are not settings of the method (how the caller uses the result).
struct ReconstructRun {
  bool keep_carver = false;  // ReconstructResult::carver holds the carving's map (e.g. --vdb)
};

// Throws Error on an unknown method or when the method cannot run on the dataset.
ReconstructResult reconstruct_dataset(const Dataset& dataset, const ReconstructConfig& config,
                                      const ReconstructRun& run = {});

// Refuses, before anything is allocated, a reconstruction whose carving (carving's map, or the
// voxel mode's candidates) would exceed `limit_bytes` (core/memory.hpp: the error gives the
// estimate and the voxel size that fits); returns the warning for an implausible voxel size
// ("" when plausible), naming `voxel_flag`. The passes mode allocates per column: nothing to check.
std::string check_reconstruct_memory(const Dataset& dataset, const ReconstructConfig& config,
                                     double limit_bytes, const std::string& voxel_flag);

// The points of `cloud` (world frame) inside `region`, with their intensities.
PointCloud crop_to_region(const PointCloud& cloud, const Eigen::AlignedBox3d& region);

// The method names reconstruct_dataset() accepts.
const std::vector<std::string>& reconstruction_methods();

}  // namespace sonar3d
