// The 3D recognition method (thesis sec. 6.3.1): spherical subspaces (eq. 6.3), the subspace
// analysis of eq. 6.4-6.7, direct 3D matching in the survivors (yaw sweep + trimmed ICP with the
// upright prior; principal-axes hypotheses + trimmed ICP without), a residual threshold,
// non-maximum suppression, models in decreasing size with their points removed.
#include "sonar3d/recog/recognition_3d.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include "recog_common.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"

namespace sonar3d {

namespace {
using namespace recog_internal;
using V3f = Eigen::Vector3f;

// Voxel keys of `points` at edge `voxel` (21 bits per axis from the points' minimum corner).
std::vector<uint64_t> voxel_keys(const std::vector<V3f>& points, double voxel) {
  V3f lo = V3f::Constant(std::numeric_limits<float>::infinity());
  V3f hi = -lo;
  for (const auto& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double span = (hi - lo).maxCoeff();
  limits::checked_count(span / voxel, 0, (1 << 21) - 2, "voxels across the points",
                        "the cloud is too large for this voxel size (is its unit metres?)");
  std::vector<uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d k = ((points[i] - lo).cast<double>() / voxel).array().floor();
    keys[i] = static_cast<uint64_t>(k.x()) | (static_cast<uint64_t>(k.y()) << 21) |
              (static_cast<uint64_t>(k.z()) << 42);
  }
  return keys;
}

// Centroid (and mean normal, when normals are given) of the points of each voxel.
void subsample(const std::vector<V3f>& points, const std::vector<V3f>* normals, double voxel,
               std::vector<V3f>* out, std::vector<V3f>* out_normals,
               std::vector<uint32_t>* counts = nullptr) {
  out->clear();
  if (out_normals) out_normals->clear();
  if (counts) counts->clear();
  if (points.empty()) return;
  const std::vector<uint64_t> keys = voxel_keys(points, voxel);
  std::vector<uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return keys[a] < keys[b] || (keys[a] == keys[b] && a < b);
  });
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), nsum = Eigen::Vector3d::Zero();
    for (; j < order.size() && keys[order[j]] == keys[order[i]]; ++j) {
      sum += points[order[j]].cast<double>();
      if (normals) nsum += (*normals)[order[j]].cast<double>();
    }
    out->push_back((sum / static_cast<double>(j - i)).cast<float>());
    if (counts) counts->push_back(static_cast<uint32_t>(j - i));
    if (normals && out_normals) {
      out_normals->push_back(nsum.norm() > 1e-9 ? V3f(nsum.normalized().cast<float>())
                                                : (*normals)[order[i]]);
    }
    i = j;
  }
}

// Local seabed height: per ground cell the lowest point, then per cell a low quantile of those
// within the window (a structure covering less than that fraction of the window does not raise
// it).
struct Ground {
  double x0 = 0, y0 = 0, cell = 1;
  int nx = 0, ny = 0;
  std::vector<float> z;  // NaN: unknown
  double at(double x, double y) const {
    const int c = static_cast<int>(std::floor((x - x0) / cell));
    const int r = static_cast<int>(std::floor((y - y0) / cell));
    if (c < 0 || r < 0 || c >= nx || r >= ny) return std::numeric_limits<double>::quiet_NaN();
    return z[static_cast<std::size_t>(r) * nx + c];
  }
};

Ground estimate_ground(const std::vector<V3f>& points, const Recognition3dConfig& cfg) {
  Ground g;
  if (points.empty()) return g;
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.head<2>().cast<double>());
    hi = hi.cwiseMax(p.head<2>().cast<double>());
  }
  g.cell = cfg.ground_cell_m;
  g.x0 = lo.x();
  g.y0 = lo.y();
  g.nx = static_cast<int>(std::floor((hi.x() - lo.x()) / g.cell)) + 1;
  g.ny = static_cast<int>(std::floor((hi.y() - lo.y()) / g.cell)) + 1;
  limits::checked_count(static_cast<double>(g.nx) * g.ny, 1, 1e8, "seabed estimate cells",
                        "use a larger ground_cell_m");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> zmin(static_cast<std::size_t>(g.nx) * g.ny, nan);
  for (const auto& p : points) {
    const int c = std::min(g.nx - 1, static_cast<int>((p.x() - g.x0) / g.cell));
    const int r = std::min(g.ny - 1, static_cast<int>((p.y() - g.y0) / g.cell));
    float& z = zmin[static_cast<std::size_t>(r) * g.nx + c];
    if (!(z <= p.z())) z = p.z();
  }
  g.z.assign(zmin.size(), nan);
  const int w = static_cast<int>(std::ceil(cfg.ground_window_m / g.cell));
  tbb::parallel_for(0, g.ny, [&](int r) {
    std::vector<float> v;
    for (int c = 0; c < g.nx; ++c) {
      v.clear();
      for (int rr = std::max(0, r - w); rr <= std::min(g.ny - 1, r + w); ++rr) {
        for (int cc = std::max(0, c - w); cc <= std::min(g.nx - 1, c + w); ++cc) {
          const float z = zmin[static_cast<std::size_t>(rr) * g.nx + cc];
          if (z == z) v.push_back(z);
        }
      }
      if (v.empty()) continue;
      const auto k = v.begin() + static_cast<std::ptrdiff_t>(cfg.ground_quantile *
                                                             static_cast<double>(v.size() - 1));
      std::nth_element(v.begin(), k, v.end());
      g.z[static_cast<std::size_t>(r) * g.nx + c] = *k;
    }
  });
  return g;
}

