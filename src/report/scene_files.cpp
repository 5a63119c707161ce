#include "sonar3d/report/scene_files.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "sonar3d/core/error.hpp"

using json = nlohmann::json;

namespace sonar3d {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Typed access to one JSON object, every error naming the file and the key path.
class Obj {
 public:
  Obj(const json& j, std::string where) : j_(j), where_(std::move(where)) {
    if (!j_.is_object()) fail("", "must be a JSON object");
  }
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw Error(where_ + (key.empty() ? "" : "'" + key + "' ") + what);
  }
  bool has(const std::string& key) const { return j_.contains(key) && !j_[key].is_null(); }
  const json& at(const std::string& key) const {
    if (!j_.contains(key)) fail(key, "is missing");
    return j_[key];
  }
  std::string str(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_string()) fail(key, "must be a string");
    return v.get<std::string>();
  }
  std::string str_or(const std::string& key, const std::string& dflt) const {
    return has(key) ? str(key) : dflt;
  }
  // A finite number; null gives NaN when allowed.
  double num(const std::string& key, bool nullable = false) const {
    const json& v = at(key);
    if (v.is_null() && nullable) return kNaN;
    if (!v.is_number()) fail(key, nullable ? "must be a number or null" : "must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(key, "must be finite");
    return d;
  }
  double num_or(const std::string& key, double dflt) const { return has(key) ? num(key) : dflt; }
  bool boolean_or(const std::string& key, bool dflt) const {
    if (!has(key)) return dflt;
    const json& v = at(key);
    if (!v.is_boolean()) fail(key, "must be true or false");
    return v.get<bool>();
  }
  long long integer(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_number_integer() && !v.is_number_unsigned()) fail(key, "must be an integer");
    if (v.is_number_unsigned() &&
        v.get<unsigned long long>() >
            static_cast<unsigned long long>(std::numeric_limits<long long>::max())) {
      fail(key, "is out of range");
    }
    return v.get<long long>();
  }
  const json& array(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_array()) fail(key, "must be an array");
    return v;
  }
  // A rigid transform: 16 numbers row-major, or 4 rows of 4 (as placements.json writes them);
  // the last row 0 0 0 1 and the rotation orthonormal with determinant +1.
  Eigen::Matrix4d pose(const std::string& key) const {
    const json& v = at(key);
    Eigen::Matrix4d T;
    auto element = [&](const json& e, int r, int c) {
      if (!e.is_number() || !std::isfinite(e.get<double>())) {
        fail(key, "must hold finite numbers");
      }
      T(r, c) = e.get<double>();
    };
    if (v.is_array() && v.size() == 16) {
      for (int k = 0; k < 16; ++k) element(v[k], k / 4, k % 4);
    } else if (v.is_array() && v.size() == 4 && std::all_of(v.begin(), v.end(), [](const json& r) {
                 return r.is_array() && r.size() == 4;
               })) {
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) element(v[r][c], r, c);
    } else {
      fail(key, "must be a 4x4 matrix: 16 numbers row-major (or 4 rows of 4)");
    }
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    if (T.row(3).cwiseAbs().head<3>().maxCoeff() > 1e-6 || std::abs(T(3, 3) - 1) > 1e-6) {
      fail(key, "must be a rigid transform (last row 0 0 0 1)");
    }
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
        R.determinant() < 0) {
      fail(key, "must be a rigid transform (its rotation is not orthonormal with det +1)");
    }
    return T;
  }
  const std::string& where() const { return where_; }

 private:
  const json& j_;
  std::string where_;
};

// Nesting deeper than any of these files needs is refused while parsing: the recursive parser
// and destructor would otherwise overflow the stack on a hostile file of nested brackets.
constexpr int kMaxJsonDepth = 32;

json parse(const std::string& text, const std::string& path) {
  const json::parser_callback_t depth_guard = [&path](int depth, json::parse_event_t event, json&) {
    if ((event == json::parse_event_t::object_start || event == json::parse_event_t::array_start) &&
        depth >= kMaxJsonDepth) {
      throw Error("report: '" + path + "' nests objects or arrays deeper than " +
                  std::to_string(kMaxJsonDepth) + " levels");
    }
    return true;
  };
  try {
    return json::parse(text, depth_guard);
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for a number beyond double (fuzz_report_scene found it).
    throw Error("report: '" + path + "' is malformed JSON: " + e.what());
  }
}

// The top level: an object with the expected "format" and a version this reader knows.
Obj top(const json& j, const std::string& path, const std::string& format) {
  Obj o(j, "report: '" + path + "': ");
  if (o.str("format") != format) o.fail("format", "must be \"" + format + "\"");
  if (o.integer("version") != 1) o.fail("version", "must be 1 (the version this reader knows)");
  return o;
}

