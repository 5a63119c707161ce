#include "sonar3d/world/world_model.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/rgb_image.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/gltf.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/texture_io.hpp"
#include "sonar3d/io/truth.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/recog/catalogue.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

constexpr std::uintmax_t kMaxJsonBytes = 64ull << 20;  // placements / summary files read whole

nlohmann::json parse_json_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error(what + " '" + path +
                "': " + (fs::exists(path, ec) ? "not a file" : "no such file"));
  }
  const std::uintmax_t size = fs::file_size(path, ec);
  require(!ec && size <= kMaxJsonBytes,
          what + " '" + path + "': larger than 64 MB, not a file sonar3d wrote");
  const std::string text = read_text_file(path);
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  require(!j.is_discarded(), what + " '" + path + "': not valid JSON");
  require(j.is_object(), what + " '" + path + "': the top level is not a JSON object");
  return j;
}

// A 4×4 rigid transform from rows [[4],[4],[4],[4]] or 16 row-major numbers.
Eigen::Isometry3d parse_pose(const nlohmann::json& j, const std::string& where) {
  Eigen::Matrix4d m;
  if (j.is_array() && j.size() == 4) {
    for (int r = 0; r < 4; ++r) {
      const nlohmann::json& row = j[static_cast<std::size_t>(r)];
      require(row.is_array() && row.size() == 4, where + ": each row must hold 4 numbers");
      for (int c = 0; c < 4; ++c) {
        const nlohmann::json& v = row[static_cast<std::size_t>(c)];
        require(v.is_number(), where + ": row " + std::to_string(r) + " holds a non-number");
        m(r, c) = v.get<double>();
      }
    }
  } else if (j.is_array() && j.size() == 16) {
    for (int k = 0; k < 16; ++k) {
      const nlohmann::json& v = j[static_cast<std::size_t>(k)];
      require(v.is_number(), where + ": entry " + std::to_string(k) + " is not a number");
      m(k / 4, k % 4) = v.get<double>();
    }
  } else {
    throw Error(where + ": expected a 4×4 matrix (4 rows of 4 numbers, or 16 numbers)");
  }
  require(m.allFinite(), where + ": a number is not finite");
  require(m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-9) && std::abs(m(3, 3) - 1) < 1e-9 &&
              m.row(3).head<3>().norm() < 1e-9,
          where + ": the last row must be 0 0 0 1");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  require((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-3 &&
              R.determinant() > 0,
          where + ": the rotation block is not a rotation (orthonormal, determinant +1)");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

double optional_number(const nlohmann::json& o, const char* key, const std::string& where) {
  if (!o.contains(key) || o[key].is_null()) return std::numeric_limits<double>::quiet_NaN();
  require(o[key].is_number(), where + ": '" + key + "' must be a number or null");
  return o[key].get<double>();
}

// A confidence (recognize's, docs/recognition.md): absent or null gives NaN (unknown), anything
// but a finite number in [0, 1] is an Error naming the key.
double optional_confidence(const nlohmann::json& o, const char* key, const std::string& where) {
  if (!o.contains(key) || o[key].is_null()) return std::numeric_limits<double>::quiet_NaN();
  const nlohmann::json& v = o[key];
  require(v.is_number(),
          where + ": '" + key + "' must be a number in [0, 1], not " + std::string(v.type_name()));
  const double c = v.get<double>();
  require(std::isfinite(c) && c >= 0 && c <= 1,
          where + ": '" + key + "' is " + fmt::format("{}", c) + ", not a number in [0, 1]");
  return c;
}

std::string optional_string(const nlohmann::json& o, const char* key) {
  return o.contains(key) && o[key].is_string() ? o[key].get<std::string>() : std::string();
}

// A placed model's bounding box (model frame) grown by the margin, and the inverse pose.
struct PlacedBox {
  Eigen::Isometry3d T_model_world;
  Eigen::AlignedBox3d box;
  double z_mid_world = 0;
};

std::vector<PlacedBox> placed_boxes(const std::vector<WorldObject>& objects, double margin_m) {
  std::vector<PlacedBox> out;
  for (const WorldObject& o : objects) {
    const Eigen::AlignedBox3f b = o.mesh_model->bounding_box();
    PlacedBox p;
    p.T_model_world = o.T_world_model.inverse();
    p.box = Eigen::AlignedBox3d(b.min().cast<double>() - Eigen::Vector3d::Constant(margin_m),
                                b.max().cast<double>() + Eigen::Vector3d::Constant(margin_m));
    p.z_mid_world = (o.T_world_model * p.box.center()).z();
    out.push_back(p);
  }
  return out;
}

// Whether world (x, y) lies in the box's footprint (tested at the box's mid height).
bool in_footprint(const PlacedBox& b, const Eigen::Vector2d& xy) {
  const Eigen::Vector3d q = b.T_model_world * Eigen::Vector3d(xy.x(), xy.y(), b.z_mid_world);
  return q.x() >= b.box.min().x() && q.x() <= b.box.max().x() && q.y() >= b.box.min().y() &&
         q.y() <= b.box.max().y();
}

float median_of(std::vector<float>& v) {
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  if (v.size() % 2 == 1) return v[h];
  const float hi = v[h];
  return 0.5f * (hi + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h)));
}

// Height at world (x, y), NaN outside the map or in a no-data cell.
float height_at(const ElevationMap& m, const Eigen::Vector2d& xy) {
  const double u = (xy.x() - m.origin_xy.x()) / m.cell_m, v = (m.origin_xy.y() - xy.y()) / m.cell_m;
  if (!(u >= 0 && v >= 0 && u < m.cols && v < m.rows)) return ElevationMap::kNoData;
  return m.at(static_cast<int>(v), static_cast<int>(u));
}

