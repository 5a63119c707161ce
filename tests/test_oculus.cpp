// Blueprint Oculus ping streams (issue 27): the three real pings in data/oculus, synthetic
// v1/v2 streams written here from the published Oculus.h layout (8/16-bit, with and without
// per-line gains), truncated and corrupt streams.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/oculus.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::poke;
using sonar3d::test::read_all;
using sonar3d::test::temp_dir;
using sonar3d::test::write_all;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;
const fs::path kReal = fs::path(SONAR3D_SOURCE_DIR) / "data/oculus/three_pings_8bit.raw";
constexpr std::size_t kRealPingBytes = 182016;  // 16 + payloadSize of each real ping

// One synthetic SimplePingResult, laid out here from Oculus.h (independently of the reader).
struct SynthPing {
  int version = 2;
  std::uint16_t msg_id = 0x23;
  bool gains = false;
  int sample_bytes = 2;
  int ranges = 5, beams = 4;
  double range_resolution = 0.01;
  double frequency = 2.1e6;
  int mode = 2;
  double start_time = 0;                                         // v2: s; v1: the counter
  std::vector<std::int16_t> bearings{-6000, -1000, 2500, 6400};  // 0.01°, not uniform
  std::vector<std::uint16_t> samples;                            // ranges × beams
  std::vector<float> line_gains;                                 // ranges
  std::size_t pad = 6;  // bytes between the bearing table and the image
};

std::string encode(const SynthPing& s) {
  const bool v2 = s.version == 2;
  const std::size_t head = v2 ? 202 : 122;
  const std::size_t image_offset = head + 2 * s.beams + s.pad;
  const std::size_t line = s.beams * s.sample_bytes + (s.gains ? 4 : 0);
  const std::size_t image_size = line * s.ranges;
  std::string b(image_offset + image_size, '\0');
  poke<std::uint16_t>(b, 0, 0x4f53);
  poke<std::uint16_t>(b, 6, s.msg_id);
  poke<std::uint16_t>(b, 8, static_cast<std::uint16_t>(s.version));
  poke<std::uint32_t>(b, 10, static_cast<std::uint32_t>(b.size() - 16));
  b[16] = static_cast<char>(s.mode);
  b[20] = static_cast<char>(0x01 | 0x08 | (s.sample_bytes == 2 ? 0x02 : 0) | (s.gains ? 0x04 : 0));
  poke<double>(b, 21, s.ranges * s.range_resolution);  // range demand
  poke<double>(b, 29, 40.0);                           // gain %
  const std::size_t base = v2 ? 89 : 53;               // pingId
  poke<std::uint32_t>(b, base, 7);
  poke<double>(b, base + 8, s.frequency);
  if (v2) {
    poke<double>(b, 121, 12.5);  // heading
    poke<double>(b, 145, 1480.0);
    poke<double>(b, 153, s.start_time);
    b[161] = static_cast<char>(s.sample_bytes - 1);
    poke<double>(b, 162, s.range_resolution);
    poke<std::uint16_t>(b, 170, static_cast<std::uint16_t>(s.ranges));
    poke<std::uint16_t>(b, 172, static_cast<std::uint16_t>(s.beams));
    poke<std::uint32_t>(b, 190, static_cast<std::uint32_t>(image_offset));
    poke<std::uint32_t>(b, 194, static_cast<std::uint32_t>(image_size));
    poke<std::uint32_t>(b, 198, static_cast<std::uint32_t>(b.size()));
  } else {
    poke<double>(b, 85, 1480.0);
    poke<std::uint32_t>(b, 93, static_cast<std::uint32_t>(s.start_time));
    b[97] = static_cast<char>(s.sample_bytes - 1);
    poke<double>(b, 98, s.range_resolution);
    poke<std::uint16_t>(b, 106, static_cast<std::uint16_t>(s.ranges));
    poke<std::uint16_t>(b, 108, static_cast<std::uint16_t>(s.beams));
    poke<std::uint32_t>(b, 110, static_cast<std::uint32_t>(image_offset));
    poke<std::uint32_t>(b, 114, static_cast<std::uint32_t>(image_size));
    poke<std::uint32_t>(b, 118, static_cast<std::uint32_t>(b.size()));
  }
  for (int j = 0; j < s.beams; ++j) poke<std::int16_t>(b, head + 2 * j, s.bearings[j]);
  for (int r = 0; r < s.ranges; ++r) {
    std::size_t at = image_offset + r * line;
    if (s.gains) {
      poke<float>(b, at, s.line_gains[r]);
      at += 4;
    }
    for (int j = 0; j < s.beams; ++j) {
      const std::uint16_t v = s.samples[r * s.beams + j];
      if (s.sample_bytes == 2) {
        poke<std::uint16_t>(b, at + 2 * j, v);
      } else {
        b[at + j] = static_cast<char>(v);
      }
    }
  }
  return b;
}

