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

// A lawnmower survey: back-and-forth lines covering a rectangle, the way an AUV flies one.
// The rectangle is given in the survey's own frame (lines along its x over [x0, x1], one every
// `line_spacing` metres in y from y0 to y1) and then turned by `heading` about +z through its
// centre, so the lines run along any heading. The vehicle heads along each line (yaw = heading,
// +π on return lines) at height z, one frame every `spacing` metres.
//
// Turns: with turn_radius 0 the vehicle jumps from one line's end to the next line's start (no
// frames in between, the idealised survey). With turn_radius R > 0 it turns outside the rectangle
// as a vehicle does — a quarter circle of radius R, a straight leg across the lines of
// line_spacing − 2R, another quarter circle — recording frames all along at the same spacing, its
// yaw following the track. R must be at most line_spacing / 2.
struct LawnmowerConfig {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;  // m, the rectangle in the survey frame
  double z = 0;                           // m, vehicle height (world)
  double line_spacing = 0;                // m, between lines (> 0)
  double spacing = 0;                     // m, between frames along the track (> 0)
  double heading = 0;                     // rad, direction of the lines about +z (0: along +x)
  double turn_radius = 0;                 // m, 0: jump between lines
  void validate() const;                  // throws Error naming the parameter
};

// Frames are `period` seconds apart starting at t0.
Trajectory lawnmower(const LawnmowerConfig& config, double t0, double period);

}  // namespace sonar3d
