#pragma once
// Python classes derived from a configuration's one declaration (core/params.hpp): one property
// per field (its docstring the help, unit and bounds; setting a value outside the bounds raises
// sonar3d.Error naming the attribute), nested groups as attributes holding their own class,
// keyword construction (`RecognitionConfig(map_cell_m=0.03)`), `to_dict()`, `__repr__`.
#include <pybind11/pybind11.h>

#include <cstddef>
#include <string>
#include <type_traits>

#include "common.hpp"
#include "sonar3d/core/params.hpp"

namespace sonar3d::python {

template <class C>
class ConfigBinder {
 public:
  ConfigBinder(py::class_<C>& cls, const char* base) : cls_(cls), base_(base) {}

  template <class T>
  void field(T& value, const params::Param& p) {
    const std::ptrdiff_t offset = reinterpret_cast<const char*>(&value) - base_;
    std::string doc = p.help;
    if (*p.unit) doc += ", " + std::string(p.unit);
    if (p.bounded()) doc += "; " + params::bounds_text(p);
    if (p.eq) doc += " (" + std::string(p.eq) + ")";
    if (p.cli) doc += "; the command line's " + std::string(p.cli);
    const params::Param spec = p;
    cls_.def_property(
        p.key,
        [offset](const C& c) {
          return *reinterpret_cast<const T*>(reinterpret_cast<const char*>(&c) + offset);
        },
        [offset, spec](C& c, T v) {
          if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
            if (spec.bounded() && !params::in_bounds(spec, static_cast<double>(v))) {
              throw Error(std::string(spec.key) + " " + params::bounds_rule(spec) + ", got " +
                          params::format_number(static_cast<double>(v)));
            }
          }
          *reinterpret_cast<T*>(reinterpret_cast<char*>(&c) + offset) = v;
        },
        doc.c_str());
  }
  template <class G>
  void group(const char* key, G& g) {
    const std::ptrdiff_t offset = reinterpret_cast<const char*>(&g) - base_;
    cls_.def_property(
        key,
        [offset](C& c) -> G& {
          return *reinterpret_cast<G*>(reinterpret_cast<char*>(&c) + offset);
        },
        [offset](C& c, const G& v) {
          *reinterpret_cast<G*>(reinterpret_cast<char*>(&c) + offset) = v;
        },
        py::return_value_policy::reference_internal);
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
    out[p.key] = value;
  }
  template <class G>
  void group(const char* key, G& g) {
    DictWriter inner;
    describe(g, inner);
    out[key] = inner.out;
  }
};

// Binds C as a Python class `name`; its groups' classes must be bound first.
template <class C>
py::class_<C> bind_config(py::module_& m, const char* name, const char* doc) {
  py::class_<C> cls(m, name, doc);
  cls.def(py::init(&from_kwargs<C>));
  C defaults;
  ConfigBinder<C> b(cls, reinterpret_cast<const char*>(&defaults));
  describe(defaults, b);
  cls.def("to_dict", [](const C& c) {
    C copy = c;
    DictWriter w;
    describe(copy, w);
    return w.out;
  });
  cls.def("__repr__", &fields_repr);
  return cls;
}

}  // namespace sonar3d::python
