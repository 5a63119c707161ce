#include "sonar3d/core/error.hpp"

#include <cmath>
#include <sstream>

namespace sonar3d {

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
