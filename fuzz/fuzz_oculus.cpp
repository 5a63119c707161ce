// Oculus ping streams (import_oculus): the first byte picks the options (--gains divide,
// --mirror, --clock rate), the rest is the raw stream of SimplePingResult messages. Every
// decoded ping is also read through OculusReader::read_ping with its samples and gains.
#include "fuzz_common.hpp"
#include "sonar3d/io/oculus.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto dir = sonar3d::fuzz::scratch();
  const auto p = dir / "in.raw";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  sonar3d::OculusImportConfig c;
  c.static_sonar = true;
  c.gains = (data[0] & 1) ? sonar3d::OculusGains::Divide : sonar3d::OculusGains::Keep;
  c.mirror = (data[0] & 2) != 0;
  if (data[0] & 4) {
    c.clock = sonar3d::OculusClock::Rate;
    c.rate_hz = 10;
  }
  sonar3d::fuzz::run([&] {
    const sonar3d::OculusReader reader(p);
    std::vector<std::uint16_t> samples;
    std::vector<float> gains;
    for (std::size_t i = 0; i < reader.info().pings.size() && i < 4; ++i) {
      reader.read_ping(i, &samples, &gains);
    }
  });
  sonar3d::fuzz::run([&] { sonar3d::import_oculus(p, dir / "out", c); });
  std::error_code ec;
  std::filesystem::remove_all(dir / "out", ec);
  return 0;
}