// Points higher than the local seabed plus `clearance`.
std::vector<V3f> above_ground(const std::vector<V3f>& points, const Ground& g, double clearance) {
  std::vector<V3f> out;
  for (const auto& p : points) {
    const double z = g.at(p.x(), p.y());
    if (!(p.z() < z + clearance)) out.push_back(p);
  }
  return out;
}

// Trimmed mean distance from `scene` to the model placed by T (each capped at `cap`): the
// closest 80 % kept, as the ICP trims.
double trimmed_mean_distance(const ModelIndex& model, const std::vector<V3f>& scene,
                             const Eigen::Isometry3d& T_world_model, double cap) {
  if (scene.empty()) return std::numeric_limits<double>::infinity();
  const Eigen::Isometry3f T_mw = T_world_model.inverse().cast<float>();
  std::vector<float> d(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i) {
    float d2 = 0;
    model.nearest(T_mw * scene[i], &d2);
    d[i] = std::min(std::sqrt(d2), static_cast<float>(cap));
  }
  const std::size_t keep = std::max<std::size_t>(1, (d.size() * 4) / 5);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(keep - 1), d.end());
  return std::accumulate(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(keep), 0.0) /
         static_cast<double>(keep);
}

// A uniform stride of at most n points.
std::vector<V3f> thin(const std::vector<V3f>& pts, std::size_t n) {
  if (pts.size() <= n) return pts;
  std::vector<V3f> out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(pts[i * pts.size() / n]);
  return out;
}

// Coarse (wide gate) then fine trimmed ICP from T0.
IcpResult refine(const ModelIndex& model, const std::vector<V3f>& scene,
                 const Eigen::Isometry3d& T0, const Recognition3dConfig& cfg) {
  TrimmedIcpConfig coarse = cfg.icp;
  coarse.max_distance_m = std::max(cfg.coarse_gate_m, cfg.icp.max_distance_m);
  coarse.max_iterations = cfg.coarse_iterations;
  IcpResult r = trimmed_icp(model, scene, T0, coarse);
  try {
    r = trimmed_icp(model, scene, r.T_world_model, cfg.icp);
  } catch (const Error&) {
    // Nothing within the fine gate after the coarse pass: keep the coarse result.
  }
  return r;
}

// Centre (3D) of a model's bounding box, model frame.
Eigen::Vector3d model_center(const ModelTemplate& m) {
  return {m.center_xy.x(), m.center_xy.y(), 0.5 * (m.base_z + m.top_z)};
}

// The 24 rotations of the cube (signed permutation matrices of determinant +1).
std::vector<Eigen::Matrix3d> cube_rotations() {
  std::vector<Eigen::Matrix3d> out;
  std::array<int, 3> perm{0, 1, 2};
  do {
    for (int s = 0; s < 8; ++s) {
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      for (int i = 0; i < 3; ++i) M(i, perm[i]) = (s >> i) & 1 ? -1.0 : 1.0;
      if (M.determinant() > 0) out.push_back(M);
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return out;
}

// Principal axes (columns, a right-handed frame) and centroid of a point set.
void principal_frame(const std::vector<V3f>& pts, Eigen::Matrix3d* E, Eigen::Vector3d* c) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p.cast<double>();
  mean /= static_cast<double>(std::max<std::size_t>(1, pts.size()));
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) {
    const Eigen::Vector3d d = p.cast<double>() - mean;
    C += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  *E = es.eigenvectors();
  if (E->determinant() < 0) E->col(0) *= -1;
  *c = mean;
}

}  // namespace

