#include "sonar3d/io/rosbag.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>

#include "rosbag_internal.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/navigation.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

bool is_sonar_image_type(const std::string& t) { return is_ros_sonar_image_type(t); }
bool is_image_type(const std::string& t) { return is_ros_image_type(t); }
bool is_nav_type(const std::string& t) { return is_ros_nav_type(t); }

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

std::string tf_frame(const std::string& name) { return ros_tf_frame(name); }

std::string topic_list(const BagReader& r) {
  std::string s;
  std::size_t k = 0;
  for (const auto& t : r.topics()) {
    if (k++ == 12) {
      s += ", …";
      break;
    }
    s += (s.empty() ? "" : ", ") + t.name + " (" + t.type + ")";
  }
  return s.empty() ? "none" : s;
}

Eigen::Isometry3d iso(const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

std::size_t dtype_size(std::uint32_t dtype) {
  switch (dtype) {
    case kRosDtypeUint8:
      return 1;
    case kRosDtypeUint16:
      return 2;
    case kRosDtypeFloat32:
      return 4;
  }
  return 0;
}

const char* dtype_name(std::uint32_t dtype) {
  static const char* kNames[] = {"uint8", "int8",   "uint16", "int16",   "uint32",
                                 "int32", "uint64", "int64",  "float32", "float64"};
  return dtype < 10 ? kNames[dtype] : "unknown";
}

// Decodes the samples of a range-major image (rows × cols of `size`-byte values) into linear
// intensities value · scale (float32 values as they are).
void samples_to_image(const std::uint8_t* p, std::size_t size, bool big_endian, bool is_float,
                      double scale, bool reversed, SonarImage& img) {
  const int cols = img.cols;
  for (int i = 0; i < img.rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const std::uint8_t* q = p + (static_cast<std::size_t>(i) * cols + j) * size;
      std::uint8_t b[4];
      for (std::size_t k = 0; k < size; ++k) b[k] = big_endian ? q[size - 1 - k] : q[k];
      float v;
      if (is_float) {
        std::memcpy(&v, b, 4);
      } else if (size == 1) {
        v = static_cast<float>(b[0] * scale);
      } else {
        v = static_cast<float>((b[0] | (b[1] << 8)) * scale);
      }
      img.at(i, reversed ? cols - 1 - j : j) = v;
    }
  }
}

}  // namespace

void write_bag(const fs::path& path, RosWire wire, const std::vector<BagOutTopic>& topics,
               const std::vector<BagOutMessage>& messages, const std::string& ros1_compression) {
  for (const auto& m : messages) {
    if (m.topic < 0 || static_cast<std::size_t>(m.topic) >= topics.size()) {
      throw Error("write_bag: a message names topic " + std::to_string(m.topic) + " of " +
                  std::to_string(topics.size()));
    }
  }
  std::size_t k = 0;
  const bag::NextMessage next = [&](BagOutMessage& m) {
    if (k == messages.size()) return false;
    m = messages[k++];
    return true;
  };
  if (wire == RosWire::Cdr) {
    bag::write_ros2(path, path.filename().string(), topics, next);
  } else {
    bag::write_ros1(path, topics, next, ros1_compression);
  }
}

Eigen::Matrix3d R_msg_flu() {
  Eigen::Matrix3d R;
  // msg x = up (flu z), msg y = starboard (−flu y), msg z = forward (flu x)
  R << 0, 0, 1, 0, -1, 0, 1, 0, 0;
  return R;
}

bool is_ros_sonar_image_type(const std::string& t) {
  const std::string n = ros_type_name(t);
  return n == "marine_acoustic_msgs/ProjectedSonarImage" ||
         n == "acoustic_msgs/ProjectedSonarImage";
}
bool is_ros_image_type(const std::string& t) { return ros_type_name(t) == "sensor_msgs/Image"; }
bool is_ros_nav_type(const std::string& t) {
  const std::string n = ros_type_name(t);
  return n == "nav_msgs/Odometry" || n == "geometry_msgs/PoseStamped" ||
         n == "geometry_msgs/PoseWithCovarianceStamped";
}

// ROS 1 logs (tf before tf2, many drivers) write "/base_link" where others write "base_link";
// tf2 strips the leading slash, so do we.
std::string ros_tf_frame(const std::string& name) {
  const std::size_t k = name.find_first_not_of('/');
  return k == std::string::npos ? std::string() : name.substr(k);
}

