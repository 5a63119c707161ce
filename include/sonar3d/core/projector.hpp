#pragma once
// Between polar sonar coordinates (range r, bearing φ, elevation θ) and Cartesian points in the
// sonar frame (FLU: +x boresight, +y left, +z up): p = r·(cosθ·cosφ, cosθ·sinφ, sinθ).
#include <Eigen/Core>

namespace sonar3d {

struct Polar {
  double range = 0;      // m
  double bearing = 0;    // rad, from +x toward +y
  double elevation = 0;  // rad, from the image plane toward +z
};

inline Eigen::Vector3d polar_to_sonar(const Polar& p) {
  const double c = std::cos(p.elevation);
  return p.range * Eigen::Vector3d(c * std::cos(p.bearing), c * std::sin(p.bearing),
                                   std::sin(p.elevation));
}

inline Polar sonar_to_polar(const Eigen::Vector3d& p_sonar) {
  Polar out;
  out.range = p_sonar.norm();
  out.bearing = std::atan2(p_sonar.y(), p_sonar.x());
  const double rho = std::hypot(p_sonar.x(), p_sonar.y());
  out.elevation = std::atan2(p_sonar.z(), rho);
  return out;
}

}  // namespace sonar3d
