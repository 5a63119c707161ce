#include "sonar3d/core/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

bool is_rigid(const Eigen::Isometry3d& T, double tol) {
  if (!T.matrix().allFinite()) return false;
  const Eigen::Matrix3d R = T.linear();
  if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), tol)) return false;
  if (std::abs(R.determinant() - 1.0) > tol) return false;
  const auto last = T.matrix().row(3);
  return std::abs(last(0)) < tol && std::abs(last(1)) < tol && std::abs(last(2)) < tol &&
         std::abs(last(3) - 1.0) < tol;
}

void Trajectory::validate(const std::string& where) const {
  if (times.size() != poses.size()) throw Error(where + ": times and poses differ in length");
  for (std::size_t i = 0; i < times.size(); ++i) {
    if (!std::isfinite(times[i])) {
      throw Error(where + ": pose " + std::to_string(i) + " has a non-finite timestamp");
    }
    if (!is_rigid(poses[i], 1e-5)) {
      throw Error(where + ": pose " + std::to_string(i) + " (t=" + std::to_string(times[i]) +
                  " s) is not a finite rigid transform");
    }
    if (poses[i].translation().cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
      throw Error(where + ": pose " + std::to_string(i) + " (t=" + std::to_string(times[i]) +
                  " s) lies more than 1e7 m from the origin; use a local frame");
    }
    if (i > 0 && !(times[i] > times[i - 1])) {
      throw Error(where + ": timestamps must increase strictly; pose " + std::to_string(i) +
                  " (t=" + std::to_string(times[i]) + " s) is not after the previous one");
    }
  }
}

Eigen::Isometry3d Trajectory::interpolate(double t) const {
  if (empty()) throw Error("cannot interpolate a pose: the trajectory is empty");
  constexpr double kTol = 1e-6;  // s
  if (!std::isfinite(t) || t < times.front() - kTol || t > times.back() + kTol) {
    std::ostringstream os;
    os << std::setprecision(10) << "time " << t << " s is outside the navigation span ["
       << times.front() << ", " << times.back() << "] s";
    throw Error(os.str());
  }
  if (size() == 1 || t <= times.front()) return poses.front();
  if (t >= times.back()) return poses.back();
  const auto it = std::upper_bound(times.begin(), times.end(), t);
  const std::size_t i = static_cast<std::size_t>(it - times.begin());
  const double a = (t - times[i - 1]) / (times[i] - times[i - 1]);
  // sec. 4.6.1: linear interpolation of positions, spherical-linear of orientations.
  const Eigen::Quaterniond q0(poses[i - 1].linear());
  const Eigen::Quaterniond q1(poses[i].linear());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q0.slerp(a, q1).normalized().toRotationMatrix();
  T.translation() = (1 - a) * poses[i - 1].translation() + a * poses[i].translation();
  return T;
}

Trajectory read_tum(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec)) {
    throw Error("cannot read trajectory '" + path + "': not a regular file");
  }
  std::ifstream f(path);
  if (!f) throw Error("cannot open trajectory '" + path + "'");
  Trajectory traj;
  std::string line;
  int lineno = 0;
  while (std::getline(f, line)) {
    ++lineno;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream is(line);
    double v[8];
    for (double& x : v) {
      if (!(is >> x)) {
        throw Error(path + ":" + std::to_string(lineno) +
                    ": expected 8 numbers 't tx ty tz qx qy qz qw'");
      }
    }
    std::string extra;
    if (is >> extra) {
      throw Error(path + ":" + std::to_string(lineno) + ": unexpected extra field '" +
                  printable(extra) + "'");
    }
    for (double x : v) {
      if (!std::isfinite(x))
        throw Error(path + ":" + std::to_string(lineno) + ": non-finite value");
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    const double n = q.norm();
    if (std::abs(n - 1.0) > 1e-3) {
      throw Error(path + ":" + std::to_string(lineno) + ": quaternion norm " + std::to_string(n) +
                  " is not 1 (not a rotation)");
    }
    q.normalize();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.toRotationMatrix();
    T.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!traj.empty() && !(v[0] > traj.times.back())) {
      throw Error(path + ":" + std::to_string(lineno) + ": timestamp " + std::to_string(v[0]) +
                  " does not increase (timestamps must go forward)");
    }
    traj.push_back(v[0], T);
  }
  return traj;
}

void write_tum(const std::string& path, const Trajectory& traj) {
  std::ostringstream os;
  os << "# t tx ty tz qx qy qz qw\n" << std::setprecision(17);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const Eigen::Quaterniond q(traj.poses[i].linear());
    const Eigen::Vector3d p = traj.poses[i].translation();
    os << traj.times[i] << ' ' << p.x() << ' ' << p.y() << ' ' << p.z() << ' ' << q.x() << ' '
       << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  write_text_file(path, os.str());
}

}  // namespace sonar3d
