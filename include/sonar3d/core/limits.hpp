#pragma once
// Limits on sizes read from files and configurations (docs/formats.md, "Limits"). Every count
// that decides an allocation or a loop is checked against one of these, or against the length of
// the file it came from, before anything is allocated: a tiny hostile input must fail with one
// line naming the file or key, never exhaust the machine.
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <string>

#include "sonar3d/core/error.hpp"

namespace sonar3d::limits {

// Frames of one trajectory (a simulated or planned one): 1 million frames are 18.5 h at 15 Hz;
// the poses alone then take 136 MB.
constexpr double kMaxFrames = 1e6;
// Beams of a sonar (bearing table entries) and range bins of an image.
constexpr int kMaxBeams = 16384;
constexpr int kMaxRangeBins = 65534;
// Pixels of one sonar image (range bins × beams): 2^25 float32 pixels = 128 MB.
constexpr double kMaxPixels = 33554432.0;
// Vertical aperture: the narrowest one we accept, in degrees (real sensors: >= 0.5°).
constexpr double kMinApertureDeg = 0.01;
// Largest coordinate of a position (sonar pose, scene vertex, region corner), in metres:
// 10,000 km. Embree computes in float and asserts on bounds beyond ~1e18; a local ENU frame
// never needs more.
constexpr double kMaxCoordinate = 1e7;
// Largest range of a sonar, in metres.
constexpr double kMaxRange = 10000.0;
// Carving: the smallest voxel edge (m) and the largest number of the map's 32³-voxel cubes a
// single frame's footprint may touch (each costs a task and ~100 bytes while carving).
constexpr double kMinVoxelSize = 1e-5;
constexpr double kMaxCarveCubesPerFrame = 2097152.0;  // 2^21: ~210 MB of tasks
// JSON and YAML nesting depth.
constexpr int kMaxNestingDepth = 64;
// Text and JSON configuration files (Config.json, scene YAML): 64 MB.
constexpr std::size_t kMaxConfigBytes = 64u << 20;
// Memory the pickle decoder may use beyond what Python and numpy need to start: this budget plus
// 4 × the largest pickle file.
constexpr std::size_t kPickleBudgetBytes = 512u << 20;

// Checks a count computed from a configuration (e.g. length / spacing) before it is converted
// to an integer: NaN, infinities and values outside [min, max] throw
// "<what> is <value>, outside [min, max]; <advice>".
inline long long checked_count(double value, double min, double max, const std::string& what,
                               const std::string& advice) {
  if (!(value >= min && value <= max)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, " is %.6g, outside [%.0f, %.0f]; ", value, min, max);
    throw Error(what + buf + advice);
  }
  return static_cast<long long>(value);
}

}  // namespace sonar3d::limits