// A ping with distinct samples (range r, beam j, ping k) and gains 1, 2, 4 … per line.
SynthPing make_ping(int version, int bytes, bool gains, int k) {
  SynthPing s;
  s.version = version;
  s.sample_bytes = bytes;
  s.gains = gains;
  s.start_time = version == 2 ? 100.0 + 0.1 * k : 1000000 + 100000000.0 * k;
  for (int r = 0; r < s.ranges; ++r) {
    for (int j = 0; j < s.beams; ++j) {
      s.samples.push_back(
          static_cast<std::uint16_t>(bytes == 2 ? 1000 * r + 10 * j + k + 7 : 40 * r + 9 * j + k));
    }
    s.line_gains.push_back(static_cast<float>(std::pow(2.0, r)));
  }
  return s;
}

OculusImportConfig static_config() {
  OculusImportConfig c;
  c.static_sonar = true;
  return c;
}

}  // namespace

TEST(Oculus, RealPingsImportWithTheirGeometry) {
  const fs::path dir = temp_dir("real");
  const OculusImportResult r = import_oculus(kReal, dir / "ds", static_config());
  EXPECT_EQ(r.pings, 3u);
  EXPECT_EQ(r.frames, 3u);
  EXPECT_EQ(r.version, 1);
  EXPECT_FALSE(r.has_gains);
  EXPECT_EQ(r.dropped_bytes, 0u);
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_NE(r.model.find("M1200d high frequency"), std::string::npos) << r.model;

  const Dataset ds = read_dataset(dir / "ds");
  ASSERT_EQ(ds.size(), 3u);
  EXPECT_EQ(ds.spec.beams(), 256);
  EXPECT_EQ(ds.spec.range_bins, 703);
  EXPECT_EQ(ds.spec.bit_depth, 8);
  EXPECT_NEAR(ds.spec.vertical_aperture_rad, 12 * kDeg, 1e-12);  // M1200d at 2.1 MHz
  // Bearings: the message's table, strictly increasing, ±30° (the M1200d's 60° at 2.1 MHz),
  // spacing 0.22–0.26° (not uniform).
  const auto& b = ds.spec.bearings_rad;
  EXPECT_NEAR(b.front(), -30 * kDeg, 1e-9);
  EXPECT_NEAR(b.back(), 30 * kDeg, 1e-9);
  double min_step = 1, max_step = 0;
  for (std::size_t j = 1; j < b.size(); ++j) {
    ASSERT_GT(b[j], b[j - 1]);
    min_step = std::min(min_step, b[j] - b[j - 1]);
    max_step = std::max(max_step, b[j] - b[j - 1]);
  }
  EXPECT_NEAR(min_step, 0.22 * kDeg, 1e-9);
  EXPECT_NEAR(max_step, 0.26 * kDeg, 1e-9);
  for (double v : b) EXPECT_LE(std::abs(v), 65 * kDeg);
  // Range lines of 2.84 mm from 0 m: 703 of them reach the 2 m range demand to within a line.
  EXPECT_EQ(ds.spec.r_min, 0.0);
  EXPECT_NEAR(ds.spec.r_max, 2.0, 0.003);
  // Frame times from the v1 counter in ns: 62.5 ms apart (16 Hz).
  EXPECT_NEAR(ds.frames[1].timestamp - ds.frames[0].timestamp, 0.0625, 1e-4);
  EXPECT_NEAR(ds.frames[2].timestamp - ds.frames[1].timestamp, 0.0625, 1e-4);
  // Every pixel is the stored byte / 255, range-major from imageOffset 2048.
  const std::string raw = read_all(kReal);
  for (std::size_t k = 0; k < 3; ++k) {
    const SonarImage img = ds.load_frame(k);
    const std::size_t at = k * kRealPingBytes + 2048;
    std::size_t mismatches = 0;
    for (int i = 0; i < 703; ++i) {
      for (int j = 0; j < 256; ++j) {
        const auto v = static_cast<unsigned char>(raw[at + i * 256 + j]);
        if (std::abs(img.at(i, j) - v / 255.0f) > 1e-7f) ++mismatches;
      }
    }
    EXPECT_EQ(mismatches, 0u) << "frame " << k;
  }
}

