// GeoTIFF elevation maps (read_elevation_geotiff, GDAL underneath): sizes, band types, the
// geotransform, no-data, uint16 offset and scale.
#include "fuzz_common.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto p = sonar3d::fuzz::scratch() / "map.tif";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data), size});
  sonar3d::fuzz::run([&] { sonar3d::read_elevation_geotiff(p.string()); });
  return 0;
}
