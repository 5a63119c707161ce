#pragma once
// One declaration per parameter (docs/design.md, "Parameters"). A component's config struct keeps
// each field's default where the field is declared; beside the struct, one function
//
//   template <class V> void describe(RecognitionConfig& c, V& v) {
//     v.field(c.map_cell_m, param("map_cell_m", "m", "fine elevation map cell").positive()
//                               .flag("--map-cell"));
//     v.group("verification", c.verification);
//   }
//
// states, once, every field's name (the YAML key and the Python attribute), unit, help, bounds,
// the thesis equation it implements and, when a command exposes it, its flag. Everything else is
// derived from that one list by visitors: bounds checks (`check`, below), the effective
// configuration as YAML and from YAML (io/params_yaml.hpp), command-line options
// (apps/sonar3d/params_cli.hpp), Python classes (python/src/params_py.hpp) and the generated
// reference (`reference_markdown`, docs/reference.md, kept current by a test).
//
// A visitor V has
//   template <class T> void field(T& value, const Param& p);   T: double, int, std::size_t,
//                                                              unsigned long long, bool, string,
//                                                              an enum (with .choices), Box (an
//                                                              optional world box), List
//                                                              (numbers, each within bounds) or
//                                                              Maybe (an optional number)
//   template <class G> void group(const char* key, G& g);      recurses with describe(g, *this)
// and `describe` is found by argument-dependent lookup.
//
// Enums and strings with a fixed set of values declare `.choices(names)`: an enum's value k is
// names[k] everywhere outside C++ (YAML, flags, Python, the reference), the one enum <-> string
// convention. A config nested in a larger one that sets some of its fields itself (the
// reconstruction's shared voxel size, say) is described there as `Nested<C>` (below), whose
// `describe` lists only the fields the larger config leaves to it.
#include <Eigen/Geometry>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "sonar3d/core/error.hpp"

namespace sonar3d::params {

// One field's declaration. Built by param(...) and chained setters, all constexpr.
struct Param {
  const char* key = "";   // YAML key and Python attribute
  const char* unit = "";  // "m", "deg", "s", "" (a count, a fraction, a switch)
  const char* help = "";
  const char* cli = nullptr;           // the command line's flag, when a command exposes the field
  const char* eq = nullptr;            // the thesis' equation or section it implements
  const char* const* names = nullptr;  // .choices: the allowed values (an enum's, by index)
  int n_names = 0;
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;

  constexpr Param flag(const char* f) const {
    return with([&](Param& p) { p.cli = f; });
  }
  template <std::size_t N>
  constexpr Param choices(const char* const (&n)[N]) const {
    return with([&](Param& p) { p.names = n, p.n_names = static_cast<int>(N); });
  }
  constexpr Param equation(const char* e) const {
    return with([&](Param& p) { p.eq = e; });
  }
  // Bounds: [lo, hi], (0, inf), [0, inf), and the open variants.
  constexpr Param range(double l, double h) const {
    return with([&](Param& p) { p.lo = l, p.hi = h; });
  }
  constexpr Param range_open_low(double l, double h) const {
    return with([&](Param& p) { p.lo = l, p.hi = h, p.lo_open = true; });
  }
  constexpr Param range_open_high(double l, double h) const {
    return with([&](Param& p) { p.lo = l, p.hi = h, p.hi_open = true; });
  }
  constexpr Param range_open(double l, double h) const {
    return with([&](Param& p) { p.lo = l, p.hi = h, p.lo_open = p.hi_open = true; });
  }
  constexpr Param positive() const {
    return with([&](Param& p) { p.lo = 0, p.lo_open = true; });
  }
  constexpr Param non_negative() const {
    return with([&](Param& p) { p.lo = 0; });
  }
  constexpr Param at_least(double l) const {
    return with([&](Param& p) { p.lo = l; });
  }
  constexpr Param at_most(double h) const {
    return with([&](Param& p) { p.hi = h; });
  }
  constexpr bool bounded() const {
    return lo > -std::numeric_limits<double>::infinity() ||
           hi < std::numeric_limits<double>::infinity();
  }

