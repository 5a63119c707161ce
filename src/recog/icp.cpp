// Trimmed ICP (Masuda et al. 1996; thesis sec. 6.3.2.5) over the nearest-neighbour index
// (core/point_index.hpp) of the model's surface samples.
#include "sonar3d/recog/icp.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void TrimmedIcpConfig::validate() const { params::check(*this, "ICP"); }

namespace {
// A model index's points: they must be checked before the index is built from them.
std::vector<Eigen::Vector3f> checked(std::vector<Eigen::Vector3f> points,
                                     const std::vector<Eigen::Vector3f>& normals) {
  require(!points.empty(), "model index: no points");
  require(normals.size() == points.size(), "model index: one normal per point is needed");
  return points;
}
}  // namespace

ModelIndex::ModelIndex(std::vector<Eigen::Vector3f> points, std::vector<Eigen::Vector3f> normals)
    : PointIndex3f(checked(std::move(points), normals)), normals_(std::move(normals)) {}

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
