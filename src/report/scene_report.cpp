// The 3D scene pages of `sonar3d report`: a map directory with placed models (thesis sec. 6.3),
// a world model (sec. 6.3.3, Fig. 6.18: seabed levels of detail, registered CAD models and their
// graph), a change directory between two surveys, and PLY clouds or meshes in their own colours
// (video texturing, sec. 6.4). Layout of the page data: docs/report.md, "Scene pages".
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "page.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/report/scene_files.hpp"
#include "sonar3d/world/world_model.hpp"

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace sonar3d::report_page {

namespace {

using Rgb = std::array<std::uint8_t, 3>;

// Colours of models (by first appearance of the model name) and of markers.
const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
                                "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

Rgb hex_rgb(const std::string& hex) {
  const unsigned long v = std::stoul(hex.substr(1), nullptr, 16);
  return {static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8),
          static_cast<std::uint8_t>(v)};
}

std::string fmt_bytes(long long b) {
  char buf[32];
  if (b >= 1000000) {
    std::snprintf(buf, sizeof buf, "%.1f MB", b / 1e6);
  } else if (b >= 1000) {
    std::snprintf(buf, sizeof buf, "%.1f kB", b / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%lld B", b);
  }
  return buf;
}

// A PLY file read as a cloud, or as a mesh when it has faces (polygons split into fans).
struct PlyData {
  PointCloud cloud;  // the vertices and their colours / properties
  TriangleMesh mesh;
  bool is_mesh = false;
};

// Whether the PLY header declares faces (read_ply keeps a cloud's extra vertex properties, such as
// change_m; read_ply_faces reads the faces). The readers check the file itself.
bool ply_has_faces(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  std::string line;
  for (int n = 0; n < 10000 && std::getline(f, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line == "end_header") break;
    std::istringstream in(line);
    std::string word, name, count;
    in >> word >> name >> count;
    if (word == "element" && name == "face") return count != "0";
  }
  return false;
}

PlyData read_any_ply(const fs::path& path) {
  if (!fs::is_regular_file(path)) throw Error("report: '" + path.string() + "' not found");
  PlyData d;
  if (!ply_has_faces(path)) {
    d.cloud = read_ply(path.string());
    return d;
  }
  std::vector<std::vector<std::uint32_t>> faces;
  d.cloud = read_ply_faces(path.string(), &faces);
  d.is_mesh = !faces.empty();
  d.mesh.vertices = d.cloud.points;
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const auto& face = faces[f];
    if (face.size() < 3) {
      throw Error("report: '" + path.string() + "': face " + std::to_string(f) + " has " +
                  std::to_string(face.size()) + " vertices (at least 3 needed)");
    }
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      d.mesh.triangles.emplace_back(static_cast<int>(face[0]), static_cast<int>(face[k]),
                                    static_cast<int>(face[k + 1]));
    }
  }
  return d;
}

double yaw_deg(const Eigen::Matrix4d& T) { return std::atan2(T(1, 0), T(0, 0)) * 180.0 / M_PI; }
json num_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
json round_to(double v, double step) {
  return std::isfinite(v) ? json(std::round(v / step) * step) : json(nullptr);
}

// Collects the layers, tables and cards of a scene page and encodes them (base64 of
// little-endian Float32 positions and scalars, Uint32 triangle indices, Uint8 colours).
class Scene {
 public:
  Scene(const ReportConfig& cfg, ReportSummary& summary) : cfg_(cfg), summary_(summary) {}

  std::string model_color(const std::string& model) {
    auto it = model_colors_.find(model);
    if (it != model_colors_.end()) return it->second;
    const std::string c = kPalette[model_colors_.size() % kPaletteSize];
    model_colors_[model] = c;
    return c;
  }

  // A cloud: coloured by its own colours, by a signed `change_m` property (diverging scale) or
  // by height; the page offers each mode the cloud has. Encoded in finish(), when the point
  // budget is shared over all clouds of the page.
  void points(const std::string& id, const std::string& name, PointCloud cloud) {
    pending_.push_back({id, name, std::move(cloud), layers_.size()});
    layers_.push_back(json());
  }