std::string entry(const std::string& path, const std::string& list, std::size_t i) {
  return "report: '" + path + "': " + list + "[" + std::to_string(i) + "]: ";
}

// A region's "centroid": 3 finite numbers.
Eigen::Vector3d centroid(const Obj& e) {
  const json& ctr = e.array("centroid");
  if (ctr.size() != 3 || !std::all_of(ctr.begin(), ctr.end(), [](const json& v) {
        return v.is_number() && std::isfinite(v.get<double>());
      })) {
    e.fail("centroid", "must be 3 finite numbers [x, y, z]");
  }
  return Eigen::Vector3d(ctr[0].get<double>(), ctr[1].get<double>(), ctr[2].get<double>());
}

}  // namespace

WorldGraph parse_world_graph(const std::string& text, const std::string& path) {
  const json j = parse(text, path);
  const Obj o = top(j, path, "sonar3d-world");
  WorldGraph g;
  std::set<std::string> ids;
  const json& objects = o.array("objects");
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const Obj e(objects[i], entry(path, "objects", i));
    WorldGraphObject w;
    w.id = e.str("id");
    if (w.id.empty()) e.fail("id", "must not be empty");
    if (!ids.insert(w.id).second) e.fail("id", "'" + w.id + "' is a duplicate");
    w.model = e.str("model");
    w.kind = e.str_or("kind", "");
    w.T_world_model = e.pose("T_world_model");
    w.score_m = e.has("score_m") ? e.num("score_m") : kNaN;
    w.residual_median_m = e.has("residual_median_m") ? e.num("residual_median_m", true) : kNaN;
    w.confidence = e.has("confidence") ? e.num("confidence") : kNaN;
    if (w.confidence < 0 || w.confidence > 1) e.fail("confidence", "must lie in [0, 1]");
    w.confirmed = e.boolean_or("confirmed", true);  // files before min_confidence: all confirmed
    w.file = e.str("file");
    g.objects.push_back(w);
  }
  const json& connections = o.array("connections");
  for (std::size_t i = 0; i < connections.size(); ++i) {
    const Obj e(connections[i], entry(path, "connections", i));
    WorldConnection c;
    c.from = e.str("from");
    c.to = e.str("to");
    if (!ids.count(c.from)) e.fail("from", "names no object ('" + c.from + "')");
    if (!ids.count(c.to)) e.fail("to", "names no object ('" + c.to + "')");
    for (const WorldGraphObject& w : g.objects) {
      if (!w.confirmed && (w.id == c.from || w.id == c.to)) {
        e.fail(w.id == c.from ? "from" : "to",
               "names an unconfirmed object ('" + w.id + "'): sonar3d world never connects one");
      }
    }
    c.kind = e.str_or("kind", "");
    c.length_m = e.has("length_m") ? e.num("length_m") : kNaN;
    c.found = e.boolean_or("found", true);  // files before given connections: all found
    c.given = e.boolean_or("given", false);
    g.connections.push_back(c);
  }
  const json& seabed = o.array("seabed");
  std::set<long long> lods;
  for (std::size_t i = 0; i < seabed.size(); ++i) {
    const Obj e(seabed[i], entry(path, "seabed", i));
    WorldSeabedLod s;
    const long long lod = e.integer("lod");
    if (lod < 0 || lod > 1000) e.fail("lod", "must be in [0, 1000]");
    if (!lods.insert(lod).second) e.fail("lod", std::to_string(lod) + " is a duplicate");
    s.lod = static_cast<int>(lod);
    s.file = e.str("file");
    s.cell_m = e.num_or("cell_m", kNaN);
    s.triangles = e.has("triangles") ? e.integer("triangles") : -1;
    s.bytes = e.has("bytes") ? e.integer("bytes") : -1;
    s.median_error_m = e.has("median_error_m") ? e.num("median_error_m", true) : kNaN;
    g.seabed.push_back(s);
  }
  std::sort(g.seabed.begin(), g.seabed.end(),
            [](const WorldSeabedLod& a, const WorldSeabedLod& b) { return a.lod < b.lod; });
  if (o.has("source")) {
    const Obj s(o.at("source"), o.where() + "source: ");
    g.source_map = s.str_or("map", "");
    g.source_placements = s.str_or("placements", "");
    g.source_catalogue = s.str_or("catalogue", "");
  }
  g.min_confidence = o.has("min_confidence") ? o.num("min_confidence") : kNaN;
  g.bytes_total = o.has("bytes_total") ? o.integer("bytes_total") : -1;
  g.cloud_bytes = o.has("cloud_bytes") ? o.integer("cloud_bytes") : -1;
  return g;
}

