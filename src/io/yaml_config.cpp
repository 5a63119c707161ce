#include "sonar3d/io/yaml_config.hpp"

#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/units.hpp"

namespace sonar3d::yaml {
namespace {

std::string full_key(const std::string& ctx, const std::string& key) {
  return ctx.empty() ? key : ctx + "." + key;
}
}  // namespace

// yaml-cpp keeps every entry of a mapping, in file order, and a lookup returns the first: a
// repeated key would silently lose its later value. Aliased nodes are visited once (their mark is
// their anchor's), so `*a` repeated a billion times costs nothing.
static void check_unique_keys(const YAML::Node& node, const std::string& path,
                              std::set<std::size_t>* visited, int depth) {
  if (!node.IsMap() && !node.IsSequence()) return;
  if (!visited->insert(node.Mark().pos).second) return;
  if (depth > limits::kMaxNestingDepth) {
    throw Error(path + ":" + std::to_string(node.Mark().line + 1) + ": nested more than " +
                std::to_string(limits::kMaxNestingDepth) + " levels deep");
  }
  if (node.IsSequence()) {
    for (const auto& child : node) check_unique_keys(child, path, visited, depth + 1);
    return;
  }
  std::map<std::string, int> seen;  // key -> line (1-based)
  for (const auto& kv : node) {
    if (kv.first.IsScalar()) {
      const int line = kv.first.Mark().line + 1;
      const auto [it, fresh] = seen.emplace(kv.first.Scalar(), line);
      if (!fresh) {
        throw Error(path + ":" + std::to_string(line) + ": duplicate key '" +
                    printable(kv.first.Scalar()) + "' (first given on line " +
                    std::to_string(it->second) + "); give each key once");
      }
    }
    check_unique_keys(kv.second, path, visited, depth + 1);
  }
}

YAML::Node load_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec)) {
    throw Error("cannot read '" + path + "': not a regular file");
  }
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > limits::kMaxConfigBytes) {
    throw Error("'" + path + "' is " + std::to_string(size) +
                " bytes; configuration files are limited to " +
                std::to_string(limits::kMaxConfigBytes) + " bytes");
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw Error("cannot open '" + path + "'");
  } catch (const YAML::ParserException& e) {
    throw Error(path + ":" + std::to_string(e.mark.line + 1) + ": malformed YAML: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw Error(path + ": malformed YAML: " + e.msg);
  }
  std::set<std::size_t> visited;
  check_unique_keys(root, path, &visited, 0);
  return root;
}

std::string where(const std::string& file, const YAML::Node& node, const std::string& key) {
  const int line = node.Mark().line;
  return file + (line >= 0 ? ":" + std::to_string(line + 1) : "") + ": key '" + key + "'";
}

static YAML::Node child(const YAML::Node& parent, const std::string& key, const std::string& file,
                        const std::string& ctx) {
  if (!parent.IsMap()) {
    throw Error(where(file, parent, ctx.empty() ? "<root>" : ctx) + ": expected a mapping");
  }
  return parent[key];
}

double get_double(const YAML::Node& parent, const std::string& key, const std::string& file,
                  const std::string& ctx) {
  const YAML::Node n = child(parent, key, file, ctx);
  if (!n) throw Error(where(file, parent, full_key(ctx, key)) + ": required key is missing");
  double v;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw Error(where(file, n, full_key(ctx, key)) + ": expected a number, got '" +
                (n.IsScalar() ? printable(n.Scalar()) : std::string("a list or map")) + "'");
  }
  if (!std::isfinite(v)) throw Error(where(file, n, full_key(ctx, key)) + ": must be finite");
  return v;
}

double get_double(const YAML::Node& parent, const std::string& key, double fallback,
                  const std::string& file, const std::string& ctx) {
  if (!child(parent, key, file, ctx)) return fallback;
  return get_double(parent, key, file, ctx);
}

