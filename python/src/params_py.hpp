#pragma once
// Python classes derived from a configuration's one declaration (core/params.hpp): one property
// per field (its docstring the help, unit and bounds; setting a value outside the bounds raises
// sonar3d.Error naming the attribute), nested groups as attributes holding their own class,
// keyword construction (`RecognitionConfig(map_cell_m=0.03)`), `to_dict()`, `__repr__`.
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <cstddef>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>

#include "common.hpp"
#include "sonar3d/core/params.hpp"

namespace sonar3d::python {

// The object a class's fields live in: the config itself, or for a Nested<C> view the C it refers
// to (a part of a larger config).
template <class C>
auto& fields_of(C& c) {
  if constexpr (params::is_nested<C>::value) {
    return c.c;
  } else {
    return c;
  }
}

// A Python value for a field: enums by name, boxes as ((min xyz), (max xyz)) or None.
template <class T>
py::object to_py(const T& value, const params::Param& p) {
  if constexpr (std::is_enum_v<T>) {
    return py::str(params::field_text(value, p));
  } else if constexpr (std::is_same_v<T, params::Box>) {
    if (!value) return py::none();
    return py::make_tuple(Eigen::Vector3d(value->min()), Eigen::Vector3d(value->max()));
  } else if constexpr (std::is_same_v<T, params::Maybe>) {
    return value ? py::object(py::float_(*value)) : py::object(py::none());
  } else if constexpr (std::is_same_v<T, params::List>) {
    py::list l;
    for (const double v : value) l.append(v);
    return l;
  } else {
    return py::cast(value);
  }
}

// A field's value from Python, checked against its declaration (raises sonar3d.Error naming it).
template <class T>
T from_py(const py::object& o, const params::Param& p) {
  const std::string name = p.key;
  if constexpr (std::is_enum_v<T>) {
    return params::parse_choice<T>(p, o.cast<std::string>(), name);
  } else if constexpr (std::is_same_v<T, params::Box>) {
    if (o.is_none()) return std::nullopt;
    const auto t = o.cast<py::sequence>();
    if (t.size() != 2) throw Error(name + " must be (min xyz, max xyz) or None");
    const Eigen::AlignedBox3d b(t[0].cast<Eigen::Vector3d>(), t[1].cast<Eigen::Vector3d>());
    if (!(b.min().allFinite() && b.max().allFinite() && (b.max().array() > b.min().array()).all()))
      throw Error(name + " must have finite corners and max > min on every axis");
    return b;
  } else if constexpr (std::is_same_v<T, params::Maybe>) {
    if (o.is_none()) return std::nullopt;
    const double v = o.cast<double>();
    if (!params::in_bounds(p, v)) {
      throw Error(name + " " + params::bounds_rule(p) + " or None, got " +
                  params::format_number(v));
    }
    return v;
  } else if constexpr (std::is_same_v<T, params::List>) {
    params::List l;
    for (const auto& item : o.cast<py::sequence>()) l.push_back(item.cast<double>());
    if (l.empty()) throw Error(name + " must hold at least one value");
    for (const double v : l) {
      if (!params::in_bounds(p, v)) {
        throw Error(name + " " + params::bounds_rule(p) + ", got " + params::format_number(v));
      }
    }
    return l;
  } else {
    const T v = o.cast<T>();
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      if (p.bounded() && !params::in_bounds(p, static_cast<double>(v))) {
        throw Error(name + " " + params::bounds_rule(p) + ", got " +
                    params::format_number(static_cast<double>(v)));
      }
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (p.n_names > 0 && params::choice_index(p, v) < 0) {
        throw Error(name + " must be one of " + params::choices_text(p) + ", got '" + v + "'");
      }
    }
    return v;
  }
}

// Binds the fields of C (or, for a Nested<C>, those its description lists) as properties of the
// Python class `cls`. Offsets are taken within fields_of(C).
template <class C>
class ConfigBinder {
 public:
  ConfigBinder(py::class_<C>& cls, const char* base) : cls_(cls), base_(base) {}

