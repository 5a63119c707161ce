// Dead-reckoning navigation error model: DVL velocity scale error and bias random walk, heading
// bias, depth offset (the drift the thesis corrects in sec. 6.2).
#include "sonar3d/sim/dead_reckoning.hpp"

#include <cmath>
#include <random>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void DeadReckoningConfig::validate() const {
  require(std::isfinite(velocity_scale_error) && std::abs(velocity_scale_error) < 0.5,
          "navigation_error.velocity_scale: must be within (-0.5, 0.5)");
  require_non_negative(velocity_bias_walk, "navigation_error.bias_walk", "m/s/√s");
  require(velocity_bias_walk <= 1.0, "navigation_error.bias_walk: at most 1 m/s/√s");
  require(std::isfinite(heading_bias_deg) && std::abs(heading_bias_deg) <= 180,
          "navigation_error.heading_bias_deg: must be within [-180, 180]");
  require(std::isfinite(depth_offset_m) && std::abs(depth_offset_m) <= 1e3,
          "navigation_error.depth_offset: must be finite, at most 1000 m");
}

Trajectory dead_reckoning(const Trajectory& truth, const DeadReckoningConfig& config,
                          unsigned long long seed) {
  config.validate();
  require(!truth.empty(), "dead reckoning: the trajectory is empty");
  std::mt19937_64 rng(seed ^ 0xD7EAD5EC0ull);
  std::normal_distribution<double> unit(0.0, 1.0);
  const Eigen::AngleAxisd yaw_bias(config.heading_bias_deg * M_PI / 180.0,
                                   Eigen::Vector3d::UnitZ());
  Trajectory out;
  Eigen::Vector3d p = truth.poses[0].translation();
  Eigen::Vector2d bias = Eigen::Vector2d::Zero();  // velocity bias, vehicle frame, m/s
  for (std::size_t k = 0; k < truth.size(); ++k) {
    if (k > 0) {
      const double dt = truth.times[k] - truth.times[k - 1];
      const Eigen::Matrix3d R_true = truth.poses[k - 1].linear();
      const Eigen::Vector3d d_world =
          truth.poses[k].translation() - truth.poses[k - 1].translation();
      // What the DVL measures, in the vehicle frame (scale error + bias), and the heading it is
      // rotated into the world with (true attitude + yaw bias).
      Eigen::Vector3d d_vehicle =
          (1.0 + config.velocity_scale_error) * (R_true.transpose() * d_world);
      bias += config.velocity_bias_walk * std::sqrt(dt) * Eigen::Vector2d(unit(rng), unit(rng));
      d_vehicle.head<2>() += bias * dt;
      const Eigen::Vector3d d_logged = yaw_bias * (R_true * d_vehicle);
      p.head<2>() += d_logged.head<2>();
    }
    // z from the depth sensor: absolute, with an offset (depth = −z).
    p.z() = truth.poses[k].translation().z() - config.depth_offset_m;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = yaw_bias * truth.poses[k].linear();
    T.translation() = p;
    out.push_back(truth.times[k], T);
  }
  return out;
}

}  // namespace sonar3d