TEST(Oculus, RealPingsThroughTheCliIntoReconstructAndPreview) {
  const fs::path dir = temp_dir("cli");
  const std::string ds = (dir / "ds").string();
  auto run =
      sonar3d::test::run_cli(dir, "import oculus " + kReal.string() + " -o " + ds + " --static -q");
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.out.find("imported 3 of 3 pings"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("703 lines × 256 beams, 8-bit"), std::string::npos) << run.out;
  // r_min = 0: reconstruct used to crash on the candidate at the sonar's centre.
  run =
      sonar3d::test::run_cli(dir, "reconstruct " + ds + " -o " + (dir / "c.ply").string() + " -q");
  EXPECT_EQ(run.code, 0) << run.out;
  EXPECT_TRUE(fs::exists(dir / "c.ply"));
  run = sonar3d::test::run_cli(dir, "preview " + ds + " -o " + (dir / "p.png").string() + " -q");
  EXPECT_EQ(run.code, 0) << run.out;
  EXPECT_GT(fs::file_size(dir / "p.png"), 1000u);
  // No navigation and no --static: one line saying what to give.
  run = sonar3d::test::run_cli(dir,
                               "import oculus " + kReal.string() + " -o " + (dir / "x").string());
  EXPECT_NE(run.code, 0);
  EXPECT_NE(run.out.find("--static"), std::string::npos) << run.out;
  EXPECT_FALSE(fs::exists(dir / "x"));
}

TEST(Oculus, SyntheticV2SixteenBitWithGains) {
  const fs::path dir = temp_dir("v2gains");
  std::string stream;
  std::vector<SynthPing> pings;
  for (int k = 0; k < 3; ++k) {
    pings.push_back(make_ping(2, 2, true, k));
    stream += encode(pings.back());
  }
  write_all(dir / "s.raw", stream);
  // A TUM navigation file: the vehicle moves 1 m along x per second from t = 99 s.
  {
    std::ofstream nav(dir / "nav.tum");
    nav << "99 0 0 0 0 0 0 1\n101 2 0 0 0 0 0 1\n";
  }
  OculusImportConfig cfg;
  cfg.navigation = dir / "nav.tum";
  const OculusImportResult keep = import_oculus(dir / "s.raw", dir / "keep", cfg);
  EXPECT_EQ(keep.version, 2);
  EXPECT_TRUE(keep.has_gains);
  EXPECT_EQ(keep.frames, 3u);
  EXPECT_DOUBLE_EQ(keep.gain_min, 1.0);
  EXPECT_DOUBLE_EQ(keep.gain_max, 16.0);
  const Dataset a = read_dataset(dir / "keep");
  EXPECT_EQ(a.spec.bit_depth, 16);
  ASSERT_EQ(a.spec.beams(), 4);
  const double want[] = {-60, -10, 25, 64};
  for (int j = 0; j < 4; ++j) EXPECT_NEAR(a.spec.bearings_rad[j], want[j] * kDeg, 1e-12);
  EXPECT_NEAR(a.spec.r_max, 0.05, 1e-12);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.frames[k].timestamp, 100.0 + 0.1 * k, 1e-9);  // pingStartTime, s
    // The pose at t = 100 + 0.1k: x = 1 + 0.1k.
    EXPECT_NEAR(a.T_world_sonar(k).translation().x(), 1.0 + 0.1 * k, 1e-9);
    const SonarImage img = a.load_frame(k);
    for (int r = 0; r < 5; ++r) {
      for (int j = 0; j < 4; ++j) {
        EXPECT_NEAR(img.at(r, j), pings[k].samples[r * 4 + j] / 65535.0, 1e-7);
      }
    }
  }
  // --gains divide: each line over its gain, as float32 TIFF frames.
  cfg.gains = OculusGains::Divide;
  import_oculus(dir / "s.raw", dir / "divide", cfg);
  const Dataset d = read_dataset(dir / "divide");
  EXPECT_EQ(d.frames[0].file.substr(d.frames[0].file.size() - 5), ".tiff");
  const SonarImage img = d.load_frame(2);
  for (int r = 0; r < 5; ++r) {
    for (int j = 0; j < 4; ++j) {
      EXPECT_NEAR(img.at(r, j), pings[2].samples[r * 4 + j] / 65535.0 / std::pow(2.0, r), 1e-7);
    }
  }
}