  // A mesh, coloured by its vertex colours when `colors` holds one per vertex, else by `color`
  // ("height": by z) ; `group` names a set of meshes of which the page shows one at a time.
  void mesh(const std::string& id, const std::string& name, const TriangleMesh& full,
            std::vector<Rgb> colors, const std::string& color, double opacity, bool visible,
            const std::string& group = "") {
    const bool rgb = !colors.empty() && colors.size() == full.vertices.size();
    if (!rgb) colors.clear();
    const TriangleMesh m = simplify_for_display(full, cfg_.max_mesh_triangles, &colors);
    std::vector<float> v(m.vertices.size() * 3);
    for (std::size_t k = 0; k < m.vertices.size(); ++k) {
      for (int c = 0; c < 3; ++c) v[3 * k + c] = m.vertices[k][c];
    }
    std::vector<std::uint32_t> f(m.triangles.size() * 3);
    for (std::size_t k = 0; k < m.triangles.size(); ++k) {
      for (int c = 0; c < 3; ++c) f[3 * k + c] = static_cast<std::uint32_t>(m.triangles[k][c]);
    }
    json j = base(id, name, "mesh", visible);
    j["xyz"] = base64(v.data(), v.size() * sizeof(float));
    j["triangles"] = base64(f.data(), f.size() * sizeof(std::uint32_t));
    j["rgb"] = rgb ? json(base64(colors.data(), colors.size() * 3)) : json(nullptr);
    j["color"] = color;
    j["opacity"] = opacity;
    j["group"] = group.empty() ? json(nullptr) : json(group);
    j["count"] = m.triangles.size();
    j["num_total"] = full.triangles.size();
    layers_.push_back(j);
    summary_.num_mesh_triangles += m.triangles.size();
  }

  // Line segments: endpoints a0 b0 a1 b1 ..., one colour per endpoint.
  void lines(const std::string& id, const std::string& name,
             const std::vector<Eigen::Vector3f>& ends, const std::vector<Rgb>& colors) {
    std::vector<float> v(ends.size() * 3);
    for (std::size_t k = 0; k < ends.size(); ++k) {
      for (int c = 0; c < 3; ++c) v[3 * k + c] = ends[k][c];
    }
    json j = base(id, name, "lines", true);
    j["xyz"] = base64(v.data(), v.size() * sizeof(float));
    j["rgb"] = base64(colors.data(), colors.size() * 3);
    j["count"] = ends.size() / 2;
    j["num_total"] = ends.size() / 2;
    layers_.push_back(j);
  }

  // `focus`: per row, the layer a click on the row brings into view (or null).
  void table(const std::string& id, const std::string& title, const json& columns, const json& rows,
             const json& focus = nullptr) {
    tables_.push_back(
        {{"id", id}, {"title", title}, {"columns", columns}, {"rows", rows}, {"focus", focus}});
    summary_.num_table_rows += rows.size();
  }
  void card(const std::string& k, const json& v) { cards_.push_back({{"k", k}, {"v", v}}); }
  // A picture (SVG) shown above the tables, with a title and a caption.
  void figure(const std::string& id, const std::string& title, const std::string& svg,
              const std::string& caption) {
    figures_.push_back({{"id", id}, {"title", title}, {"svg", svg}, {"caption", caption}});
  }
  void legend(const std::string& color, const std::string& text) {
    legend_.push_back({{"color", color}, {"text", text}});
  }

  json finish() {
    const std::size_t per_cloud =
        pending_.empty()
            ? cfg_.max_points_per_cloud
            : std::max<std::size_t>(
                  1, std::min(cfg_.max_points_per_cloud, cfg_.max_points_total / pending_.size()));
    for (Pending& p : pending_) {
      std::size_t total = 0;
      const std::vector<std::uint32_t> idx =
          subsample(p.cloud, per_cloud, cfg_.seed ^ fnv1a(p.id), &total);
      std::vector<float> xyz(idx.size() * 3);
      for (std::size_t k = 0; k < idx.size(); ++k) {
        for (int c = 0; c < 3; ++c) xyz[3 * k + c] = p.cloud.points[idx[k]][c];
      }
      json j = base(p.id, p.name, "points", true);
      j["xyz"] = base64(xyz.data(), xyz.size() * sizeof(float));
      json modes = json::array();
      const PointProperty* change = p.cloud.property("change_m");
      if (change != nullptr) {
        std::vector<float> s(idx.size());
        for (std::size_t k = 0; k < idx.size(); ++k) s[k] = change->values[idx[k]];
        j["change"] = base64(s.data(), s.size() * sizeof(float));
        modes.push_back("change");
      }
      if (p.cloud.has_color()) {
        std::vector<Rgb> rgb(idx.size());
        for (std::size_t k = 0; k < idx.size(); ++k) rgb[k] = p.cloud.color[idx[k]];
        j["rgb"] = base64(rgb.data(), rgb.size() * 3);
        modes.push_back("rgb");
      }
      modes.push_back("height");
      if (p.cloud.has_intensity()) {
        std::vector<float> in(idx.size());
        for (std::size_t k = 0; k < idx.size(); ++k) in[k] = p.cloud.intensity[idx[k]];
        j["intensity"] = base64(in.data(), in.size() * sizeof(float));
        modes.push_back("intensity");
      }
      j["color_modes"] = modes;
      j["count"] = idx.size();
      j["num_total"] = total;
      layers_[p.slot] = j;
      summary_.num_cloud_points += idx.size();
      ++summary_.num_clouds;
    }
    summary_.num_layers = layers_.size();
    json d = json::object();
    d["layers"] = layers_;
    d["tables"] = tables_;
    d["cards"] = cards_;
    d["figures"] = figures_;
    d["legend"] = legend_;
    d["max_points_per_cloud"] = per_cloud;
    return d;
  }

