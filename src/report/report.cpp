#include "sonar3d/report/report.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <unordered_map>

#include "page.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/mesh_io.hpp"

namespace fs = std::filesystem;
// ordered_json keeps the file's key order: axes and parameters appear in sweep order.
using json = nlohmann::ordered_json;

namespace sonar3d {

using report_page::base64;
using report_page::simplify_for_display;

namespace {

// Loads and checks results.json (docs/report.md); every error names the file and the entry.
json load_results(const fs::path& plan_dir) {
  const fs::path path = plan_dir / "results.json";
  if (!fs::is_directory(plan_dir)) {
    throw Error("report: plan directory '" + plan_dir.string() + "' does not exist");
  }
  if (!fs::is_regular_file(path)) {
    throw Error("report: '" + path.string() + "' not found: run `sonar3d plan SWEEP.yaml -o " +
                plan_dir.string() + "` first (it writes results.json)");
  }
  json r;
  try {
    r = json::parse(read_text_file(path.string()));
  } catch (const json::exception& e) {  // parse_error, or out_of_range for a number beyond double
    throw Error("report: '" + path.string() + "' is malformed JSON: " + e.what());
  }
  const std::string where = "report: '" + path.string() + "': ";
  if (!r.is_object()) throw Error(where + "the top level must be a JSON object");
  if (!r.contains("points") || !r["points"].is_array()) {
    throw Error(where + "'points' must be an array of configuration points");
  }
  std::set<std::string> ids;
  for (std::size_t i = 0; i < r["points"].size(); ++i) {
    json& p = r["points"][i];
    const std::string at = where + "points[" + std::to_string(i) + "]: ";
    if (!p.is_object()) throw Error(at + "must be an object");
    if (!p.contains("id") || !p["id"].is_string() || p["id"].get<std::string>().empty()) {
      throw Error(at + "missing string 'id'");
    }
    const std::string id = p["id"].get<std::string>();
    if (!ids.insert(id).second) throw Error(at + "duplicate id '" + id + "'");
    if (!p.contains("status") || !p["status"].is_string()) {
      throw Error(at + "(id '" + id + "') missing string 'status'");
    }
    if (!p.contains("params") || p["params"].is_null()) p["params"] = json::object();
    if (!p["params"].is_object()) throw Error(at + "(id '" + id + "') 'params' must be an object");
    if (p.contains("metrics") && !p["metrics"].is_null() && !p["metrics"].is_object()) {
      throw Error(at + "(id '" + id + "') 'metrics' must be an object or null");
    }
    if (p.contains("cloud") && !p["cloud"].is_null() && !p["cloud"].is_string()) {
      throw Error(at + "(id '" + id + "') 'cloud' must be a path string or null");
    }
    if (p.contains("objects") && !p["objects"].is_null()) {
      if (!p["objects"].is_array()) {
        throw Error(at + "(id '" + id + "') 'objects' must be an array of object names");
      }
      for (const auto& o : p["objects"]) {
        if (!o.is_string()) throw Error(at + "(id '" + id + "') 'objects' must hold strings");
      }
    }
  }
  // The swept axes in sweep order; derived from the points' parameters when absent.
  if (!r.contains("axes") || r["axes"].is_null()) {
    json axes = json::object();
    for (const auto& p : r["points"]) {
      for (const auto& [k, v] : p["params"].items()) {
        if (!axes.contains(k)) axes[k] = json::array();
        if (std::find(axes[k].begin(), axes[k].end(), v) == axes[k].end()) axes[k].push_back(v);
      }
    }
    r["axes"] = axes;
  } else {
    if (!r["axes"].is_object()) throw Error(where + "'axes' must be an object of value arrays");
    for (const auto& [k, v] : r["axes"].items()) {
      if (!v.is_array()) throw Error(where + "axes['" + k + "'] must be an array of values");
    }
  }
  return r;
}

struct Truth {
  TriangleMesh mesh;
  bool ok = false;
};

}  // namespace

ReportColor parse_report_color(const std::string& name) {
  return parse_enum<ReportColor>(kReportColorNames, name, "report colour mode");
}

void ReportConfig::validate() const {
  params::check(*this, "report");
  require(max_points_per_cloud >= 1, "report: max_points_per_cloud must be >= 1");
  require(max_points_total >= 1, "report: max_points_total must be >= 1");
  require(max_mesh_triangles >= 100, "report: max_mesh_triangles must be >= 100");
  require_non_negative(error_color_max, "report: error_color_max", "m");
}

fs::path default_web_dir() {
  if (const char* env = std::getenv("SONAR3D_WEB_DIR"); env != nullptr && *env != '\0') {
    return fs::path(env);
  }
  // Installed: <prefix>/bin/sonar3d finds <prefix>/share/sonar3d/web wherever the prefix was
  // installed or moved to (SONAR3D_WEB_DIR_FROM_BIN is that relative path, src/CMakeLists.txt).
  std::error_code ec;
  fs::path installed;
#ifdef SONAR3D_WEB_DIR_FROM_BIN
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && !exe.empty()) {
    installed = (exe.parent_path() / SONAR3D_WEB_DIR_FROM_BIN).lexically_normal();
    if (fs::is_regular_file(installed / "report_template.html", ec)) return installed;
  }
#endif
  // Development: a build that is not installed reads the source tree's web/.
#ifdef SONAR3D_SOURCE_DIR
  const fs::path source = fs::path(SONAR3D_SOURCE_DIR) / "web";
#else
  const fs::path source = fs::path(__FILE__).parent_path().parent_path().parent_path() / "web";
#endif
  if (installed.empty() || fs::is_directory(source, ec)) return source;
  return installed;  // neither exists: the error then names the installed location
}

