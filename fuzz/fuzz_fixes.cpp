// Position fixes (read_position_fixes: CSV, or TUM with one σ), the absolute references of
// `sonar3d map --fixes` (issue 26).
#include "fuzz_common.hpp"
#include "sonar3d/io/position_fixes.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  // First byte: bit 0 picks the extension (.csv / .tum), bit 1 gives TUM files a σ (or none).
  const bool tum = data[0] & 1;
  const auto p = sonar3d::fuzz::scratch() / (tum ? "fixes.tum" : "fixes.csv");
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  const double sigma = (data[0] & 2) ? 0.5 : 0.0;
  sonar3d::fuzz::run([&] {
    const auto fixes = sonar3d::read_position_fixes(p.string(), sonar3d::FixFormat::Auto, sigma);
    // What the parser promises: finite values, σ in (0, max], strictly increasing times.
    for (std::size_t k = 0; k < fixes.size(); ++k) {
      const auto& f = fixes[k];
      if (!f.p.allFinite() || !(f.sigma_m > 0 && f.sigma_m <= sonar3d::kMaxFixSigma) ||
          !std::isfinite(f.time) || (k > 0 && !(f.time > fixes[k - 1].time))) {
        std::abort();
      }
    }
  });
  return 0;
}