int get_int(const YAML::Node& parent, const std::string& key, int fallback, const std::string& file,
            const std::string& ctx) {
  const YAML::Node n = child(parent, key, file, ctx);
  if (!n) return fallback;
  try {
    return n.as<int>();
  } catch (const YAML::Exception&) {
    throw Error(where(file, n, full_key(ctx, key)) + ": expected an integer, got '" +
                (n.IsScalar() ? printable(n.Scalar()) : std::string("a list or map")) + "'");
  }
}

namespace {

// Whether `s` is well-formed UTF-8 (no overlong forms, surrogates or code points past U+10FFFF).
bool valid_utf8(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int n = 0;
    unsigned min = 0;
    unsigned cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xE0) == 0xC0) {
      n = 1, min = 0x80, cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      n = 2, min = 0x800, cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      n = 3, min = 0x10000, cp = c & 0x07;
    } else {
      return false;
    }
    for (int k = 1; k <= n; ++k) {
      if (i + k >= s.size()) return false;
      const auto d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += n + 1;
  }
  return true;
}

}  // namespace

std::string get_string(const YAML::Node& parent, const std::string& key,
                       const std::string& fallback, const std::string& file,
                       const std::string& ctx) {
  const YAML::Node n = child(parent, key, file, ctx);
  if (!n) return fallback;
  if (!n.IsScalar()) throw Error(where(file, n, full_key(ctx, key)) + ": expected a string");
  // Names travel into JSON outputs, which must be UTF-8: refused here, naming the key, rather
  // than by the JSON writer later with its own words.
  if (!valid_utf8(n.Scalar())) {
    throw Error(where(file, n, full_key(ctx, key)) + ": '" + printable(n.Scalar()) +
                "' is not valid UTF-8 text (save the file as UTF-8)");
  }
  return n.Scalar();
}

bool get_bool(const YAML::Node& parent, const std::string& key, bool fallback,
              const std::string& file, const std::string& ctx) {
  const YAML::Node n = child(parent, key, file, ctx);
  if (!n) return fallback;
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    throw Error(where(file, n, full_key(ctx, key)) + ": expected true or false");
  }
}

std::vector<double> get_vector(const YAML::Node& parent, const std::string& key,
                               std::size_t expected_size, const std::string& file,
                               const std::string& ctx) {
  const YAML::Node n = child(parent, key, file, ctx);
  if (!n) throw Error(where(file, parent, full_key(ctx, key)) + ": required key is missing");
  if (!n.IsSequence() || (expected_size && n.size() != expected_size)) {
    throw Error(where(file, n, full_key(ctx, key)) + ": expected a list of " +
                (expected_size ? std::to_string(expected_size) + " " : std::string()) + "numbers");
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < n.size(); ++i) {
    double v;
    try {
      v = n[i].as<double>();
    } catch (const YAML::Exception&) {
      throw Error(where(file, n[i], full_key(ctx, key)) + ": element " + std::to_string(i) +
                  " is not a number");
    }
    if (!std::isfinite(v)) {
      throw Error(where(file, n[i], full_key(ctx, key)) + ": element " + std::to_string(i) +
                  " is not finite");
    }
    out.push_back(v);
  }
  return out;
}

void check_keys(const YAML::Node& node, const std::set<std::string>& allowed,
                const std::string& file, const std::string& ctx) {
  if (!node.IsMap()) {
    throw Error(where(file, node, ctx.empty() ? "<root>" : ctx) + ": expected a mapping");
  }
  for (const auto& kv : node) {
    if (!kv.first.IsScalar()) {
      throw Error(where(file, kv.first, ctx.empty() ? "<root>" : ctx) +
                  ": a key must be a plain name, not a list or mapping");
    }
    const std::string k = kv.first.Scalar();
    if (!allowed.count(k)) {
      const std::string shown = printable(k);
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw Error(where(file, kv.first, full_key(ctx, shown)) +
                  ": unknown key (expected one of: " + list + ")");
    }
  }
}

