// Deconvolution reconstruction (thesis ch. 5): configuration, pass analysis, the column kernel
// A* (eq. 5.27), the per-column NNLS (eq. 5.28), de-ringing and the dataset driver. The exact
// geometry mode lives in deconvolve_exact.cpp, the multipass kernels in deconvolve_multipass.cpp.
#include "sonar3d/recon/deconvolve.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>

#include "deconvolve_internal.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/units.hpp"

namespace sonar3d {

namespace {

std::string fmt(double v, int prec = 3) {
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(prec);
  os << v;
  return os.str();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Configuration

void DeconvConfig::validate() const {
  require(std::isfinite(lambda_fraction) && lambda_fraction >= 0 && lambda_fraction <= 1,
          "parameter 'deconv.lambda' (fraction of λ_max) must lie in [0, 1], got " +
              fmt(lambda_fraction));
  require(std::isfinite(max_axis_angle_deg) && max_axis_angle_deg > 0 && max_axis_angle_deg < 90,
          "parameter 'deconv.max_axis_angle_deg' must lie in (0, 90)");
  require(std::isfinite(max_rotation_deg) && max_rotation_deg > 0 && max_rotation_deg < 180,
          "parameter 'deconv.max_rotation_deg' must lie in (0, 180)");
  require_positive(max_lateral_deviation, "deconv.max_lateral_deviation", "m");
  require_positive(max_spacing_deviation, "deconv.max_spacing_deviation", "(fraction of Δz)");
  require_non_negative(layer_spacing, "deconv.layer_spacing", "m");
  require(std::isfinite(split_jump_factor) && split_jump_factor > 1,
          "parameter 'deconv.split_jump_factor' must be > 1");
  require(min_pass_frames >= 2, "parameter 'deconv.min_pass_frames' must be >= 2, got " +
                                    std::to_string(min_pass_frames));
  require_non_negative(max_range, "deconv.max_range", "m");
  require_positive(rectilinear_warn_bins, "deconv.rectilinear_warn_bins", "bins");
  denoise.validate();
  if (resolve_occlusions) occlusion.validate();
  require_positive(normal_radius, "deconv.normal_radius", "m");
  require_positive(occlusion_elevation_step_deg, "deconv.occlusion_elevation_step_deg", "deg");
  require(subsamples >= 1 && subsamples <= 64,
          "parameter 'deconv.subsamples' must lie in [1, 64], got " + std::to_string(subsamples));
  require_non_negative(min_intensity, "deconv.min_intensity");
  require(std::isfinite(max_extrapolation),
          "parameter 'deconv.max_extrapolation' must be finite (< 0 = keep every layer)");
  require(std::isfinite(min_relative_intensity) && min_relative_intensity >= 0 &&
              min_relative_intensity < 1,
          "parameter 'deconv.min_relative_intensity' must lie in [0, 1)");
  nnls.validate();
  require(exact_max_sweeps >= 1, "parameter 'deconv.exact_max_sweeps' must be >= 1");
  require(std::isfinite(exact_tolerance) && exact_tolerance > 0 && exact_tolerance < 1,
          "parameter 'deconv.exact_tolerance' must lie in (0, 1)");
  require(exact_range_subsamples >= 1 && exact_range_subsamples <= 16,
          "parameter 'deconv.exact_range_subsamples' must lie in [1, 16]");
  require(!exact_lambertian || exact,
          "parameter 'deconv.exact_lambertian' needs the exact mode (deconv.exact = true, "
          "--exact)");
  require(num_threads >= 0, "parameter 'deconv.num_threads' must be >= 0 (0 = all cores), got " +
                                std::to_string(num_threads));
  require(!(exact && kernel != Kernel::Plain),
          "parameter 'deconv.kernel': the multipass kernels (normal, occlusion) need the "
          "approximate (rectilinear) mode; drop --exact or use kernel 'plain'");
  require(
      !(mode == Mode::Voxel && (kernel == Kernel::Occlusion || kernel == Kernel::NormalOcclusion)),
      "parameter 'deconv.kernel': the voxel mode takes kernel 'plain' or 'normal' (its "
      "occlusion model is deconv.voxel.occlusion_aware, on by default)");
  if (mode != Mode::Passes) voxel.validate();
}

void VoxelDeconvConfig::validate() const {
  require(
      std::isfinite(voxel_size) && voxel_size >= 1e-4 && voxel_size <= 10,
      "parameter 'deconv.voxel.voxel_size' must lie in [0.0001, 10] m, got " + fmt(voxel_size, 4));
  require(max_iterations >= 1 && max_iterations <= 100000,
          "parameter 'deconv.voxel.max_iterations' must lie in [1, 100000], got " +
              std::to_string(max_iterations));
  require(std::isfinite(tolerance) && tolerance > 0 && tolerance < 1,
          "parameter 'deconv.voxel.tolerance' must lie in (0, 1), got " + fmt(tolerance, 6));
  require(std::isfinite(min_relative) && min_relative >= 0 && min_relative < 1,
          "parameter 'deconv.voxel.min_relative' must lie in [0, 1), got " + fmt(min_relative, 4));
  require(std::isfinite(min_relative_bracketed) && min_relative_bracketed >= 0 &&
              min_relative_bracketed < 1,
          "parameter 'deconv.voxel.min_relative_bracketed' must lie in [0, 1), got " +
              fmt(min_relative_bracketed, 6));
  require(std::isfinite(bracketed) && bracketed >= 0 && bracketed <= 1,
          "parameter 'deconv.voxel.bracketed' must lie in [0, 1], got " + fmt(bracketed, 4));
  require(min_observations >= 1, "parameter 'deconv.voxel.min_observations' must be >= 1, got " +
                                     std::to_string(min_observations));
  require(
      std::isfinite(support_min_bracket) && support_min_bracket >= 0 && support_min_bracket <= 1,
      "parameter 'deconv.voxel.support_min_bracket' must lie in [0, 1], got " +
          fmt(support_min_bracket, 4));
}

// The one enum <-> string convention (core/enum_names.hpp).
DeconvConfig::Mode DeconvConfig::parse_mode(const std::string& s) {
  return parse_enum<Mode>(kModeNames, s, "deconvolution mode");
}
const char* DeconvConfig::mode_name(Mode m) { return enum_name(kModeNames, m); }
DeconvConfig::Beam DeconvConfig::parse_beam(const std::string& s) {
  return parse_enum<Beam>(kBeamNames, s, "deconvolution beam pattern");
}
const char* DeconvConfig::beam_name(Beam b) { return enum_name(kBeamNames, b); }
DeconvConfig::Kernel DeconvConfig::parse_kernel(const std::string& s) {
  return parse_enum<Kernel>(kKernelNames, s, "deconvolution kernel");
}
const char* DeconvConfig::kernel_name(Kernel k) { return enum_name(kKernelNames, k); }

// ---------------------------------------------------------------------------------------------
// Geometry helpers

int footprint_layers(double range, double vertical_aperture_rad, double dz) {
  // eq. 5.25 (the 1e-9 keeps an exact multiple from flooring one short).
  const double k = 2.0 * range * std::tan(0.5 * vertical_aperture_rad) / dz;
  return std::max(1, static_cast<int>(std::floor(k + 1e-9)));
}

double rectilinear_mismatch(double range, double theta_3db_rad) {
  // eq. 5.21 compares the arc of radius r swept by the aperture with the vertical line at r: at
  // the aperture edge the arc is r·(1 − cos θ_3dB) nearer than the line.
  return range * (1.0 - std::cos(theta_3db_rad));
}

double rectilinear_max_aperture(double range, double range_resolution) {
  const double c = 1.0 - range_resolution / (2.0 * range);  // eq. 5.21
  return c <= -1.0 ? M_PI : 2.0 * std::acos(std::max(-1.0, std::min(1.0, c)));
}

// ---------------------------------------------------------------------------------------------
// The pass

std::vector<std::pair<std::size_t, std::size_t>> split_passes(
    const std::vector<Eigen::Isometry3d>& T_world_sonar, const DeconvConfig& config) {
  const std::size_t n = T_world_sonar.size();
  std::vector<std::pair<std::size_t, std::size_t>> out;
  if (n == 0) return out;
  if (n < 3) return {{0, n}};
  std::vector<double> steps(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    steps[k] = (T_world_sonar[k + 1].translation() - T_world_sonar[k].translation()).norm();
  }
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  // A jump (the vehicle moving to the next object) or a reversal (a yo-yo profile; the kernel
  // needs monotone heights) ends a pass. Both thresholds exceed what pose noise does: several
  // median steps and twice the lateral tolerance, so ±2 cm jitter on 1 cm steps splits nothing.
  const double jump = std::max(config.split_jump_factor * std::max(median, 1e-6),
                               2.0 * config.max_lateral_deviation);
  const double max_rot = config.max_rotation_deg * kDeg;
  std::size_t first = 0;
  while (first < n) {
    // Height along the sonar z relative to the pass' first frame; the running extremum in the
    // pass direction; a reversal is a retreat from it by more than `jump`.
    const Eigen::Vector3d ez = T_world_sonar[first].linear().col(2);
    const Eigen::Vector3d origin = T_world_sonar[first].translation();
    int direction = 0;
    double extreme = 0.0;
    std::size_t extreme_at = first;
    std::size_t end = n;
    for (std::size_t k = first; k + 1 < n; ++k) {
      const Eigen::AngleAxisd rot(T_world_sonar[k].linear().transpose() *
                                  T_world_sonar[k + 1].linear());
      if (steps[k] > jump || std::abs(rot.angle()) > max_rot) {
        end = k + 1;
        break;
      }
      const double h = (T_world_sonar[k + 1].translation() - origin).dot(ez);
      if (direction == 0) {
        if (std::abs(h) > jump) direction = h > 0 ? 1 : -1;
        if (direction * h >= direction * extreme) {
          extreme = h;
          extreme_at = k + 1;
        }
        continue;
      }
      if (direction * h >= direction * extreme) {
        extreme = h;
        extreme_at = k + 1;
      } else if (direction * (extreme - h) > jump) {
        end = extreme_at + 1;  // the turning frame closes this pass
        break;
      }
    }
    out.emplace_back(first, end);
    first = end;
  }
  return out;
}

namespace {

// The uniform model of the sensor heights z_i of a pass (sec. 5.4): z_k ≈ z_0 + k·Δz fitted by
// least squares to the pass's sorted heights; sets g.spacing and the largest and rms departures.
void fit_uniform_spacing(PassGeometry& g) {
  const std::size_t n = g.heights.size();
  double sk = 0, sz = 0, skk = 0, skz = 0;
  for (std::size_t k = 0; k < n; ++k) {
    sk += k;
    sz += g.heights[k];
    skk += static_cast<double>(k) * k;
    skz += k * g.heights[k];
  }
  const double den = n * skk - sk * sk;
  g.spacing = den > 0 ? (n * skz - sk * sz) / den : 0.0;
  const double z0 = (sz - g.spacing * sk) / n;
  double sum_e2 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double e = g.heights[k] - (z0 + k * g.spacing);
    g.max_spacing_error = std::max(g.max_spacing_error, std::abs(e));
    sum_e2 += e * e;
  }
  g.rms_spacing_error = std::sqrt(sum_e2 / n);
}

// The pass's geometry against the tolerances of DeconvConfig: an error naming the measured figures
// when the orientation turns, the motion leaves the sonar's z axis, a frame lies off the axis or
// the spacing is not uniform; a warning when the spacing is uneven but within tolerance.
void check_pass_geometry(PassGeometry& g, const DeconvConfig& config, const std::string& where) {
  const std::string figures =
      " (measured: axis " + fmt(g.axis_angle_rad / kDeg, 2) + "° from the sonar z, lateral max " +
      fmt(g.max_lateral * 100, 2) + " cm / rms " + fmt(g.rms_lateral * 100, 2) + " cm, spacing " +
      fmt(g.spacing * 100, 3) + " cm ± max " + fmt(g.max_spacing_error * 100, 2) + " cm / rms " +
      fmt(g.rms_spacing_error * 100, 2) + " cm, orientation max " +
      fmt(g.max_rotation_rad / kDeg, 2) + "°)";
  if (g.max_rotation_rad > config.max_rotation_deg * kDeg) {
    throw Error(
        where + ": the sonar orientation changes by " + fmt(g.max_rotation_rad / kDeg, 2) +
        "° during the pass (tolerance max_rotation_deg = " + fmt(config.max_rotation_deg, 2) +
        "°); deconvolution needs a pure translation along the sonar's z axis" + figures);
  }
  if (g.axis_angle_rad > config.max_axis_angle_deg * kDeg) {
    throw Error(
        where + ": the motion is not along the sonar's z axis: the positions fit a line " +
        fmt(g.axis_angle_rad / kDeg, 2) +
        "° away from it (tolerance max_axis_angle_deg = " + fmt(config.max_axis_angle_deg, 2) +
        "°); deconvolution needs a pass along the vertical aperture — use carving for "
        "other trajectories" +
        figures);
  }
  if (g.max_lateral > config.max_lateral_deviation) {
    throw Error(where + ": a frame lies " + fmt(g.max_lateral * 100, 2) +
                " cm from the pass axis (tolerance max_lateral_deviation = " +
                fmt(config.max_lateral_deviation * 100, 2) + " cm)" + figures);
  }
  if (!(g.spacing > 1e-6)) {
    throw Error(where + ": the frames do not advance along the sonar's z axis (fitted spacing " +
                fmt(g.spacing * 1000, 4) + " mm)" + figures);
  }
  if (g.max_spacing_error > config.max_spacing_deviation * g.spacing) {
    throw Error(where + ": the frame spacing is not uniform: a frame is " +
                fmt(g.max_spacing_error * 100, 2) + " cm off the uniform grid of spacing " +
                fmt(g.spacing * 100, 3) + " cm (tolerance max_spacing_deviation = " +
                fmt(config.max_spacing_deviation, 2) + " × spacing)" + figures);
  }
  if (g.max_spacing_error > 0.25 * g.spacing) {
    g.warnings.push_back(
        where + ": non-uniform spacing, max " + fmt(g.max_spacing_error * 100, 2) + " cm / rms " +
        fmt(g.rms_spacing_error * 100, 2) + " cm off the " + fmt(g.spacing * 100, 3) + " cm grid" +
        (config.use_measured_heights ? " (modelled: the kernel uses each frame's measured height)"
                                     : " (ignored: use_measured_heights is off)"));
  }
}

}  // namespace

PassGeometry analyze_pass(const std::vector<Eigen::Isometry3d>& T_world_sonar,
                          const DeconvConfig& config, const std::string& where) {
  const std::size_t n = T_world_sonar.size();
  if (n < 2) {
    throw Error(where + ": a deconvolution pass needs at least 2 frames, got " + std::to_string(n));
  }
  PassGeometry g;
  // Mean orientation: the rotation nearest (Frobenius) to the mean of the rotation matrices.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& T : T_world_sonar) {
    M += T.linear();
    centroid += T.translation();
  }
  centroid /= static_cast<double>(n);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixU() * D * svd.matrixV().transpose();
  for (const auto& T : T_world_sonar) {
    const Eigen::AngleAxisd aa(R.transpose() * T.linear());
    g.max_rotation_rad = std::max(g.max_rotation_rad, std::abs(aa.angle()));
  }
  g.T_world_pass.linear() = R;
  g.T_world_pass.translation() = centroid;
  const Eigen::Vector3d ez = R.col(2);

