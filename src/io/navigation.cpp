#include "sonar3d/io/navigation.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "text_fields.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

using text::lower;
using text::parse_number;
using text::skip_line;
using text::split_csv;
using text::trim;

// Column index of the first header name in `names`, or -1.
int column(const std::vector<std::string>& header, std::initializer_list<const char*> names) {
  for (std::size_t i = 0; i < header.size(); ++i) {
    for (const char* n : names) {
      if (lower(header[i]) == n) return static_cast<int>(i);
    }
  }
  return -1;
}

std::string fmt_time(double t) {
  std::ostringstream os;
  os << std::setprecision(10) << t;
  return os.str();
}

}  // namespace

NavConvention parse_nav_convention(const std::string& s) {
  return parse_enum<NavConvention>(kNavConventionNames, lower(s), "navigation convention");
}

const char* nav_convention_name(NavConvention c) { return enum_name(kNavConventionNames, c); }

Eigen::Isometry3d vehicle_pose_from_nav(const Eigen::Vector3d& xyz, double roll, double pitch,
                                        double yaw, NavConvention convention) {
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (convention == NavConvention::Enu) {
    T.linear() = R;
    T.translation() = xyz;
    return T;
  }
  // p_world = C·p_ned (north, east, down → east, north, up) and p_frd = D·p_flu, so
  // R_world_vehicle = C·R_ned_frd·D and t_world = C·t_ned. Both C and D are proper rotations.
  Eigen::Matrix3d C;
  C << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  const Eigen::Matrix3d D = Eigen::Vector3d(1, -1, -1).asDiagonal();
  T.linear() = C * R * D;
  T.translation() = C * xyz;
  return T;
}

Trajectory read_navigation_csv(const std::string& path, const NavCsvConfig& config) {
  std::error_code ec;
  if (fs::exists(path, ec) && !fs::is_regular_file(path, ec)) {
    throw Error("cannot read navigation file '" + path + "': not a regular file");
  }
  std::ifstream f(path);
  if (!f) throw Error("cannot open navigation file '" + path + "'");
  Trajectory traj;
  std::string line;
  int lineno = 0;
  std::vector<int> col;  // time x y z roll pitch yaw
  while (std::getline(f, line)) {
    ++lineno;
    if (skip_line(line)) continue;
    const std::string where = path + ":" + std::to_string(lineno);
    const std::vector<std::string> cells = split_csv(line);
    if (col.empty()) {
      col = {column(cells, {"time", "t", "timestamp"}),
             column(cells, {"x"}),
             column(cells, {"y"}),
             column(cells, {"z"}),
             column(cells, {"roll"}),
             column(cells, {"pitch"}),
             column(cells, {"yaw"})};
      if (std::count(col.begin(), col.end(), -1)) {
        throw Error(where +
                    ": expected a header naming the columns time, x, y, z, roll, pitch, "
                    "yaw (any order), got '" +
                    printable(trim(line)) + "'");
      }
      continue;
    }
    const int needed = *std::max_element(col.begin(), col.end()) + 1;
    if (static_cast<int>(cells.size()) < needed) {
      throw Error(where + ": expected at least " + std::to_string(needed) + " fields, got " +
                  std::to_string(cells.size()));
    }
    static const char* kNames[] = {"time", "x", "y", "z", "roll", "pitch", "yaw"};
    double v[7];
    for (int k = 0; k < 7; ++k) v[k] = parse_number(cells[col[k]], where, kNames[k]);
    if (!traj.empty() && !(v[0] > traj.times.back())) {
      throw Error(where + ": time " + fmt_time(v[0]) + " s is not after the previous sample (" +
                  fmt_time(traj.times.back()) + " s): navigation timestamps must increase");
    }
    const double s = config.angles == AngleUnit::Deg ? kDeg : 1.0;
    traj.push_back(v[0], vehicle_pose_from_nav(Eigen::Vector3d(v[1], v[2], v[3]), v[4] * s,
                                               v[5] * s, v[6] * s, config.convention));
  }
  if (col.empty()) throw Error(path + ": empty navigation file (no header)");
  if (traj.empty()) throw Error(path + ": the navigation file holds no sample");
  return traj;
}

