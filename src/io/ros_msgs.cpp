#include "sonar3d/io/ros_msgs.hpp"

#include <cmath>
#include <cstring>

#include "binary.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {
namespace {

// Reads one serialised message. CDR: a 4-byte encapsulation header (0x00 0x01 = little-endian
// CDR), then fields aligned to their size relative to the end of that header. ROS 1: packed.
class Reader {
 public:
  Reader(const std::uint8_t* p, std::size_t n, RosWire wire, const std::string& where)
      : p_(p), n_(n), wire_(wire), where_(where) {
    if (wire_ == RosWire::Cdr) {
      if (n_ < 4) fail(0, "shorter than the 4-byte CDR encapsulation header");
      if (p_[0] != 0x00 || p_[1] != 0x01) {
        if (p_[0] == 0x00 && p_[1] == 0x00) {
          fail(0, "big-endian CDR is not supported (encapsulation 0x0000)");
        }
        char buf[64];
        std::snprintf(buf, sizeof buf, "unknown CDR encapsulation 0x%02x%02x (expected 0x0001)",
                      p_[0], p_[1]);
        fail(0, buf);
      }
      origin_ = pos_ = 4;
    }
  }
  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    throw Error(where_ + ": byte " + std::to_string(at) + ": " + what);
  }
  void align(std::size_t a) {
    if (wire_ != RosWire::Cdr) return;
    const std::size_t off = (pos_ - origin_) % a;
    if (off) skip(a - off, "padding");
  }
  void need(std::size_t k, const char* what) const {
    if (k > n_ - pos_) {
      fail(pos_, std::string("the message ends inside ") + what + " (" + std::to_string(k) +
                     " bytes needed, " + std::to_string(n_ - pos_) + " left)");
    }
  }
  void skip(std::size_t k, const char* what) {
    need(k, what);
    pos_ += k;
  }
  template <class T>
  T get(const char* what) {
    align(sizeof(T));
    need(sizeof(T), what);
    const T v = bin::load<T>(p_ + pos_);
    pos_ += sizeof(T);
    return v;
  }
  // A sequence count whose elements take at least `min_elem` bytes each: checked against the
  // bytes left, so a hostile count can never drive an allocation.
  std::uint32_t count(std::size_t min_elem, const char* what) {
    const std::size_t at = pos_;
    const auto c = get<std::uint32_t>(what);
    if (min_elem && c > (n_ - pos_) / min_elem) {
      fail(at, std::string(what) + " claims " + std::to_string(c) + " elements but only " +
                   std::to_string(n_ - pos_) + " bytes are left");
    }
    return c;
  }
  std::string str(const char* what) {
    const std::size_t at = pos_;
    const std::uint32_t len = count(1, what);
    if (wire_ == RosWire::Cdr) {
      if (len == 0) return "";  // some writers send 0 for an empty string
      const char* s = reinterpret_cast<const char*>(p_ + pos_);
      if (s[len - 1] != '\0') fail(at, std::string(what) + " is not null-terminated");
      pos_ += len;
      return std::string(s, len - 1);
    }
    std::string out(reinterpret_cast<const char*>(p_ + pos_), len);
    pos_ += len;
    return out;
  }
  RosTime time(const char* what) {
    RosTime t;
    if (wire_ == RosWire::Cdr) {
      t.sec = get<std::int32_t>(what);
    } else {
      t.sec = get<std::uint32_t>(what);
    }
    t.nanosec = get<std::uint32_t>(what);
    if (t.nanosec >= 1000000000u) {
      fail(pos_ - 4, std::string(what) + " has " + std::to_string(t.nanosec) + " nanoseconds");
    }
    return t;
  }
  void header(RosTime& stamp, std::string& frame_id) {
    if (wire_ == RosWire::Ros1) get<std::uint32_t>("header.seq");
    stamp = time("header.stamp");
    frame_id = str("header.frame_id");
  }
  template <class T>
  std::vector<T> array(const char* what) {
    const std::uint32_t c = count(sizeof(T), what);
    align(sizeof(T));
    need(std::size_t(c) * sizeof(T), what);
    std::vector<T> v(c);
    if (c) std::memcpy(v.data(), p_ + pos_, std::size_t(c) * sizeof(T));
    pos_ += std::size_t(c) * sizeof(T);
    return v;
  }
  Eigen::Vector3d vec3(const char* what) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v[k] = get<double>(what);
    return v;
  }
  Eigen::Quaterniond quat(const char* what) {
    double q[4];
    for (double& x : q) x = get<double>(what);
    return Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
  }
  std::size_t pos() const { return pos_; }
  std::size_t size() const { return n_; }

 private:
  const std::uint8_t* p_;
  std::size_t n_;
  RosWire wire_;
  std::string where_;
  std::size_t pos_ = 0, origin_ = 0;
};

