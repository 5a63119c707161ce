#pragma once
// The description of a 2D imaging sonar: bearing table, range binning, vertical aperture and beam
// pattern (thesis sec. 2.2.8 and 2.4.1), intensity encoding and mounting on the vehicle.
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace sonar3d {

// Vertical beam pattern B(θ). Amplitude, not power: pixel intensities weight returns by B(θ)².
struct BeamPattern {
  enum class Kind { Sinc, Flat, Table };
  Kind kind = Kind::Sinc;
  // Kind::Table: amplitude samples at increasing elevation angles (rad), linearly interpolated,
  // zero outside the table.
  std::vector<double> table_elevation_rad;
  std::vector<double> table_amplitude;

  // κ such that B(θ_3dB)² = ½ (eq. 2.8; the thesis rounds it to 1.389).
  static constexpr double kKappa = 1.39156;

  // Amplitude at elevation theta_rad for a pattern whose half-power half-width is theta_3db_rad.
  double amplitude(double theta_rad, double theta_3db_rad) const;
  double power(double theta_rad, double theta_3db_rad) const {
    const double b = amplitude(theta_rad, theta_3db_rad);
    return b * b;
  }
  static const char* kind_name(Kind k);
  static Kind parse_kind(const std::string& s);  // throws Error naming the accepted values
};

struct SonarSpec {
  std::string name = "sonar";
  // Beam bearings φ in rad, strictly increasing (column j of an image is bearings[j]).
  std::vector<double> bearings_rad;
  double r_min = 0.5;      // m, near edge of range bin 0
  double r_max = 7.0;      // m, far edge of the last range bin
  int range_bins = 325;    // rows of an image
  double vertical_aperture_rad = 0.3490658503988659;  // A_v = 2·θ_3dB (full width)
  BeamPattern beam_pattern;
  int bit_depth = 16;      // 8 or 16: quantisation of stored frames
  // Stored integer value v maps to linear intensity v · intensity_scale.
  double intensity_scale = 1.0 / 65535.0;
  Eigen::Isometry3d T_vehicle_sonar = Eigen::Isometry3d::Identity();

  int beams() const { return static_cast<int>(bearings_rad.size()); }
  double range_resolution() const { return (r_max - r_min) / range_bins; }
  double theta_3db() const { return 0.5 * vertical_aperture_rad; }
  // Centre of range bin i: r_min + (i + 0.5)·Δr.
  double range_of_bin(int i) const { return r_min + (i + 0.5) * range_resolution(); }
  // Bin containing range r, or -1 outside [r_min, r_max).
  int bin_of_range(double r) const;
  // Beam whose bearing cell contains phi (cell edges halfway between bearings; the outer cells
  // extend by half the neighbouring spacing), or -1 outside the field of view.
  int beam_of_bearing(double phi_rad) const;
  // Lower and upper bearing edges of beam j's cell.
  double beam_edge_low(int j) const;
  double beam_edge_high(int j) const;
  double fov_min() const { return beams() ? beam_edge_low(0) : 0.0; }
  double fov_max() const { return beams() ? beam_edge_high(beams() - 1) : 0.0; }
  double max_intensity_value() const { return (bit_depth == 8 ? 255.0 : 65535.0); }

  // Throws Error naming the first invalid field (non-finite, non-positive, aperture outside
  // (0°, 180°), non-increasing bearings...).
  void validate() const;

  // Fills bearings_rad with `count` beams uniformly spanning a field of view of fov_rad centred
  // on the boresight (bearing of beam j: -fov/2 + (j+0.5)·fov/count).
  void set_uniform_bearings(double fov_rad, int count);
  // True when bearings are uniform within 1e-9 rad.
  bool uniform_bearings() const;
};

// Sensor presets: "p900-130", "mb2250", "aris3000", "sim-1deg", "sim-10deg", "sim-20deg",
// "sim-30deg" (thesis Tables 4.2–4.4, Appendix A, sec. 4.5.2). Throws Error listing the names on
// an unknown preset.
SonarSpec sonar_preset(const std::string& name);
std::vector<std::string> sonar_preset_names();

}  // namespace sonar3d