  // Line fit (principal axis of the positions) vs the sonar z axis.
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& T : T_world_sonar) {
    const Eigen::Vector3d d = T.translation() - centroid;
    C += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C);
  const Eigen::Vector3d dir = eig.eigenvectors().col(2);
  const double extent = std::sqrt(std::max(0.0, eig.eigenvalues()(2)) / n);
  if (!(extent > 1e-6)) {
    throw Error(where + ": the sonar does not move (all " + std::to_string(n) +
                " frames at the same position); deconvolution needs a pass along the sonar's z "
                "axis");
  }
  g.axis_angle_rad = std::acos(std::min(1.0, std::abs(dir.dot(ez))));

  // Heights along the sonar z and distances from the axis line through the centroid.
  std::vector<double> h(n);
  double sum_lat2 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d d = T_world_sonar[k].translation() - centroid;
    h[k] = d.dot(ez);
    const double lat = (d - h[k] * ez).norm();
    g.max_lateral = std::max(g.max_lateral, lat);
    sum_lat2 += lat * lat;
  }
  g.rms_lateral = std::sqrt(sum_lat2 / n);
  g.descending = h.back() < h.front();
  g.frames.resize(n);
  std::iota(g.frames.begin(), g.frames.end(), std::size_t{0});
  std::stable_sort(g.frames.begin(), g.frames.end(),
                   [&](std::size_t a, std::size_t b) { return h[a] < h[b]; });
  g.heights.resize(n);
  for (std::size_t k = 0; k < n; ++k) g.heights[k] = h[g.frames[k]];

  fit_uniform_spacing(g);
  check_pass_geometry(g, config, where);
  return g;
}

