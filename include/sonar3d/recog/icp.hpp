#pragma once
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_index.hpp"
// Trimmed ICP (Masuda et al. 1996, as the thesis uses it in sec. 6.3.2.5): the full 6D pose of a
// model from scene points, each iteration keeping only the closest fraction of correspondences,
// so that seabed, clutter and marine growth beyond the model do not pull it.
#include <Eigen/Geometry>
#include <vector>

namespace sonar3d {

struct TrimmedIcpConfig {
  int max_iterations = 60;
  double max_distance_m = 0.15;          // correspondences farther than this are never used, m
  double keep_fraction = 0.8;            // trimming: the closest fraction of correspondences kept
  bool point_to_plane = true;            // residual along the model normal (else point to point)
  double converged_m = 1e-5;             // stop when an update moves points less than this, m
  std::size_t max_scene_points = 30000;  // scene points used (a uniform stride beyond)
  void validate() const;
};
template <class V>
void describe(TrimmedIcpConfig& c, V& v) {
  using params::param;
  v.field(c.max_iterations, param("max_iterations", "", "ICP iterations at most").range(1, 10000));
  v.field(
      c.max_distance_m,
      param("max_distance_m", "m", "correspondences farther than this are never used").positive());
  v.field(c.keep_fraction,
          param("keep_fraction", "", "trimming: the closest fraction of correspondences kept")
              .range_open_low(0, 1));
  v.field(c.point_to_plane,
          param("point_to_plane", "", "residual along the model normal (else point to point)"));
  v.field(c.converged_m,
          param("converged_m", "m", "stop when an update moves points less than this").positive());
  v.field(
      c.max_scene_points,
      param("max_scene_points", "", "scene points used (a uniform stride beyond)").at_least(10));
}

struct IcpResult {
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  int iterations = 0;
  bool converged = false;
  std::size_t used = 0;  // correspondences kept at the last iteration
  double rms_m = 0;      // RMS distance of those, m
};

// A model's surface samples and their normals, searched by the library's nearest-neighbour
// index (core/point_index.hpp: nearest, nearest_within, within, points()).
class ModelIndex : public PointIndex3f {
 public:
  // Throws Error when there are no points or not one normal per point.
  ModelIndex(std::vector<Eigen::Vector3f> points, std::vector<Eigen::Vector3f> normals);
  const std::vector<Eigen::Vector3f>& normals() const { return normals_; }

 private:
  std::vector<Eigen::Vector3f> normals_;
};

// Registers `model` onto `scene_world` from `T_init`: per iteration, each scene point's nearest
// model sample (within max_distance), the closest keep_fraction of them kept (trimmed), then the
// rigid update minimising the point-to-plane (or point-to-point) distances, solved in closed
// form (linearised rotation, 6×6 normal equations). Throws Error when no correspondence is
// within max_distance at the start.
IcpResult trimmed_icp(const ModelIndex& model, const std::vector<Eigen::Vector3f>& scene_world,
                      const Eigen::Isometry3d& T_init, const TrimmedIcpConfig& config);

}  // namespace sonar3d