const char* report_input_name(ReportInput kind) {
  static constexpr const char* kNames[] = {"sweep", "map", "world", "changes",
                                           "ply"};  // by ReportInput
  return enum_name(kNames, kind);
}

ReportInput detect_report_input(const fs::path& input) {
  std::error_code ec;
  if (fs::is_regular_file(input, ec)) {
    std::ifstream f(input, std::ios::binary);
    char magic[4] = {};
    f.read(magic, 4);
    if (f.gcount() == 4 && std::string(magic, 3) == "ply" &&
        (magic[3] == '\n' || magic[3] == '\r')) {
      return ReportInput::Ply;
    }
    throw Error("report: '" + input.string() +
                "' is a file but not a PLY (no 'ply' magic line): give a PLY cloud or mesh, or a "
                "directory of sonar3d plan, map, world or diff");
  }
  if (!fs::is_directory(input, ec)) {
    throw Error("report: '" + input.string() + "' does not exist");
  }
  if (fs::exists(input / "results.json", ec)) return ReportInput::Sweep;
  if (fs::exists(input / "graph.json", ec)) return ReportInput::World;
  if (fs::exists(input / "changes.json", ec)) return ReportInput::Changes;
  if (fs::exists(input / "merged.ply", ec)) return ReportInput::Map;
  throw Error("report: '" + input.string() +
              "' holds none of results.json (run `sonar3d plan SWEEP.yaml -o " + input.string() +
              "` first), graph.json (`sonar3d world`), changes.json (`sonar3d diff`) or "
              "merged.ply (`sonar3d map`)");
}

namespace {

ReportSummary write_sweep_report(const fs::path& plan_dir, const ReportConfig& cfg) {
  ReportSummary summary;
  summary.output = cfg.output.empty() ? plan_dir / "report.html" : cfg.output;
  report_page::check_replaceable(summary.output);

  // Assets first: a missing `npm ci` should fail before any heavy work.
  const fs::path web_dir = cfg.web_dir.empty() ? default_web_dir() : cfg.web_dir;
  const report_page::WebAssets assets = report_page::load_web_assets(web_dir, "report.js", true);
  json results = load_results(plan_dir);
  json& points = results["points"];
  summary.num_points = points.size();

  auto resolve = [&](const std::string& rel) {
    const fs::path p(rel);
    return p.is_absolute() ? p : plan_dir / p;
  };

  // Points with a cloud to show, and the per-cloud point budget shared evenly over them.
  std::vector<std::size_t> with_cloud;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const json& p = points[i];
    const std::string status = p["status"].get<std::string>();
    if (status == "ok") ++summary.num_ok;
    if (status == "failed") ++summary.num_failed;
    if (p.contains("cloud") && p["cloud"].is_string()) with_cloud.push_back(i);
  }
  const std::size_t per_cloud =
      with_cloud.empty()
          ? cfg.max_points_per_cloud
          : std::max<std::size_t>(
                1, std::min(cfg.max_points_per_cloud, cfg.max_points_total / with_cloud.size()));

