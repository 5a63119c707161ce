#include "sonar3d/plan/sweep.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d {
namespace {

const std::map<std::string, SweepValue>& defaults() {
  static const std::map<std::string, SweepValue> d = {{"object", std::string("sphere")},
                                                      {"aperture_deg", 10.0},
                                                      {"range_res_m", 0.02},
                                                      {"bearing_res_deg", 0.2},
                                                      {"fov_deg", 60.0},
                                                      {"snr_db", std::monostate{}},
                                                      {"spacing_m", 0.01},
                                                      {"standoff_m", 3.0},
                                                      {"path", std::string("vertical")},
                                                      // the reconstruction's own defaults
                                                      {"method", ReconstructConfig().method},
                                                      {"voxel_m", ReconstructConfig().voxel_size}};
  return d;
}

// "reconstruct.<dotted path>": any setting of the reconstruction (ReconstructConfig's one
// declaration, docs/reference.md), e.g. reconstruct.bracket.min_bracket.
constexpr const char* kReconstructPrefix = "reconstruct.";
bool is_reconstruct_path(const std::string& p) { return p.rfind(kReconstructPrefix, 0) == 0; }

// Checks a reconstruct.* value as a configuration file's would be (key, type, bounds, choices).
void check_reconstruct_value(const YAML::Node& n, const std::string& param,
                             const std::string& file) {
  ReconstructConfig scratch;
  params::set_dotted(scratch, param.substr(std::string(kReconstructPrefix).size()), n, file,
                     "reconstruct");
}

bool is_string_parameter(const std::string& p) {
  return p == "object" || p == "path" || p == "method";
}

SweepValue parse_value(const YAML::Node& n, const std::string& param, const std::string& file,
                       const std::string& ctx) {
  if (!n.IsScalar()) throw Error(yaml::where(file, n, ctx) + ": expected a single value");
  const std::string s = n.Scalar();
  if (is_reconstruct_path(param)) {
    check_reconstruct_value(n, param, file);
    double v = 0;
    if (YAML::convert<double>::decode(n, v) && std::isfinite(v)) return v;
    return s;
  }
  if (param == "snr_db" && (s == "none" || s == "null" || s == "~" || s.empty())) {
    return std::monostate{};
  }
  if (is_string_parameter(param)) {
    if (param == "path" && s != "vertical" && s != "orbit") {
      throw Error(yaml::where(file, n, ctx) + ": path must be vertical or orbit, got '" + s + "'");
    }
    if (param == "method" && s != "carve" && s != "deconv" && s != "deconv-l1" &&
        s != "deconv-exact") {
      throw Error(yaml::where(file, n, ctx) +
                  ": method must be carve, deconv, deconv-l1 or deconv-exact, got '" + s + "'");
    }
    return s;
  }
  double v;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw Error(yaml::where(file, n, ctx) + ": expected a number, got '" + s + "'");
  }
  if (!std::isfinite(v)) throw Error(yaml::where(file, n, ctx) + ": must be finite");
  if (param != "snr_db" && !(v > 0)) throw Error(yaml::where(file, n, ctx) + ": must be > 0");
  if (param == "aperture_deg" && !(v < 180)) {
    throw Error(yaml::where(file, n, ctx) + ": a vertical aperture must lie in (0°, 180°)");
  }
  return v;
}

}  // namespace

std::string to_string(const SweepValue& v) {
  if (std::holds_alternative<std::monostate>(v)) return "none";
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  std::ostringstream os;
  os << std::setprecision(10) << std::get<double>(v);
  return os.str();
}

const std::vector<std::string>& sweep_parameter_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& kv : defaults()) n.push_back(kv.first);
    return n;
  }();
  return names;
}

bool SweepConstraint::satisfied_by(const std::map<std::string, SweepValue>& params) const {
  const auto it = params.find(parameter);
  if (it == params.end() || !std::holds_alternative<double>(it->second)) return false;
  const double x = std::get<double>(it->second);
  if (op == ">=") return x >= value;
  if (op == "<=") return x <= value;
  if (op == ">") return x > value;
  if (op == "<") return x < value;
  if (op == "==") return x == value;
  return x != value;
}

std::size_t Sweep::size() const {
  std::size_t n = 1;
  for (const auto& a : axes) n *= a.second.size();
  return n;
}

std::map<std::string, SweepValue> Sweep::point(std::size_t index) const {
  if (index >= size()) throw Error("sweep point " + std::to_string(index) + " does not exist");
  std::map<std::string, SweepValue> p = defaults();
  for (const auto& kv : fixed) p[kv.first] = kv.second;
  for (auto it = axes.rbegin(); it != axes.rend(); ++it) {
    const std::size_t n = it->second.size();
    p[it->first] = it->second[index % n];
    index /= n;
  }
  return p;
}

bool metric_higher_is_better(const std::string& metric) { return metric == "coverage"; }