Trajectory read_navigation(const std::string& path, const NavCsvConfig& csv,
                           const std::string& format) {
  std::string fmt = lower(format);
  if (fmt.empty()) {
    const std::string ext = lower(fs::path(path).extension().string());
    if (ext == ".csv") {
      fmt = "csv";
    } else if (ext == ".tum" || ext == ".txt") {
      fmt = "tum";
    } else {
      throw Error("navigation file '" + path + "': cannot tell the format from the extension '" +
                  ext + "'; name it .tum or .csv or give the format (tum, csv)");
    }
  }
  Trajectory traj;
  if (fmt == "csv") {
    traj = read_navigation_csv(path, csv);
  } else if (fmt == "tum") {
    traj = read_tum(path);
    if (traj.empty()) throw Error(path + ": the navigation file holds no pose");
  } else {
    throw Error("unknown navigation format '" + format + "' (expected 'tum' or 'csv')");
  }
  traj.validate(path);
  return traj;
}

SonarSpec read_sonar_description(const std::string& path) {
  const YAML::Node root = yaml::load_file(path);
  if (!root.IsMap()) throw Error(path + ": expected a mapping of sensor fields");
  if (root["sensor"]) return yaml::parse_sonar_spec(root["sensor"], path, "sensor");
  return yaml::parse_sonar_spec(root, path);
}

std::vector<FrameTime> read_frame_times(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw Error("cannot open frame list '" + path + "'");
  std::vector<FrameTime> out;
  std::string line;
  int lineno = 0, c_time = -1, c_file = -1;
  bool header = true;
  while (std::getline(f, line)) {
    ++lineno;
    if (skip_line(line)) continue;
    const std::string where = path + ":" + std::to_string(lineno);
    const std::vector<std::string> cells = split_csv(line);
    if (header) {
      header = false;
      c_time = column(cells, {"timestamp", "time", "t"});
      c_file = column(cells, {"file"});
      if (c_time < 0 || c_file < 0) {
        throw Error(where + ": expected the header 'timestamp,file', got '" +
                    printable(trim(line)) + "'");
      }
      continue;
    }
    if (static_cast<int>(cells.size()) <= std::max(c_time, c_file)) {
      throw Error(where + ": expected 'timestamp,file'");
    }
    FrameTime ft;
    ft.timestamp = parse_number(cells[c_time], where, "timestamp");
    ft.file = cells[c_file];
    ft.line = lineno;
    if (ft.file.empty()) throw Error(where + ": the file name is empty");
    if (!out.empty() && ft.timestamp < out.back().timestamp) {
      throw Error(where + ": timestamp " + fmt_time(ft.timestamp) + " s goes backwards (previous " +
                  "frame at " + fmt_time(out.back().timestamp) + " s)");
    }
    out.push_back(ft);
  }
  if (header) throw Error(path + ": empty frame list (no header)");
  if (out.empty()) throw Error(path + ": the frame list holds no frame");
  return out;
}

bool frame_inside_navigation(const Trajectory& nav, double t, bool drop_outside,
                             const std::string& what) {
  constexpr double kTol = 1e-6;  // s, as Trajectory::interpolate
  if (nav.empty()) throw Error(what + ": the navigation holds no pose");
  if (t >= nav.times.front() - kTol && t <= nav.times.back() + kTol) return true;
  if (drop_outside) return false;
  throw Error(what + " at t = " + fmt_time(t) + " s (navigation clock) is outside the " +
              "navigation span [" + fmt_time(nav.times.front()) + ", " +
              fmt_time(nav.times.back()) +
              "] s; poses are not extrapolated (drop such frames "
              "with --drop-outside, or shift the clock with --time-offset)");
}

Error no_frame_inside_navigation(const Trajectory& nav, const std::string& source) {
  return Error("no frame of '" + source + "' lies inside the navigation span [" +
               fmt_time(nav.times.front()) + ", " + fmt_time(nav.times.back()) +
               "] s: check the clocks (--time-offset)");
}

void check_navigation_format(const std::string& format, const std::string& what) {
  if (!format.empty() && format != "tum" && format != "csv") {
    throw Error(what + " must be tum, csv or empty (by the file's extension), got '" +
                printable(format) + "'");
  }
}

