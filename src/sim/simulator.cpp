#include "sonar3d/sim/simulator.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>

#include "../core/embree_device.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

void SimulatorConfig::validate() const {
  require_positive(elevation_step_rad, "simulation.elevation_step_deg", "(deg)");
  require(rays_per_beam >= 1 && rays_per_beam <= 64,
          "parameter 'simulation.rays_per_beam' must be in [1, 64], got " +
              std::to_string(rays_per_beam));
  require_positive(gain, "simulation.gain");
  require(num_threads >= 0, "parameter 'num_threads' must be >= 0 (0 = all cores)");
}

struct Simulator::Impl {
  RTCScene scene = nullptr;
  std::vector<float> reflectivity;  // by geometry id
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

Simulator::Simulator(const Scene& scene, const SonarSpec& spec, const SimulatorConfig& config)
    : impl_(std::make_unique<Impl>()), spec_(spec), config_(config) {
  spec_.validate();
  config_.validate();
  if (scene.empty()) throw Error("the scene is empty: it has no object with triangles to image");
  if (config_.elevation_step_rad > spec_.vertical_aperture_rad) {
    throw Error(
        "simulation.elevation_step_deg exceeds the vertical aperture: at least one ray "
        "per beam is needed across the aperture");
  }
  RTCDevice device = detail::embree_device();
  impl_->scene = rtcNewScene(device);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  for (const SceneObject& obj : scene.objects) {
    if (obj.mesh_world.empty()) continue;
    if (!(obj.reflectivity >= 0.0 && obj.reflectivity <= 1.0)) {
      throw Error("object '" + obj.name + "': reflectivity must lie in [0, 1]");
    }
    const unsigned id =
        detail::attach_mesh(impl_->scene, obj.mesh_world, "object '" + obj.name + "'");
    if (impl_->reflectivity.size() <= id) impl_->reflectivity.resize(id + 1, 0.0f);
    impl_->reflectivity[id] = static_cast<float>(obj.reflectivity);
  }
  rtcCommitScene(impl_->scene);
}

Simulator::~Simulator() = default;

std::size_t Simulator::rays_per_image() const {
  const int m =
      static_cast<int>(std::ceil(spec_.vertical_aperture_rad / config_.elevation_step_rad - 1e-9));
  return static_cast<std::size_t>(spec_.beams()) * config_.rays_per_beam * m;
}

namespace {
// splitmix64: decorrelates per-beam seeds so that each beam's jitter is independent of the
// thread that renders it (same seed, same image).
unsigned long long splitmix(unsigned long long x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
}  // namespace

SonarImage Simulator::render(const Eigen::Isometry3d& T_world_sonar,
                             unsigned long long seed) const {
  if (!T_world_sonar.matrix().allFinite()) throw Error("render: the sonar pose is not finite");
  if (T_world_sonar.translation().cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
    throw Error("render: the sonar lies more than 1e7 m from the origin; use a local frame");
  }
  const SonarSpec& s = spec_;
  const int beams = s.beams();
  const int bins = s.range_bins;
  const double A_v = s.vertical_aperture_rad;
  const double theta_res = config_.elevation_step_rad;
  const int m = static_cast<int>(std::ceil(A_v / theta_res - 1e-9));
  const int sub = config_.rays_per_beam;
  const double theta_3db = s.theta_3db();
  // Each ray stands for θ_res/A_v of the aperture and 1/sub of the beam: a surface filling the
  // whole aperture at one range, facing the sonar, with μ = 1 and a flat pattern gives 1.
  const double ray_weight = (theta_res / A_v) / sub;
  const Eigen::Matrix3f R = T_world_sonar.linear().cast<float>();
  const Eigen::Vector3f o = T_world_sonar.translation().cast<float>();
  const float r_max = static_cast<float>(s.r_max);
  const std::vector<float>& refl = impl_->reflectivity;
  RTCScene scene = impl_->scene;

  // Per-render tables shared by every beam: the elevation cell edges' sin/cos and the beam
  // pattern power B(θ)² at the cell edges. A ray's jitter δ within its cell is at most one cell
  // (0.01° by default), so its direction follows from the angle-addition formulas with a
  // third-order expansion of sin δ and cos δ (error < δ⁴/24 ≈ 1e-17), and B² from linear
  // interpolation between the edges. This keeps libm out of the per-ray loop (it was a third of
  // the render time).
  std::vector<double> sin_k(m), cos_k(m), b2_edge(m + 1);
  for (int k = 0; k < m; ++k) {
    const double t = -0.5 * A_v + k * theta_res;
    sin_k[k] = std::sin(t);
    cos_k[k] = std::cos(t);
  }
  for (int k = 0; k <= m; ++k) {
    b2_edge[k] = s.beam_pattern.power(std::min(-0.5 * A_v + k * theta_res, 0.5 * A_v), theta_3db);
  }
  // Last cell may be cut short by the aperture edge.
  const double last_cell = 0.5 * A_v - (-0.5 * A_v + (m - 1) * theta_res);

  SonarImage image(bins, beams);
  auto render_beams = [&](const tbb::blocked_range<int>& range) {
    std::vector<double> column(bins);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    float b2_of[16];
    for (int j = range.begin(); j != range.end(); ++j) {
      std::fill(column.begin(), column.end(), 0.0);
      // Counter-based random stream per beam: the same seed gives the same image whatever thread
      // renders the beam.
      unsigned long long state = splitmix(seed ^ splitmix(static_cast<unsigned long long>(j) + 1));
      auto next_pair = [&state](double& a, double& b) {
        const unsigned long long x = splitmix(state++);
        a = static_cast<double>(x >> 32) * (1.0 / 4294967296.0);
        b = static_cast<double>(x & 0xFFFFFFFFull) * (1.0 / 4294967296.0);
      };
      const double lo = s.beam_edge_low(j);
      const double w = (s.beam_edge_high(j) - lo) / sub;
      for (int q = 0; q < sub; ++q) {
        const double phi0 = lo + q * w;
        const double sin_phi0 = std::sin(phi0), cos_phi0 = std::cos(phi0);
        for (int k0 = 0; k0 < m; k0 += 16) {
          const int n = std::min(16, m - k0);
          for (int l = 0; l < 16; ++l) {
            if (l >= n) {
              valid[l] = 0;
              continue;
            }
            valid[l] = -1;
            const int k = k0 + l;
            // eq. 2.14–2.15: one ray per (bearing, elevation) cell, uniformly inside the cell.
            double jp = 0.5, jt = 0.5;
            if (config_.jitter) next_pair(jp, jt);
            const double cell = (k == m - 1) ? last_cell : theta_res;
            const double dt = jt * cell;
            const double dp = jp * w;
            const double sdt = dt - dt * dt * dt / 6.0, cdt = 1.0 - 0.5 * dt * dt;
            const double sdp = dp - dp * dp * dp / 6.0, cdp = 1.0 - 0.5 * dp * dp;
            const double st = sin_k[k] * cdt + cos_k[k] * sdt;  // sin(θ_k + δθ)
            const double ct = cos_k[k] * cdt - sin_k[k] * sdt;
            const double sp = sin_phi0 * cdp + cos_phi0 * sdp;  // sin(φ_0 + δφ)
            const double cp = cos_phi0 * cdp - sin_phi0 * sdp;
            // eq. 2.8: the pattern weighs each return by B(θ)² (emission and reception).
            const double a = dt / theta_res;
            b2_of[l] = static_cast<float>((1.0 - a) * b2_edge[k] + a * b2_edge[k + 1]);
            const Eigen::Vector3f d_sonar(static_cast<float>(ct * cp), static_cast<float>(ct * sp),
                                          static_cast<float>(st));
            const Eigen::Vector3f d = R * d_sonar;
            rh.ray.org_x[l] = o.x();
            rh.ray.org_y[l] = o.y();
            rh.ray.org_z[l] = o.z();
            rh.ray.dir_x[l] = d.x();
            rh.ray.dir_y[l] = d.y();
            rh.ray.dir_z[l] = d.z();
            rh.ray.tnear[l] = 0.0f;  // objects nearer than r_min still cast shadows
            rh.ray.tfar[l] = r_max;
            rh.ray.time[l] = 0.0f;
            rh.ray.mask[l] = 0xFFFFFFFFu;
            rh.ray.id[l] = l;
            rh.ray.flags[l] = 0;
            rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
          }
          rtcIntersect16(valid, scene, &ctx, &rh);
          for (int l = 0; l < n; ++l) {
            if (rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) continue;
            const float t = rh.ray.tfar[l];
            const int bin = s.bin_of_range(t);
            if (bin < 0) continue;
            // eq. 2.6 / 2.13: Lambertian backscatter ∝ μ·|cos(incidence)|; |·| because CAD
            // files do not always agree on triangle winding.
            const Eigen::Vector3f ng(rh.hit.Ng_x[l], rh.hit.Ng_y[l], rh.hit.Ng_z[l]);
            const Eigen::Vector3f d(rh.ray.dir_x[l], rh.ray.dir_y[l], rh.ray.dir_z[l]);
            const float nn = ng.norm();
            if (!(nn > 0)) continue;
            const double lambert = std::abs(ng.dot(d)) / nn;
            const double weight =
                (k0 + l == m - 1) ? ray_weight * last_cell / theta_res : ray_weight;
            column[bin] += refl[rh.hit.geomID[l]] * lambert * b2_of[l] * weight;
          }
        }
      }
      for (int i = 0; i < bins; ++i) {
        image.at(i, j) = static_cast<float>(config_.gain * column[i]);
      }
    }
  };
  const int threads =
      config_.num_threads > 0 ? config_.num_threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] { tbb::parallel_for(tbb::blocked_range<int>(0, beams, 4), render_beams); });
  return image;
}

}  // namespace sonar3d
