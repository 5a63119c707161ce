#include "sonar3d/io/aris.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "binary.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

// Byte offsets of the FileHeader and FrameHeader fields we use, from Sound Metrics' published
// type definitions (ARIS file SDK, type-definitions/C, packed structs of 1024 bytes).
namespace file_off {
constexpr int kVersion = 0, kFrameCount = 4, kNumRawBeams = 16, kSamplesPerChannel = 24;
}  // namespace file_off
namespace frame_off {
constexpr int kFrameIndex = 0, kFrameTime = 4, kVersion = 12, kSonarTimeStamp = 20;
constexpr int kWindowStart = 52, kWindowLength = 56, kDepth = 128, kPitch = 136, kRoll = 144,
              kHeading = 152, kCompassHeading = 160, kCompassPitch = 164, kCompassRoll = 168,
              kLatitude = 172, kLongitude = 180, kPingMode = 436, kSamplePeriod = 452,
              kSoundSpeed = 464, kSamplesPerBeam = 468, kSampleStartDelay = 476, kLargeLens = 480,
              kSystemType = 484, kReorderedSamples = 516;
}  // namespace frame_off

// Beam centres in degrees, beam 0 first: the centre column of Sound Metrics' current published
// beam-width tables, github.com/SoundMetrics/aris-file-sdk, beam-width-metrics/BeamWidths_*.h
// (composite lenses), as SoundMetrics.Aris.BeamWidths (file-utility-code) loads them and its
// approval files (SoundMetrics.Aris.BeamWidths.Tests/approval-files) list them. The telephoto
// 48-beam and ARIS 3000 64- and 128-beam tables are the "Updated Beam Angles" revision
// (DEFINE_BEAMWIDTH3, (c) 2010-2018) that replaced the 2015 "Approximate Beam Widths" tables
// (telephoto 48 beams then ended at +-6.742 deg, now +-7.339 deg; ARIS 3000 64 at +-14.703, now
// +-14.8872; 128 at +-14.705, now -15.0068/+15.0156, no longer symmetric). The other three tables
// are unchanged between the revisions.
const double kAris1800_1200_48[48] = {
    -13.5735, -13.1419, -12.7003, -12.2442, -11.7721, -11.2881, -10.7921, -10.2824,
    -9.7597,  -9.2206,  -8.6630,  -8.0899,  -7.5026,  -6.9019,  -6.2897,  -5.6661,
    -5.0291,  -4.3823,  -3.7264,  -3.0632,  -2.3931,  -1.7170,  -1.0343,  -0.3461,
    0.3461,   1.0343,   1.7170,   2.3931,   3.0632,   3.7264,   4.3823,   5.0291,
    5.6661,   6.2897,   6.9019,   7.5026,   8.0899,   8.6630,   9.2206,   9.7597,
    10.2824,  10.7921,  11.2881,  11.7721,  12.2442,  12.7003,  13.1419,  13.5735};
const double kAris1800_96[96] = {
    -13.749,  -13.5347, -13.3174, -13.0975, -12.8758, -12.6498, -12.4197, -12.1855, -11.9476,
    -11.7069, -11.4636, -11.2173, -10.9676, -10.7144, -10.4579, -10.1985, -9.9352,  -9.668,
    -9.3961,  -9.1195,  -8.8385,  -8.5535,  -8.2654,  -7.9738,  -7.6781,  -7.3793,  -7.0774,
    -6.7727,  -6.4652,  -6.1549,  -5.8416,  -5.5246,  -5.2046,  -4.8824,  -4.5578,  -4.231,
    -3.9019,  -3.5711,  -3.2387,  -2.9044,  -2.5686,  -2.2314,  -1.8925,  -1.5519,  -1.2098,
    -0.8664,  -0.5216,  -0.1757,  0.1706,   0.5169,   0.8628,   1.2076,   1.551,    1.8931,
    2.2337,   2.5726,   2.9098,   3.2456,   3.5799,   3.9123,   4.2431,   4.5722,   4.899,
    5.2236,   5.5458,   5.8658,   6.1828,   6.4961,   6.8064,   7.1139,   7.4186,   7.7205,
    8.0193,   8.315,    8.6066,   8.8947,   9.1797,   9.4607,   9.7373,   10.0092,  10.2764,
    10.5397,  10.7991,  11.0556,  11.3088,  11.5585,  11.8048,  12.0481,  12.2888,  12.5267,
    12.7609,  12.991,   13.217,   13.4387,  13.6586,  13.8759};