Eigen::Isometry3d mounting_from_list(const params::List& v, const std::string& what) {
  if (v.size() != 6) {
    throw Error(what + " must hold 6 numbers x,y,z,roll,pitch,yaw (m, degrees), got " +
                std::to_string(v.size()));
  }
  for (int k = 0; k < 6; ++k) {
    if (!std::isfinite(v[k]))
      throw Error(what + ": position " + std::to_string(k + 1) + " is not a finite number");
  }
  for (int k = 0; k < 3; ++k) {
    if (std::abs(v[k]) > limits::kMaxCoordinate) {
      throw Error(what + ": offset beyond " + params::format_number(limits::kMaxCoordinate) + " m");
    }
  }
  return vehicle_pose_from_nav(Eigen::Vector3d(v[0], v[1], v[2]), v[3] * kDeg, v[4] * kDeg,
                               v[5] * kDeg, NavConvention::Enu);
}

params::List parse_mounting_list(const std::string& text) {
  params::List v;
  std::string cell;
  std::istringstream is(text);
  while (std::getline(is, cell, ',')) {
    std::size_t used = 0;
    double x = 0;
    try {
      x = std::stod(cell, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    while (used < cell.size() && std::isspace(static_cast<unsigned char>(cell[used]))) ++used;
    if (cell.empty() || used != cell.size() || !std::isfinite(x)) {
      throw Error("mounting '" + printable(text) + "': '" + printable(cell) + "' is not a number");
    }
    v.push_back(x);
  }
  if (v.size() != 6) {
    throw Error("mounting '" + printable(text) +
                "': expected 6 numbers x,y,z,roll,pitch,yaw (m, degrees)");
  }
  for (int k = 0; k < 3; ++k) {
    if (std::abs(v[k]) > limits::kMaxCoordinate) {
      throw Error("mounting '" + printable(text) + "': offset beyond " +
                  params::format_number(limits::kMaxCoordinate) + " m");
    }
  }
  return v;
}

void FrameImportConfig::validate() const {
  params::check(*this, "frames import:");
  if (images_dir.empty()) throw Error("frames import: 'images_dir' is not set");
  if (times_csv.empty()) throw Error("frames import: 'times_csv' is not set");
  if (navigation.empty()) throw Error("frames import: 'navigation' is not set");
  if (!std::isfinite(time_offset)) throw Error("frames import: 'time_offset' must be finite");
  check_navigation_format(navigation_format, "frames import: navigation_format");
  spec.validate();
}

FrameImportResult import_frames(const FrameImportConfig& config, const fs::path& out,
                                bool progress) {
  config.validate();
  if (!fs::is_directory(config.images_dir)) {
    throw Error("images directory '" + config.images_dir + "' does not exist");
  }
  const Trajectory nav =
      read_navigation(config.navigation, config.navigation_csv, config.navigation_format);
  const std::vector<FrameTime> times = read_frame_times(config.times_csv);
  bool tiff = false;
  for (const auto& ft : times) {
    const std::string ext = lower(fs::path(ft.file).extension().string());
    tiff = tiff || ext == ".tif" || ext == ".tiff";
  }
  FrameImportResult res;
  res.navigation_samples = nav.size();
  DatasetWriter writer(out, config.spec,
                       tiff ? DatasetWriter::ImageFormat::Tiff : DatasetWriter::ImageFormat::Png);
  Progress bar("import", times.size(), progress);
  for (const FrameTime& ft : times) {
    const double t = ft.timestamp + config.time_offset;
    if (!frame_inside_navigation(
            nav, t, config.drop_outside,
            config.times_csv + ":" + std::to_string(ft.line) + ": frame '" + ft.file + "'")) {
      ++res.dropped;
      bar.add();
      continue;
    }
    SonarImage img =
        read_sonar_image((fs::path(config.images_dir) / ft.file).string(), config.spec);
    img.timestamp = t;
    writer.add_frame(img);
    if (res.frames == 0) res.first_time = t;
    res.last_time = t;
    ++res.frames;
    bar.add();
  }
  bar.finish();
  if (res.frames == 0) throw no_frame_inside_navigation(nav, config.times_csv);
  writer.set_navigation(nav);
  writer.commit();
  return res;
}

}  // namespace sonar3d
