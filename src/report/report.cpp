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

#include "sonar3d/core/atomic_file.hpp"
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

namespace {

// The files of the web assets directory the page is made of. The first three are the project's
// own (committed); the last two come from npm (`npm ci` in web/, run by scripts/install-deps.sh,
// builds dist/three-bundle.js from three.js and its OrbitControls).
struct WebAssets {
  std::string template_html, css, app_js, plotly_js, three_js;
};

std::string read_asset(const fs::path& dir, const fs::path& rel) {
  const fs::path p = dir / rel;
  if (!fs::is_regular_file(p)) {
    throw Error("report: web asset '" + p.string() +
                "' not found: run scripts/install-deps.sh (it runs `npm ci` in web/), or point "
                "--web-dir / SONAR3D_WEB_DIR at a web directory that holds it");
  }
  return read_text_file(p.string());
}

WebAssets load_web_assets(const fs::path& dir) {
  WebAssets a;
  a.template_html = read_asset(dir, "report_template.html");
  a.css = read_asset(dir, "report.css");
  a.app_js = read_asset(dir, "report.js");
  a.plotly_js = read_asset(dir, "node_modules/plotly.js-basic-dist-min/plotly-basic.min.js");
  a.three_js = read_asset(dir, "dist/three-bundle.js");
  return a;
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (std::size_t pos = s.find(from); pos != std::string::npos; pos = s.find(from, pos)) {
    s.replace(pos, from.size(), to);
    pos += to.size();
  }
}

// A script inlined in <script>...</script> must not contain "</script" (it would end the
// element) nor "<!--" (it changes how the HTML parser reads script text). Both only occur in
// strings, comments or regular expressions, where "<\/" and "<\!" mean the same.
std::string script_safe(std::string js) {
  replace_all(js, "</script", "<\\/script");
  replace_all(js, "</SCRIPT", "<\\/SCRIPT");
  replace_all(js, "<!--", "<\\!--");
  return js;
}

std::string html_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string base64(const void* data, std::size_t n) {
  static const char* tbl = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* b = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < n; i += 3) {
    const unsigned v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2];
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += tbl[(v >> 6) & 63];
    out += tbl[v & 63];
  }
  if (i < n) {
    unsigned v = b[i] << 16;
    if (i + 1 < n) v |= b[i + 1] << 8;
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += (i + 1 < n) ? tbl[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

// Display-only simplification of a large CAD mesh by vertex clustering on a grid: each occupied
// cell keeps the mean of its vertices, triangles that collapse are dropped. The cell grows until
// the mesh has at most `max_tris` triangles.
TriangleMesh simplify_for_display(const TriangleMesh& mesh, std::size_t max_tris) {
  if (mesh.triangles.size() <= max_tris) return mesh;
  const Eigen::AlignedBox3f box = mesh.bounding_box();
  const Eigen::Vector3f lo = box.min();
  const double diag = std::max<double>(box.diagonal().norm(), 1e-9);
  double cell = diag / std::sqrt(static_cast<double>(max_tris));
  for (int attempt = 0; attempt < 40; ++attempt, cell *= 1.3) {
    std::unordered_map<std::uint64_t, int> index;
    std::vector<Eigen::Vector3d> sums;
    std::vector<int> counts;
    std::vector<int> remap(mesh.vertices.size());
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      const Eigen::Vector3f q = ((mesh.vertices[v] - lo).cast<double>() / cell).cast<float>();
      const auto ix = static_cast<std::uint64_t>(std::max(0.f, q.x())) & 0x1fffff;
      const auto iy = static_cast<std::uint64_t>(std::max(0.f, q.y())) & 0x1fffff;
      const auto iz = static_cast<std::uint64_t>(std::max(0.f, q.z())) & 0x1fffff;
      const std::uint64_t key = (ix << 42) | (iy << 21) | iz;
      auto [it, inserted] = index.emplace(key, static_cast<int>(sums.size()));
      if (inserted) {
        sums.emplace_back(Eigen::Vector3d::Zero());
        counts.push_back(0);
      }
      sums[it->second] += mesh.vertices[v].cast<double>();
      counts[it->second] += 1;
      remap[v] = it->second;
    }
    TriangleMesh out;
    for (const auto& t : mesh.triangles) {
      const Eigen::Vector3i r(remap[t[0]], remap[t[1]], remap[t[2]]);
      if (r[0] != r[1] && r[1] != r[2] && r[0] != r[2]) out.triangles.push_back(r);
    }
    if (out.triangles.size() > max_tris) continue;
    out.vertices.resize(sums.size());
    for (std::size_t c = 0; c < sums.size(); ++c) {
      out.vertices[c] = (sums[c] / counts[c]).cast<float>();
    }
    return out;
  }
  return mesh;  // unreachable for finite meshes: the last grid has one cell
}

std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", &tm);
  return buf;
}

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
  } catch (const json::parse_error& e) {
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
  if (name == "error") return ReportColor::Error;
  if (name == "height") return ReportColor::Height;
  throw Error("report: unknown colour mode '" + name + "' (expected error or height)");
}