 private:
  struct Pending {
    std::string id, name;
    PointCloud cloud;
    std::size_t slot;
  };
  static json base(const std::string& id, const std::string& name, const char* type, bool visible) {
    return {{"id", id}, {"name", name}, {"type", type}, {"visible", visible}};
  }
  const ReportConfig& cfg_;
  ReportSummary& summary_;
  std::vector<Pending> pending_;
  json layers_ = json::array(), tables_ = json::array(), cards_ = json::array(),
       legend_ = json::array(), figures_ = json::array();
  std::map<std::string, std::string> model_colors_;
};

// Catalogue meshes by model name, loaded once; a model the catalogue lacks is an Error naming
// the file that asked for it.
class Models {
 public:
  explicit Models(const fs::path& catalogue) : cat_(read_catalogue(catalogue.string())) {}
  const Catalogue& catalogue() const { return cat_; }
  const TriangleMesh& mesh(const std::string& model, const std::string& asked_by) {
    auto it = meshes_.find(model);
    if (it != meshes_.end()) return it->second;
    for (const CatalogueModel& m : cat_.models) {
      if (m.name == model) return meshes_[model] = load_catalogue_mesh(cat_, m);
    }
    throw Error("report: " + asked_by + ": model '" + model + "' is not in the catalogue '" +
                cat_.path + "'");
  }
  // The placed mesh: T · S(scale) · model (recognize's scale, docs/formats.md).
  TriangleMesh placed(const std::string& model, const Eigen::Matrix4d& T,
                      const std::string& asked_by, double scale = 1) {
    TriangleMesh m = mesh(model, asked_by);
    for (auto& v : m.vertices) v *= static_cast<float>(scale);
    Eigen::Isometry3d iso;
    iso.matrix() = T;
    m.transform(iso);
    return m;
  }

 private:
  Catalogue cat_;
  std::map<std::string, TriangleMesh> meshes_;
};

json vec3(const Eigen::Matrix4d& T) { return {T(0, 3), T(1, 3), T(2, 3)}; }

// A map directory's merged cloud (or any PLY cloud), with the placements of `sonar3d
// recognize` drawn over it as semi-transparent meshes and listed.
void build_map(const fs::path& cloud_path, const PlyData& ply, const ReportConfig& cfg,
               Scene& scene) {
  if (ply.is_mesh) {
    scene.mesh("mesh", cloud_path.filename().string(), ply.mesh, ply.cloud.color, "height", 1.0,
               true);
    scene.card("triangles", ply.mesh.triangles.size());
  } else {
    scene.points("cloud", cloud_path.filename().string(), ply.cloud);
    scene.card("points", ply.cloud.size());
  }
  if (cfg.placements.empty()) return;
  const std::string ppath = cfg.placements.string();
  // The one reader of placements.json (world/world_model.hpp), as `sonar3d world` and `diff`.
  const PlacementsFile file = read_placements(ppath);
  const std::vector<PlacementRecord>& placements = file.placements;
  const std::string& catalogue_source = file.catalogue;
  fs::path cat = cfg.catalogue;
  if (cat.empty()) {
    // The catalogue the placements name: as written, or relative to the placements file.
    const fs::path named(catalogue_source);
    const fs::path beside = cfg.placements.parent_path() / named;
    if (!catalogue_source.empty() && fs::is_regular_file(named)) {
      cat = named;
    } else if (!catalogue_source.empty() && fs::is_regular_file(beside)) {
      cat = beside;
    } else {
      throw Error("report: '" + ppath + "' names the catalogue '" + catalogue_source +
                  "', which is not found: give it with --catalogue CAT.yaml");
    }
  }
  Models models(cat);
  json rows = json::array(), focus = json::array();
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const PlacementRecord& p = placements[i];
    const Eigen::Matrix4d T = p.T_world_model.matrix();
    const std::string asked = "'" + ppath + "': placements[" + std::to_string(i) + "]";
    scene.mesh("placement_" + std::to_string(i), p.model + " #" + std::to_string(i + 1),
               models.placed(p.model, T, asked, p.scale), {}, scene.model_color(p.model), 0.45,
               true);
    focus.push_back("placement_" + std::to_string(i));
    rows.push_back({i + 1, p.model, T(0, 3), T(1, 3), T(2, 3), yaw_deg(T), p.score_m,
                    num_or_null(p.residual_median_m), num_or_null(p.residual_mean_m), p.method,
                    num_or_null(p.confidence)});
  }
  scene.table("placements", "Placements (" + ppath + ")",
              {"#", "model", "x [m]", "y [m]", "z [m]", "yaw [°]", "score [m]",
               "residual median [m]", "residual mean [m]", "method", "confidence"},
              rows, focus);
  scene.card("placements", placements.size());
  // Per catalogue model: how many were expected (the catalogue's `expected`) and found.
  std::map<std::string, int> found;
  for (const PlacementRecord& p : placements) ++found[p.model];
  json model_rows = json::array();
  int expected_total = 0, found_of_expected = 0;
  bool all_known = true;
  for (const CatalogueModel& m : models.catalogue().models) {
    const int n = found.count(m.name) ? found[m.name] : 0;
    const std::string text =
        m.expected >= 0 ? m.name + ": " + std::to_string(n) + " of " + std::to_string(m.expected)
                        : m.name + ": " + std::to_string(n) + " (expected count not given)";
    model_rows.push_back({m.name, m.expected >= 0 ? json(m.expected) : json(nullptr), n, text});
    if (m.expected >= 0) {
      expected_total += m.expected;
      found_of_expected += std::min(n, m.expected);
    } else {
      all_known = false;
    }
  }
  scene.table("models", "Per catalogue model: expected and found (" + models.catalogue().path + ")",
              {"model", "expected", "found", "summary"}, model_rows);
  if (expected_total > 0 || all_known) {
    scene.card("found of expected",
               std::to_string(found_of_expected) + " of " + std::to_string(expected_total));
  }
}