TEST(Oculus, EightAndSixteenBitWithAndWithoutGainsBothVersions) {
  const fs::path dir = temp_dir("combos");
  for (int version : {1, 2}) {
    for (int bytes : {1, 2}) {
      for (bool gains : {false, true}) {
        const std::string tag = "v" + std::to_string(version) + "_" + std::to_string(8 * bytes) +
                                (gains ? "_gains" : "");
        SCOPED_TRACE(tag);
        std::string stream;
        std::vector<SynthPing> pings;
        for (int k = 0; k < 2; ++k) {
          pings.push_back(make_ping(version, bytes, gains, k));
          stream += encode(pings.back());
        }
        write_all(dir / (tag + ".raw"), stream);
        const OculusImportResult r =
            import_oculus(dir / (tag + ".raw"), dir / tag, static_config());
        EXPECT_EQ(r.frames, 2u);
        EXPECT_EQ(r.version, version);
        EXPECT_EQ(r.has_gains, gains);
        const Dataset ds = read_dataset(dir / tag);
        EXPECT_EQ(ds.spec.bit_depth, 8 * bytes);
        const double full = bytes == 1 ? 255.0 : 65535.0;
        const SonarImage img = ds.load_frame(1);
        for (int i = 0; i < 20; ++i) {
          EXPECT_NEAR(img.data[i], pings[1].samples[i] / full, 1e-7);
        }
        // v1 times: the counter in ns (100 ms apart); v2: seconds.
        EXPECT_NEAR(ds.frames[1].timestamp - ds.frames[0].timestamp, 0.1, 1e-9);
      }
    }
  }
}

TEST(Oculus, MirrorAndApertureTable) {
  const fs::path dir = temp_dir("mirror");
  write_all(dir / "s.raw", encode(make_ping(2, 1, false, 0)));
  OculusImportConfig cfg = static_config();
  cfg.mirror = true;
  cfg.vertical_aperture_deg = 15;
  import_oculus(dir / "s.raw", dir / "m", cfg);
  const Dataset ds = read_dataset(dir / "m");
  const double want[] = {-64, -25, 10, 60};
  for (int j = 0; j < 4; ++j) EXPECT_NEAR(ds.spec.bearings_rad[j], want[j] * kDeg, 1e-12);
  EXPECT_NEAR(ds.spec.vertical_aperture_rad, 15 * kDeg, 1e-12);
  const SynthPing p = make_ping(2, 1, false, 0);
  const SonarImage img = ds.load_frame(0);
  EXPECT_NEAR(img.at(3, 0), p.samples[3 * 4 + 3] / 255.0, 1e-7);  // columns reversed
  EXPECT_NEAR(img.at(3, 3), p.samples[3 * 4 + 0] / 255.0, 1e-7);

  std::string model;
  EXPECT_NEAR(oculus_vertical_aperture(375e3, 1, &model), 20 * kDeg, 1e-12);
  EXPECT_NEAR(oculus_vertical_aperture(750e3, 1, &model), 20 * kDeg, 1e-12);
  EXPECT_NEAR(oculus_vertical_aperture(1.2e6, 1, &model), 20 * kDeg, 1e-12);
  EXPECT_NEAR(oculus_vertical_aperture(1.2e6, 2, &model), 12 * kDeg, 1e-12);
  EXPECT_NE(model.find("M750d"), std::string::npos);
  EXPECT_NEAR(oculus_vertical_aperture(2.0988e6, 2, &model), 12 * kDeg, 1e-12);
  EXPECT_NE(model.find("M1200d"), std::string::npos);
  EXPECT_NEAR(oculus_vertical_aperture(3.0e6, 2, &model), 20 * kDeg, 1e-12);
  EXPECT_NE(model.find("M3000d"), std::string::npos);
  expect_error([] { oculus_vertical_aperture(5.5e6, 2, nullptr); }, "--vertical-aperture-deg");
}