void Recognition3dConfig::validate() const {
  require_positive(voxel_m, "3D recognition voxel_m", "m");
  require(period_fraction > 0.05 && period_fraction <= 4,
          "3D recognition period_fraction (T / r_model) must lie in (0.05, 4]");
  require(alpha_fit > 0 && alpha_fit <= 100, "3D recognition alpha_fit must lie in (0, 100]");
  require(alpha_volume >= 0 && alpha_volume <= 100,
          "3D recognition alpha_volume must lie in [0, 100]");
  require(n_min >= 3, "3D recognition n_min must be >= 3");
  require(alpha_occupancy >= 0 && alpha_occupancy <= 100,
          "3D recognition alpha_occupancy must lie in [0, 100]");
  require_positive(occupancy_voxel_m, "3D recognition occupancy_voxel_m", "m");
  require(yaw_step_deg > 0 && yaw_step_deg <= 180,
          "3D recognition yaw_step_deg must lie in (0, 180]");
  require_non_negative(seabed_clearance_m, "3D recognition seabed_clearance_m", "m");
  require_positive(ground_cell_m, "3D recognition ground_cell_m", "m");
  require_non_negative(ground_window_m, "3D recognition ground_window_m", "m");
  require(ground_quantile >= 0 && ground_quantile <= 1,
          "3D recognition ground_quantile must lie in [0, 1]");
  require(starts >= 1 && starts <= 100, "3D recognition starts must lie in 1-100");
  require_positive(coarse_gate_m, "3D recognition coarse_gate_m", "m");
  require(coarse_iterations >= 1 && coarse_iterations <= 10000,
          "3D recognition coarse_iterations must lie in 1-10000");
  require(dedup_fraction >= 0 && dedup_fraction <= 10,
          "3D recognition dedup_fraction must lie in [0, 10]");
  require(max_points >= 10, "3D recognition max_points must be >= 10");
  require_positive(max_start_score_m, "3D recognition max_start_score_m", "m");
  icp.validate();
  require_positive(max_residual_median_m, "3D recognition max_residual_median_m", "m");
  require(min_coverage >= 0 && min_coverage <= 1, "3D recognition min_coverage must lie in [0, 1]");
  require_positive(coverage_tol_m, "3D recognition coverage_tol_m", "m");
  require(max_tilt_deg >= 0 && max_tilt_deg <= 180,
          "3D recognition max_tilt_deg must lie in [0, 180]");
  require(nms_fraction >= 0 && nms_fraction <= 10,
          "3D recognition nms_fraction must lie in [0, 10]");
  require_non_negative(removal_margin_m, "3D recognition removal_margin_m", "m");
  require(max_instances >= 1 && max_instances <= kMaxExpectedInstances,
          "3D recognition max_instances must lie in [1, " + std::to_string(kMaxExpectedInstances) +
              "]");
  sampling.validate();
  require(num_threads >= 0, "3D recognition num_threads must be >= 0 (0 = all cores)");
}

std::vector<Eigen::Vector3f> voxel_subsample(const std::vector<Eigen::Vector3f>& points,
                                             double voxel_m) {
  require_positive(voxel_m, "voxel subsampling voxel_m", "m");
  std::vector<V3f> out;
  subsample(points, nullptr, voxel_m, &out, nullptr);
  return out;
}

namespace {
// Sec. 6.3.1.1: the OBB from the decomposition of the points' scatter about their centroid; each
// side is the extent of the points along one principal direction (plus `pad`), sorted
// decreasing.
Eigen::Vector3d obb_sides(const std::vector<V3f>& points, double pad) {
  Eigen::Matrix3d E;
  Eigen::Vector3d c;
  principal_frame(points, &E, &c);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3d q = E.transpose() * (p.cast<double>() - c);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  Eigen::Vector3d sides = (hi - lo).array() + pad;
  std::sort(sides.data(), sides.data() + 3, std::greater<double>());
  return sides;
}
}  // namespace

ShapeStats shape_stats(const std::vector<Eigen::Vector3f>& points, double occupancy_voxel_m) {
  require_positive(occupancy_voxel_m, "shape statistics occupancy_voxel_m", "m");
  ShapeStats s;
  s.points = points.size();
  if (points.empty()) return s;
  s.sides = obb_sides(points, 0);
  s.volume = s.sides.prod();
  std::vector<uint64_t> keys = voxel_keys(points, occupancy_voxel_m);
  std::sort(keys.begin(), keys.end());
  s.occupancy = static_cast<std::size_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
  return s;
}

namespace {
// Shape statistics for the subspace analysis from a coarse cloud: one point per occupied voxel of
// the occupancy grid (its centroid), weighing the fine points it stands for. The occupancy is the
// number of coarse points, the point count the sum of the weights, and the OBB sides those of
// the centroids plus one voxel (each stands for a voxel's extent). About ten times fewer points
// than the 3 cm cloud: the analysis of a 54 x 38 m field's tens of thousands of subspaces stays
// in seconds.
ShapeStats coarse_stats(const std::vector<V3f>& coarse, const std::vector<uint32_t>& weight,
                        const std::vector<std::size_t>& idx, double voxel) {
  ShapeStats s;
  std::vector<V3f> pts(idx.size());
  for (std::size_t i = 0; i < idx.size(); ++i) {
    pts[i] = coarse[idx[i]];
    s.points += weight[idx[i]];
  }
  s.occupancy = idx.size();
  if (pts.empty()) return s;
  s.sides = obb_sides(pts, voxel);
  s.volume = s.sides.prod();
  return s;
}
}  // namespace