 private:
  template <class F>
  constexpr Param with(F&& f) const {
    Param p = *this;
    f(p);
    return p;
  }
};

constexpr Param param(const char* key, const char* unit, const char* help) {
  Param p;
  p.key = key;
  p.unit = unit;
  p.help = help;
  return p;
}

// An optional world-frame box (a region of interest): absent = unbounded.
using Box = std::optional<Eigen::AlignedBox3d>;

// A list of numbers (the seabed's levels of detail, say): each element within the field's bounds;
// whether it may be empty is the config's validate() to say.
using List = std::vector<double>;

// An optional number: absent ("none" in YAML and the reference, null in JSON, None in Python)
// means the value comes from elsewhere, which the field's help says (a placements file's own
// threshold, say). When present it must lie within the field's bounds.
using Maybe = std::optional<double>;

// A config C nested in a larger one that sets some of C's fields itself: `describe(Nested<C>&,
// V&)` (declared beside C's own describe) lists only the fields the larger config leaves to C.
// Visitors see the fields of `c` (a reference into the larger config), so offsets, paths and
// values are those of the larger config.
template <class C>
struct Nested {
  C& c;
};
template <class G>
struct is_nested : std::false_type {};
template <class C>
struct is_nested<Nested<C>> : std::true_type {};

// "(0, 180]", "> 0", ">= 1": the bounds in words; "a | b | c" for choices.
std::string bounds_text(const Param& p);
// "must lie in (0, 180] deg", "must be a finite number > 0 m".
std::string bounds_rule(const Param& p);
inline bool in_bounds(const Param& p, double v) {
  return std::isfinite(v) && (p.lo_open ? v > p.lo : v >= p.lo) &&
         (p.hi_open ? v < p.hi : v <= p.hi);
}
// The value formatted as the YAML writer and the reference show it (shortest round-trip form).
std::string format_number(double v);
// A field's value as text: whole numbers exactly, reals by format_number.
template <class T>
std::string format_value(const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    return value ? "true" : "false";
  } else if constexpr (std::is_integral_v<T>) {
    return std::to_string(value);
  } else if constexpr (std::is_arithmetic_v<T>) {
    return format_number(static_cast<double>(value));
  } else {
    return value;
  }
}
// "passes, voxel or auto".
std::string choices_text(const Param& p);
// The index of `s` among p's choices, -1 when it is none of them.
int choice_index(const Param& p, const std::string& s);
// The name of choice k (an enum's value), "?" when out of range.
inline const char* choice_name(const Param& p, int k) {
  return k >= 0 && k < p.n_names ? p.names[k] : "?";
}
// `s` as a value of the enum E declared with p's choices; throws "<what> must be one of ...".
template <class E>
E parse_choice(const Param& p, const std::string& s, const std::string& what) {
  const int k = choice_index(p, s);
  if (k < 0) throw Error(what + " must be one of " + choices_text(p) + ", got '" + s + "'");
  return static_cast<E>(k);
}
// "[xmin, ymin, zmin, xmax, ymax, zmax]" or "none".
std::string box_text(const Box& b);
// "[0.05, 0.2, 1]".
std::string list_text(const List& l);
// A field's value as text, as the YAML writer and the reference show it.
template <class T>
std::string field_text(const T& value, const Param& p) {
  if constexpr (std::is_enum_v<T>) {
    return choice_name(p, static_cast<int>(value));
  } else if constexpr (std::is_same_v<T, Box>) {
    return box_text(value);
  } else if constexpr (std::is_same_v<T, List>) {
    return list_text(value);
  } else if constexpr (std::is_same_v<T, Maybe>) {
    return value ? format_number(*value) : std::string("none");
  } else {
    return format_value(value);
  }
}

// The error for `value` outside p's bounds: "<where>: <path> (<flag>) must ..., got <value>".
[[noreturn]] void throw_out_of_bounds(const std::string& where, const std::string& path,
                                      const Param& p, double value);

// Joins dotted paths: "" + "a" = "a", "a" + "b" = "a.b".
inline std::string join(const std::string& prefix, const char* key) {
  return prefix.empty() ? std::string(key) : prefix + "." + key;
}

// Visits every field with its dotted path ("verification.min_confidence"): the common base of the
// visitors that need paths.
template <class Derived>
struct PathVisitor {
  std::string prefix;
  template <class G>
  void group(const char* key, G& g) {
    const std::string saved = prefix;
    prefix = join(prefix, key);
    describe(g, static_cast<Derived&>(*this));
    prefix = saved;
  }
};