namespace {

std::string frames_label(std::size_t index, std::size_t first, std::size_t count) {
  return "pass " + std::to_string(index + 1) + " (frames " + std::to_string(first) + "–" +
         std::to_string(first + count - 1) + ")";
}

}  // namespace

std::string auto_mode_reason(const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const DeconvConfig& config) {
  const std::size_t n = T_world_sonar.size();
  if (n == 0) return "no frame";
  const std::vector<std::pair<std::size_t, std::size_t>> ranges =
      config.split_passes ? split_passes(T_world_sonar, config)
                          : std::vector<std::pair<std::size_t, std::size_t>>{{0, n}};
  std::size_t outside = 0;  // frames in passes too short to reconstruct
  for (const auto& [first, last] : ranges) {
    if (static_cast<int>(last - first) < config.min_pass_frames) outside += last - first;
  }
  if (outside > 0) {
    return std::to_string(outside) + " of " + std::to_string(n) + " frames lie in no pass of " +
           std::to_string(config.min_pass_frames) + " frames or more";
  }
  // Each pass within the tolerances of analyze_pass (attitude, axis, lateral, spacing).
  for (std::size_t pi = 0; pi < ranges.size(); ++pi) {
    const auto [first, last] = ranges[pi];
    const std::vector<Eigen::Isometry3d> poses(T_world_sonar.begin() + first,
                                               T_world_sonar.begin() + last);
    try {
      analyze_pass(poses, config, frames_label(pi, first, last - first));
    } catch (const Error& e) {
      return e.what();
    }
  }
  // One pass broken in two (a gap in the recording, a jolt of attitude) is one irregular pass,
  // not two regular ones: the next part continues along the same line, in the same direction.
  for (std::size_t pi = 0; pi + 1 < ranges.size(); ++pi) {
    const Eigen::Isometry3d& a0 = T_world_sonar[ranges[pi].first];
    const Eigen::Isometry3d& a1 = T_world_sonar[ranges[pi].second - 1];
    const Eigen::Isometry3d& b0 = T_world_sonar[ranges[pi + 1].first];
    const Eigen::Isometry3d& b1 = T_world_sonar[ranges[pi + 1].second - 1];
    const Eigen::Vector3d ez = a1.linear().col(2);
    const double along_a = (a1.translation() - a0.translation()).dot(ez);
    const double along_b = (b1.translation() - b0.translation()).dot(ez);
    const Eigen::Vector3d step = b0.translation() - a1.translation();
    const double along = step.dot(ez), lateral = (step - along * ez).norm();
    const double turn = Eigen::AngleAxisd(a1.linear().transpose() * b0.linear()).angle();
    if (along_a * along_b > 0 && along * along_a >= 0 &&
        lateral <= 2.0 * config.max_lateral_deviation && turn <= 10.0 * kDeg) {
      return frames_label(pi, ranges[pi].first, ranges[pi].second - ranges[pi].first) + " and " +
             frames_label(pi + 1, ranges[pi + 1].first,
                          ranges[pi + 1].second - ranges[pi + 1].first) +
             " are one pass broken by a step of " + fmt(step.norm() * 100, 2) +
             " cm and a turn of " + fmt(std::abs(turn) / kDeg, 2) +
             "°: its spacing or attitude is beyond the tolerances of the passes mode";
    }
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// The column kernel A* (eq. 5.27)

namespace deconv_detail {

double layer_power(const BeamPattern& pattern, double theta_3db, double r, double offset, double dz,
                   int subsamples, double half_width) {
  double sum = 0.0;
  for (int s = 0; s < subsamples; ++s) {
    const double h = offset + ((s + 0.5) / subsamples - 0.5) * dz;
    if (std::abs(h) > half_width) continue;     // outside the modelled footprint
    const double theta = std::atan2(h, r);      // rectilinear geometry (eq. 5.21): height h at r
    if (std::abs(theta) > theta_3db) continue;  // the sensor integrates over its aperture only
    sum += pattern.power(theta, theta_3db);
  }
  return sum / subsamples;
}

}  // namespace deconv_detail

ColumnKernel build_column_kernel(double range, const std::vector<double>& heights, double dz,
                                 const BeamPattern& pattern, double theta_3db, int subsamples) {
  require(!heights.empty(), "build_column_kernel: no frame");
  require_positive(dz, "deconv.layer_spacing", "m");
  require_positive(range, "range", "m");
  const int n = static_cast<int>(heights.size());
  ColumnKernel ker;
  ker.dz = dz;
  ker.K = footprint_layers(range, 2.0 * theta_3db, dz);
  const int K = ker.K;
  const double z0 = heights.front();
  // Layer p is centred at u_p = z_0 + (p − (K − 1)/2)·Δz: frame k at z_0 + k·Δz sees layers
  // k..k+K−1, centred on its own height (Fig. 5.3), i.e. the footprint is modelled as K whole
  // layers, |u − z_k| ≤ K·Δz/2 (eq. 5.25 rounds the aperture's 2·r·tan θ_3dB down to K·Δz).
  ker.first_layer = z0 - 0.5 * (K - 1) * dz;
  const double half_width = 0.5 * K * dz;

  // Row k starts at layer p0 = ⌊t_k⌋, t_k = (z_k − z_0)/Δz, with fraction f_k = t_k − p0 ∈ [0, 1):
  // a frame between two layer positions (non-uniform pass) overlaps K + 1 layers, the two end
  // ones in part. A uniform pass has f_k = 0, K layers per row, and shares one weight vector.
  std::vector<int> p0(n);
  std::vector<double> frac(n);
  bool uniform = true;
  for (int k = 0; k < n; ++k) {
    const double t = (heights[k] - z0) / dz;
    p0[k] = static_cast<int>(std::floor(t + 1e-9));
    frac[k] = std::max(0.0, t - p0[k]);
    uniform = uniform && frac[k] < 1e-9;
  }
  auto weight = [&](int d, double f) {
    // Layer p0 + d is centred (d − (K − 1)/2 − f)·Δz above the frame.
    return deconv_detail::layer_power(pattern, theta_3db, range, (d - 0.5 * (K - 1) - f) * dz, dz,
                                      subsamples, half_width);
  };
  // Weights per (fraction sample, d), d = 0..K: exact for a uniform pass, linearly interpolated in
  // the fraction otherwise (1/16-layer samples).
  constexpr int kFracSamples = 17;  // f ∈ [0, 1] in steps of 1/16
  const int W = K + 1;
  std::vector<double> table;
  if (uniform) {
    table.resize(W);
    for (int d = 0; d < W; ++d) table[d] = weight(d, 0.0);
  } else {
    table.resize(static_cast<std::size_t>(kFracSamples) * W);
    for (int s = 0; s < kFracSamples; ++s) {
      const double f = s / double(kFracSamples - 1);
      for (int d = 0; d < W; ++d) table[static_cast<std::size_t>(s) * W + d] = weight(d, f);
    }
  }
  auto w_of = [&](int k, int d) {
    if (uniform) return table[d];
    const double x = frac[k] * (kFracSamples - 1);
    const int s = std::min(kFracSamples - 2, std::max(0, static_cast<int>(x)));
    const double t = x - s;
    return (1 - t) * table[static_cast<std::size_t>(s) * W + d] +
           t * table[static_cast<std::size_t>(s + 1) * W + d];
  };

  // Entries row by row (only non-zero weights), then CSC: the frames seeing a layer are
  // contiguous (heights sorted) and stay sorted.
  std::vector<std::vector<std::pair<int, float>>> rows(n);
  int P = 0;
  for (int k = 0; k < n; ++k) {
    for (int d = 0; d < W; ++d) {
      const double w = w_of(k, d);
      if (!(w > 0.0)) continue;
      rows[k].emplace_back(p0[k] + d, static_cast<float>(w));
      P = std::max(P, p0[k] + d + 1);
    }
  }
  ker.layers = P;  // eq. 5.26: N + K − 1 for a uniform pass
  SparseColumns& A = ker.A;
  A.rows = n;
  A.cols = P;
  A.start.assign(P + 1, 0);
  for (const auto& r : rows)
    for (const auto& e : r) ++A.start[e.first + 1];
  for (int p = 0; p < P; ++p) A.start[p + 1] += A.start[p];
  A.row.assign(A.start[P], 0);
  A.value.assign(A.start[P], 0.0f);
  std::vector<int> fill(A.start.begin(), A.start.end() - 1);
  for (int k = 0; k < n; ++k) {
    for (const auto& [p, w] : rows[k]) {
      const int at = fill[p]++;
      A.row[at] = k;
      A.value[at] = w;
    }
  }
  ker.gram = BandMatrix::gram(A);
  return ker;
}

// ---------------------------------------------------------------------------------------------
// Approximate (rectilinear) mode: one NNLS per (range, bearing) column

namespace deconv_detail {

namespace {

// The row view of a bin's kernel A* for ignore_shadowed_zeros: row k (frame k by height) holds the
// layers row_first[k] .. + row_count[k] − 1 (at most K + 1), their values in row_val; per layer
// its number of rows. Per-task scratch of solve_approx, reused across its bins and beams.
struct KernelRows {
  std::vector<int> row_first, row_count, layer_rows, rows_left;
  std::vector<double> row_val;
  std::vector<char> drop;  // per frame: a zero pixel behind its beam's first return (left out)

  void build(const ColumnKernel& ker, int n) {
    const int P = ker.layers;
    row_first.assign(n, P);
    row_count.assign(n, 0);
    layer_rows.assign(P, 0);
    rows_left.resize(P);
    drop.assign(n, 0);
    for (int p = 0; p < P; ++p) {
      layer_rows[p] = ker.A.start[p + 1] - ker.A.start[p];
      for (int e = ker.A.start[p]; e < ker.A.start[p + 1]; ++e) {
        const int k = ker.A.row[e];
        row_first[k] = std::min(row_first[k], p);
        ++row_count[k];
      }
    }
    row_val.assign(static_cast<std::size_t>(n) * (ker.K + 1), 0.0);
    for (int p = 0; p < P; ++p) {
      for (int e = ker.A.start[p]; e < ker.A.start[p + 1]; ++e) {
        const int k = ker.A.row[e];
        row_val[static_cast<std::size_t>(k) * (ker.K + 1) + (p - row_first[k])] = ker.A.value[e];
      }
    }
  }
};

// The Gram matrix of a column without its dropped rows, into shadow.gram: Q' = Q − Σ_dropped
// a_k a_kᵀ (c is unchanged: dropped rows have y = 0). A layer left without rows gets an exactly
// zero column so that rounding cannot revive it.
void drop_shadowed_rows(const ColumnKernel& ker, int n, KernelRows& rows, ColumnKernel& shadow) {
  const int P = ker.layers;
  shadow.gram = ker.gram;
  std::copy(rows.layer_rows.begin(), rows.layer_rows.end(), rows.rows_left.begin());
  for (int k = 0; k < n; ++k) {
    if (!rows.drop[k]) continue;
    const double* a = &rows.row_val[static_cast<std::size_t>(k) * (ker.K + 1)];
    const int p0 = rows.row_first[k], m = rows.row_count[k];
    for (int u = 0; u < m; ++u) {
      --rows.rows_left[p0 + u];
      for (int v = u; v < m; ++v) shadow.gram.upper(p0 + u, v - u) -= a[u] * a[v];
    }
  }
  const int bw = shadow.gram.bandwidth();
  for (int p = 0; p < P; ++p) {
    if (rows.rows_left[p] > 0) continue;
    for (int d = 0; d <= bw && p + d < P; ++d) shadow.gram.upper(p, d) = 0.0;
    for (int d = 1; d <= bw && p - d >= 0; ++d) shadow.gram.upper(p - d, d) = 0.0;
  }
}

// sec. 5.6.7: one column's kernel for the second pass, into `scaled`: A*_kp scaled by the
// second-pass factor of frame k and layer p (the dropped rows zeroed when `dropped`), and its
// Gram matrix.
void scale_column_kernel(const PassData& pd, const ColumnKernel& ker, const KernelScaler& scaler,
                         int beam, double r, double phi, const std::vector<char>& drop, int dropped,
                         ColumnKernel& scaled) {
  scaled.A = ker.A;
  for (int p = 0; p < ker.layers; ++p) {
    const Eigen::Vector3d pw = pd.to_world(r, phi, ker.layer_height(p));
    const int e0 = scaled.A.start[p];
    scaler.scale(beam, pw, &scaled.A.row[e0], scaled.A.start[p + 1] - e0, &scaled.A.value[e0]);
    if (dropped) {
      for (int e = e0; e < scaled.A.start[p + 1]; ++e) {
        if (drop[scaled.A.row[e]]) scaled.A.value[e] = 0.0f;
      }
    }
  }
  scaled.gram = BandMatrix::gram(scaled.A);
}

// The layers of a solved column (b) kept as points: b_p above min_intensity and, with
// min_relative_intensity, explaining at least that fraction of the column's brightest pixel ymax
// through its largest kernel entry; placed at horizontal distance r, bearing phi and the layer's
// height in the pass frame.
void keep_layers(const PassData& pd, const DeconvConfig& cfg, const ColumnKernel& ker,
                 const SparseColumns& A_col, const std::vector<double>& b, float ymax, double r,
                 double phi, int beam, int bin, std::vector<LayerPoint>& pts) {
  const double min_contribution = cfg.min_relative_intensity * ymax;
  for (int p = 0; p < ker.layers; ++p) {
    if (!(b[p] > cfg.min_intensity)) continue;
    if (min_contribution > 0) {
      double amax = 0.0;
      for (int e = A_col.start[p]; e < A_col.start[p + 1]; ++e) {
        amax = std::max(amax, static_cast<double>(A_col.value[e]));
      }
      if (b[p] * amax < min_contribution) continue;
    }
    LayerPoint lp;
    const double u = ker.layer_height(p);
    lp.p_world = pd.to_world(r, phi, u).cast<float>();
    lp.value = static_cast<float>(b[p]);
    lp.rho = static_cast<float>(r);
    lp.height = static_cast<float>(u);
    lp.beam = beam;
    lp.bin = bin;
    pts.push_back(lp);
  }
}

}  // namespace

// One NNLS per (range, bearing) column (eq. 5.28) with the column kernel A* of its range (eq.
// 5.27), bins in parallel; each task keeps its solver and kernel copies across its bins.
void solve_approx(const PassData& pd, const DeconvConfig& cfg, const BeamPattern& pattern,
                  const KernelScaler* scaler, PassReport& report, std::vector<LayerPoint>& out,
                  Progress* progress) {
  const SonarSpec& spec = *pd.spec;
  const int n = pd.n;
  std::vector<std::vector<LayerPoint>> per_bin(pd.bins);
  std::atomic<std::size_t> solved{0}, unconverged{0};
  std::atomic<int> max_iter{0};

  tbb::parallel_for(
      tbb::blocked_range<int>(pd.bin_lo, pd.bin_hi + 1, 1), [&](const tbb::blocked_range<int>& rg) {
        NnlsSolver solver;
        std::vector<double> y(n), c, b;
        ColumnKernel scaled;  // multipass: per-column copy of the kernel
        ColumnKernel shadow;  // ignore_shadowed_zeros: per-column Gram without the shadowed rows
        KernelRows rows;      // ignore_shadowed_zeros: the kernel's row view
        for (int bin = rg.begin(); bin < rg.end(); ++bin) {
          if (!pd.bin_has_data[bin - pd.bin_lo]) {
            if (progress) progress->add();
            continue;
          }
          const double r = spec.range_of_bin(bin);
          const ColumnKernel ker =
              build_column_kernel(r, pd.heights, pd.dz, pattern, pd.theta_3db, cfg.subsamples);
          const int P = ker.layers;
          c.resize(P);
          b.resize(P);
          if (cfg.ignore_shadowed_zeros) rows.build(ker, n);
          std::vector<LayerPoint>& pts = per_bin[bin - pd.bin_lo];
          for (int beam = 0; beam < pd.beams; ++beam) {
            const float* col = pd.column(bin, beam);
            float ymax = 0.0f;
            for (int k = 0; k < n; ++k) {
              y[k] = col[k];
              ymax = std::max(ymax, col[k]);
            }
            if (!(ymax > 0.0f)) continue;  // an empty column: b = 0 (skip, sec. 5.6.8 speed-up)
            const double phi = spec.bearings_rad[beam];
            const SparseColumns* A_col = &ker.A;
            const BandMatrix* Q_col = &ker.gram;
            // Rows of zero pixels behind their beam's first return (possible shadows) leave the fit
            // when ignore_shadowed_zeros is set.
            int dropped = 0;
            if (cfg.ignore_shadowed_zeros) {
              const int* fr = &pd.first_return[static_cast<std::size_t>(beam) * n];
              for (int k = 0; k < n; ++k) {
                rows.drop[k] = y[k] == 0.0 && fr[k] < bin;
                dropped += rows.drop[k];
              }
            }
            if (scaler) {
              scale_column_kernel(pd, ker, *scaler, beam, r, phi, rows.drop, dropped, scaled);
              A_col = &scaled.A;
              Q_col = &scaled.gram;
            } else if (dropped) {
              drop_shadowed_rows(ker, n, rows, shadow);
              Q_col = &shadow.gram;
            }
            A_col->transpose_times(y.data(), c.data());
            double cmax = 0.0;
            for (double v : c) cmax = std::max(cmax, v);
            if (!(cmax > 0.0)) continue;
            // c = A*ᵀI − λ/2, λ = f·λ_max, λ_max = 2·max(A*ᵀI) (recon/nnls.hpp).
            const double half_lambda = cfg.lambda_fraction * cmax;
            for (double& v : c) v -= half_lambda;
            std::fill(b.begin(), b.end(), 0.0);
            const NnlsStats st = solver.solve(*Q_col, c.data(), b.data(), cfg.nnls);
            ++solved;
            if (!st.converged) ++unconverged;
            int cur = max_iter.load();
            while (st.iterations > cur && !max_iter.compare_exchange_weak(cur, st.iterations)) {
            }
            keep_layers(pd, cfg, ker, *A_col, b, ymax, r, phi, beam, bin, pts);
          }
          if (progress) progress->add();
        }
      });
  report.columns += static_cast<std::size_t>(pd.bins) * pd.beams;
  report.columns_solved += solved.load();
  report.unconverged += unconverged.load();
  report.max_iterations = std::max(report.max_iterations, max_iter.load());
  for (auto& v : per_bin) out.insert(out.end(), v.begin(), v.end());
}

std::size_t dering(const PassData& pd, std::vector<LayerPoint>& points) {
  if (pd.returns.empty() || points.empty()) return 0;
  const SonarSpec& spec = *pd.spec;
  const double tan3 = std::tan(pd.theta_3db);
  std::vector<char> drop(points.size(), 0);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, points.size(), 256),
      [&](const tbb::blocked_range<std::size_t>& rg) {
        for (std::size_t m = rg.begin(); m < rg.end(); ++m) {
          const LayerPoint& lp = points[m];
          // Only frames whose footprint can hold the layer (heights sorted): |z_k − u| ≤ ρ·tan
          // θ_3dB.
          const double reach = lp.rho * tan3 + pd.dz;
          const auto lo = std::lower_bound(pd.heights.begin(), pd.heights.end(), lp.height - reach);
          const auto hi = std::upper_bound(pd.heights.begin(), pd.heights.end(), lp.height + reach);
          const Eigen::Vector3d p = lp.p_world.cast<double>();
          const int j0 = std::max(0, lp.beam - 2), j1 = std::min(pd.beams - 1, lp.beam + 2);
          for (auto it = lo; it != hi; ++it) {
            const std::size_t k = static_cast<std::size_t>(it - pd.heights.begin());
            const FrameReturns& fr = *pd.returns[k];
            // Cheap necessary condition first: free needs the layer's bin (≥ its column's bin − 1,
            // slant ≥ horizontal distance) in front of the first return of its beam (± 2 beams for
            // pose deviations). Most layers of a surface fail it; seen_free decides the rest.
            int first = 0;
            for (int j = j0; j <= j1; ++j) first = std::max(first, fr.first_return_bin[j]);
            if (first <= lp.bin - 1) continue;
            // sec. 5.5.4: a layer seen as empty by one unoccluded view cannot hold a surface.
            if (seen_free(fr, spec, p)) {
              drop[m] = 1;
              break;
            }
          }
        }
      });
  std::size_t kept = 0;
  for (std::size_t m = 0; m < points.size(); ++m) {
    if (!drop[m]) points[kept++] = points[m];
  }
  const std::size_t removed = points.size() - kept;
  points.resize(kept);
  return removed;
}

}  // namespace deconv_detail

