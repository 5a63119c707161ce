#include "sonar3d/io/oculus.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "binary.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

// Byte offsets from the start of a message, from Blueprint's published Oculus.h (packed).
namespace hdr {
constexpr int kOculusId = 0, kMsgId = 6, kMsgVersion = 8, kPayloadSize = 10;
}  // namespace hdr
// OculusSimpleFireMessage and OculusSimpleFireMessage2 share their first fields.
namespace fire {
constexpr int kMasterMode = 16, kFlags = 20, kRange = 21, kGainPercent = 29;
}  // namespace fire
// The ping fields after the fire message, for each version.
struct PingOffsets {
  int ping_id, frequency, sound_speed, ping_start_time, data_size, range_resolution, n_ranges,
      n_beams, image_offset, image_size, message_size, heading, pitch, roll;
  std::size_t size;  // of the structure: the bearing table follows it
};
constexpr PingOffsets kV1{
    53, 61, 85, 93, 97, 98, 106, 108, 110, 114, 118, -1, -1, -1, kOculusPingV1Bytes};
constexpr PingOffsets kV2{
    89, 97, 145, 153, 161, 162, 170, 172, 190, 194, 198, 121, 129, 137, kOculusPingV2Bytes};

std::string at_offset(const std::string& file, std::uint64_t offset) {
  return file + " (offset " + std::to_string(offset) + ")";
}

std::string num(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

void read_exact(std::ifstream& f, const std::string& path, std::uint64_t offset, void* dst,
                std::size_t n, const std::string& what) {
  f.clear();
  f.seekg(static_cast<std::streamoff>(offset));
  f.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
  if (static_cast<std::size_t>(f.gcount()) != n) {
    throw Error(at_offset(path, offset) + ": cannot read the " + what + " (" + std::to_string(n) +
                " bytes): the file changed or is unreadable");
  }
}

// The published (nominal) operating frequencies and the full vertical apertures Blueprint
// Subsea's datasheets give for them (docs/import.md §8 cites them).
struct ApertureRow {
  double hz;
  int mode;  // master mode that tells the row apart at a shared frequency, 0 = any
  double aperture_deg;
  const char* model;
};
constexpr ApertureRow kApertures[] = {
    {375e3, 0, 20.0, "M370s (375 kHz)"},
    {750e3, 0, 20.0, "M750d low frequency (750 kHz)"},
    {1.2e6, 1, 20.0, "M1200d/M3000d low frequency (1.2 MHz)"},
    {1.2e6, 2, 12.0, "M750d high frequency (1.2 MHz)"},
    {2.1e6, 0, 12.0, "M1200d high frequency (2.1 MHz)"},
    {3.0e6, 0, 20.0, "M3000d high frequency (3.0 MHz)"},
};

}  // namespace

