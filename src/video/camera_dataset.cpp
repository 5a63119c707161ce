// Camera frames in a dataset (include/sonar3d/video/camera_dataset.hpp).
#include "sonar3d/video/camera_dataset.hpp"

#include <cstdio>
#include <set>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/video/texture_files.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

CameraRig parse_camera_rig(const YAML::Node& node, const std::string& file, const std::string& ctx,
                           const std::vector<std::string>& extra) {
  if (!node.IsMap()) throw Error(yaml::where(file, node, ctx) + ": expected a mapping");
  std::set<std::string> allowed = {"width", "height", "fx", "fy", "cx", "cy",
                                   "k1",    "k2",     "p1", "p2", "k3", "T_vehicle_camera"};
  allowed.insert(extra.begin(), extra.end());
  yaml::check_keys(node, allowed, file, ctx);
  CameraRig rig;
  CameraIntrinsics& c = rig.intrinsics;
  const auto dim = [&](const char* key) {
    if (!node[key]) throw Error(yaml::where(file, node, ctx) + ": required key '" + key + "'");
    const int v = yaml::get_int(node, key, 0, file, ctx);
    if (v < 1 || v > 100000) {
      throw Error(yaml::where(file, node[key], ctx + "." + key) +
                  ": must be within 1..100000 pixels");
    }
    return v;
  };
  c.width = dim("width");
  c.height = dim("height");
  c.fx = yaml::get_double(node, "fx", file, ctx);
  c.fy = yaml::get_double(node, "fy", file, ctx);
  c.cx = yaml::get_double(node, "cx", file, ctx);
  c.cy = yaml::get_double(node, "cy", file, ctx);
  c.k1 = yaml::get_double(node, "k1", 0.0, file, ctx);
  c.k2 = yaml::get_double(node, "k2", 0.0, file, ctx);
  c.p1 = yaml::get_double(node, "p1", 0.0, file, ctx);
  c.p2 = yaml::get_double(node, "p2", 0.0, file, ctx);
  c.k3 = yaml::get_double(node, "k3", 0.0, file, ctx);
  try {
    c.validate();
  } catch (const Error& e) {
    throw Error(yaml::where(file, node, ctx) + ": " + e.what());
  }
  if (const YAML::Node m = node["T_vehicle_camera"]) {
    rig.T_vehicle_camera =
        yaml::get_pose(m, file, ctx.empty() ? "T_vehicle_camera" : ctx + ".T_vehicle_camera");
  }
  return rig;
}

void emit_camera_rig(YAML::Emitter& out, const CameraRig& rig) {
  const CameraIntrinsics& c = rig.intrinsics;
  out << YAML::Key << "width" << YAML::Value << c.width;
  out << YAML::Key << "height" << YAML::Value << c.height;
  for (const auto& [key, v] : {std::pair<const char*, double>{"fx", c.fx},
                               {"fy", c.fy},
                               {"cx", c.cx},
                               {"cy", c.cy},
                               {"k1", c.k1},
                               {"k2", c.k2},
                               {"p1", c.p1},
                               {"p2", c.p2},
                               {"k3", c.k3}}) {
    out << YAML::Key << key << YAML::Value << v;
  }
  const Eigen::Quaterniond q(rig.T_vehicle_camera.linear());
  const Eigen::Vector3d t = rig.T_vehicle_camera.translation();
  out << YAML::Key << "T_vehicle_camera" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "translation" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x() << t.y()
      << t.z() << YAML::EndSeq;
  out << YAML::Key << "quaternion" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.x() << q.y()
      << q.z() << q.w() << YAML::EndSeq;
  out << YAML::EndMap;
}

Eigen::Isometry3d CameraDataset::T_world_camera(std::size_t i) const {
  if (i >= frames.size()) throw Error("camera frame " + std::to_string(i) + " does not exist");
  try {
    return navigation.interpolate(frames[i].timestamp) * rig.T_vehicle_camera;
  } catch (const Error& e) {
    throw Error((root / "camera" / "frames.csv").string() + ": frame " +
                std::to_string(frames[i].index) + " has no pose: " + e.what());
  }
}

bool has_camera_frames(const fs::path& dataset_dir) {
  return fs::exists(dataset_dir / "camera" / "camera.yaml");
}

CameraDataset read_camera_dataset(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw Error("dataset '" + dir.string() + "' is not a directory");
  const fs::path yaml_path = dir / "camera" / "camera.yaml";
  if (!fs::exists(yaml_path)) {
    throw Error("dataset '" + dir.string() +
                "' has no camera frames (camera/camera.yaml is missing)");
  }
  const std::string file = yaml_path.string();
  const YAML::Node root = yaml::load_file(file);
  if (!root.IsMap()) throw Error(file + ": expected a mapping at the top level");
  const int version = yaml::get_int(root, "version", -1, file);
  if (version != kCameraFramesVersion) {
    throw Error(yaml::where(file, root, "version") + ": unsupported camera frames version " +
                std::to_string(version) + " (this build reads version " +
                std::to_string(kCameraFramesVersion) + ")");
  }
  CameraDataset ds;
  ds.root = dir;
  ds.rig = parse_camera_rig(root, file, "", {"format", "version"});
  const fs::path csv = dir / "camera" / "frames.csv";
  if (!fs::exists(csv)) throw Error("dataset '" + dir.string() + "': camera/frames.csv is missing");
  ds.frames = read_frames_csv(csv);
  const fs::path nav = dir / "navigation.tum";
  if (!fs::exists(nav)) throw Error("dataset '" + dir.string() + "': navigation.tum is missing");
  ds.navigation = read_tum(nav.string());
  ds.navigation.validate(nav.string());
  return ds;
}

CameraFramesWriter::CameraFramesWriter(const fs::path& camera_dir, const CameraRig& rig)
    : dir_(camera_dir), rig_(rig) {
  rig.intrinsics.validate();
  fs::create_directories(dir_ / "frames");
}

void CameraFramesWriter::add(double timestamp, const RgbImage& image) {
  require(std::isfinite(timestamp), "camera frame: timestamp is not finite");
  require(image.width == rig_.intrinsics.width && image.height == rig_.intrinsics.height,
          "camera frame: the image's size is not the camera's");
  if (!frames_.empty() && timestamp < frames_.back().timestamp) {
    throw Error("camera frame " + std::to_string(frames_.size()) + ": timestamps go backwards");
  }
  FrameRecord r;
  r.index = static_cast<int>(frames_.size());
  r.timestamp = timestamp;
  char name[32];
  std::snprintf(name, sizeof name, "%06d.png", r.index);
  r.file = std::string("camera/frames/") + name;
  write_rgb_image(dir_ / "frames" / name, image);
  frames_.push_back(r);
}

void CameraFramesWriter::finish() {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "sonar3d-camera";
  out << YAML::Key << "version" << YAML::Value << kCameraFramesVersion;
  emit_camera_rig(out, rig_);
  out << YAML::EndMap;
  write_text_file((dir_ / "camera.yaml").string(), std::string(out.c_str()) + "\n");
  write_text_file((dir_ / "frames.csv").string(), frames_csv_text(frames_));
}

}  // namespace sonar3d
