#pragma once
// Fields of the text tables sonar3d reads (navigation CSV/TUM, position fixes): one place for
// trimming, splitting and the number parser, so that every table names a bad cell the same way.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"

namespace sonar3d::text {

inline std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

inline std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Comma-separated cells, each trimmed; a trailing comma gives a last empty cell.
inline std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream is(line);
  while (std::getline(is, cell, ',')) out.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

// Blank lines and # comments.
inline bool skip_line(const std::string& line) {
  const std::string t = trim(line);
  return t.empty() || t[0] == '#';
}

// One cell as a finite number, else "<where>: <what> '<cell>' is not a number" / "is not finite".
inline double parse_number(const std::string& cell, const std::string& where,
                           const std::string& what) {
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(cell, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (cell.empty() || used != cell.size()) {
    throw Error(where + ": " + what + " '" + printable(cell) + "' is not a number");
  }
  if (!std::isfinite(v)) throw Error(where + ": " + what + " is not finite");
  return v;
}

}  // namespace sonar3d::text
