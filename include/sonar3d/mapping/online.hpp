#pragma once
// Online maps (issue 25): frames pushed as they arrive, the map queried at any time.
//
// OnlineMapper wraps the space carver (recon/carve.hpp, thesis ch. 4), which already integrates
// frame by frame (the min-filter of eq. 4.6 is order-independent), and adds what a live vehicle
// needs: poses from a navigation stream interpolated at the frame times as import does
// (linear + slerp, sec. 4.6.1; never extrapolated), bad input counted and skipped instead of
// thrown, occlusion resolution (sec. 4.4.5) run incrementally on the blocks that changed
// (Carver::resolve()), and bounded memory through a rolling window whose finished blocks go to
// disk. The same frames pushed online give the same cloud as `sonar3d reconstruct` (carving with
// the same CarveConfig). A ROS node (or a notebook) is a thin adapter: it converts messages to
// push_navigation() / push_image() and publishes cloud() / elevation() / stats() at its own rate
// (docs/online.md).
//
//   OnlineMapper map(spec, config, noise);
//   map.push_navigation(t_nav, T_world_vehicle);   // as navigation arrives
//   map.push_image(t_frame, image);                // pose interpolated when navigation brackets it
//   PointCloud cloud = map.cloud();                // at any time
//
// Not thread-safe for concurrent pushes from several threads beyond what the internal mutex
// serialises: every call locks it, so a query from another thread waits for the push in progress.
#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/denoise.hpp"

namespace sonar3d {

struct OnlineMapConfig {
  // The carving every frame goes through (voxel size, denoising, occlusion resolution, filters):
  // the same settings as batch reconstruction. carve.region is the region of interest.
  CarveConfig carve;
  // Rolling window: only the voxels within this distance (m, per axis: a cube of edge 2·window_m)
  // of the latest sonar position stay in memory; 8³ blocks that leave it are finished (resolved)
  // and written to output_dir, then freed. 0 = off (the map grows with the surveyed volume; bound
  // it with carve.region). Must be at least the sonar's r_max so the current footprint is always
  // inside the window.
  double window_m = 0;
  // The window is moved (blocks evicted) when the sonar has moved this far since the last move,
  // m; 0 = window_m / 4.
  double window_step_m = 0;
  // Directory for the finished blocks of the rolling window: block_<n>.ply, one file per window
  // move that finished points (world frame, intensity = carved bound). Created when needed.
  // Empty = finished points are counted and dropped, not written.
  std::string output_dir;
  // Memory limit for the map and the kept frame summaries (bytes); frames that arrive while the
  // map is above it are dropped and counted ("memory"). 0 = no limit.
  double max_memory_bytes = 0;
  // A frame older than the newest frame by more than this is dropped as late (s); younger
  // out-of-order frames are carved (the min-filter does not depend on the order) and counted.
  double max_lateness_s = 1.0;
  // Images waiting for navigation to reach their time (push_image()); when full the oldest is
  // dropped and counted ("queue full"): never queued without bound.
  std::size_t max_pending_images = 64;
  // Navigation samples older than the newest frame minus max_lateness_s (and than the oldest
  // pending image) are forgotten, one sample before that kept to bracket.
  ElevationMapConfig elevation;  // elevation(): cell size (region ignored: the map's extent)
  void validate() const;         // throws Error naming the field
};

// Why a frame was not carved.
enum class FrameDrop {
  None,           // carved
  WrongSize,      // image size differs from the sonar's range bins × beams
  BadPose,        // pose not finite (NaN) or not rigid
  NoPose,         // outside the navigation span: the pose would need extrapolation
  Late,           // older than the newest frame by more than max_lateness_s
  QueueFull,      // pushed out of the pending-image queue
  OutsideWindow,  // (rolling window) its footprint lies outside the window
  Memory,         // map above max_memory_bytes
  BadTime,        // time not finite
};
const char* frame_drop_name(FrameDrop d);

struct OnlineMapStats {
  std::size_t frames_received = 0;  // push_frame() + push_image() calls
  std::size_t frames_used = 0;      // carved
  std::size_t frames_pending = 0;   // images waiting for navigation
  std::size_t out_of_order = 0;     // carved although older than the newest frame
  // Dropped, by reason (FrameDrop).
  std::size_t dropped_wrong_size = 0, dropped_bad_pose = 0, dropped_no_pose = 0, dropped_late = 0,
              dropped_queue_full = 0, dropped_outside_window = 0, dropped_memory = 0,
              dropped_bad_time = 0;
  std::size_t navigation_received = 0;
  std::size_t navigation_rejected = 0;  // not finite, not rigid, or not after the previous sample
  // The map now.
  std::size_t frames_kept = 0;  // frame summaries in memory (the window drops the old ones)
  std::size_t active_voxels = 0, candidate_voxels = 0, leaves = 0;
  std::size_t map_bytes = 0, frame_bytes = 0;  // OpenVDB grids; frame summaries
  std::size_t points = 0;                      // in the last cloud()
  // Rolling window.
  std::size_t window_moves = 0, blocks_written = 0, points_finished = 0, frames_evicted = 0;
  // Latency (ms) of push_frame() (denoise + carve) over the last 1000 frames carved, and of the
  // last query's incremental occlusion resolution.
  double push_ms_last = 0, push_ms_median = 0, push_ms_p95 = 0, push_ms_max = 0;
  double resolve_ms_last = 0;
  Carver::ResolveStats last_resolve;  // what the last resolution redid
  std::size_t dropped() const;
  std::string to_json() const;  // every field, one JSON object
};

class OnlineMapper {
 public:
  // Throws Error on an invalid spec or config (naming the field), or noise statistics of another
  // size than the sonar's images.
  OnlineMapper(const SonarSpec& spec, const OnlineMapConfig& config,
               std::optional<NoiseImages> noise = std::nullopt);
  ~OnlineMapper();
  OnlineMapper(const OnlineMapper&) = delete;
  OnlineMapper& operator=(const OnlineMapper&) = delete;