// ---------------------------------------------------------------------------------------------
// Driver

namespace deconv_detail {

BeamPattern kernel_pattern(const DeconvConfig& cfg, const SonarSpec& spec) {
  switch (cfg.beam) {
    case DeconvConfig::Beam::Flat: {
      BeamPattern b;
      b.kind = BeamPattern::Kind::Flat;
      return b;
    }
    case DeconvConfig::Beam::Sensor:
      return spec.beam_pattern;
    case DeconvConfig::Beam::Sinc:
    default: {
      BeamPattern b;
      b.kind = BeamPattern::Kind::Sinc;
      return b;
    }
  }
}

}  // namespace deconv_detail

// Driver: deconvolve_frames and its stages (thesis ch. 5), in the order it runs them: check the
// frames, choose the mode (auto), plan the passes (eq. 5.25–5.26), summarise free space, then per
// pass: its report (eq. 5.21, 5.25), its column stack, the NNLS solve (eq. 5.28), de-ringing and
// the second pass (sec. 5.6.7); last, the occlusion resolution (sec. 5.6.7.3).

namespace {

using namespace deconv_detail;  // PassData, LayerPoint, the solvers (deconvolve_internal.hpp)

// The frames are as many as the poses and each is the sonar's size.
void check_frames(const std::vector<SonarImage>& denoised,
                  const std::vector<Eigen::Isometry3d>& T_world_sonar, const SonarSpec& spec) {
  require(denoised.size() == T_world_sonar.size(),
          "deconvolve: " + std::to_string(denoised.size()) + " frames but " +
              std::to_string(T_world_sonar.size()) + " poses");
  for (std::size_t f = 0; f < denoised.size(); ++f) {
    if (denoised[f].rows != spec.range_bins || denoised[f].cols != spec.beams()) {
      throw Error("deconvolve: frame " + std::to_string(f) + " is " +
                  std::to_string(denoised[f].rows) + "×" + std::to_string(denoised[f].cols) +
                  " but sonar '" + spec.name + "' has " + std::to_string(spec.range_bins) +
                  " range bins × " + std::to_string(spec.beams()) + " beams");
    }
  }
}

// The farthest range bin within max_range (the whole range when max_range is 0).
int farthest_bin(const SonarSpec& spec, const DeconvConfig& config) {
  const double r_far_limit =
      config.max_range > 0 ? std::min(config.max_range, spec.r_max) : spec.r_max;
  int bin_hi = spec.range_bins - 1;
  while (bin_hi >= 0 && spec.range_of_bin(bin_hi) > r_far_limit) --bin_hi;
  require(bin_hi >= 0, "deconv.max_range (" + fmt(config.max_range) +
                           " m) is below the sonar's first range bin (" +
                           fmt(spec.range_of_bin(0)) + " m)");
  return bin_hi;
}

// A pass to reconstruct: its frames, geometry (analyze_pass), layer height and range window.
struct PassPlan {
  std::size_t first, count;
  std::string label;
  PassGeometry geo;
  double dz;
  int bin_hi;  // farthest range bin holding a return (within max_range)
};

// The farthest range bin (≤ bin_hi) holding a return in any of the pass's frames, −1 for none:
// columns beyond it hold nothing, the window ends there.
int last_return_bin(const std::vector<SonarImage>& denoised, std::size_t first, std::size_t count,
                    int bin_hi) {
  std::vector<int> last_bin(count, -1);
  tbb::parallel_for(std::size_t{0}, count, [&](std::size_t k) {
    const SonarImage& im = denoised[first + k];
    for (int i = bin_hi; i >= 0 && last_bin[k] < 0; --i) {
      const float* row = im.row_ptr(i);
      for (int j = 0; j < im.cols; ++j) {
        if (row[j] > 0.0f) {
          last_bin[k] = i;
          break;
        }
      }
    }
  });
  int out = -1;
  for (int b : last_bin) out = std::max(out, b);
  return out;
}

// The passes (split_passes, or all frames as one), each checked before the heavy work so that a
// bad pass fails fast: too short ones and ones without a return are skipped with a warning; one
// too short for its footprint at the far range (eq. 5.25–5.26) is an error.
std::vector<PassPlan> plan_passes(const std::vector<SonarImage>& denoised,
                                  const std::vector<Eigen::Isometry3d>& T_world_sonar,
                                  const SonarSpec& spec, const DeconvConfig& config, int bin_hi,
                                  DeconvReport& report) {
  const double theta3 = spec.theta_3db();
  const double dr = spec.range_resolution();
  std::vector<std::pair<std::size_t, std::size_t>> ranges =
      config.split_passes
          ? split_passes(T_world_sonar, config)
          : std::vector<std::pair<std::size_t, std::size_t>>{{0, T_world_sonar.size()}};
  std::vector<PassPlan> plans;
  for (std::size_t pi = 0; pi < ranges.size(); ++pi) {
    const std::size_t first = ranges[pi].first, last = ranges[pi].second;
    const std::string label = frames_label(pi, first, last - first);
    if (static_cast<int>(last - first) < config.min_pass_frames) {
      report.warnings.push_back(
          label + ": skipped, only " + std::to_string(last - first) +
          " frames (min_pass_frames = " + std::to_string(config.min_pass_frames) + ")");
      continue;
    }
    std::vector<Eigen::Isometry3d> poses(T_world_sonar.begin() + first,
                                         T_world_sonar.begin() + last);
    PassPlan plan{first, last - first, label, analyze_pass(poses, config, label), 0.0, -1};
    plan.dz = config.layer_spacing > 0 ? config.layer_spacing : plan.geo.spacing;
    // Columns beyond the farthest return hold nothing: the window ends there.
    plan.bin_hi = last_return_bin(denoised, first, plan.count, bin_hi);
    if (plan.bin_hi < 0) {
      report.warnings.push_back(label + ": skipped, no return in any frame after denoising");
      continue;
    }
    if (config.exact) {
      // A cell seen off-centre lands up to r·(1/cos θ_3dB − 1) farther: keep those empty
      // bins, they constrain the far cells.
      const double r = spec.range_of_bin(plan.bin_hi);
      plan.bin_hi = std::min(
          bin_hi,
          plan.bin_hi + 1 + static_cast<int>(std::ceil(r * (1.0 / std::cos(theta3) - 1.0) / dr)));
    }
    // eq. 5.25–5.26: the far range needs K frames to be seen by a full footprint.
    const double r_far = spec.range_of_bin(plan.bin_hi);
    const int K_far = footprint_layers(r_far, spec.vertical_aperture_rad, plan.dz);
    if (static_cast<int>(plan.count) < K_far) {
      const double r_ok = plan.count * plan.dz / (2.0 * std::tan(theta3));
      throw Error(label + ": too few frames for the footprint: at r = " + fmt(r_far, 2) +
                  " m the aperture of " + fmt(spec.vertical_aperture_rad / kDeg, 1) +
                  "° spans K = " + std::to_string(K_far) + " layers of " + fmt(plan.dz * 100, 2) +
                  " cm (eq. 5.25) but the pass has " + std::to_string(plan.count) +
                  " frames; record a longer pass or limit the "
                  "range with max_range ≤ " +
                  fmt(r_ok, 2) + " m (the farthest return is at " + fmt(r_far, 2) + " m)");
    }
    plans.push_back(std::move(plan));
  }
  return plans;
}

// A pass's report before solving: its geometry, footprint sizes (eq. 5.25) and the rectilinear
// approximation's mismatch (eq. 5.21), with a warning for each that does not hold.
PassReport pass_report(const PassPlan& plan, const SonarSpec& spec, const DeconvConfig& config) {
  const double theta3 = spec.theta_3db();
  const double dr = spec.range_resolution();
  PassReport pr;
  pr.first_frame = plan.first;
  pr.frames = plan.count;
  const PassGeometry& g = plan.geo;
  pr.spacing = g.spacing;
  pr.axis_angle_deg = g.axis_angle_rad / kDeg;
  pr.max_rotation_deg = g.max_rotation_rad / kDeg;
  pr.max_lateral = g.max_lateral;
  pr.rms_lateral = g.rms_lateral;
  pr.max_spacing_error = g.max_spacing_error;
  pr.rms_spacing_error = g.rms_spacing_error;
  pr.warnings = g.warnings;
  const double r_far = spec.range_of_bin(plan.bin_hi);
  pr.K_min = footprint_layers(spec.range_of_bin(0), spec.vertical_aperture_rad, plan.dz);
  pr.K_max = footprint_layers(r_far, spec.vertical_aperture_rad, plan.dz);
  pr.rectilinear_mismatch_bins = rectilinear_mismatch(r_far, theta3) / dr;
  pr.rectilinear_max_aperture_deg = rectilinear_max_aperture(r_far, dr) / kDeg;
  if (g.max_lateral > 0.5 * dr) {
    pr.warnings.push_back(plan.label + ": frames deviate up to " + fmt(g.max_lateral * 100, 2) +
                          " cm (rms " + fmt(g.rms_lateral * 100, 2) +
                          " cm) from the pass axis, more than half a range bin (" +
                          fmt(0.5 * dr * 100, 2) + " cm): returns shift between columns");
  }
  if (!config.exact && pr.rectilinear_mismatch_bins > config.rectilinear_warn_bins) {
    // eq. 5.21 gives the largest range where the approximation holds for this aperture.
    const double r_ok = 0.5 * dr / (1.0 - std::cos(theta3));
    pr.warnings.push_back(
        plan.label +
        ": the rectilinear approximation (eq. 5.21) is violated beyond r = " + fmt(r_ok, 2) +
        " m: at r = " + fmt(r_far, 2) + " m the " + fmt(spec.vertical_aperture_rad / kDeg, 1) +
        "° aperture bends the footprint by " + fmt(pr.rectilinear_mismatch_bins, 2) +
        " range bins at its edge (eq. 5.21 allows " + fmt(pr.rectilinear_max_aperture_deg, 1) +
        "° here); vertical surfaces may show gaps (Fig. 5.14) — the exact mode avoids them");
  }
  if (pr.K_max < 2) {
    pr.warnings.push_back(plan.label +
                          ": footprints do not overlap (K = " + std::to_string(pr.K_max) +
                          " at the far range): deconvolution reduces to a reprojection");
  }
  return pr;
}

// A pass's column stack (sec. 5.5): its frames ordered by height, their model heights (measured,
// or the thesis' uniform z_0 + k·Δz), the intensities transposed into (bin, beam) columns along
// the frames, and each frame's first return per beam. `returns`: the frames' free-space summaries
// (empty when not needed).
PassData column_stack(const PassPlan& plan, const std::vector<SonarImage>& denoised,
                      const std::vector<Eigen::Isometry3d>& T_world_sonar, const SonarSpec& spec,
                      const DeconvConfig& config, const std::vector<FrameReturns>& returns) {
  const bool need_returns = config.dering || config.resolve_occlusions;
  const PassGeometry& g = plan.geo;
  PassData pd;
  pd.spec = &spec;
  pd.geo = g;
  pd.dz = plan.dz;
  pd.theta_3db = spec.theta_3db();
  pd.n = static_cast<int>(plan.count);
  pd.bin_lo = 0;
  pd.bin_hi = plan.bin_hi;
  pd.bins = plan.bin_hi + 1;
  pd.beams = spec.beams();
  if (config.use_measured_heights) {
    pd.heights = g.heights;
  } else {
    // The thesis' model: uniform z_0 + k·Δz (from the least-squares fit).
    pd.heights.resize(pd.n);
    double mean_h = 0;
    for (double v : g.heights) mean_h += v;
    mean_h /= pd.n;
    for (int k = 0; k < pd.n; ++k) pd.heights[k] = mean_h + (k - 0.5 * (pd.n - 1)) * g.spacing;
  }
  pd.stack.assign(static_cast<std::size_t>(pd.beams) * pd.bins * pd.n, 0.0f);
  pd.bin_has_data.assign(pd.bins, 0);
  pd.T_world_sonar.resize(pd.n);
  if (need_returns) pd.returns.resize(pd.n);
  std::vector<const SonarImage*> by_height(pd.n);
  for (int k = 0; k < pd.n; ++k) {
    const std::size_t f = plan.first + g.frames[k];
    by_height[k] = &denoised[f];
    pd.T_world_sonar[k] = T_world_sonar[f];
    if (need_returns) pd.returns[k] = &returns[f];
  }
  // Transpose to columns bin by bin: contiguous writes along the frames, one streaming read
  // per frame row.
  tbb::parallel_for(0, pd.bins, [&](int i) {
    bool any = false;
    for (int j = 0; j < pd.beams; ++j) {
      float* col = &pd.stack[(static_cast<std::size_t>(j) * pd.bins + i) * pd.n];
      for (int k = 0; k < pd.n; ++k) {
        const float v = by_height[k]->row_ptr(i)[j];
        col[k] = v;
        any = any || v > 0.0f;
      }
    }
    pd.bin_has_data[i] = any;
  });
  pd.first_return.assign(static_cast<std::size_t>(pd.beams) * pd.n, pd.bins);
  tbb::parallel_for(0, pd.beams, [&](int j) {
    for (int i = 0; i < pd.bins; ++i) {
      const float* col = &pd.stack[(static_cast<std::size_t>(j) * pd.bins + i) * pd.n];
      for (int k = 0; k < pd.n; ++k) {
        int& f = pd.first_return[static_cast<std::size_t>(j) * pd.n + k];
        if (f == pd.bins && col[k] > 0.0f) f = i;
      }
    }
  });
  return pd;
}

// A pass's layers: the per-column NNLS (eq. 5.28; the exact geometry mode, or the rectilinear
// approximation of eq. 5.27), layers beyond max_extrapolation dropped, de-ringing (sec. 5.5.4)
// and, with a kernel other than plain, the second pass whose kernel the first reconstruction
// scales (sec. 5.6.7). Fills `pr` and the timing of `report`.
std::vector<LayerPoint> solve_pass(const PassData& pd, const DeconvConfig& config,
                                   const BeamPattern& pattern, PassReport& pr, DeconvReport& report,
                                   Progress& bar) {
  auto t0 = std::chrono::steady_clock::now();
  std::vector<LayerPoint> points;
  if (config.exact) {
    solve_exact(pd, config, pattern, pr, points, &bar);
  } else {
    solve_approx(pd, config, pattern, nullptr, pr, points, &bar);
  }
  report.seconds_solve += seconds_since(t0);
  if (config.max_extrapolation >= 0) {
    const double lo = pd.heights.front() - config.max_extrapolation;
    const double hi = pd.heights.back() + config.max_extrapolation;
    points.erase(
        std::remove_if(points.begin(), points.end(),
                       [&](const LayerPoint& lp) { return lp.height < lo || lp.height > hi; }),
        points.end());
  }
  pr.points_solved = points.size();
  t0 = std::chrono::steady_clock::now();
  if (config.dering) pr.points_deringed = dering(pd, points);
  report.seconds_dering += seconds_since(t0);

  if (config.kernel != DeconvConfig::Kernel::Plain) {
    // sec. 5.6.7: the first reconstruction provides normals / occlusions for a second pass.
    t0 = std::chrono::steady_clock::now();
    const std::unique_ptr<KernelScaler> scaler = make_multipass_scaler(pd, config, points);
    std::vector<LayerPoint> second;
    PassReport pr2;
    solve_approx(pd, config, pattern, scaler.get(), pr2, second, &bar);
    pr.unconverged += pr2.unconverged;
    pr.max_iterations = std::max(pr.max_iterations, pr2.max_iterations);
    pr.points_solved = second.size();
    if (config.dering) pr.points_deringed = dering(pd, second);
    points.swap(second);
    report.seconds_multipass += seconds_since(t0);
  }
  return points;
}

// The auto mode: the passes mode when the frames form regular passes, the voxel mode otherwise:
// decided first from the poses alone (auto_mode_reason), then, should the passes mode still refuse
// (e.g. too few frames for a footprint) or leave frames out, by its outcome.
PointCloud deconvolve_auto(const std::vector<SonarImage>& denoised,
                           const std::vector<Eigen::Isometry3d>& T_world_sonar,
                           const SonarSpec& spec, const DeconvConfig& config,
                           DeconvReport* report_out, bool progress) {
  std::string why = auto_mode_reason(T_world_sonar, config);
  if (why.empty()) {
    DeconvConfig pc = config;
    pc.mode = DeconvConfig::Mode::Passes;
    DeconvReport pr;
    try {
      PointCloud cloud = deconvolve_frames(denoised, T_world_sonar, spec, pc, &pr, progress);
      std::size_t in_passes = 0;
      for (const PassReport& p : pr.passes) in_passes += p.frames;
      if (in_passes == denoised.size()) {
        if (report_out) *report_out = std::move(pr);
        return cloud;
      }
      why = std::to_string(denoised.size() - in_passes) + " of " + std::to_string(denoised.size()) +
            " frames in no reconstructed pass";
    } catch (const Error& e) {
      why = e.what();
    }
  }
  DeconvConfig vc = config;
  vc.mode = DeconvConfig::Mode::Voxel;
  DeconvReport vr;
  PointCloud cloud = deconvolve_frames(denoised, T_world_sonar, spec, vc, &vr, progress);
  vr.mode_note = "deconvolution mode auto: voxel mode, the passes mode does not apply (" + why +
                 "); --deconv-mode passes forces it";
  if (report_out) *report_out = std::move(vr);
  return cloud;
}

// The passes mode: plan the passes, summarise every frame's free space (de-ringing, occlusion
// resolution), reconstruct pass by pass (report, column stack, solve), then keep the front
// surfaces (sec. 5.6.7.3, as carving does, sec. 4.4.5). Runs in the caller's task arena.
PointCloud deconvolve_passes(const std::vector<SonarImage>& denoised,
                             const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const SonarSpec& spec, const DeconvConfig& config, int bin_hi,
                             DeconvReport& report, bool progress) {
  const BeamPattern pattern = kernel_pattern(config, spec);
  // Split and check every pass before the heavy work: a bad pass fails fast.
  const std::vector<PassPlan> plans =
      plan_passes(denoised, T_world_sonar, spec, config, bin_hi, report);

  // Free-space summaries of every frame (de-ringing, occlusion resolution).
  std::vector<FrameReturns> returns;
  if (config.dering || config.resolve_occlusions) {
    returns.resize(denoised.size());
    tbb::parallel_for(std::size_t{0}, denoised.size(), [&](std::size_t f) {
      returns[f] = summarize_frame(denoised[f], T_world_sonar[f], spec);
    });
  }

  std::size_t units = 0;
  for (const auto& p : plans) {
    units += static_cast<std::size_t>(config.exact ? spec.beams() : p.bin_hi + 1);
  }
  if (config.kernel != DeconvConfig::Kernel::Plain) units *= 2;
  Progress bar("deconvolve", units, progress);

  PointCloud cloud;
  for (const PassPlan& plan : plans) {
    PassReport pr = pass_report(plan, spec, config);
    const PassData pd = column_stack(plan, denoised, T_world_sonar, spec, config, returns);
    for (const LayerPoint& lp : solve_pass(pd, config, pattern, pr, report, bar)) {
      cloud.points.push_back(lp.p_world);
      cloud.intensity.push_back(lp.value);
    }
    for (const auto& w : pr.warnings) report.warnings.push_back(w);
    report.passes.push_back(std::move(pr));
  }
  bar.finish();

  report.points_before_occlusion = cloud.size();
  if (config.resolve_occlusions && !cloud.empty()) {
    // sec. 5.6.7.3: keep the front surfaces, as carving does (sec. 4.4.5).
    const auto t0 = std::chrono::steady_clock::now();
    OcclusionConfig oc = config.occlusion;
    if (oc.num_threads == 0) oc.num_threads = config.num_threads;
    if (config.occlusion_auto_voxel) {
      oc.voxel_size = spec.range_resolution();
      for (const PassPlan& p : plans) oc.voxel_size = std::min(oc.voxel_size, p.dz);
    }
    cloud = resolve_occlusions(cloud, returns, spec, oc);
    report.seconds_occlusion = seconds_since(t0);
  }
  return cloud;
}

}  // namespace

