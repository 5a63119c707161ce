#pragma once
// Import of the HoloOcean imaging-sonar layout used by HoloOcean-based reconstruction work
// (neusis, AONeuS, SonarSplat) into a dataset directory v1 (docs/import.md):
//
//   DIR/Config.json    the HoloOcean scenario: agents[].sensors[] holds one "ImagingSonar" whose
//                      configuration gives RangeBins, AzimuthBins, RangeMin, RangeMax (m) and the
//                      Azimuth and Elevation apertures (degrees, full width)
//   DIR/Data/N.pkl     one pickled dict per frame: "ImagingSonar" (uint8 or float32 numpy array,
//                      range bins × azimuth bins) and "PoseSensor" (4×4, sensor to world)
//
// Pickles are decoded by a Python interpreter with numpy (Debian: python3, python3-numpy) run as
// a child process with a restricted unpickler that only builds numpy arrays and plain containers.
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

// The ImagingSonar entry of a HoloOcean Config.json, in its own units (m, degrees).
struct HoloOceanSonar {
  std::string agent_name;    // the agent that carries the sensor
  std::string sensor_name;   // its "sensor_name", else "ImagingSonar": the image key in the pickles
  int range_bins = 0;        // RangeBins: image rows
  int azimuth_bins = 0;      // AzimuthBins: image columns
  double range_min = 0;      // RangeMin, m
  double range_max = 0;      // RangeMax, m
  double azimuth_deg = 0;    // Azimuth: full horizontal aperture
  double elevation_deg = 0;  // Elevation: full vertical aperture
  double rate_hz = 0;        // "Hz" of the sensor; 0 when Config.json does not give it
  // Things worth knowing that do not stop the import (e.g. the PoseSensor is not mounted on the
  // sonar's socket, so its poses are not the sonar's).
  std::vector<std::string> warnings;
};

// How a HoloOcean pixel index maps to a range and an azimuth.
enum class HoloOceanBins {
  // The reading of neusis and AONeuS (the format's declared convention): row i is the range
  // RangeMin + i·Δr and column j the azimuth −Azimuth/2 + j·Δa, where
  // Δr = (RangeMax − RangeMin)/RangeBins and Δa = Azimuth/AzimuthBins. Our row centres then sit
  // at those ranges (r_min = RangeMin − Δr/2) and the bearing table holds those azimuths.
  Sample,
  // HoloOcean's renderer: a return at range r lands in row floor((r − RangeMin)/Δr), i.e. row i is
  // the cell [RangeMin + iΔr, RangeMin + (i+1)Δr), and likewise for columns. r_min = RangeMin and
  // centred uniform bearings. Half a bin away from Sample.
  Cell,
};
const char* holoocean_bins_name(HoloOceanBins b);
HoloOceanBins parse_holoocean_bins(const std::string& s);  // "sample" | "cell"; throws Error
inline constexpr const char* kHoloOceanBinsNames[] = {"sample", "cell"};  // by HoloOceanBins

struct HoloOceanImportConfig {
  HoloOceanBins bins = HoloOceanBins::Sample;
  std::string sensor;                   // sensor_name to import when Config.json has several
  std::string image_key;                // pickle key of the image; "" = the sensor's name
  std::string pose_key = "PoseSensor";  // pickle key of the 4×4 sensor-to-world pose
  // The pickles carry no time: Data/N.pkl gets t = N / rate. 0 = the sensor's Hz, else 1 Hz.
  double frame_rate_hz = 0;
  // Interpreter with numpy used to decode pickles; "" = $SONAR3D_PYTHON, else /usr/bin/python3
  // when it exists, else python3 on PATH.
  std::string python;
  // PoseSensor is float32: a rotation is accepted when every entry of RᵀR − I and det R − 1 is
  // within this, then re-orthonormalised; anything worse is not a rigid transform.
  double rigid_tolerance = 1e-4;
  void validate() const;  // throws Error naming the field
};

// The one declaration of HoloOceanImportConfig's fields (core/params.hpp).
template <class V>
void describe(HoloOceanImportConfig& c, V& v) {
  using params::param;
  v.field(c.bins, param("bins", "",
                        "pixel convention: 'sample' (neusis/AONeuS: row i at RangeMin + i·Δr, "
                        "column j at −Azimuth/2 + j·Δa) or 'cell' (HoloOcean's renderer: row i "
                        "is the cell [RangeMin + i·Δr, RangeMin + (i+1)·Δr))")
                      .choices(kHoloOceanBinsNames)
                      .flag("--bins"));
  v.field(c.sensor,
          param("sensor", "", "sensor_name of the ImagingSonar when Config.json has several")
              .flag("--sensor"));
  v.field(c.image_key, param("image_key", "", "pickle key of the image; empty: the sensor's name")
                           .flag("--image-key"));
  v.field(c.pose_key,
          param("pose_key", "", "pickle key of the 4×4 sensor-to-world pose").flag("--pose-key"));
  v.field(c.frame_rate_hz,
          param("frame_rate_hz", "Hz",
                "frames per second for the timestamps t = N / rate of Data/N.pkl; 0: the "
                "sensor's Hz, else 1")
              .non_negative()
              .flag("--rate"));
  v.field(c.python, param("python", "",
                          "Python interpreter with numpy; empty: $SONAR3D_PYTHON, else "
                          "/usr/bin/python3")
                        .flag("--python"));
  v.field(c.rigid_tolerance,
          param("rigid_tolerance", "",
                "a float32 pose rotation is accepted when every entry of RᵀR − I and det R − 1 "
                "is within this")
              .range_open(0, 0.1));
}

struct HoloOceanImportResult {
  HoloOceanSonar sonar;
  SonarSpec spec;  // as written to sonar.yaml
  std::size_t frames = 0;
  std::string dtype;         // "uint8" (stored as 8-bit PNG, intensity v/255) or "float32" (TIFF)
  double frame_rate_hz = 0;  // used for the timestamps
  std::vector<std::string> warnings;
};

// Reads the ImagingSonar of `config_json`; `sensor` selects by sensor_name when there are several.
// Errors name the file and the missing or invalid key.
HoloOceanSonar read_holoocean_config(const std::filesystem::path& config_json,
                                     const std::string& sensor = "");

// Our sensor description of a HoloOcean sonar: bearing table and range window per `bins`
// (HoloOcean's sonar frame is ours: x forward, y left = positive azimuth, z up), vertical aperture
// = Elevation with a flat beam pattern (HoloOcean has no vertical beam pattern), T_vehicle_sonar =
// identity (the navigation holds the sonar poses themselves). Throws Error when `bins` cannot
// represent the sensor (Sample with RangeMin < Δr/2 would need r_min < 0).
SonarSpec holoocean_sonar_spec(const HoloOceanSonar& sonar, HoloOceanBins bins);

// Imports DIR (Config.json + Data/*.pkl) into a dataset at `out`, written atomically: on any error
// nothing is left at `out`. Errors name the file (Data/N.pkl) and what is wrong: unreadable or
// truncated pickle, missing key, wrong shape or dtype, non-finite intensities, a pose that is not
// a rigid transform, a missing Python or numpy.
HoloOceanImportResult import_holoocean(const std::filesystem::path& dir,
                                       const std::filesystem::path& out,
                                       const HoloOceanImportConfig& config = {},
                                       bool progress = false);

// The interpreter import_holoocean would run for `requested` (see HoloOceanImportConfig::python).
std::string pickle_python(const std::string& requested = "");

}  // namespace sonar3d
