// Trimmed ICP (Masuda et al. 1996; thesis sec. 6.3.2.5) over a nanoflann KD-tree of the model's
// surface samples (Debian's libnanoflann-dev, header only).
#include "sonar3d/recog/icp.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <nanoflann.hpp>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void TrimmedIcpConfig::validate() const { params::check(*this, "ICP"); }

namespace {
struct Cloud {
  std::vector<Eigen::Vector3f> pts;
  std::size_t kdtree_get_point_count() const { return pts.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][static_cast<int>(d)]; }
  template <class BBOX>
  bool kdtree_get_bbox(BBOX&) const {
    return false;
  }
};
using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3>;
}  // namespace

struct ModelIndex::Impl {
  Cloud cloud;
  std::vector<Eigen::Vector3f> normals;
  std::unique_ptr<Tree> tree;
};

ModelIndex::ModelIndex(std::vector<Eigen::Vector3f> points, std::vector<Eigen::Vector3f> normals)
    : impl_(std::make_unique<Impl>()) {
  require(!points.empty(), "model index: no points");
  require(normals.size() == points.size(), "model index: one normal per point is needed");
  impl_->cloud.pts = std::move(points);
  impl_->normals = std::move(normals);
  impl_->tree =
      std::make_unique<Tree>(3, impl_->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  impl_->tree->buildIndex();
}

ModelIndex::~ModelIndex() = default;

std::size_t ModelIndex::nearest(const Eigen::Vector3f& p, float* dist2) const {
  unsigned idx = 0;  // nanoflann 1.4's default index type
  float d2 = 0;
  impl_->tree->knnSearch(p.data(), 1, &idx, &d2);
  if (dist2) *dist2 = d2;
  return idx;
}

bool ModelIndex::nearest_within(const Eigen::Vector3f& p, float max_dist2, std::size_t* index,
                                float* dist2) const {
  unsigned idx = 0;
  float d2 = 0;
  nanoflann::KNNResultSet<float, unsigned> result(1);
  result.init(&idx, &d2);
  // The worst distance kept: just above the bound, so that a sample at exactly the bound is
  // found (as nearest() followed by d2 <= max_dist2).
  d2 = std::nextafter(max_dist2, std::numeric_limits<float>::infinity());
  impl_->tree->findNeighbors(result, p.data(), nanoflann::SearchParams());
  if (result.size() == 0) {
    *dist2 = std::numeric_limits<float>::infinity();
    return false;
  }
  if (index) *index = idx;
  *dist2 = d2;
  return true;
}

std::vector<std::size_t> ModelIndex::within(const Eigen::Vector3f& p, float radius) const {
  std::vector<std::pair<unsigned, float>> found;
  impl_->tree->radiusSearch(p.data(), radius * radius, found,
                            nanoflann::SearchParams(32, 0, false));
  std::vector<std::size_t> out(found.size());
  for (std::size_t i = 0; i < found.size(); ++i) out[i] = found[i].first;
  return out;
}

const std::vector<Eigen::Vector3f>& ModelIndex::points() const { return impl_->cloud.pts; }
const std::vector<Eigen::Vector3f>& ModelIndex::normals() const { return impl_->normals; }

IcpResult trimmed_icp(const ModelIndex& model, const std::vector<Eigen::Vector3f>& scene_world,
                      const Eigen::Isometry3d& T_init, const TrimmedIcpConfig& config) {
  config.validate();
  require(!scene_world.empty(), "ICP: no scene points");
  std::vector<Eigen::Vector3f> scene;
  const std::size_t stride =
      (scene_world.size() + config.max_scene_points - 1) / config.max_scene_points;
  for (std::size_t i = 0; i < scene_world.size(); i += std::max<std::size_t>(1, stride)) {
    scene.push_back(scene_world[i]);
  }
  struct Match {
    float d2;
    int scene, model;
  };
  std::vector<Match> matches(scene.size());
  IcpResult res;
  res.T_world_model = T_init;
  const float gate2 = static_cast<float>(config.max_distance_m * config.max_distance_m);
  for (int it = 0; it < config.max_iterations; ++it) {
    const Eigen::Isometry3f T_model_world = res.T_world_model.inverse().cast<float>();
    tbb::parallel_for(std::size_t(0), scene.size(), [&](std::size_t i) {
      // Beyond the gate a match is never used: its branches are not searched (d2 = +inf).
      float d2 = 0;
      std::size_t j = 0;
      model.nearest_within(T_model_world * scene[i], gate2, &j, &d2);
      matches[i] = {d2, static_cast<int>(i), static_cast<int>(j)};
    });
    // Trimming (Masuda): within the gate, the closest keep_fraction.
    std::vector<Match> kept;
    kept.reserve(matches.size());
    for (const Match& m : matches) {
      if (m.d2 <= gate2) kept.push_back(m);
    }
    if (kept.size() < 6) {
      if (it == 0) {
        throw Error("ICP: fewer than 6 scene points within " +
                    std::to_string(config.max_distance_m) + " m of the model at its initial pose");
      }
      break;
    }
    const std::size_t n_keep = std::max<std::size_t>(
        6, static_cast<std::size_t>(std::ceil(config.keep_fraction * kept.size())));
    if (n_keep < kept.size()) {
      std::nth_element(kept.begin(), kept.begin() + static_cast<std::ptrdiff_t>(n_keep), kept.end(),
                       [](const Match& a, const Match& b) { return a.d2 < b.d2; });
      kept.resize(n_keep);
    }
    // Linearised update in the world frame: q' = q + ω × q + δ (q: model sample in world).
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    double sum2 = 0;
    const Eigen::Matrix3d R = res.T_world_model.linear();
    // Linearised about the kept scene points' centroid (well conditioned far from the origin).
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const Match& m : kept) centroid += scene[m.scene].cast<double>();
    centroid /= static_cast<double>(kept.size());
    for (const Match& m : kept) {
      const Eigen::Vector3d q =
          res.T_world_model * model.points()[m.model].cast<double>() - centroid;
      const Eigen::Vector3d p = scene[m.scene].cast<double>() - centroid;
      sum2 += m.d2;
      if (config.point_to_plane) {
        const Eigen::Vector3d n = R * model.normals()[m.model].cast<double>();
        Eigen::Matrix<double, 6, 1> J;
        J << q.cross(n), n;
        const double r = (q - p).dot(n);
        A += J * J.transpose();
        b -= J * r;
      } else {
        // Three rows: the residual q − p along each axis.
        for (int a = 0; a < 3; ++a) {
          Eigen::Matrix<double, 6, 1> J = Eigen::Matrix<double, 6, 1>::Zero();
          const Eigen::Vector3d e = Eigen::Vector3d::Unit(a);
          J.head<3>() = q.cross(e);
          J.tail<3>() = e;
          A += J * J.transpose();
          b -= J * (q - p)[a];
        }
      }
    }
    // A little damping keeps directions the data do not constrain (a flat top slides) still.
    A += 1e-6 * (A.trace() / 6 + 1e-12) * Eigen::Matrix<double, 6, 6>::Identity();
    const Eigen::Matrix<double, 6, 1> x = A.ldlt().solve(b);
    if (!x.allFinite()) break;
    const Eigen::Vector3d w = x.head<3>();
    Eigen::Isometry3d dT = Eigen::Isometry3d::Identity();
    if (w.norm() > 0) dT.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    // About the centroid: p ↦ R_ω (p − c) + c + δ.
    dT.translation() = x.tail<3>() + centroid - dT.linear() * centroid;
    res.T_world_model = dT * res.T_world_model;
    res.iterations = it + 1;
    res.used = kept.size();
    res.rms_m = std::sqrt(sum2 / static_cast<double>(kept.size()));
    const double moved = x.tail<3>().norm() + w.norm() * 2.0;  // ~ displacement at 2 m
    if (moved < config.converged_m) {
      res.converged = true;
      break;
    }
  }
  return res;
}

}  // namespace sonar3d