nlohmann::json num_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

// Per vertex of height_field_mesh(map) (a vertex per valid cell, row-major): the linear-RGB mean
// of the coloured points falling in the vertex's cell, and their count.
void seabed_colors(const ElevationMap& map, const PointCloud& seabed,
                   const std::vector<std::uint8_t>& coloured, SeabedLod& lod) {
  std::vector<int> vid(map.z.size(), -1);
  int n = 0;
  for (std::size_t k = 0; k < map.z.size(); ++k) {
    if (map.z[k] == map.z[k]) vid[k] = n++;
  }
  lod.color.assign(static_cast<std::size_t>(n), Eigen::Vector3f::Zero());
  lod.color_points.assign(static_cast<std::size_t>(n), 0);
  std::array<float, 256> linear{};
  for (int v = 0; v < 256; ++v) linear[v] = srgb_to_linear(static_cast<float>(v) / 255.0f);
  for (std::size_t i = 0; i < seabed.size(); ++i) {
    if (!coloured[i]) continue;
    const Eigen::Vector3f& p = seabed.points[i];
    const double c = std::floor((p.x() - map.origin_xy.x()) / map.cell_m);
    const double r = std::floor((map.origin_xy.y() - p.y()) / map.cell_m);
    if (!(c >= 0 && c < map.cols && r >= 0 && r < map.rows)) continue;
    const int v = vid[map.index(static_cast<int>(r), static_cast<int>(c))];
    if (v < 0) continue;
    const auto& rgb = seabed.color[i];
    lod.color[v] += Eigen::Vector3f(linear[rgb[0]], linear[rgb[1]], linear[rgb[2]]);
    ++lod.color_points[v];
  }
  for (int v = 0; v < n; ++v) {
    if (lod.color_points[v] > 0) lod.color[v] /= static_cast<float>(lod.color_points[v]);
  }
}

}  // namespace

std::size_t SeabedLod::coloured_vertices() const {
  return static_cast<std::size_t>(std::count_if(color_points.begin(), color_points.end(),
                                                [](std::uint32_t k) { return k > 0; }));
}

PlacementsFile parse_placements(const std::string& text, const std::string& source) {
  const std::string where = "placements '" + source + "'";
  // Nesting bounded while parsing (as io/holoocean.cpp does): a value nested 100,000 levels deep
  // would overflow the stack when copied or destroyed.
  const nlohmann::json::parser_callback_t depth_guard =
      [&where](int depth, nlohmann::json::parse_event_t event, nlohmann::json&) {
        if ((event == nlohmann::json::parse_event_t::object_start ||
             event == nlohmann::json::parse_event_t::array_start) &&
            depth >= limits::kMaxNestingDepth) {
          throw Error(where + ": JSON nested more than " +
                      std::to_string(limits::kMaxNestingDepth) + " levels deep");
        }
        return true;
      };
  const nlohmann::json j = nlohmann::json::parse(text, depth_guard, /*allow_exceptions=*/false);
  require(!j.is_discarded(), where + ": not valid JSON");
  require(j.is_object(), where + ": the top level is not a JSON object");
  require(j.contains("format") && j["format"].is_string() &&
              j["format"].get<std::string>() == "sonar3d-placements",
          where + ": no \"format\": \"sonar3d-placements\" (write it with sonar3d recognize)");
  require(j.contains("version") && j["version"].is_number_integer() &&
              j["version"].get<long long>() == 1,
          where + ": unsupported \"version\" (this sonar3d reads version 1)");
  require(j.contains("placements") && j["placements"].is_array(),
          where + ": no \"placements\" list");
  const nlohmann::json& list = j["placements"];
  require(list.size() <= kMaxPlacements,
          where + ": more than " + std::to_string(kMaxPlacements) + " placements");
  PlacementsFile out;
  out.path = source;
  out.map = optional_string(j, "map");
  out.catalogue = optional_string(j, "catalogue");
  if (j.contains("settings") && j["settings"].is_object()) {
    out.min_confidence = optional_confidence(j["settings"], "min_confidence", where + ": settings");
  }
  for (std::size_t i = 0; i < list.size(); ++i) {
    const nlohmann::json& e = list[i];
    const std::string at = where + ": placement " + std::to_string(i);
    require(e.is_object(), at + " is not an object");
    require(e.contains("model") && e["model"].is_string() && !e["model"].get<std::string>().empty(),
            at + ": 'model' must be a non-empty string");
    require(e.contains("T_world_model"), at + ": no 'T_world_model'");
    PlacementRecord p;
    p.model = e["model"].get<std::string>();
    p.T_world_model = parse_pose(e["T_world_model"], at + ": T_world_model");
    p.scale = optional_number(e, "scale", at);
    if (!std::isfinite(p.scale)) p.scale = 1;  // absent or null: files before the size search
    require(p.scale > 1e-3 && p.scale < 1e3, at + ": 'scale' must lie in (0.001, 1000)");
    p.score_m = optional_number(e, "score_m", at);
    p.residual_median_m = optional_number(e, "residual_median_m", at);
    p.residual_mean_m = optional_number(e, "residual_mean_m", at);
    p.method = optional_string(e, "method");
    p.confidence = optional_confidence(e, "confidence", at);
    out.placements.push_back(p);
  }
  return out;
}

PlacementsFile read_placements(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error("placements '" + path +
                "': " + (fs::exists(path, ec) ? "not a file" : "no such file"));
  }
  const std::uintmax_t size = fs::file_size(path, ec);
  require(!ec && size <= kMaxJsonBytes,
          "placements '" + path + "': larger than 64 MB, not a file sonar3d wrote");
  return parse_placements(read_text_file(path), path);
}