OculusPing decode_oculus_ping(const unsigned char* p, std::size_t n, std::uint64_t offset,
                              const std::string& file, std::vector<std::uint16_t>* samples,
                              std::vector<float>* gains) {
  using bin::load;
  const auto where = [&](std::size_t field) { return at_offset(file, offset + field); };
  if (n < kOculusHeaderBytes) {
    throw Error(where(0) + ": a message of " + std::to_string(n) + " bytes has no header");
  }
  OculusPing g;
  g.offset = offset;
  // The three real pings carry msgVersion 0 with the v1 layout (docs/import.md §8): 0 and 1 are
  // OculusSimplePingResult, 2 is OculusSimplePingResult2 (as liboculus dispatches them).
  const std::uint16_t msg_version = load<std::uint16_t>(p + hdr::kMsgVersion);
  g.version = msg_version == 2 ? 2 : 1;
  if (load<std::uint16_t>(p + hdr::kMsgId) != kOculusSimplePingResult) {
    throw Error(where(hdr::kMsgId) + ": message id " +
                std::to_string(load<std::uint16_t>(p + hdr::kMsgId)) +
                " is not a SimplePingResult (0x23)");
  }
  if (msg_version > 2) {
    throw Error(where(hdr::kMsgVersion) + ": SimplePingResult version " +
                std::to_string(msg_version) + " is not one Blueprint publishes (0/1 or 2)");
  }
  const PingOffsets& o = g.version == 1 ? kV1 : kV2;
  if (n < o.size) {
    throw Error(where(0) + ": a SimplePingResult v" + std::to_string(g.version) + " needs " +
                std::to_string(o.size) + " bytes, the message holds " + std::to_string(n));
  }
  g.master_mode = p[fire::kMasterMode];
  g.flags = p[fire::kFlags];
  g.range_demand = load<double>(p + fire::kRange);
  g.gain_percent = load<double>(p + fire::kGainPercent);
  g.ping_id = load<std::uint32_t>(p + o.ping_id);
  g.frequency = load<double>(p + o.frequency);
  g.speed_of_sound = load<double>(p + o.sound_speed);
  g.ping_start_time = g.version == 1 ? double(load<std::uint32_t>(p + o.ping_start_time))
                                     : load<double>(p + o.ping_start_time);
  if (g.version == 2) {
    g.heading = load<double>(p + o.heading);
    g.pitch = load<double>(p + o.pitch);
    g.roll = load<double>(p + o.roll);
  }
  const std::uint8_t data_size = p[o.data_size];
  g.range_resolution = load<double>(p + o.range_resolution);
  g.n_ranges = load<std::uint16_t>(p + o.n_ranges);
  g.n_beams = load<std::uint16_t>(p + o.n_beams);
  g.image_offset = load<std::uint32_t>(p + o.image_offset);
  g.image_size = load<std::uint32_t>(p + o.image_size);
  g.message_size = load<std::uint32_t>(p + o.message_size);

  if (data_size > 1) {
    throw Error(where(o.data_size) + ": dataSize " + std::to_string(data_size) + " (" +
                std::to_string(8 * (data_size + 1)) +
                "-bit samples): only 8- and 16-bit pings are read");
  }
  g.sample_bytes = data_size + 1;
  if (g.n_beams < 1 || g.n_beams > limits::kMaxBeams) {
    throw Error(where(o.n_beams) + ": nBeams " + std::to_string(g.n_beams) + " is outside [1, " +
                std::to_string(limits::kMaxBeams) + "]");
  }
  if (g.n_ranges < 1 || g.n_ranges > limits::kMaxRangeBins) {
    throw Error(where(o.n_ranges) + ": nRanges " + std::to_string(g.n_ranges) + " is outside [1, " +
                std::to_string(limits::kMaxRangeBins) + "]");
  }
  if (double(g.n_ranges) * g.n_beams > limits::kMaxPixels) {
    throw Error(where(o.n_ranges) + ": " + std::to_string(g.n_ranges) + " range lines × " +
                std::to_string(g.n_beams) + " beams exceed " + num(limits::kMaxPixels) +
                " pixels per image");
  }
  if (!(g.range_resolution > 0) || !std::isfinite(g.range_resolution) ||
      g.range_resolution * g.n_ranges > limits::kMaxRange) {
    throw Error(where(o.range_resolution) + ": rangeResolution " + num(g.range_resolution) +
                " m is not a positive range step (×" + std::to_string(g.n_ranges) +
                " range lines within " + num(limits::kMaxRange) + " m)");
  }
  if (!(g.frequency > 0) || !std::isfinite(g.frequency)) {
    throw Error(where(o.frequency) + ": frequency " + num(g.frequency) + " Hz is not positive");
  }
  // The bearing table lies between the structure and the image.
  const std::uint64_t bearings_end = o.size + 2ull * g.n_beams;
  if (g.image_offset < bearings_end) {
    throw Error(where(o.image_offset) + ": imageOffset " + std::to_string(g.image_offset) +
                " leaves no room for the " + std::to_string(g.n_beams) +
                " bearings that end at byte " + std::to_string(bearings_end));
  }
  const std::uint64_t want = std::uint64_t(g.n_ranges) * g.line_bytes();
  if (g.image_size != want) {
    throw Error(where(o.image_size) + ": imageSize " + std::to_string(g.image_size) + " is not " +
                std::to_string(g.n_ranges) + " range lines × " + std::to_string(g.line_bytes()) +
                " bytes (" + std::to_string(g.n_beams) + " beams × " +
                std::to_string(g.sample_bytes) + " bytes" +
                (g.has_gains() ? " + a 4-byte gain" : "") + ") = " + std::to_string(want));
  }
  if (std::uint64_t(g.image_offset) + g.image_size > n) {
    throw Error(where(o.image_offset) + ": the image (" + std::to_string(g.image_size) +
                " bytes at " + std::to_string(g.image_offset) + ") runs past the message's " +
                std::to_string(n) + " bytes");
  }
  g.bearings_rad.resize(g.n_beams);
  for (int j = 0; j < g.n_beams; ++j) {
    const std::int16_t b = load<std::int16_t>(p + o.size + 2 * j);
    if (std::abs(int(b)) > 9000) {
      throw Error(where(o.size + 2 * j) + ": bearing " + std::to_string(j) + " is " +
                  num(b * 0.01) + "°, beyond ±90°");
    }
    g.bearings_rad[j] = b * 0.01 * kDeg;
    if (j > 0 && !(g.bearings_rad[j] > g.bearings_rad[j - 1])) {
      throw Error(where(o.size + 2 * j) + ": bearing " + std::to_string(j) + " (" + num(b * 0.01) +
                  "°) does not increase from bearing " + std::to_string(j - 1) + " (" +
                  num(g.bearings_rad[j - 1] / kDeg) + "°)");
    }
  }
  const unsigned char* img = p + g.image_offset;
  const std::size_t lead = g.has_gains() ? 4 : 0;
  if (gains) {
    gains->clear();
    if (g.has_gains()) {
      gains->resize(g.n_ranges);
      for (int r = 0; r < g.n_ranges; ++r) {
        const float v = load<float>(img + std::size_t(r) * g.line_bytes());
        if (!(v > 0) || !std::isfinite(v)) {
          throw Error(where(g.image_offset + std::size_t(r) * g.line_bytes()) +
                      ": the gain of range line " + std::to_string(r) + " is " + num(v) +
                      ", not a positive number");
        }
        (*gains)[r] = v;
      }
    }
  }
  if (samples) {
    samples->resize(std::size_t(g.n_ranges) * g.n_beams);
    std::uint16_t* out = samples->data();
    for (int r = 0; r < g.n_ranges; ++r) {
      const unsigned char* line = img + std::size_t(r) * g.line_bytes() + lead;
      if (g.sample_bytes == 1) {
        for (int j = 0; j < g.n_beams; ++j) *out++ = line[j];
      } else {
        for (int j = 0; j < g.n_beams; ++j) *out++ = load<std::uint16_t>(line + 2 * j);
      }
    }
  }
  return g;
}

