// PLY point clouds (read_ply): ascii and binary_little_endian headers, counts, properties, data.
#include "fuzz_common.hpp"
#include "sonar3d/core/point_cloud.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto p = sonar3d::fuzz::scratch() / "cloud.ply";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data), size});
  sonar3d::fuzz::run([&] { sonar3d::read_ply(p.string()); });
  return 0;
}
