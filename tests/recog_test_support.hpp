#pragma once
// Helpers shared by the recognition tests (test_recognition.cpp, test_recognition_3d.cpp).
#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "sonar3d/recog/model.hpp"
#include "sonar3d/sim/reference_objects.hpp"

namespace sonar3d::test {

constexpr double kDeg = M_PI / 180.0;

// A reference object (sphere, tank, pillar, riser) sampled every 1.5 cm.
inline ModelTemplate reference_template(const std::string& name, Symmetry s = Symmetry::None) {
  ModelSamplingConfig sc;
  sc.spacing_m = 0.015;
  return make_model_template(name, make_reference_object(name), s, -1, sc);
}

// T = Trans(x, y, z) · Rz(yaw) · Ry(pitch) · Rx(roll), degrees.
inline Eigen::Isometry3d pose(double x, double y, double z, double yaw_deg, double roll_deg = 0,
                              double pitch_deg = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() = (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return T;
}

}  // namespace sonar3d::test