OculusReader::OculusReader(const fs::path& path) : path_(path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error("cannot read Oculus stream '" + file + "': not a regular file");
  }
  info_.file_size = fs::file_size(path, ec);
  if (ec) throw Error("cannot read Oculus stream '" + file + "': " + ec.message());
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open Oculus stream '" + file + "'");
  std::uint64_t at = 0;
  while (at < info_.file_size) {
    const std::uint64_t left = info_.file_size - at;
    if (left < kOculusHeaderBytes) {  // a header cut by the end of the stream
      info_.dropped_bytes = left;
      info_.dropped_offset = at;
      break;
    }
    unsigned char h[kOculusHeaderBytes];
    read_exact(f, file, at, h, sizeof h, "message header");
    const auto id = bin::load<std::uint16_t>(h + hdr::kOculusId);
    if (id != kOculusId) {
      throw Error(at_offset(file, at) + ": not an Oculus message: oculusId " +
                  bin::hex32(id).replace(2, 4, "") + ", expected 0x4f53" +
                  (at == 0 ? " (is this a raw Oculus ping stream?)"
                           : " (the stream is corrupt, or the previous message's payloadSize "
                             "is wrong)"));
    }
    OculusMessageRef m;
    m.offset = at;
    m.msg_id = bin::load<std::uint16_t>(h + hdr::kMsgId);
    m.version = bin::load<std::uint16_t>(h + hdr::kMsgVersion);
    m.payload = bin::load<std::uint32_t>(h + hdr::kPayloadSize);
    if (m.payload > kOculusMaxPayload) {
      throw Error(at_offset(file, at + hdr::kPayloadSize) + ": payloadSize " +
                  std::to_string(m.payload) + " bytes is beyond any Oculus message (" +
                  std::to_string(kOculusMaxPayload) + ")");
    }
    const std::uint64_t size = kOculusHeaderBytes + std::uint64_t(m.payload);
    if (size > left) {  // the last message, cut by the end of the stream
      info_.dropped_bytes = left;
      info_.dropped_offset = at;
      break;
    }
    if (m.msg_id == kOculusSimplePingResult) {
      info_.pings.push_back(m);
    } else {
      ++info_.other_messages;
    }
    at += size;
  }
  if (info_.pings.empty()) {
    throw Error(file + ": no complete SimplePingResult (0x23) message in " +
                std::to_string(info_.file_size) + " bytes" +
                (info_.dropped_bytes ? " (the stream ends inside a message at offset " +
                                           std::to_string(info_.dropped_offset) + ")"
                                     : ""));
  }
}

