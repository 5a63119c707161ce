#include "sonar3d/sim/trajectory_gen.hpp"

#include <cmath>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

Trajectory straight_pass(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double spacing,
                         const Eigen::Matrix3d& R_world_vehicle, double t0, double period) {
  require_positive(spacing, "trajectory.spacing", "m");
  require_positive(period, "trajectory.period", "s");
  require(start.allFinite() && end.allFinite(), "trajectory: start and end must be finite");
  require(start.cwiseAbs().maxCoeff() <= limits::kMaxCoordinate &&
              end.cwiseAbs().maxCoeff() <= limits::kMaxCoordinate,
          "trajectory: start and end coordinates must lie within ±1e7 m");
  const double length = (end - start).norm();
  // Frames at 0, Δ, 2Δ ... up to the end (inclusive within 1e-9 of a step). Counted in double:
  // length / spacing overflows an int for a tiny spacing.
  const int n = static_cast<int>(limits::checked_count(
      std::floor(length / spacing + 1e-9) + 1, 1, limits::kMaxFrames,
      "trajectory: the frame count (length / spacing + 1)", "increase 'spacing'"));
  const Eigen::Vector3d dir =
      length > 0 ? Eigen::Vector3d((end - start) / length) : Eigen::Vector3d::Zero();
  Trajectory traj;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R_world_vehicle;
    T.translation() = start + dir * (k * spacing);
    traj.push_back(t0 + k * period, T);
  }
  return traj;
}