void SeabedConfig::validate() const {
  params::check(*this, "seabed");
  require(!lod_cells_m.empty(), "seabed.lod_cells_m must hold at least one value");
  require(lod_cells_m.size() <= 8, "seabed.lod_cells_m: at most 8 levels of detail");
  for (std::size_t k = 1; k < lod_cells_m.size(); ++k) {
    const double f = lod_cells_m[k] / lod_cells_m[k - 1];
    require(f >= 1.999 && std::abs(f - std::round(f)) < 1e-6,
            fmt::format("seabed.lod_cells_m: {} m is not an integer multiple (at least 2×) of {} m",
                        lod_cells_m[k], lod_cells_m[k - 1]));
  }
}

void ConnectionConfig::validate() const {
  params::check(*this, "pipeline_search");
  require(band_m > corridor_m,
          "pipeline_search.band_m: must exceed corridor_m (the ground lies beyond it)");
}

void WorldModelConfig::validate() const {
  params::check(*this, "world");
  seabed.validate();
  connections.validate();
}

double world_confidence_threshold(const PlacementsFile& placements, std::optional<double> asked,
                                  const std::string& param) {
  double t = 0;
  std::string from = "the default";
  if (asked) {
    require(std::isfinite(*asked) && *asked >= 0 && *asked <= 1,
            param + ": " + fmt::format("{}", *asked) + " is not a confidence in [0, 1]");
    t = *asked;
    from = param;
  } else if (std::isfinite(placements.min_confidence)) {
    t = placements.min_confidence;
    from = "its settings.min_confidence";
  }
  if (t > 0) {
    for (std::size_t i = 0; i < placements.placements.size(); ++i) {
      require(std::isfinite(placements.placements[i].confidence),
              "placements '" + placements.path + "': placement " + std::to_string(i) +
                  " has no 'confidence', so the threshold " + fmt::format("{}", t) + " (" + from +
                  ") cannot be checked: write the placements again with sonar3d recognize, or "
                  "give " +
                  param + " 0");
    }
  }
  return t;
}

std::size_t confirm_objects(std::vector<WorldObject>& objects, double min_confidence) {
  std::size_t unconfirmed = 0;
  for (WorldObject& o : objects) {
    o.confirmed =
        std::isfinite(o.confidence) ? o.confidence >= min_confidence : min_confidence <= 0;
    unconfirmed += !o.confirmed;
  }
  return unconfirmed;
}

std::vector<WorldObject> world_objects(const PlacementsFile& placements,
                                       const std::vector<std::string>& catalogue_names,
                                       const std::vector<TriangleMesh>& catalogue_meshes,
                                       const std::string& catalogue_path) {
  require(catalogue_names.size() == catalogue_meshes.size(),
          "world_objects: one mesh per catalogue name");
  std::vector<std::shared_ptr<const TriangleMesh>> shared;
  for (const TriangleMesh& m : catalogue_meshes) {
    shared.push_back(std::make_shared<const TriangleMesh>(m));
  }
  std::map<std::string, int> count;
  std::vector<WorldObject> out;
  for (std::size_t i = 0; i < placements.placements.size(); ++i) {
    const PlacementRecord& p = placements.placements[i];
    const auto it = std::find(catalogue_names.begin(), catalogue_names.end(), p.model);
    if (it == catalogue_names.end()) {
      throw Error("placements '" + placements.path + "': placement " + std::to_string(i) +
                  " names model '" + printable(p.model) + "', which catalogue '" + catalogue_path +
                  "' does not list: give the catalogue the placements were made with");
    }
    WorldObject o;
    o.model = p.model;
    o.id = p.model + "_" + std::to_string(count[p.model]++);
    o.T_world_model = p.T_world_model;
    o.score_m = p.score_m;
    o.residual_median_m = p.residual_median_m;
    o.confidence = p.confidence;
    o.mesh_model = shared[static_cast<std::size_t>(it - catalogue_names.begin())];
    if (p.scale != 1.0) {
      // A placement at another size gets its own mesh: T_world_model · S(scale) · model.
      TriangleMesh scaled = *o.mesh_model;
      for (auto& v : scaled.vertices) v *= static_cast<float>(p.scale);
      o.mesh_model = std::make_shared<const TriangleMesh>(std::move(scaled));
      o.scale = p.scale;
    }
    out.push_back(std::move(o));
  }
  return out;
}

std::vector<WorldObject> world_objects(const PlacementsFile& placements,
                                       const Catalogue& catalogue) {
  std::vector<std::string> names;
  std::vector<TriangleMesh> meshes;
  for (const CatalogueModel& m : catalogue.models) {
    names.push_back(m.name);
    const bool placed = std::any_of(placements.placements.begin(), placements.placements.end(),
                                    [&](const PlacementRecord& p) { return p.model == m.name; });
    meshes.push_back(placed ? load_catalogue_mesh(catalogue, m) : TriangleMesh{});
  }
  return world_objects(placements, names, meshes, catalogue.path);
}

std::vector<std::uint8_t> explained_points(const PointCloud& cloud_world,
                                           const std::vector<WorldObject>& objects,
                                           double margin_m) {
  const std::vector<PlacedBox> boxes = placed_boxes(objects, margin_m);
  std::vector<std::uint8_t> out(cloud_world.size(), 0);
  for (std::size_t i = 0; i < cloud_world.size(); ++i) {
    const Eigen::Vector3d p = cloud_world.points[i].cast<double>();
    for (std::size_t k = 0; k < boxes.size(); ++k) {
      const PlacedBox& b = boxes[k];
      if (objects[k].confirmed && b.box.contains(b.T_model_world * p)) {
        out[i] = 1;
        break;
      }
    }
  }
  return out;
}

