#pragma once
// Sound Metrics ARIS recordings (.aris, written by ARISFish and ARIScope), read from the layout
// Sound Metrics publishes in its ARIS file SDK (docs/import.md, "ARIS"):
//
//   offset 0     FileHeader, 1024 bytes: Version = 0x05464444 ("DDF" 0x05), ...
//   offset 1024  frame 0: FrameHeader (1024 bytes) then SamplesPerBeam × BeamCount bytes
//   ...          frame i at 1024 + i · (1024 + SamplesPerBeam · BeamCount)
//
// The frame count comes from the file size, as the SDK asks (FileHeader.FrameCount is only
// compared). BeamCount comes from the frame header's PingMode; samples are stored sample-major
// (row = sample, nearest first), beam 0 the right-most beam, so a frame is already our image:
// rows are range bins, columns beams by increasing bearing (our bearings turn toward +y = left).
// Range: sample i lies at WindowStart + i·ΔL with WindowStart = SampleStartDelay·c/2,
// ΔL = SamplePeriod·c/2 (µs, c = SoundSpeed), so r_min = WindowStart − ΔL/2 and the row centres
// are the sample ranges. Bearings come from Sound Metrics' published beam-width tables.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/navigation.hpp"

namespace sonar3d {

inline constexpr std::uint32_t kArisSignature = 0x05464444;  // "DDF" + 0x05, little-endian
inline constexpr std::size_t kArisHeaderBytes = 1024;        // file header and frame header

// FrameHeader.TheSystemType.
enum class ArisSystem : std::uint32_t { Aris1800 = 0, Aris3000 = 1, Aris1200 = 2 };
const char* aris_system_name(ArisSystem s);

// Beam count of a PingMode (1–2: 48, 3–5: 96, 6–8: 64, 9–12: 128), 0 for an unknown mode.
int aris_beams_of_ping_mode(std::uint32_t ping_mode);

// Beam bearings (rad, increasing, beam 0 first) from Sound Metrics' published beam-width tables:
// ARIS 1200/1800 48 beams, 1800 96, 3000 64 and 128, telephoto lens 48 and 96. Throws Error
// naming the combination when no table is published (e.g. an ARIS 3000 with a telephoto lens).
std::vector<double> aris_beam_bearings(ArisSystem system, bool telephoto, int beams);
// Full vertical aperture of the model (Sound Metrics' specifications): 14° for the standard lens
// of ARIS 1200, 1800 and 3000, 3° with the telephoto lens.
double aris_vertical_aperture(ArisSystem system, bool telephoto);

// The fields of one frame header sonar3d uses (names as in Sound Metrics' FrameHeader).
struct ArisFrameHeader {
  std::uint32_t frame_index = 0;           // FrameIndex
  std::uint64_t frame_time_us = 0;         // FrameTime: PC time, µs since 1970
  std::uint64_t sonar_time_us = 0;         // sonarTimeStamp: on-sonar time, µs since 1970
  float depth = 0;                         // Depth: platform depth from AUV integration, m
  float pitch = 0, roll = 0, heading = 0;  // platform attitude, degrees
  float compass_heading = 0, compass_pitch = 0, compass_roll = 0;  // sonar compass, degrees
  double latitude = 0, longitude = 0;                              // degrees (auxiliary GPS)
  std::uint32_t ping_mode = 0;                                     // PingMode
  std::uint32_t sample_period_us = 0;                              // SamplePeriod
  float sound_speed = 0;                                           // SoundSpeed, m/s
  std::uint32_t samples_per_beam = 0;                              // SamplesPerBeam
  std::uint32_t sample_start_delay_us = 0;                         // SampleStartDelay
  std::uint32_t large_lens = 0;                                    // LargeLens: 1 = telephoto
  std::uint32_t system_type = 0;                                   // TheSystemType
  std::uint32_t reordered_samples = 1;        // ReorderedSamples: 1 = stored [sample][beam]
  float window_start = 0, window_length = 0;  // WindowStart, WindowLength (m, informative)
};

// Which frame clock gives the timestamps.
enum class ArisClock { Pc, Sonar };                                // FrameTime | sonarTimeStamp
ArisClock parse_aris_clock(const std::string& s);                  // "pc" | "sonar"
inline constexpr const char* kArisClockNames[] = {"pc", "sonar"};  // by ArisClock

// What the file holds, from its size, file header and first frame header.
struct ArisFileInfo {
  std::uint64_t file_size = 0;
  std::uint32_t header_frame_count = 0;  // FileHeader.FrameCount (compared, not trusted)
  std::size_t frames = 0;                // complete frames, from the file size
  std::uint64_t trailing_bytes = 0;      // bytes after the last complete frame
  int beams = 0, samples = 0;
  ArisSystem system = ArisSystem::Aris1800;
  bool telephoto = false;
  std::uint64_t frame_bytes() const { return kArisHeaderBytes + std::uint64_t(beams) * samples; }
};

// Reads an ARIS file frame by frame. Every size is checked against the file before anything is
// allocated; errors name the file, the frame and its byte offset.
class ArisReader {
 public:
  // Throws Error on a missing file, a wrong signature (naming DIDSON's DDF_03/04 when it is
  // one), a file too short for one frame, an unknown ping mode or absurd sample counts.
  explicit ArisReader(const std::filesystem::path& path);
  const ArisFileInfo& info() const { return info_; }
  const std::filesystem::path& path() const { return path_; }
  // Frame i (< info().frames): its header (signature and geometry checked against frame 0) and
  // its samples as an image of samples × beams, values 0–255 as they are stored.
  ArisFrameHeader read_frame(std::size_t i, std::vector<std::uint8_t>& samples) const;
  std::uint64_t frame_offset(std::size_t i) const {
    return kArisHeaderBytes + std::uint64_t(i) * info_.frame_bytes();
  }