TEST(Oculus, TruncatedStreamKeepsItsWholePings) {
  const fs::path dir = temp_dir("cut");
  const std::string raw = read_all(kReal);
  for (std::size_t cut : {std::size_t{1000}, kRealPingBytes - 10, kRealPingBytes - 16}) {
    SCOPED_TRACE(cut);
    write_all(dir / "cut.raw", raw.substr(0, raw.size() - cut));
    const OculusImportResult r = import_oculus(dir / "cut.raw", dir / "ds", static_config());
    EXPECT_EQ(r.frames, 2u);
    EXPECT_EQ(r.dropped_bytes, kRealPingBytes - cut);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_NE(r.warnings[0].find("dropped its last " + std::to_string(kRealPingBytes - cut) +
                                 " bytes (from offset " + std::to_string(2 * kRealPingBytes)),
              std::string::npos)
        << r.warnings[0];
    EXPECT_EQ(read_dataset(dir / "ds").size(), 2u);
    fs::remove_all(dir / "ds");
  }
  // The CLI says how many bytes were dropped.
  write_all(dir / "cut.raw", raw.substr(0, raw.size() - 1000));
  const auto run = sonar3d::test::run_cli(dir, "import oculus " + (dir / "cut.raw").string() +
                                                   " -o " + (dir / "c").string() + " --static -q");
  EXPECT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.out.find("dropped 181016 bytes of a cut last message"), std::string::npos)
      << run.out;
  // Less than one whole ping: an error, nothing written.
  write_all(dir / "cut.raw", raw.substr(0, 5000));
  expect_error([&] { import_oculus(dir / "cut.raw", dir / "none", static_config()); },
               "no complete SimplePingResult");
  EXPECT_FALSE(fs::exists(dir / "none"));
}

