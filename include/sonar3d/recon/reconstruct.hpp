#pragma once
// One entry point for every reconstruction method, used by the planner and the bindings:
// dataset in, world-frame point cloud out.
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"

namespace sonar3d {

struct ReconstructOptions {
  // "carve" (ch. 4), "deconv" (ch. 5 with the DeconvConfig defaults, see docs/deconvolution.md),
  // "deconv-l1" (L1 with
  // λ = 0.5·λ_max, Table 5.1), "deconv-exact" (exact slant-range geometry).
  std::string method = "carve";
  CarveConfig carve;
  DeconvConfig deconv;  // "deconv-l1" and "deconv-exact" set lambda_fraction / exact on a copy
  // World-frame region of interest for every method (e.g. a seabed prior: nothing below the
  // seabed). Carving maps only the voxels inside it (it replaces CarveConfig::region); the other
  // methods reconstruct as usual and keep the points inside it.
  std::optional<Eigen::AlignedBox3d> region;
  // Every method's points get the properties "bracket" and "views" (recon/bracketing.hpp); the
  // report gains "bracketing" (never-bracketed share of the region, passes that stop short) and
  // the notes a warning per short pass. bracket.min_bracket > 0 drops unbracketed points.
  BracketConfig bracket;
  bool progress = false;  // terminal bars (and a ScopedProgressCallback, core/progress.hpp)
  int num_threads = 0;    // 0 = all cores; overrides the method configs' thread counts
};

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
};

// Throws Error on an unknown method or when the method cannot run on the dataset.
ReconstructResult reconstruct_dataset(const Dataset& dataset, const ReconstructOptions& options);

// The points of `cloud` (world frame) inside `region`, with their intensities.
PointCloud crop_to_region(const PointCloud& cloud, const Eigen::AlignedBox3d& region);

// The method names reconstruct_dataset() accepts.
const std::vector<std::string>& reconstruction_methods();

}  // namespace sonar3d
