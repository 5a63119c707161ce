#pragma once
// Space carving (thesis ch. 4): every frame bounds the reflectivity of each map voxel in its
// footprint by I/B(θ)² (eq. 4.7) and the map keeps the minimum over frames (eq. 4.6, min-filter);
// an empty pixel with no return nearer on its beam carves its voxels to 0 (conservative
// reprojection, Fig. 4.5). A final occlusion resolution keeps the front surfaces (sec. 4.4.5).
//
// Unlike the thesis' pixel-to-points expansion (sec. 4.4.2, 4.4.6), each frame projects the centre
// of every map voxel in its footprint into the image (voxel-centric), so the map has neither holes
// nor aliasing whatever the range, bearing and voxel resolutions. The map is an OpenVDB float grid:
//   inactive voxel      = never observed (unknown)
//   active, value 0     = seen free (carved); stays free (min with 0 is 0)
//   active, value v > 0 = candidate scatterer whose reflectivity is at most v
// Wholly free 8³ (and 128³) cubes are stored as single tiles, so memory follows the mapped
// volume and its surfaces, not the number of frames. See docs/carving.md.
//
//   Carver carver(spec, config, dataset.noise);
//   for (...) carver.integrate(image, T_world_sonar);   // online; snapshot() at any time
//   PointCloud cloud = carver.finalize();                  // occlusion resolution
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/denoise.hpp"
#include "sonar3d/recon/visibility.hpp"