// Horizontal positions of a trajectory's poses.
std::vector<Eigen::Vector2d> track_xy(const Trajectory& t) {
  std::vector<Eigen::Vector2d> xy;
  xy.reserve(t.size());
  for (const Eigen::Isometry3d& T : t.poses) xy.push_back(T.translation().head<2>());
  return xy;
}

// What `sonar3d map` recorded (summary.json, docs/formats.md "Map directory"): the swaths with
// their offsets and drift rates, the ties between them, and the navigation before and after
// correction (the dataset's navigation.tum, navigation_corrected.tum) as a picture and figures.
void build_map_record(const fs::path& dir, Scene& scene, std::vector<std::string>& warnings) {
  const fs::path spath = dir / "summary.json";
  if (!fs::is_regular_file(spath)) return;
  json sm;
  try {
    sm = json::parse(read_text_file(spath.string()));
  } catch (const json::exception& e) {
    throw Error("report: '" + spath.string() + "' is not valid JSON: " + e.what());
  }
  auto get_num = [&](const json& j, const char* key, std::size_t i) -> json {
    if (!j.contains(key) || j[key].is_null()) return nullptr;
    const json& v = j[key];
    if (v.is_array()) return i < v.size() && v[i].is_number() ? v[i] : json(nullptr);
    return v.is_number() ? v : json(nullptr);
  };
  const std::string where = "'" + spath.string() + "'";
  if (sm.contains("method") && sm["method"].is_string()) scene.card("map method", sm["method"]);
  if (sm.contains("swaths")) {
    require(sm["swaths"].is_array(), "report: " + where + ": 'swaths' must be an array");
    json rows = json::array();
    bool drift = false;
    for (std::size_t k = 0; k < sm["swaths"].size(); ++k) {
      const json& w = sm["swaths"][k];
      require(w.is_object(),
              "report: " + where + ": swaths[" + std::to_string(k) + "] must be an object");
      drift = drift || w.contains("rate_mps");
      rows.push_back({k, get_num(w, "frames", 0), get_num(w, "frames", 1), get_num(w, "time_s", 0),
                      get_num(w, "time_s", 1), get_num(w, "points", 0), get_num(w, "offset_m", 0),
                      get_num(w, "offset_m", 1), get_num(w, "offset_m", 2),
                      get_num(w, "rate_mps", 0), get_num(w, "rate_mps", 1)});
    }
    scene.table("swaths",
                std::string("Swaths: navigation offsets") + (drift ? " and drift rates" : ""),
                {"swath", "first frame", "last frame", "t0 [s]", "t1 [s]", "points", "offset x [m]",
                 "offset y [m]", "offset z [m]", "drift rate x [m/s]", "drift rate y [m/s]"},
                rows);
    scene.card("swaths", sm["swaths"].size());
  }
  if (sm.contains("ties")) {
    require(sm["ties"].is_array(), "report: " + where + ": 'ties' must be an array");
    json rows = json::array();
    std::size_t used = 0;
    for (std::size_t k = 0; k < sm["ties"].size(); ++k) {
      const json& t = sm["ties"][k];
      require(t.is_object(),
              "report: " + where + ": ties[" + std::to_string(k) + "] must be an object");
      const bool u = t.contains("used") && t["used"].is_boolean() && t["used"].get<bool>();
      used += u ? 1 : 0;
      rows.push_back({get_num(t, "reference", 0), get_num(t, "moving", 0),
                      get_num(t, "time_reference_s", 0), get_num(t, "time_moving_s", 0),
                      get_num(t, "shift_m", 0), get_num(t, "shift_m", 1), get_num(t, "shift_m", 2),
                      get_num(t, "score_m", 0), get_num(t, "overlap_cells", 0),
                      get_num(t, "confidence", 0), u ? "yes" : "no", get_num(t, "residual_m", 0)});
    }
    scene.table("ties", "Ties between swaths (registrations)",
                {"reference swath", "moving swath", "t reference [s]", "t moving [s]",
                 "shift x [m]", "shift y [m]", "shift z [m]", "score [m]", "overlap cells",
                 "confidence", "used", "residual [m]"},
                rows);
    scene.card("ties used", std::to_string(used) + " of " + std::to_string(sm["ties"].size()));
  }
  // The navigation before (the dataset's, as logged) and after (corrected).
  const fs::path after_path = dir / "navigation_corrected.tum";
  fs::path before_path;
  if (sm.contains("dataset") && sm["dataset"].is_string()) {
    const fs::path ds = sm["dataset"].get<std::string>();
    for (const fs::path& cand : {ds / "navigation.tum", dir.parent_path() / ds / "navigation.tum",
                                 dir / ds / "navigation.tum"}) {
      if (fs::is_regular_file(cand)) {
        before_path = cand;
        break;
      }
    }
  }
  if (!fs::is_regular_file(after_path)) return;
  const Trajectory after = read_tum(after_path.string());
  Trajectory before;
  if (!before_path.empty()) {
    before = read_tum(before_path.string());
  } else {
    warnings.push_back(
        "the dataset's navigation.tum (summary.json's 'dataset') is not found: the "
        "track picture shows the corrected navigation only");
  }
  // The correction at each corrected pose: its horizontal distance from the logged pose at the
  // same time (logged navigation interpolated; outside its span, not compared).
  std::vector<double> shift;
  for (std::size_t k = 0; k < after.size() && !before.empty(); ++k) {
    const double t = after.times[k];
    if (t < before.times.front() || t > before.times.back()) continue;
    shift.push_back(
        (after.poses[k].translation() - before.interpolate(t).translation()).head<2>().norm());
  }
  std::string caption =
      "Top view, world frame (x East, y North), metres; dashed: the navigation as logged (" +
      (before_path.empty() ? std::string("not found") : before_path.string()) +
      "), solid: corrected (" + after_path.string() + ").";
  if (!shift.empty()) {
    std::sort(shift.begin(), shift.end());
    const double median = shift[shift.size() / 2], max = shift.back();
    scene.card("navigation correction, median [m]", round_to(median, 0.001));
    scene.card("navigation correction, max [m]", round_to(max, 0.001));
    char buf[96];
    std::snprintf(buf, sizeof buf, " Horizontal correction: median %.3f m, max %.3f m.", median,
                  max);
    caption += buf;
  }
  scene.figure("track", "Navigation before and after correction",
               track_svg(track_xy(before), track_xy(after)), caption);
}