 private:
  std::filesystem::path path_;
  ArisFileInfo info_;
};

// Our sensor description of an ARIS frame: published bearing table, range window of the frame
// (sample centres, see the top of this file), the model's vertical aperture with a sinc beam
// pattern, 8-bit intensities (stored value v ↦ v/255). Throws Error naming the bad field.
SonarSpec aris_sonar_spec(const ArisFrameHeader& h, int beams, const std::string& where);

// Where an ARIS import takes the vehicle poses from.
enum class ArisNavSource {
  Auto,    // a --nav file when given, else the frame headers when they hold a position
  Header,  // the frame headers: Latitude/Longitude (local ENU about the first fix), Depth,
           // Heading/Pitch/Roll (NED convention, degrees) — T_world_vehicle
  File,    // a navigation file (TUM or CSV), timed as `import frames` does
  Static,  // a fixed sonar: T_world_vehicle = identity for every frame
};
ArisNavSource parse_aris_nav_source(const std::string& s);  // auto | header | file | static
inline constexpr const char* kArisNavSourceNames[] = {"auto", "header", "file",
                                                      "static"};  // by ArisNavSource

struct ArisImportConfig {
  ArisNavSource nav_source = ArisNavSource::Auto;
  std::string navigation;         // File: TUM or CSV
  std::string navigation_format;  // "" (by extension), "tum" or "csv"
  NavCsvConfig navigation_csv;
  ArisClock clock = ArisClock::Pc;
  double time_offset = 0;     // s added to frame times to reach the navigation clock
  bool drop_outside = false;  // frames outside the navigation span: dropped (true) or an error
  bool drop_partial = false;  // a trailing partial frame: ignored (true) or an error
  // T_vehicle_sonar: x, y, z (m), roll, pitch, yaw (degrees), as mounting_from_list reads it.
  params::List mount = kNoMounting;
  params::Maybe vertical_aperture_deg;  // none = the model's (aris_vertical_aperture)
  void validate() const;                // throws Error naming the field
};

// The one declaration of ArisImportConfig's fields (core/params.hpp).
template <class V>
void describe(ArisImportConfig& c, V& v) {
  using params::param;
  v.field(c.nav_source,
          param("nav_source", "",
                "where the poses come from: 'auto' (the navigation file when given, else the "
                "frame headers), 'header' (Latitude/Longitude/Depth/Heading/Pitch/Roll of each "
                "frame header), 'file' (the navigation file) or 'static' (a fixed sonar: "
                "identity poses)")
              .choices(kArisNavSourceNames)
              .flag("--nav-source"));
  v.field(c.navigation,
          param("navigation", "",
                "navigation file: TUM (T_world_vehicle) or CSV (time,x,y,z,roll,pitch,yaw), "
                "timed onto the frames as `import frames` does; empty: none")
              .flag("--nav"));
  v.field(c.navigation_format,
          param("navigation_format", "", "tum or csv; empty: by the file's extension")
              .flag("--nav-format"));
  v.group("navigation_csv", c.navigation_csv);
  v.field(c.clock, param("clock", "",
                         "frame times from FrameTime ('pc', the recording PC) or sonarTimeStamp "
                         "('sonar')")
                       .choices(kArisClockNames)
                       .flag("--clock"));
  v.field(c.time_offset,
          param("time_offset", "s", "added to frame times to reach the navigation clock")
              .flag("--time-offset"));
  v.field(c.drop_outside,
          param("drop_outside", "",
                "drop (and count) frames outside the navigation span instead of failing")
              .flag("--drop-outside"));
  v.field(c.drop_partial,
          param("drop_partial", "",
                "import the complete frames of a recording whose last frame was cut")
              .flag("--drop-partial"));
  v.field(c.mount, param("mount", "m, deg",
                         "T_vehicle_sonar as x, y, z (m), roll, pitch, yaw (degrees; R = "
                         "Rz(yaw)·Ry(pitch)·Rx(roll); vehicle x forward, y left, z up)")
                       .flag("--mount"));
  v.field(c.vertical_aperture_deg,
          param("vertical_aperture_deg", "deg",
                "full vertical aperture; none: the model's (14°, 3° with the telephoto lens)")
              .range_open_high(limits::kMinApertureDeg, 180)
              .flag("--vertical-aperture-deg"));
}

struct ArisImportResult {
  ArisFileInfo info;
  SonarSpec spec;
  std::size_t frames = 0;                            // written
  std::size_t dropped = 0;                           // outside the navigation span
  ArisNavSource nav_source = ArisNavSource::Static;  // the one used
  double first_time = 0, last_time = 0;
  std::vector<std::string> warnings;
};

// Imports FILE.aris into a dataset at `out`, atomically (nothing is left there on error).
ArisImportResult import_aris(const std::filesystem::path& file, const std::filesystem::path& out,
                             const ArisImportConfig& config = {}, bool progress = false);

// ------------------------------------------------------------------ writing (tests, exports)

// One frame to write: header fields and samples (samples_per_beam × beams, sample-major).
struct ArisWriteFrame {
  ArisFrameHeader header;
  std::vector<std::uint8_t> samples;
};
// Writes an ARIS file in the published layout (file header with FrameCount, NumRawBeams,
// SamplesPerChannel; every frame header with its signature). Atomic. Throws Error when a frame's
// sample count does not match its ping mode and SamplesPerBeam.
void write_aris(const std::filesystem::path& path, const std::vector<ArisWriteFrame>& frames);

// Local ENU (x east, y north) of a WGS84 latitude/longitude about an origin, through ECEF on the
// ellipsoid surface (the up component is dropped; depth gives z); and its inverse.
Eigen::Vector2d enu_from_geodetic(double lat_deg, double lon_deg, double lat0_deg, double lon0_deg);
Eigen::Vector2d geodetic_from_enu(const Eigen::Vector2d& en, double lat0_deg, double lon0_deg);

// "x,y,z,roll,pitch,yaw" (m, degrees; R = Rz(yaw)·Ry(pitch)·Rx(roll), FLU) to T_vehicle_sonar.
// Throws Error naming the text.
Eigen::Isometry3d parse_mounting(const std::string& text);

}  // namespace sonar3d
