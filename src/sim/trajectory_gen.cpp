#include "sonar3d/sim/trajectory_gen.hpp"

#include <cmath>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

Trajectory straight_pass(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double spacing,
                         const Eigen::Matrix3d& R_world_vehicle, double t0, double period) {
  require_positive(spacing, "trajectory.spacing", "m");
  require_positive(period, "trajectory.period", "s");
  require(start.allFinite() && end.allFinite(), "trajectory: start and end must be finite");
  const double length = (end - start).norm();
  // Frames at 0, Δ, 2Δ ... up to the end (inclusive within 1e-9 of a step).
  const int n = static_cast<int>(std::floor(length / spacing + 1e-9)) + 1;
  if (n > 10000000) throw Error("trajectory: more than 10 million frames; increase the spacing");
  const Eigen::Vector3d dir = length > 0 ? Eigen::Vector3d((end - start) / length)
                                         : Eigen::Vector3d::Zero();
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
  Trajectory traj;
  double t = t0;
  int line = 0;
  for (double y = y0; y <= y1 + 1e-9; y += line_spacing, ++line) {
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