// A world model directory of `sonar3d world` (docs/formats.md, "World model directory").
void build_world(const fs::path& dir, Scene& scene) {
  const fs::path gpath = dir / "graph.json";
  const WorldGraph g = parse_world_graph(read_text_file(gpath.string()), gpath.string());
  json lod_rows = json::array();
  for (std::size_t i = 0; i < g.seabed.size(); ++i) {
    const WorldSeabedLod& s = g.seabed[i];
    const fs::path p = dir / s.file;
    const PlyData d = read_any_ply(p);
    if (!d.is_mesh)
      throw Error("report: '" + p.string() + "' (seabed lod " + std::to_string(s.lod) +
                  ") has no faces: a mesh is expected");
    // Only the coarsest level is shown at first (the page switches between them).
    scene.mesh("seabed_lod" + std::to_string(s.lod), "seabed LOD " + std::to_string(s.lod), d.mesh,
               d.cloud.color, "height", 1.0, i + 1 == g.seabed.size(), "seabed");
    lod_rows.push_back({s.lod, s.file, num_or_null(s.cell_m), d.mesh.triangles.size(),
                        s.bytes >= 0 ? json(s.bytes) : json(nullptr),
                        num_or_null(s.median_error_m)});
  }
  json obj_rows = json::array(), obj_focus = json::array();
  std::map<std::string, Eigen::Vector3f> centre;
  const char* kUnconfirmed = "#9aa0a6";
  std::size_t unconfirmed = 0;
  for (const WorldGraphObject& o : g.objects) {
    const fs::path p = dir / o.file;
    const PlyData d = read_any_ply(p);
    if (!d.is_mesh)
      throw Error("report: '" + p.string() + "' (object '" + o.id +
                  "') has no faces: a mesh is expected");
    // An unconfirmed placement (below the world's confidence threshold) in grey, without its
    // vertex colours: listed, never connected.
    if (o.confirmed) {
      scene.mesh("object_" + o.id, o.id, d.mesh, d.cloud.color, scene.model_color(o.model), 0.85,
                 true);
    } else {
      scene.mesh("object_" + o.id, o.id + " (unconfirmed)", d.mesh, {}, kUnconfirmed, 0.5, true);
      ++unconfirmed;
    }
    centre[o.id] = d.mesh.bounding_box().center();  // of the model as placed (world frame)
    obj_focus.push_back("object_" + o.id);
    obj_rows.push_back({o.id, o.model, o.kind, o.T_world_model(0, 3), o.T_world_model(1, 3),
                        o.T_world_model(2, 3), yaw_deg(o.T_world_model), num_or_null(o.score_m),
                        num_or_null(o.residual_median_m), num_or_null(o.confidence),
                        o.confirmed ? "confirmed" : "unconfirmed",
                        d.cloud.has_color() ? "yes" : "no"});
  }
  if (unconfirmed > 0) {
    scene.legend(kUnconfirmed, "unconfirmed placement (confidence below the threshold)");
  }
  json con_rows = json::array();
  if (!g.connections.empty()) {
    std::vector<Eigen::Vector3f> ends;
    std::vector<Rgb> colors;
    for (const WorldConnection& c : g.connections) {
      const Rgb rgb = hex_rgb(c.kind == "pipeline" ? "#ff7f0e" : "#d62728");
      ends.push_back(centre.at(c.from));
      ends.push_back(centre.at(c.to));
      colors.push_back(rgb);
      colors.push_back(rgb);
      const std::string source = c.found && c.given ? "found and given"
                                 : c.found          ? "found in the map"
                                                    : "given";
      con_rows.push_back({c.from, c.to, c.kind, num_or_null(c.length_m), source});
    }
    scene.lines("connections", "connections", ends, colors);
    scene.legend("#ff7f0e", "pipeline connection");
    scene.legend("#d62728", "other connection (given)");
  }
  scene.table("objects", "Objects",
              {"id", "model", "kind", "x [m]", "y [m]", "z [m]", "yaw [°]", "score [m]",
               "residual median [m]", "confidence", "status", "vertex colours"},
              obj_rows, obj_focus);
  scene.table("connections", "Connections", {"from", "to", "kind", "length [m]", "source"},
              con_rows);
  scene.table("seabed", "Seabed levels of detail",
              {"lod", "file", "cell [m]", "triangles", "bytes", "median error [m]"}, lod_rows);
  scene.card("objects", g.objects.size());
  if (unconfirmed > 0) scene.card("unconfirmed", unconfirmed);
  if (std::isfinite(g.min_confidence)) scene.card("min confidence", g.min_confidence);
  scene.card("connections", g.connections.size());
  scene.card("seabed LODs", g.seabed.size());
  if (g.bytes_total > 0) scene.card("world model", fmt_bytes(g.bytes_total));
  if (g.cloud_bytes > 0) scene.card("point cloud", fmt_bytes(g.cloud_bytes));
  if (g.bytes_total > 0 && g.cloud_bytes > 0) {
    scene.card("reduction", json(std::round(10.0 * g.cloud_bytes / g.bytes_total) / 10.0));
  }
}