  template <class T>
  void field(T& value, const params::Param& p) {
    const std::ptrdiff_t offset = reinterpret_cast<const char*>(&value) - base_;
    std::string doc = p.help;
    if (*p.unit) doc += ", " + std::string(p.unit);
    if (p.n_names > 0) doc += "; one of " + params::choices_text(p);
    if (p.bounded()) doc += "; " + params::bounds_text(p);
    if (p.eq) doc += " (" + std::string(p.eq) + ")";
    if (p.cli) doc += "; the command line's " + std::string(p.cli);
    const params::Param spec = p;
    cls_.def_property(
        p.key,
        [offset, spec](C& c) {
          const char* base = reinterpret_cast<const char*>(&fields_of(c));
          return to_py(*reinterpret_cast<const T*>(base + offset), spec);
        },
        [offset, spec](C& c, const py::object& v) {
          char* base = reinterpret_cast<char*>(&fields_of(c));
          *reinterpret_cast<T*>(base + offset) = from_py<T>(v, spec);
        },
        doc.c_str());
  }
  template <class G>
  void group(const char* key, G& g) {
    if constexpr (params::is_nested<G>::value) {
      // A view of part of a config: returned by value, referring into (and keeping alive) the
      // object it belongs to.
      const std::ptrdiff_t offset = reinterpret_cast<const char*>(&g.c) - base_;
      using Inner = std::remove_reference_t<decltype(g.c)>;
      cls_.def_property_readonly(
          key,
          [offset](C& c) {
            char* base = reinterpret_cast<char*>(&fields_of(c));
            return G{*reinterpret_cast<Inner*>(base + offset)};
          },
          py::keep_alive<0, 1>());
    } else {
      const std::ptrdiff_t offset = reinterpret_cast<const char*>(&g) - base_;
      cls_.def_property(
          key,
          [offset](C& c) -> G& {
            return *reinterpret_cast<G*>(reinterpret_cast<char*>(&fields_of(c)) + offset);
          },
          [offset](C& c, const G& v) {
            *reinterpret_cast<G*>(reinterpret_cast<char*>(&fields_of(c)) + offset) = v;
          },
          py::return_value_policy::reference_internal);
    }
  }

 private:
  py::class_<C>& cls_;
  const char* base_;
};

// The fields as a dict (groups as nested dicts), for JSON-like use.
struct DictWriter {
  py::dict out;
  template <class T>
  void field(T& value, const params::Param& p) {
    out[p.key] = to_py(value, p);
  }
  template <class G>
  void group(const char* key, G& g) {
    DictWriter inner;
    describe(g, inner);
    out[key] = inner.out;
  }
};

// The top-level keys of C (fields and groups), for messages.
struct TopKeys {
  std::string out;
  template <class T>
  void field(T&, const params::Param& p) {
    out += (out.empty() ? "" : ", ") + std::string(p.key);
  }
  template <class G>
  void group(const char* key, G&) {
    out += (out.empty() ? "" : ", ") + std::string(key);
  }
};

// A function's configuration: `config` (a C, or None for the defaults) with each keyword of
// `settings` set as its attribute (checked by the bound setters). An unknown keyword is an Error
// naming `what` and the fields C has.
template <class C>
C config_with_settings(const py::object& config, const py::kwargs& settings, const char* what) {
  C c = config.is_none() ? C() : config.cast<C>();
  py::object view = py::cast(&c, py::return_value_policy::reference);
  for (auto item : settings) {
    if (!py::hasattr(view, item.first)) {
      TopKeys keys;
      describe(c, keys);
      throw Error(std::string(what) + ": unknown setting '" +
                  py::str(item.first).cast<std::string>() + "' (a " +
                  py::type::of(view).attr("__name__").cast<std::string>() + " field: " + keys.out +
                  ")");
    }
    py::setattr(view, item.first, item.second);
  }
  return c;
}

// Binds C as a Python class `name`; its groups' classes must be bound first. A Nested<X> class is
// a view (no constructor): the part of a larger config its description lists.
template <class C>
py::class_<C> bind_config(py::module_& m, const char* name, const char* doc) {
  py::class_<C> cls(m, name, doc);
  auto to_dict = [](C& c) {
    DictWriter w;
    describe(c, w);
    return w.out;
  };
  if constexpr (params::is_nested<C>::value) {
    using Inner = std::remove_reference_t<decltype(std::declval<C&>().c)>;
    static Inner defaults;
    C view{defaults};
    ConfigBinder<C> b(cls, reinterpret_cast<const char*>(&defaults));
    describe(view, b);
    cls.def("to_dict", to_dict);
  } else {
    cls.def(py::init(&from_kwargs<C>));
    C defaults;
    ConfigBinder<C> b(cls, reinterpret_cast<const char*>(&defaults));
    describe(defaults, b);
    cls.def("to_dict", [to_dict](const C& c) {
      C copy = c;
      return to_dict(copy);
    });
  }
  cls.def("__repr__", &fields_repr);
  return cls;
}

}  // namespace sonar3d::python
