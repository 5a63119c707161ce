#include "sonar3d/core/sonar_spec.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/units.hpp"

namespace sonar3d {

double BeamPattern::amplitude(double theta, double theta_3db) const {
  switch (kind) {
    case Kind::Flat:
      // sec. 5.6.6: a flat pattern weighs every elevation inside the aperture equally.
      return std::abs(theta) <= theta_3db ? 1.0 : 0.0;
    case Kind::Table: {
      const auto& x = table_elevation_rad;
      const auto& y = table_amplitude;
      if (x.empty() || theta < x.front() || theta > x.back()) return 0.0;
      const auto it = std::upper_bound(x.begin(), x.end(), theta);
      if (it == x.end()) return y.back();
      const std::size_t i = static_cast<std::size_t>(it - x.begin());
      const double t = (theta - x[i - 1]) / (x[i] - x[i - 1]);
      return y[i - 1] + t * (y[i] - y[i - 1]);
    }
    case Kind::Sinc:
    default: {
      // eq. 2.8: B(θ) = |sin(κθ/θ_3dB) / (κθ/θ_3dB)|
      const double u = kKappa * theta / theta_3db;
      if (std::abs(u) < 1e-8) return 1.0;
      return std::abs(std::sin(u) / u);
    }
  }
}

namespace {
constexpr const char* kBeamPatternNames[] = {"sinc", "flat", "table"};  // by BeamPattern::Kind
}  // namespace

const char* BeamPattern::kind_name(Kind k) { return enum_name(kBeamPatternNames, k); }

BeamPattern::Kind BeamPattern::parse_kind(const std::string& s) {
  return parse_enum<Kind>(kBeamPatternNames, s, "the beam pattern");
}

int SonarSpec::bin_of_range(double r) const {
  if (!(r >= r_min) || !(r < r_max)) return -1;
  const int i = static_cast<int>((r - r_min) / range_resolution());
  return std::min(i, range_bins - 1);
}

double SonarSpec::beam_edge_low(int j) const {
  const auto& b = bearings_rad;
  if (b.size() == 1) return b[0] - 0.5 * vertical_aperture_rad;  // degenerate single beam
  if (j == 0) return b[0] - 0.5 * (b[1] - b[0]);
  return 0.5 * (b[j - 1] + b[j]);
}

double SonarSpec::beam_edge_high(int j) const {
  const auto& b = bearings_rad;
  const int n = beams();
  if (n == 1) return b[0] + 0.5 * vertical_aperture_rad;
  if (j == n - 1) return b[n - 1] + 0.5 * (b[n - 1] - b[n - 2]);
  return 0.5 * (b[j] + b[j + 1]);
}

int SonarSpec::beam_of_bearing(double phi) const {
  const int n = beams();
  if (n == 0 || !(phi >= fov_min()) || !(phi < fov_max())) return -1;
  if (n > 1) {
    // O(1) guess as if the table were uniform, verified against the cell's own edges: exact for
    // any table, with no cached uniformity flag that an in-place edit of the public bearings_rad
    // could leave stale. (Testing uniform_bearings() here made every call O(beams).)
    const double lo = fov_min();
    const double w = (fov_max() - lo) / n;
    const int j = std::clamp(static_cast<int>((phi - lo) / w), 0, n - 1);
    if (phi >= beam_edge_low(j) && phi < beam_edge_high(j)) return j;
  }
  // Non-uniform table (or a guess off by rounding at a cell edge): cell edges are midpoints, so
  // the owning beam is the nearest bearing.
  const auto it = std::lower_bound(bearings_rad.begin(), bearings_rad.end(), phi);
  int j = static_cast<int>(it - bearings_rad.begin());
  if (j == n) return n - 1;
  if (j > 0 && phi < beam_edge_low(j)) --j;  // the edge itself, not a distance test: consistent
  return j;
}

bool SonarSpec::uniform_bearings() const {
  const int n = beams();
  if (n < 3) return true;
  const double d = (bearings_rad.back() - bearings_rad.front()) / (n - 1);
  for (int j = 1; j < n; ++j) {
    if (std::abs(bearings_rad[j] - bearings_rad[0] - j * d) > 1e-9) return false;
  }
  return true;
}

void SonarSpec::set_uniform_bearings(double fov_rad, int count) {
  require_positive(fov_rad, "fov", "rad");
  require(count > 0 && count <= limits::kMaxBeams, "parameter 'beams' must lie in [1, " +
                                                       std::to_string(limits::kMaxBeams) +
                                                       "], got " + std::to_string(count));
  bearings_rad.resize(count);
  for (int j = 0; j < count; ++j) bearings_rad[j] = -0.5 * fov_rad + (j + 0.5) * fov_rad / count;
}

void SonarSpec::validate() const {
  const std::string where = "sonar '" + printable(name) + "': ";
  if (bearings_rad.empty()) throw Error(where + "no beams (bearings is empty)");
  if (bearings_rad.size() > static_cast<std::size_t>(limits::kMaxBeams)) {
    throw Error(where + "too many beams (" + std::to_string(bearings_rad.size()) +
                "; the limit is " + std::to_string(limits::kMaxBeams) + ")");
  }
  for (std::size_t j = 0; j < bearings_rad.size(); ++j) {
    if (!std::isfinite(bearings_rad[j]) || std::abs(bearings_rad[j]) >= M_PI) {
      throw Error(where + "bearing " + std::to_string(j) +
                  " is not a finite angle in (-180°, 180°)");
    }
    if (j > 0 && !(bearings_rad[j] > bearings_rad[j - 1])) {
      throw Error(where + "bearings must be strictly increasing (beam " + std::to_string(j) + ")");
    }
  }
  auto positive = [&](double v, const char* field, const char* unit) {
    if (!std::isfinite(v) || v <= 0) {
      std::ostringstream os;
      os << where << "'" << field << "' must be a finite number > 0 " << unit << ", got " << v;
      throw Error(os.str());
    }
  };
  positive(r_max, "r_max", "m");
  if (r_max > limits::kMaxRange) {
    std::ostringstream os;
    os << where << "'r_max' must be <= " << limits::kMaxRange << " m, got " << r_max;
    throw Error(os.str());
  }
  if (!std::isfinite(r_min) || r_min < 0) {
    throw Error(where + "'r_min' must be a finite number >= 0 m, got " + std::to_string(r_min));
  }
  if (!(r_max > r_min)) {
    throw Error(where + "'r_max' (" + std::to_string(r_max) + " m) must exceed 'r_min' (" +
                std::to_string(r_min) + " m)");
  }
  if (range_bins <= 0 || range_bins > limits::kMaxRangeBins) {
    throw Error(where + "'range_bins' must lie in [1, " + std::to_string(limits::kMaxRangeBins) +
                "], got " + std::to_string(range_bins));
  }
  if (static_cast<double>(range_bins) * static_cast<double>(bearings_rad.size()) >
      limits::kMaxPixels) {
    throw Error(where + "an image of " + std::to_string(range_bins) + " range bins × " +
                std::to_string(bearings_rad.size()) + " beams exceeds the limit of " +
                std::to_string(static_cast<long long>(limits::kMaxPixels)) + " pixels");
  }
  if (!std::isfinite(vertical_aperture_rad) ||
      vertical_aperture_rad < limits::kMinApertureDeg * kDeg || vertical_aperture_rad >= M_PI) {
    std::ostringstream os;
    os << where << "'vertical_aperture_deg' must lie in [" << limits::kMinApertureDeg
       << "°, 180°), got " << vertical_aperture_rad / kDeg << "°";
    throw Error(os.str());
  }
  if (beam_pattern.kind == BeamPattern::Kind::Table) {
    const auto& x = beam_pattern.table_elevation_rad;
    const auto& y = beam_pattern.table_amplitude;
    if (x.size() < 2 || x.size() != y.size()) {
      throw Error(where +
                  "beam_pattern table needs >= 2 elevation/amplitude pairs of equal length");
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || y[i] < 0 ||
          (i > 0 && !(x[i] > x[i - 1]))) {
        throw Error(where + "beam_pattern table entry " + std::to_string(i) +
                    " must be finite, amplitude >= 0, elevations increasing");
      }
    }
  }
  if (bit_depth != 8 && bit_depth != 16) {
    throw Error(where + "'bit_depth' must be 8 or 16, got " + std::to_string(bit_depth));
  }
  positive(intensity_scale, "intensity.scale", "");
  if (!T_vehicle_sonar.matrix().allFinite()) throw Error(where + "T_vehicle_sonar is not finite");
}