Eigen::Isometry3d pose_from_rpy(const Eigen::Vector3d& t, double roll, double pitch, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

Eigen::Isometry3d get_pose(const YAML::Node& node, const std::string& file,
                           const std::string& ctx) {
  check_keys(node, {"translation", "rpy_deg", "quaternion"}, file, ctx);
  if (node["quaternion"] && node["rpy_deg"]) {
    throw Error(where(file, node["rpy_deg"], full_key(ctx, "rpy_deg")) +
                ": give the orientation once, as either 'rpy_deg' or 'quaternion'");
  }
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  if (node["translation"]) {
    const auto v = get_vector(node, "translation", 3, file, ctx);
    t = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  if (node["quaternion"]) {
    const auto q = get_vector(node, "quaternion", 4, file, ctx);
    Eigen::Quaterniond quat(q[3], q[0], q[1], q[2]);
    if (std::abs(quat.norm() - 1.0) > 1e-3) {
      throw Error(where(file, node["quaternion"], ctx + ".quaternion") +
                  ": [qx, qy, qz, qw] must have unit norm");
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = quat.normalized().toRotationMatrix();
    T.translation() = t;
    return T;
  }
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();
  if (node["rpy_deg"]) {
    const auto v = get_vector(node, "rpy_deg", 3, file, ctx);
    rpy = Eigen::Vector3d(v[0], v[1], v[2]) * kDeg;
  }
  return pose_from_rpy(t, rpy[0], rpy[1], rpy[2]);
}

SonarSpec parse_sonar_spec(const YAML::Node& node, const std::string& file,
                           const std::string& ctx) {
  check_keys(node,
             {"preset", "name", "bearings_deg", "fov_deg", "beams", "r_min", "r_max", "range_bins",
              "vertical_aperture_deg", "beam_pattern", "intensity", "T_vehicle_sonar"},
             file, ctx);
  SonarSpec s;
  if (node["preset"]) s = sonar_preset(get_string(node, "preset", "", file, ctx));
  s.name = get_string(node, "name", s.name, file, ctx);
  if (node["bearings_deg"]) {
    if (node["fov_deg"] || node["beams"]) {
      throw Error(where(file, node["bearings_deg"], full_key(ctx, "bearings_deg")) +
                  ": give either a bearing table or fov_deg + beams, not both");
    }
    const auto b = get_vector(node, "bearings_deg", 0, file, ctx);
    s.bearings_rad.clear();
    for (double d : b) s.bearings_rad.push_back(d * kDeg);
  } else if (node["fov_deg"] || node["beams"]) {
    const double fov =
        get_double(node, "fov_deg", s.fov_max() / kDeg - s.fov_min() / kDeg, file, ctx);
    const int beams = get_int(node, "beams", s.beams(), file, ctx);
    if (!(fov > 0 && fov < 360) || beams <= 0) {
      throw Error(where(file, node, full_key(ctx, "fov_deg")) +
                  ": fov_deg must be in (0, 360) and beams > 0");
    }
    try {
      s.set_uniform_bearings(fov * kDeg, beams);
    } catch (const Error& e) {
      throw Error(where(file, node, full_key(ctx, "beams")) + ": " + e.what());
    }
  }
  s.r_min = get_double(node, "r_min", s.r_min, file, ctx);
  s.r_max = get_double(node, "r_max", s.r_max, file, ctx);
  s.range_bins = get_int(node, "range_bins", s.range_bins, file, ctx);
  s.vertical_aperture_rad =
      get_double(node, "vertical_aperture_deg", s.vertical_aperture_rad / kDeg, file, ctx) * kDeg;
  if (const YAML::Node bp = node["beam_pattern"]) {
    const std::string c = full_key(ctx, "beam_pattern");
    check_keys(bp, {"type", "elevation_deg", "amplitude"}, file, c);
    try {
      s.beam_pattern.kind = BeamPattern::parse_kind(get_string(bp, "type", "sinc", file, c));
    } catch (const Error& e) {
      throw Error(where(file, bp, c + ".type") + ": " + e.what());
    }
    if (s.beam_pattern.kind == BeamPattern::Kind::Table) {
      const auto el = get_vector(bp, "elevation_deg", 0, file, c);
      s.beam_pattern.table_amplitude = get_vector(bp, "amplitude", el.size(), file, c);
      s.beam_pattern.table_elevation_rad.clear();
      for (double e : el) s.beam_pattern.table_elevation_rad.push_back(e * kDeg);
    }
  }
  if (const YAML::Node in = node["intensity"]) {
    const std::string c = full_key(ctx, "intensity");
    check_keys(in, {"bit_depth", "scale"}, file, c);
    s.bit_depth = get_int(in, "bit_depth", s.bit_depth, file, c);
    s.intensity_scale = get_double(in, "scale", 1.0 / s.max_intensity_value(), file, c);
  }
  if (node["T_vehicle_sonar"]) {
    s.T_vehicle_sonar = get_pose(node["T_vehicle_sonar"], file, full_key(ctx, "T_vehicle_sonar"));
  }
  try {
    s.validate();
  } catch (const Error& e) {
    throw Error(file + ": " + (ctx.empty() ? "" : ctx + ": ") + e.what());
  }
  return s;
}

void emit_sonar_spec(YAML::Emitter& out, const SonarSpec& s) {
  out << YAML::Key << "name" << YAML::Value << s.name;
  // fov_deg + beams re-reads as a table centred on the boresight: only for such tables (an
  // imported table may be uniform but off-centre, e.g. HoloOcean's −A/2 … A/2 − Δa).
  const bool centred =
      s.beams() > 1 && std::abs(s.bearings_rad.front() + s.bearings_rad.back()) < 1e-9;
  if (s.uniform_bearings() && centred) {
    out << YAML::Key << "fov_deg" << YAML::Value << (s.fov_max() - s.fov_min()) / kDeg;
    out << YAML::Key << "beams" << YAML::Value << s.beams();
  } else {
    out << YAML::Key << "bearings_deg" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (double b : s.bearings_rad) out << b / kDeg;
    out << YAML::EndSeq;
  }
  out << YAML::Key << "r_min" << YAML::Value << s.r_min;
  out << YAML::Key << "r_max" << YAML::Value << s.r_max;
  out << YAML::Key << "range_bins" << YAML::Value << s.range_bins;
  out << YAML::Key << "vertical_aperture_deg" << YAML::Value << s.vertical_aperture_rad / kDeg;
  out << YAML::Key << "beam_pattern" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << BeamPattern::kind_name(s.beam_pattern.kind);
  if (s.beam_pattern.kind == BeamPattern::Kind::Table) {
    out << YAML::Key << "elevation_deg" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (double e : s.beam_pattern.table_elevation_rad) out << e / kDeg;
    out << YAML::EndSeq;
    out << YAML::Key << "amplitude" << YAML::Value << YAML::Flow << s.beam_pattern.table_amplitude;
  }
  out << YAML::EndMap;
  out << YAML::Key << "intensity" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "bit_depth" << YAML::Value << s.bit_depth;
  out << YAML::Key << "scale" << YAML::Value << s.intensity_scale;
  out << YAML::EndMap;
  const Eigen::Quaterniond q(s.T_vehicle_sonar.linear());
  const Eigen::Vector3d t = s.T_vehicle_sonar.translation();
  out << YAML::Key << "T_vehicle_sonar" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "translation" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x() << t.y()
      << t.z() << YAML::EndSeq;
  out << YAML::Key << "quaternion" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.x() << q.y()
      << q.z() << q.w() << YAML::EndSeq;
  out << YAML::EndMap;
}

}  // namespace sonar3d::yaml