OculusPing OculusReader::read_ping(std::size_t i, std::vector<std::uint16_t>* samples,
                                   std::vector<float>* gains) const {
  if (i >= info_.pings.size()) {
    throw Error(path_.string() + ": ping " + std::to_string(i) + " does not exist (" +
                std::to_string(info_.pings.size()) + " pings)");
  }
  const OculusMessageRef& m = info_.pings[i];
  std::ifstream f(path_, std::ios::binary);
  if (!f) throw Error("cannot open Oculus stream '" + path_.string() + "'");
  // Bounded by the file: the scan found the whole message inside it.
  std::vector<unsigned char> buf(kOculusHeaderBytes + std::size_t(m.payload));
  read_exact(f, path_.string(), m.offset, buf.data(), buf.size(), "ping " + std::to_string(i));
  return decode_oculus_ping(buf.data(), buf.size(), m.offset, path_.string(), samples, gains);
}

double oculus_vertical_aperture(double frequency_hz, int master_mode, std::string* model) {
  const ApertureRow* best = nullptr;
  for (const ApertureRow& row : kApertures) {
    if (std::abs(frequency_hz - row.hz) > 0.2 * row.hz) continue;
    if (row.mode != 0 && row.mode != master_mode) continue;
    if (!best || std::abs(frequency_hz - row.hz) < std::abs(frequency_hz - best->hz)) best = &row;
  }
  if (!best) {
    throw Error("no Oculus model publishes a vertical aperture for a " + num(frequency_hz / 1e3) +
                " kHz ping (mode " + std::to_string(master_mode) +
                "); give it with --vertical-aperture-deg");
  }
  if (model) *model = best->model;
  return best->aperture_deg * kDeg;
}

SonarSpec oculus_sonar_spec(const OculusPing& g, const std::string& where) {
  SonarSpec s;
  std::string model;
  s.vertical_aperture_rad = oculus_vertical_aperture(g.frequency, g.master_mode, &model);
  s.name = "oculus-" + model.substr(0, model.find(' '));
  for (char& ch : s.name) ch = ch == '/' ? '-' : static_cast<char>(std::tolower(ch));
  s.name += g.master_mode == 2 ? "-hf" : "-lf";
  s.bearings_rad = g.bearings_rad;
  s.range_bins = g.n_ranges;
  // Range line i covers [i·Δr, (i+1)·Δr): nRanges·Δr is the range demand (docs/import.md §8).
  s.r_min = 0;
  s.r_max = g.n_ranges * g.range_resolution;
  s.beam_pattern.kind = BeamPattern::Kind::Sinc;
  s.bit_depth = g.sample_bytes == 1 ? 8 : 16;
  s.intensity_scale = g.sample_bytes == 1 ? 1.0 / 255.0 : 1.0 / 65535.0;
  if (s.r_max > limits::kMaxRange) {
    throw Error(where + ": the pings reach " + num(s.r_max) + " m, beyond " +
                num(limits::kMaxRange) + " m");
  }
  return s;
}

OculusGains parse_oculus_gains(const std::string& s) {
  return parse_enum<OculusGains>(kOculusGainsNames, s, "Oculus gain handling");
}