const double kAris3000_64[64] = {
    -14.8872, -14.4266, -13.9637, -13.499, -13.0332, -12.5665, -12.0986, -11.6295,
    -11.1593, -10.6883, -10.2165, -9.7439, -9.2706,  -8.7969,  -8.3228,  -7.8486,
    -7.3742,  -6.8997,  -6.425,   -5.9502, -5.4753,  -5.0003,  -4.5251,  -4.0499,
    -3.5745,  -3.0991,  -2.6234,  -2.1473, -1.6708,  -1.1939,  -0.7166,  -0.2389,
    0.2389,   0.7166,   1.1939,   1.6708,  2.1473,   2.6234,   3.0991,   3.5745,
    4.0499,   4.5251,   5.0003,   5.4753,  5.9502,   6.425,    6.8997,   7.3742,
    7.8486,   8.3228,   8.7969,   9.2706,  9.7439,   10.2165,  10.6883,  11.1593,
    11.6295,  12.0986,  12.5665,  13.0332, 13.499,   13.9637,  14.4266,  14.8872};
const double kAris3000_128[128] = {
    -15.0068, -14.7768, -14.5462, -14.315,  -14.0833, -13.8511, -13.6186, -13.3858, -13.1528,
    -12.9196, -12.6861, -12.4523, -12.2182, -11.9838, -11.7491, -11.5141, -11.2789, -11.0435,
    -10.8079, -10.5721, -10.3361, -10.0999, -9.8635,  -9.6269,  -9.3902,  -9.1534,  -8.9165,
    -8.6795,  -8.4424,  -8.2053,  -7.9682,  -7.731,   -7.4938,  -7.2566,  -7.0193,  -6.782,
    -6.5446,  -6.3072,  -6.0698,  -5.8324,  -5.5949,  -5.3574,  -5.1199,  -4.8823,  -4.6447,
    -4.4071,  -4.1695,  -3.9318,  -3.6941,  -3.4564,  -3.2187,  -2.9809,  -2.743,   -2.505,
    -2.2669,  -2.0287,  -1.7904,  -1.552,   -1.3135,  -1.0749,  -0.8362,  -0.5974,  -0.3585,
    -0.1196,  0.1194,   0.3584,   0.5973,   0.8362,   1.075,    1.3137,   1.5523,   1.7908,
    2.0292,   2.2675,   2.5057,   2.7438,   2.9818,   3.2197,   3.4575,   3.6952,   3.9329,
    4.1706,   4.4083,   4.6459,   4.8835,   5.1211,   5.3587,   5.5962,   5.8337,   6.0712,
    6.3086,   6.546,    6.7834,   7.0208,   7.2581,   7.4954,   7.7326,   7.9698,   8.207,
    8.4441,   8.6812,   8.9183,   9.1553,   9.3922,   9.629,    9.8657,   10.1023,  10.3387,
    10.5749,  10.8109,  11.0467,  11.2823,  11.5177,  11.7529,  11.9879,  12.2226,  12.457,
    12.6911,  12.9249,  13.1584,  13.3916,  13.6246,  13.8574,  14.0899,  14.3221,  14.5538,
    14.785,   15.0156};
const double kArisTele_48[48] = {
    -7.339, -7.043, -6.744, -6.443, -6.14,  -5.835, -5.529, -5.222, -4.913, -4.602, -4.29, -3.975,
    -3.659, -3.342, -3.025, -2.708, -2.391, -2.074, -1.756, -1.438, -1.119, -0.8,   -0.48, -0.16,
    0.16,   0.48,   0.8,    1.119,  1.438,  1.756,  2.074,  2.391,  2.708,  3.025,  3.342, 3.659,
    3.975,  4.29,   4.602,  4.913,  5.222,  5.529,  5.835,  6.14,   6.443,  6.744,  7.043, 7.339};
const double kArisTele_96[96] = {
    -7.419, -7.271, -7.123, -6.974, -6.824, -6.674, -6.523, -6.372, -6.220, -6.068, -5.915, -5.763,
    -5.609, -5.456, -5.302, -5.148, -4.993, -4.838, -4.682, -4.526, -4.370, -4.213, -4.055, -3.897,
    -3.739, -3.581, -3.422, -3.264, -3.105, -2.947, -2.788, -2.630, -2.471, -2.313, -2.154, -1.995,
    -1.836, -1.677, -1.518, -1.359, -1.199, -1.039, -0.880, -0.720, -0.560, -0.400, -0.240, -0.080,
    0.080,  0.240,  0.400,  0.560,  0.720,  0.880,  1.039,  1.199,  1.359,  1.518,  1.677,  1.836,
    1.995,  2.154,  2.313,  2.471,  2.630,  2.788,  2.947,  3.105,  3.264,  3.422,  3.581,  3.739,
    3.897,  4.055,  4.213,  4.370,  4.526,  4.682,  4.838,  4.993,  5.148,  5.302,  5.456,  5.609,
    5.763,  5.915,  6.068,  6.220,  6.372,  6.523,  6.674,  6.824,  6.974,  7.123,  7.271,  7.419};

