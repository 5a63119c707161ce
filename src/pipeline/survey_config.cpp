// The survey's configuration: one declaration per option (the commands' own describe() for
// import, map, recognize and world; survey_options.hpp's visit() for texture and report), from
// which the YAML reading, the printed configuration and the stage stamps all derive.
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
#include "sonar3d/video/texture.hpp"
#include "sonar3d/world/world_model.hpp"
#include "survey_options.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

// Defaults: the library configs' (what each command starts from).
SurveyTextureOptions::SurveyTextureOptions() {
  const TextureConfig c;
  point_spacing = c.point_spacing_m;
  depth_tolerance = c.depth_tolerance_m;
  max_range = c.max_range_m;
}

SurveyReportOptions::SurveyReportOptions() {
  const ReportConfig c;
  max_points = static_cast<long long>(c.max_points_per_cloud);
  max_total_points = static_cast<long long>(c.max_points_total);
  max_mesh_triangles = static_cast<long long>(c.max_mesh_triangles);
  error_max = c.error_color_max;
  seed = static_cast<long long>(c.seed);
}

namespace survey_detail {

namespace {

// Reads each declared option present in a stage's mapping.
struct Loader {
  const YAML::Node& node;
  const std::string& file;
  std::string ctx;
  fs::path base;  // relative paths are taken from the configuration file's directory
  std::set<std::string> keys;

  YAML::Node get(const char* k) {
    keys.insert(k);
    return node.IsMap() ? node[k] : YAML::Node();
  }
  void operator()(const char* k, double& x) {
    if (get(k)) x = yaml::get_double(node, k, file, ctx);
  }
  void operator()(const char* k, int& x) {
    if (get(k)) x = yaml::get_int(node, k, x, file, ctx);
  }
  void operator()(const char* k, long long& x) {
    if (!get(k)) return;
    const double v = yaml::get_double(node, k, file, ctx);
    if (v != std::floor(v) || std::abs(v) > 9e15) {
      throw Error(yaml::where(file, node[k], ctx + "." + k) + ": expected an integer");
    }
    x = static_cast<long long>(v);
  }
  void operator()(const char* k, bool& x) {
    if (get(k)) x = yaml::get_bool(node, k, x, file, ctx);
  }
  void operator()(const char* k, std::string& x) {
    const YAML::Node n = get(k);
    if (!n) return;
    x = n.IsNull() ? std::string() : yaml::get_string(node, k, x, file, ctx);
  }
  void operator()(const char* k, std::vector<double>& x) {
    const YAML::Node n = get(k);
    if (!n) return;
    x = n.IsNull() ? std::vector<double>() : yaml::get_vector(node, k, 0, file, ctx);
  }
  void path(const char* k, std::string& x) {
    (*this)(k, x);
    if (!x.empty() && fs::path(x).is_relative() && node[k]) x = (base / x).lexically_normal();
  }
};

// The options as YAML lines ("  key: value"), every key, in declaration order.
struct Emitter {
  std::string out;
  std::string indent = "  ";
  static std::string quote(const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') {
        q += '\\';
        q += c;
      } else if (c == '\n') {
        q += "\\n";
      } else if (c == '\t') {
        q += "\\t";
      } else {
        q += c;
      }
    }
    return q + "\"";
  }
  void line(const char* k, const std::string& v) { out += indent + k + ": " + v + "\n"; }
  void operator()(const char* k, const double& x) { line(k, fmt::format("{}", x)); }
  void operator()(const char* k, const int& x) { line(k, std::to_string(x)); }
  void operator()(const char* k, const long long& x) { line(k, std::to_string(x)); }
  void operator()(const char* k, const bool& x) { line(k, x ? "true" : "false"); }
  void operator()(const char* k, const std::string& x) { line(k, quote(x)); }
  void operator()(const char* k, const std::vector<double>& x) {
    std::string s = "[";
    for (std::size_t i = 0; i < x.size(); ++i) s += (i ? ", " : "") + fmt::format("{}", x[i]);
    line(k, s + "]");
  }
  void path(const char* k, const std::string& x) { (*this)(k, x); }
};

template <class Opts>
void load_stage(const YAML::Node& root, const char* stage, const std::string& file,
                const fs::path& base, Opts& opts) {
  const YAML::Node node = root[stage];
  if (!node || node.IsNull()) return;
  if (!node.IsMap()) throw Error(yaml::where(file, node, stage) + ": expected a mapping");
  Loader l{node, file, stage, base, {}};
  visit(opts, l);
  yaml::check_keys(node, l.keys, file, stage);
}

}  // namespace

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

template <class Opts>
std::string stage_yaml(const Opts& opts) {
  Emitter e;
  visit(const_cast<Opts&>(opts), e);  // the emitter only reads
  return e.out;
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
  // The map's, the recognition's and the world's own declarations (core/params.hpp): the keys of
  // their commands' --print-config.
  if (stage == "recognize") return params_yaml(c.recognize);
  if (stage == "world") return params_yaml(c.world);
  if (stage == "map") return params_yaml(c.map);
  if (stage == "texture") return stage_yaml(c.texture);
  if (stage == "report") return stage_yaml(c.report);
  throw Error("no survey stage '" + stage + "'");
}

// A key of the flat import block of earlier versions (`nav`, `static`, `rate`, ... : the import
// flags' names) is an error that names where that setting lives now: the importers' fields whose
// flag or name it is (`import.aris.navigation`, `import.oculus.navigation`).
void check_import_keys(const YAML::Node& n, const std::string& file) {
  if (!n.IsMap()) return;  // the reader says what is wrong
  const std::vector<params::Row> rows = params::rows(SurveyImportOptions());
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
      if (flag == k || leaf == k) now += (now.empty() ? "" : ", ") + ("import." + r.path);
    }
    if (!now.empty()) {
      throw Error(yaml::where(file, kv.first, "import." + k) +
                  ": the import block holds each importer's own settings under its kind "
                  "(docs/survey.md): write " +
                  now);
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
    check_import_keys(n, path);
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
  load_stage(root, "texture", path, base, c.texture);
  load_stage(root, "report", path, base, c.report);
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