void RosStaticTransforms::add(const std::vector<RosTransform>& transforms) {
  for (const RosTransform& t : transforms) {
    parent_of_[ros_tf_frame(t.child)] = {ros_tf_frame(t.parent), iso(t.translation, t.rotation)};
  }
}

Eigen::Isometry3d RosStaticTransforms::chain(const std::string& base, const std::string& frame_in,
                                             const std::string& where, std::string* chain_out,
                                             int* depth_out) const {
  Eigen::Isometry3d T_base_frame = Eigen::Isometry3d::Identity();
  std::string frame = frame_in, chain = frame_in;
  int depth = 0;
  while (frame != base) {
    const auto it = parent_of_.find(frame);
    if (it == parent_of_.end()) break;
    if (++depth > 64)
      throw Error(where + ": the static transforms above '" + frame_in + "' form a cycle");
    T_base_frame = it->second.second * T_base_frame;
    frame = it->second.first;
    chain = frame + " -> " + chain;
  }
  if (!base.empty() && frame != base) {
    throw Error(where + ": no static transform chain from '" + base + "' to the sonar frame '" +
                frame_in + "' (reached '" + frame +
                "'); give the mounting with --mount or the vehicle frame with --base-frame");
  }
  if (chain_out) *chain_out = chain;
  if (depth_out) *depth_out = depth;
  return T_base_frame;
}

RosSonarFrames::RosSonarFrames(const std::string& type, RosWire wire, const std::uint8_t* p,
                               std::size_t n, const std::string& where,
                               const std::optional<SonarSpec>& described,
                               double vertical_aperture_rad)
    : wire_(wire) {
  projected_ = is_ros_sonar_image_type(type);
  if (!projected_ && !is_ros_image_type(type)) {
    throw Error(where + ": messages of type " + type +
                ", not marine_acoustic_msgs/ProjectedSonarImage (or acoustic_msgs/…) or "
                "sensor_msgs/Image");
  }
  if (!projected_ && !described) {
    throw Error(where +
                ": sensor_msgs/Image says nothing of the sonar: give its description (--sonar "
                "FILE.yaml)");
  }
  if (!projected_) {
    const RosImage m = decode_image(p, n, wire, where);
    frame_id_ = ros_tf_frame(m.frame_id);
    // 32FC1 frames are linear intensities: a float TIFF dataset whatever bit depth the
    // description gives for integer frames (which must be 8 or 16).
    is_float_ = m.encoding == "32FC1";
    spec_ = *described;
  } else {
    const RosSonarImage m = decode_sonar_image(p, n, wire, where);
    frame_id_ = ros_tf_frame(m.frame_id);
    spec_ = sonar_spec_from_message(m, where, &reversed_);
    sample_size_ = dtype_size(m.dtype);
    is_float_ = m.dtype == kRosDtypeFloat32;
    big_endian_ = m.is_bigendian;
    if (described) {
      if (spec_.vertical_aperture_rad == 0)
        spec_.vertical_aperture_rad = described->vertical_aperture_rad;
      spec_.beam_pattern = described->beam_pattern;
      spec_.name = described->name;
      if (!is_float_ && described->bit_depth == spec_.bit_depth) {
        spec_.intensity_scale = described->intensity_scale;
      }
    }
  }
  if (vertical_aperture_rad > 0) spec_.vertical_aperture_rad = vertical_aperture_rad;
}

const SonarSpec& RosSonarFrames::set_mounting(const std::optional<Eigen::Isometry3d>& mount,
                                              const Eigen::Isometry3d& T_vehicle_frame,
                                              bool from_tf, const std::string& topic) {
  if (!(spec_.vertical_aperture_rad > 0)) {
    throw Error(topic +
                " give no vertical aperture "
                "(ping_info.tx_beamwidths is empty): give --vertical-aperture-deg or --sonar");
  }
  if (mount) {
    spec_.T_vehicle_sonar = *mount;
  } else if (projected_) {
    // The message frame is z forward, x up: our FLU sonar frame is that frame rotated.
    Eigen::Isometry3d R = Eigen::Isometry3d::Identity();
    R.linear() = R_msg_flu();
    spec_.T_vehicle_sonar = T_vehicle_frame * R;
  } else if (from_tf) {
    spec_.T_vehicle_sonar = T_vehicle_frame;
  }
  spec_.validate();
  return spec_;
}