std::string at_offset(const fs::path& file, std::uint64_t offset) {
  return file.string() + " (offset " + std::to_string(offset) + ")";
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

ArisFrameHeader decode_frame_header(const unsigned char* p) {
  using bin::load;
  namespace o = frame_off;
  ArisFrameHeader h;
  h.frame_index = load<std::uint32_t>(p + o::kFrameIndex);
  h.frame_time_us = load<std::uint64_t>(p + o::kFrameTime);
  h.sonar_time_us = load<std::uint64_t>(p + o::kSonarTimeStamp);
  h.window_start = load<float>(p + o::kWindowStart);
  h.window_length = load<float>(p + o::kWindowLength);
  h.depth = load<float>(p + o::kDepth);
  h.pitch = load<float>(p + o::kPitch);
  h.roll = load<float>(p + o::kRoll);
  h.heading = load<float>(p + o::kHeading);
  h.compass_heading = load<float>(p + o::kCompassHeading);
  h.compass_pitch = load<float>(p + o::kCompassPitch);
  h.compass_roll = load<float>(p + o::kCompassRoll);
  h.latitude = load<double>(p + o::kLatitude);
  h.longitude = load<double>(p + o::kLongitude);
  h.ping_mode = load<std::uint32_t>(p + o::kPingMode);
  h.sample_period_us = load<std::uint32_t>(p + o::kSamplePeriod);
  h.sound_speed = load<float>(p + o::kSoundSpeed);
  h.samples_per_beam = load<std::uint32_t>(p + o::kSamplesPerBeam);
  h.sample_start_delay_us = load<std::uint32_t>(p + o::kSampleStartDelay);
  h.large_lens = load<std::uint32_t>(p + o::kLargeLens);
  h.system_type = load<std::uint32_t>(p + o::kSystemType);
  h.reordered_samples = load<std::uint32_t>(p + o::kReorderedSamples);
  return h;
}

void encode_frame_header(const ArisFrameHeader& h, unsigned char* p) {
  using bin::store;
  namespace o = frame_off;
  std::fill(p, p + kArisHeaderBytes, 0);
  store(p + o::kFrameIndex, h.frame_index);
  store(p + o::kFrameTime, h.frame_time_us);
  store(p + o::kVersion, kArisSignature);
  store(p + o::kSonarTimeStamp, h.sonar_time_us);
  store(p + o::kWindowStart, h.window_start);
  store(p + o::kWindowLength, h.window_length);
  store(p + o::kDepth, h.depth);
  store(p + o::kPitch, h.pitch);
  store(p + o::kRoll, h.roll);
  store(p + o::kHeading, h.heading);
  store(p + o::kCompassHeading, h.compass_heading);
  store(p + o::kCompassPitch, h.compass_pitch);
  store(p + o::kCompassRoll, h.compass_roll);
  store(p + o::kLatitude, h.latitude);
  store(p + o::kLongitude, h.longitude);
  store(p + o::kPingMode, h.ping_mode);
  store(p + o::kSamplePeriod, h.sample_period_us);
  store(p + o::kSoundSpeed, h.sound_speed);
  store(p + o::kSamplesPerBeam, h.samples_per_beam);
  store(p + o::kSampleStartDelay, h.sample_start_delay_us);
  store(p + o::kLargeLens, h.large_lens);
  store(p + o::kSystemType, h.system_type);
  store(p + o::kReorderedSamples, h.reordered_samples);
}

void read_exact(std::ifstream& f, const fs::path& path, std::uint64_t offset, void* dst,
                std::size_t n, const char* what) {
  f.clear();
  f.seekg(static_cast<std::streamoff>(offset));
  f.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
  if (static_cast<std::size_t>(f.gcount()) != n) {
    throw Error(at_offset(path, offset) + ": cannot read the " + what + " (" + std::to_string(n) +
                " bytes): the file is truncated or unreadable");
  }
}

// Position of a frame header's geodetic fix, or false when it holds none.
bool has_fix(const ArisFrameHeader& h) {
  return std::isfinite(h.latitude) && std::isfinite(h.longitude) && std::abs(h.latitude) <= 90 &&
         std::abs(h.longitude) <= 180 && !(h.latitude == 0 && h.longitude == 0);
}

// WGS84
constexpr double kA = 6378137.0;
constexpr double kF = 1.0 / 298.257223563;
constexpr double kE2 = kF * (2 - kF);

Eigen::Vector3d ecef(double lat, double lon) {
  const double s = std::sin(lat), c = std::cos(lat);
  const double n = kA / std::sqrt(1 - kE2 * s * s);
  return {n * c * std::cos(lon), n * c * std::sin(lon), n * (1 - kE2) * s};
}

}  // namespace

