#pragma once
// Blueprint Subsea Oculus multibeam imaging sonars: the raw ping stream the sonar sends over its
// network link, one message after another, read from the layout Blueprint publishes in Oculus.h
// (Oculus ViewPoint/SDK sources; all structures single-byte packed, little-endian):
//
//   OculusMessageHeader      16 bytes: oculusId = 0x4f53, srcDeviceId, dstDeviceId, msgId,
//                            msgVersion, payloadSize (u32, bytes after the header), spare
//   OculusSimplePingResult   msgId 0x23, version 1: the fire message echoed back (53 bytes with
//                            the header), then pingId … messageSize: 122 bytes in all
//   OculusSimplePingResult2  msgId 0x23, version 2: the longer fire message (89 bytes), ping
//                            fields with heading/pitch/roll and a double pingStartTime: 202 bytes
//   then nBeams int16 bearings (0.01°), and at imageOffset the image: nRanges range lines of
//   nBeams samples (8- or 16-bit), each line led by a 4-byte gain when fire flag bit 2 is set.
//
// What the published layout leaves open (bearing sign, where a range line lies, the gain records,
// the v1 time unit, image order, vertical aperture) and how each was settled: docs/import.md §8.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/navigation.hpp"

namespace sonar3d {

inline constexpr std::uint16_t kOculusId = 0x4f53;              // OCULUS_CHECK_ID
inline constexpr std::uint16_t kOculusSimplePingResult = 0x23;  // messageSimplePingResult
inline constexpr std::size_t kOculusHeaderBytes = 16;           // OculusMessageHeader
inline constexpr std::size_t kOculusPingV1Bytes = 122;          // OculusSimplePingResult
inline constexpr std::size_t kOculusPingV2Bytes = 202;          // OculusSimplePingResult2
// The largest message we accept: 65535 range lines of 1024 16-bit beams with gains are 134 MB.
inline constexpr std::uint32_t kOculusMaxPayload = 256u << 20;

// Fire-message flag bits (OculusSimpleFireMessage.flags).
inline constexpr std::uint8_t kOculusFlagRangeInMetres = 0x01;
inline constexpr std::uint8_t kOculusFlag16Bit = 0x02;
inline constexpr std::uint8_t kOculusFlagSendGain = 0x04;
inline constexpr std::uint8_t kOculusFlagSimpleReturn = 0x08;

// The fields of one SimplePingResult (v1 or v2) sonar3d uses, names as in Oculus.h.
struct OculusPing {
  std::uint64_t offset = 0;      // byte offset of the message in the stream
  int version = 1;               // layout: 1 (msgVersion 0 or 1, OculusSimplePingResult) or 2
  std::uint8_t master_mode = 0;  // 1 = low-frequency mode, 2 = high-frequency mode
  std::uint8_t flags = 0;        // fire-message flags
  double range_demand = 0;       // range (m, or % without flag bit 0)
  double gain_percent = 0;       // gain demand
  std::uint32_t ping_id = 0;
  double frequency = 0;        // Hz
  double speed_of_sound = 0;   // speedOfSoundUsed, m/s
  double ping_start_time = 0;  // v2: s since power-up; v1: the u32 counter as it is stored
  double heading = 0, pitch = 0, roll = 0;  // v2 only, degrees
  int sample_bytes = 1;                     // dataSize: 1 (8-bit) or 2 (16-bit)
  double range_resolution = 0;              // m per range line
  int n_ranges = 0, n_beams = 0;
  std::uint32_t image_offset = 0, image_size = 0, message_size = 0;
  std::vector<double> bearings_rad;  // the message's table, 0.01° units converted, beam 0 first
  bool has_gains() const { return (flags & kOculusFlagSendGain) != 0; }
  std::size_t line_bytes() const {
    return std::size_t(n_beams) * sample_bytes + (has_gains() ? 4 : 0);
  }
};

// One message of the stream, located by a scan of the headers.
struct OculusMessageRef {
  std::uint64_t offset = 0;
  std::uint16_t msg_id = 0, version = 0;
  std::uint32_t payload = 0;
};

// What the stream holds, from a scan of its message headers.
struct OculusStreamInfo {
  std::uint64_t file_size = 0;
  std::vector<OculusMessageRef> pings;  // complete SimplePingResult messages, in stream order
  std::size_t other_messages = 0;       // complete messages of other ids (skipped)
  std::uint64_t dropped_bytes = 0;      // a message cut by the end of the stream
  std::uint64_t dropped_offset = 0;     // where that message starts
};

// Decodes one SimplePingResult message (`n` bytes at `p`, header included; `offset` its place in
// `file` for errors). Every size is checked against `n` before anything is read or allocated.
// samples: n_ranges × n_beams stored values, range-major (row = range line, nearest first);
// gains: one per range line when the ping carries them (else empty). Either may be null.
// Throws Error naming the file, the byte offset and the bad field.
OculusPing decode_oculus_ping(const unsigned char* p, std::size_t n, std::uint64_t offset,
                              const std::string& file, std::vector<std::uint16_t>* samples,
                              std::vector<float>* gains);

// Reads an Oculus stream message by message.
class OculusReader {
 public:
  // Scans the message headers. Throws Error (file and offset) on a missing or empty file, a
  // header without the 0x4f53 id, a payload beyond kOculusMaxPayload, or a stream without pings.
  // A last message cut by the end of the file is not an error: info().dropped_bytes says so.
  explicit OculusReader(const std::filesystem::path& path);
  const OculusStreamInfo& info() const { return info_; }
  const std::filesystem::path& path() const { return path_; }
  // Ping i (< info().pings.size()), decoded as decode_oculus_ping does.
  OculusPing read_ping(std::size_t i, std::vector<std::uint16_t>* samples,
                       std::vector<float>* gains) const;