// Bounds checks: every numeric field inside its declared bounds (finite when bounded).
struct BoundsCheck : PathVisitor<BoundsCheck> {
  std::string where;
  template <class T>
  void field(T& value, const Param& p) {
    if constexpr (std::is_same_v<T, std::string>) {
      if (p.n_names > 0 && choice_index(p, value) < 0) {
        throw Error((where.empty() ? std::string() : where + " ") + join(prefix, p.key) +
                    (p.cli ? std::string(" (") + p.cli + ")" : std::string()) + " must be one of " +
                    choices_text(p) + ", got '" + value + "'");
      }
    } else if constexpr (std::is_same_v<T, Box>) {
      if (value && !(value->min().allFinite() && value->max().allFinite() &&
                     (value->max().array() > value->min().array()).all())) {
        throw Error((where.empty() ? std::string() : where + " ") + join(prefix, p.key) +
                    (p.cli ? std::string(" (") + p.cli + ")" : std::string()) +
                    " must have finite corners and max > min on every axis, got " +
                    box_text(value));
      }
    } else if constexpr (std::is_same_v<T, List>) {
      // An empty list is the config's to judge (validate()): "none" for some, an error for others.
      for (const double v : value) {
        if (!in_bounds(p, v)) throw_out_of_bounds(where, join(prefix, p.key), p, v);
      }
    } else if constexpr (std::is_same_v<T, Maybe>) {
      if (value && !in_bounds(p, *value))
        throw_out_of_bounds(where, join(prefix, p.key), p, *value);
    } else if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      if (!p.bounded()) return;
      const double v = static_cast<double>(value);
      if (!in_bounds(p, v)) throw_out_of_bounds(where, join(prefix, p.key), p, v);
    }
  }
};

// Throws naming the field (its dotted path under `where`, and its flag) when a value lies outside
// its declared bounds. Cross-field rules stay in the config's validate().
template <class C>
void check(const C& config, const std::string& where) {
  C copy = config;
  BoundsCheck v;
  v.where = where;
  describe(copy, v);
}

// One row per field of the reference: path, flag, default, unit, bounds, help.
struct Row {
  std::string path, flag, value, unit, bounds, help, eq;
};
struct RowCollector : PathVisitor<RowCollector> {
  std::vector<Row> rows;
  template <class T>
  void field(T& value, const Param& p) {
    Row r;
    r.path = join(prefix, p.key);
    r.flag = p.cli ? p.cli : "";
    r.value = field_text(value, p);
    r.unit = p.unit;
    r.bounds = p.n_names > 0 ? choices_text(p) : p.bounded() ? bounds_text(p) : "";
    r.help = p.help;
    r.eq = p.eq ? p.eq : "";
    rows.push_back(r);
  }
};
template <class C>
std::vector<Row> rows(const C& config) {
  C copy = config;
  RowCollector v;
  describe(copy, v);
  return v.rows;
}
// A markdown table of a config's fields and their defaults (docs/reference.md).
std::string reference_markdown(const std::string& title, const std::string& intro,
                               const std::vector<Row>& rows);

// The configuration as one JSON object (groups nest): the "settings" block of a command's JSON
// output. Numbers as the YAML shows them, enums by name, a box as six numbers or null.
std::string json_string(const std::string& s);  // a JSON string literal
struct JsonWriter {
  std::string out = "{";
  bool first = true;
  void key(const char* k) {
    out += (first ? "" : ", ") + json_string(k) + ": ";
    first = false;
  }
  template <class T>
  void field(T& value, const Param& p) {
    key(p.key);
    if constexpr (std::is_same_v<T, std::string>) {
      out += json_string(value);
    } else if constexpr (std::is_enum_v<T>) {
      out += json_string(field_text(value, p));
    } else if constexpr (std::is_same_v<T, Box>) {
      out += value ? field_text(value, p) : std::string("null");
    } else if constexpr (std::is_same_v<T, List>) {
      out += list_text(value);
    } else if constexpr (std::is_same_v<T, Maybe>) {
      out += value ? format_number(*value) : std::string("null");
    } else {
      out += format_value(value);
    }
  }
  template <class G>
  void group(const char* k, G& g) {
    key(k);
    JsonWriter inner;
    describe(g, inner);
    out += inner.out + "}";
  }
};
template <class C>
std::string to_json(const C& config) {
  C copy = config;
  JsonWriter w;
  describe(copy, w);
  return w.out + "}";
}

}  // namespace sonar3d::params