double RosSonarFrames::decode(const std::uint8_t* p, std::size_t n, const std::string& where,
                              SonarImage& img) const {
  double t = 0;
  const SonarSpec& spec = spec_;
  if (img.rows != spec.range_bins || img.cols != spec.beams()) {
    img = SonarImage(spec.range_bins, spec.beams());
  }
  if (projected_) {
    const RosSonarImage m = decode_sonar_image(p, n, wire_, where);
    if (m.beam_directions.size() != static_cast<std::size_t>(spec.beams()) ||
        m.ranges.size() != static_cast<std::size_t>(spec.range_bins) ||
        dtype_size(m.dtype) != sample_size_ || m.is_bigendian != big_endian_) {
      throw Error(where + ": the image changes size or encoding (" +
                  std::to_string(m.ranges.size()) + " ranges × " +
                  std::to_string(m.beam_directions.size()) + " beams, " + dtype_name(m.dtype) +
                  "; the first message has " + std::to_string(spec.range_bins) + " × " +
                  std::to_string(spec.beams()) + "); a dataset holds one sensor geometry");
    }
    bool rev = false;
    const SonarSpec si = sonar_spec_from_message(m, where, &rev);
    const double tol = 1e-5 * spec.r_max;
    if (std::abs(si.r_min - spec.r_min) > tol || std::abs(si.r_max - spec.r_max) > tol ||
        rev != reversed_) {
      throw Error(where + ": the range window or beam order changes (" + fmt(si.r_min) + "–" +
                  fmt(si.r_max) + " m; the first message has " + fmt(spec.r_min) + "–" +
                  fmt(spec.r_max) + " m)");
    }
    for (int j = 0; j < spec.beams(); ++j) {
      if (std::abs(si.bearings_rad[j] - spec.bearings_rad[j]) > 1e-6) {
        throw Error(where + ": beam " + std::to_string(j) + " moves to " +
                    fmt(si.bearings_rad[j] / kDeg) + "°; a dataset holds one bearing table");
      }
    }
    samples_to_image(m.data.data(), sample_size_, m.is_bigendian, is_float_, spec.intensity_scale,
                     reversed_, img);
    t = m.stamp.seconds();
  } else {
    const RosImage m = decode_image(p, n, wire_, where);
    std::size_t size = 0;
    if (m.encoding == "mono8" || m.encoding == "8UC1") size = 1;
    if (m.encoding == "mono16" || m.encoding == "16UC1") size = 2;
    if (m.encoding == "32FC1") size = 4;
    if (size == 0) {
      throw Error(where + ": encoding '" + printable(m.encoding) +
                  "' is not read (mono8, mono16, 32FC1 are)");
    }
    if ((size == 1 && spec.bit_depth != 8) || (size == 2 && spec.bit_depth != 16)) {
      throw Error(where + ": a " + m.encoding + " image but the sonar description declares " +
                  std::to_string(spec.bit_depth) + "-bit intensities");
    }
    if (m.height != static_cast<std::uint32_t>(spec.range_bins) ||
        m.width != static_cast<std::uint32_t>(spec.beams())) {
      throw Error(where + ": a " + std::to_string(m.height) + "×" + std::to_string(m.width) +
                  " image but the sonar description has " + std::to_string(spec.range_bins) +
                  " range bins × " + std::to_string(spec.beams()) + " beams");
    }
    if (m.step != m.width * size || m.data.size() != std::size_t(m.step) * m.height) {
      throw Error(where + ": step " + std::to_string(m.step) + " and " +
                  std::to_string(m.data.size()) + " data bytes do not match " +
                  std::to_string(m.height) + " rows of " + std::to_string(m.width) + " × " +
                  std::to_string(size) + " bytes");
    }
    if ((size == 4) != is_float_) {
      throw Error(where + ": a " + m.encoding + " image after " +
                  (is_float_ ? "32FC1 images" : "integer images") +
                  "; a dataset holds one encoding (float TIFF or integer PNG frames)");
    }
    samples_to_image(m.data.data(), size, m.is_bigendian != 0, size == 4, spec.intensity_scale,
                     false, img);
    t = m.stamp.seconds();
  }
  for (float v : img.data) {
    if (!std::isfinite(v)) throw Error(where + ": a non-finite intensity");
  }
  return t;
}

const BagTopic* BagReader::find(const std::string& topic) const {
  for (const auto& t : topics()) {
    if (t.name == topic) return &t;
  }
  return nullptr;
}

bool BagReader::read_first(const std::string& topic, const Visitor& fn) const {
  struct Stop {};  // ends the walk over the topic after its first message
  bool got = false;
  try {
    read(topic, [&](std::int64_t t, const std::uint8_t* p, std::size_t n, const std::string& w) {
      fn(t, p, n, w);
      got = true;
      throw Stop{};
    });
  } catch (const Stop&) {
  }
  return got;
}