 private:
  std::filesystem::path path_;
  OculusStreamInfo info_;
};

// Full vertical aperture (rad) from Blueprint Subsea's published specifications, chosen by the
// ping's frequency and mode (docs/import.md §8): 20° for the 375 kHz, 750 kHz and 1.2 MHz
// low-frequency modes and the M3000d's 3 MHz, 12° for the M750d's 1.2 MHz and the M1200d's
// 2.1 MHz high-frequency modes. `model` receives the model and mode the ping identifies.
// Throws Error for a frequency no model publishes.
double oculus_vertical_aperture(double frequency_hz, int master_mode, std::string* model);

// Our sensor description of a ping: the message's bearing table (positive to port, beam 0
// first, strictly increasing), range lines as bins of width rangeResolution from 0 m, the
// published vertical aperture with a sinc pattern, 8- or 16-bit intensities (v/255, v/65535).
// Throws Error (with `where`) on a bad field.
SonarSpec oculus_sonar_spec(const OculusPing& ping, const std::string& where);

// How per-line gains (fire flag bit 2) are used.
enum class OculusGains {
  Keep,    // samples as sent; the dataset keeps the sonar's 8/16-bit encoding
  Divide,  // sample / gain of its line, written as float32 TIFF frames
};
OculusGains parse_oculus_gains(const std::string& s);                   // "keep" | "divide"
inline constexpr const char* kOculusGainsNames[] = {"keep", "divide"};  // by OculusGains

// Frame times.
enum class OculusClock {
  Ping,  // pingStartTime: v2 seconds since power-up; v1 counter in ns, unwrapped at 2^32
  Rate,  // ping i (in stream order) at i / rate_hz
};
OculusClock parse_oculus_clock(const std::string& s);                 // "ping" | "rate"
inline constexpr const char* kOculusClockNames[] = {"ping", "rate"};  // by OculusClock

struct OculusImportConfig {
  std::string navigation;         // TUM or CSV (T_world_vehicle); empty with static_sonar
  std::string navigation_format;  // "" (by extension), "tum" or "csv"
  NavCsvConfig navigation_csv;
  bool static_sonar = false;  // a fixed sonar: identity vehicle pose for every frame
  OculusClock clock = OculusClock::Ping;
  double rate_hz = 0;         // Rate clock: pings per second
  double time_offset = 0;     // s added to frame times to reach the navigation clock
  bool drop_outside = false;  // frames outside the navigation span: dropped (true) or an error
  OculusGains gains = OculusGains::Keep;
  // T_vehicle_sonar: x, y, z (m), roll, pitch, yaw (degrees), as mounting_from_list reads it.
  params::List mount = kNoMounting;
  params::Maybe vertical_aperture_deg;  // none = the published one (oculus_vertical_aperture)
  bool mirror = false;    // bearings positive to starboard: negate them (and reverse the columns)
  void validate() const;  // throws Error naming the field
};

// The one declaration of OculusImportConfig's fields (core/params.hpp).
template <class V>
void describe(OculusImportConfig& c, V& v) {
  using params::param;
  v.field(c.navigation,
          param("navigation", "",
                "navigation file: TUM (T_world_vehicle) or CSV (time,x,y,z,roll,pitch,yaw), "
                "timed onto the pings as `import frames` does; empty with static_sonar")
              .flag("--nav"));
  v.field(
      c.static_sonar,
      param("static_sonar", "", "a fixed sonar: no navigation, identity poses").flag("--static"));
  v.field(c.navigation_format,
          param("navigation_format", "", "tum or csv; empty: by the file's extension")
              .flag("--nav-format"));
  v.group("navigation_csv", c.navigation_csv);
  v.field(c.clock, param("clock", "",
                         "ping times from pingStartTime ('ping': v2 seconds since power-up, v1 "
                         "nanosecond counter) or from the ping order ('rate', with rate_hz)")
                       .choices(kOculusClockNames)
                       .flag("--clock"));
  v.field(c.rate_hz, param("rate_hz", "Hz", "pings per second of the 'rate' clock; 0 otherwise")
                         .range(0, 1e4)
                         .flag("--rate"));
  v.field(c.gains, param("gains", "",
                         "per-line gains of pings that carry them: 'keep' the samples as sent, "
                         "or 'divide' each line by its gain (float32 TIFF frames)")
                       .choices(kOculusGainsNames)
                       .flag("--gains"));
  v.field(c.mirror,
          param("mirror", "",
                "the stream's bearings are positive to starboard: mirror them (default: positive "
                "to port, docs/import.md §8)")
              .flag("--mirror"));
  v.field(c.mount, param("mount", "m, deg",
                         "T_vehicle_sonar as x, y, z (m), roll, pitch, yaw (degrees; R = "
                         "Rz(yaw)·Ry(pitch)·Rx(roll); vehicle x forward, y left, z up)")
                       .flag("--mount"));
  v.field(c.vertical_aperture_deg,
          param("vertical_aperture_deg", "deg",
                "full vertical aperture; none: the published one of the model and mode the ping "
                "frequency identifies (20° or 12°)")
              .range_open_high(limits::kMinApertureDeg, 180)
              .flag("--vertical-aperture-deg"));
  v.field(c.time_offset,
          param("time_offset", "s", "added to ping times to reach the navigation clock")
              .flag("--time-offset"));
  v.field(c.drop_outside,
          param("drop_outside", "",
                "drop (and count) pings outside the navigation span instead of failing")
              .flag("--drop-outside"));
}

struct OculusImportResult {
  SonarSpec spec;
  std::string model;                // model and mode identified from frequency and mode
  std::size_t pings = 0;            // complete pings in the stream
  std::size_t frames = 0;           // written
  std::size_t dropped = 0;          // outside the navigation span
  std::size_t other_messages = 0;   // messages of other ids, skipped
  std::uint64_t dropped_bytes = 0;  // a cut last message
  int version = 1;
  bool has_gains = false;
  double gain_min = 0, gain_max = 0;  // over every line of every ping, when it has gains
  double first_time = 0, last_time = 0;
  std::vector<std::string> warnings;
};

// Imports an Oculus stream into a dataset at `out`, atomically (nothing is left there on error).
OculusImportResult import_oculus(const std::filesystem::path& file,
                                 const std::filesystem::path& out,
                                 const OculusImportConfig& config = {}, bool progress = false);

}  // namespace sonar3d
