#pragma once
// The configurations declared with core/params.hpp, as YAML: the effective configuration printed
// by `--print-config` and read back by `--config FILE` (a run from a printed configuration is the
// run that printed it). Keys are the fields' names, groups nest; reading rejects unknown keys and
// out-of-bounds or mistyped values naming the file, line and dotted key.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace sonar3d::params {

// Writes the fields as a block map into an open YAML emitter (inside a map: call between
// BeginMap/EndMap of the caller, after emitting the group's key).
struct YamlWriter {
  YAML::Emitter& out;
  template <class T>
  void field(T& value, const Param& p) {
    out << YAML::Key << p.key << YAML::Value;
    if constexpr (std::is_enum_v<T>) {
      out << field_text(value, p);
    } else if constexpr (std::is_same_v<T, Box>) {
      if (!value) {
        out << YAML::Null;
      } else {
        out << YAML::Flow << YAML::BeginSeq;
        for (int k = 0; k < 6; ++k) {
          out << format_number(k < 3 ? value->min()[k] : value->max()[k - 3]);
        }
        out << YAML::EndSeq;
      }
    } else if constexpr (std::is_same_v<T, Maybe>) {
      if (value) {
        out << format_number(*value);
      } else {
        out << YAML::Null;
      }
    } else if constexpr (std::is_same_v<T, List>) {
      out << YAML::Flow << YAML::BeginSeq;
      for (const double v : value) out << format_number(v);
      out << YAML::EndSeq;
    } else if constexpr (std::is_same_v<T, bool>) {
      out << (value ? "true" : "false");
    } else if constexpr (std::is_arithmetic_v<T>) {
      out << format_value(value);
    } else {
      out << YAML::DoubleQuoted << value;
    }
  }
  template <class G>
  void group(const char* key, G& g) {
    out << YAML::Key << key << YAML::Value << YAML::BeginMap;
    describe(g, *this);
    out << YAML::EndMap;
  }
};
template <class C>
void emit_yaml(YAML::Emitter& out, const C& config) {
  C copy = config;
  YamlWriter w{out};
  out << YAML::BeginMap;
  describe(copy, w);
  out << YAML::EndMap;
}