std::vector<std::string> sonar_preset_names() {
  return {"p900-130", "mb2250", "aris3000", "sim-1deg", "sim-10deg", "sim-20deg", "sim-30deg"};
}

SonarSpec sonar_preset(const std::string& name) {
  SonarSpec s;
  s.name = name;
  if (name == "p900-130") {
    // Table 4.4 and sec. 2.5.2: 130° × 20°, 768 beams, 2.5 cm range resolution, 7 m used range.
    s.set_uniform_bearings(130 * kDeg, 768);
    s.r_min = 0.5;
    s.r_max = 7.0;
    s.range_bins = 260;  // 6.5 m / 2.5 cm
    s.vertical_aperture_rad = 20 * kDeg;
  } else if (name == "mb2250") {
    // Tables 4.2–4.3: ±38.14° field of view, 512 image columns (0.15°), 1° vertical aperture,
    // 0.25–1.4 m at 0.6 cm (174 rows) in the tank settings.
    s.set_uniform_bearings(2 * 38.14 * kDeg, 512);
    s.r_min = 0.25;
    s.r_max = 1.4;
    s.range_bins = 174;
    s.vertical_aperture_rad = 1 * kDeg;
  } else if (name == "aris3000") {
    // Tables 4.2–4.3: ±15°, 128 beams, 14° vertical aperture, 0.67–1.66 m in 341 rows (0.3 cm).
    s.set_uniform_bearings(30 * kDeg, 128);
    s.r_min = 0.67;
    s.r_max = 1.66;
    s.range_bins = 341;
    s.vertical_aperture_rad = 14 * kDeg;
  } else if (name.rfind("sim-", 0) == 0 && (name == "sim-1deg" || name == "sim-10deg" ||
                                            name == "sim-20deg" || name == "sim-30deg")) {
    // sec. 4.5.2: simulated sensors with 2 cm range and 0.2° bearing resolution. The thesis does
    // not give their field of view or range window; we use 60° and 1–5 m (documented).
    const double ap = std::stod(name.substr(4));
    s.set_uniform_bearings(60 * kDeg, 300);
    s.r_min = 1.0;
    s.r_max = 5.0;
    s.range_bins = 200;
    s.vertical_aperture_rad = ap * kDeg;
  } else {
    std::string names;
    for (const auto& n : sonar_preset_names()) names += (names.empty() ? "" : ", ") + n;
    throw Error("unknown sonar preset '" + printable(name) + "' (known: " + names + ")");
  }
  return s;
}

}  // namespace sonar3d
