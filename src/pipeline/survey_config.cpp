// The survey's configuration: one declaration per option (each stage's command's own describe(),
// survey_pipeline.hpp), from which the YAML reading, the printed configuration and the stage
// stamps all derive.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/pipeline/survey_pipeline.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/world_model.hpp"
#include "survey_options.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace survey_detail {

// A config declared with core/params.hpp as the stage's indented YAML lines.
template <class C>
std::string params_yaml(const C& config) {
  YAML::Emitter e;
  params::emit_yaml(e, config);
  std::string out;
  std::istringstream lines(e.c_str());
  for (std::string line; std::getline(lines, line);) out += "  " + line + "\n";
  return out;
}

// The importer's block of `kind` (none for a dataset), under the kind's key.
template <class C>
std::string import_block(const char* kind, const C& config) {
  std::string out = std::string("  ") + kind + ":\n";
  std::istringstream lines(params_yaml(config));
  for (std::string line; std::getline(lines, line);) out += "  " + line + "\n";
  return out;
}

std::string stage_settings(const SurveyConfig& c, const std::string& stage,
                           const std::string& kind) {
  if (stage == "import") {
    // The importers' own declarations (io/*.hpp): the keys of `sonar3d import <kind>
    // --print-config`, one block per kind. A stamp holds the block of the kind imported only.
    if (kind.empty()) return params_yaml(c.import);
    std::string s = "  kind: " + kind + "\n";
    if (kind == "aris") s += import_block("aris", c.import.aris);
    if (kind == "rosbag") s += import_block("rosbag", c.import.rosbag);
    if (kind == "oculus") s += import_block("oculus", c.import.oculus);
    if (kind == "holoocean") s += import_block("holoocean", c.import.holoocean);
    return s;
  }
  // The other stages' commands' own declarations (core/params.hpp): the keys of their
  // --print-config.
  if (stage == "recognize") return params_yaml(c.recognize);
  if (stage == "world") return params_yaml(c.world);
  if (stage == "map") return params_yaml(c.map);
  if (stage == "texture") return params_yaml(c.texture);
  if (stage == "report") return params_yaml(c.report);
  throw Error("no survey stage '" + stage + "'");
}

// A key of a stage's block as earlier versions named it (the import's flat block: `nav`,
// `static`, `rate`, ...; the texture's `point_spacing`, `max_range`: the flags' names) is an
// error that names where that setting lives now: the declared fields whose flag or name it is
// (`import.aris.navigation`, `texture.point_spacing_m`).
template <class C>
void check_moved_keys(const YAML::Node& n, const C& config, const std::string& stage,
                      const std::string& file, const std::string& why) {
  if (!n.IsMap()) return;  // the reader says what is wrong
  const std::vector<params::Row> rows = params::rows(config);
  for (const auto& kv : n) {
    const std::string k = kv.first.Scalar();
    std::string now;
    for (const params::Row& r : rows) {
      if (r.path == k || r.path.rfind(k + ".", 0) == 0) {
        now.clear();  // a key of the block
        break;
      }
      std::string flag = r.flag.rfind("--", 0) == 0 ? r.flag.substr(2) : r.flag;
      std::replace(flag.begin(), flag.end(), '-', '_');
      const std::string leaf = r.path.substr(r.path.rfind('.') + 1);
      if (flag == k || leaf == k) now += (now.empty() ? "" : ", ") + (stage + "." + r.path);
    }
    if (!now.empty()) {
      throw Error(yaml::where(file, kv.first, stage + "." + k) + ": " + why + ": write " + now);
    }
  }
}

}  // namespace survey_detail

SurveyConfig load_survey_config(const std::string& path, const fs::path& base_dir) {
  using namespace survey_detail;
  const YAML::Node root = yaml::load_file(path);
  SurveyConfig c;
  if (!root || root.IsNull()) return c;  // an empty file: every default
  yaml::check_keys(root, {"import", "map", "recognize", "world", "texture", "report"}, path);
  const fs::path base =
      base_dir.empty() ? fs::absolute(fs::path(path)).parent_path() : fs::absolute(base_dir);
  if (const YAML::Node n = root["import"]; n && !n.IsNull()) {
    check_moved_keys(n, c.import, "import", path,
                     "the import block holds each importer's own settings under its kind "
                     "(docs/survey.md)");
    params::read_yaml(n, path, "import", c.import);
    // The importers' file paths: relative to the configuration file.
    for (std::string* p : {&c.import.aris.navigation, &c.import.oculus.navigation,
                           &c.import.rosbag.sonar_description}) {
      if (!p->empty() && fs::path(*p).is_relative()) *p = (base / *p).lexically_normal().string();
    }
  }
  if (const YAML::Node n = root["map"]; n && !n.IsNull()) {
    params::read_yaml(n, path, "map", c.map);
  }
  if (const YAML::Node n = root["recognize"]; n && !n.IsNull()) {
    params::read_yaml(n, path, "recognize", c.recognize);
  }
  if (const YAML::Node n = root["world"]; n && !n.IsNull()) {
    params::read_yaml(n, path, "world", c.world);
    const fs::path given = c.world.connections;
    if (!given.empty() && given.is_relative() && n["connections"]) {
      c.world.connections = (base / given).lexically_normal().string();
    }
  }
  if (const YAML::Node n = root["texture"]; n && !n.IsNull()) {
    check_moved_keys(n, c.texture, "texture", path,
                     "the texture block holds the keys of `sonar3d texture --print-config` "
                     "(docs/survey.md)");
    params::read_yaml(n, path, "texture", c.texture);
  }
  if (const YAML::Node n = root["report"]; n && !n.IsNull()) {
    params::read_yaml(n, path, "report", c.report);
    const fs::path given = c.report.web_dir;
    if (!given.empty() && given.is_relative() && n["web_dir"]) {
      c.report.web_dir = (base / given).lexically_normal().string();
    }
  }
  return c;
}

std::string survey_config_yaml(const SurveyConfig& c) {
  using namespace survey_detail;
  std::string s =
      "# sonar3d survey configuration (docs/survey.md): each stage's block as its command's "
      "--print-config prints it\n";
  for (const char* stage : {"import", "map", "recognize", "world", "texture", "report"}) {
    s += std::string(stage) + ":\n" + stage_settings(c, stage);
  }
  return s;
}

}  // namespace sonar3d
