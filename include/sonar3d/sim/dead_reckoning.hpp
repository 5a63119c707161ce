#pragma once
// Navigation as a vehicle logs it (thesis sec. 6.2: dead-reckoning drift of about 1 % of the
// distance travelled, yaw within a fraction of a degree). The simulator renders with the true
// trajectory and writes this one to navigation.tum; truth/navigation.tum keeps the true one.
#include <Eigen/Core>

#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

struct DeadReckoningConfig {
  // DVL-like velocity: measured = (1 + velocity_scale_error) · true + bias (vehicle frame,
  // horizontal), the bias a random walk of velocity_bias_walk m/s per √s on each axis.
  double velocity_scale_error = 0.01;
  // 5e-5 m/s/√s: the bias wanders to about 1.5 mm/s in 15 minutes, a DVL's bias stability.
  double velocity_bias_walk = 0.00005;  // m/s/√s
  double heading_bias_deg = 0.2;        // compass/AHRS yaw error, degrees (at the edge: _deg)
  double depth_offset_m = 0.05;         // depth sensor offset (logged z = true z − offset), m

  void validate() const;  // throws Error naming the field
};

// Integrates the true trajectory's velocity as a DVL + compass + depth sensor would measure it,
// starting at the true first pose: horizontal positions drift, z is the true height shifted by
// the depth offset, orientations carry the heading bias. Seeded: same seed, same trajectory.
Trajectory dead_reckoning(const Trajectory& T_world_vehicle_true, const DeadReckoningConfig& config,
                          unsigned long long seed);

}  // namespace sonar3d