std::unique_ptr<BagReader> BagReader::open(const fs::path& bag) {
  std::error_code ec;
  if (!fs::exists(bag, ec)) throw Error("bag '" + bag.string() + "' does not exist");
  if (fs::is_regular_file(bag, ec)) {
    std::ifstream f(bag, std::ios::binary);
    char magic[13] = {};
    f.read(magic, 13);
    if (f.gcount() == 13 && std::memcmp(magic, "#ROSBAG V2.0\n", 13) == 0) {
      return bag::open_ros1(bag);
    }
    if (f.gcount() >= 8 && std::memcmp(magic, "#ROSBAG ", 8) == 0) {
      throw Error(bag.string() + ": a ROS 1 bag of a format other than 2.0 ('" +
                  printable(std::string(magic, 12)) + "'); migrate it with `rosbag fix`");
    }
    if (f.gcount() >= 8 && std::memcmp(magic, "\x89MCAP", 5) == 0) {
      throw Error(bag.string() + ": an MCAP file; convert it with `ros2 bag convert` to sqlite3");
    }
  }
  return bag::open_ros2(bag);
}

void RosbagImportConfig::validate() const {
  params::check(*this, "rosbag import:");
  if (sonar_topic.empty()) throw Error("rosbag import: the sonar topic is not set");
  if (nav_topic.empty() && !static_sonar) {
    throw Error(
        "rosbag import: give the navigation topic (--nav-topic), or --static for a fixed "
        "sonar");
  }
  if (!std::isfinite(time_offset)) throw Error("rosbag import: 'time_offset' must be finite");
  T_vehicle_sonar();  // checks the mounting
}

std::optional<Eigen::Isometry3d> RosbagImportConfig::T_vehicle_sonar() const {
  if (mount.empty()) return std::nullopt;
  return mounting_from_list(mount, "rosbag import: mount");
}

SonarSpec sonar_spec_from_message(const RosSonarImage& m, const std::string& where,
                                  bool* reversed) {
  const std::size_t beams = m.beam_directions.size();
  const std::size_t bins = m.ranges.size();
  if (beams == 0 || beams > static_cast<std::size_t>(limits::kMaxBeams)) {
    throw Error(where + ": " + std::to_string(beams) + " beam directions, outside [1, " +
                std::to_string(limits::kMaxBeams) + "]");
  }
  if (bins < 2 || bins > static_cast<std::size_t>(limits::kMaxRangeBins)) {
    throw Error(where + ": " + std::to_string(bins) + " ranges, outside [2, " +
                std::to_string(limits::kMaxRangeBins) + "] (the range spacing needs two)");
  }
  if (m.beam_count != beams) {
    throw Error(where + ": image.beam_count is " + std::to_string(m.beam_count) +
                " but there are " + std::to_string(beams) + " beam directions");
  }
  const std::size_t size = dtype_size(m.dtype);
  if (size == 0) {
    throw Error(where + ": image.dtype " + std::to_string(m.dtype) + " (" + dtype_name(m.dtype) +
                ") is not read; uint8, uint16 and float32 are");
  }
  if (m.data.size() != beams * bins * size) {
    throw Error(where + ": image.data holds " + std::to_string(m.data.size()) + " bytes, not " +
                std::to_string(bins) + " ranges × " + std::to_string(beams) + " beams × " +
                std::to_string(size) + " bytes");
  }
  SonarSpec s;
  s.name = "rosbag";
  std::vector<double> phi(beams);
  for (std::size_t j = 0; j < beams; ++j) {
    const Eigen::Vector3d& d = m.beam_directions[j];
    if (d.norm() < 1e-9) throw Error(where + ": beam direction " + std::to_string(j) + " is zero");
    phi[j] = std::atan2(-d.y(), d.z());  // message frame: z forward, y starboard
  }
  bool rev = beams > 1 && phi[1] < phi[0];
  if (rev) std::reverse(phi.begin(), phi.end());
  for (std::size_t j = 1; j < beams; ++j) {
    if (!(phi[j] > phi[j - 1])) {
      throw Error(where + ": beam bearings are not monotonic at beam " + std::to_string(j) + " (" +
                  fmt(phi[j - 1] / kDeg) + "°, " + fmt(phi[j] / kDeg) + "°)");
    }
  }
  if (reversed) *reversed = rev;
  s.bearings_rad = phi;
  const double r0 = m.ranges.front(), r1 = m.ranges.back();
  const double dr = (r1 - r0) / static_cast<double>(bins - 1);
  if (!std::isfinite(dr) || !(dr > 0)) {
    throw Error(where + ": ranges must increase (first " + fmt(r0) + " m, last " + fmt(r1) + " m)");
  }
  for (std::size_t i = 0; i < bins; ++i) {
    const double want = r0 + dr * static_cast<double>(i);
    if (!(std::abs(m.ranges[i] - want) <= 1e-3 * dr + 4e-7 * std::abs(want))) {
      throw Error(where + ": range bin " + std::to_string(i) + " is at " + fmt(m.ranges[i]) +
                  " m, not " + fmt(want) + " m: a dataset needs uniformly spaced range bins");
    }
  }
  s.r_min = r0 - dr / 2;
  s.r_max = s.r_min + dr * static_cast<double>(bins);
  s.range_bins = static_cast<int>(bins);
  if (s.r_min < 0) throw Error(where + ": the first range bin starts below 0 m");
  if (s.r_max > limits::kMaxRange) {
    throw Error(where + ": ranges reach " + fmt(s.r_max) + " m, beyond " + fmt(limits::kMaxRange) +
                " m");
  }
  s.vertical_aperture_rad = 0;  // unknown unless tx_beamwidths says
  if (!m.tx_beamwidths.empty()) {
    const double a = m.tx_beamwidths.front();
    if (std::isfinite(a) && a > 0 && a < M_PI) s.vertical_aperture_rad = a;
  }
  s.beam_pattern.kind = BeamPattern::Kind::Sinc;
  if (m.dtype == kRosDtypeUint8) {
    s.bit_depth = 8;
    s.intensity_scale = 1.0 / 255.0;
  } else {
    s.bit_depth = 16;
    s.intensity_scale = 1.0 / 65535.0;
  }
  return s;
}

