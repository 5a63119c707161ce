#include "sonar3d/core/params.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace sonar3d::params {

std::string format_number(double v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  // The shortest of %.{1..17}g that reads back as the same double: a printed configuration runs
  // the same computation.
  char buf[40];
  if (v == std::floor(v) &&
      std::fabs(v) < 1e15) {  // whole numbers as they are typed: 100, not 1e+02
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string bounds_text(const Param& p) {
  const bool has_lo = p.lo > -std::numeric_limits<double>::infinity();
  const bool has_hi = p.hi < std::numeric_limits<double>::infinity();
  if (has_lo && has_hi) {
    return std::string(p.lo_open ? "(" : "[") + format_number(p.lo) + ", " + format_number(p.hi) +
           (p.hi_open ? ")" : "]");
  }
  if (has_lo) return std::string(p.lo_open ? "> " : ">= ") + format_number(p.lo);
  if (has_hi) return std::string(p.hi_open ? "< " : "<= ") + format_number(p.hi);
  return "";
}

std::string bounds_rule(const Param& p) {
  const bool both = p.lo > -std::numeric_limits<double>::infinity() &&
                    p.hi < std::numeric_limits<double>::infinity();
  return (both ? "must lie in " : "must be a finite number ") + bounds_text(p) +
         (*p.unit ? std::string(" ") + p.unit : "");
}

void throw_out_of_bounds(const std::string& where, const std::string& path, const Param& p,
                         double value) {
  std::string what = where.empty() ? path : where + " " + path;
  if (p.cli) what += std::string(" (") + p.cli + ")";
  throw Error(what + " " + bounds_rule(p) + ", got " + format_number(value));
}

std::string choices_text(const Param& p) {
  std::string out;
  for (int k = 0; k < p.n_names; ++k) {
    if (k > 0) out += k + 1 == p.n_names ? " or " : ", ";
    out += p.names[k];
  }
  return out;
}

int choice_index(const Param& p, const std::string& s) {
  for (int k = 0; k < p.n_names; ++k) {
    if (s == p.names[k]) return k;
  }
  return -1;
}

std::string box_text(const Box& b) {
  if (!b) return "none";
  std::string out = "[";
  for (int k = 0; k < 6; ++k) {
    out += (k ? ", " : "") + format_number(k < 3 ? b->min()[k] : b->max()[k - 3]);
  }
  return out + "]";
}

std::string list_text(const List& l) {
  std::string out = "[";
  for (std::size_t k = 0; k < l.size(); ++k) out += (k ? ", " : "") + format_number(l[k]);
  return out + "]";
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

std::string reference_markdown(const std::string& title, const std::string& intro,
                               const std::vector<Row>& rows) {
  std::string out = "## " + title + "\n\n" + intro + "\n\n";
  out += "| key | flag | default | unit | bounds | meaning |\n|---|---|---|---|---|---|\n";
  auto cell = [](std::string s) {
    std::string r;
    for (char c : s) r += c == '|' ? std::string("\\|") : std::string(1, c);
    return r;
  };
  for (const Row& r : rows) {
    std::string help = r.help;
    if (!r.eq.empty()) help += " (" + r.eq + ")";
    out += "| `" + r.path + "` | " + (r.flag.empty() ? "" : "`" + r.flag + "`") + " | " +
           cell(r.value) + " | " + r.unit + " | " + cell(r.bounds) + " | " + cell(help) + " |\n";
  }
  return out;
}

}  // namespace sonar3d::params