  std::map<std::string, Truth> truths;  // by object name
  auto truth_of = [&](const std::string& name) -> Truth& {
    auto it = truths.find(name);
    if (it != truths.end()) return it->second;
    Truth& t = truths[name];
    const fs::path p = plan_dir / "truth" / (name + ".ply");
    if (!fs::is_regular_file(p)) {
      summary.warnings.push_back("truth mesh '" + p.string() + "' not found: clouds of object '" +
                                 name + "' are shown without it, coloured by height");
      return t;
    }
    try {
      t.mesh = load_mesh(p.string());
      t.ok = !t.mesh.empty();
      if (!t.ok) summary.warnings.push_back("truth mesh '" + p.string() + "' has no triangles");
    } catch (const std::exception& e) {
      summary.warnings.push_back(std::string("truth mesh unreadable: ") + e.what());
    }
    return t;
  };
  std::map<std::string, std::unique_ptr<MeshDistance>> distance_by_set;  // key: "a+b"

  json clouds = json::object();
  json extras = json::object();
  Progress progress("report", with_cloud.size(), cfg.progress);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const json& p = points[i];
    const std::string id = p["id"].get<std::string>();
    const bool ok = p["status"].get<std::string>() == "ok";
    json extra = json::object();
    // Per-object metrics (same JSON as `sonar3d evaluate --json`), for the viewer's side panel.
    const fs::path metrics_path = plan_dir / "points" / id / "metrics.json";
    if (fs::is_regular_file(metrics_path)) {
      try {
        extra["object_metrics"] = json::parse(read_text_file(metrics_path.string()));
      } catch (const std::exception& e) {
        summary.warnings.push_back("'" + metrics_path.string() + "' ignored: " + e.what());
      }
    }
    if (!(p.contains("cloud") && p["cloud"].is_string())) {
      extra["cloud_status"] = "none";
      extras[id] = extra;
      continue;
    }
    const fs::path cloud_path = resolve(p["cloud"].get<std::string>());
    PointCloud cloud;
    try {
      if (!fs::is_regular_file(cloud_path)) throw Error("file not found");
      cloud = read_ply(cloud_path.string());
    } catch (const std::exception& e) {
      const bool missing = !fs::is_regular_file(cloud_path);
      extra["cloud_status"] = missing ? "missing" : "unreadable";
      extra["cloud_message"] =
          missing ? "cloud file '" + cloud_path.string() + "' not found" : std::string(e.what());
      if (ok) {
        summary.warnings.push_back("point " + id + ": " +
                                   extra["cloud_message"].get<std::string>() +
                                   "; listed without a cloud");
      }
      extras[id] = extra;
      progress.add();
      continue;
    }
    // Uniform random subsample of the finite points, seeded per point id so a point shows the
    // same subset whatever else is in the sweep.
    std::size_t total = 0;
    const std::vector<std::uint32_t> idx =
        report_page::subsample(cloud, per_cloud, cfg.seed ^ report_page::fnv1a(id), &total);
    std::vector<Eigen::Vector3f> shown(idx.size());
    std::vector<float> xyz(idx.size() * 3);
    for (std::size_t k = 0; k < idx.size(); ++k) {
      shown[k] = cloud.points[idx[k]];
      for (int c = 0; c < 3; ++c) xyz[3 * k + c] = shown[k][c];
    }
    json jc = json::object();
    jc["num_shown"] = idx.size();
    jc["num_total"] = total;
    jc["xyz"] = base64(xyz.data(), xyz.size() * sizeof(float));