// The pipeline of deconvolution (thesis ch. 5): checks, the mode (auto: passes or voxel), then
// the passes mode's stages above (deconvolve_passes) in a task arena of num_threads.
PointCloud deconvolve_frames(const std::vector<SonarImage>& denoised,
                             const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const SonarSpec& spec, const DeconvConfig& config,
                             DeconvReport* report_out, bool progress) {
  using namespace deconv_detail;
  const auto t_start = std::chrono::steady_clock::now();
  config.validate();
  spec.validate();
  check_frames(denoised, T_world_sonar, spec);
  if (config.mode == DeconvConfig::Mode::Auto) {
    return deconvolve_auto(denoised, T_world_sonar, spec, config, report_out, progress);
  }
  DeconvReport report;
  report.frames = denoised.size();
  PointCloud cloud;
  if (config.mode == DeconvConfig::Mode::Voxel) {
    report.mode = "voxel";
    cloud = deconvolve_voxels(denoised, T_world_sonar, spec, config, report, progress);
    report.points = cloud.size();
    report.seconds_total = seconds_since(t_start);
    if (report_out) *report_out = std::move(report);
    return cloud;
  }
  const int bin_hi = farthest_bin(spec, config);
  tbb::task_arena arena(config.num_threads > 0 ? config.num_threads : tbb::task_arena::automatic);
  arena.execute([&] {
    cloud = deconvolve_passes(denoised, T_world_sonar, spec, config, bin_hi, report, progress);
  });
  if (report.passes.empty()) {
    report.warnings.push_back("no pass was reconstructed");
  }
  report.points = cloud.size();
  report.seconds_total = seconds_since(t_start);
  if (report_out) *report_out = std::move(report);
  return cloud;
}