const char* aris_system_name(ArisSystem s) {
  switch (s) {
    case ArisSystem::Aris1800:
      return "ARIS 1800";
    case ArisSystem::Aris3000:
      return "ARIS 3000";
    case ArisSystem::Aris1200:
      return "ARIS 1200";
  }
  return "ARIS";
}

int aris_beams_of_ping_mode(std::uint32_t m) {
  if (m == 1 || m == 2) return 48;
  if (m >= 3 && m <= 5) return 96;
  if (m >= 6 && m <= 8) return 64;
  if (m >= 9 && m <= 12) return 128;
  return 0;
}

std::vector<double> aris_beam_bearings(ArisSystem system, bool telephoto, int beams) {
  const double* table = nullptr;
  if (telephoto) {
    if (beams == 48 && system != ArisSystem::Aris3000) table = kArisTele_48;
    if (beams == 96 && system == ArisSystem::Aris1800) table = kArisTele_96;
  } else if (system == ArisSystem::Aris3000) {
    if (beams == 64) table = kAris3000_64;
    if (beams == 128) table = kAris3000_128;
  } else {
    if (beams == 48) table = kAris1800_1200_48;
    if (beams == 96 && system == ArisSystem::Aris1800) table = kAris1800_96;
  }
  if (!table) {
    throw Error(std::string("Sound Metrics publishes no beam table for an ") +
                aris_system_name(system) + (telephoto ? " with a telephoto lens" : "") + " with " +
                std::to_string(beams) + " beams");
  }
  std::vector<double> out(beams);
  for (int j = 0; j < beams; ++j) out[j] = table[j] * kDeg;
  return out;
}

double aris_vertical_aperture(ArisSystem, bool telephoto) {
  return (telephoto ? 3.0 : 14.0) * kDeg;
}

ArisClock parse_aris_clock(const std::string& s) {
  return parse_enum<ArisClock>(kArisClockNames, s, "ARIS clock");
}

ArisNavSource parse_aris_nav_source(const std::string& s) {
  return parse_enum<ArisNavSource>(kArisNavSourceNames, s, "ARIS navigation source");
}

ArisReader::ArisReader(const fs::path& path) : path_(path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error("cannot read ARIS file '" + path.string() + "': not a regular file");
  }
  info_.file_size = fs::file_size(path, ec);
  if (ec) throw Error("cannot read ARIS file '" + path.string() + "': " + ec.message());
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open ARIS file '" + path.string() + "'");
  if (info_.file_size < kArisHeaderBytes) {
    throw Error(path.string() + ": " + std::to_string(info_.file_size) +
                " bytes, too short for the 1024-byte ARIS file header");
  }
  unsigned char fh[kArisHeaderBytes];
  read_exact(f, path, 0, fh, sizeof fh, "file header");
  const auto version = bin::load<std::uint32_t>(fh + file_off::kVersion);
  if (version != kArisSignature) {
    if ((version & 0x00ffffffu) == 0x464444u) {
      throw Error(at_offset(path, 0) + ": a DIDSON file (DDF_0" + std::to_string(version >> 24) +
                  "); only ARIS files (DDF_05) are read: convert it with ARISFish");
    }
    throw Error(at_offset(path, 0) + ": not an ARIS file: signature " + bin::hex32(version) +
                ", expected " + bin::hex32(kArisSignature) + " (DDF_05)");
  }
  info_.header_frame_count = bin::load<std::uint32_t>(fh + file_off::kFrameCount);
  if (info_.file_size < 2 * kArisHeaderBytes) {
    throw Error(path.string() + ": holds no frame (" + std::to_string(info_.file_size) +
                " bytes; a frame header alone is 1024 bytes after the file header)");
  }
  unsigned char h0[kArisHeaderBytes];
  read_exact(f, path, kArisHeaderBytes, h0, sizeof h0, "header of frame 0");
  const ArisFrameHeader h = decode_frame_header(h0);
  const std::uint64_t at = kArisHeaderBytes;
  if (bin::load<std::uint32_t>(h0 + frame_off::kVersion) != kArisSignature) {
    throw Error(at_offset(path, at + frame_off::kVersion) +
                ": frame 0 has no ARIS frame signature (" +
                bin::hex32(bin::load<std::uint32_t>(h0 + frame_off::kVersion)) + ")");
  }
  info_.beams = aris_beams_of_ping_mode(h.ping_mode);
  if (info_.beams == 0) {
    throw Error(at_offset(path, at + frame_off::kPingMode) + ": frame 0 has PingMode " +
                std::to_string(h.ping_mode) + ", not one of ARIS's 1–12");
  }
  if (h.samples_per_beam < 1 || h.samples_per_beam > static_cast<unsigned>(limits::kMaxRangeBins)) {
    throw Error(at_offset(path, at + frame_off::kSamplesPerBeam) + ": frame 0 has SamplesPerBeam " +
                std::to_string(h.samples_per_beam) + ", outside [1, " +
                std::to_string(limits::kMaxRangeBins) + "]");
  }
  info_.samples = static_cast<int>(h.samples_per_beam);
  if (h.system_type > 2) {
    throw Error(at_offset(path, at + frame_off::kSystemType) + ": frame 0 has TheSystemType " +
                std::to_string(h.system_type) + " (0 = ARIS 1800, 1 = ARIS 3000, 2 = ARIS 1200)");
  }
  info_.system = static_cast<ArisSystem>(h.system_type);
  info_.telephoto = h.large_lens != 0;
  // The SDK's rule: frames = (file size − file header) / (frame header + samples).
  const std::uint64_t body = info_.file_size - kArisHeaderBytes;
  info_.frames = static_cast<std::size_t>(body / info_.frame_bytes());
  info_.trailing_bytes = body % info_.frame_bytes();
  if (info_.frames == 0) {
    throw Error(at_offset(path, at) + ": frame 0 needs " + std::to_string(info_.frame_bytes()) +
                " bytes (" + std::to_string(info_.samples) + " samples × " +
                std::to_string(info_.beams) + " beams + header) but the file holds " +
                std::to_string(body) + ": the file is truncated");
  }
}

