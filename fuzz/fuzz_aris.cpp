// ARIS recordings (import_aris): the first byte picks the options (navigation from the frame
// headers or a fixed sonar, --drop-partial, the sonar clock), the rest is the .aris file.
#include "fuzz_common.hpp"
#include "sonar3d/io/aris.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto dir = sonar3d::fuzz::scratch();
  const auto p = dir / "in.aris";
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  sonar3d::ArisImportConfig c;
  c.nav_source = (data[0] & 1) ? sonar3d::ArisNavSource::Header : sonar3d::ArisNavSource::Static;
  c.drop_partial = (data[0] & 2) != 0;
  c.clock = (data[0] & 4) ? sonar3d::ArisClock::Sonar : sonar3d::ArisClock::Pc;
  sonar3d::fuzz::run([&] { sonar3d::import_aris(p, dir / "out", c); });
  std::error_code ec;
  std::filesystem::remove_all(dir / "out", ec);
  return 0;
}
