#pragma once
// Navigation logs and sonar frames recorded on their own clock, turned into a dataset v1
// (docs/import.md). Navigation comes as TUM (our format: T_world_vehicle) or as CSV
// (time, x, y, z, roll, pitch, yaw) in a declared convention; frame poses are then the navigation
// interpolated at each frame time (linear + slerp, thesis sec. 4.6.1) times the sonar mounting
// T_vehicle_sonar, as Dataset::T_world_sonar computes them.
#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

// The frame convention of a navigation CSV.
enum class NavConvention {
  // World x east, y north, z up; vehicle x forward, y left, z up (ROS REP 103). Attitude
  // R_world_vehicle = Rz(yaw)·Ry(pitch)·Rx(roll), yaw counter-clockwise from east. This is our own
  // world frame, so poses are taken as they are.
  Enu,
  // World x north, y east, z down; vehicle x forward, y right (starboard), z down, as INS and
  // DVL navigation report. R_ned_frd = Rz(yaw)·Ry(pitch)·Rx(roll): yaw = heading clockwise from
  // north, pitch positive nose up, roll positive starboard down. Converted to our world (x east,
  // y north, z up) and vehicle frame (x forward, y left, z up).
  Ned,
};
NavConvention parse_nav_convention(const std::string& s);  // "enu" | "ned"; throws Error
const char* nav_convention_name(NavConvention c);
inline constexpr const char* kNavConventionNames[] = {"enu", "ned"};  // by NavConvention

// The unit of a navigation CSV's roll, pitch and yaw.
enum class AngleUnit { Deg, Rad };
inline constexpr const char* kAngleUnitNames[] = {"deg", "rad"};  // by AngleUnit

struct NavCsvConfig {
  NavConvention convention = NavConvention::Enu;
  AngleUnit angles = AngleUnit::Deg;  // of roll, pitch, yaw
};

// The one declaration of NavCsvConfig's fields (core/params.hpp).
template <class V>
void describe(NavCsvConfig& c, V& v) {
  using params::param;
  v.field(c.convention,
          param("convention", "",
                "frames of a navigation CSV: 'enu' (x east, y north, z up; vehicle x forward, y "
                "left, z up; yaw counter-clockwise from east) or 'ned' (x north, y east, z down; "
                "vehicle x forward, y starboard, z down; heading clockwise from north)")
              .choices(kNavConventionNames)
              .flag("--nav-convention"));
  v.field(c.angles, param("angles", "", "unit of a navigation CSV's roll, pitch and yaw")
                        .choices(kAngleUnitNames)
                        .flag("--angles"));
}

// Navigation file formats: "" (by extension: .csv, else TUM), "tum" or "csv". Throws Error naming
// `what` (the flag or key) for anything else.
void check_navigation_format(const std::string& format, const std::string& what);

// The sonar mounting T_vehicle_sonar declared as six numbers: x, y, z (m), roll, pitch, yaw
// (degrees; R = Rz(yaw)·Ry(pitch)·Rx(roll), vehicle x forward, y left, z up). Throws Error naming
// `what` (the flag or key) when it is not six finite numbers with offsets within reach.
Eigen::Isometry3d mounting_from_list(const params::List& m, const std::string& what);
// "x,y,z,roll,pitch,yaw" as that list. Throws Error naming the text.
params::List parse_mounting_list(const std::string& text);
inline const params::List kNoMounting = {0, 0, 0, 0, 0, 0};

// T_world_vehicle (our world: z up, FLU vehicle) of one navigation sample given in `convention`;
// angles in radians.
Eigen::Isometry3d vehicle_pose_from_nav(const Eigen::Vector3d& xyz, double roll, double pitch,
                                        double yaw, NavConvention convention);

// A navigation CSV: a header line naming the columns time (or t, timestamp), x, y, z, roll,
// pitch, yaw in any order (other columns are ignored), then one sample a line; '#' comments and
// blank lines are skipped. Times in seconds, strictly increasing. Errors name the file and line.
Trajectory read_navigation_csv(const std::string& path, const NavCsvConfig& config);