ArisFrameHeader ArisReader::read_frame(std::size_t i, std::vector<std::uint8_t>& samples) const {
  if (i >= info_.frames) {
    throw Error(path_.string() + ": frame " + std::to_string(i) + " does not exist (" +
                std::to_string(info_.frames) + " frames)");
  }
  std::ifstream f(path_, std::ios::binary);
  if (!f) throw Error("cannot open ARIS file '" + path_.string() + "'");
  const std::uint64_t at = frame_offset(i);
  unsigned char raw[kArisHeaderBytes];
  const std::string frame = "frame " + std::to_string(i);
  read_exact(f, path_, at, raw, sizeof raw, ("header of " + frame).c_str());
  const auto sig = bin::load<std::uint32_t>(raw + frame_off::kVersion);
  if (sig != kArisSignature) {
    throw Error(at_offset(path_, at + frame_off::kVersion) + ": " + frame +
                " has no ARIS frame signature (" + bin::hex32(sig) +
                "): the file is corrupt or its frames change size");
  }
  const ArisFrameHeader h = decode_frame_header(raw);
  if (aris_beams_of_ping_mode(h.ping_mode) != info_.beams ||
      h.samples_per_beam != static_cast<unsigned>(info_.samples)) {
    throw Error(at_offset(path_, at + frame_off::kPingMode) + ": " + frame + " has PingMode " +
                std::to_string(h.ping_mode) + " and SamplesPerBeam " +
                std::to_string(h.samples_per_beam) + " but frame 0 has " +
                std::to_string(info_.samples) + " samples × " + std::to_string(info_.beams) +
                " beams; a dataset holds one image size (split the recording in ARISFish)");
  }
  if (h.reordered_samples == 0) {
    throw Error(at_offset(path_, at + frame_off::kReorderedSamples) + ": " + frame +
                " holds samples in the sonar's transmission order (ReorderedSamples = 0), whose "
                "permutation the ARIS file SDK does not publish; re-save the file with ARISFish");
  }
  samples.resize(static_cast<std::size_t>(info_.beams) * info_.samples);
  read_exact(f, path_, at + kArisHeaderBytes, samples.data(), samples.size(),
             ("samples of " + frame).c_str());
  return h;
}