std::vector<std::string> choose_rosbag_topics(const fs::path& bag_path,
                                              RosbagImportConfig& config) {
  std::vector<std::string> chosen;
  if (!config.sonar_topic.empty() && (config.static_sonar || !config.nav_topic.empty())) {
    return chosen;
  }
  const std::unique_ptr<BagReader> bag = BagReader::open(bag_path);
  const std::string src = bag_path.string();
  auto of = [&](bool (*fits)(const std::string&)) {
    std::vector<const BagTopic*> v;
    for (const BagTopic& t : bag->topics()) {
      if (fits(t.type)) v.push_back(&t);
    }
    return v;
  };
  auto names = [](const std::vector<const BagTopic*>& v) {
    std::string s;
    for (const BagTopic* t : v) s += (s.empty() ? "" : ", ") + t->name + " (" + t->type + ")";
    return s;
  };
  if (config.sonar_topic.empty()) {
    std::vector<const BagTopic*> c = of(is_sonar_image_type);
    if (c.empty()) c = of(is_image_type);
    if (c.size() != 1) {
      throw Error(src +
                  (c.empty() ? ": no sonar topic (ProjectedSonarImage or sensor_msgs/Image)"
                             : ": several sonar topics: " + names(c)) +
                  "; name one (--sonar-topic); the bag holds " + topic_list(*bag));
    }
    config.sonar_topic = c[0]->name;
    chosen.push_back("sonar topic " + c[0]->name + " (by type " + c[0]->type + ")");
  }
  if (!config.static_sonar && config.nav_topic.empty()) {
    const std::vector<const BagTopic*> c = of(is_nav_type);
    if (c.size() != 1) {
      throw Error(src +
                  (c.empty() ? ": no navigation topic (nav_msgs/Odometry, "
                               "geometry_msgs/PoseStamped or PoseWithCovarianceStamped)"
                             : ": several navigation topics: " + names(c)) +
                  "; name one (--nav-topic), or import a fixed sonar (--static)");
    }
    config.nav_topic = c[0]->name;
    chosen.push_back("navigation topic " + c[0]->name + " (by type " + c[0]->type + ")");
  }
  return chosen;
}

