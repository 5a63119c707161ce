// The size of a placed CAD model within the catalogue's scale_range (thesis sec. 6.7, future
// work; docs/recognition.md, "Scale"): a 1D search on the top-view agreement of eq. 6.9, then
// the trimmed ICP of sec. 6.3.2.5 at the chosen scale.
#include "sonar3d/recog/scale.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "recog_common.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/recog/recognition.hpp"

namespace sonar3d {

void ScaleSearchConfig::validate() const {
  params::check(*this, "scale search");
  require(tolerance <= coarse_step, "scale search tolerance must lie in (0, coarse_step]");
  require(max_tilt_deg >= 0 && max_tilt_deg <= 180,
          "scale search max_tilt_deg must lie in [0, 180]");
  require_non_negative(max_icp_shift_m, "scale search max_icp_shift_m", "m");
}

ModelTemplate scaled_template(const ModelTemplate& m, double s) {
  require(std::isfinite(s) && s > 0, "scaled_template: the scale must be a positive number");
  ModelTemplate out = m;
  const float f = static_cast<float>(s);
  for (auto& v : out.mesh.vertices) v *= f;
  for (auto& p : out.points) p *= f;
  out.center_xy *= s;
  out.base_z *= s;
  out.top_z *= s;
  out.radius_m *= s;
  return out;
}

Eigen::Isometry3d pose_at_scale(const ModelTemplate& m, const Eigen::Isometry3d& T, double s_from,
                                double s_to) {
  // T'·(s_to·b) = T·(s_from·b) for the base centre b, same rotation: T' = T·Trans((s_from−s_to)·b).
  const Eigen::Vector3d b(m.center_xy.x(), m.center_xy.y(), m.base_z);
  Eigen::Isometry3d out = T;
  out.translate((s_from - s_to) * b);
  return out;
}

double scale_cost(const ModelTemplate& m_s, const Eigen::Isometry3d& T, const ElevationMap& scene,
                  const std::vector<uint8_t>& removed, double disc_m,
                  const ScaleSearchConfig& config) {
  const double cell = scene.cell_m;
  TopViewConfig tv;
  tv.cell_m = cell;
  tv.grid_anchor_xy = scene.origin_xy;
  tv.background_radius_m = disc_m;  // every cell of the disc: a region independent of the scale
  tv.background_ring_m = 0;
  const Eigen::Vector2d center =
      (T * Eigen::Vector3d(m_s.center_xy.x(), m_s.center_xy.y(), 0)).head<2>();
  std::vector<uint8_t> fp;
  const ElevationMap v = render_placed_top_view(m_s, T, center, tv, &fp);
  const int dc0 = static_cast<int>(std::lround((v.origin_xy.x() - scene.origin_xy.x()) / cell));
  const int dr0 = static_cast<int>(std::lround((scene.origin_xy.y() - v.origin_xy.y()) / cell));
  // Per disc cell: the scene's height, and the model's (footprint) or none (seabed).
  std::vector<float> foot_diff, ring;
  std::vector<std::pair<float, float>> cells;  // (scene z, model z or NaN)
  cells.reserve(v.z.size());
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      const std::size_t i = v.index(r, c);
      if (v.z[i] != v.z[i]) continue;  // outside the disc
      const int rr = r + dr0, cc = c + dc0;
      if (rr < 0 || cc < 0 || rr >= scene.rows || cc >= scene.cols) continue;
      const std::size_t k = scene.index(rr, cc);
      if (!removed.empty() && removed[k]) continue;
      const float zs = scene.z[k];
      if (zs != zs) continue;  // unobserved: neither for nor against
      if (fp[i]) {
        cells.emplace_back(zs, v.z[i]);
        foot_diff.push_back(zs - v.z[i]);
      } else {
        cells.emplace_back(zs, ElevationMap::kNoData);
        ring.push_back(zs);
      }
    }
  }
  if (foot_diff.empty() || ring.empty()) return std::numeric_limits<double>::infinity();
  auto median = [](std::vector<float>& x) {
    const auto mid = x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2);
    std::nth_element(x.begin(), mid, x.end());
    return static_cast<double>(*mid);
  };
  const double zeta = median(foot_diff);  // eq. 6.1's signed median offset
  const double ground = median(ring);
  const double cap2 = config.cap_m * config.cap_m;
  double sum = 0;
  for (const auto& [zs, zm] : cells) {
    const double d = zm == zm ? zm + zeta - zs : ground - zs;
    sum += std::min(d * d, cap2);
  }
  return sum / static_cast<double>(cells.size());
}

namespace {
using Clock = std::chrono::steady_clock;
constexpr double kGolden = 0.6180339887498949;
}  // namespace

