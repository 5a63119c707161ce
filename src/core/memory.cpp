#include "sonar3d/core/memory.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

MemoryEstimate& MemoryEstimate::add(std::string what, double bytes, std::string option) {
  parts.push_back({std::move(what), bytes, std::move(option)});
  return *this;
}

MemoryEstimate& MemoryEstimate::operator+=(const MemoryEstimate& other) {
  parts.insert(parts.end(), other.parts.begin(), other.parts.end());
  if (!other.advice.empty()) advice += (advice.empty() ? "" : "; ") + other.advice;
  return *this;
}

double MemoryEstimate::total() const {
  double t = 0;
  for (const auto& p : parts) t += p.bytes;
  return t;
}

std::string grid_part(const std::string& what, double cells, double cell_m) {
  char s[64];
  std::snprintf(s, sizeof s, ": %.3g cells of %.3g m", cells, cell_m);
  return what + s;
}

std::string format_bytes(double bytes) {
  char buf[64];
  if (!std::isfinite(bytes)) return "an unbounded amount";
  if (bytes >= 1e12) {
    std::snprintf(buf, sizeof buf, "%.1f TB", bytes / 1e12);
  } else if (bytes >= 1e9) {
    std::snprintf(buf, sizeof buf, "%.1f GB", bytes / 1e9);
  } else if (bytes >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.0f MB", bytes / 1e6);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f kB", bytes / 1e3);
  }
  return buf;
}

std::string MemoryEstimate::describe() const {
  std::vector<const Part*> sorted;
  for (const auto& p : parts) sorted.push_back(&p);
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const Part* a, const Part* b) { return a->bytes > b->bytes; });
  std::string s = format_bytes(total());
  if (sorted.empty()) return s;
  s += " (";
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    s += (i ? "; " : "") + sorted[i]->what + ": " + format_bytes(sorted[i]->bytes);
  }
  return s + ")";
}

std::size_t physical_memory_bytes() {
  std::ifstream f("/proc/meminfo");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("MemTotal:", 0) == 0) {
      std::istringstream is(line.substr(9));
      std::size_t kb = 0;
      is >> kb;
      return kb * 1024;
    }
  }
  return 0;
}

double default_memory_limit_bytes() {
  const double ceiling = 8e9;
  const double ram = static_cast<double>(physical_memory_bytes());
  return ram > 0 ? std::min(ceiling, 0.75 * ram) : ceiling;
}

void check_memory(const MemoryEstimate& estimate, double limit_bytes, const std::string& command) {
  const double total = estimate.total();
  if (limit_bytes <= 0 || total <= limit_bytes) return;
  // The options of the parts, largest part first, each once.
  std::vector<const MemoryEstimate::Part*> sorted;
  for (const auto& p : estimate.parts) sorted.push_back(&p);
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const auto* a, const auto* b) { return a->bytes > b->bytes; });
  std::vector<std::string> options;
  for (const auto* p : sorted) {
    if (!p->option.empty() &&
        std::find(options.begin(), options.end(), p->option) == options.end()) {
      options.push_back(p->option);
    }
  }
  std::string change;
  for (std::size_t i = 0; i < options.size(); ++i) {
    change += (i == 0 ? "" : i + 1 == options.size() ? " or " : ", ") + options[i];
  }
  char limit[64];
  std::snprintf(limit, sizeof limit, "%.3g", limit_bytes / 1e9);
  throw Error(command + " needs an estimated " + estimate.describe() +
              ", more than the memory limit of " + limit +
              " GB (--max-memory): " + (change.empty() ? std::string() : "change " + change) +
              (estimate.advice.empty()
                   ? std::string()
                   : (change.empty() ? "" : " (") + estimate.advice + (change.empty() ? "" : ")")) +
              (change.empty() && estimate.advice.empty() ? "" : ", ") +
              "or raise --max-memory if the machine has the memory");
}

}  // namespace sonar3d
