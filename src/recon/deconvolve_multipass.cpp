// Multipass deconvolution (thesis sec. 5.6.7): the first reconstruction gives the geometry that
// the kernel A* = β̃ (eq. 5.27) ignores, and a second deconvolution uses it:
//   - normal-based kernel (5.6.7.1): A⊥_kp = A*_kp·cos α_kp, the Lambertian cosine between the
//     view from frame k and the normal at layer p, estimated by SVD over a 5 cm neighbourhood of
//     the first cloud (Fig. 5.26);
//   - occlusion-based kernel (5.6.7.2): A*_kp·δ_kp with δ_kp = 0 when a first-cloud point lies
//     nearer on the same ray from frame k (Fig. 5.27).
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "deconvolve_internal.hpp"
#include "sonar3d/core/point_index.hpp"
#include "sonar3d/core/projector.hpp"

namespace sonar3d::deconv_detail {

namespace {

// The first-pass points within `radius` of q (core/point_index.hpp), in a fixed order: by the
// cubes of side `radius` they fall in (x, then y, then z, about q's cube), then by index. The
// normals sum over them in floating point, so the order is the result's: this is the order of
// the radius-wide grid this index replaced, kept so the multipass clouds stay byte-identical.
std::vector<std::size_t> neighbours(const PointIndex3d& index, const Eigen::Vector3d& q,
                                    double radius) {
  std::vector<std::size_t> found = index.within(q, radius);
  const double inv = 1.0 / radius;
  const auto cube = [inv](const Eigen::Vector3d& p) {
    return Eigen::Array3d((p * inv).array().floor());
  };
  const Eigen::Array3d c = cube(q);
  std::vector<std::pair<int, std::size_t>> keyed(found.size());
  for (std::size_t n = 0; n < found.size(); ++n) {
    const Eigen::Array3d d = cube(index.points()[found[n]]) - c;  // each -1, 0 or 1
    keyed[n] = {static_cast<int>(9 * d.x() + 3 * d.y() + d.z()), found[n]};
  }
  std::sort(keyed.begin(), keyed.end());
  for (std::size_t n = 0; n < found.size(); ++n) found[n] = keyed[n].second;
  return found;
}

// Normals of the lowest-variance direction in a neighbourhood (SVD of the covariance, sec.
// 5.6.7.1); zero vector where fewer than 5 neighbours exist.
std::vector<Eigen::Vector3d> estimate_normals(const PointIndex3d& index, double radius) {
  const std::vector<Eigen::Vector3d>& pts = index.points();
  std::vector<Eigen::Vector3d> normals(pts.size(), Eigen::Vector3d::Zero());
  tbb::parallel_for(std::size_t{0}, pts.size(), [&](std::size_t i) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    int count = 0;
    for (const std::size_t j : neighbours(index, pts[i], radius)) {
      mean += pts[j];
      S += pts[j] * pts[j].transpose();
      ++count;
    }
    if (count < 5) return;
    mean /= count;
    const Eigen::Matrix3d C = S / count - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C);
    normals[i] = eig.eigenvectors().col(0);
  });
  return normals;
}

// The normal of the nearest point within `radius` of q that has one (zero if none).
Eigen::Vector3d nearest_normal(const PointIndex3d& index,
                               const std::vector<Eigen::Vector3d>& normals,
                               const Eigen::Vector3d& q, double radius) {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double best = radius * radius * 1.0001;
  for (const std::size_t j : neighbours(index, q, radius)) {
    const double d2 = (index.points()[j] - q).squaredNorm();
    if (d2 < best && normals[j].squaredNorm() > 0) {
      best = d2;
      normal = normals[j];
    }
  }
  return normal;
}

}  // namespace

std::vector<Eigen::Vector3f> normals_near(const std::vector<Eigen::Vector3d>& pts, double radius,
                                          const std::vector<Eigen::Vector3f>& queries) {
  const auto index = PointIndex3d::borrow(pts);
  const std::vector<Eigen::Vector3d> normals = estimate_normals(index, radius);
  std::vector<Eigen::Vector3f> out(queries.size(), Eigen::Vector3f::Zero());
  tbb::parallel_for(std::size_t{0}, queries.size(), [&](std::size_t i) {
    out[i] = nearest_normal(index, normals, queries[i].cast<double>(), radius).cast<float>();
  });
  return out;
}