TriangleMesh height_field_mesh(const ElevationMap& map) {
  TriangleMesh mesh;
  std::vector<int> vid(map.z.size(), -1);
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      if (!map.valid(r, c)) continue;
      vid[map.index(r, c)] = static_cast<int>(mesh.vertices.size());
      const Eigen::Vector2d xy = map.cell_center_xy(r, c);
      mesh.vertices.emplace_back(static_cast<float>(xy.x()), static_cast<float>(xy.y()),
                                 map.at(r, c));
    }
  }
  // a (NW) b (NE) / d (SW) e (SE): rows run south, columns east; (d, e, b) is counter-clockwise
  // seen from above.
  for (int r = 0; r + 1 < map.rows; ++r) {
    for (int c = 0; c + 1 < map.cols; ++c) {
      const int a = vid[map.index(r, c)], b = vid[map.index(r, c + 1)];
      const int d = vid[map.index(r + 1, c)], e = vid[map.index(r + 1, c + 1)];
      const int valid = (a >= 0) + (b >= 0) + (d >= 0) + (e >= 0);
      if (valid < 3) continue;
      if (valid == 4) {
        const float db = std::abs(map.at(r + 1, c) - map.at(r, c + 1));
        const float ae = std::abs(map.at(r, c) - map.at(r + 1, c + 1));
        if (db <= ae) {
          mesh.triangles.emplace_back(d, e, b);
          mesh.triangles.emplace_back(d, b, a);
        } else {
          mesh.triangles.emplace_back(a, d, e);
          mesh.triangles.emplace_back(a, e, b);
        }
      } else if (a < 0) {
        mesh.triangles.emplace_back(d, e, b);
      } else if (b < 0) {
        mesh.triangles.emplace_back(a, d, e);
      } else if (d < 0) {
        mesh.triangles.emplace_back(a, e, b);
      } else {
        mesh.triangles.emplace_back(d, b, a);
      }
    }
  }
  return mesh;
}

ElevationMap downsample_heights(const ElevationMap& fine, int factor, double min_valid_fraction) {
  require(factor >= 1, "downsample_heights: factor must be at least 1");
  ElevationMap out;
  out.origin_xy = fine.origin_xy;
  out.cell_m = fine.cell_m * factor;
  out.rows = (fine.rows + factor - 1) / factor;
  out.cols = (fine.cols + factor - 1) / factor;
  out.z.assign(static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(out.cols),
               ElevationMap::kNoData);
  const double need = min_valid_fraction * factor * factor;
  std::vector<float> v;
  for (int R = 0; R < out.rows; ++R) {
    for (int C = 0; C < out.cols; ++C) {
      v.clear();
      for (int r = R * factor; r < std::min(fine.rows, (R + 1) * factor); ++r) {
        for (int c = C * factor; c < std::min(fine.cols, (C + 1) * factor); ++c) {
          if (fine.valid(r, c)) v.push_back(fine.at(r, c));
        }
      }
      if (!v.empty() && static_cast<double>(v.size()) >= need) out.at(R, C) = median_of(v);
    }
  }
  return out;
}

std::size_t fill_holes(ElevationMap& map, const std::vector<std::uint8_t>& fill_mask) {
  require(fill_mask.size() == map.z.size(), "fill_holes: the mask must have one entry per cell");
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < map.z.size(); ++i) {
    if (fill_mask[i] && !(map.z[i] == map.z[i])) todo.push_back(i);
  }
  std::size_t filled = 0;
  // Ring by ring from each hole's edge inward: a cell with valid neighbours takes their mean.
  while (!todo.empty()) {
    std::vector<std::pair<std::size_t, float>> now;
    std::vector<std::size_t> later;
    for (std::size_t i : todo) {
      const int r = static_cast<int>(i / static_cast<std::size_t>(map.cols));
      const int c = static_cast<int>(i % static_cast<std::size_t>(map.cols));
      double sum = 0;
      int n = 0;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= map.rows || cc >= map.cols)
            continue;
          if (map.valid(rr, cc)) {
            sum += map.at(rr, cc);
            ++n;
          }
        }
      }
      if (n > 0) {
        now.emplace_back(i, static_cast<float>(sum / n));
      } else {
        later.push_back(i);
      }
    }
    if (now.empty()) break;  // holes with no valid cell around them stay holes
    for (const auto& [i, z] : now) map.z[i] = z;
    filled += now.size();
    todo.swap(later);
  }
  return filled;
}

