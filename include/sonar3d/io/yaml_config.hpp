#pragma once
// YAML helpers shared by every configuration file: values are read with the file, line and key
// named in any error, unknown keys are rejected.
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <set>
#include <string>
#include <vector>

#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d::yaml {

// Parses a YAML file; a syntax error names file and line.
YAML::Node load_file(const std::string& path);

// "file:line: key 'a.b'" for error messages.
std::string where(const std::string& file, const YAML::Node& node, const std::string& key);

double get_double(const YAML::Node& parent, const std::string& key, const std::string& file,
                  const std::string& ctx = "");
double get_double(const YAML::Node& parent, const std::string& key, double fallback,
                  const std::string& file, const std::string& ctx = "");
int get_int(const YAML::Node& parent, const std::string& key, int fallback,
            const std::string& file, const std::string& ctx = "");
std::string get_string(const YAML::Node& parent, const std::string& key,
                       const std::string& fallback, const std::string& file,
                       const std::string& ctx = "");
bool get_bool(const YAML::Node& parent, const std::string& key, bool fallback,
              const std::string& file, const std::string& ctx = "");
std::vector<double> get_vector(const YAML::Node& parent, const std::string& key,
                               std::size_t expected_size, const std::string& file,
                               const std::string& ctx = "");
// Throws naming the first key of `node` that is not in `allowed`.
void check_keys(const YAML::Node& node, const std::set<std::string>& allowed,
                const std::string& file, const std::string& ctx = "");

// A pose {translation: [x,y,z], rpy_deg: [roll,pitch,yaw]} or {translation, quaternion:
// [qx,qy,qz,qw]}. Roll about x, pitch about y, yaw about z: R = Rz(yaw)·Ry(pitch)·Rx(roll).
Eigen::Isometry3d get_pose(const YAML::Node& node, const std::string& file,
                           const std::string& ctx);
Eigen::Isometry3d pose_from_rpy(const Eigen::Vector3d& t, double roll, double pitch, double yaw);

// The sensor fields of sonar.yaml (and of a scene's `sensor:` block, which may start from
// `preset:`). Validates the result.
SonarSpec parse_sonar_spec(const YAML::Node& node, const std::string& file,
                           const std::string& ctx = "");
void emit_sonar_spec(YAML::Emitter& out, const SonarSpec& spec);

}  // namespace sonar3d::yaml