void ReportConfig::validate() const {
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

ReportSummary write_report(const fs::path& plan_dir, const ReportConfig& cfg) {
  cfg.validate();
  ReportSummary summary;
  summary.output = cfg.output.empty() ? plan_dir / "report.html" : cfg.output;

  // Assets first: a missing `npm ci` should fail before any heavy work.
  const fs::path web_dir = cfg.web_dir.empty() ? default_web_dir() : cfg.web_dir;
  const WebAssets assets = load_web_assets(web_dir);
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
    // Uniform random subsample of the finite points (partial Fisher-Yates, seeded per point id so
    // a point shows the same subset whatever else is in the sweep).
    std::vector<std::uint32_t> idx;
    idx.reserve(cloud.size());
    for (std::size_t k = 0; k < cloud.size(); ++k) {
      if (cloud.points[k].allFinite()) idx.push_back(static_cast<std::uint32_t>(k));
    }
    const std::size_t total = idx.size();
    if (idx.size() > per_cloud) {
      std::mt19937_64 rng(cfg.seed ^ fnv1a(id));
      for (std::size_t k = 0; k < per_cloud; ++k) {
        std::uniform_int_distribution<std::size_t> pick(k, idx.size() - 1);
        std::swap(idx[k], idx[pick(rng)]);
      }
      idx.resize(per_cloud);
      std::sort(idx.begin(), idx.end());
    }
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
  data["generated"] = utc_now();
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

  // JSON inside <script type="application/json">: '<' only occurs inside JSON strings, where
  // \u003c means the same, so no "</script>" or "<!--" can end or confuse the element.
  std::string data_text = data.dump(-1, ' ', false, json::error_handler_t::replace);
  replace_all(data_text, "<", "\\u003c");

  // Fill the template: each placeholder must appear exactly once; positions are found in the
  // template itself so inserted text can never be taken for a placeholder.
  const std::string& tpl = assets.template_html;
  const std::vector<std::pair<std::string, std::string>> parts = {
      {"{{TITLE}}", html_escape(data["title"].get<std::string>())},
      {"/*{{STYLE}}*/", assets.css},
      {"<!--{{LIBS}}-->", "<script>\n" + script_safe(assets.plotly_js) + "\n</script>\n<script>\n" +
                              script_safe(assets.three_js) + "\n</script>"},
      {"<!--{{DATA}}-->",
       "<script type=\"application/json\" id=\"sonar3d-data\">" + data_text + "</script>"},
      {"<!--{{APP}}-->", "<script>\n" + script_safe(assets.app_js) + "\n</script>"}};
  std::vector<std::pair<std::size_t, std::size_t>> at;  // (position in tpl, part index)
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const std::string& ph = parts[k].first;
    const std::size_t pos = tpl.find(ph);
    if (pos == std::string::npos || tpl.find(ph, pos + 1) != std::string::npos) {
      throw Error("report: web asset '" + (web_dir / "report_template.html").string() +
                  "' must contain " + ph + " exactly once");
    }
    at.emplace_back(pos, k);
  }
  std::sort(at.begin(), at.end());
  std::string html;
  std::size_t reserve = tpl.size();
  for (const auto& part : parts) reserve += part.second.size();
  html.reserve(reserve);
  std::size_t cursor = 0;
  for (const auto& [pos, k] : at) {
    html.append(tpl, cursor, pos - cursor);
    html += parts[k].second;
    cursor = pos + parts[k].first.size();
  }
  html.append(tpl, cursor, std::string::npos);

  write_text_file(summary.output.string(), html);
  summary.bytes = html.size();
  return summary;
}

}  // namespace sonar3d