SonarSpec aris_sonar_spec(const ArisFrameHeader& h, int beams, const std::string& where) {
  if (!(h.sound_speed >= 1000.0f && h.sound_speed <= 2000.0f)) {
    throw Error(where + ": SoundSpeed " + fmt(h.sound_speed) + " m/s is outside [1000, 2000] m/s");
  }
  if (h.sample_period_us < 1 || h.sample_period_us > 1000) {
    throw Error(where + ": SamplePeriod " + std::to_string(h.sample_period_us) +
                " µs is outside [1, 1000] µs");
  }
  const double c = h.sound_speed;
  const double dl = h.sample_period_us * 1e-6 * c / 2;
  const double start = h.sample_start_delay_us * 1e-6 * c / 2;
  SonarSpec s;
  const auto system = static_cast<ArisSystem>(h.system_type);
  const bool tele = h.large_lens != 0;
  s.name = std::string(aris_system_name(system)) + (tele ? " telephoto" : "");
  for (char& ch : s.name) ch = ch == ' ' ? '-' : static_cast<char>(std::tolower(ch));
  s.bearings_rad = aris_beam_bearings(system, tele, beams);
  s.range_bins = static_cast<int>(h.samples_per_beam);
  // Row i is sample i at WindowStart + i·ΔL: the row centres are the sample ranges.
  s.r_min = start - dl / 2;
  s.r_max = s.r_min + s.range_bins * dl;
  if (s.r_min < 0) {
    throw Error(where + ": SampleStartDelay " + std::to_string(h.sample_start_delay_us) +
                " µs puts the first sample closer than half a sample to the sonar");
  }
  if (s.r_max > limits::kMaxRange) {
    throw Error(where + ": the window ends at " + fmt(s.r_max) + " m, beyond " +
                fmt(limits::kMaxRange) + " m");
  }
  s.vertical_aperture_rad = aris_vertical_aperture(system, tele);
  s.beam_pattern.kind = BeamPattern::Kind::Sinc;
  s.bit_depth = 8;
  s.intensity_scale = 1.0 / 255.0;
  return s;
}

void ArisImportConfig::validate() const {
  params::check(*this, "ARIS import:");
  if (!std::isfinite(time_offset)) throw Error("ARIS import: 'time_offset' must be finite");
  check_navigation_format(navigation_format, "ARIS import: navigation_format");
  if (nav_source == ArisNavSource::File && navigation.empty()) {
    throw Error("ARIS import: nav_source 'file' needs a navigation file");
  }
  if (!navigation.empty() && nav_source != ArisNavSource::File &&
      nav_source != ArisNavSource::Auto) {
    throw Error("ARIS import: a navigation file is given but nav_source is '" +
                std::string(kArisNavSourceNames[static_cast<int>(nav_source)]) +
                "' (use auto or file)");
  }
  mounting_from_list(mount, "ARIS import: mount");
}

