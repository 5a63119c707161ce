#pragma once
// The one enum <-> string convention (issue 24, item 3; docs/design.md, "Choices and enums").
// An enum with names has one table, its names indexed by the enum's value, declared once beside
// the enum:
//
//   enum class NavConvention { Enu, Ned };
//   inline constexpr const char* kNavConventionNames[] = {"enu", "ned"};  // by NavConvention
//
// and everything else reads that table: a config field declares `.choices(kNavConventionNames)`
// (core/params.hpp: YAML, flags, Python and the reference), and code converts with
//
//   enum_name(kNavConventionNames, NavConvention::Ned)           -> "ned"
//   parse_enum<NavConvention>(kNavConventionNames, text, what)   -> the value, or an Error
//       "<what> must be one of enu or ned, got 'x'" (`what` names the user's flag, key or file)
//
// An enum may also name its table once for the templates below, by a function found by
// argument-dependent lookup (for an enum nested in a struct, a `friend` of that struct):
//
//   constexpr const auto& enum_names(NavConvention) { return kNavConventionNames; }
//
// so that `to_string(NavConvention::Ned)` and `parse_enum<NavConvention>(text, what)` need no
// table. The names are those written to files (JSON, YAML): renaming one changes the files.
#include <cstddef>
#include <iterator>
#include <string>
#include <type_traits>
#include <utility>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

// "a", "a or b", "a, b or c": the names as error messages and the reference list them (as
// params::choices_text).
template <std::size_t N>
std::string enum_choices_text(const char* const (&names)[N]) {
  std::string out;
  for (std::size_t k = 0; k < N; ++k) {
    if (k > 0) out += k + 1 == N ? " or " : ", ";
    out += names[k];
  }
  return out;
}

// The name of `value`; "?" for a value outside the table.
template <class E, std::size_t N>
const char* enum_name(const char* const (&names)[N], E value) {
  static_assert(std::is_enum_v<E>);
  const auto k = static_cast<std::size_t>(value);
  return k < N ? names[k] : "?";
}

// `text` as an error message quotes it: control and non-ASCII bytes as '?', at most 64 bytes.
inline std::string enum_quoted(const std::string& text) {
  std::string out = text.substr(0, 64);
  for (char& c : out) {
    if (c < 0x20 || c > 0x7e) c = '?';
  }
  return "'" + out + (text.size() > 64 ? "...'" : "'");
}

// The value named `text` (exact, case-sensitive); throws Error
// "<what> must be one of a, b or c, got '<text>'".
template <class E, std::size_t N>
E parse_enum(const char* const (&names)[N], const std::string& text, const std::string& what) {
  static_assert(std::is_enum_v<E>);
  for (std::size_t k = 0; k < N; ++k) {
    if (text == names[k]) return static_cast<E>(k);
  }
  throw Error(what + " must be one of " + enum_choices_text(names) + ", got " + enum_quoted(text));
}

// The same through the enum's `enum_names` (above).
template <class E, class = std::enable_if_t<std::is_enum_v<E>>,
          class = decltype(enum_names(std::declval<E>()))>
const char* to_string(E value) {
  return enum_name(enum_names(value), value);
}
template <class E>
E parse_enum(const std::string& text, const std::string& what) {
  return parse_enum<E>(enum_names(E{}), text, what);
}

}  // namespace sonar3d