std::vector<Connection> find_connections(const ElevationMap& seabed,
                                         const std::vector<WorldObject>& objects,
                                         const ConnectionConfig& config, double margin_m) {
  config.validate();
  std::vector<Connection> out;
  if (seabed.empty()) return out;
  const std::vector<PlacedBox> boxes = placed_boxes(objects, margin_m);
  const double step = std::min(seabed.cell_m, config.corridor_m / 2);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    for (std::size_t j = i + 1; j < objects.size(); ++j) {
      // A placement below the confidence threshold is never an end of a pipeline: three false
      // tanks on a wreck must not be joined (issue 28).
      if (!objects[i].confirmed || !objects[j].confirmed) continue;
      const Eigen::Vector2d a = (objects[i].T_world_model * boxes[i].box.center()).head<2>();
      const Eigen::Vector2d b = (objects[j].T_world_model * boxes[j].box.center()).head<2>();
      const double length = (b - a).norm();
      if (length > config.max_length_m || length < 2 * config.station_m) continue;
      const Eigen::Vector2d u = (b - a) / length, n(-u.y(), u.x());
      int stations = 0, with_data = 0, ridges = 0;
      double first = -1, last = -1;
      for (double t = config.station_m / 2; t < length; t += config.station_m) {
        const Eigen::Vector2d s = a + t * u;
        bool inside = false;
        for (std::size_t k = 0; k < boxes.size(); ++k) {
          inside = inside || (objects[k].confirmed && in_footprint(boxes[k], s));
        }
        if (inside) continue;  // the structures themselves (and any third one on the way)
        ++stations;
        // Cross-section: the ground beyond the corridor, fitted by a line (a slope across the
        // pipe is no ridge), and the crest within it.
        std::vector<std::pair<double, double>> ground, corridor;
        for (double o = -config.band_m; o <= config.band_m + 1e-9; o += step) {
          const float h = height_at(seabed, s + o * n);
          if (!(h == h)) continue;
          (std::abs(o) <= config.corridor_m ? corridor : ground).emplace_back(o, h);
        }
        if (ground.size() < 4 || corridor.size() < 2) continue;
        ++with_data;
        double so = 0, sh = 0, soo = 0, soh = 0;
        for (const auto& [o, h] : ground) {
          so += o;
          sh += h;
          soo += o * o;
          soh += o * h;
        }
        const double m = static_cast<double>(ground.size());
        const double den = m * soo - so * so;
        const double slope = std::abs(den) > 1e-12 ? (m * soh - so * sh) / den : 0;
        const double icpt = (sh - slope * so) / m;
        double crest = -1e9;
        for (const auto& [o, h] : corridor) crest = std::max(crest, h - (icpt + slope * o));
        if (crest >= config.min_ridge_m) {
          ++ridges;
          if (first < 0) first = t;
          last = t;
        }
      }
      if (with_data < 4 || 2 * with_data < stations) continue;  // too little seen to decide
      const double fraction = static_cast<double>(ridges) / with_data;
      if (fraction < config.min_fraction) continue;
      Connection c;
      c.from = objects[i].id;
      c.to = objects[j].id;
      c.length_m = last - first + config.station_m;
      c.fraction = fraction;
      c.found = true;
      out.push_back(c);
    }
  }
  return out;
}

WorldModel build_world_model(const PointCloud& cloud_world, std::vector<WorldObject> objects,
                             const WorldModelConfig& config) {
  config.validate();
  const auto t0 = std::chrono::steady_clock::now();
  require(!cloud_world.empty(), "the map holds no points: nothing to build a world model from");
  WorldModel w;
  w.cloud_points = cloud_world.size();
  w.min_confidence = config.min_confidence.value_or(0.0);
  confirm_objects(objects, w.min_confidence);
  const std::vector<std::uint8_t> explained =
      explained_points(cloud_world, objects, config.seabed.margin_m);
  const std::vector<std::uint8_t> coloured_all = video_coloured(cloud_world);
  PointCloud seabed;
  std::vector<std::uint8_t> coloured;
  Eigen::Vector2f lo = Eigen::Vector2f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (std::size_t i = 0; i < cloud_world.size(); ++i) {
    const Eigen::Vector3f& p = cloud_world.points[i];
    require(p.allFinite(), "the map's point " + std::to_string(i) + " is not finite");
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
    if (explained[i]) continue;
    seabed.points.push_back(p);
    if (cloud_world.has_color()) {
      seabed.color.push_back(cloud_world.color[i]);
      coloured.push_back(coloured_all[i]);
      w.coloured_seabed_points += coloured_all[i];
    }
  }
  w.seabed_points = seabed.size();
  require(!seabed.empty(),
          "every point of the map lies on a placed model: no seabed left to mesh (check the "
          "placements against the map)");

  // The finest height field over the whole map's extent (holes where the structures stood),
  // sec. 6.2.1: the highest point per cell.
  ElevationMapConfig map_cfg;
  map_cfg.cell_m = config.seabed.lod_cells_m.front();
  map_cfg.region_min_xy = lo.cast<double>();
  map_cfg.region_max_xy = hi.cast<double>();
  map_cfg.max_cells = config.seabed.max_cells;
  ElevationMap fine = elevation_map_from_points(seabed, map_cfg);
  if (config.seabed.fill_footprints && !objects.empty()) {
    const std::vector<PlacedBox> boxes = placed_boxes(objects, config.seabed.margin_m);
    std::vector<std::uint8_t> mask(fine.z.size(), 0);
    for (int r = 0; r < fine.rows; ++r) {
      for (int c = 0; c < fine.cols; ++c) {
        const Eigen::Vector2d xy = fine.cell_center_xy(r, c);
        for (std::size_t k = 0; k < boxes.size(); ++k) {
          if (objects[k].confirmed && in_footprint(boxes[k], xy)) mask[fine.index(r, c)] = 1;
        }
      }
    }
    w.filled_cells = fill_holes(fine, mask);
  }
  for (std::size_t k = 0; k < config.seabed.lod_cells_m.size(); ++k) {
    SeabedLod lod;
    lod.lod = static_cast<int>(k);
    lod.cell_m = config.seabed.lod_cells_m[k];
    if (k == 0) {
      lod.heights = fine;
    } else {
      const int factor = static_cast<int>(std::lround(lod.cell_m / config.seabed.lod_cells_m[0]));
      lod.heights = downsample_heights(fine, factor, config.seabed.min_valid_fraction);
      lod.cell_m = lod.heights.cell_m;
    }
    lod.mesh = height_field_mesh(lod.heights);
    if (w.coloured_seabed_points > 0) seabed_colors(lod.heights, seabed, coloured, lod);
    w.seabed.push_back(std::move(lod));
  }
  if (config.find_connections) {
    w.connections = find_connections(fine, objects, config.connections, config.seabed.margin_m);
  }
  w.objects = std::move(objects);
  w.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return w;
}