// TUM (".tum", ".txt") or CSV (".csv") by extension, or by `format` ("tum" | "csv") when given.
Trajectory read_navigation(const std::string& path, const NavCsvConfig& csv = {},
                           const std::string& format = "");

// The sensor description of a frames import: a YAML file holding the sensor fields of sonar.yaml
// (as in docs/formats.md, optionally starting from `preset:`), either at the top level or under
// `sensor:` (so a dataset's own sonar.yaml works). T_vehicle_sonar is the mounting.
SonarSpec read_sonar_description(const std::string& path);

// The timing rule shared by every import that puts frames onto a navigation log (frames, aris,
// rosbag): a frame at time t (navigation clock) gets a pose only inside the navigation span
// [front, back] (1 µs tolerance, as Trajectory::interpolate); poses are never extrapolated.
// Returns true inside; outside, returns false when `drop_outside` (the caller drops and counts
// the frame), else throws Error "<what> at t = … s (navigation clock) is outside the navigation
// span […] s; …" with the advice of the import commands.
bool frame_inside_navigation(const Trajectory& nav, double t, bool drop_outside,
                             const std::string& what);
// The Error of an import whose frames all fell outside the navigation span: names `source`.
Error no_frame_inside_navigation(const Trajectory& nav, const std::string& source);

struct FrameTime {
  double timestamp = 0;  // s, on the frame clock
  std::string file;      // relative to the images directory
  int line = 0;          // in the times file, for errors
};
// A frame list CSV with the header "timestamp,file" (either order); timestamps must not go
// backwards. Errors name the file and line.
std::vector<FrameTime> read_frame_times(const std::string& path);

struct FrameImportConfig {
  std::string images_dir;         // frame images: PNG (8/16-bit, scaled by the sensor's
                                  // intensity scale) or float32 TIFF, range bins × beams
  std::string times_csv;          // timestamp,file per frame
  std::string navigation;         // TUM or CSV (T_world_vehicle)
  std::string navigation_format;  // "" (by extension), "tum" or "csv"
  NavCsvConfig navigation_csv;
  // The sensor (a sonar.yaml, with the mounting T_vehicle_sonar): not a declared setting, the
  // command's --sonar file (read_sonar_description) or Python's `sonar`.
  SonarSpec spec;
  double time_offset = 0;  // s added to frame timestamps to reach the navigation clock
  // Frames outside the navigation span: an error naming the first (false), or dropped and
  // counted (true). Poses are never extrapolated.
  bool drop_outside = false;
  void validate() const;  // throws Error naming the field
};

// The one declaration of FrameImportConfig's fields (core/params.hpp); `spec` is the sensor file.
template <class V>
void describe(FrameImportConfig& c, V& v) {
  using params::param;
  v.field(
      c.images_dir,
      param("images_dir", "", "directory of frame images (PNG or float32 TIFF)").flag("--images"));
  v.field(
      c.times_csv,
      param("times_csv", "", "CSV 'timestamp,file' (file relative to images_dir)").flag("--times"));
  v.field(c.navigation, param("navigation", "",
                              "navigation: TUM (t tx ty tz qx qy qz qw, T_world_vehicle) or CSV "
                              "(time,x,y,z,roll,pitch,yaw)")
                            .flag("--nav"));
  v.field(c.navigation_format,
          param("navigation_format", "", "tum or csv; empty: by the file's extension")
              .flag("--nav-format"));
  v.group("navigation_csv", c.navigation_csv);
  v.field(c.time_offset,
          param("time_offset", "s", "added to frame timestamps to reach the navigation clock")
              .flag("--time-offset"));
  v.field(c.drop_outside,
          param("drop_outside", "",
                "drop (and count) frames outside the navigation span instead of failing")
              .flag("--drop-outside"));
}

struct FrameImportResult {
  std::size_t frames = 0;   // written
  std::size_t dropped = 0;  // outside the navigation span (drop_outside)
  std::size_t navigation_samples = 0;
  double first_time = 0, last_time = 0;  // s, written frames on the navigation clock
};

// Writes the dataset at `out` atomically (nothing is left there on error).
FrameImportResult import_frames(const FrameImportConfig& config, const std::filesystem::path& out,
                                bool progress = false);

}  // namespace sonar3d