class Writer {
 public:
  explicit Writer(RosWire wire) : wire_(wire) {
    if (wire_ == RosWire::Cdr) {
      out_ = {0x00, 0x01, 0x00, 0x00};
      origin_ = 4;
    }
  }
  void align(std::size_t a) {
    if (wire_ != RosWire::Cdr) return;
    while ((out_.size() - origin_) % a) out_.push_back(0);
  }
  template <class T>
  void put(T v) {
    align(sizeof(T));
    bin::append(out_, v);
  }
  void str(const std::string& s) {
    if (wire_ == RosWire::Cdr) {
      put<std::uint32_t>(static_cast<std::uint32_t>(s.size() + 1));
      bin::append_bytes(out_, s.data(), s.size());
      out_.push_back(0);
    } else {
      put<std::uint32_t>(static_cast<std::uint32_t>(s.size()));
      bin::append_bytes(out_, s.data(), s.size());
    }
  }
  void time(const RosTime& t) {
    if (wire_ == RosWire::Cdr) {
      put<std::int32_t>(static_cast<std::int32_t>(t.sec));
    } else {
      put<std::uint32_t>(static_cast<std::uint32_t>(t.sec));
    }
    put<std::uint32_t>(t.nanosec);
  }
  void header(const RosTime& stamp, const std::string& frame_id) {
    if (wire_ == RosWire::Ros1) put<std::uint32_t>(0);
    time(stamp);
    str(frame_id);
  }
  template <class T>
  void array(const std::vector<T>& v) {
    put<std::uint32_t>(static_cast<std::uint32_t>(v.size()));
    align(sizeof(T));
    if (!v.empty()) bin::append_bytes(out_, v.data(), v.size() * sizeof(T));
  }
  void vec3(const Eigen::Vector3d& v) {
    for (int k = 0; k < 3; ++k) put<double>(v[k]);
  }
  void quat(const Eigen::Quaterniond& q) {
    put<double>(q.x());
    put<double>(q.y());
    put<double>(q.z());
    put<double>(q.w());
  }
  std::vector<std::uint8_t> take() { return std::move(out_); }

 private:
  RosWire wire_;
  std::vector<std::uint8_t> out_;
  std::size_t origin_ = 0;
};

void finite_or_fail(const Reader& r, const Eigen::Vector3d& v, const char* what) {
  if (!v.allFinite()) r.fail(r.pos(), std::string(what) + " is not finite");
}

void unit_or_fail(const Reader& r, Eigen::Quaterniond& q, const char* what) {
  const double n = q.coeffs().norm();
  if (!std::isfinite(n) || std::abs(n - 1) > 1e-3) {
    r.fail(r.pos(),
           std::string(what) + " is not a unit quaternion (norm " + std::to_string(n) + ")");
  }
  q.normalize();
}

}  // namespace

std::string ros_type_name(const std::string& type) {
  const auto at = type.find("/msg/");
  if (at == std::string::npos) return type;
  return type.substr(0, at) + "/" + type.substr(at + 5);
}

RosTime RosTime::from_seconds(double t) {
  // Whole seconds and the fraction apart: t · 1e9 as one double would lose ~100 ns at epoch
  // times (1.7e18 ns), the fraction alone keeps every bit t has.
  RosTime r;
  double sec = std::floor(t);
  long long ns = std::llround((t - sec) * 1e9);
  if (ns >= 1000000000LL) {
    ns -= 1000000000LL;
    sec += 1;
  }
  r.sec = static_cast<std::int64_t>(sec);
  r.nanosec = static_cast<std::uint32_t>(ns);
  return r;
}

RosSonarImage decode_sonar_image(const std::uint8_t* p, std::size_t n, RosWire wire,
                                 const std::string& where) {
  Reader r(p, n, wire, where);
  RosSonarImage m;
  r.header(m.stamp, m.frame_id);
  m.frequency = r.get<float>("ping_info.frequency");
  m.sound_speed = r.get<float>("ping_info.sound_speed");
  m.tx_beamwidths = r.array<float>("ping_info.tx_beamwidths");
  m.rx_beamwidths = r.array<float>("ping_info.rx_beamwidths");
  const std::uint32_t beams = r.count(24, "beam_directions");
  m.beam_directions.reserve(beams);
  for (std::uint32_t j = 0; j < beams; ++j) {
    m.beam_directions.push_back(r.vec3("beam_directions"));
    finite_or_fail(r, m.beam_directions.back(), "a beam direction");
  }
  m.ranges = r.array<float>("ranges");
  m.is_bigendian = r.get<std::uint8_t>("image.is_bigendian") != 0;
  m.dtype = r.get<std::uint32_t>("image.dtype");
  m.beam_count = r.get<std::uint32_t>("image.beam_count");
  m.data = r.array<std::uint8_t>("image.data");
  return m;
}