const char* subspace_test_name(SubspaceTest t) {
  switch (t) {
    case SubspaceTest::None:
      return "kept";
    case SubspaceTest::Fit:
      return "obb_fit";
    case SubspaceTest::Volume:
      return "volume";
    case SubspaceTest::Points:
      return "points";
    case SubspaceTest::Occupancy:
      return "occupancy";
  }
  return "?";
}

SubspaceTest subspace_test(const ShapeStats& sub, const ShapeStats& model,
                           const Recognition3dConfig& config) {
  // Eq. 6.4: each side of the model's OBB fits the subspace's, with the margin alpha_fit.
  for (int i = 0; i < 3; ++i) {
    if (model.sides[i] > config.alpha_fit * sub.sides[i]) return SubspaceTest::Fit;
  }
  // Eq. 6.5: the subspace's OBB volume is not much smaller than the model's.
  if (sub.volume < config.alpha_volume * model.volume) return SubspaceTest::Volume;
  // Eq. 6.6: enough points to represent the geometry.
  if (sub.points < static_cast<std::size_t>(config.n_min)) return SubspaceTest::Points;
  // Eq. 6.7: occupied voxels, against the model's.
  if (static_cast<double>(sub.occupancy) <
      config.alpha_occupancy * static_cast<double>(model.occupancy)) {
    return SubspaceTest::Occupancy;
  }
  return SubspaceTest::None;
}

IcpResult global_registration(const ModelIndex& model, const std::vector<Eigen::Vector3f>& scene,
                              const Recognition3dConfig& config, double* score_m) {
  config.validate();
  require(scene.size() >= 6, "global registration: fewer than 6 scene points");
  const std::vector<V3f> pts = thin(scene, config.max_points);
  Eigen::Matrix3d Em, Es;
  Eigen::Vector3d cm, cs;
  principal_frame(model.points(), &Em, &cm);
  principal_frame(pts, &Es, &cs);
  // Hypotheses: the scene's principal frame matched to the model's under each cube rotation
  // (the eigenvectors' order and signs say nothing about the object's own axes), centroids
  // matched.
  struct Start {
    Eigen::Isometry3d T;
    double score;
  };
  const std::vector<Eigen::Matrix3d> G = cube_rotations();
  std::vector<Start> starts(G.size());
  tbb::parallel_for(std::size_t(0), G.size(), [&](std::size_t k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Es * G[k] * Em.transpose();
    T.translation() = cs - T.linear() * cm;
    starts[k] = {T, trimmed_mean_distance(model, pts, T, config.coarse_gate_m)};
  });
  std::sort(starts.begin(), starts.end(),
            [](const Start& a, const Start& b) { return a.score < b.score; });
  IcpResult best;
  double best_score = std::numeric_limits<double>::infinity();
  for (int k = 0; k < std::min<int>(config.starts, static_cast<int>(starts.size())); ++k) {
    try {
      const IcpResult r = refine(model, pts, starts[k].T, config);
      const double s = trimmed_mean_distance(model, pts, r.T_world_model, config.coarse_gate_m);
      if (s < best_score) best_score = s, best = r;
    } catch (const Error&) {
      // No correspondence within the gate from this start.
    }
  }
  if (score_m) *score_m = best_score;
  return best;
}

namespace {

// A catalogue model prepared for the 3D method.
struct Model3d {
  const ModelTemplate* t = nullptr;
  std::vector<V3f> pts, normals;  // subsampled, above the base clearance
  std::unique_ptr<ModelIndex> index;
  ShapeStats stats;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double r_model = 0;  // bounding sphere radius about the bounding box centre
};

Model3d prepare(const ModelTemplate& t, const Recognition3dConfig& cfg) {
  Model3d m;
  m.t = &t;
  std::vector<V3f> p, n;
  subsample(t.points, &t.normals, cfg.voxel_m, &p, &n);
  const double clip = cfg.upright ? t.base_z + cfg.seabed_clearance_m : -1e300;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p[i].z() < clip) continue;
    m.pts.push_back(p[i]);
    m.normals.push_back(n[i]);
  }
  if (m.pts.size() < 6) {  // a flat model: keep it whole
    m.pts = p;
    m.normals = n;
  }
  const Eigen::Vector3d c = model_center(t);
  for (const auto& q : t.points) m.r_model = std::max(m.r_model, (q.cast<double>() - c).norm());
  for (const auto& q : m.pts) m.centroid += q.cast<double>();
  m.centroid /= static_cast<double>(m.pts.size());
  std::vector<V3f> coarse;
  std::vector<uint32_t> weight;
  subsample(m.pts, nullptr, cfg.occupancy_voxel_m, &coarse, nullptr, &weight);
  std::vector<std::size_t> all(coarse.size());
  std::iota(all.begin(), all.end(), std::size_t(0));
  m.stats = coarse_stats(coarse, weight, all, cfg.occupancy_voxel_m);
  m.index = std::make_unique<ModelIndex>(m.pts, m.normals);
  return m;
}