PointCloud deconvolve_dataset(const Dataset& dataset, const DeconvConfig& config, bool progress,
                              DeconvReport* report_out) {
  config.validate();
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = dataset.size();
  std::vector<SonarImage> frames(n);
  std::vector<Eigen::Isometry3d> poses(n);
  {
    Progress bar("read+denoise", n, progress);
    tbb::task_arena arena(config.num_threads > 0 ? config.num_threads : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        frames[i] = dataset.load_frame(i);
        poses[i] = dataset.T_world_sonar(i);
        denoise(frames[i], dataset.noise, config.denoise);  // sec. 5.5.4: Z-test before
        bar.add();
      });
    });
    bar.finish();
  }
  const double t_load = seconds_since(t0);
  DeconvReport report;
  PointCloud cloud = deconvolve_frames(frames, poses, dataset.spec, config, &report, progress);
  report.seconds_load = t_load;
  report.seconds_total += t_load;
  if (report_out) *report_out = std::move(report);
  return cloud;
}

// ---------------------------------------------------------------------------------------------
// Reports

std::vector<std::string> summarize_pass_warnings(const std::vector<std::string>& warnings) {
  // "pass N (frames A–B): what" → group by "what", in order of first appearance.
  std::vector<std::string> keys;
  std::map<std::string, std::vector<std::string>> labels;  // what -> pass labels
  std::vector<std::string> out_order;                      // key, or "\n" + a plain warning
  for (const auto& w : warnings) {
    const std::size_t sep = w.find("): ");
    if (w.rfind("pass ", 0) != 0 || sep == std::string::npos) {
      out_order.push_back("\n" + w);
      continue;
    }
    const std::string label = w.substr(0, sep + 1), what = w.substr(sep + 3);
    auto& l = labels[what];
    if (l.empty()) out_order.push_back(what);
    l.push_back(label);
  }
  std::vector<std::string> out;
  for (const auto& k : out_order) {
    if (k.rfind("\n", 0) == 0) {
      out.push_back(k.substr(1));
      continue;
    }
    const auto& l = labels[k];
    if (l.size() == 1) {
      out.push_back(l[0] + ": " + k);
    } else {
      out.push_back(std::to_string(l.size()) + " passes, " + l.front() +
                    (l.size() > 2 ? " … " : " and ") + l.back() + ": " + k);
    }
  }
  return out;
}