  // A frame with its pose (sonar in world, T_world_sonar) at time t (s). Carved unless dropped
  // (the reason is returned and counted; nothing throws for bad input).
  FrameDrop push_frame(double t, const SonarImage& image, const Eigen::Isometry3d& T_world_sonar);
  // A navigation sample T_world_vehicle at time t (s, strictly after the previous one): frames
  // are placed at navigation(t) · spec.T_vehicle_sonar, as Dataset::T_world_sonar does. Returns
  // false (counted) for a sample that is not finite, not rigid or not after the previous one.
  // Pending images that the navigation now brackets are carved.
  bool push_navigation(double t, const Eigen::Isometry3d& T_world_vehicle);
  // A frame without pose: carved now when the navigation brackets t, queued when t is after the
  // newest navigation sample, dropped (NoPose) when before the oldest one kept. Returns None when
  // carved or queued.
  FrameDrop push_image(double t, const SonarImage& image);

  // The occlusion-resolved cloud of the map in memory (resolved incrementally): with the same
  // frames, the same points, bounds and order as batch reconstruction (Carver::finalize()).
  // Empty before the first frame.
  PointCloud cloud();
  // The candidates before occlusion resolution (cheap; Carver::snapshot()).
  PointCloud candidates() const;
  // Elevation map (sec. 6.2.1, mapping/elevation_map.hpp) of cloud() plus, with a rolling window,
  // the highest point of every cell finished so far.
  ElevationMap elevation();
  OnlineMapStats stats() const;
  // The frame counters alone, cheap enough for every message (stats() also walks the map to
  // count its voxels and bytes: O(active voxels)).
  std::size_t frames_used() const;
  std::size_t frames_pending() const;

  // Finishes every block still in memory (writes them with a rolling window) and returns their
  // points; the mapper is empty afterwards but keeps its counters and navigation.
  PointCloud flush();
  // Forgets the map, the frames, the navigation and the counters.
  void reset();

  const SonarSpec& spec() const;
  const OnlineMapConfig& config() const;
  const Carver& carver() const;  // the map itself (read-only)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonar3d