ArisImportResult import_aris(const fs::path& file, const fs::path& out,
                             const ArisImportConfig& config, bool progress) {
  config.validate();
  ArisReader reader(file);
  ArisImportResult res;
  res.info = reader.info();
  const ArisFileInfo& info = res.info;
  if (info.trailing_bytes != 0) {
    const std::uint64_t at = reader.frame_offset(info.frames);
    if (!config.drop_partial) {
      throw Error(at_offset(file, at) + ": the last " + std::to_string(info.trailing_bytes) +
                  " bytes are a partial frame (a frame is " + std::to_string(info.frame_bytes()) +
                  " bytes): the recording was cut; import the " + std::to_string(info.frames) +
                  " complete frames with --drop-partial");
    }
    res.warnings.push_back("ignored a partial frame of " + std::to_string(info.trailing_bytes) +
                           " bytes at offset " + std::to_string(at));
  }
  if (info.header_frame_count != info.frames &&
      !(info.trailing_bytes && info.header_frame_count == info.frames + 1)) {
    res.warnings.push_back("the file header says " + std::to_string(info.header_frame_count) +
                           " frames, the file size holds " + std::to_string(info.frames) +
                           " (the size is what counts)");
  }

  // Pass 1: headers only — geometry, times and navigation fields of every frame.
  std::vector<ArisFrameHeader> headers;
  headers.reserve(info.frames);  // bounded: each frame is >= 1024 bytes of the file
  {
    std::ifstream f(file, std::ios::binary);
    unsigned char raw[kArisHeaderBytes];
    for (std::size_t i = 0; i < info.frames; ++i) {
      const std::uint64_t at = reader.frame_offset(i);
      read_exact(f, file, at, raw, sizeof raw, ("header of frame " + std::to_string(i)).c_str());
      headers.push_back(decode_frame_header(raw));
    }
  }
  const std::string where0 = at_offset(file, reader.frame_offset(0)) + ": frame 0";
  res.spec = aris_sonar_spec(headers[0], info.beams, where0);
  if (config.vertical_aperture_deg)
    res.spec.vertical_aperture_rad = *config.vertical_aperture_deg * kDeg;
  res.spec.T_vehicle_sonar = mounting_from_list(config.mount, "ARIS import: mount");
  res.spec.validate();

  std::vector<double> times(info.frames);
  for (std::size_t i = 0; i < info.frames; ++i) {
    const ArisFrameHeader& h = headers[i];
    const std::string where =
        at_offset(file, reader.frame_offset(i)) + ": frame " + std::to_string(i);
    const std::uint64_t us = config.clock == ArisClock::Pc ? h.frame_time_us : h.sonar_time_us;
    times[i] = static_cast<double>(us) * 1e-6 + config.time_offset;
    if (i > 0 && times[i] < times[i - 1]) {
      throw Error(where + ": its time " + fmt(times[i]) + " s goes backwards (frame " +
                  std::to_string(i - 1) + " at " + fmt(times[i - 1]) + " s)");
    }
    if (i > 0) {
      // The window may only stay where it is: one dataset, one range binning.
      const SonarSpec si = aris_sonar_spec(h, info.beams, where);
      const double tol = 1e-6 * res.spec.r_max;
      if (std::abs(si.r_min - res.spec.r_min) > tol || std::abs(si.r_max - res.spec.r_max) > tol ||
          si.bearings_rad != res.spec.bearings_rad) {
        throw Error(where + ": the window moves from " + fmt(res.spec.r_min) + "–" +
                    fmt(res.spec.r_max) + " m (frame 0) to " + fmt(si.r_min) + "–" + fmt(si.r_max) +
                    " m, or the lens changes; a dataset holds one sensor "
                    "geometry (split the recording in ARISFish)");
      }
    }
  }

  // Navigation.
  ArisNavSource src = config.nav_source;
  if (src == ArisNavSource::Auto) {
    if (!config.navigation.empty()) {
      src = ArisNavSource::File;
    } else {
      const bool all = std::all_of(headers.begin(), headers.end(), has_fix);
      if (!all) {
        throw Error(file.string() +
                    ": no navigation: the frame headers hold no position "
                    "(Latitude/Longitude are 0); give a navigation file (--nav), or "
                    "--nav-source static for a fixed sonar");
      }
      src = ArisNavSource::Header;
    }
  }
  res.nav_source = src;
  Trajectory nav;
  if (src == ArisNavSource::File) {
    nav = read_navigation(config.navigation, config.navigation_csv, config.navigation_format);
  } else if (src == ArisNavSource::Header) {
    const double lat0 = headers[0].latitude, lon0 = headers[0].longitude;
    for (std::size_t i = 0; i < info.frames; ++i) {
      const ArisFrameHeader& h = headers[i];
      const std::string where =
          at_offset(file, reader.frame_offset(i)) + ": frame " + std::to_string(i);
      if (!has_fix(h)) {
        throw Error(where + ": no position in the frame header (Latitude " + fmt(h.latitude) +
                    ", Longitude " + fmt(h.longitude) + ")");
      }
      for (float v : {h.depth, h.heading, h.pitch, h.roll}) {
        if (!std::isfinite(v) || std::abs(v) > 1e5f) {
          throw Error(where + ": Depth/Heading/Pitch/Roll are not finite or absurd");
        }
      }
      if (i > 0 && !(times[i] > times[i - 1])) {
        throw Error(where + ": two frames at the same time " + fmt(times[i]) +
                    " s cannot each carry a navigation sample");
      }
      const Eigen::Vector2d en = enu_from_geodetic(h.latitude, h.longitude, lat0, lon0);
      if (en.cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
        throw Error(where + ": its fix is " + fmt(en.norm()) + " m from frame 0's, beyond " +
                    fmt(limits::kMaxCoordinate) + " m");
      }
      // NED position (north, east, depth) and attitude, as vehicle_pose_from_nav takes them.
      nav.push_back(times[i],
                    vehicle_pose_from_nav(Eigen::Vector3d(en.y(), en.x(), h.depth), h.roll * kDeg,
                                          h.pitch * kDeg, h.heading * kDeg, NavConvention::Ned));
    }
    nav.validate(file.string() + " (frame headers)");
    const auto zero_attitude = [](const ArisFrameHeader& h) {
      return h.heading == 0 && h.pitch == 0 && h.roll == 0;
    };
    const auto compass = [](const ArisFrameHeader& h) {
      return h.compass_heading != 0 || h.compass_pitch != 0 || h.compass_roll != 0;
    };
    if (std::all_of(headers.begin(), headers.end(), zero_attitude) &&
        std::any_of(headers.begin(), headers.end(), compass)) {
      res.warnings.push_back(
          "the platform Heading/Pitch/Roll of every frame header are 0 while the sonar's compass "
          "reports an attitude: the poses use the platform fields (level, heading north); give a "
          "navigation file (--nav) if the vehicle turned");
    }
  } else {
    nav.push_back(times.front(), Eigen::Isometry3d::Identity());
    if (times.back() > times.front()) nav.push_back(times.back(), Eigen::Isometry3d::Identity());
  }

  DatasetWriter writer(out, res.spec, DatasetWriter::ImageFormat::Png);
  Progress bar("import", info.frames, progress);
  std::vector<std::uint8_t> samples;
  SonarImage img(res.spec.range_bins, res.spec.beams());
  for (std::size_t i = 0; i < info.frames; ++i) {
    if (!frame_inside_navigation(
            nav, times[i], config.drop_outside,
            at_offset(file, reader.frame_offset(i)) + ": frame " + std::to_string(i))) {
      ++res.dropped;
      bar.add();
      continue;
    }
    reader.read_frame(i, samples);
    for (std::size_t k = 0; k < samples.size(); ++k) img.data[k] = samples[k] / 255.0f;
    img.timestamp = times[i];
    writer.add_frame(img);
    if (res.frames == 0) res.first_time = times[i];
    res.last_time = times[i];
    ++res.frames;
    bar.add();
  }
  bar.finish();
  if (res.frames == 0) throw no_frame_inside_navigation(nav, file.string());
  writer.set_navigation(nav);
  writer.commit();
  return res;
}