ChangeSet parse_changes_json(const std::string& text, const std::string& path) {
  const json j = parse(text, path);
  const Obj o = top(j, path, "sonar3d-changes");
  ChangeSet c;
  c.T_a_b = o.pose("T_a_b");
  if (o.has("registration")) {
    const Obj r(o.at("registration"), o.where() + "registration: ");
    c.registration_method = r.str_or("method", "");
    c.registration_rms_m = r.has("rms_m") ? r.num("rms_m", true) : kNaN;
    c.overlap_cells = r.has("overlap_cells") ? r.integer("overlap_cells") : -1;
  }
  const json& objects = o.array("objects");
  static const std::set<std::string> kStatus = {"unchanged", "moved", "added", "removed",
                                                "uncertain"};
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const Obj e(objects[i], entry(path, "objects", i));
    ChangedObject ob;
    ob.id = e.str("id");
    ob.model = e.str("model");
    ob.status = e.str("status");
    if (!kStatus.count(ob.status)) {
      e.fail("status",
             "'" + ob.status + "' is none of unchanged, moved, added, removed, uncertain");
    }
    ob.has_a = e.has("T_world_model_a");
    ob.has_b = e.has("T_world_model_b_in_a");
    if (ob.has_a) ob.T_world_model_a = e.pose("T_world_model_a");
    if (ob.has_b) ob.T_world_model_b_in_a = e.pose("T_world_model_b_in_a");
    ob.reason = e.str_or("reason", "");
    ob.other_model = e.str_or("other_model", "");
    if (ob.status == "unchanged" && ob.has_a != ob.has_b) {
      // Written by sonar3d diff before "uncertain": a recognition in one survey only that no
      // height change confirmed (issue 28).
      ob.status = "uncertain";
      if (ob.reason.empty()) {
        ob.reason = std::string("recognised in ") + (ob.has_a ? "A" : "B") +
                    " only; no height change confirmed it (read from an older file as "
                    "\"unchanged\")";
      }
    }
    if (ob.status == "uncertain" && !ob.has_a && !ob.has_b) {
      e.fail("T_world_model_a",
             "and 'T_world_model_b_in_a' are null: an uncertain object was "
             "recognised in at least one survey");
    }
    if (ob.status != "added" && ob.status != "uncertain" && !ob.has_a) {
      e.fail("T_world_model_a", "is null, but a " + ob.status + " object was in survey A");
    }
    if (ob.status != "removed" && ob.status != "uncertain" && !ob.has_b) {
      e.fail("T_world_model_b_in_a", "is null, but a " + ob.status + " object is in survey B");
    }
    ob.shift_m = e.has("shift_m") ? e.num("shift_m", true) : kNaN;
    ob.turn_deg = e.has("turn_deg") ? e.num("turn_deg", true) : kNaN;
    ob.change_area_m2 = e.has("change_area_m2") ? e.num("change_area_m2", true) : kNaN;
    c.objects.push_back(ob);
  }
  if (o.has("regions")) {
    const json& regions = o.array("regions");
    for (std::size_t i = 0; i < regions.size(); ++i) {
      const Obj e(regions[i], entry(path, "regions", i));
      ChangedRegion r;
      r.id = e.integer("id");
      r.centroid = centroid(e);
      r.area_m2 = e.num("area_m2");
      r.max_abs_change_m = e.num("max_abs_change_m");
      r.mean_change_m = e.num("mean_change_m");
      r.kind = e.str_or("kind", "");
      c.regions.push_back(r);
    }
  }
  if (o.has("colour")) {
    const Obj col(o.at("colour"), o.where() + "colour: ");
    c.colour_space = col.str("space");
    const json& regions = col.array("regions");
    for (std::size_t i = 0; i < regions.size(); ++i) {
      const Obj e(regions[i], entry(path, "colour.regions", i));
      ChangedColourRegion r;
      r.id = e.integer("id");
      r.centroid = centroid(e);
      r.area_m2 = e.num("area_m2");
      r.max_delta = e.num("max_delta");
      r.mean_delta = e.num("mean_delta");
      r.height_change_fraction =
          e.has("height_change_fraction") ? e.num("height_change_fraction") : kNaN;
      for (const char* key : {"colour_a", "colour_b"}) {
        const json& v = e.array(key);
        if (v.size() != 3 || !std::all_of(v.begin(), v.end(), [](const json& x) {
              return x.is_number_integer() && x.get<long long>() >= 0 && x.get<long long>() <= 255;
            })) {
          e.fail(key, "must be 3 integers in [0, 255] (8-bit sRGB)");
        }
        auto& rgb = std::string(key) == "colour_a" ? r.colour_a : r.colour_b;
        for (std::size_t k = 0; k < 3; ++k) rgb[k] = v[k].get<int>();
      }
      c.colour_regions.push_back(r);
    }
  }
  return c;
}

}  // namespace sonar3d
