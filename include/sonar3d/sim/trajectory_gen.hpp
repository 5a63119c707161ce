#pragma once
// Vehicle trajectories for simulation: straight passes (the thesis' vertical inspection), orbits,
// lawnmower surveys, or a TUM file. Each generator returns T_world_vehicle samples, one per frame.
#include <Eigen/Geometry>
#include <string>

#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

// From `start` to `end` (world, m) with one frame every `spacing` metres (the vertical sampling
// period Δz for a vertical pass), constant orientation R_world_vehicle. Frames are `period`
// seconds apart starting at t0.
Trajectory straight_pass(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double spacing,
                         const Eigen::Matrix3d& R_world_vehicle, double t0, double period);

// A circle of `radius` around `center` at height center.z(), `count` frames, vehicle +x facing
// the centre (yaw only), starting at bearing `start_angle` (rad, about +z) and covering
// `sweep` rad (2π for a closed orbit; the last frame does not repeat the first).
Trajectory orbit(const Eigen::Vector3d& center, double radius, int count, double start_angle,
                 double sweep, double t0, double period);

// Back-and-forth lines along x over [x0, x1] at y = y0, y0 + line_spacing, ... <= y1, height z,
// one frame every `spacing` metres, vehicle heading along each line.
Trajectory lawnmower(double x0, double x1, double y0, double y1, double z, double line_spacing,
                     double spacing, double t0, double period);

}  // namespace sonar3d