namespace sonar3d {

class Progress;  // core/progress.hpp

// Throws Error naming `name` unless the box has finite corners and max > min on every axis.
void validate_region(const Eigen::AlignedBox3d& region, const std::string& name);

struct CarveConfig {
  double voxel_size = 0.01;  // m, edge of a map voxel
  // World-frame region of interest: only voxels whose centre lies inside are mapped. Empty = all
  // that the sonar sees (memory then grows with the swept volume).
  std::optional<Eigen::AlignedBox3d> region;
  DenoiseConfig denoise;  // applied to every frame before carving (sec. 4.4.7)
  bool resolve_occlusions = true;
  // occlusion.voxel_size and occlusion.num_threads are overridden by this config's voxel_size and
  // num_threads; occlusion.min_intensity by static_threshold when the latter is larger.
  // refute_free is on for carving (measured: docs/carving.md, "Free space behind another
  // elevation's return").
  OcclusionConfig occlusion = [] {
    OcclusionConfig c;
    c.refute_free = true;
    return c;
  }();
  // Static threshold on the map (sec. 4.4.7): keep candidates whose bound is > this.
  double static_threshold = 0.0;
  // A voxel is carved only when the ball of radius carve_margin × (half its diagonal) around its
  // centre lies in free space; 0 = the point rule (the voxel centre alone: thinner surfaces,
  // measured best, docs/carving.md), 1 = the whole voxel (keeps the voxel whose centre falls just
  // in front of the return's range bin: surfaces one voxel thicker).
  double carve_margin = 0.0;
  // Navigation uncertainty (issue 15 item 4, thesis future work): per-frame standard deviations
  // of the sonar position (m) and attitude (deg). A voxel is carved only when the ball of radius
  // pose_sigma_k·(σ_position + r_max·σ_attitude) around its centre (added to the carve_margin
  // ball) lies in free space in the frame: the empty region is eroded by the displacement the
  // pose error can cause, so a surface the pose error moves into an empty pixel is not carved.
  // 0 = poses are exact (the thesis).
  double pose_sigma_position = 0.0;
  double pose_sigma_attitude_deg = 0.0;
  double pose_sigma_k = 2.0;
  // Keep only candidates whose observations (return pixels) spread over at least this fraction
  // of the vertical aperture (in sin θ). The min-filter bounds a scatterer along the elevation
  // arc only where frames saw free space on both sides of it; at the edges of a pass (below the
  // lowest frame, above the highest) a return's arc is never carved and stays as outliers. 0 =
  // off (the thesis' rule, and the right choice for trajectories that do not sweep the
  // elevation, e.g. level approaches).
  double min_elevation_span = 0.0;
  // Keep only candidates bounded by at least this many return pixels (frames). A noise pixel that
  // passes the Z-test (0.13 % of them at T = 3) bounds its arc in one frame only, while a surface
  // is seen by every frame whose aperture covers it. 1 = off (the thesis' rule; a snapshot then
  // also shows what a single frame bounded). Lowered automatically when the frames are too sparse
  // for a surface to be seen that many times: see Carver::min_observations_used().
  int min_observations = 2;
  int num_threads = 0;    // 0 = all cores (TBB)
  void validate() const;  // throws Error naming the field
};

// The one declaration of CarveConfig's fields (core/params.hpp). describe_carve_own lists those
// that only carving has; a reconstruction (recon/reconstruct.hpp) declares the others once for
// every method and describes its carving as Nested<CarveConfig>.
template <class V>
void describe_carve_own(CarveConfig& c, V& v) {
  using params::param;
  params::Nested<OcclusionConfig> occlusion{c.occlusion};
  v.group("occlusion", occlusion);
  v.field(c.static_threshold,
          param("static_threshold", "", "keep map points whose carved bound is > this")
              .range(-1e30, 1e30)
              .equation("sec. 4.4.7")
              .flag("--static-threshold"));
  v.field(c.carve_margin,
          param("carve_margin", "",
                "carve a voxel only when this fraction of its half-diagonal around its centre "
                "is free (0 = centre only, 1 = whole voxel)")
              .range(0, 1)
              .flag("--carve-margin"));
  v.field(c.pose_sigma_position,
          param("pose_sigma_position", "m",
                "standard deviation of each frame's position: a voxel is carved only when free "
                "for every pose within pose_sigma_k standard deviations (0 = exact poses)")
              .range(0, 10)
              .flag("--pose-sigma"));
  v.field(c.pose_sigma_attitude_deg,
          param("pose_sigma_attitude_deg", "deg",
                "standard deviation of each frame's attitude, as pose_sigma_position")
              .range(0, 30)
              .flag("--attitude-sigma-deg"));
  v.field(c.pose_sigma_k,
          param("pose_sigma_k", "", "margin of the pose uncertainty, in standard deviations")
              .range_open_low(0, 10)
              .flag("--pose-sigma-k"));
  v.field(c.min_elevation_span,
          param("min_elevation_span", "",
                "keep candidates observed over at least this fraction of the vertical aperture "
                "(drops the unbracketed arcs at the ends of a pass; 0 = off)")
              .range(0, 1)
              .flag("--min-elevation-span"));
}
template <class V>
void describe(CarveConfig& c, V& v) {
  using params::param;
  v.field(c.voxel_size, param("voxel_size", "m", "edge of a map voxel").range(1e-5, 1e3));
  v.field(c.region, param("region", "m", "world-frame region of interest (none = all in view)"));
  v.group("denoise", c.denoise);
  v.field(c.resolve_occlusions,
          param("resolve_occlusions", "", "keep the front surfaces").equation("sec. 4.4.5"));
  v.field(c.min_observations,
          param("min_observations", "",
                "keep candidates bounded by at least this many frames (1 = off)")
              .range(1, 255));
  v.field(c.num_threads, param("num_threads", "", "worker threads (0 = all cores)").non_negative());
  describe_carve_own(c, v);
}
template <class V>
void describe(params::Nested<CarveConfig>& n, V& v) {
  describe_carve_own(n.c, v);
}

struct CarveStats {
  std::size_t frames = 0;
  double integrate_seconds = 0;  // total wall time in integrate() (denoise included)
  double occlusion_seconds = 0;  // wall time of finalize()'s occlusion resolution
  std::size_t candidates = 0;    // points before occlusion resolution (last finalize/snapshot)
  std::size_t points = 0;        // points after finalize()
  std::size_t map_bytes = 0;     // OpenVDB grid memory
  std::size_t frame_bytes = 0;   // kept per-frame return summaries
  std::size_t leaf_voxels_visited = 0;  // voxels projected one by one (work counter)
  double views_per_scatterer =
      0;  // median frames seeing a mid-range boresight point (0: < 2 frames)
  int min_observations_used = 0;  // the observation filter the last snapshot/finalize applied
  // Map contents (refreshed by stats()): voxels known (active), of which candidates (value > 0),
  // and leaves (8³ voxel blocks stored densely).
  std::size_t active_voxels = 0;
  std::size_t candidate_voxels = 0;
  std::size_t leaves = 0;
  std::size_t occlusion_bytes = 0;  // working memory of the last finalize()'s occlusion resolution
  std::size_t ghosts = 0;           // points the last finalize()'s return explanation removed
};

class Carver {
 public:
  // `noise`: per-pixel noise statistics for the Z-test (eq. 4.8); without them only the static
  // image threshold of config.denoise applies. Throws Error on an invalid spec or config.
  Carver(const SonarSpec& spec, const CarveConfig& config,
         std::optional<NoiseImages> noise = std::nullopt);
  ~Carver();
  Carver(const Carver&) = delete;
  Carver& operator=(const Carver&) = delete;

  // Denoises `image` (raw, linear intensities) and carves it into the map. Throws Error naming
  // the frame (its integration index, or `frame_label` when given) on a wrong image size or a
  // non-finite / non-rigid pose.
  void integrate(const SonarImage& image, const Eigen::Isometry3d& T_world_sonar,
                 const std::string& frame_label = "");

  // Current candidates (world frame, voxel centres, intensity = carved bound) above the static
  // threshold. Cheap enough to call while frames arrive.
  PointCloud snapshot() const;

  // Occlusion resolution over every frame integrated so far (or the snapshot when
  // config.resolve_occlusions is false). The carver stays usable afterwards. Throws Error when no
  // frame was integrated.
  PointCloud finalize(Progress* progress = nullptr);