struct Candidate {
  bool ok = false;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity(), T_start = Eigen::Isometry3d::Identity();
  double start_score = 0, residual_median = 0, coverage = 0;
  int iterations = 0;
};

// Median distance from the scene points over the placed model (inside its box grown by 5 cm) to
// its samples, and the fraction of its samples with a scene point within tol.
void judge(const Model3d& m, const ModelIndex& scene_index, const std::vector<V3f>& local,
           const Recognition3dConfig& cfg, Candidate* c) {
  const Eigen::AlignedBox3f box = m.t->mesh.bounding_box();
  const Eigen::Isometry3f T_mw = c->T.inverse().cast<float>();
  std::vector<float> d;
  for (const auto& p : local) {
    const V3f q = T_mw * p;
    if ((q.array() < box.min().array() - 0.05f).any() ||
        (q.array() > box.max().array() + 0.05f).any()) {
      continue;
    }
    float d2 = 0;
    m.index->nearest(q, &d2);
    d.push_back(std::sqrt(d2));
  }
  if (d.empty()) {
    c->residual_median = std::numeric_limits<double>::infinity();
    return;
  }
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  c->residual_median = *mid;
  const Eigen::Isometry3f T = c->T.cast<float>();
  std::size_t hit = 0;
  const float tol2 = static_cast<float>(cfg.coverage_tol_m * cfg.coverage_tol_m);
  for (const auto& q : m.pts) {
    float d2 = 0;
    scene_index.nearest(T * q, &d2);
    hit += d2 <= tol2;
  }
  c->coverage = static_cast<double>(hit) / static_cast<double>(m.pts.size());
}

// Direct 3D matching in one subspace (sec. 6.3.1.2).
Candidate match_subspace(const Model3d& m, const ModelIndex& scene_index,
                         const std::vector<V3f>& sub, const Ground& ground,
                         const Recognition3dConfig& cfg) {
  Candidate c;
  const std::vector<V3f> pts = thin(sub, cfg.max_points);
  if (!cfg.upright) {
    double score = 0;
    const IcpResult r = global_registration(*m.index, pts, cfg, &score);
    if (!std::isfinite(score) || score > cfg.max_start_score_m) return c;
    c.T = c.T_start = r.T_world_model;
    c.start_score = score;
    c.iterations = r.iterations;
  } else {
    // Yaw sweep about the vertical through the points' centroid, the model's base on the local
    // seabed (or centroids level when the seabed is kept).
    Eigen::Vector3d cs = Eigen::Vector3d::Zero();
    for (const auto& p : pts) cs += p.cast<double>();
    cs /= static_cast<double>(pts.size());
    const double g = ground.at(cs.x(), cs.y());
    const double tz = (cfg.seabed_clearance_m > 0 && std::isfinite(g)) ? g - m.t->base_z
                                                                       : cs.z() - m.centroid.z();
    struct Start {
      Eigen::Isometry3d T;
      double score;
    };
    std::vector<Start> starts;
    for (double yaw : yaw_range(m.t->symmetry, cfg.yaw_step_deg * kDeg)) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translate(Eigen::Vector3d(cs.x(), cs.y(), tz));
      T.rotate(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
      T.translate(Eigen::Vector3d(-m.centroid.x(), -m.centroid.y(), 0));
      starts.push_back({T, trimmed_mean_distance(*m.index, pts, T, cfg.coarse_gate_m)});
    }
    std::sort(starts.begin(), starts.end(),
              [](const Start& a, const Start& b) { return a.score < b.score; });
    // Early rejection: no start close enough to be worth refining.
    if (starts.front().score > cfg.max_start_score_m) return c;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < std::min<int>(cfg.starts, static_cast<int>(starts.size())); ++k) {
      if (starts[k].score > cfg.max_start_score_m) break;
      try {
        const IcpResult r = refine(*m.index, pts, starts[k].T, cfg);
        const double s = trimmed_mean_distance(*m.index, pts, r.T_world_model, cfg.coarse_gate_m);
        if (s < best) {
          best = s;
          c.T = r.T_world_model;
          c.T_start = starts[k].T;
          c.start_score = starts[k].score;
          c.iterations = r.iterations;
        }
      } catch (const Error&) {
        // Nothing within the coarse gate from this start.
      }
    }
    if (!std::isfinite(best)) return c;
    if (tilt_deg(c.T) > cfg.max_tilt_deg) return c;
  }
  judge(m, scene_index, pts, cfg, &c);
  c.ok = c.residual_median <= cfg.max_residual_median_m && c.coverage >= cfg.min_coverage;
  return c;
}

}  // namespace