RosImage decode_image(const std::uint8_t* p, std::size_t n, RosWire wire,
                      const std::string& where) {
  Reader r(p, n, wire, where);
  RosImage m;
  r.header(m.stamp, m.frame_id);
  m.height = r.get<std::uint32_t>("height");
  m.width = r.get<std::uint32_t>("width");
  m.encoding = r.str("encoding");
  m.is_bigendian = r.get<std::uint8_t>("is_bigendian");
  m.step = r.get<std::uint32_t>("step");
  m.data = r.array<std::uint8_t>("data");
  return m;
}

RosPose decode_pose(const std::string& type_in, const std::uint8_t* p, std::size_t n, RosWire wire,
                    const std::string& where) {
  const std::string type = ros_type_name(type_in);
  Reader r(p, n, wire, where);
  RosPose m;
  r.header(m.stamp, m.frame_id);
  if (type == "nav_msgs/Odometry") {
    m.child_frame_id = r.str("child_frame_id");
  } else if (type != "geometry_msgs/PoseStamped" &&
             type != "geometry_msgs/PoseWithCovarianceStamped") {
    throw Error(where + ": " + type_in +
                " is not a navigation message (nav_msgs/Odometry, geometry_msgs/PoseStamped, "
                "geometry_msgs/PoseWithCovarianceStamped)");
  }
  m.position = r.vec3("pose.position");
  finite_or_fail(r, m.position, "pose.position");
  m.orientation = r.quat("pose.orientation");
  unit_or_fail(r, m.orientation, "pose.orientation");
  // The covariance and twist that follow are not needed.
  return m;
}

std::vector<RosTransform> decode_tf(const std::uint8_t* p, std::size_t n, RosWire wire,
                                    const std::string& where) {
  Reader r(p, n, wire, where);
  const std::uint32_t c = r.count(60, "transforms");
  std::vector<RosTransform> out;
  out.reserve(c);
  for (std::uint32_t k = 0; k < c; ++k) {
    RosTransform t;
    r.header(t.stamp, t.parent);
    t.child = r.str("child_frame_id");
    t.translation = r.vec3("transform.translation");
    finite_or_fail(r, t.translation, "transform.translation");
    t.rotation = r.quat("transform.rotation");
    unit_or_fail(r, t.rotation, "transform.rotation");
    out.push_back(t);
  }
  return out;
}

std::vector<std::uint8_t> encode_sonar_image(const RosSonarImage& m, RosWire wire) {
  Writer w(wire);
  w.header(m.stamp, m.frame_id);
  w.put<float>(m.frequency);
  w.put<float>(m.sound_speed);
  w.array(m.tx_beamwidths);
  w.array(m.rx_beamwidths);
  w.put<std::uint32_t>(static_cast<std::uint32_t>(m.beam_directions.size()));
  for (const auto& d : m.beam_directions) w.vec3(d);
  w.array(m.ranges);
  w.put<std::uint8_t>(m.is_bigendian ? 1 : 0);
  w.put<std::uint32_t>(m.dtype);
  w.put<std::uint32_t>(m.beam_count);
  w.array(m.data);
  return w.take();
}

std::vector<std::uint8_t> encode_image(const RosImage& m, RosWire wire) {
  Writer w(wire);
  w.header(m.stamp, m.frame_id);
  w.put<std::uint32_t>(m.height);
  w.put<std::uint32_t>(m.width);
  w.str(m.encoding);
  w.put<std::uint8_t>(m.is_bigendian);
  w.put<std::uint32_t>(m.step);
  w.array(m.data);
  return w.take();
}

std::vector<std::uint8_t> encode_odometry(const RosPose& m, RosWire wire) {
  Writer w(wire);
  w.header(m.stamp, m.frame_id);
  w.str(m.child_frame_id);
  w.vec3(m.position);
  w.quat(m.orientation);
  for (int k = 0; k < 36; ++k) w.put<double>(0.0);  // pose covariance
  for (int k = 0; k < 6; ++k) w.put<double>(0.0);   // twist
  for (int k = 0; k < 36; ++k) w.put<double>(0.0);  // twist covariance
  return w.take();
}

std::vector<std::uint8_t> encode_pose_stamped(const RosPose& m, RosWire wire) {
  Writer w(wire);
  w.header(m.stamp, m.frame_id);
  w.vec3(m.position);
  w.quat(m.orientation);
  return w.take();
}

std::vector<std::uint8_t> encode_tf(const std::vector<RosTransform>& m, RosWire wire) {
  Writer w(wire);
  w.put<std::uint32_t>(static_cast<std::uint32_t>(m.size()));
  for (const auto& t : m) {
    w.header(t.stamp, t.parent);
    w.str(t.child);
    w.vec3(t.translation);
    w.quat(t.rotation);
  }
  return w.take();
}

}  // namespace sonar3d