std::string point_id(std::size_t index) {
  std::ostringstream os;
  os << 'p' << std::setw(4) << std::setfill('0') << index;
  return os.str();
}

Sweep load_sweep(const std::string& path) {
  Sweep s;
  s.source = path;
  YAML::Node root = yaml::load_file(path);
  if (!root.IsMap()) throw Error(path + ": expected a mapping at the top level");
  yaml::check_keys(root,
                   {"axes", "fixed", "constraints", "rank_by", "workers", "keep_datasets",
                    "elevation_step_deg", "seed"},
                   path);
  std::set<std::string> known(sweep_parameter_names().begin(), sweep_parameter_names().end());
  const YAML::Node axes = root["axes"];
  if (!axes || !axes.IsMap() || axes.size() == 0) {
    throw Error(path + ": 'axes' must map at least one parameter to a list of values");
  }
  auto with_reconstruct_paths = [&](const YAML::Node& block) {
    std::set<std::string> k = known;
    for (const auto& kv : block) {
      const std::string name = kv.first.as<std::string>();
      if (is_reconstruct_path(name)) k.insert(name);
    }
    return k;
  };
  yaml::check_keys(axes, with_reconstruct_paths(axes), path, "axes");
  for (const auto& kv : axes) {
    const std::string name = kv.first.as<std::string>();
    const std::string ctx = "axes." + name;
    const YAML::Node list = kv.second;
    if (!list.IsSequence() || list.size() == 0) {
      throw Error(yaml::where(path, list, ctx) + ": an axis needs a non-empty list of values");
    }
    std::vector<SweepValue> values;
    for (std::size_t i = 0; i < list.size(); ++i) {
      values.push_back(parse_value(list[i], name, path, ctx + "[" + std::to_string(i) + "]"));
    }
    s.axes.emplace_back(name, std::move(values));
  }
  if (const YAML::Node f = root["fixed"]) {
    yaml::check_keys(f, with_reconstruct_paths(f), path, "fixed");
    for (const auto& kv : f) {
      const std::string name = kv.first.as<std::string>();
      s.fixed[name] = parse_value(kv.second, name, path, "fixed." + name);
    }
  }
  if (const YAML::Node c = root["constraints"]) {
    if (!c.IsSequence()) throw Error(yaml::where(path, c, "constraints") + ": expected a list");
    for (std::size_t i = 0; i < c.size(); ++i) {
      const std::string ctx = "constraints[" + std::to_string(i) + "]";
      const std::string text = c[i].IsScalar() ? c[i].Scalar() : "";
      std::istringstream is(text);
      SweepConstraint k;
      k.text = text;
      std::string value;
      if (!(is >> k.parameter >> k.op >> value) || !(k.op == ">=" || k.op == "<=" || k.op == ">" ||
                                                     k.op == "<" || k.op == "==" || k.op == "!=")) {
        throw Error(yaml::where(path, c[i], ctx) +
                    ": expected 'parameter op number' with op one of >= <= > < == !=");
      }
      if ((!known.count(k.parameter) && !is_reconstruct_path(k.parameter)) ||
          is_string_parameter(k.parameter)) {
        throw Error(yaml::where(path, c[i], ctx) + ": '" + k.parameter +
                    "' is not a numeric sweep parameter");
      }
      try {
        k.value = std::stod(value);
      } catch (const std::exception&) {
        throw Error(yaml::where(path, c[i], ctx) + ": '" + value + "' is not a number");
      }
      s.constraints.push_back(k);
    }
  }
  s.rank_by = yaml::get_string(root, "rank_by", s.rank_by, path);
  static const std::set<std::string> metrics = {"median_error_m", "mean_error_m",       "coverage",
                                                "outliers",       "median_to_coverage", "runtime_s",
                                                "peak_rss_mb",    "data_bytes"};
  if (!metrics.count(s.rank_by)) {
    std::string list;
    for (const auto& m : metrics) list += (list.empty() ? "" : ", ") + m;
    throw Error(yaml::where(path, root["rank_by"], "rank_by") + ": unknown metric '" + s.rank_by +
                "' (one of " + list + ")");
  }
  s.workers = yaml::get_int(root, "workers", 0, path);
  if (s.workers < 0) throw Error(yaml::where(path, root["workers"], "workers") + ": must be >= 0");
  s.keep_datasets = yaml::get_bool(root, "keep_datasets", false, path);
  s.elevation_step_deg = yaml::get_double(root, "elevation_step_deg", s.elevation_step_deg, path);
  if (!(s.elevation_step_deg > 0)) {
    throw Error(yaml::where(path, root["elevation_step_deg"], "elevation_step_deg") +
                ": must be > 0");
  }
  s.seed = static_cast<unsigned long long>(yaml::get_int(root, "seed", 1, path));
  if (s.size() > 100000) throw Error(path + ": the sweep has more than 100000 points");
  return s;
}

}  // namespace sonar3d