RosbagImportResult import_rosbag(const fs::path& bag_path, const fs::path& out,
                                 const RosbagImportConfig& config, bool progress) {
  config.validate();
  const std::unique_ptr<BagReader> bag = BagReader::open(bag_path);
  RosbagImportResult res;
  res.format = bag->format();
  const RosWire wire = bag->wire();
  const std::string src = bag_path.string();

  const BagTopic* sonar = bag->find(config.sonar_topic);
  if (!sonar) {
    throw Error(src + ": no topic '" + config.sonar_topic + "'; the bag holds " + topic_list(*bag));
  }
  const bool projected = is_sonar_image_type(sonar->type);
  if (!projected && !is_image_type(sonar->type)) {
    throw Error(src + ": topic '" + sonar->name + "' is of type " + sonar->type +
                ", not marine_acoustic_msgs/ProjectedSonarImage (or acoustic_msgs/…) or "
                "sensor_msgs/Image");
  }
  res.sonar_type = sonar->type;
  if (!projected && config.sonar_description.empty()) {
    throw Error(src + ": topic '" + sonar->name +
                "' carries sensor_msgs/Image, which says "
                "nothing of the sonar: give its description (--sonar FILE.yaml)");
  }
  std::optional<SonarSpec> described;
  if (!config.sonar_description.empty()) {
    described = read_sonar_description(config.sonar_description);
  }

  // Navigation: T_world_vehicle from the header stamps.
  Trajectory nav;
  std::string body_frame;
  if (!config.static_sonar) {
    const BagTopic* navt = bag->find(config.nav_topic);
    if (!navt) {
      throw Error(src + ": no topic '" + config.nav_topic + "'; the bag holds " + topic_list(*bag));
    }
    if (!is_nav_type(navt->type)) {
      throw Error(src + ": topic '" + navt->name + "' is of type " + navt->type +
                  ", not nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                  "geometry_msgs/PoseWithCovarianceStamped");
    }
    res.nav_type = navt->type;
    std::vector<std::pair<double, Eigen::Isometry3d>> samples;
    bag->read(navt->name,
              [&](std::int64_t, const std::uint8_t* p, std::size_t n, const std::string& where) {
                const RosPose m = decode_pose(navt->type, p, n, wire, where);
                if (body_frame.empty()) body_frame = tf_frame(m.child_frame_id);
                if (std::abs(m.position.maxCoeff()) > limits::kMaxCoordinate ||
                    std::abs(m.position.minCoeff()) > limits::kMaxCoordinate) {
                  throw Error(where + ": position beyond " + fmt(limits::kMaxCoordinate) + " m");
                }
                samples.emplace_back(m.stamp.seconds(), iso(m.position, m.orientation));
              });
    std::stable_sort(samples.begin(), samples.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& s : samples) {
      if (!nav.empty() && s.first <= nav.times.back()) {
        res.warnings.push_back("navigation sample at " + fmt(s.first) +
                               " s repeats a header stamp: kept the first");
        continue;
      }
      nav.push_back(s.first, s.second);
    }
    if (nav.empty()) throw Error(src + ": topic '" + navt->name + "' holds no message");
    nav.validate(src + ": " + navt->name);
    res.navigation_samples = nav.size();
  }

  // The sonar's frame and the sensor description: from its first message (RosSonarFrames, shared
  // with the ROS node).
  std::optional<RosSonarFrames> frames;
  const bool have_first = bag->read_first(
      sonar->name,
      [&](std::int64_t, const std::uint8_t* p, std::size_t n, const std::string& where) {
        frames.emplace(sonar->type, wire, p, n, where, described,
                       config.vertical_aperture_deg ? *config.vertical_aperture_deg * kDeg : 0.0);
      });
  if (!have_first) throw Error(src + ": topic '" + sonar->name + "' holds no message");
  const std::string sonar_frame = frames->frame_id();
  const bool is_float = frames->is_float();

  // Mounting: --mount, else the static transforms from the vehicle frame to the sonar frame.
  Eigen::Isometry3d T_vehicle_frame = Eigen::Isometry3d::Identity();
  res.mounting_source = "identity (no static transform)";
  bool from_tf = false;
  const std::optional<Eigen::Isometry3d> mount = config.T_vehicle_sonar();
  if (mount) {
    res.mounting_source = "--mount";
  } else if (const BagTopic* tf = bag->find(config.tf_topic)) {
    if (ros_type_name(tf->type) != "tf2_msgs/TFMessage") {
      throw Error(src + ": topic '" + tf->name + "' is of type " + tf->type +
                  ", not tf2_msgs/TFMessage");
    }
    RosStaticTransforms statics;
    bag->read(tf->name,
              [&](std::int64_t, const std::uint8_t* p, std::size_t n, const std::string& where) {
                statics.add(decode_tf(p, n, wire, where));
              });
    const std::string base = !config.base_frame.empty() ? tf_frame(config.base_frame) : body_frame;
    std::string chain;
    int depth = 0;
    T_vehicle_frame = statics.chain(base, sonar_frame, src + ": " + tf->name, &chain, &depth);
    if (depth > 0) {
      res.mounting_source = tf->name + ": " + chain;
      from_tf = true;
    }
  }

  // The sensor description.
  const SonarSpec spec = frames->set_mounting(mount, T_vehicle_frame, from_tf,
                                              src + ": the messages of '" + sonar->name + "'");
  res.spec = spec;

  const bool tiff = is_float;
  std::unique_ptr<DatasetWriter> writer;
  Progress bar("import", sonar->messages, progress);
  SonarImage img(spec.range_bins, spec.beams());
  double last_t = -INFINITY, first_t = 0;
  std::vector<double> stamps;
  bag->read(sonar->name, [&](std::int64_t, const std::uint8_t* p, std::size_t n,
                             const std::string& where) {
    double t = frames->decode(p, n, where, img);
    t += config.time_offset;
    if (t < last_t) {
      throw Error(where + ": header stamp " + fmt(t) + " s goes backwards (previous " +
                  fmt(last_t) + " s)");
    }
    if (!config.static_sonar && !frame_inside_navigation(nav, t, config.drop_outside, where)) {
      ++res.dropped;
      bar.add();
      return;
    }
    if (!writer) {
      writer = std::make_unique<DatasetWriter>(
          out, spec, tiff ? DatasetWriter::ImageFormat::Tiff : DatasetWriter::ImageFormat::Png);
      first_t = t;
    }
    img.timestamp = t;
    writer->add_frame(img);
    stamps.push_back(t);
    last_t = t;
    ++res.frames;
    bar.add();
  });
  bar.finish();
  if (res.frames == 0) {
    if (!config.static_sonar) throw no_frame_inside_navigation(nav, src + ": " + sonar->name);
    throw Error(src + ": topic '" + sonar->name + "' holds no frame");
  }
  if (config.static_sonar) {
    nav = Trajectory();
    nav.push_back(first_t, Eigen::Isometry3d::Identity());
    if (last_t > first_t) nav.push_back(last_t, Eigen::Isometry3d::Identity());
  }
  writer->set_navigation(nav);
  writer->commit();
  return res;
}

void RosbagExportConfig::validate() const {
  params::check(*this, "export rosbag");
  for (const auto& [value, name] : {std::pair{&sonar_topic, "sonar_topic"},
                                    {&nav_topic, "nav_topic"},
                                    {&world_frame, "world_frame"},
                                    {&base_frame, "base_frame"},
                                    {&sonar_frame, "sonar_frame"}}) {
    require(!value->empty(), std::string("export rosbag: ") + name + " must not be empty");
  }
}

RosbagExportResult export_rosbag(const fs::path& dataset, const fs::path& out,
                                 const RosbagExportConfig& config, bool progress) {
  config.validate();
  const Dataset ds = read_dataset(dataset);
  if (ds.size() == 0) throw Error(dataset.string() + ": the dataset holds no frame");
  std::error_code ec;
  if (fs::exists(out, ec) || fs::is_symlink(out, ec)) {
    throw Error("'" + out.string() + "' exists; `export rosbag` writes a new bag only");
  }
  if (config.message_package != "marine_acoustic_msgs" &&
      config.message_package != "acoustic_msgs") {
    throw Error("unknown message package '" + config.message_package +
                "' (marine_acoustic_msgs or acoustic_msgs)");
  }
  const SonarSpec& spec = ds.spec;
  const bool ros2 = config.wire == RosWire::Cdr;
  auto type = [&](const std::string& pkg, const std::string& name) {
    return ros2 ? pkg + "/msg/" + name : pkg + "/" + name;
  };
  std::vector<BagOutTopic> topics = {
      {config.sonar_topic, type(config.message_package, "ProjectedSonarImage"), false},
      {config.nav_topic, type("nav_msgs", "Odometry"), false},
      {"/tf_static", type("tf2_msgs", "TFMessage"), true}};
  // The mounting: base_frame -> sonar_frame, in the message's frame convention.
  Eigen::Isometry3d Rm = Eigen::Isometry3d::Identity();
  Rm.linear() = R_msg_flu().transpose();
  const Eigen::Isometry3d T_base_msg = spec.T_vehicle_sonar * Rm;
  RosTransform tf;
  tf.stamp = RosTime::from_seconds(std::min(
      ds.frames.front().timestamp, ds.navigation.empty() ? INFINITY : ds.navigation.times.front()));
  tf.parent = config.base_frame;
  tf.child = config.sonar_frame;
  tf.translation = T_base_msg.translation();
  tf.rotation = Eigen::Quaterniond(T_base_msg.linear());

  const std::string ext = fs::path(ds.frames.front().file).extension().string();
  const bool tiff = ext == ".tif" || ext == ".tiff";
  RosSonarImage m;
  m.frame_id = config.sonar_frame;
  m.sound_speed = 0;  // not known to a dataset
  m.dtype = tiff ? kRosDtypeFloat32 : spec.bit_depth == 8 ? kRosDtypeUint8 : kRosDtypeUint16;
  m.beam_count = static_cast<std::uint32_t>(spec.beams());
  for (int j = 0; j < spec.beams(); ++j) {
    const double phi = spec.bearings_rad[j];
    m.beam_directions.push_back(R_msg_flu() * Eigen::Vector3d(std::cos(phi), std::sin(phi), 0));
    m.tx_beamwidths.push_back(static_cast<float>(spec.vertical_aperture_rad));
    m.rx_beamwidths.push_back(static_cast<float>(spec.beam_edge_high(j) - spec.beam_edge_low(j)));
  }
  for (int i = 0; i < spec.range_bins; ++i) {
    m.ranges.push_back(static_cast<float>(spec.range_of_bin(i)));
  }
  const std::size_t size = dtype_size(m.dtype);

  // Messages in time order, made one at a time (a dataset may be larger than memory): the static
  // transform first, then navigation samples and frames merged by stamp.
  RosbagExportResult res;
  // A ROS 1 bag's record times start at ros::TIME_MIN (1 ns): Debian's rosbag player refuses to
  // load index entries at 0 ("contains invalid time") and would lose the messages of a dataset
  // that starts at t = 0, among them the only /tf_static. The header stamps stay as they are.
  auto record_ns = [&](std::int64_t ns) { return ros2 ? ns : std::max<std::int64_t>(ns, 1); };
  Progress bar("export", ds.size(), progress);
  bool tf_sent = false;
  std::size_t nav_k = 0, frame_k = 0;
  const bag::NextMessage next = [&](BagOutMessage& out_msg) {
    if (!tf_sent) {
      tf_sent = true;
      out_msg = {2, record_ns(tf.stamp.ns()), encode_tf({tf}, config.wire)};
      return true;
    }
    const bool have_nav = nav_k < ds.navigation.size();
    const bool have_frame = frame_k < ds.size();
    if (!have_nav && !have_frame) return false;
    if (have_nav && (!have_frame || RosTime::from_seconds(ds.navigation.times[nav_k]).ns() <=
                                        RosTime::from_seconds(ds.frames[frame_k].timestamp).ns())) {
      RosPose p;
      p.stamp = RosTime::from_seconds(ds.navigation.times[nav_k]);
      p.frame_id = config.world_frame;
      p.child_frame_id = config.base_frame;
      p.position = ds.navigation.poses[nav_k].translation();
      p.orientation = Eigen::Quaterniond(ds.navigation.poses[nav_k].linear());
      out_msg = {1, record_ns(p.stamp.ns()), encode_odometry(p, config.wire)};
      ++nav_k;
      ++res.navigation_samples;
      return true;
    }
    const SonarImage img = ds.load_frame(frame_k);
    m.stamp = RosTime::from_seconds(ds.frames[frame_k].timestamp);
    m.data.assign(img.data.size() * size, 0);
    for (std::size_t i = 0; i < img.data.size(); ++i) {
      if (tiff) {
        std::memcpy(&m.data[i * 4], &img.data[i], 4);
      } else {
        // The stored integer the dataset's frame holds (exact: it was read as value · scale).
        const double v = std::round(img.data[i] / spec.intensity_scale);
        const auto q = static_cast<std::uint32_t>(std::clamp(v, 0.0, spec.max_intensity_value()));
        m.data[i * size] = static_cast<std::uint8_t>(q & 0xff);
        if (size == 2) m.data[i * size + 1] = static_cast<std::uint8_t>(q >> 8);
      }
    }
    out_msg = {0, record_ns(m.stamp.ns()), encode_sonar_image(m, config.wire)};
    ++frame_k;
    ++res.frames;
    bar.add();
    return true;
  };
  AtomicPath atomic(out);
  if (ros2) {
    bag::write_ros2(atomic.temp(), out.filename().string(), topics, next);
  } else {
    bag::write_ros1(atomic.temp(), topics, next, config.ros1_compression);
  }
  bar.finish();
  atomic.commit();
  return res;
}

}  // namespace sonar3d