void take_video_colours(PointCloud& cloud, const PointCloud& coloured, const std::string& source) {
  require(coloured.has_color(), "'" + source +
                                    "' carries no colours (red green blue): colour the map's "
                                    "cloud with sonar3d texture first");
  require(coloured.size() == cloud.size(),
          "'" + source + "' holds " + std::to_string(coloured.size()) + " points, the map " +
              std::to_string(cloud.size()) +
              ": give the map's cloud as coloured by sonar3d texture (without --drop-uncoloured)");
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!(coloured.points[i] - cloud.points[i]).isZero(1e-4f)) {
      throw Error("'" + source + "' point " + std::to_string(i) +
                  " is not the map's: give the map's own cloud as coloured by sonar3d texture");
    }
  }
  cloud.color = coloured.color;
  for (const PointProperty& p : coloured.properties) {
    if (p.name != "views") continue;
    auto same = std::find_if(cloud.properties.begin(), cloud.properties.end(),
                             [](const PointProperty& q) { return q.name == "views"; });
    if (same != cloud.properties.end()) {
      same->values = p.values;
    } else {
      cloud.properties.push_back(p);
    }
  }
}

std::vector<GivenConnection> read_given_connections(const std::string& path) {
  const YAML::Node root = yaml::load_file(path);  // size limit, syntax errors with file:line
  require(root.IsMap() && root["connections"] && root["connections"].IsSequence(),
          "connections '" + path + "': no 'connections' list (connections: - {from: ID, to: ID})");
  yaml::check_keys(root, {"connections"}, path);  // a misspelt key is an error, as in every YAML
  const YAML::Node list = root["connections"];
  require(list.size() <= kMaxGivenConnections, "connections '" + path + "': more than " +
                                                   std::to_string(kMaxGivenConnections) +
                                                   " connections");
  std::vector<GivenConnection> out;
  for (const YAML::Node& e : list) {
    const std::string at = path + ":" + std::to_string(e.Mark().line + 1);
    require(e.IsMap(), at + ": a connection is a map {from: ID, to: ID, kind: KIND}");
    yaml::check_keys(e, {"from", "to", "kind"}, path, "connection");
    GivenConnection c;
    c.line = e.Mark().line + 1;
    c.from = yaml::get_string(e, "from", "", path, "connection");
    c.to = yaml::get_string(e, "to", "", path, "connection");
    c.kind = yaml::get_string(e, "kind", c.kind, path, "connection");
    require(!c.from.empty() && !c.to.empty(), at + ": 'from' and 'to' must name objects");
    out.push_back(std::move(c));
  }
  return out;
}

void add_given_connections(WorldModel& world, const std::vector<GivenConnection>& given,
                           const std::string& source, double margin_m) {
  std::map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < world.objects.size(); ++i) index[world.objects[i].id] = i;
  const std::vector<PlacedBox> boxes = placed_boxes(world.objects, margin_m);
  std::map<std::pair<std::string, std::string>, int> seen;  // unordered pair → line
  for (const GivenConnection& g : given) {
    const std::string at = source + ":" + std::to_string(g.line);
    for (const std::string* id : {&g.from, &g.to}) {
      if (!index.count(*id)) {
        std::string ids;
        for (const WorldObject& o : world.objects) ids += (ids.empty() ? "" : ", ") + o.id;
        throw Error(at + ": '" + *id +
                    "' names no placed object (the objects: " + (ids.empty() ? "none" : ids) + ")");
      }
    }
    for (const std::string* id : {&g.from, &g.to}) {
      const WorldObject& o = world.objects[index[*id]];
      const std::string conf = std::isfinite(o.confidence)
                                   ? "confidence " + fmt::format("{:.2f}", o.confidence)
                                   : std::string("confidence unknown");
      require(o.confirmed, at + ": '" + *id + "' is an unconfirmed placement (" + conf +
                               " below the threshold " +
                               fmt::format("{:.2f}", world.min_confidence) +
                               "): it is not connected; lower --min-confidence to connect it");
    }
    require(g.from != g.to, at + ": a connection from '" + g.from + "' to itself");
    const auto key = std::minmax(g.from, g.to);
    const auto [it, fresh] = seen.emplace(std::make_pair(key.first, key.second), g.line);
    require(fresh, at + ": " + g.from + " - " + g.to + " is given twice (also on line " +
                       std::to_string(it->second) + ")");
    Connection* match = nullptr;
    for (Connection& c : world.connections) {
      if (std::minmax(c.from, c.to) == key && c.kind == g.kind) match = &c;
    }
    if (match != nullptr) {
      match->given = true;
      continue;
    }
    const std::size_t i = index[g.from], j = index[g.to];
    const Eigen::Vector2d a = (world.objects[i].T_world_model * boxes[i].box.center()).head<2>();
    const Eigen::Vector2d b = (world.objects[j].T_world_model * boxes[j].box.center()).head<2>();
    Connection c;
    c.from = g.from;
    c.to = g.to;
    c.kind = g.kind;
    c.length_m = (b - a).norm();
    c.given = true;
    world.connections.push_back(c);
  }
}