std::string DeconvReport::to_text(bool with_warnings) const {
  std::ostringstream os;
  for (std::size_t i = 0; i < passes.size(); ++i) {
    const PassReport& p = passes[i];
    os << "pass " << i + 1 << ": frames " << p.first_frame << "–" << p.first_frame + p.frames - 1
       << ", Δz " << fmt(p.spacing * 100, 3) << " cm (± max " << fmt(p.max_spacing_error * 100, 2)
       << " cm), axis " << fmt(p.axis_angle_deg, 2) << "°, lateral max "
       << fmt(p.max_lateral * 100, 2) << " cm, K " << p.K_min << "–" << p.K_max << ", arc-vs-chord "
       << fmt(p.rectilinear_mismatch_bins, 2) << " bins, columns " << p.columns_solved << "/"
       << p.columns << ", points " << p.points_solved << " − " << p.points_deringed << " de-ringed";
    if (p.exact_sweeps > 0) {
      os << ", sweeps " << p.exact_sweeps << " (KKT " << std::scientific << p.exact_kkt
         << std::defaultfloat << ")";
    }
    if (p.unconverged) os << ", " << p.unconverged << " unconverged";
    os << "\n";
  }
  if (mode == "voxel") {
    os << "voxel deconvolution: " << voxel.candidates << " candidate voxels (" << voxel.unknowns
       << " in a return pixel; left out: " << voxel.unbracketed << " never bracketed, "
       << voxel.refuted << " seen free), " << voxel.equations << " equations, " << voxel.nonzeros
       << " non-zeros, " << voxel.iterations << " iterations"
       << (voxel.converged ? "" : " (iteration cap)") << ", residual "
       << fmt(voxel.relative_residual, 3) << ", " << voxel.points_solved << " voxels kept (";
    if (voxel.kept_bracketed > 0) os << voxel.kept_bracketed << " of them faint but bracketed; ";
    os << fmt(voxel.seconds_carve, 2) << " s carving, " << fmt(voxel.seconds_build, 2)
       << " s model, " << fmt(voxel.seconds_solve, 2) << " s solve)\n";
  }
  os << "deconvolution: " << frames << " frames, ";
  if (mode == "voxel") {
    os << "voxel mode, ";
  } else {
    os << passes.size() << " passes, ";
  }
  os << points << " points";
  if (points_before_occlusion != points) {
    os << " (" << points_before_occlusion << " before occlusion resolution)";
  }
  os << "; " << fmt(seconds_total, 2) << " s (read " << fmt(seconds_load, 2) << ", solve "
     << fmt(seconds_solve, 2) << ", de-ring " << fmt(seconds_dering, 2) << ", multipass "
     << fmt(seconds_multipass, 2) << ", occlusion " << fmt(seconds_occlusion, 2) << ")\n";
  if (with_warnings) {
    for (const auto& w : summarize_pass_warnings(warnings)) os << "warning: " << w << "\n";
  }
  return os.str();
}

