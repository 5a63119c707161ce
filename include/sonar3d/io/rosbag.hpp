#pragma once
// ROS bags to datasets and back (docs/import.md, "ROS bags"):
//   - ROS 2 bags: a directory with metadata.yaml and sqlite3 .db3 files (or one .db3 file), CDR
//     messages, read with libsqlite3;
//   - ROS 1 bags (format 2.0, .bag), read by hand from the documented format.
// Sonar topics: marine_acoustic_msgs/ProjectedSonarImage or its predecessor
// acoustic_msgs/ProjectedSonarImage (sensor description from the message), or sensor_msgs/Image
// plus a sensor description file. Navigation: nav_msgs/Odometry, geometry_msgs/PoseStamped,
// geometry_msgs/PoseWithCovarianceStamped (T_world_vehicle). Mounting: --mount, or the static
// transform (tf2_msgs/TFMessage on /tf_static) from the vehicle frame to the sonar's frame_id.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/ros_msgs.hpp"

namespace sonar3d {

struct BagTopic {
  std::string name;
  std::string type;  // as the bag names it (ROS 2: pkg/msg/Name, ROS 1: pkg/Name)
  std::size_t messages = 0;
};

// A bag opened for reading: its topics and their messages in time order. Errors name the file.
class BagReader {
 public:
  virtual ~BagReader() = default;
  // ROS 2 (a bag directory, or a .db3 file) or ROS 1 (.bag, by its "#ROSBAG V2.0" line).
  static std::unique_ptr<BagReader> open(const std::filesystem::path& bag);
  virtual const std::vector<BagTopic>& topics() const = 0;
  virtual RosWire wire() const = 0;
  virtual std::string format() const = 0;  // "ROS 2 (sqlite3)" | "ROS 1 (v2.0)"
  // Calls fn(receive time ns, bytes, size, where) for each message of `topic` in time order;
  // `where` names the file, topic and message number for errors.
  using Visitor =
      std::function<void(std::int64_t, const std::uint8_t*, std::size_t, const std::string&)>;
  virtual void read(const std::string& topic, const Visitor& fn) const = 0;
  // Calls fn for the first message of `topic` only (in time order); false when it has none.
  bool read_first(const std::string& topic, const Visitor& fn) const;
  const BagTopic* find(const std::string& topic) const;
};

struct RosbagImportConfig {
  std::string sonar_topic;    // required (choose_rosbag_topics fills it by type when empty)
  std::string nav_topic;      // "" only with static_sonar
  bool static_sonar = false;  // no navigation: T_world_vehicle = identity
  std::string tf_topic = "/tf_static";
  // The vehicle frame the mounting is expressed in; "" = the Odometry child_frame_id when the
  // navigation has one, else the root of the static transform tree above the sonar frame.
  std::string base_frame;
  // --mount: T_vehicle_sonar as x, y, z (m), roll, pitch, yaw (degrees; mounting_from_list),
  // overriding the static transforms; empty = from the static transforms.
  params::List mount;
  // Sensor description (sonar.yaml fields): required for sensor_msgs/Image; for
  // ProjectedSonarImage it supplies what the message lacks (vertical aperture, beam pattern).
  std::string sonar_description;
  // Overrides the message's tx_beamwidths and the description; none = theirs.
  params::Maybe vertical_aperture_deg;
  double time_offset = 0;  // s added to sonar stamps to reach the navigation clock
  bool drop_outside = false;
  void validate() const;
  // The mounting `mount` declares, when it declares one.
  std::optional<Eigen::Isometry3d> T_vehicle_sonar() const;
};

// The one declaration of RosbagImportConfig's fields (core/params.hpp).
template <class V>
void describe(RosbagImportConfig& c, V& v) {
  using params::param;
  v.field(c.sonar_topic,
          param("sonar_topic", "",
                "topic of ProjectedSonarImage or sensor_msgs/Image messages; empty: the one "
                "topic of such a type")
              .flag("--sonar-topic"));
  v.field(c.nav_topic,
          param("nav_topic", "",
                "topic of nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                "PoseWithCovarianceStamped (T_world_vehicle); empty: the one topic of such a "
                "type")
              .flag("--nav-topic"));
  v.field(
      c.static_sonar,
      param("static_sonar", "", "a fixed sonar: no navigation, identity poses").flag("--static"));
  v.field(c.tf_topic,
          param("tf_topic", "", "static transforms (tf2_msgs/TFMessage)").flag("--tf-topic"));
  v.field(c.base_frame,
          param("base_frame", "",
                "vehicle frame of the mounting; empty: the Odometry child_frame_id, else the root "
                "of the static transforms above the sonar frame")
              .flag("--base-frame"));
  v.field(c.mount, param("mount", "m, deg",
                         "T_vehicle_sonar as x, y, z (m), roll, pitch, yaw (degrees; R = "
                         "Rz(yaw)·Ry(pitch)·Rx(roll); our FLU sonar frame), instead of the static "
                         "transforms; empty: from the static transforms")
                       .flag("--mount"));
  v.field(c.sonar_description,
          param("sonar_description", "",
                "sensor YAML (sonar.yaml fields): required for sensor_msgs/Image; supplies the "
                "vertical aperture and beam pattern a ProjectedSonarImage lacks")
              .flag("--sonar"));
  v.field(c.vertical_aperture_deg,
          param("vertical_aperture_deg", "deg",
                "full vertical aperture; none: the messages' tx_beamwidths, or the sensor YAML's")
              .range_open_high(limits::kMinApertureDeg, 180)
              .flag("--vertical-aperture-deg"));
  v.field(c.time_offset,
          param("time_offset", "s", "added to sonar stamps to reach the navigation clock")
              .flag("--time-offset"));
  v.field(c.drop_outside,
          param("drop_outside", "",
                "drop (and count) frames outside the navigation span instead of failing")
              .flag("--drop-outside"));
}

struct RosbagImportResult {
  std::string format;
  std::string sonar_type, nav_type;
  SonarSpec spec;
  std::size_t frames = 0, dropped = 0, navigation_samples = 0;
  std::string mounting_source;  // "--mount", "identity", "/tf_static: base_link -> sonar"
  std::vector<std::string> warnings;
};

RosbagImportResult import_rosbag(const std::filesystem::path& bag, const std::filesystem::path& out,
                                 const RosbagImportConfig& config, bool progress = false);

// Fills the empty sonar_topic (and nav_topic, unless static_sonar) of `config` from the bag's
// topics by message type: the one ProjectedSonarImage topic (else the one sensor_msgs/Image
// topic), the one nav_msgs/Odometry, geometry_msgs/PoseStamped or PoseWithCovarianceStamped
// topic. Several candidates, or none, are an Error naming the bag and listing them. Returns a line
// per topic chosen ("sonar topic /oculus/image (by type sensor_msgs/Image)").
std::vector<std::string> choose_rosbag_topics(const std::filesystem::path& bag,
                                              RosbagImportConfig& config);

// Our sensor description of a ProjectedSonarImage (bearings from beam_directions, range bins
// from the uniformly spaced ranges, vertical aperture from tx_beamwidths, intensity encoding
// from dtype). `reversed` is set when the beams come by decreasing bearing (columns are then
// flipped). Throws Error naming `where`.
SonarSpec sonar_spec_from_message(const RosSonarImage& m, const std::string& where,
                                  bool* reversed = nullptr);

// The messages of one sonar topic as SonarImages, exactly as `import rosbag` reads them; shared by
// import_rosbag() and the ROS node (`sonar3d ros`), so that a bag and a live topic give the same
// frames. The sensor description comes from the first message (ProjectedSonarImage: bearings,
// range bins, tx_beamwidths, dtype; `described` supplies what it lacks) or from `described`
// alone (sensor_msgs/Image); every later message is checked against it.
class RosSonarFrames {
 public:
  // `type`: the topic's message type (either naming); p, n: its first message. Throws Error naming
  // `where` (also when `type` is no sonar type, or an Image comes without `described`).
  RosSonarFrames(const std::string& type, RosWire wire, const std::uint8_t* p, std::size_t n,
                 const std::string& where, const std::optional<SonarSpec>& described,
                 double vertical_aperture_rad = 0);
  bool projected() const { return projected_; }
  bool is_float() const { return is_float_; }                // float32 intensities (a TIFF dataset)
  const std::string& frame_id() const { return frame_id_; }  // the sonar's TF frame (no "/")
  // Completes the description with the mounting: `mount` (--mount, our FLU sonar frame) when
  // given, else T_vehicle_frame (vehicle → the message's frame_id, from static transforms;
  // `from_tf` false = none found: identity for ProjectedSonarImage, the description's mounting
  // for Image). Checks the vertical aperture (`topic` names the topic in that error) and
  // validates. Returns the description.
  const SonarSpec& set_mounting(const std::optional<Eigen::Isometry3d>& mount,
                                const Eigen::Isometry3d& T_vehicle_frame, bool from_tf,
                                const std::string& topic);
  const SonarSpec& spec() const { return spec_; }
  // One message into `img` (spec().range_bins × beams()); returns its header stamp, s. Throws
  // Error naming `where` when it disagrees with the first message (size, encoding, bearings,
  // range window) or holds a non-finite intensity.
  double decode(const std::uint8_t* p, std::size_t n, const std::string& where,
                SonarImage& img) const;