void write_aris(const fs::path& path, const std::vector<ArisWriteFrame>& frames) {
  if (frames.empty()) throw Error("write_aris: no frame to write to '" + path.string() + "'");
  const ArisFrameHeader& h0 = frames.front().header;
  std::vector<unsigned char> fh(kArisHeaderBytes, 0);
  bin::store(fh.data() + file_off::kVersion, kArisSignature);
  bin::store(fh.data() + file_off::kFrameCount, static_cast<std::uint32_t>(frames.size()));
  bin::store(fh.data() + file_off::kNumRawBeams,
             static_cast<std::uint32_t>(aris_beams_of_ping_mode(h0.ping_mode)));
  bin::store(fh.data() + file_off::kSamplesPerChannel, h0.samples_per_beam);
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary | std::ios::trunc);
    if (!f) throw Error("cannot write ARIS file '" + path.string() + "'");
    f.write(reinterpret_cast<const char*>(fh.data()), kArisHeaderBytes);
    unsigned char raw[kArisHeaderBytes];
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const ArisFrameHeader& h = frames[i].header;
      const int beams = aris_beams_of_ping_mode(h.ping_mode);
      if (beams == 0 || frames[i].samples.size() != std::size_t(beams) * h.samples_per_beam) {
        throw Error("write_aris: frame " + std::to_string(i) + " holds " +
                    std::to_string(frames[i].samples.size()) + " samples, not SamplesPerBeam × " +
                    "the beams of PingMode " + std::to_string(h.ping_mode));
      }
      encode_frame_header(h, raw);
      f.write(reinterpret_cast<const char*>(raw), kArisHeaderBytes);
      f.write(reinterpret_cast<const char*>(frames[i].samples.data()),
              static_cast<std::streamsize>(frames[i].samples.size()));
    }
    f.flush();
    if (!f) throw Error("cannot write ARIS file '" + path.string() + "': write failed");
  }
  out.commit();
}

Eigen::Vector2d enu_from_geodetic(double lat_deg, double lon_deg, double lat0_deg,
                                  double lon0_deg) {
  const double lat0 = lat0_deg * kDeg, lon0 = lon0_deg * kDeg;
  const Eigen::Vector3d d = ecef(lat_deg * kDeg, lon_deg * kDeg) - ecef(lat0, lon0);
  const double sl = std::sin(lat0), cl = std::cos(lat0), so = std::sin(lon0), co = std::cos(lon0);
  const double e = -so * d.x() + co * d.y();
  const double n = -sl * co * d.x() - sl * so * d.y() + cl * d.z();
  return {e, n};
}

Eigen::Vector2d geodetic_from_enu(const Eigen::Vector2d& en, double lat0_deg, double lon0_deg) {
  // Newton-like refinement of the local scale's first guess; converges to < 1e-9 m in a few steps
  // within tens of kilometres.
  const double lat0 = lat0_deg * kDeg;
  const double s = std::sin(lat0);
  const double rn = kA / std::sqrt(1 - kE2 * s * s);
  const double rm = rn * (1 - kE2) / (1 - kE2 * s * s);
  double lat = lat0_deg + en.y() / rm / kDeg;
  double lon = lon0_deg + en.x() / (rn * std::cos(lat0)) / kDeg;
  for (int it = 0; it < 8; ++it) {
    const Eigen::Vector2d got = enu_from_geodetic(lat, lon, lat0_deg, lon0_deg);
    const Eigen::Vector2d r = en - got;
    lat += r.y() / rm / kDeg;
    lon += r.x() / (rn * std::cos(lat * kDeg)) / kDeg;
    if (r.norm() < 1e-10) break;
  }
  return {lat, lon};
}

Eigen::Isometry3d parse_mounting(const std::string& text) {
  return mounting_from_list(parse_mounting_list(text), "mounting '" + printable(text) + "'");
}

}  // namespace sonar3d
