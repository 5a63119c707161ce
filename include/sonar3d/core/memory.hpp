#pragma once
// Memory estimates made before allocating (issue 29 item 5). Every command computes, from its
// options and its data (map cells, voxels, samples, rays), the memory its large structures will
// take, and refuses to start when that exceeds a limit: the error names the estimate, its parts
// and the option to change. The CLI's --max-memory sets the limit (README, "Memory").
//
//   MemoryEstimate e;
//   e.add("elevation map", cells * 4.0, "--cell-m");
//   check_memory(e, limit_bytes, "elevation");   // throws Error when e.total() > limit
#include <cstddef>
#include <string>
#include <vector>

namespace sonar3d {

struct MemoryEstimate {
  struct Part {
    std::string what;    // "carving map: 12.5 M leaves of 8³ voxels on 180 m² ..."
    double bytes = 0;    // estimated bytes
    std::string option;  // the option that scales it ("--voxel-size"), "" when none does
  };
  std::vector<Part> parts;
  // What to change to make it fit, beyond the options of the parts (e.g. "or --voxel-size 0.002
  // fits"); appended to the refusal.
  std::string advice;

  MemoryEstimate& add(std::string what, double bytes, std::string option = "");
  MemoryEstimate& operator+=(const MemoryEstimate& other);
  double total() const;
  // "27.4 GB (carving map ...: 27.3 GB; frame summaries: 13 MB)"
  std::string describe() const;
};

// "512 MB", "27.4 GB" (decimal units, as --max-memory).
std::string format_bytes(double bytes);

// A grid's part of an estimate: "<what>: 1.6e+11 cells of 5e-05 m".
std::string grid_part(const std::string& what, double cells, double cell_m);

// Physical memory of the machine in bytes (Linux: MemTotal of /proc/meminfo), 0 when unknown.
std::size_t physical_memory_bytes();

// The default limit: 8 GB, or 75 % of the machine's physical memory when that is less. A fixed
// ceiling keeps a command's acceptance the same on every machine large enough; the fraction
// keeps a smaller machine out of swap and the OOM killer.
double default_memory_limit_bytes();

// Throws Error "<command> needs an estimated <total> (<parts>), more than the memory limit of
// <limit> (--max-memory): change <options of the largest parts>, or raise --max-memory" when the
// estimate exceeds `limit_bytes`. A limit <= 0 disables the check.
void check_memory(const MemoryEstimate& estimate, double limit_bytes, const std::string& command);

}  // namespace sonar3d