ScaleFit search_scale(const ModelTemplate& m, const Eigen::Isometry3d& T_world_model,
                      const ElevationMap& scene, const std::vector<uint8_t>& removed,
                      const std::vector<Eigen::Vector3f>& scene_points, const TrimmedIcpConfig* icp,
                      const ScaleSearchConfig& config) {
  config.validate();
  require(m.scale_searched() && m.scale_min > 0 && m.scale_min <= m.scale_max,
          "scale search: model '" + m.name + "' has no scale range");
  require(!scene.empty(), "scale search: the scene map is empty");
  const auto start = Clock::now();
  const double lo = m.scale_min, hi = m.scale_max;
  // A disc holding the largest model and its ring: the same cells are compared at every scale.
  const double ring = std::max(config.ring_min_m, config.ring_fraction * m.radius_m * hi);
  const double disc = m.radius_m * hi + ring;
  ScaleFit out;
  out.scale = 1;
  out.T_world_model = T_world_model;
  // The pose the costs are measured about (scale `pose_scale`), updated by each round's ICP.
  Eigen::Isometry3d T_pose = T_world_model;
  double pose_scale = 1;
  auto cost = [&](double s) {
    ++out.evaluations;
    return scale_cost(scaled_template(m, s), pose_at_scale(m, T_pose, pose_scale, s), scene,
                      removed, disc, config);
  };
  out.cost_unit = cost(1.0);
  double a = lo, b = hi;
  for (int round = 0; round < config.rounds; ++round) {
    // Coarse: every coarse_step across [a, b] (both ends included).
    const int n = std::max(1, static_cast<int>(std::ceil((b - a) / config.coarse_step - 1e-9)));
    double best_s = a, best_c = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= n; ++k) {
      const double s = a + (b - a) * k / n;
      const double c = cost(s);
      if (c < best_c) best_c = c, best_s = s;
    }
    // Golden section about the best coarse scale.
    const double h = (b - a) / n;
    double x0 = std::max(lo, best_s - h), x3 = std::min(hi, best_s + h);
    double x1 = x3 - kGolden * (x3 - x0), x2 = x0 + kGolden * (x3 - x0);
    double c1 = cost(x1), c2 = cost(x2);
    while (x3 - x0 > config.tolerance) {
      if (c1 <= c2) {
        x3 = x2, x2 = x1, c2 = c1;
        x1 = x3 - kGolden * (x3 - x0);
        c1 = cost(x1);
      } else {
        x0 = x1, x1 = x2, c1 = c2;
        x2 = x0 + kGolden * (x3 - x0);
        c2 = cost(x2);
      }
    }
    double s = c1 <= c2 ? x1 : x2, c = std::min(c1, c2);
    if (best_c < c) s = best_s, c = best_c;
    s = std::clamp(s, lo, hi);
    out.scale = s;
    out.cost = c;
    out.T_world_model = pose_at_scale(m, T_pose, pose_scale, s);
    // Trimmed ICP of the scaled model (sec. 6.3.2.5): the pose re-fitted at this size.
    if (icp && scene_points.size() >= 6) {
      const ModelTemplate ms = scaled_template(m, s);
      const ModelIndex index(ms.points, ms.normals);
      ++out.icp_runs;
      try {
        const IcpResult r = trimmed_icp(index, scene_points, out.T_world_model, *icp);
        const Eigen::Vector3d c_model(ms.center_xy.x(), ms.center_xy.y(),
                                      0.5 * (ms.base_z + ms.top_z));
        const double shift = (r.T_world_model * c_model - out.T_world_model * c_model).norm();
        const double tilt =
            std::acos(std::clamp(r.T_world_model.linear()(2, 2), -1.0, 1.0)) * 180 / M_PI;
        if (tilt <= config.max_tilt_deg && shift <= config.max_icp_shift_m) {
          out.T_world_model = r.T_world_model;
          ++out.icp_kept;
        }
      } catch (const Error&) {
        // No scene point near the scaled model: the pose stays.
      }
    }
    T_pose = out.T_world_model;
    pose_scale = s;
    a = std::max(lo, s - config.coarse_step);
    b = std::min(hi, s + config.coarse_step);
  }
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

void refine_placement_scale(const ModelTemplate& m, Placement& p, const ElevationMap& fine,
                            const std::vector<uint8_t>& removed_fine,
                            const std::vector<Eigen::Vector3f>& local,
                            const RecognitionConfig& config) {
  ScaleSearchConfig sc = config.scale;
  sc.max_tilt_deg = config.max_tilt_deg;
  sc.max_icp_shift_m = config.max_icp_shift_m;
  const ScaleFit f = search_scale(m, p.T_world_model, fine, removed_fine, local,
                                  config.run_icp ? &config.icp : nullptr, sc);
  const ModelAtScale ms(m, f.scale);
  p.scale = f.scale;
  p.T_world_model = f.T_world_model;
  p.residual = structure_residual(local, *ms, f.T_world_model);
  p.set_verification(
      verify_placement(*ms, f.T_world_model, fine, removed_fine, config.verification));
  p.seconds_scale = f.seconds;
}

}  // namespace sonar3d
