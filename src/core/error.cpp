#include "sonar3d/core/error.hpp"

#include <cmath>
#include <sstream>

namespace sonar3d {

std::string printable(const std::string& text, std::size_t max) {
  std::string out;
  for (char c : text) {
    if (out.size() >= max) {
      out += "...";
      break;
    }
    const auto u = static_cast<unsigned char>(c);
    out.push_back(u >= 0x20 && u < 0x7F ? c : '?');
  }
  return out;
}

void require_positive(double value, const char* name, const char* unit) {
  if (!std::isfinite(value) || value <= 0.0) {
    std::ostringstream os;
    os << "parameter '" << name << "' must be a finite number > 0" << (*unit ? " " : "") << unit
       << ", got " << value;
    throw Error(os.str());
  }
}

void require_non_negative(double value, const char* name, const char* unit) {
  if (!std::isfinite(value) || value < 0.0) {
    std::ostringstream os;
    os << "parameter '" << name << "' must be a finite number >= 0" << (*unit ? " " : "") << unit
       << ", got " << value;
    throw Error(os.str());
  }
}

}  // namespace sonar3d
