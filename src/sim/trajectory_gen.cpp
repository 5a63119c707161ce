#include "sonar3d/sim/trajectory_gen.hpp"

#include <cmath>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

Trajectory straight_pass(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double spacing,
                         const Eigen::Matrix3d& R_world_vehicle, double t0, double period) {
  require_positive(spacing, "trajectory.spacing", "m");
  require_positive(period, "trajectory.period", "s");
  require(start.allFinite() && end.allFinite(), "trajectory: start and end must be finite");
  require(start.cwiseAbs().maxCoeff() <= limits::kMaxCoordinate &&
              end.cwiseAbs().maxCoeff() <= limits::kMaxCoordinate,
          "trajectory: start and end coordinates must lie within ±1e7 m");
  const double length = (end - start).norm();
  // Frames at 0, Δ, 2Δ ... up to the end (inclusive within 1e-9 of a step). Counted in double:
  // length / spacing overflows an int for a tiny spacing.
  const int n = static_cast<int>(limits::checked_count(
      std::floor(length / spacing + 1e-9) + 1, 1, limits::kMaxFrames,
      "trajectory: the frame count (length / spacing + 1)", "increase 'spacing'"));
  const Eigen::Vector3d dir =
      length > 0 ? Eigen::Vector3d((end - start) / length) : Eigen::Vector3d::Zero();
  Trajectory traj;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R_world_vehicle;
    T.translation() = start + dir * (k * spacing);
    traj.push_back(t0 + k * period, T);
  }
  return traj;
}

Trajectory orbit(const Eigen::Vector3d& center, double radius, int count, double start_angle,
                 double sweep, double t0, double period) {
  require_positive(radius, "trajectory.radius", "m");
  require_positive(period, "trajectory.period", "s");
  require(count >= 1, "parameter 'trajectory.count' must be >= 1");
  limits::checked_count(count, 1, limits::kMaxFrames, "parameter 'trajectory.count'",
                        "use fewer frames");
  require(center.allFinite() && center.cwiseAbs().maxCoeff() + radius <= limits::kMaxCoordinate,
          "trajectory: the orbit must lie within ±1e7 m");
  require(std::isfinite(start_angle) && std::isfinite(sweep) && sweep != 0.0,
          "trajectory: orbit angles must be finite and the sweep non-zero");
  const bool closed = std::abs(std::abs(sweep) - 2 * M_PI) < 1e-9;
  Trajectory traj;
  for (int k = 0; k < count; ++k) {
    const double a = start_angle + sweep * k / (closed || count == 1 ? count : count - 1);
    const Eigen::Vector3d p = center + radius * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    // Face the centre: heading a + π about +z.
    T.linear() = Eigen::AngleAxisd(a + M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = p;
    traj.push_back(t0 + k * period, T);
  }
  return traj;
}

Trajectory lawnmower(double x0, double x1, double y0, double y1, double z, double line_spacing,
                     double spacing, double t0, double period) {
  require_positive(line_spacing, "trajectory.line_spacing", "m");
  require_positive(spacing, "trajectory.spacing", "m");
  require(x1 > x0 && y1 >= y0, "trajectory: lawnmower area needs x1 > x0 and y1 >= y0");
  // Lines counted up front: `y += line_spacing` never moves y when the spacing is below its
  // rounding step (1e-300: an endless loop).
  const long long lines = limits::checked_count(
      std::floor((y1 - y0) / line_spacing + 1e-9) + 1, 1, limits::kMaxFrames,
      "trajectory: the line count ((y1 - y0) / line_spacing + 1)", "increase 'line_spacing'");
  const double per_line = std::floor((x1 - x0) / spacing + 1e-9) + 1;
  limits::checked_count(per_line * static_cast<double>(lines), 1, limits::kMaxFrames,
                        "trajectory: the frame count (lines × frames per line)",
                        "increase 'spacing' or 'line_spacing'");
  Trajectory traj;
  double t = t0;
  for (long long line = 0; line < lines; ++line) {
    const double y = y0 + static_cast<double>(line) * line_spacing;
    const bool forward = (line % 2 == 0);
    const Eigen::Vector3d a(forward ? x0 : x1, y, z), b(forward ? x1 : x0, y, z);
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(forward ? 0.0 : M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Trajectory seg = straight_pass(a, b, spacing, R, t, period);
    for (std::size_t k = 0; k < seg.size(); ++k) traj.push_back(seg.times[k], seg.poses[k]);
    t = traj.times.back() + period;
  }
  return traj;
}

}  // namespace sonar3d