RecognitionResult recognize_3d(const PointCloud& scene_world,
                               const std::vector<ModelTemplate>& models_in,
                               const Recognition3dConfig& cfg,
                               std::vector<Search3dRecord>* searches, bool progress) {
  cfg.validate();
  const auto threads = check_recognition_inputs(scene_world, models_in, cfg.num_threads);
  const auto start = Clock::now();
  RecognitionResult out;
  out.scene_points = scene_world.size();
  Eigen::AlignedBox3f scene_box;
  for (const auto& p : scene_world.points) scene_box.extend(p);
  const Eigen::Vector3f extent = scene_box.sizes();
  for (const auto& m : models_in) {
    if (2 * m.radius_m > std::min(extent.x(), extent.y())) {
      throw Error("recognition: model '" + m.name + "' (diameter " +
                  std::to_string(2 * m.radius_m) + " m) is larger than the scene (" +
                  std::to_string(extent.x()) + " x " + std::to_string(extent.y()) +
                  " m): check the model's unit and the map");
    }
  }

  // Seabed: with the upright prior, points near the local seabed are dropped (the thesis' OBB and
  // volume tests are otherwise dominated by the seabed, sec. 6.3.1.4).
  std::vector<V3f> full = scene_world.points, scene;
  Ground ground;
  if (cfg.seabed_clearance_m > 0) {
    ground = estimate_ground(full, cfg);
    full = above_ground(full, ground, cfg.seabed_clearance_m);
  }
  subsample(full, nullptr, cfg.voxel_m, &scene, nullptr);
  out.seconds_maps = since(start);

  // Sec. 6.3.2.6 (as in the 2D method): models in decreasing size.
  const std::vector<const ModelTemplate*> order = by_decreasing_size(models_in);
  Progress bar("recognize 3d", order.size(), progress);
  for (const ModelTemplate* mt : order) {
    Search3dRecord rec;
    rec.model = mt->name;
    const auto t0 = Clock::now();
    if (scene.size() < static_cast<std::size_t>(cfg.n_min)) {
      if (searches) searches->push_back(rec);
      bar.add();
      continue;
    }
    const Model3d m = prepare(*mt, cfg);
    rec.r_model_m = m.r_model;
    rec.period_m = cfg.period_fraction * m.r_model;
    rec.r_subspace_m = m.r_model + std::sqrt(3.0) / 2 * rec.period_m;  // eq. 6.3
    const ModelIndex scene_index(scene, std::vector<V3f>(scene.size(), V3f::UnitZ()));
    std::vector<V3f> coarse;
    std::vector<uint32_t> weight;
    subsample(scene, nullptr, cfg.occupancy_voxel_m, &coarse, nullptr, &weight);
    const ModelIndex coarse_index(coarse, std::vector<V3f>(coarse.size(), V3f::UnitZ()));

    // Subspace centres on a grid of period T over the scene's points.
    Eigen::AlignedBox3f box;
    for (const auto& p : scene) box.extend(p);
    const double T = rec.period_m;
    const Eigen::Vector3i n = ((box.sizes().cast<double>() / T).array().floor() + 1).cast<int>();
    limits::checked_count(static_cast<double>(n.x()) * n.y() * n.z(), 1, 5e7,
                          "subspaces of model '" + mt->name + "'",
                          "increase the period fraction or crop the scene");
    const std::size_t count = static_cast<std::size_t>(n.x()) * n.y() * n.z();
    std::vector<SubspaceTest> verdict(count, SubspaceTest::Points);
    std::vector<uint8_t> nonempty(count, 0);
    const float rs = static_cast<float>(rec.r_subspace_m);
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t k) {
      const int ix = static_cast<int>(k % n.x()), iy = static_cast<int>((k / n.x()) % n.y()),
                iz = static_cast<int>(k / (static_cast<std::size_t>(n.x()) * n.y()));
      const V3f c = box.min() + Eigen::Vector3i(ix, iy, iz).cast<float>() * static_cast<float>(T);
      const std::vector<std::size_t> idx = coarse_index.within(c, rs);
      nonempty[k] = !idx.empty();
      if (idx.empty()) return;
      verdict[k] =
          subspace_test(coarse_stats(coarse, weight, idx, cfg.occupancy_voxel_m), m.stats, cfg);
    });
    std::vector<std::size_t> kept;
    for (std::size_t k = 0; k < count; ++k) {
      if (!nonempty[k]) continue;
      ++rec.subspaces;
      if (verdict[k] == SubspaceTest::None) {
        kept.push_back(k);
      } else {
        ++rec.failed[static_cast<int>(verdict[k])];
      }
    }
    rec.kept = kept.size();
    rec.seconds_subspaces = since(t0);

    // Survivors around one structure hold nearly the same points: one representative (the
    // subspace with the most points) per group of survivors whose points' centroids lie within
    // dedup_fraction · r_model of each other is matched.
    const auto t1 = Clock::now();
    auto centre_of = [&](std::size_t k) {
      const int ix = static_cast<int>(k % n.x()), iy = static_cast<int>((k / n.x()) % n.y()),
                iz = static_cast<int>(k / (static_cast<std::size_t>(n.x()) * n.y()));
      return V3f(box.min() + Eigen::Vector3i(ix, iy, iz).cast<float>() * static_cast<float>(T));
    };
    std::vector<Eigen::Vector3d> centroid(kept.size(), Eigen::Vector3d::Zero());
    std::vector<std::size_t> npts(kept.size(), 0);
    tbb::parallel_for(std::size_t(0), kept.size(), [&](std::size_t j) {
      const std::vector<std::size_t> idx = scene_index.within(centre_of(kept[j]), rs);
      for (std::size_t i : idx) centroid[j] += scene[i].cast<double>();
      npts[j] = idx.size();
      centroid[j] /= static_cast<double>(std::max<std::size_t>(1, idx.size()));
    });
    std::vector<std::size_t> by_count(kept.size());
    std::iota(by_count.begin(), by_count.end(), std::size_t(0));
    std::stable_sort(by_count.begin(), by_count.end(),
                     [&](std::size_t a, std::size_t b) { return npts[a] > npts[b]; });
    std::vector<std::size_t> reps;
    const double dedup = cfg.dedup_fraction * m.r_model;
    for (std::size_t j : by_count) {
      bool dup = false;
      for (std::size_t k : reps) dup = dup || (centroid[k] - centroid[j]).norm() < dedup;
      if (!dup) reps.push_back(j);
    }
    rec.registered = reps.size();
    // Direct matching in every representative, in parallel.
    std::vector<Candidate> cands(reps.size());
    tbb::parallel_for(std::size_t(0), reps.size(), [&](std::size_t j) {
      std::vector<V3f> pts;
      for (std::size_t i : scene_index.within(centre_of(kept[reps[j]]), rs)) {
        pts.push_back(scene[i]);
      }
      cands[j] = match_subspace(m, scene_index, pts, ground, cfg);
    });
    std::vector<std::size_t> passed;
    for (std::size_t j = 0; j < cands.size(); ++j) {
      if (cands[j].ok) {
        passed.push_back(j);
      } else if (cands[j].iterations > 0 && cands[j].coverage >= rec.best_rejected_coverage) {
        rec.best_rejected_coverage = cands[j].coverage;
        rec.best_rejected_residual_m = cands[j].residual_median;
      }
    }
    rec.passed = passed.size();
    // Non-maximum suppression: best coverage first (then lowest residual). Each accepted
    // placement takes the scene points it covers; a later candidate's coverage counts only the
    // points not taken (a placement over part of a found structure falls below min_coverage),
    // and one whose centre lies within nms_fraction · r_model (horizontal) of a kept one is the
    // same instance.
    std::sort(passed.begin(), passed.end(), [&](std::size_t a, std::size_t b) {
      if (cands[a].coverage != cands[b].coverage) return cands[a].coverage > cands[b].coverage;
      return cands[a].residual_median < cands[b].residual_median;
    });
    const int wanted = mt->expected >= 0 ? mt->expected : cfg.max_instances;
    const Eigen::Vector3d cm = model_center(*mt);
    std::vector<Eigen::Vector3d> centres;
    std::vector<const Candidate*> accepted;
    std::vector<uint8_t> taken(scene.size(), 0);
    const float tol2 = static_cast<float>(cfg.coverage_tol_m * cfg.coverage_tol_m);
    for (std::size_t j : passed) {
      const Eigen::Vector3d c = cands[j].T * cm;
      bool dup = static_cast<int>(accepted.size()) >= wanted;
      for (const auto& o : centres) dup = dup || (o - c).norm() < cfg.nms_fraction * mt->radius_m;
      std::vector<std::size_t> hits;
      if (!dup) {
        const Eigen::Isometry3f Tf = cands[j].T.cast<float>();
        std::size_t free = 0;
        for (const auto& q : m.pts) {
          float d2 = 0;
          const std::size_t i = scene_index.nearest(Tf * q, &d2);
          if (d2 > tol2) continue;
          hits.push_back(i);
          free += !taken[i];
        }
        dup = static_cast<double>(free) < cfg.min_coverage * static_cast<double>(m.pts.size());
      }
      if (dup) {
        ++rec.suppressed;
        continue;
      }
      for (std::size_t i : hits) taken[i] = 1;
      centres.push_back(c);
      accepted.push_back(&cands[j]);
    }
    rec.accepted = accepted.size();
    rec.seconds_matching = since(t1);

    for (const Candidate* c : accepted) {
      Placement p;
      p.model = mt->name;
      p.method = "3d";
      p.T_world_model = c->T;
      p.T_world_model_4d = c->T_start;
      p.score_m = c->start_score;
      p.support = c->coverage;
      p.observed = std::numeric_limits<double>::quiet_NaN();
      p.icp_iterations = c->iterations;
      p.icp_kept = true;
      const Eigen::Vector3d ctr = c->T * cm;
      p.ground_z =
          ground.z.empty() ? std::numeric_limits<double>::quiet_NaN() : ground.at(ctr.x(), ctr.y());
      // Table 6.1's metric on the full-resolution points (above the seabed) near the model.
      std::vector<V3f> local;
      const double reach = m.r_model + 0.3;
      for (const auto& q : full) {
        if ((q.cast<double>() - ctr).norm() < reach) local.push_back(q);
      }
      p.residual = structure_residual(local, *mt, c->T);
      p.residual_4d = structure_residual(local, *mt, c->T_start);
      p.seconds_scan = rec.seconds_subspaces;
      p.seconds_registration = rec.seconds_matching;
      p.seconds = since(t0);
      out.placements.push_back(p);
    }
    // Each detection removes its points from the later searches.
    if (!accepted.empty()) {
      const float margin2 = static_cast<float>(cfg.removal_margin_m * cfg.removal_margin_m);
      std::vector<Eigen::Isometry3f> inv;
      for (const Candidate* c : accepted) inv.push_back(c->T.inverse().cast<float>());
      auto near_placed = [&](const V3f& q) {
        for (const auto& T_mw : inv) {
          float d2 = 0;
          m.index->nearest(T_mw * q, &d2);
          if (d2 <= margin2) return true;
        }
        return false;
      };
      scene.erase(std::remove_if(scene.begin(), scene.end(), near_placed), scene.end());
      full.erase(std::remove_if(full.begin(), full.end(), near_placed), full.end());
    }
    if (searches) searches->push_back(rec);
    bar.add();
  }
  bar.finish();
  out.seconds = since(start);
  return out;
}