  // Incremental occlusion resolution (issue 25, online maps): the same cloud as finalize(), in
  // the same order, but only the 8³ blocks whose result can have changed since the last call are
  // resolved again. A block's result (sec. 4.4.5: observed in some frame, refuted in none) depends
  // on the frames whose footprint holds it and, through their depth grids, on the candidates
  // nearer along those frames' lines of sight; so after new frames the blocks redone are those in
  // the footprints of the new frames and of the old frames that see a block whose candidates
  // changed, tested against every frame that sees them, with every candidate in those frames'
  // footprints as occluders (docs/online.md). The first call, and any call after the observation
  // filter (min_observations_used()) changed, resolves everything. With
  // config.occlusion.explain_returns the explanation then runs over the whole cloud, as in
  // finalize(). Throws Error when no frame was integrated.
  PointCloud resolve(Progress* progress = nullptr);
  struct ResolveStats {
    bool full = false;        // everything resolved (first call, filter changed)
    std::size_t blocks = 0;   // 8³ blocks whose result was recomputed
    std::size_t context = 0;  // blocks projected as occluders (including those)
    std::size_t frames = 0;   // frames the recomputation tested them against
    std::size_t cached = 0;   // blocks holding candidates, all told
    double seconds = 0;       // wall time of the resolution (assembly excluded)
  };
  const ResolveStats& last_resolve() const;

  // Rolling window (issue 25): resolves (incrementally), then removes from the map every 8³ block
  // that lies wholly outside `keep` (world frame) and returns the points those blocks kept, with
  // their bounds: they are finished. Frames whose footprint lies wholly outside `keep` are
  // dropped too (`frames_dropped` receives how many): no block left can lie in them. A block
  // finished here is final only if no later frame sees it: a map that comes back to it starts
  // again from unknown (docs/online.md).
  PointCloud evict_outside(const Eigen::AlignedBox3d& keep, std::size_t* frames_dropped = nullptr);

  // Writes an OpenVDB file (atomically) with the grid "carve_map" (the map: active 0 = free,
  // active v > 0 = bound, inactive = unknown) and, when `surface` is given, a grid "surface" with
  // one active voxel per point holding its intensity.
  void write_vdb(const std::string& path, const PointCloud* surface = nullptr) const;

  std::size_t frames() const;
  // Memory of the map grids, the frame summaries and the incremental resolution's cache (bytes),
  // without the full statistics pass of stats(): cheap enough to check after every frame.
  std::size_t memory_bytes() const;
  const std::vector<FrameReturns>& frame_returns() const;
  const CarveStats& stats() const;
  // The observation filter that applies to the frames integrated so far: config.min_observations,
  // lowered to the number of frames a scatterer at mid range can be seen in when the trajectory
  // is sparser than that (e.g. a 1° sonar stepping 5 cm at 3 m sees each point once, and a
  // filter asking for two would delete the whole surface). With one frame, 1.
  int min_observations_used() const;  // map_bytes/frame_bytes refreshed on each call
  const SonarSpec& spec() const;
  const CarveConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Integrates every frame of a dataset in order (frames are read and denoised ahead, in parallel),
// with a progress bar when `progress` is set. Throws Error on an empty dataset or a frame without
// pose (naming the frame).
void integrate_dataset(Carver& carver, const Dataset& dataset, bool progress);

// Integrates frames first…last (inclusive, in order) of a dataset the same way — the next frames
// read and decoded in parallel while one is carved — counting each on `bar` when given (a swath
// of `sonar3d map` or `relocalize`). Throws Error naming the first frame that fails.
void integrate_frames(Carver& carver, const Dataset& dataset, std::size_t first, std::size_t last,
                      Progress* bar);

// Memory a carving of these poses will take (core/memory.hpp), estimated before anything is
// allocated from the sonar's footprint, the poses, config.region and config.voxel_size: the map's
// nodes on the boundary of the observed volume and the frame summaries (the candidate surfaces
// add to it: docs/carving.md, "Memory"). With `limit_bytes` > 0 and an estimate above it, the
// advice names the voxel size that fits.
MemoryEstimate estimate_carve_memory(const SonarSpec& spec,
                                     const std::vector<Eigen::Isometry3d>& poses,
                                     const CarveConfig& config, double limit_bytes = 0);

// A warning (naming `flag`) when a voxel edge is implausible for the data, "" otherwise: more than
// 10 times the sonar's resolution cell (its range bin, or its beam width at r_max, whichever is
// larger: every structure the sonar resolves is then a voxel or two) or more than a quarter of
// the region's smallest extent; such values are usually centimetres given as metres.
std::string implausible_voxel_size(const SonarSpec& spec, double voxel_size,
                                   const std::optional<Eigen::AlignedBox3d>& region,
                                   const std::string& flag);

// World box of what these poses' footprints cover (the sonar's wedges), clipped to `region`;
// empty when nothing lies inside it.
Eigen::AlignedBox3d footprint_bounds(const SonarSpec& spec,
                                     const std::vector<Eigen::Isometry3d>& poses,
                                     const std::optional<Eigen::AlignedBox3d>& region);

// Peak resident memory of this process in bytes (Linux: VmHWM), 0 when unknown.
std::size_t peak_rss_bytes();

}  // namespace sonar3d