OculusClock parse_oculus_clock(const std::string& s) {
  return parse_enum<OculusClock>(kOculusClockNames, s, "Oculus clock");
}

void OculusImportConfig::validate() const {
  params::check(*this, "Oculus import:");
  check_navigation_format(navigation_format, "Oculus import: navigation_format");
  if (!std::isfinite(time_offset)) throw Error("Oculus import: 'time_offset' must be finite");
  if (static_sonar == !navigation.empty()) {
    throw Error(static_sonar ? "Oculus import: give a navigation file or a static sonar, not both"
                             : "Oculus import: Oculus pings carry no position: give a "
                               "navigation file (--nav) or a fixed sonar (--static)");
  }
  if (clock == OculusClock::Rate && !(rate_hz > 0 && rate_hz <= 1e4)) {
    throw Error("Oculus import: the rate clock needs a rate in (0, 10000] pings/s (--rate)");
  }
  if (clock != OculusClock::Rate && rate_hz != 0) {
    throw Error("Oculus import: a rate is given but the clock is not 'rate'");
  }
  mounting_from_list(mount, "Oculus import: mount");
}

OculusImportResult import_oculus(const fs::path& file, const fs::path& out,
                                 const OculusImportConfig& config, bool progress) {
  config.validate();
  const std::string name = file.string();
  OculusReader reader(file);
  const OculusStreamInfo& info = reader.info();
  OculusImportResult res;
  res.pings = info.pings.size();
  res.other_messages = info.other_messages;
  res.dropped_bytes = info.dropped_bytes;
  if (info.dropped_bytes) {
    res.warnings.push_back("the stream ends inside a message: dropped its last " +
                           std::to_string(info.dropped_bytes) + " bytes (from offset " +
                           std::to_string(info.dropped_offset) + ")");
  }
  if (info.other_messages) {
    res.warnings.push_back("skipped " + std::to_string(info.other_messages) +
                           " messages that are not SimplePingResult (0x23)");
  }

  // Pass 1: every ping's header fields and bearings (no image), the geometry and the times.
  const std::size_t n = info.pings.size();
  std::vector<double> times(n);
  OculusPing first;
  double unwrap = 0, prev_raw = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const OculusPing g = reader.read_ping(i, nullptr, nullptr);
    const std::string where = at_offset(name, g.offset) + ": ping " + std::to_string(i);
    if (i == 0) {
      first = g;
      res.version = g.version;
      res.has_gains = g.has_gains();
      res.spec = oculus_sonar_spec(g, where);
      oculus_vertical_aperture(g.frequency, g.master_mode, &res.model);
    } else {
      const double tol = 1e-9 * first.range_resolution;
      if (g.n_ranges != first.n_ranges || g.n_beams != first.n_beams ||
          g.sample_bytes != first.sample_bytes ||
          std::abs(g.range_resolution - first.range_resolution) > tol ||
          g.bearings_rad != first.bearings_rad || g.has_gains() != first.has_gains()) {
        throw Error(where + ": the geometry changes from ping 0 (" +
                    std::to_string(first.n_ranges) + " lines of " + num(first.range_resolution) +
                    " m × " + std::to_string(first.n_beams) + " beams, " +
                    std::to_string(8 * first.sample_bytes) + "-bit" +
                    (first.has_gains() ? ", gains" : "") + ") to " + std::to_string(g.n_ranges) +
                    " lines of " + num(g.range_resolution) + " m × " + std::to_string(g.n_beams) +
                    " beams, " + std::to_string(8 * g.sample_bytes) + "-bit" +
                    (g.has_gains() ? ", gains" : "") +
                    " (or the bearings change); a dataset holds one sensor geometry: split the "
                    "stream where the operator changed the range or mode");
      }
      std::string model;
      if (oculus_vertical_aperture(g.frequency, g.master_mode, &model) !=
          res.spec.vertical_aperture_rad) {
        throw Error(where + ": the frequency mode changes from " + res.model + " to " + model +
                    "; a dataset holds one sensor: split the stream");
      }
    }
    if (config.clock == OculusClock::Rate) {
      times[i] = double(i) / config.rate_hz;
    } else if (g.version == 2) {
      if (!std::isfinite(g.ping_start_time) || std::abs(g.ping_start_time) > 1e12) {
        throw Error(where + ": pingStartTime " + num(g.ping_start_time) +
                    " s is not a time; time the pings with --clock rate --rate HZ");
      }
      times[i] = g.ping_start_time;
    } else {
      // v1: a 32-bit counter of nanoseconds (docs/import.md §8) that wraps every 4.29 s.
      if (i > 0 && g.ping_start_time < prev_raw) unwrap += 4294967296.0;
      prev_raw = g.ping_start_time;
      times[i] = (unwrap + g.ping_start_time) * 1e-9;
    }
    times[i] += config.time_offset;
    if (i > 0 && times[i] < times[i - 1]) {
      throw Error(where + ": its time " + num(times[i]) + " s goes backwards (ping " +
                  std::to_string(i - 1) + " at " + num(times[i - 1]) +
                  " s); time the pings with --clock rate --rate HZ");
    }
    if (g.version != first.version) {
      throw Error(where + ": SimplePingResult version " + std::to_string(g.version) +
                  " after version " + std::to_string(first.version) + " pings");
    }
  }
  if (config.vertical_aperture_deg)
    res.spec.vertical_aperture_rad = *config.vertical_aperture_deg * kDeg;
  if (config.mirror) {
    std::reverse(res.spec.bearings_rad.begin(), res.spec.bearings_rad.end());
    for (double& b : res.spec.bearings_rad) b = -b;
  }
  res.spec.T_vehicle_sonar = mounting_from_list(config.mount, "Oculus import: mount");
  res.spec.validate();
  const bool divide = config.gains == OculusGains::Divide && res.has_gains;
  if (config.gains == OculusGains::Divide && !res.has_gains) {
    res.warnings.push_back(
        "--gains divide: the pings carry no per-line gains (fire flag bit 2 "
        "clear); samples kept as sent");
  }

  Trajectory nav;
  if (config.static_sonar) {
    nav.push_back(times.front(), Eigen::Isometry3d::Identity());
    if (times.back() > times.front()) nav.push_back(times.back(), Eigen::Isometry3d::Identity());
  } else {
    nav = read_navigation(config.navigation, config.navigation_csv, config.navigation_format);
  }

  DatasetWriter writer(out, res.spec,
                       divide ? DatasetWriter::ImageFormat::Tiff : DatasetWriter::ImageFormat::Png);
  Progress bar("import", n, progress);
  std::vector<std::uint16_t> samples;
  std::vector<float> gains;
  SonarImage img(res.spec.range_bins, res.spec.beams());
  const float scale = static_cast<float>(res.spec.intensity_scale);
  const int beams = res.spec.beams();
  bool gains_seen = false;
  for (std::size_t i = 0; i < n; ++i) {
    const std::string where = at_offset(name, info.pings[i].offset) + ": ping " + std::to_string(i);
    if (!frame_inside_navigation(nav, times[i], config.drop_outside, where)) {
      ++res.dropped;
      bar.add();
      continue;
    }
    reader.read_ping(i, &samples, &gains);
    for (const float v : gains) {
      res.gain_min = gains_seen ? std::min<double>(res.gain_min, v) : v;
      res.gain_max = gains_seen ? std::max<double>(res.gain_max, v) : v;
      gains_seen = true;
    }
    for (int r = 0; r < img.rows; ++r) {
      const std::uint16_t* src = samples.data() + std::size_t(r) * beams;
      float* dst = img.row_ptr(r);
      const float k = divide ? scale / gains[r] : scale;
      if (config.mirror) {
        for (int j = 0; j < beams; ++j) dst[j] = src[beams - 1 - j] * k;
      } else {
        for (int j = 0; j < beams; ++j) dst[j] = src[j] * k;
      }
    }
    img.timestamp = times[i];
    writer.add_frame(img);
    if (res.frames == 0) res.first_time = times[i];
    res.last_time = times[i];
    ++res.frames;
    bar.add();
  }
  bar.finish();
  if (res.frames == 0) throw no_frame_inside_navigation(nav, name);
  writer.set_navigation(nav);
  writer.commit();
  return res;
}

}  // namespace sonar3d