namespace {

class MultipassScaler : public KernelScaler {
 public:
  MultipassScaler(const PassData& pd, const DeconvConfig& cfg, const std::vector<LayerPoint>& first)
      : pd_(pd), spec_(*pd.spec) {
    use_normals_ = cfg.kernel == DeconvConfig::Kernel::Normal ||
                   cfg.kernel == DeconvConfig::Kernel::NormalOcclusion;
    use_occlusion_ = cfg.kernel == DeconvConfig::Kernel::Occlusion ||
                     cfg.kernel == DeconvConfig::Kernel::NormalOcclusion;
    radius_ = cfg.normal_radius;
    pts_.reserve(first.size());
    for (const LayerPoint& lp : first) pts_.push_back(lp.p_world.cast<double>());
    if (use_normals_) {
      index_ = std::make_unique<PointIndex3d>(PointIndex3d::borrow(pts_));
      normals_ = estimate_normals(*index_, radius_);
    }
    if (use_occlusion_) build_occlusion_maps(cfg);
  }

  void scale(int beam, const Eigen::Vector3d& p_world, const int* frames, int count,
             float* values) const override {
    (void)beam;
    // The normal of the nearest first-pass point within the radius.
    const Eigen::Vector3d normal = use_normals_
                                       ? nearest_normal(*index_, normals_, p_world, radius_)
                                       : Eigen::Vector3d::Zero();
    for (int e = 0; e < count; ++e) {
      const int k = frames[e];
      const Eigen::Isometry3d& T = pd_.T_world_sonar[k];
      double f = 1.0;
      if (use_normals_ && normal.squaredNorm() > 0) {
        // Lambert (eq. 2.6): the return scales with the cosine of the incidence angle.
        const Eigen::Vector3d v = (p_world - T.translation()).normalized();
        f *= std::max(kMinLambertCosine, std::abs(v.dot(normal)));
      }
      if (use_occlusion_ && f > 0) {
        const Polar q = sonar_to_polar(T.inverse() * p_world);
        const int j = spec_.beam_of_bearing(q.bearing);
        const int el = elevation_bin(q.elevation);
        if (j >= 0 && el >= 0) {
          const float nearest =
              occl_[(static_cast<std::size_t>(k) * spec_.beams() + j) * n_el_ + el];
          // δ_kp = 0: a first-pass surface lies nearer on this ray (Fig. 5.27).
          if (nearest < q.range - margin_) f = 0.0;
        }
      }
      values[e] = static_cast<float>(values[e] * f);
    }
  }

 private:
  int elevation_bin(double theta) const {
    if (std::abs(theta) > pd_.theta_3db) return -1;
    return std::min(n_el_ - 1, static_cast<int>((theta + pd_.theta_3db) / el_step_));
  }

  void build_occlusion_maps(const DeconvConfig& cfg) {
    el_step_ = cfg.occlusion_elevation_step_deg * M_PI / 180.0;
    n_el_ = std::max(1, static_cast<int>(std::ceil(2 * pd_.theta_3db / el_step_)));
    margin_ = 2.0 * spec_.range_resolution();  // a surface is a few range bins thick
    occl_.assign(static_cast<std::size_t>(pd_.n) * spec_.beams() * n_el_,
                 std::numeric_limits<float>::infinity());
    tbb::parallel_for(0, pd_.n, [&](int k) {
      const Eigen::Isometry3d T_sonar_world = pd_.T_world_sonar[k].inverse();
      float* map = &occl_[static_cast<std::size_t>(k) * spec_.beams() * n_el_];
      for (const Eigen::Vector3d& p : pts_) {
        const Polar q = sonar_to_polar(T_sonar_world * p);
        if (q.range < spec_.r_min || q.range >= spec_.r_max) continue;
        const int el = elevation_bin(q.elevation);
        const int j = spec_.beam_of_bearing(q.bearing);
        if (el < 0 || j < 0) continue;
        float& m = map[static_cast<std::size_t>(j) * n_el_ + el];
        m = std::min(m, static_cast<float>(q.range));
      }
    });
  }

  const PassData& pd_;
  const SonarSpec& spec_;
  bool use_normals_ = false, use_occlusion_ = false;
  double radius_ = 0.05;
  std::vector<Eigen::Vector3d> pts_;
  std::unique_ptr<PointIndex3d> index_;  // over pts_
  std::vector<Eigen::Vector3d> normals_;
  double el_step_ = 0.0, margin_ = 0.0;
  int n_el_ = 1;
  std::vector<float> occl_;  // per frame, beam, elevation interval: nearest first-pass range
};

}  // namespace

std::unique_ptr<KernelScaler> make_multipass_scaler(const PassData& pd, const DeconvConfig& cfg,
                                                    const std::vector<LayerPoint>& first) {
  return std::make_unique<MultipassScaler>(pd, cfg, first);
}

}  // namespace sonar3d::deconv_detail
