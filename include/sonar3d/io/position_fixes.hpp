#pragma once
// Absolute position fixes (USBL, GNSS at the surface) with their standard deviation: the
// absolute references of field mapping (docs/formats.md "Position fixes", docs/mapping.md).
//
// Frames: the navigation's world frame, local ENU (x East, y North, z up), metres; times on the
// navigation clock, seconds.
//
// CSV (".csv"): a header naming the columns time_s, x_m, y_m, sigma_m and optionally z_m (any
// order; also time/t, x, y, z, sigma; other columns are ignored), then one fix a line; '#'
// comments and blank lines are skipped. sigma_m is the fix's horizontal (and, with z_m, vertical)
// standard deviation, one per axis.
//   time_s,x_m,y_m,sigma_m
//   120.0,14.82,-3.10,1.0
// TUM (".tum", ".txt"): "t x y z qx qy qz qw" a line (the orientation is ignored), every fix with
// the one σ given by the caller (`sonar3d map --fix-sigma`), z taken.
//
// Refused, with one line naming the file, line and column: a field that is not a number, NaN or
// infinite values, σ ≤ 0 or above kMaxFixSigma, coordinates beyond limits::kMaxCoordinate, times
// that do not strictly increase (unsorted or duplicated), more than kMaxFixes fixes, a file larger
// than kMaxFixFileBytes.
#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

namespace sonar3d {

struct PositionFix {
  double time = 0;                              // s, navigation clock
  Eigen::Vector3d p = Eigen::Vector3d::Zero();  // world (ENU), m
  bool has_z = false;                           // z given (else only x, y constrain)
  double sigma_m = 1;                           // standard deviation per axis, m
  int line = 0;                                 // in the file, for reports
};

constexpr double kMaxFixSigma = 1e4;                            // m
constexpr std::size_t kMaxFixes = 10'000'000;                   // 1 Hz for 115 days
constexpr std::size_t kMaxFixFileBytes = std::size_t(1) << 30;  // 1 GiB

enum class FixFormat { Auto, Csv, Tum };

// Parses `text` as the fixes file `name` (used in errors). Auto: TUM when `name` ends in .tum or
// .txt, else CSV. `tum_sigma_m` is the σ of TUM fixes (must then be > 0). Throws Error.
std::vector<PositionFix> parse_position_fixes(const std::string& text, const std::string& name,
                                              FixFormat format = FixFormat::Auto,
                                              double tum_sigma_m = 0);
std::vector<PositionFix> read_position_fixes(const std::string& path,
                                             FixFormat format = FixFormat::Auto,
                                             double tum_sigma_m = 0);

}  // namespace sonar3d