// A change directory of `sonar3d diff` (docs/formats.md, "Change directory").
void build_changes(const fs::path& dir, const ReportConfig& cfg, Scene& scene) {
  const fs::path cpath = dir / "changes.json";
  const ChangeSet c = parse_changes_json(read_text_file(cpath.string()), cpath.string());
  const fs::path ppath = dir / "change_points.ply";
  PlyData d = read_any_ply(ppath);
  if (d.cloud.property("change_m") == nullptr) {
    throw Error("report: '" + ppath.string() + "' has no float vertex property change_m");
  }
  Eigen::AlignedBox3f box;
  for (const auto& p : d.cloud.points)
    if (p.allFinite()) box.extend(p);
  for (const ChangedObject& o : c.objects) {
    if (o.has_a) box.extend(o.T_world_model_a.topRightCorner<3, 1>().cast<float>());
    if (o.has_b) box.extend(o.T_world_model_b_in_a.topRightCorner<3, 1>().cast<float>());
  }
  scene.points("change_points", "change points", std::move(d.cloud));

  // Markers: a cross at each object's position with a stroke along its x axis (its yaw), in
  // survey A (before) and survey B (after, in A's frame), joined for moved objects.
  const float size = box.isEmpty() ? 0.3f : std::max(0.1f, 0.03f * box.diagonal().norm());
  const char* kBefore = "#d62728";  // before / removed
  const char* kAfter = "#2ca02c";   // after / added
  const char* kSame = "#9aa0a6";    // unchanged
  const char* kMove = "#f2c12e";    // before -> after of a moved object
  const char* kUnsure = "#9467bd";  // uncertain: the recognitions disagree, the heights did not
                                    // change
  std::vector<Eigen::Vector3f> ends;
  std::vector<Rgb> colors;
  auto seg = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b, const char* hex) {
    ends.push_back(a);
    ends.push_back(b);
    colors.push_back(hex_rgb(hex));
    colors.push_back(hex_rgb(hex));
  };
  auto marker = [&](const Eigen::Matrix4d& T, const char* hex) {
    const Eigen::Vector3f p = T.topRightCorner<3, 1>().cast<float>();
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3f e = Eigen::Vector3f::Unit(a) * (0.5f * size);
      seg(p - e, p + e, hex);
    }
    const Eigen::Vector3f x = T.block<3, 1>(0, 0).cast<float>();
    seg(p, p + 1.5f * size * x, hex);
  };
  std::unique_ptr<Models> models;
  if (!cfg.catalogue.empty()) models = std::make_unique<Models>(cfg.catalogue);
  json rows = json::array();
  std::map<std::string, int> counts;
  for (std::size_t i = 0; i < c.objects.size(); ++i) {
    const ChangedObject& o = c.objects[i];
    ++counts[o.status];
    const bool same = o.status == "unchanged";
    const bool unsure = o.status == "uncertain";  // drawn where each survey placed it, in violet
    if (o.has_a) marker(o.T_world_model_a, same ? kSame : unsure ? kUnsure : kBefore);
    if (o.has_b && !same) marker(o.T_world_model_b_in_a, unsure ? kUnsure : kAfter);
    if (o.has_a && o.has_b && !same && !unsure) {
      seg(o.T_world_model_a.topRightCorner<3, 1>().cast<float>(),
          o.T_world_model_b_in_a.topRightCorner<3, 1>().cast<float>(), kMove);
    }
    if (models) {
      const std::string asked = "'" + cpath.string() + "': objects[" + std::to_string(i) + "]";
      if (o.has_a) {
        scene.mesh("before_" + o.id,
                   o.id + (same     ? ""
                           : unsure ? " (uncertain, survey A)"
                                    : " (before)"),
                   models->placed(o.model, o.T_world_model_a, asked), {},
                   same     ? kSame
                   : unsure ? kUnsure
                            : kBefore,
                   0.35, true);
      }
      if (o.has_b && !same) {
        scene.mesh("after_" + o.id, o.id + (unsure ? " (uncertain, survey B)" : " (after)"),
                   models->placed(o.model, o.T_world_model_b_in_a, asked), {},
                   unsure ? kUnsure : kAfter, 0.35, true);
      }
    }
    rows.push_back({o.id, o.model, o.status, round_to(o.shift_m * 100, 0.1),
                    round_to(o.turn_deg, 0.1), o.has_a ? vec3(o.T_world_model_a) : json(nullptr),
                    o.has_b ? vec3(o.T_world_model_b_in_a) : json(nullptr),
                    num_or_null(o.change_area_m2), o.reason});
  }
  if (!ends.empty()) scene.lines("markers", "object markers", ends, colors);
  scene.legend(kBefore, "before (survey A) / removed");
  scene.legend(kAfter, "after (survey B, in A's frame) / added");
  scene.legend(kSame, "unchanged");
  scene.legend(kMove, "moved: before to after");
  if (counts["uncertain"] > 0) {
    scene.legend(kUnsure, "uncertain: recognised differently, no height change");
  }
  scene.table("objects", "Objects",
              {"id", "model", "status", "shift [cm]", "turn [°]", "position A [m]",
               "position B in A [m]", "height change [m²]", "why uncertain"},
              rows);
  json region_rows = json::array();
  for (const ChangedRegion& r : c.regions) {
    region_rows.push_back({r.id, r.kind, json{r.centroid.x(), r.centroid.y(), r.centroid.z()},
                           r.area_m2, r.max_abs_change_m, r.mean_change_m});
  }
  scene.table("regions", "Changed regions",
              {"id", "kind", "centroid [m]", "area [m²]", "max |change| [m]", "mean change [m]"},
              region_rows);
  // Colour change (when both surveys had video): a ring at each region in its colour after, a
  // table with the colours before and after.
  if (!c.colour_space.empty()) {
    json colour_rows = json::array();
    std::vector<Eigen::Vector3f> ring;
    std::vector<Rgb> ring_colors;
    for (const ChangedColourRegion& r : c.colour_regions) {
      auto hex = [](const std::array<int, 3>& v) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "#%02x%02x%02x", v[0], v[1], v[2]);
        return std::string(buf);
      };
      constexpr double kTwoPi = 6.283185307179586;
      // A circle of the region's area around its centroid.
      const float rad = std::max(0.05f, static_cast<float>(std::sqrt(2 * r.area_m2 / kTwoPi)));
      const Eigen::Vector3f p = r.centroid.cast<float>();
      for (int k = 0; k < 24; ++k) {
        for (int e = 0; e < 2; ++e) {
          const float t = static_cast<float>(kTwoPi * (k + e) / 24);
          ring.push_back(p + rad * Eigen::Vector3f(std::cos(t), std::sin(t), 0));
          ring_colors.push_back(hex_rgb(hex(r.colour_b)));
        }
      }
      colour_rows.push_back({r.id, json{r.centroid.x(), r.centroid.y(), r.centroid.z()}, r.area_m2,
                             r.max_delta, r.mean_delta, hex(r.colour_a), hex(r.colour_b),
                             num_or_null(100 * r.height_change_fraction)});
    }
    if (!ring.empty()) scene.lines("colour_regions", "colour change regions", ring, ring_colors);
    scene.table("colour_regions", "Colour changes (" + c.colour_space + ")",
                {"id", "centroid [m]", "area [m²]", "max difference", "mean difference",
                 "colour before", "colour after", "with height change [%]"},
                colour_rows);
    scene.card("colour regions", c.colour_regions.size());
  }
  scene.card("registration", c.registration_method.empty() ? "–" : c.registration_method);
  scene.card("registration rms [m]", num_or_null(c.registration_rms_m));
  for (const char* s : {"moved", "added", "removed", "unchanged", "uncertain"}) {
    scene.card(s, counts[s]);
  }
  scene.card("changed regions", c.regions.size());
}

}  // namespace

