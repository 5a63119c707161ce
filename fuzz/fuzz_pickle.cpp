// HoloOcean pickles (import_holoocean): the input is Data/0.pkl of a recording with a fixed
// 8 × 6 Config.json; the pickle is decoded by the Python child under its memory budget and every
// message it sends back is checked. Slow (one interpreter per input): a few executions a second.
#include "fuzz_common.hpp"
#include "sonar3d/io/holoocean.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = sonar3d::fuzz::scratch() / "holo";
  static const bool init = [&] {
    sonar3d::fuzz::write_file(
        dir / "Config.json",
        R"({"agents": [{"agent_name": "auv0", "sensors": [{"sensor_type": "PoseSensor"},
        {"sensor_type": "ImagingSonar", "Hz": 10, "configuration": {"RangeBins": 8,
        "AzimuthBins": 6, "RangeMin": 0.5, "RangeMax": 4.5, "Azimuth": 60, "Elevation": 12}}]}]})");
    return true;
  }();
  (void)init;
  sonar3d::fuzz::write_file(dir / "Data/0.pkl", {reinterpret_cast<const char*>(data), size});
  const auto out = sonar3d::fuzz::scratch() / "holo_out";
  sonar3d::fuzz::run([&] { sonar3d::import_holoocean(dir, out, {}, false); });
  std::filesystem::remove_all(out);
  return 0;
}