std::optional<SeabedTruth> find_seabed_truth(const fs::path& map_path, const fs::path& dataset) {
  SeabedTruth truth;
  fs::path ds = dataset;
  const fs::path summary = map_path / "summary.json";
  std::error_code ec;
  if (fs::is_directory(map_path, ec) && fs::is_regular_file(summary, ec)) {
    const nlohmann::json j = parse_json_file(summary.string(), "map summary");
    if (ds.empty() && j.contains("dataset") && j["dataset"].is_string()) {
      ds = j["dataset"].get<std::string>();
    }
    const nlohmann::json* a = nullptr;
    if (j.contains("alignment") && j["alignment"].is_object() && j["alignment"].contains("after")) {
      a = &j["alignment"]["after"];
    }
    if (a != nullptr) {
      const std::string where = "map summary '" + summary.string() + "': alignment.after";
      try {
        const auto& M = (*a).at("matrix");
        const auto& s = (*a).at("shift_m");
        truth.M << M.at(0).at(0).get<double>(), M.at(0).at(1).get<double>(),
            M.at(1).at(0).get<double>(), M.at(1).at(1).get<double>();
        truth.b = {s.at(0).get<double>(), s.at(1).get<double>()};
        truth.dz = s.at(2).get<double>();
      } catch (const nlohmann::json::exception&) {
        throw Error(where + ": expected matrix [[2],[2]] and shift_m [3] numbers");
      }
      require(truth.M.allFinite() && truth.b.allFinite() && std::isfinite(truth.dz),
              where + ": a number is not finite");
      truth.has_alignment = true;
    }
  }
  if (ds.empty()) return std::nullopt;
  if (!fs::is_regular_file(ds / "truth" / "scene.yaml", ec)) {
    if (!dataset.empty()) {
      throw Error("truth dataset '" + ds.string() +
                  "': no truth/scene.yaml (a simulated dataset "
                  "from sonar3d simulate is needed)");
    }
    return std::nullopt;  // the map's dataset was not simulated (or moved): no error to measure
  }
  for (const SceneObject& o : read_truth(ds)) {
    if (o.kind == ObjectKind::Terrain) truth.terrain_world.append(o.mesh_world);
  }
  require(!truth.terrain_world.empty(),
          "truth dataset '" + ds.string() + "': truth/scene.yaml has no object of kind terrain");
  truth.dataset = ds.string();
  return truth;
}

SeabedError seabed_error(const TriangleMesh& mesh, const SeabedTruth& truth, std::size_t samples,
                         unsigned long long seed) {
  require(!mesh.empty(), "seabed_error: the seabed mesh is empty");
  const std::vector<Eigen::Vector3f> pts = sample_surface(mesh, samples, seed);
  const MeshDistance dist(truth.terrain_world);
  auto median = [](std::vector<double> d) {
    std::vector<float> f(d.begin(), d.end());
    return static_cast<double>(median_of(f));
  };
  SeabedError e;
  e.samples = pts.size();
  e.median_as_mapped_m = median(dist.distances(pts));
  if (truth.has_alignment) {
    std::vector<Eigen::Vector3f> placed;
    placed.reserve(pts.size());
    for (const Eigen::Vector3f& p : pts) {
      const Eigen::Vector2d xy = truth.M * p.head<2>().cast<double>() + truth.b;
      placed.emplace_back(static_cast<float>(xy.x()), static_cast<float>(xy.y()),
                          static_cast<float>(p.z() + truth.dz));
    }
    e.median_m = median(dist.distances(placed));
  } else {
    e.median_m = e.median_as_mapped_m;
  }
  return e;
}