    // Per-point error: distance to the union of the point's truth meshes.
    std::vector<std::string> names;
    if (p.contains("objects") && p["objects"].is_array()) {
      for (const auto& o : p["objects"]) names.push_back(o.get<std::string>());
    }
    std::sort(names.begin(), names.end());
    names.erase(std::unique(names.begin(), names.end()), names.end());
    json objects = json::array();
    TriangleMesh truth_union;
    std::string key;
    for (const auto& n : names) {
      Truth& t = truth_of(n);
      if (!t.ok) continue;
      objects.push_back(n);
      key += (key.empty() ? "" : "+") + n;
    }
    jc["objects"] = objects;
    if (!key.empty() && !shown.empty()) {
      auto& md = distance_by_set[key];
      if (!md) {
        for (const auto& n : objects) truth_union.append(truths[n.get<std::string>()].mesh);
        md = std::make_unique<MeshDistance>(truth_union);
      }
      const std::vector<double> d = md->distances(shown);
      std::vector<float> err(d.begin(), d.end());
      jc["err"] = base64(err.data(), err.size() * sizeof(float));
    } else {
      jc["err"] = nullptr;
    }
    clouds[id] = jc;
    extra["cloud_status"] = "shown";
    extras[id] = extra;
    ++summary.num_clouds;
    summary.num_cloud_points += idx.size();
    progress.add();
  }
  progress.finish();

  // Every truth mesh referenced by a point, once, simplified for display when very large.
  json meshes = json::object();
  for (const auto& p : points) {
    if (!(p.contains("objects") && p["objects"].is_array())) continue;
    for (const auto& o : p["objects"]) truth_of(o.get<std::string>());
  }
  for (const auto& [name, t] : truths) {
    if (!t.ok) continue;
    const TriangleMesh shown = simplify_for_display(t.mesh, cfg.max_mesh_triangles);
    std::vector<float> v(shown.vertices.size() * 3);
    for (std::size_t k = 0; k < shown.vertices.size(); ++k) {
      for (int c = 0; c < 3; ++c) v[3 * k + c] = shown.vertices[k][c];
    }
    std::vector<std::uint32_t> f(shown.triangles.size() * 3);
    for (std::size_t k = 0; k < shown.triangles.size(); ++k) {
      for (int c = 0; c < 3; ++c) f[3 * k + c] = static_cast<std::uint32_t>(shown.triangles[k][c]);
    }
    json jm = json::object();
    jm["num_triangles"] = shown.triangles.size();
    jm["num_triangles_full"] = t.mesh.triangles.size();
    jm["vertices"] = base64(v.data(), v.size() * sizeof(float));
    jm["triangles"] = base64(f.data(), f.size() * sizeof(std::uint32_t));
    meshes[name] = jm;
  }

  json data = json::object();
  data["format"] = 1;
  const std::string dir_name = fs::absolute(plan_dir).lexically_normal().filename().string();
  data["title"] = cfg.title.empty() ? "sonar3d sweep: " + dir_name : cfg.title;
  data["plan_dir"] = fs::absolute(plan_dir).lexically_normal().string();
  data["generated"] = report_page::utc_now();
  data["results"] = results;
  data["color_mode"] = cfg.color == ReportColor::Error ? "error" : "height";
  data["error_color_max_m"] = cfg.error_color_max > 0 ? json(cfg.error_color_max) : json(nullptr);
  data["max_points_per_cloud"] = per_cloud;
  data["clouds"] = clouds;
  data["meshes"] = meshes;
  data["extras"] = extras;
  data["warnings"] = summary.warnings;
  const fs::path sweep_path = plan_dir / "sweep.yaml";
  data["sweep_yaml"] =
      fs::is_regular_file(sweep_path) ? json(read_text_file(sweep_path.string())) : json(nullptr);

  const std::string html =
      report_page::fill_page(assets, data["title"].get<std::string>(),
                             data.dump(-1, ' ', false, json::error_handler_t::replace));
  write_text_file(summary.output.string(), html);
  summary.bytes = html.size();
  return summary;
}

}  // namespace

ReportSummary write_report(const fs::path& input, const ReportConfig& cfg) {
  cfg.validate();
  const ReportInput kind = detect_report_input(input);
  ReportSummary s = kind == ReportInput::Sweep ? write_sweep_report(input, cfg)
                                               : report_page::write_scene_report(input, kind, cfg);
  s.input = kind;
  return s;
}

}  // namespace sonar3d
