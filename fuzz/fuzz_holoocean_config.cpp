// HoloOcean Config.json (read_holoocean_config, holoocean_sonar_spec in both bin conventions).
#include "fuzz_common.hpp"
#include "sonar3d/io/holoocean.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto p = sonar3d::fuzz::scratch() / "Config.json";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data), size});
  sonar3d::fuzz::run([&] {
    const sonar3d::HoloOceanSonar h = sonar3d::read_holoocean_config(p);
    sonar3d::fuzz::run([&] { sonar3d::holoocean_sonar_spec(h, sonar3d::HoloOceanBins::Sample); });
    sonar3d::fuzz::run([&] { sonar3d::holoocean_sonar_spec(h, sonar3d::HoloOceanBins::Cell); });
  });
  return 0;
}