 private:
  RosWire wire_;
  bool projected_ = false, is_float_ = false, big_endian_ = false, reversed_ = false;
  std::size_t sample_size_ = 0;
  std::string frame_id_;
  SonarSpec spec_;
};

// The static transforms (tf2_msgs/TFMessage on /tf_static) seen so far, child → parent.
class RosStaticTransforms {
 public:
  void add(const std::vector<RosTransform>& transforms);
  bool empty() const { return parent_of_.empty(); }
  // T_base_frame along the chain from `frame` up to `base` ("" = as far as the chain goes);
  // `chain` gets "base -> … -> frame" and `depth` the number of links (0: none found). Throws
  // Error (naming `where`) on a cycle, or when `base` is given and not reached.
  Eigen::Isometry3d chain(const std::string& base, const std::string& frame,
                          const std::string& where, std::string* chain = nullptr,
                          int* depth = nullptr) const;

 private:
  std::map<std::string, std::pair<std::string, Eigen::Isometry3d>> parent_of_;
};

// A TF frame name as tf2 compares them (leading slashes stripped).
std::string ros_tf_frame(const std::string& name);
// The message types read: ProjectedSonarImage (both packages), sensor_msgs/Image, navigation
// (nav_msgs/Odometry, geometry_msgs/PoseStamped, PoseWithCovarianceStamped); either naming.
bool is_ros_sonar_image_type(const std::string& type);
bool is_ros_image_type(const std::string& type);
bool is_ros_nav_type(const std::string& type);

struct RosbagExportConfig {
  RosWire wire = RosWire::Cdr;  // Cdr: ROS 2 sqlite3 bag directory; Ros1: ROS 1 .bag file
  std::string sonar_topic = "/sonar3d/image";
  std::string nav_topic = "/sonar3d/odom";
  std::string message_package = "marine_acoustic_msgs";  // or "acoustic_msgs"
  std::string world_frame = "map", base_frame = "base_link", sonar_frame = "sonar";
  std::string ros1_compression = "none";  // ROS 1 chunks: none, bz2 or lz4 (as rosbag --bz2/--lz4)
  void validate() const;                  // throws Error naming the field
};

inline constexpr const char* kRosWireNames[] = {"ros2", "ros1"};  // RosWire: Cdr, Ros1
inline constexpr const char* kRosMessagePackages[] = {"marine_acoustic_msgs", "acoustic_msgs"};
inline constexpr const char* kRos1Compressions[] = {"none", "bz2", "lz4"};

// The one declaration of RosbagExportConfig's settings (core/params.hpp): sonar3d export
// rosbag's flags and --print-config keys. `wire` has no flag of its own: the command's --ros1
// sets it to ros1.
template <class V>
void describe(RosbagExportConfig& c, V& v) {
  using params::param;
  v.field(c.wire, param("wire", "",
                        "the bag: ros2 (a sqlite3 bag directory, CDR messages) or ros1 (a v2.0 "
                        ".bag file)")
                      .choices(kRosWireNames));
  v.field(
      c.sonar_topic,
      param("sonar_topic", "", "topic of the ProjectedSonarImage messages").flag("--sonar-topic"));
  v.field(
      c.nav_topic,
      param("nav_topic", "", "topic of the navigation (nav_msgs/Odometry)").flag("--nav-topic"));
  v.field(c.message_package, param("message_package", "", "message package of ProjectedSonarImage")
                                 .choices(kRosMessagePackages)
                                 .flag("--package"));
  v.field(c.world_frame, param("world_frame", "", "frame of the navigation's poses (the world)")
                             .flag("--world-frame"));
  v.field(
      c.base_frame,
      param("base_frame", "", "the vehicle's frame (the odometry's child)").flag("--base-frame"));
  v.field(c.sonar_frame, param("sonar_frame", "",
                               "the sonar's frame (the mounting on /tf_static: base_frame "
                               "to sonar_frame)")
                             .flag("--sonar-frame"));
  v.field(c.ros1_compression,
          param("ros1_compression", "", "ROS 1 chunk compression (as rosbag record --bz2/--lz4)")
              .choices(kRos1Compressions)
              .flag("--compression"));
}

struct RosbagExportResult {
  std::size_t frames = 0, navigation_samples = 0;
};

// Writes a dataset as a bag: one ProjectedSonarImage per frame (dtype from the dataset's
// encoding: 8-bit → uint8, 16-bit → uint16, TIFF → float32), the navigation as nav_msgs/Odometry,
// the mounting as a static transform base_frame → sonar_frame on /tf_static. Written under a
// temporary name and renamed into place; `out` must not exist.
RosbagExportResult export_rosbag(const std::filesystem::path& dataset,
                                 const std::filesystem::path& out,
                                 const RosbagExportConfig& config = {}, bool progress = false);

// Writing bags of any messages (used by export_rosbag; tests and fuzz seeds build bags with it).
struct BagOutTopic {
  std::string name, type;  // type in the bag's naming: ROS 2 pkg/msg/Name, ROS 1 pkg/Name
  bool latched = false;    // transient-local (ROS 2) / latching (ROS 1), as /tf_static needs
};
struct BagOutMessage {
  int topic = 0;  // index into the topics
  std::int64_t time_ns = 0;
  std::vector<std::uint8_t> data;  // serialised for the bag's wire
};
// Cdr: a ROS 2 bag directory `path` (metadata.yaml, <name>_0.db3); Ros1: a v2.0 .bag file
// (uncompressed chunks, connection/chunk-info records, index). `path` must not exist; not
// atomic (export_rosbag writes under a temporary name).
void write_bag(const std::filesystem::path& path, RosWire wire,
               const std::vector<BagOutTopic>& topics, const std::vector<BagOutMessage>& messages,
               const std::string& ros1_compression = "none");

// The rotation from our FLU sonar frame to the ProjectedSonarImage frame (z forward, x up,
// y starboard): p_msg = R · p_flu.
Eigen::Matrix3d R_msg_flu();

}  // namespace sonar3d
