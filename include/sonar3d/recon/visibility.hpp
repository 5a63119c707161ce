#pragma once
// What one sonar frame says about space, shared by carving and deconvolution (thesis sec. 4.4.3,
// 4.4.5, 5.5.4, 5.6.7.3): which points it sees as free (conservative reprojection, Fig. 4.5) and
// which map points are front surfaces it observed rather than shadowed (occlusion resolution,
// Fig. 4.7–4.8).
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

// A compact summary of a denoised frame: its pose and, per beam, the returns (non-zero pixels).
// Small enough to keep for thousands of frames (the online carver keeps one per frame).
struct FrameReturns {
  Eigen::Isometry3d T_world_sonar = Eigen::Isometry3d::Identity();
  // Per beam: the first range bin holding a return, or range_bins when the beam saw nothing.
  std::vector<int> first_return_bin;
  // Row-major range bins × beams, 1 where the denoised pixel is > 0.
  std::vector<std::uint8_t> has_return;
};

FrameReturns summarize_frame(const SonarImage& denoised, const Eigen::Isometry3d& T_world_sonar,
                             const SonarSpec& spec);

// Conservative free space (Fig. 4.5): true when p_world lies inside the frame's footprint
// (field of view, vertical aperture, range window) in a pixel without return and no return lies
// at a shorter range on that beam.
bool seen_free(const FrameReturns& frame, const SonarSpec& spec, const Eigen::Vector3d& p_world);

struct OcclusionConfig {
  double elevation_resolution_rad = 0.1 * M_PI / 180.0;  // interval size along the aperture
  double voxel_size = 0.01;      // m: the final map keeps one point per voxel (sec. 4.4.5)
  double min_intensity = 0.0;    // threshold on the carved bound before resolution
  int num_threads = 0;           // 0 = all cores
  void validate() const;
};

// Occlusion resolution (sec. 4.4.5): for every frame, walks each beam from short to long range,
// labels map points (candidates, world frame, intensity = carved bound) as observed or shadowed
// by a nearer scatterer along the same elevation interval, and keeps the points observed in at
// least one frame, one per voxel with the lowest bound (carving rule).
PointCloud resolve_occlusions(const PointCloud& candidates_world,
                              const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                              const OcclusionConfig& config);

}  // namespace sonar3d
