#pragma once
// Small shared constants and helpers: angles in radians per degree, wall time since a start.
#include <chrono>

namespace sonar3d {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDeg = kPi / 180;  // radians per degree: x_deg * kDeg is in radians

// Wall time elapsed since t0, s.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace sonar3d