std::string placements_json_3d(const RecognitionResult& result,
                               const std::vector<Search3dRecord>& searches,
                               const std::string& map_source, const std::string& catalogue_source,
                               const Recognition3dConfig& config) {
  nlohmann::json j;
  j["format"] = "sonar3d-placements";
  j["version"] = 1;
  j["method"] = "3d";
  j["map"] = map_source;
  j["catalogue"] = catalogue_source;
  j["frame"] = "world: local ENU (x East, y North, z up), metres";
  j["settings"] = {{"voxel_m", config.voxel_m},
                   {"period_fraction", config.period_fraction},
                   {"alpha_fit", config.alpha_fit},
                   {"alpha_volume", config.alpha_volume},
                   {"n_min", config.n_min},
                   {"alpha_occupancy", config.alpha_occupancy},
                   {"occupancy_voxel_m", config.occupancy_voxel_m},
                   {"upright", config.upright},
                   {"yaw_step_deg", config.yaw_step_deg},
                   {"seabed_clearance_m", config.seabed_clearance_m},
                   {"max_residual_median_m", config.max_residual_median_m},
                   {"min_coverage", config.min_coverage}};
  j["placements"] = placements_list_json(result.placements);
  nlohmann::json list = nlohmann::json::array();
  for (const Search3dRecord& s : searches) {
    nlohmann::json failed;
    for (int t = 1; t <= 4; ++t) {
      failed[subspace_test_name(static_cast<SubspaceTest>(t))] = s.failed[t];
    }
    list.push_back({{"model", s.model},
                    {"r_model_m", s.r_model_m},
                    {"r_subspace_m", s.r_subspace_m},
                    {"period_m", s.period_m},
                    {"subspaces", s.subspaces},
                    {"kept", s.kept},
                    {"failed", failed},
                    {"registered", s.registered},
                    {"passed", s.passed},
                    {"suppressed", s.suppressed},
                    {"accepted", s.accepted},
                    {"best_rejected_coverage", s.best_rejected_coverage},
                    {"best_rejected_residual_median_m", s.best_rejected_residual_m},
                    {"seconds_subspaces", s.seconds_subspaces},
                    {"seconds_matching", s.seconds_matching}});
  }
  j["searches"] = list;
  j["scene_points"] = result.scene_points;
  j["seconds"] = result.seconds;
  return j.dump(2) + "\n";
}

}  // namespace sonar3d