std::string DeconvReport::to_json(int indent) const {
  nlohmann::ordered_json j;
  j["mode"] = mode;
  if (!mode_note.empty()) j["mode_note"] = mode_note;
  j["frames"] = frames;
  j["points"] = points;
  if (mode == "voxel") {
    j["voxel"] = {{"candidates", voxel.candidates},
                  {"unbracketed", voxel.unbracketed},
                  {"refuted", voxel.refuted},
                  {"unknowns", voxel.unknowns},
                  {"equations", voxel.equations},
                  {"nonzeros", voxel.nonzeros},
                  {"iterations", voxel.iterations},
                  {"converged", voxel.converged},
                  {"relative_residual", voxel.relative_residual},
                  {"points_solved", voxel.points_solved},
                  {"kept_bracketed", voxel.kept_bracketed},
                  {"seconds_carve", voxel.seconds_carve},
                  {"seconds_build", voxel.seconds_build},
                  {"seconds_solve", voxel.seconds_solve}};
  }
  j["points_before_occlusion"] = points_before_occlusion;
  j["seconds"] = {{"total", seconds_total},         {"load", seconds_load},
                  {"solve", seconds_solve},         {"dering", seconds_dering},
                  {"multipass", seconds_multipass}, {"occlusion", seconds_occlusion}};
  nlohmann::ordered_json ps = nlohmann::ordered_json::array();
  for (const auto& p : passes) {
    nlohmann::ordered_json q;
    q["first_frame"] = p.first_frame;
    q["frames"] = p.frames;
    q["spacing_m"] = p.spacing;
    q["axis_angle_deg"] = p.axis_angle_deg;
    q["max_rotation_deg"] = p.max_rotation_deg;
    q["max_lateral_m"] = p.max_lateral;
    q["rms_lateral_m"] = p.rms_lateral;
    q["max_spacing_error_m"] = p.max_spacing_error;
    q["rms_spacing_error_m"] = p.rms_spacing_error;
    q["K_min"] = p.K_min;
    q["K_max"] = p.K_max;
    q["rectilinear_mismatch_bins"] = p.rectilinear_mismatch_bins;
    q["rectilinear_max_aperture_deg"] = p.rectilinear_max_aperture_deg;
    q["columns"] = p.columns;
    q["columns_solved"] = p.columns_solved;
    q["unconverged"] = p.unconverged;
    q["max_iterations"] = p.max_iterations;
    q["exact_sweeps"] = p.exact_sweeps;
    q["exact_kkt"] = p.exact_kkt;
    q["points_solved"] = p.points_solved;
    q["points_deringed"] = p.points_deringed;
    q["warnings"] = p.warnings;
    ps.push_back(q);
  }
  j["passes"] = ps;
  j["warnings"] = warnings;
  return j.dump(indent);
}

}  // namespace sonar3d
