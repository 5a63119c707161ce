// COLMAP text models: cameras.txt and images.txt, read and written.
#include "sonar3d/video/colmap.hpp"

#include <fmt/core.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

namespace {

std::vector<std::string> tokens(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  for (std::string t; in >> t;) out.push_back(t);
  return out;
}

double number(const std::string& t, const std::string& where, const char* what) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end == t.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) {
    throw Error(where + ": " + what + " '" + printable(t) + "' is not a finite number");
  }
  return v;
}

int integer(const std::string& t, const std::string& where, const char* what) {
  errno = 0;
  char* end = nullptr;
  const long v = std::strtol(t.c_str(), &end, 10);
  if (end == t.c_str() || *end != '\0' || errno == ERANGE || v < 0 || v > 2147483647L) {
    throw Error(where + ": " + what + " '" + printable(t) + "' is not an integer 0 … 2^31 − 1");
  }
  return static_cast<int>(v);
}

// The line after its first `skip` whitespace-separated tokens, trimmed.
std::string rest_after(const std::string& line, int skip) {
  std::size_t i = 0;
  auto space = [](char ch) { return ch == ' ' || ch == '\t' || ch == '\r'; };
  for (int k = 0; k < skip; ++k) {
    while (i < line.size() && space(line[i])) ++i;
    while (i < line.size() && !space(line[i])) ++i;
  }
  while (i < line.size() && space(line[i])) ++i;
  std::size_t end = line.size();
  while (end > i && space(line[end - 1])) --end;
  return line.substr(i, end - i);
}

std::ifstream open_text(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw Error("cannot read '" + p.string() + "' (a COLMAP text model needs it)");
  return in;
}

// The camera models sonar3d's pinhole + OpenCV distortion can hold: (name, parameter count).
CameraIntrinsics camera_from(const std::string& model, const std::vector<double>& p,
                             const std::string& where) {
  static const std::map<std::string, std::size_t> counts = {
      {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4}, {"SIMPLE_RADIAL", 4},
      {"RADIAL", 5},         {"OPENCV", 8},  {"FULL_OPENCV", 12}};
  const auto it = counts.find(model);
  if (it == counts.end()) {
    throw Error(where + ": camera model '" + printable(model) +
                "' is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, "
                "FULL_OPENCV)");
  }
  if (p.size() != it->second) {
    throw Error(fmt::format("{}: camera model {} takes {} parameters, found {}", where, model,
                            it->second, p.size()));
  }
  CameraIntrinsics c;
  const bool one_f = model == "SIMPLE_PINHOLE" || model == "SIMPLE_RADIAL" || model == "RADIAL";
  c.fx = p[0];
  c.fy = one_f ? p[0] : p[1];
  c.cx = (one_f ? p[1] : p[2]) - 0.5;  // COLMAP's top-left pixel centre is (0.5, 0.5)
  c.cy = (one_f ? p[2] : p[3]) - 0.5;
  if (model == "SIMPLE_RADIAL") c.k1 = p[3];
  if (model == "RADIAL") {
    c.k1 = p[3];
    c.k2 = p[4];
  }
  if (model == "OPENCV" || model == "FULL_OPENCV") {
    c.k1 = p[4];
    c.k2 = p[5];
    c.p1 = p[6];
    c.p2 = p[7];
  }
  if (model == "FULL_OPENCV") {
    c.k3 = p[8];
    if (p[9] != 0 || p[10] != 0 || p[11] != 0) {
      throw Error(where +
                  ": FULL_OPENCV with k4, k5, k6 ≠ 0 (OpenCV's rational model) is not "
                  "supported");
    }
  }
  return c;
}

}  // namespace

