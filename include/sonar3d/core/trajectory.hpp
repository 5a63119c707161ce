#pragma once
// Timestamped poses T_world_<frame> with TUM file IO and interpolation (linear + slerp,
// thesis sec. 4.6.1). A time outside the span is an error, not an extrapolation.
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace sonar3d {

struct Trajectory {
  std::vector<double> times;             // s, strictly increasing
  std::vector<Eigen::Isometry3d> poses;  // T_world_frame

  std::size_t size() const { return times.size(); }
  bool empty() const { return times.empty(); }
  void push_back(double t, const Eigen::Isometry3d& T) {
    times.push_back(t);
    poses.push_back(T);
  }
  // Pose at time t: linear interpolation of the translation and slerp of the rotation between
  // the bracketing samples. Throws Error when t is outside [front, back] (with a 1 µs tolerance)
  // or the trajectory is empty.
  Eigen::Isometry3d interpolate(double t) const;
  // Throws Error naming the first sample that is not finite, not rigid or out of time order.
  void validate(const std::string& where = "trajectory") const;
};

// TUM format: "t tx ty tz qx qy qz qw" per line, '#' comments. Errors name file and line.
Trajectory read_tum(const std::string& path);
void write_tum(const std::string& path, const Trajectory& traj);  // atomic write

// True when the rotation part is orthonormal with det +1 and all entries are finite.
bool is_rigid(const Eigen::Isometry3d& T, double tol = 1e-6);

}  // namespace sonar3d