// Reads the keys present in a map node; absent keys keep their value. Unknown keys are an error.
struct YamlReader : PathVisitor<YamlReader> {
  const YAML::Node* node;
  std::string file;
  std::set<std::string> known;
  template <class T>
  void field(T& value, const Param& p) {
    known.insert(p.key);
    const YAML::Node n = (*node)[p.key];
    if (!n) return;
    const std::string path = join(prefix, p.key);
    const std::string at = yaml::where(file, n, path);
    if constexpr (std::is_same_v<T, Box>) {
      // [xmin, ymin, zmin, xmax, ymax, zmax], or null / none for no region
      if (n.IsNull() || (n.IsScalar() && n.Scalar() == "none")) {
        value.reset();
        return;
      }
      if (!n.IsSequence() || n.size() != 6) {
        throw Error(at + ": expected [xmin, ymin, zmin, xmax, ymax, zmax] (m) or none");
      }
      double v[6];
      for (int k = 0; k < 6; ++k) {
        if (!n[k].IsScalar() || !YAML::convert<double>::decode(n[k], v[k]) ||
            !std::isfinite(v[k])) {
          throw Error(at + ": expected a finite number at position " + std::to_string(k + 1));
        }
      }
      const Eigen::AlignedBox3d b(Eigen::Vector3d(v[0], v[1], v[2]),
                                  Eigen::Vector3d(v[3], v[4], v[5]));
      if (!(b.max().array() > b.min().array()).all()) {
        throw Error(at + ": max must exceed min on every axis, got " + box_text(b));
      }
      value = b;
    } else if constexpr (std::is_same_v<T, List>) {
      // [a, b, ...]: finite numbers, each within the field's bounds (whether the list may be
      // empty is the config's validate() to say)
      if (!n.IsSequence() || n.size() > 1000) {
        throw Error(at + ": expected a list of at most 1000 numbers" +
                    (*p.unit ? " (" + std::string(p.unit) + ")" : std::string()));
      }
      List l;
      for (std::size_t k = 0; k < n.size(); ++k) {
        double d = 0;
        if (!n[k].IsScalar() || !YAML::convert<double>::decode(n[k], d) || !std::isfinite(d)) {
          throw Error(at + ": expected a finite number at position " + std::to_string(k + 1));
        }
        if (!in_bounds(p, d)) {
          throw Error(at + ": position " + std::to_string(k + 1) + " " + bounds_rule(p) + ", got " +
                      n[k].Scalar());
        }
        l.push_back(d);
      }
      value = std::move(l);
    } else if constexpr (std::is_same_v<T, Maybe>) {
      // a number, or null / none for "from elsewhere"
      if (n.IsNull() || (n.IsScalar() && n.Scalar() == "none")) {
        value.reset();
        return;
      }
      double d = 0;
      read_scalar(d, p, n, at);
      value = d;
    } else {
      read_scalar(value, p, n, at);
    }
  }
  template <class T>
  void read_scalar(T& value, const Param& p, const YAML::Node& n, const std::string& at) {
    if (!n.IsScalar()) throw Error(at + ": expected a single value");
    if constexpr (std::is_enum_v<T>) {
      value = parse_choice<T>(p, n.Scalar(), at);
    } else if constexpr (std::is_same_v<T, bool>) {
      bool b = false;
      if (!YAML::convert<bool>::decode(n, b)) throw Error(at + ": expected true or false");
      value = b;
    } else if constexpr (std::is_integral_v<T>) {
      T t{};
      if (!YAML::convert<T>::decode(n, t)) {
        throw Error(at + ": expected a whole number" +
                    (std::is_unsigned_v<T> ? std::string(" >= 0") : std::string()) + ", got '" +
                    printable(n.Scalar()) + "'");
      }
      if (p.bounded() && !in_bounds(p, static_cast<double>(t))) {
        throw Error(at + ": " + bounds_rule(p) + ", got " + n.Scalar());
      }
      value = t;
    } else if constexpr (std::is_arithmetic_v<T>) {
      double d = 0;
      if (!YAML::convert<double>::decode(n, d) || !std::isfinite(d)) {
        throw Error(at + ": expected a finite number, got '" + printable(n.Scalar()) + "'");
      }
      if (p.bounded() && !in_bounds(p, d)) {
        throw Error(at + ": " + bounds_rule(p) + ", got " + n.Scalar());
      }
      value = static_cast<T>(d);
    } else {
      if (p.n_names > 0 && choice_index(p, n.Scalar()) < 0) {
        throw Error(at + ": must be one of " + choices_text(p) + ", got '" + printable(n.Scalar()) +
                    "'");
      }
      value = n.Scalar();
    }
  }
  template <class G>
  void group(const char* key, G& g) {
    known.insert(key);
    const YAML::Node n = (*node)[key];
    if (!n) return;
    read_map(n, file, join(prefix, key), g);
  }
  // A map node onto `g`: its fields read, any other key refused.
  template <class G>
  static void read_map(const YAML::Node& n, const std::string& file, const std::string& path,
                       G& g) {
    if (!n.IsMap()) throw Error(yaml::where(file, n, path) + ": expected a map of settings");
    YamlReader inner;
    inner.node = &n;
    inner.file = file;
    inner.prefix = path;
    describe(g, inner);
    yaml::check_keys(n, inner.known, file, path);
  }
};
// `node` (a map) onto `config`; `ctx` the dotted path of the node in its file, for errors.
template <class C>
void read_yaml(const YAML::Node& node, const std::string& file, const std::string& ctx, C& config) {
  YamlReader::read_map(node, file, ctx, config);
}

// One field given by its dotted path ("carve.occlusion.explain_returns") and a YAML value onto
// `config`, checked as a configuration file's (unknown keys, bounds, choices; errors name `file`,
// the value's line and `ctx` + the path). The planner's sweep varies any setting this way.
inline YAML::Node nest_dotted(const std::vector<std::string>& parts, std::size_t i,
                              const YAML::Node& leaf) {
  if (i == parts.size()) return leaf;
  YAML::Node m(YAML::NodeType::Map);
  m[parts[i]] = nest_dotted(parts, i + 1, leaf);
  return m;
}
template <class C>
void set_dotted(C& config, const std::string& dotted, const YAML::Node& value,
                const std::string& file, const std::string& ctx) {
  std::vector<std::string> parts;
  std::size_t a = 0;
  while (a <= dotted.size()) {
    const std::size_t b = std::min(dotted.find('.', a), dotted.size());
    if (b == a) throw Error(file + ": '" + ctx + dotted + "': an empty key in the dotted path");
    parts.push_back(dotted.substr(a, b - a));
    a = b + 1;
  }
  read_yaml(nest_dotted(parts, 0, value), file, ctx, config);
}

}  // namespace sonar3d::params