TEST(Oculus, CorruptHeadersNameTheFileAndOffset) {
  const fs::path dir = temp_dir("corrupt");
  const std::string raw = read_all(kReal);
  const std::size_t p1 = kRealPingBytes;  // ping 1
  struct Case {
    const char* name;
    std::function<void(std::string&)> damage;
    std::string needle;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"magic", [&](std::string& b) { poke<std::uint16_t>(b, p1, 0x1234); },
       "(offset 182016): not an Oculus message: oculusId 0x1234"},
      {"payload", [&](std::string& b) { poke<std::uint32_t>(b, p1 + 10, 0xfffffff0u); },
       "(offset 182026): payloadSize 4294967280"},
      {"nan range", [&](std::string& b) { poke<double>(b, p1 + 98, nan); },
       "(offset 182114): rangeResolution nan"},
      {"negative range", [&](std::string& b) { poke<double>(b, p1 + 98, -0.01); },
       "rangeResolution -0.01"},
      {"beams", [&](std::string& b) { poke<std::uint16_t>(b, p1 + 108, 0); },
       "(offset 182124): nBeams 0"},
      {"pixels",
       [&](std::string& b) {
         poke<std::uint16_t>(b, p1 + 106, 65000);
         poke<std::uint16_t>(b, p1 + 108, 16000);
       },
       "(offset 182122): 65000 range lines × 16000 beams exceed 33554432 pixels"},
      {"image size", [&](std::string& b) { poke<std::uint32_t>(b, p1 + 114, 179969); },
       "(offset 182130): imageSize 179969 is not 703 range lines × 256 bytes"},
      {"image offset", [&](std::string& b) { poke<std::uint32_t>(b, p1 + 110, 100); },
       "imageOffset 100 leaves no room for the 256 bearings"},
      {"image past the end", [&](std::string& b) { poke<std::uint32_t>(b, p1 + 110, 3000); },
       "runs past the message"},
      {"bearings", [&](std::string& b) { poke<std::int16_t>(b, p1 + 122 + 2 * 10, 2000); },
       "bearing 11 (-27.18°) does not increase"},
      {"version", [&](std::string& b) { poke<std::uint16_t>(b, p1 + 8, 7); },
       "(offset 182024): SimplePingResult version 7"},
      {"24-bit", [&](std::string& b) { b[p1 + 97] = 2; }, "only 8- and 16-bit pings"},
      {"frequency", [&](std::string& b) { poke<double>(b, p1 + 61, nan); }, "frequency nan"},
      {"geometry", [&](std::string& b) { poke<double>(b, p1 + 98, 0.003); },
       "the geometry changes from ping 0"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::string b = raw;
    c.damage(b);
    write_all(dir / "bad.raw", b);
    expect_error([&] { import_oculus(dir / "bad.raw", dir / "ds", static_config()); },
                 (dir / "bad.raw").string());
    expect_error([&] { import_oculus(dir / "bad.raw", dir / "ds", static_config()); }, c.needle);
    EXPECT_FALSE(fs::exists(dir / "ds"));
  }
  // The CLI: one line, non-zero exit.
  std::string b = raw;
  poke<std::uint16_t>(b, p1, 0x1234);
  write_all(dir / "bad.raw", b);
  const auto run = sonar3d::test::run_cli(dir, "import oculus " + (dir / "bad.raw").string() +
                                                   " -o " + (dir / "c").string() + " --static -q");
  EXPECT_NE(run.code, 0);
  EXPECT_EQ(std::count(run.out.begin(), run.out.end(), '\n'), 1) << run.out;
  EXPECT_NE(run.out.find("offset 182016"), std::string::npos) << run.out;
  // Not an Oculus stream at all, and an empty file.
  write_all(dir / "text.raw", "this is not a sonar stream at all\n");
  expect_error([&] { import_oculus(dir / "text.raw", dir / "ds", static_config()); },
               "(offset 0): not an Oculus message");
  write_all(dir / "empty.raw", "");
  expect_error([&] { import_oculus(dir / "empty.raw", dir / "ds", static_config()); },
               "no complete SimplePingResult");
}

TEST(Oculus, OtherMessagesAreSkippedAndCounted) {
  const fs::path dir = temp_dir("other");
  // A 0x80 log message of 20 payload bytes between two pings.
  std::string other(36, 'x');
  poke<std::uint16_t>(other, 0, 0x4f53);
  poke<std::uint16_t>(other, 6, 0x80);
  poke<std::uint16_t>(other, 8, 0);
  poke<std::uint32_t>(other, 10, 20);
  write_all(dir / "s.raw",
            encode(make_ping(1, 1, false, 0)) + other + encode(make_ping(1, 1, false, 1)));
  const OculusImportResult r = import_oculus(dir / "s.raw", dir / "ds", static_config());
  EXPECT_EQ(r.frames, 2u);
  EXPECT_EQ(r.other_messages, 1u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("skipped 1 messages"), std::string::npos);
}

TEST(Oculus, ConfigurationErrors) {
  const fs::path dir = temp_dir("config");
  OculusImportConfig c;
  expect_error([&] { import_oculus(kReal, dir / "ds", c); }, "--static");
  c.static_sonar = true;
  c.navigation = "nav.tum";
  expect_error([&] { c.validate(); }, "not both");
  c.navigation.clear();
  c.clock = OculusClock::Rate;
  expect_error([&] { c.validate(); }, "--rate");
  c.rate_hz = 10;
  const OculusImportResult r = import_oculus(kReal, dir / "ds", c);
  const Dataset ds = read_dataset(dir / "ds");
  EXPECT_NEAR(ds.frames[2].timestamp, 0.2, 1e-12);  // ping i at i / rate
  EXPECT_EQ(r.frames, 3u);
  expect_error([] { parse_oculus_gains("halve"); }, "keep or divide");
  expect_error([] { parse_oculus_clock("gps"); }, "ping or rate");
}
