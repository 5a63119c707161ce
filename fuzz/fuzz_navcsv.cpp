// Navigation logs (read_navigation with format "csv" in ENU and NED, and "tum").
#include "fuzz_common.hpp"
#include "sonar3d/io/navigation.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto p = sonar3d::fuzz::scratch() / "nav.csv";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  sonar3d::NavCsvConfig c;
  c.convention = (data[0] & 1) ? sonar3d::NavConvention::Ned : sonar3d::NavConvention::Enu;
  c.angles = (data[0] & 2) == 0 ? sonar3d::AngleUnit::Deg : sonar3d::AngleUnit::Rad;
  const char* format = (data[0] & 4) ? "tum" : "csv";
  sonar3d::fuzz::run([&] { sonar3d::read_navigation(p.string(), c, format).validate(p.string()); });
  return 0;
}