PosedImages read_colmap_text(const fs::path& dir) {
  PosedImages out;
  const fs::path cam_path = dir / "cameras.txt", img_path = dir / "images.txt";
  {
    std::ifstream in = open_text(cam_path);
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      const std::vector<std::string> t = tokens(line);
      if (t.empty() || t[0][0] == '#') continue;
      const std::string where = cam_path.string() + ":" + std::to_string(n);
      if (t.size() < 4) throw Error(where + ": expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
      const int id = integer(t[0], where, "CAMERA_ID");
      std::vector<double> p;
      for (std::size_t k = 4; k < t.size() && k < 20; ++k)
        p.push_back(number(t[k], where, "a parameter"));
      if (t.size() >= 20) throw Error(where + ": too many camera parameters");
      CameraIntrinsics c = camera_from(t[1], p, where);
      c.width = integer(t[2], where, "WIDTH");
      c.height = integer(t[3], where, "HEIGHT");
      try {
        c.validate();
      } catch (const Error& e) {
        throw Error(where + ": " + e.what());
      }
      if (!out.cameras.emplace(id, c).second) {
        throw Error(where + ": camera " + std::to_string(id) + " is defined twice");
      }
    }
  }
  if (out.cameras.empty()) throw Error(cam_path.string() + ": no camera");
  std::ifstream in = open_text(img_path);
  std::set<int> ids;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    const std::vector<std::string> t = tokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string where = img_path.string() + ":" + std::to_string(n);
    if (t.size() < 10) {
      throw Error(where + ": expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    }
    PosedImage im;
    im.id = integer(t[0], where, "IMAGE_ID");
    const Eigen::Quaterniond q(number(t[1], where, "QW"), number(t[2], where, "QX"),
                               number(t[3], where, "QY"), number(t[4], where, "QZ"));
    const Eigen::Vector3d tr(number(t[5], where, "TX"), number(t[6], where, "TY"),
                             number(t[7], where, "TZ"));
    if (!(q.norm() > 1e-6)) throw Error(where + ": the quaternion is zero");
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      throw Error(fmt::format("{}: the quaternion's norm is {:.6f}, not 1", where, q.norm()));
    }
    if (tr.cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
      throw Error(where + ": the translation lies beyond ±1e7 m");
    }
    im.camera_id = integer(t[8], where, "CAMERA_ID");
    if (!out.cameras.count(im.camera_id)) {
      throw Error(where + ": image " + std::to_string(im.id) + " refers to camera " +
                  std::to_string(im.camera_id) + ", which cameras.txt does not define");
    }
    im.name = rest_after(line, 9);  // the name may hold spaces
    if (!ids.insert(im.id).second) {
      throw Error(where + ": image " + std::to_string(im.id) + " is listed twice");
    }
    // World → camera in the file; sonar3d keeps camera → world.
    Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();
    T_camera_world.linear() = q.normalized().toRotationMatrix();
    T_camera_world.translation() = tr;
    im.T_world_camera = T_camera_world.inverse();
    out.images.push_back(im);
    // The next line lists the image's 2D points (possibly none): skipped.
    if (!std::getline(in, line)) break;
    ++n;
  }
  if (out.images.empty()) throw Error(img_path.string() + ": no image");
  return out;
}

void write_colmap_text(const PosedImages& posed, const fs::path& dir) {
  std::string cams =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
  for (const auto& [id, c] : posed.cameras) {
    c.validate();
    // COLMAP's pixel centres are at +0.5.
    const double cx = c.cx + 0.5, cy = c.cy + 0.5;
    if (!c.distorted()) {
      cams += fmt::format("{} PINHOLE {} {} {:.17g} {:.17g} {:.17g} {:.17g}\n", id, c.width,
                          c.height, c.fx, c.fy, cx, cy);
    } else if (c.k3 == 0) {
      cams += fmt::format(
          "{} OPENCV {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} "
          "{:.17g}\n",
          id, c.width, c.height, c.fx, c.fy, cx, cy, c.k1, c.k2, c.p1, c.p2);
    } else {
      cams += fmt::format(
          "{} FULL_OPENCV {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} "
          "{:.17g} {:.17g} {:.17g} 0 0 0\n",
          id, c.width, c.height, c.fx, c.fy, cx, cy, c.k1, c.k2, c.p1, c.p2, c.k3);
    }
  }
  std::string imgs =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (const PosedImage& im : posed.images) {
    require(posed.cameras.count(im.camera_id),
            "COLMAP export: image '" + im.name + "' has an unknown camera");
    require(!im.name.empty() && im.name.find('\n') == std::string::npos,
            "COLMAP export: image names must be one non-empty line");
    const Eigen::Isometry3d T_camera_world = im.T_world_camera.inverse();
    const Eigen::Quaterniond q(T_camera_world.linear());
    const Eigen::Vector3d t = T_camera_world.translation();
    imgs +=
        fmt::format("{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {} {}\n\n", im.id,
                    q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z(), im.camera_id, im.name);
  }
  write_text_file((dir / "cameras.txt").string(), cams);
  write_text_file((dir / "images.txt").string(), imgs);
}

void check_images_exist(const PosedImages& posed, const fs::path& images_dir) {
  for (const PosedImage& im : posed.images) {
    if (!fs::is_regular_file(images_dir / im.name)) {
      throw Error("image " + std::to_string(im.id) + " ('" + printable(im.name) + "') is not in '" +
                  images_dir.string() + "'");
    }
  }
}

}  // namespace sonar3d
