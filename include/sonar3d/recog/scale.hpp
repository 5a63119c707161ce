#pragma once
// The size of a placed CAD model (thesis sec. 6.7, future work: structures "can be found in
// various sizes"; issue 28: sizes off by ±10 %): a uniform scale searched within the catalogue's
// scale_range once the 2D method has placed the model at scale 1 (docs/recognition.md, "Scale").
//
// Convention: a placement at scale s puts the model's point p (model frame, metres) at
// T_world_model · (s · p): the scale is about the model frame's origin and T_world_model stays a
// rigid isometry. The search itself scales about the model's base centre (its horizontal centre
// at its lowest z), so that the base stays where it stood; pose_at_scale turns one into the other.
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/recog/icp.hpp"
#include "sonar3d/recog/model.hpp"

namespace sonar3d {

struct ScaleSearchConfig {
  // Scales tried evenly across the range first (the cost has local minima a bracket search
  // alone can fall into), then a golden-section search about the best to `tolerance`.
  double coarse_step = 0.02;
  double tolerance = 0.002;
  // Rounds of (scale search, trimmed ICP of the scaled model): the pose found at scale 1 is
  // biased when the structure is not symmetric about its centre; the second round searches
  // ±coarse_step about the first round's scale from the re-registered pose.
  int rounds = 2;
  // The cost compares the scene with the scaled model's top view over its footprint and a ring
  // around it (at least ring_min_m, else ring_fraction · r_model) where the scene must stand at
  // the local seabed (the ring's median height). Height differences are truncated at cap_m: a
  // cell the model claims but the scene shows as seabed (or the reverse) costs cap_m², whatever
  // the structure's height; noise below it counts as it is.
  double ring_min_m = 0.2;
  double ring_fraction = 0.25;
  double cap_m = 0.1;
  // The ICP at the chosen scale is kept only when it tilts the model at most this from upright
  // and moves it at most max_icp_shift_m (the 2D method's rules, RecognitionConfig).
  double max_tilt_deg = 10;
  double max_icp_shift_m = 0.2;
  void validate() const;
};
// max_tilt_deg and max_icp_shift_m are not declared: the 2D recognition sets them from its own.
template <class V>
void describe(ScaleSearchConfig& c, V& v) {
  using params::param;
  v.field(c.coarse_step,
          param("coarse_step", "", "scales tried evenly across the range at this step first")
              .range_open_low(0, 0.5));
  v.field(c.tolerance, param("tolerance", "", "then a golden-section search about the best to this")
                           .range_open_low(0, 0.5));
  v.field(c.rounds, param("rounds", "", "rounds of (scale search, trimmed ICP of the scaled model)")
                        .range(1, 10));
  v.field(c.ring_min_m,
          param("ring_min_m", "m", "seabed ring compared around the footprint, at least this")
              .non_negative());
  v.field(c.ring_fraction,
          param("ring_fraction", "", "else this fraction of the model's radius").range(0, 2));
  v.field(c.cap_m, param("cap_m", "m", "height differences are truncated at this").positive());
}

// `m` scaled by s about its model frame's origin: mesh, samples, centre, base, top, radius (the
// samples are not drawn again: their spacing scales with s).
ModelTemplate scaled_template(const ModelTemplate& m, double s);

// The template at a placement's scale: `m` itself at scale 1, else a scaled copy held here.
class ModelAtScale {
 public:
  ModelAtScale(const ModelTemplate& m, double s) : m_(&m) {
    if (s != 1.0) {
      held_ = scaled_template(m, s);
      m_ = &*held_;
    }
  }
  ModelAtScale(const ModelAtScale&) = delete;
  ModelAtScale& operator=(const ModelAtScale&) = delete;
  const ModelTemplate& operator*() const { return *m_; }
  const ModelTemplate* operator->() const { return m_; }

 private:
  std::optional<ModelTemplate> held_;
  const ModelTemplate* m_;
};

// The placement of `m` (unit scale) at scale s_to that keeps the base centre where
// T_world_model placed it at scale s_from (same rotation).
Eigen::Isometry3d pose_at_scale(const ModelTemplate& m, const Eigen::Isometry3d& T_world_model,
                                double s_from, double s_to);

// The cost minimised over the scale: the truncated sum of squared height differences between the
// scene (`scene`, cells in `removed` unobserved) and the top view of `m_s` (already scaled) placed
// by T_world_model, over the disc of radius `disc_m` about its centre: footprint cells against
// the model's heights (up to a vertical offset, the median difference: burial and the carving's
// bias do not count), the others against the local seabed. Divided by the disc's observed cells.
double scale_cost(const ModelTemplate& m_s, const Eigen::Isometry3d& T_world_model,
                  const ElevationMap& scene, const std::vector<uint8_t>& removed, double disc_m,
                  const ScaleSearchConfig& config);

struct ScaleFit {
  double scale = 1;  // within [m.scale_min, m.scale_max]
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();  // of m at `scale`
  double cost = 0, cost_unit = 0;  // scale_cost at `scale` and at scale 1 (same pose)
  int evaluations = 0;             // scale_cost evaluations
  int icp_runs = 0, icp_kept = 0;
  double seconds = 0;
};

// Searches m's scale in [m.scale_min, m.scale_max] about a placement T_world_model found at
// scale 1: per round, scale_cost at every coarse_step, golden section about the best, then the
// trimmed ICP of the scaled model on `scene_points` (the structure's points; skipped when `icp` is
// null or there are fewer than 6). Throws Error on a model without a scale range.
ScaleFit search_scale(const ModelTemplate& m, const Eigen::Isometry3d& T_world_model,
                      const ElevationMap& scene, const std::vector<uint8_t>& removed,
                      const std::vector<Eigen::Vector3f>& scene_points, const TrimmedIcpConfig* icp,
                      const ScaleSearchConfig& config);

}  // namespace sonar3d