namespace {

// ---------------------------------------------------------------------------------------------
// The stages of write_world_model, in the order it runs them: the seabed levels of detail (PLY),
// the glTF scene's seabed, each placed model (PLY, glTF node), the connections, then graph.json.

// The seabed levels of detail as PLY files (with vertex colours when video coloured them), their
// sizes into r.seabed_bytes; returns graph.json's "seabed" list.
nlohmann::json write_seabed_lods(const fs::path& tmp, const WorldModel& world,
                                 const WorldWriteInfo& info, WorldWriteResult& r) {
  nlohmann::json seabed = nlohmann::json::array();
  for (std::size_t k = 0; k < world.seabed.size(); ++k) {
    const SeabedLod& lod = world.seabed[k];
    require(!lod.mesh.empty(), fmt::format("seabed level of detail {} ({} m cells) has no "
                                           "triangle: use a finer cell",
                                           k, lod.cell_m));
    const std::string file = fmt::format("seabed_lod{}.ply", lod.lod);
    if (lod.color.empty()) {
      save_mesh((tmp / file).string(), lod.mesh);
    } else {
      // Vertex colours, sRGB bytes, black where no coloured point fell (as sonar3d texture).
      TexturedMesh tm;
      tm.mesh = lod.mesh;
      tm.color = lod.color;
      tm.views = lod.color_points;
      write_textured_mesh_ply(tmp / file, tm);
    }
    r.seabed_bytes.push_back(fs::file_size(tmp / file));
    const double err = info.seabed_error_m.empty() ? std::numeric_limits<double>::quiet_NaN()
                                                   : info.seabed_error_m[k];
    seabed.push_back({{"lod", lod.lod},
                      {"file", file},
                      {"cell_m", lod.cell_m},
                      {"triangles", lod.mesh.triangles.size()},
                      {"bytes", r.seabed_bytes.back()},
                      {"median_error_m", num_or_null(err)},
                      {"coloured_vertices", lod.coloured_vertices()}});
  }
  return seabed;
}

// glTF: the root turns ENU (z up) into glTF's y up; under it the seabed (the coarsest level, or
// every level with info.glb_all_lods), sand-coloured or with its video colours.
GltfScene seabed_scene(const WorldModel& world, const WorldWriteInfo& info) {
  GltfScene scene;
  const Eigen::Vector4f sand(0.62f, 0.56f, 0.42f, 1.0f);
  scene.nodes.push_back({"world (ENU z-up to glTF y-up)", -1, enu_to_gltf(), {}});
  scene.roots = {0};
  const std::size_t first_lod = info.glb_all_lods ? 0 : world.seabed.size() - 1;
  for (std::size_t k = first_lod; k < world.seabed.size(); ++k) {
    const SeabedLod& lod = world.seabed[k];
    std::vector<std::array<std::uint8_t, 3>> colors;
    for (std::size_t v = 0; v < lod.color.size(); ++v) {
      colors.push_back(lod.color_points[v] > 0 ? linear_to_srgb8(lod.color[v])
                                               : std::array<std::uint8_t, 3>{0, 0, 0});
    }
    // With video colours the material is white, so that COLOR_0 shows as it is.
    const Eigen::Vector4f base = colors.empty() ? sand : Eigen::Vector4f(1, 1, 1, 1);
    scene.meshes.push_back({fmt::format("seabed_lod{}", k), lod.mesh, std::move(colors), base});
    scene.nodes.push_back({fmt::format("seabed_lod{}", k),
                           static_cast<int>(scene.meshes.size()) - 1,
                           Eigen::Matrix4d::Identity(),
                           {}});
    scene.nodes[0].children.push_back(static_cast<int>(scene.nodes.size()) - 1);
  }
  return scene;
}

// Each placed model: models/<id>.ply in the world frame (sizes into r.models_bytes) and a glTF
// node under the root (its catalogue mesh in the model frame, shared per model, node =
// T_world_model; unconfirmed placements grey, named "<id> (unconfirmed)"); returns graph.json's
// "objects" list.
nlohmann::json write_placed_models(const fs::path& tmp, const WorldModel& world, GltfScene& scene,
                                   WorldWriteResult& r) {
  const Eigen::Vector4f steel(0.85f, 0.45f, 0.12f, 1.0f);
  // Unconfirmed placements (below the confidence threshold): grey, named "<id> (unconfirmed)".
  const Eigen::Vector4f unconfirmed(0.55f, 0.55f, 0.6f, 1.0f);
  std::map<std::string, int> mesh_of_model;
  nlohmann::json objects = nlohmann::json::array();
  for (const WorldObject& o : world.objects) {
    const std::string file = "models/" + o.id + ".ply";
    TriangleMesh placed = *o.mesh_model;
    placed.transform(o.T_world_model);
    save_mesh((tmp / file).string(), placed);
    r.models_bytes += fs::file_size(tmp / file);
    const std::string mesh_name = (o.confirmed ? o.model : o.model + " (unconfirmed)") +
                                  (o.scale != 1.0 ? fmt::format(" x{:.4f}", o.scale) : "");
    if (!mesh_of_model.count(mesh_name)) {
      scene.meshes.push_back({mesh_name, *o.mesh_model, {}, o.confirmed ? steel : unconfirmed});
      mesh_of_model[mesh_name] = static_cast<int>(scene.meshes.size()) - 1;
    }
    scene.nodes.push_back({o.confirmed ? o.id : o.id + " (unconfirmed)",
                           mesh_of_model[mesh_name],
                           o.T_world_model.matrix(),
                           {}});
    scene.nodes[0].children.push_back(static_cast<int>(scene.nodes.size()) - 1);
    nlohmann::json T = nlohmann::json::array();
    for (int rr = 0; rr < 4; ++rr) {
      for (int c = 0; c < 4; ++c) T.push_back(o.T_world_model.matrix()(rr, c));
    }
    objects.push_back({{"id", o.id},
                       {"model", o.model},
                       {"kind", o.kind},
                       {"T_world_model", T},
                       {"scale", o.scale},
                       {"score_m", num_or_null(o.score_m)},
                       {"residual_median_m", num_or_null(o.residual_median_m)},
                       {"confidence", num_or_null(o.confidence)},
                       {"confirmed", o.confirmed},
                       {"file", file}});
  }
  return objects;
}

// graph.json's "connections" list.
nlohmann::json connections_json(const WorldModel& world) {
  nlohmann::json connections = nlohmann::json::array();
  for (const Connection& c : world.connections) {
    connections.push_back({{"from", c.from},
                           {"to", c.to},
                           {"kind", c.kind},
                           {"length_m", c.length_m},
                           {"fraction", num_or_null(c.fraction)},
                           {"found", c.found},
                           {"given", c.given}});
  }
  return connections;
}

}  // namespace

// The world model's directory (stages above): seabed PLYs, model PLYs, world.glb, graph.json,
// written into a temporary directory and moved into place at the end.
WorldWriteResult write_world_model(const fs::path& dir, const WorldModel& world,
                                   const WorldWriteInfo& info) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(dir, ec)) &&
      !(fs::is_directory(dir, ec) && fs::is_empty(dir, ec))) {
    throw Error("'" + dir.string() +
                "' exists: sonar3d world writes a new directory; choose "
                "another output (-o) or remove it yourself");
  }
  require(!world.seabed.empty(), "write_world_model: no seabed level of detail");
  require(info.seabed_error_m.empty() || info.seabed_error_m.size() == world.seabed.size(),
          "write_world_model: one seabed error per level of detail");
  WorldWriteResult r;
  AtomicPath out(dir);
  const fs::path tmp = out.temp();
  fs::create_directories(tmp / "models");

  const nlohmann::json seabed = write_seabed_lods(tmp, world, info, r);
  GltfScene scene = seabed_scene(world, info);
  const nlohmann::json objects = write_placed_models(tmp, world, scene, r);
  write_glb(tmp / "world.glb", scene);
  r.glb_bytes = fs::file_size(tmp / "world.glb");

  r.bytes_total = r.glb_bytes + r.models_bytes;
  for (std::uintmax_t b : r.seabed_bytes) r.bytes_total += b;
  const nlohmann::json graph = {
      {"format", "sonar3d-world"},
      {"version", 1},
      {"min_confidence", world.min_confidence},
      {"objects", objects},
      {"connections", connections_json(world)},
      {"seabed", seabed},
      {"source",
       {{"map", info.map}, {"placements", info.placements}, {"catalogue", info.catalogue}}},
      {"bytes_total", r.bytes_total},
      {"cloud_bytes", info.cloud_bytes}};
  write_text_file((tmp / "graph.json").string(), graph.dump(2) + "\n");
  out.commit();
  return r;
}

}  // namespace sonar3d