Trajectory orbit(const Eigen::Vector3d& center, double radius, int count, double start_angle,
                 double sweep, double t0, double period) {
  require_positive(radius, "trajectory.radius", "m");
  require_positive(period, "trajectory.period", "s");
  require(count >= 1, "parameter 'trajectory.count' must be >= 1");
  limits::checked_count(count, 1, limits::kMaxFrames, "parameter 'trajectory.count'",
                        "use fewer frames");
  require(center.allFinite() && center.cwiseAbs().maxCoeff() + radius <= limits::kMaxCoordinate,
          "trajectory: the orbit must lie within ±1e7 m");
  require(std::isfinite(start_angle) && std::isfinite(sweep) && sweep != 0.0,
          "trajectory: orbit angles must be finite and the sweep non-zero");
  const bool closed = std::abs(std::abs(sweep) - 2 * M_PI) < 1e-9;
  Trajectory traj;
  for (int k = 0; k < count; ++k) {
    const double a = start_angle + sweep * k / (closed || count == 1 ? count : count - 1);
    const Eigen::Vector3d p = center + radius * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    // Face the centre: heading a + π about +z.
    T.linear() = Eigen::AngleAxisd(a + M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = p;
    traj.push_back(t0 + k * period, T);
  }
  return traj;
}

namespace {

// One piece of a planar track, parameterised by arc length: a straight line from a to b, or an
// arc of radius r about c from angle a0 through the signed angle sweep (rad, > 0 anticlockwise).
struct TrackPiece {
  bool arc = false;
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  double r = 0, a0 = 0, sweep = 0;

  double length() const { return arc ? r * std::abs(sweep) : (b - a).norm(); }
  // Position and direction of travel (yaw about +z) at arc length s along the piece.
  void at(double s, Eigen::Vector2d& p, double& yaw) const {
    if (!arc) {
      const Eigen::Vector2d d = b - a;
      const double len = d.norm();
      p = len > 0 ? Eigen::Vector2d(a + d * (s / len)) : a;
      yaw = std::atan2(d.y(), d.x());
      return;
    }
    const double sign = sweep > 0 ? 1.0 : -1.0;
    const double ang = a0 + sign * s / r;
    p = c + r * Eigen::Vector2d(std::cos(ang), std::sin(ang));
    yaw = ang + sign * M_PI / 2;  // the tangent, in the direction of travel
  }
};

TrackPiece line_piece(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  TrackPiece t;
  t.a = a;
  t.b = b;
  return t;
}

TrackPiece arc_piece(const Eigen::Vector2d& c, double r, double a0, double sweep) {
  TrackPiece t;
  t.arc = true;
  t.c = c;
  t.r = r;
  t.a0 = a0;
  t.sweep = sweep;
  return t;
}

}  // namespace

void LawnmowerConfig::validate() const {
  require(std::isfinite(x0) && std::isfinite(x1) && std::isfinite(y0) && std::isfinite(y1) &&
              std::isfinite(z) && std::isfinite(heading),
          "trajectory: lawnmower x, y, z and heading must be finite");
  require(x1 > x0 && y1 >= y0, "trajectory: lawnmower area needs x1 > x0 and y1 >= y0");
  require_positive(line_spacing, "trajectory.line_spacing", "m");
  require_positive(spacing, "trajectory.spacing", "m");
  require(std::isfinite(turn_radius) && turn_radius >= 0,
          "parameter 'trajectory.turn_radius' must be >= 0 m (0: jump between lines)");
  require(turn_radius <= line_spacing / 2 * (1 + 1e-12),
          "parameter 'trajectory.turn_radius' (" + std::to_string(turn_radius) +
              " m) must be at most line_spacing / 2 (" + std::to_string(line_spacing / 2) +
              " m): a vehicle turning wider cannot reach the next line with two quarter turns");
  const double reach = std::max({std::abs(x0), std::abs(x1), std::abs(y0), std::abs(y1)}) +
                       std::hypot(x1 - x0, y1 - y0) + turn_radius;
  require(reach <= limits::kMaxCoordinate && std::abs(z) <= limits::kMaxCoordinate,
          "trajectory: the lawnmower must lie within ±1e7 m");
}

Trajectory lawnmower(const LawnmowerConfig& c, double t0, double period) {
  c.validate();
  require_positive(period, "trajectory.period", "s");
  // Lines counted up front: `y += line_spacing` never moves y when the spacing is below its
  // rounding step (1e-300: an endless loop).
  const long long lines = limits::checked_count(
      std::floor((c.y1 - c.y0) / c.line_spacing + 1e-9) + 1, 1, limits::kMaxFrames,
      "trajectory: the line count ((y1 - y0) / line_spacing + 1)", "increase 'line_spacing'");
  const double R = c.turn_radius;
  // The track in the survey frame, line by line with its turns.
  std::vector<TrackPiece> pieces;
  for (long long line = 0; line < lines; ++line) {
    const double y = c.y0 + static_cast<double>(line) * c.line_spacing;
    const bool forward = (line % 2 == 0);
    pieces.push_back(line_piece({forward ? c.x0 : c.x1, y}, {forward ? c.x1 : c.x0, y}));
    if (R <= 0 || line + 1 == lines) continue;
    const double y_next = y + c.line_spacing;
    // Beyond the line's end: a quarter circle towards +y, the leg across, a quarter circle back.
    if (forward) {
      pieces.push_back(arc_piece({c.x1, y + R}, R, -M_PI / 2, M_PI / 2));
      pieces.push_back(line_piece({c.x1 + R, y + R}, {c.x1 + R, y_next - R}));
      pieces.push_back(arc_piece({c.x1, y_next - R}, R, 0.0, M_PI / 2));
    } else {
      pieces.push_back(arc_piece({c.x0, y + R}, R, -M_PI / 2, -M_PI / 2));
      pieces.push_back(line_piece({c.x0 - R, y + R}, {c.x0 - R, y_next - R}));
      pieces.push_back(arc_piece({c.x0, y_next - R}, R, M_PI, -M_PI / 2));
    }
  }
  // Frames: with turns, every `spacing` metres along the whole track; without, every line
  // sampled from its own start (the vehicle jumps between lines).
  std::vector<std::pair<std::size_t, double>> samples;  // (piece, arc length within it)
  if (R > 0) {
    double total = 0;
    for (const TrackPiece& p : pieces) total += p.length();
    const long long n = limits::checked_count(
        std::floor(total / c.spacing + 1e-9) + 1, 1, limits::kMaxFrames,
        "trajectory: the frame count (track length / spacing + 1)", "increase 'spacing'");
    samples.reserve(static_cast<std::size_t>(n));
    std::size_t k = 0;
    double before = 0;  // track length before piece k
    for (long long i = 0; i < n; ++i) {
      const double s = static_cast<double>(i) * c.spacing;
      while (k + 1 < pieces.size() && s > before + pieces[k].length())
        before += pieces[k++].length();
      samples.emplace_back(k, std::min(s - before, pieces[k].length()));
    }
  } else {
    const double per_line = std::floor((c.x1 - c.x0) / c.spacing + 1e-9) + 1;
    limits::checked_count(per_line * static_cast<double>(lines), 1, limits::kMaxFrames,
                          "trajectory: the frame count (lines × frames per line)",
                          "increase 'spacing' or 'line_spacing'");
    for (std::size_t k = 0; k < pieces.size(); ++k) {
      for (long long i = 0; i < static_cast<long long>(per_line); ++i) {
        samples.emplace_back(k, static_cast<double>(i) * c.spacing);
      }
    }
  }
  // Into the world: turned by `heading` about +z through the rectangle's centre.
  const Eigen::Vector2d centre(0.5 * (c.x0 + c.x1), 0.5 * (c.y0 + c.y1));
  const Eigen::Rotation2Dd turn(c.heading);
  Trajectory traj;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    Eigen::Vector2d p;
    double yaw = 0;
    pieces[samples[i].first].at(samples[i].second, p, yaw);
    const Eigen::Vector2d w = centre + turn * (p - centre);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw + c.heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(w.x(), w.y(), c.z);
    traj.push_back(t0 + static_cast<double>(i) * period, T);
  }
  return traj;
}

}  // namespace sonar3d