ReportSummary write_scene_report(const fs::path& input, ReportInput kind, const ReportConfig& cfg) {
  ReportSummary summary;
  const bool is_file = kind == ReportInput::Ply;
  if (cfg.output.empty()) {
    summary.output = is_file ? fs::path(input).replace_extension(".html") : input / "report.html";
  } else {
    summary.output = cfg.output;
  }
  check_replaceable(summary.output);
  if (!cfg.placements.empty() && kind != ReportInput::Map && kind != ReportInput::Ply) {
    throw Error("report: --placements is for a map directory or a PLY cloud, not a " +
                std::string(report_input_name(kind)) + " input");
  }
  if (!cfg.catalogue.empty() && cfg.placements.empty() && kind != ReportInput::Changes) {
    throw Error("report: --catalogue goes with --placements (map) or a change directory");
  }
  const fs::path web_dir = cfg.web_dir.empty() ? default_web_dir() : cfg.web_dir;
  const WebAssets assets = load_web_assets(web_dir, "scene.js", false);

  Scene scene(cfg, summary);
  Progress progress("report", 1 + cfg.overlays.size(), cfg.progress);
  switch (kind) {
    case ReportInput::Map: {
      const fs::path cloud = input / "merged.ply";
      build_map(cloud, read_any_ply(cloud), cfg, scene);
      build_map_record(input, scene, summary.warnings);
      break;
    }
    case ReportInput::Ply:
      build_map(input, read_any_ply(input), cfg, scene);
      break;
    case ReportInput::World:
      build_world(input, scene);
      break;
    case ReportInput::Changes:
      build_changes(input, cfg, scene);
      break;
    case ReportInput::Sweep:
      throw Error("report: internal: a sweep is not a scene page");
  }
  progress.add();
  for (std::size_t k = 0; k < cfg.overlays.size(); ++k) {
    const PlyData d = read_any_ply(cfg.overlays[k]);
    const std::string id = "overlay_" + std::to_string(k);
    const std::string name = cfg.overlays[k].filename().string();
    if (d.is_mesh) {
      scene.mesh(id, name, d.mesh, d.cloud.color, scene.model_color(name), 0.9, true);
    } else {
      scene.points(id, name, d.cloud);
    }
    progress.add();
  }
  progress.finish();

  json data = scene.finish();
  const std::string name = fs::absolute(input).lexically_normal().filename().string();
  data["format"] = 1;
  data["kind"] = report_input_name(kind);
  data["title"] = cfg.title.empty()
                      ? std::string("sonar3d ") + report_input_name(kind) + ": " + name
                      : cfg.title;
  data["source"] = fs::absolute(input).lexically_normal().string();
  data["generated"] = utc_now();
  data["warnings"] = summary.warnings;
  const std::string html = fill_page(assets, data["title"].get<std::string>(),
                                     data.dump(-1, ' ', false, json::error_handler_t::replace));
  write_text_file(summary.output.string(), html);
  summary.bytes = html.size();
  return summary;
}

}  // namespace sonar3d::report_page
