// io: imports of real data — HoloOcean/neusis pickles, navigation logs (TUM, CSV in ENU/NED),
// frames + navigation — their mappings, their bad inputs, and a round trip through our simulator.
// HoloOcean fixtures are written here with the Debian python3 + numpy (pickle), in their own
// convention, independently of our projector.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <random>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::read_all;
using sonar3d::test::run_cli_log;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Everything a run writes lives under one directory of its own (ctest runs tests in parallel
// processes), removed at the end when every test passed.
fs::path run_root() {
  static const fs::path root =
      fs::temp_directory_path() / ("sonar3d_test_import_" + std::to_string(getpid()));
  return root;
}

class CleanUp : public ::testing::Environment {
 public:
  void TearDown() override {
    if (::testing::UnitTest::GetInstance()->Passed()) fs::remove_all(run_root());
  }
};
const auto* const kCleanUp = ::testing::AddGlobalTestEnvironment(new CleanUp);

fs::path temp_dir(const std::string& name) {
  const fs::path p = run_root() / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

void write_file(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary);
  f << text;
}

void expect_error(const std::function<void()>& f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "expected an error mentioning '" << needles.front() << "'";
  } catch (const Error& e) {
    for (const auto& n : needles) {
      EXPECT_NE(std::string(e.what()).find(n), std::string::npos)
          << "'" << n << "' not in: " << e.what();
    }
  }
}

// Runs a Python script with the interpreter the importer uses; returns its exit status.
int run_python(const fs::path& dir, const std::string& script) {
  const fs::path p = dir / "script.py";
  write_file(p, script);
  const std::string cmd =
      pickle_python() + " " + p.string() + " > " + (dir / "py.log").string() + " 2>&1";
  return std::system(cmd.c_str());
}

bool have_numpy() {
  static const bool ok = [] {
    const std::string cmd = pickle_python() + " -c 'import numpy' > /dev/null 2>&1";
    return std::system(cmd.c_str()) == 0;
  }();
  return ok;
}

#define REQUIRE_NUMPY()                                              \
  if (!have_numpy())                                                 \
  GTEST_SKIP() << pickle_python() << " with numpy is not available " \
               << "(Debian: python3-numpy)"

// The sonar of our HoloOcean fixtures.
struct HoloSonar {
  int range_bins = 100;
  int azimuth_bins = 64;
  double range_min = 0.5, range_max = 4.5;  // m
  double azimuth_deg = 60, elevation_deg = 12;
  double hz = 10;
  double dr() const { return (range_max - range_min) / range_bins; }
  double da() const { return azimuth_deg * kDeg / azimuth_bins; }
};

// A Config.json shaped like the ones shipped with AONeuS/neusis (extra sensors, PoseSensor on the
// sonar socket).
std::string config_json(const HoloSonar& s, const std::string& extra_sensor = "",
                        const std::string& pose_rotation = "[0, 45, 0]") {
  std::ostringstream os;
  os << std::setprecision(17);
  os << R"({"name": "HoveringImagingSonar", "world": "SimpleUnderwater", "main_agent": "auv0",
  "ticks_per_sec": 200, "frames_per_sec": true, "octree_min": 0.02, "octree_max": 5.0,
  "agents": [{"agent_name": "auv0", "agent_type": "HoveringAUV", "sensors": [
    {"sensor_type": "OrientationSensor"}, {"sensor_type": "LocationSensor"},
    {"sensor_type": "PoseSensor", "socket": "SonarSocket", "rotation": )"
     << pose_rotation << R"(},
    {"sensor_type": "IMUSensor", "socket": "IMUSocket", "Hz": 200,
     "configuration": {"AccelSigma": 0.00277, "ReturnBias": true}},
    {"sensor_type": "DVLSensor", "socket": "DVLSocket", "Hz": 20,
     "configuration": {"Elevation": 22.5, "MaxRange": 50}},)"
     << extra_sensor << R"(
    {"sensor_type": "ImagingSonar", "socket": "SonarSocket", "Hz": )"
     << s.hz << R"(, "rotation": [0, 45, 0],
     "configuration": {"RangeBins": )"
     << s.range_bins << R"(, "AzimuthBins": )" << s.azimuth_bins << R"(, "RangeMin": )"
     << s.range_min << R"(, "RangeMax": )" << s.range_max
     << R"(, "InitOctreeRange": 50, "Elevation": )" << s.elevation_deg << R"(, "Azimuth": )"
     << s.azimuth_deg << R"(, "AzimuthStreaks": -1, "ScaleNoise": true, "AddSigma": 0.15,
       "MultSigma": 0.2, "RangeSigma": 0.0, "MultiPath": true, "ViewOctree": -1}}],
    "control_scheme": 0, "location": [-18, 16, -22], "rotation": [0.0, 0.0, 130.0]}],
  "window_width": 1280, "window_height": 720})";
  return os.str();
}

// One frame to pickle: an image (float values, stored as `dtype`) and a pose.
struct HoloFrame {
  int number = 0;
  std::vector<float> image;  // range bins × azimuth bins
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
};

// Writes DIR/Config.json and DIR/Data/NNN.pkl with numpy pickles: {"ImagingSonar": image as
// dtype, "PoseSensor": float32 4×4}. Raw data go through .bin files and a small Python packer.
void write_holoocean(const fs::path& dir, const HoloSonar& s, const std::vector<HoloFrame>& frames,
                     const std::string& dtype) {
  write_file(dir / "Config.json", config_json(s));
  const fs::path raw = dir / "raw";
  fs::create_directories(raw);
  fs::create_directories(dir / "Data");
  std::ostringstream list;
  list << std::setprecision(17) << "frames = [\n";
  for (const auto& f : frames) {
    const std::string bin = (raw / (std::to_string(f.number) + ".bin")).string();
    std::ofstream(bin, std::ios::binary)
        .write(reinterpret_cast<const char*>(f.image.data()), f.image.size() * sizeof(float));
    list << "  (" << f.number << ", '" << bin << "', [";
    for (int k = 0; k < 16; ++k) list << f.pose(k / 4, k % 4) << (k < 15 ? ", " : "");
    list << "]),\n";
  }
  list << "]\n";
  const std::string script = "import numpy as np, pickle\n" + list.str() +
                             "for n, path, pose in frames:\n"
                             "    img = np.fromfile(path, dtype=np.float32).reshape(" +
                             std::to_string(s.range_bins) + ", " + std::to_string(s.azimuth_bins) +
                             ")\n"
                             "    img = np.round(img).astype(np.uint8) if '" +
                             dtype +
                             "' == 'uint8' else img\n"
                             "    d = {'ImagingSonar': img, 'PoseSensor': np.array(pose, "
                             "dtype=np.float32).reshape(4, 4)}\n"
                             "    with open('" +
                             (dir / "Data").string() +
                             "/%03d.pkl' % n, 'wb') as f:\n"
                             "        pickle.dump(d, f)\n";
  ASSERT_EQ(run_python(dir, script), 0) << "fixture generation failed";
  fs::remove_all(raw);
}

Eigen::Matrix4d test_pose(int k) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(0.3 + 0.7 * k, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.4 - 0.2 * k, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(-0.25 + 0.1 * k, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(-18 + k, 16 - 0.5 * k, -22 + 0.3 * k);
  return T.matrix();
}

// Their sensor model (neusis helpers.get_arcs): azimuth θ, elevation φ,
// p = (r·cosθ·cosφ, r·sinθ·cosφ, r·sinφ) in the sensor frame, then PoseSensor (sensor → world).
Eigen::Vector3d their_point(const Eigen::Matrix4d& pose, double r, double az, double el) {
  const Eigen::Vector4d p(r * std::cos(az) * std::cos(el), r * std::sin(az) * std::cos(el),
                          r * std::sin(el), 1.0);
  return (pose * p).head<3>();
}

struct Scatterer {
  int frame, row, col;
  Eigen::Vector3d p_world;
  double elevation;
};

// Places scatterers at random world points in every frame's field of view, finds the pixel each
// lands in under the convention, and makes the fixture frames with a return there.
std::vector<Scatterer> place_scatterers(const HoloSonar& s, HoloOceanBins bins, int nframes,
                                        std::vector<HoloFrame>& frames, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ur(s.range_min + s.dr(), s.range_max - s.dr());
  std::uniform_real_distribution<double> ua(-0.45 * s.azimuth_deg * kDeg,
                                            0.45 * s.azimuth_deg * kDeg);
  std::uniform_real_distribution<double> ue(-0.45 * s.elevation_deg * kDeg,
                                            0.45 * s.elevation_deg * kDeg);
  std::vector<Scatterer> out;
  for (int k = 0; k < nframes; ++k) {
    HoloFrame f;
    f.number = k;
    f.pose = test_pose(k);
    f.image.assign(static_cast<std::size_t>(s.range_bins) * s.azimuth_bins, 0.0f);
    for (int q = 0; q < 4; ++q) {
      const double r = ur(rng), az = ua(rng), el = ue(rng);
      const Eigen::Vector3d p_world = their_point(f.pose, r, az, el);
      // Which pixel: invert their indexing from the point's own polar coordinates.
      const Eigen::Vector3d p_s = (f.pose.inverse() * p_world.homogeneous()).head<3>();
      const double rr = p_s.norm(), aa = std::atan2(p_s.y(), p_s.x());
      const double fi = (rr - s.range_min) / s.dr();
      const double fj = (aa + 0.5 * s.azimuth_deg * kDeg) / s.da();
      const int row =
          static_cast<int>(bins == HoloOceanBins::Sample ? std::lround(fi) : std::floor(fi));
      const int col =
          static_cast<int>(bins == HoloOceanBins::Sample ? std::lround(fj) : std::floor(fj));
      f.image[static_cast<std::size_t>(row) * s.azimuth_bins + col] = 100.0f + 30 * q;
      out.push_back({k, row, col, p_world, el});
    }
    frames.push_back(std::move(f));
  }
  return out;
}

void check_scatterers(const fs::path& dataset, const HoloSonar& s, const std::vector<Scatterer>& sc,
                      float scale) {
  const Dataset ds = read_dataset(dataset);
  for (const Scatterer& q : sc) {
    const SonarImage img = ds.load_frame(q.frame);
    EXPECT_GT(img.at(q.row, q.col), 0.0f) << "frame " << q.frame;
    // Our projector: row centre range, column bearing, at the scatterer's true elevation.
    const Eigen::Vector3d p_sonar =
        polar_to_sonar({ds.spec.range_of_bin(q.row), ds.spec.bearings_rad[q.col], q.elevation});
    const Eigen::Vector3d p_world = ds.T_world_sonar(q.frame) * p_sonar;
    const double r = (q.p_world - ds.T_world_sonar(q.frame).translation()).norm();
    const double bound = std::hypot(0.5 * s.dr(), 0.5 * r * s.da()) + 1e-4;  // within the bin
    EXPECT_LT((p_world - q.p_world).norm(), bound)
        << "frame " << q.frame << " pixel (" << q.row << ", " << q.col << ")";
  }
  // Nothing else lit, and the values survive exactly.
  int lit = 0;
  for (std::size_t i = 0; i < ds.size(); ++i) {
    const SonarImage img = ds.load_frame(i);
    for (float v : img.data) {
      if (v > 0) {
        ++lit;
        EXPECT_NEAR(v / scale, std::round(v / scale), 1e-4);
      }
    }
  }
  EXPECT_EQ(lit, static_cast<int>(sc.size()));
}

}  // namespace

// ------------------------------------------------------------------------------ Config.json

TEST(HoloOceanConfig, ReadsTheImagingSonarOfAnAoneusStyleConfig) {
  const fs::path root = temp_dir("config");
  HoloSonar s;
  write_file(root / "Config.json", config_json(s));
  const HoloOceanSonar h = read_holoocean_config(root / "Config.json");
  EXPECT_EQ(h.agent_name, "auv0");
  EXPECT_EQ(h.sensor_name, "ImagingSonar");
  EXPECT_EQ(h.range_bins, 100);
  EXPECT_EQ(h.azimuth_bins, 64);
  EXPECT_DOUBLE_EQ(h.range_min, 0.5);
  EXPECT_DOUBLE_EQ(h.range_max, 4.5);
  EXPECT_DOUBLE_EQ(h.azimuth_deg, 60);
  EXPECT_DOUBLE_EQ(h.elevation_deg, 12);
  EXPECT_DOUBLE_EQ(h.rate_hz, 10);
  EXPECT_TRUE(h.warnings.empty()) << h.warnings.front();

  // A PoseSensor mounted elsewhere than the sonar is worth a warning.
  write_file(root / "Config.json", config_json(s, "", "[0, 0, 0]"));
  const HoloOceanSonar w = read_holoocean_config(root / "Config.json");
  ASSERT_EQ(w.warnings.size(), 1u);
  EXPECT_NE(w.warnings[0].find("not mounted like the ImagingSonar"), std::string::npos);
}

TEST(HoloOceanConfig, BadConfigsNameTheFileAndKey) {
  const fs::path root = temp_dir("config_bad");
  const fs::path cfg = root / "Config.json";
  expect_error([&] { read_holoocean_config(cfg); }, {"Config.json"});
  write_file(cfg, "{\"agents\": [");
  expect_error([&] { read_holoocean_config(cfg); }, {"Config.json", "malformed JSON"});
  HoloSonar s;
  std::string text = config_json(s);
  text.replace(text.find("\"RangeBins\""), 11, "\"RangeBinz\"");
  write_file(cfg, text);
  expect_error([&] { read_holoocean_config(cfg); }, {"Config.json", "'RangeBins' is missing"});
  text = config_json(s);
  text.replace(text.find("\"Azimuth\": 60"), 13, "\"Azimuth\": \"wide\"");
  write_file(cfg, text);
  expect_error([&] { read_holoocean_config(cfg); }, {"'Azimuth' must be a number"});
  // Two sonars: ambiguous unless one is named.
  const std::string second =
      R"({"sensor_type": "ImagingSonar", "sensor_name": "Side", "socket": "SonarSocket",
         "configuration": {"RangeBins": 10, "AzimuthBins": 8, "RangeMin": 1, "RangeMax": 2,
                           "Elevation": 1, "Azimuth": 20}},)";
  write_file(cfg, config_json(s, second));
  expect_error([&] { read_holoocean_config(cfg); }, {"several ImagingSonar", "--sensor"});
  EXPECT_EQ(read_holoocean_config(cfg, "Side").range_bins, 10);
  EXPECT_EQ(read_holoocean_config(cfg, "ImagingSonar").range_bins, 100);
  expect_error([&] { read_holoocean_config(cfg, "Nope"); }, {"no ImagingSonar named 'Nope'"});
}

// ------------------------------------------------------------------------------ the mapping

TEST(HoloOceanMapping, SampleConventionPutsRowAndColumnCentresOnTheirRangesAndAzimuths) {
  HoloOceanSonar h;
  h.sensor_name = "ImagingSonar";
  h.range_bins = 256;
  h.azimuth_bins = 96;
  h.range_min = 0.01;  // AONeuS: RangeMin 0.01, RangeMax 3.3
  h.range_max = 3.3;
  h.azimuth_deg = 60;
  h.elevation_deg = 12;
  const SonarSpec s = holoocean_sonar_spec(h, HoloOceanBins::Sample);
  const double dr = (h.range_max - h.range_min) / h.range_bins;
  for (int i : {0, 1, 100, 255}) EXPECT_NEAR(s.range_of_bin(i), h.range_min + i * dr, 1e-12);
  for (int j : {0, 1, 48, 95}) {
    EXPECT_NEAR(s.bearings_rad[j], (-30.0 + j * 60.0 / 96) * kDeg, 1e-12);
  }
  EXPECT_NEAR(s.vertical_aperture_rad, 12 * kDeg, 1e-12);
  EXPECT_EQ(s.beam_pattern.kind, BeamPattern::Kind::Flat);
  EXPECT_TRUE(s.T_vehicle_sonar.isApprox(Eigen::Isometry3d::Identity()));
  // A point at a pixel's own (range, azimuth) falls in that pixel under our binning.
  EXPECT_EQ(s.bin_of_range(h.range_min + 17 * dr), 17);
  EXPECT_EQ(s.beam_of_bearing((-30.0 + 40 * 60.0 / 96) * kDeg), 40);

  const SonarSpec c = holoocean_sonar_spec(h, HoloOceanBins::Cell);
  EXPECT_DOUBLE_EQ(c.r_min, h.range_min);
  EXPECT_DOUBLE_EQ(c.r_max, h.range_max);
  EXPECT_NEAR(c.bearings_rad[0], (-30.0 + 0.5 * 60.0 / 96) * kDeg, 1e-12);
  // HoloOcean bins by floor((r − RangeMin)/Δr): the cell edges are ours.
  EXPECT_EQ(c.bin_of_range(h.range_min + 17.99 * dr), 17);

  h.range_min = 0;  // row 0 at r = 0 cannot be a bin centre with r_min >= 0
  expect_error([&] { holoocean_sonar_spec(h, HoloOceanBins::Sample); }, {"--bins cell"});
  EXPECT_NO_THROW(holoocean_sonar_spec(h, HoloOceanBins::Cell));
}

TEST(HoloOceanMapping, SampleBearingTableSurvivesTheDatasetRoundTrip) {
  // The sample convention's bearing table is uniform but not centred on the boresight: sonar.yaml
  // must keep it as it is.
  HoloOceanSonar h;
  h.sensor_name = "ImagingSonar";
  h.range_bins = 20;
  h.azimuth_bins = 8;
  h.range_min = 1;
  h.range_max = 3;
  h.azimuth_deg = 40;
  h.elevation_deg = 10;
  const SonarSpec s = holoocean_sonar_spec(h, HoloOceanBins::Sample);
  const fs::path root = temp_dir("bearing_table");
  {
    DatasetWriter w(root / "ds", s, DatasetWriter::ImageFormat::Tiff);
    w.add_frame(SonarImage(20, 8));
    Trajectory nav;
    nav.push_back(0, Eigen::Isometry3d::Identity());
    w.set_navigation(nav);
    w.commit();
  }
  const Dataset ds = read_dataset(root / "ds");
  ASSERT_EQ(ds.spec.beams(), 8);
  for (int j = 0; j < 8; ++j) {
    EXPECT_NEAR(ds.spec.bearings_rad[j], s.bearings_rad[j], 1e-12) << "beam " << j;
  }
}

class HoloOceanScatterers
    : public ::testing::TestWithParam<std::tuple<HoloOceanBins, std::string>> {};

// A scatterer at a known world point, put in the pixel it lands in under THEIR convention, comes
// back to that point through OUR projector and the imported pose, within the bin size.
TEST_P(HoloOceanScatterers, PlacedPointsComeBackThroughOurProjector) {
  REQUIRE_NUMPY();
  const auto [bins, dtype] = GetParam();
  const std::string name = std::string(holoocean_bins_name(bins)) + "_" + dtype;
  const fs::path root = temp_dir("scatter_" + name);
  HoloSonar s;
  std::vector<HoloFrame> frames;
  const auto sc = place_scatterers(s, bins, 4, frames, 7);
  write_holoocean(root / "holo", s, frames, dtype);
  HoloOceanImportConfig cfg;
  cfg.bins = bins;
  const HoloOceanImportResult r = import_holoocean(root / "holo", root / "ds", cfg);
  EXPECT_EQ(r.frames, 4u);
  EXPECT_EQ(r.dtype, dtype);
  EXPECT_TRUE(r.warnings.empty());
  check_scatterers(root / "ds", s, sc, dtype == "uint8" ? 1.0f / 255.0f : 1.0f);
}

INSTANTIATE_TEST_SUITE_P(
    BothConventionsBothDtypes, HoloOceanScatterers,
    ::testing::Combine(::testing::Values(HoloOceanBins::Sample, HoloOceanBins::Cell),
                       ::testing::Values(std::string("uint8"), std::string("float32"))),
    [](const auto& info) {
      return std::string(holoocean_bins_name(std::get<0>(info.param))) + "_" +
             std::get<1>(info.param);
    });

TEST(HoloOceanImport, PixelAtItsOwnRangeAndAzimuthMapsBackExactly) {
  REQUIRE_NUMPY();
  // Under the sample convention a pixel (i, j) IS the point at RangeMin + iΔr, −A/2 + jΔa.
  const fs::path root = temp_dir("exact");
  HoloSonar s;
  HoloFrame f;
  f.pose = test_pose(2);
  f.image.assign(static_cast<std::size_t>(s.range_bins) * s.azimuth_bins, 0.0f);
  const int i = 37, j = 11;
  f.image[i * s.azimuth_bins + j] = 0.75f;
  write_holoocean(root / "holo", s, {f}, "float32");
  import_holoocean(root / "holo", root / "ds");
  const Dataset ds = read_dataset(root / "ds");
  const double r = s.range_min + i * s.dr();
  const double az = -0.5 * s.azimuth_deg * kDeg + j * s.da();
  for (double el : {-0.1, 0.0, 0.08}) {
    const Eigen::Vector3d theirs = their_point(f.pose, r, az, el);
    const Eigen::Vector3d ours =
        ds.T_world_sonar(0) *
        polar_to_sonar({ds.spec.range_of_bin(i), ds.spec.bearings_rad[j], el});
    EXPECT_LT((ours - theirs).norm(), 5e-5) << "elevation " << el;  // float32 pose storage
  }
  EXPECT_FLOAT_EQ(ds.load_frame(0).at(i, j), 0.75f);
}

TEST(HoloOceanImport, TimestampsFollowFileNumbersAndPosesAreExact) {
  REQUIRE_NUMPY();
  const fs::path root = temp_dir("times");
  HoloSonar s;
  std::vector<HoloFrame> frames;
  for (int n : {0, 1, 5, 12}) {
    HoloFrame f;
    f.number = n;
    f.pose = test_pose(n);
    f.image.assign(static_cast<std::size_t>(s.range_bins) * s.azimuth_bins, 0.5f);
    frames.push_back(f);
  }
  write_holoocean(root / "holo", s, frames, "float32");
  const auto r = import_holoocean(root / "holo", root / "ds");
  EXPECT_DOUBLE_EQ(r.frame_rate_hz, 10.0);
  const Dataset ds = read_dataset(root / "ds");
  ASSERT_EQ(ds.size(), 4u);
  const double expected_t[] = {0.0, 0.1, 0.5, 1.2};
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_NEAR(ds.frames[k].timestamp, expected_t[k], 1e-12);
    EXPECT_LT((ds.T_world_sonar(k).matrix() - frames[k].pose).cwiseAbs().maxCoeff(), 1e-5);
    EXPECT_TRUE(is_rigid(ds.T_world_sonar(k), 1e-9)) << "poses are re-orthonormalised";
  }
  // An explicit rate overrides the sensor's Hz.
  HoloOceanImportConfig cfg;
  cfg.frame_rate_hz = 2;
  import_holoocean(root / "holo", root / "ds2", cfg);
  EXPECT_NEAR(read_dataset(root / "ds2").frames[3].timestamp, 6.0, 1e-12);
}

// ------------------------------------------------------------------------------ bad input

class HoloOceanBadInput : public ::testing::Test {
 protected:
  // One good recording and its dataset, made once and copied into each test's directory.
  static void SetUpTestSuite() {
    if (!have_numpy()) return;
    const fs::path t = template_dir();
    fs::remove_all(t);
    std::vector<HoloFrame> frames;
    HoloSonar s;
    for (int n = 0; n < 3; ++n) {
      HoloFrame f;
      f.number = n;
      f.pose = test_pose(n);
      f.image.assign(static_cast<std::size_t>(s.range_bins) * s.azimuth_bins, 0.25f);
      frames.push_back(f);
    }
    write_holoocean(t / "holo", s, frames, "float32");
    import_holoocean(t / "holo", t / "ds");
  }
  static fs::path template_dir() { return run_root() / "bad_template"; }
  void SetUp() override {
    if (!have_numpy()) GTEST_SKIP() << "python3 with numpy is not available";
    root_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    // An older, complete dataset at the output must survive a failed import untouched.
    fs::copy(template_dir() / "holo", root_ / "holo", fs::copy_options::recursive);
    fs::copy(template_dir() / "ds", root_ / "ds", fs::copy_options::recursive);
    ASSERT_EQ(read_dataset(root_ / "ds").size(), 3u);
  }
  // Replaces Data/001.pkl by what `python` (a statement using np, pickle, f = the open file)
  // writes, then expects the import to fail naming that file and `needles`.
  void expect_bad_frame(const std::string& python, const std::vector<std::string>& needles) {
    const std::string script = "import numpy as np, pickle\nwith open('" +
                               (root_ / "holo/Data/001.pkl").string() + "', 'wb') as f:\n    " +
                               python + "\n";
    ASSERT_EQ(run_python(root_, script), 0) << python;
    expect_failure(needles);
  }
  void expect_failure(std::vector<std::string> needles, const HoloOceanImportConfig& cfg = {}) {
    needles.insert(needles.begin(), "001.pkl");
    expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds", cfg); }, needles);
    expect_intact();
  }
  void expect_intact() {
    const Dataset ds = read_dataset(root_ / "ds");
    EXPECT_EQ(ds.size(), 3u);
    for (const auto& e : fs::directory_iterator(root_)) {
      const std::string n = e.path().filename().string();
      EXPECT_TRUE(n == "holo" || n == "ds" || n == "bin" || n == "script.py" || n == "py.log")
          << "left behind: " << n;
    }
  }
  std::string img(const std::string& shape = "(100, 64)", const std::string& dtype = "np.float32") {
    return "np.zeros(" + shape + ", dtype=" + dtype + ")";
  }
  const std::string pose = "np.eye(4, dtype=np.float32)";
  HoloSonar s_;
  fs::path root_;
};

TEST_F(HoloOceanBadInput, TruncatedPickle) {
  const fs::path p = root_ / "holo/Data/001.pkl";
  fs::resize_file(p, fs::file_size(p) / 2);
  expect_failure({"truncated or corrupt"});
}

TEST_F(HoloOceanBadInput, CorruptPickle) {
  write_file(root_ / "holo/Data/001.pkl", "this is not a pickle at all \x01\x02\x03");
  expect_failure({"cannot unpickle"});
}

TEST_F(HoloOceanBadInput, EmptyPickle) {
  write_file(root_ / "holo/Data/001.pkl", "");
  expect_failure({"cannot unpickle"});
}

TEST_F(HoloOceanBadInput, NotADict) {
  expect_bad_frame("pickle.dump([1, 2, 3], f)", {"holds a list", "expected a dict"});
}

TEST_F(HoloOceanBadInput, MissingImageKey) {
  expect_bad_frame("pickle.dump({'PoseSensor': " + pose + "}, f)",
                   {"key 'ImagingSonar' is missing", "'PoseSensor'"});
}

TEST_F(HoloOceanBadInput, MissingPoseKey) {
  expect_bad_frame("pickle.dump({'ImagingSonar': " + img() + ", 'Pose': " + pose + "}, f)",
                   {"key 'PoseSensor' is missing"});
}

TEST_F(HoloOceanBadInput, ImageNotAnArray) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': [[0.0] * 64] * 100, 'PoseSensor': " + pose + "}, f)",
      {"'ImagingSonar' is a list", "numpy array"});
}

TEST_F(HoloOceanBadInput, WrongShape) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': " + img("(99, 64)") + ", 'PoseSensor': " + pose + "}, f)",
      {"99×64", "RangeBins 100 × AzimuthBins 64"});
}

TEST_F(HoloOceanBadInput, TransposedImage) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': " + img("(64, 100)") + ", 'PoseSensor': " + pose + "}, f)",
      {"64×100"});
}

TEST_F(HoloOceanBadInput, ThreeDimensionalImage) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': " + img("(100, 64, 3)") + ", 'PoseSensor': " + pose + "}, f)",
      {"3 dimensions"});
}

TEST_F(HoloOceanBadInput, WrongDtype) {
  expect_bad_frame("pickle.dump({'ImagingSonar': " + img("(100, 64)", "np.int16") +
                       ", 'PoseSensor': " + pose + "}, f)",
                   {"dtype int16", "uint8 or float32"});
}

TEST_F(HoloOceanBadInput, Float64IsNotAccepted) {
  expect_bad_frame("pickle.dump({'ImagingSonar': " + img("(100, 64)", "np.float64") +
                       ", 'PoseSensor': " + pose + "}, f)",
                   {"dtype float64"});
}

TEST_F(HoloOceanBadInput, MixedDtypes) {
  expect_bad_frame("pickle.dump({'ImagingSonar': " + img("(100, 64)", "np.uint8") +
                       ", 'PoseSensor': " + pose + "}, f)",
                   {"is uint8 but 000.pkl is float32"});
}

TEST_F(HoloOceanBadInput, NonFiniteIntensity) {
  expect_bad_frame("a = " + img() +
                       "; a[7, 3] = np.nan; pickle.dump({'ImagingSonar': a, "
                       "'PoseSensor': " +
                       pose + "}, f)",
                   {"non-finite intensity at row 7, column 3"});
}

TEST_F(HoloOceanBadInput, ScaledPoseIsNotRigid) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': " + img() + ", 'PoseSensor': 2 * " + pose + "}, f)",
      {"not a rigid transform"});
}

TEST_F(HoloOceanBadInput, ReflectionIsNotRigid) {
  expect_bad_frame("pickle.dump({'ImagingSonar': " + img() +
                       ", 'PoseSensor': np.diag([1, -1, 1, 1]).astype(np.float32)}, f)",
                   {"not a rigid transform", "det R = -1"});
}

TEST_F(HoloOceanBadInput, PoseBottomRowMustBe0001) {
  expect_bad_frame("p = " + pose + "; p[3, 0] = 0.5; pickle.dump({'ImagingSonar': " + img() +
                       ", 'PoseSensor': p}, f)",
                   {"not a rigid transform", "last row"});
}

TEST_F(HoloOceanBadInput, PoseOfWrongShape) {
  expect_bad_frame(
      "pickle.dump({'ImagingSonar': " + img() + ", 'PoseSensor': np.zeros((3, 4), np.float32)}, f)",
      {"'PoseSensor' is 3×4", "4×4"});
}

TEST_F(HoloOceanBadInput, NonFinitePose) {
  expect_bad_frame("p = " + pose + "; p[0, 3] = np.inf; pickle.dump({'ImagingSonar': " + img() +
                       ", 'PoseSensor': p}, f)",
                   {"non-finite"});
}

TEST_F(HoloOceanBadInput, PickleThatRunsCodeIsRefused) {
  const fs::path marker = root_ / "pwned";
  expect_bad_frame(
      "import os\n"
      "    class Evil:\n"
      "        def __reduce__(self): return (os.system, ('touch " +
          marker.string() +
          "',))\n"
          "    pickle.dump({'ImagingSonar': Evil(), 'PoseSensor': 0}, f)",
      {"not loaded", "system"});
  EXPECT_FALSE(fs::exists(marker)) << "the pickle ran code";
}

TEST_F(HoloOceanBadInput, BadFileNames) {
  write_file(root_ / "holo/Data/frame_a.pkl", "x");
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds"); },
               {"frame_a.pkl", "named by their number"});
  fs::remove(root_ / "holo/Data/frame_a.pkl");
  fs::copy_file(root_ / "holo/Data/001.pkl", root_ / "holo/Data/1.pkl");
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds"); }, {"repeats"});
  fs::remove(root_ / "holo/Data/1.pkl");
  for (const auto& e : fs::directory_iterator(root_ / "holo/Data")) fs::remove(e.path());
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds"); }, {"holds no .pkl"});
  fs::remove_all(root_ / "holo/Data");
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds"); }, {"Data", "missing"});
  expect_intact();
}

TEST_F(HoloOceanBadInput, MissingPythonOrNumpySaysSo) {
  HoloOceanImportConfig cfg;
  cfg.python = (root_ / "no_such_python").string();
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds", cfg); },
               {"cannot run the Python interpreter", "python3-numpy"});
  // An interpreter without numpy: Debian's python3 with its site directories disabled.
  const fs::path fake = root_ / "bin/python_without_numpy";
  write_file(fake, "#!/bin/sh\nexec " + pickle_python() + " -S \"$@\"\n");
  fs::permissions(fake, fs::perms::owner_all);
  cfg.python = fake.string();
  expect_error([&] { import_holoocean(root_ / "holo", root_ / "ds", cfg); },
               {"numpy cannot be imported", "python3-numpy"});
  expect_intact();
}

// ------------------------------------------------------------------------------ navigation

TEST(NavigationCsv, EnuIsOurWorldFrame) {
  const fs::path root = temp_dir("nav_enu");
  write_file(root / "nav.csv",
             "# a comment\nyaw,time,x,y,z,roll,pitch,extra\n"
             "30,0.0,1,2,3,10,-20,x\n"
             "40,1.0,2,2,3,10,-20,y\n");
  const Trajectory t = read_navigation_csv((root / "nav.csv").string(), {});
  ASSERT_EQ(t.size(), 2u);
  const Eigen::Isometry3d expected =
      yaml::pose_from_rpy(Eigen::Vector3d(1, 2, 3), 10 * kDeg, -20 * kDeg, 30 * kDeg);
  EXPECT_TRUE(t.poses[0].isApprox(expected, 1e-12));
  // Radians give the same poses.
  write_file(root / "rad.csv", "time,x,y,z,roll,pitch,yaw\n0,1,2,3," + std::to_string(10 * kDeg) +
                                   "," + std::to_string(-20 * kDeg) + "," +
                                   std::to_string(30 * kDeg) + "\n");
  NavCsvConfig rad;
  rad.angles = AngleUnit::Rad;
  EXPECT_TRUE(
      read_navigation_csv((root / "rad.csv").string(), rad).poses[0].isApprox(expected, 1e-6));
}

TEST(NavigationCsv, NedHeadingPitchRollMeanWhatTheySay) {
  const Eigen::Vector3d ned(1, 2, 3);  // 1 m north, 2 m east, 3 m down
  const Eigen::Isometry3d level_north = vehicle_pose_from_nav(ned, 0, 0, 0, NavConvention::Ned);
  EXPECT_TRUE(level_north.translation().isApprox(Eigen::Vector3d(2, 1, -3)));  // east, north, up
  EXPECT_TRUE(is_rigid(level_north));
  EXPECT_TRUE((level_north.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()))
      << "heading 0 looks north (+y)";
  EXPECT_TRUE((level_north.linear() * Eigen::Vector3d::UnitY()).isApprox(-Eigen::Vector3d::UnitX()))
      << "facing north, left is west";
  const Eigen::Isometry3d east = vehicle_pose_from_nav(ned, 0, 0, 90 * kDeg, NavConvention::Ned);
  EXPECT_TRUE((east.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitX(), 1e-12))
      << "heading 90° (clockwise from north) looks east (+x)";
  const Eigen::Isometry3d up = vehicle_pose_from_nav(ned, 0, 10 * kDeg, 0, NavConvention::Ned);
  EXPECT_NEAR((up.linear() * Eigen::Vector3d::UnitX()).z(), std::sin(10 * kDeg), 1e-12)
      << "positive pitch is nose up";
  const Eigen::Isometry3d roll = vehicle_pose_from_nav(ned, 10 * kDeg, 0, 0, NavConvention::Ned);
  EXPECT_NEAR((roll.linear() * -Eigen::Vector3d::UnitY()).z(), -std::sin(10 * kDeg), 1e-12)
      << "positive roll puts starboard down";
  EXPECT_TRUE((roll.linear() * Eigen::Vector3d::UnitZ()).z() > 0.98) << "z stays up";
}

TEST(NavigationCsv, BadFilesNameFileAndLine) {
  const fs::path root = temp_dir("nav_bad");
  const std::string p = (root / "nav.csv").string();
  write_file(p, "time,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n2,0,0,0,0,0,0\n1,0,0,0,0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:4", "must increase"});
  write_file(p, "time,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:3"});
  write_file(p, "time,x,y,z,roll,pitch\n0,0,0,0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:1", "yaw"});
  write_file(p, "time,x,y,z,roll,pitch,yaw\n0,0,zero,0,0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:2", "y 'zero'"});
  write_file(p, "time,x,y,z,roll,pitch,yaw\n0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:2", "fields"});
  write_file(p, "time,x,y,z,roll,pitch,yaw\n0,nan,0,0,0,0,0\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"nav.csv:2", "not finite"});
  write_file(p, "time,x,y,z,roll,pitch,yaw\n");
  expect_error([&] { read_navigation_csv(p, {}); }, {"no sample"});
  expect_error([&] { read_navigation((root / "nav.bin").string()); }, {"extension"});
  expect_error([&] { parse_nav_convention("nwu"); }, {"enu or ned", "'nwu'"});
}

// ------------------------------------------------------------------------------ frames import

namespace {

SonarSpec frames_spec() {
  SonarSpec s;
  s.name = "logged";
  s.set_uniform_bearings(40 * kDeg, 24);
  s.r_min = 0.5;
  s.r_max = 3.5;
  s.range_bins = 30;
  s.vertical_aperture_rad = 14 * kDeg;
  s.bit_depth = 8;
  s.intensity_scale = 1.0 / 255;
  s.T_vehicle_sonar = yaml::pose_from_rpy(Eigen::Vector3d(0.5, 0, -0.2), 0, 30 * kDeg, 0);
  return s;
}

// Five 8-bit frames at t = 1.0, 1.5, ... 3.0 on their clock, and an NED navigation log 0–10 s.
struct FramesFixture {
  fs::path root;
  SonarSpec spec = frames_spec();
  std::vector<SonarImage> images;
  explicit FramesFixture(const std::string& name) : root(temp_dir(name)) {
    std::ostringstream times;
    times << "timestamp,file\n";
    std::mt19937 rng(3);
    std::uniform_int_distribution<int> u(0, 255);
    for (int k = 0; k < 5; ++k) {
      SonarImage img(spec.range_bins, spec.beams());
      for (auto& v : img.data) v = u(rng) / 255.0f;
      const std::string file = "img" + std::to_string(k) + ".png";
      fs::create_directories(root / "images");
      write_sonar_image((root / "images" / file).string(), img, spec);
      images.push_back(img);
      times << 1.0 + 0.5 * k << "," << file << "\n";
    }
    write_file(root / "times.csv", times.str());
    std::ostringstream nav;
    nav << "time,x,y,z,roll,pitch,yaw\n";
    for (int k = 0; k <= 10; ++k) {
      nav << k << "," << 10 + k << "," << -5 + 0.5 * k << "," << 20 << "," << 2 * k << "," << -k
          << "," << 10 * k << "\n";
    }
    write_file(root / "nav.csv", nav.str());
    write_file(root / "sonar.yaml", sonar_spec_to_yaml(spec));
  }
  FrameImportConfig config() const {
    FrameImportConfig c;
    c.images_dir = root / "images";
    c.times_csv = root / "times.csv";
    c.navigation = root / "nav.csv";
    c.navigation_csv.convention = NavConvention::Ned;
    c.spec = read_sonar_description((root / "sonar.yaml").string());
    return c;
  }
};

}  // namespace

TEST(FramesImport, PosesAreInterpolatedNavigationTimesMounting) {
  FramesFixture fx("frames");
  FrameImportConfig cfg = fx.config();
  cfg.time_offset = 0.25;
  const FrameImportResult r = import_frames(cfg, fx.root / "ds");
  EXPECT_EQ(r.frames, 5u);
  EXPECT_EQ(r.dropped, 0u);
  EXPECT_EQ(r.navigation_samples, 11u);
  const Dataset ds = read_dataset(fx.root / "ds");
  ASSERT_EQ(ds.size(), 5u);
  const Trajectory nav = read_navigation_csv(cfg.navigation, cfg.navigation_csv);
  for (int k = 0; k < 5; ++k) {
    const double t = 1.0 + 0.5 * k + 0.25;
    EXPECT_NEAR(ds.frames[k].timestamp, t, 1e-12);
    const Eigen::Isometry3d expected = nav.interpolate(t) * fx.spec.T_vehicle_sonar;
    EXPECT_TRUE(ds.T_world_sonar(k).isApprox(expected, 1e-9)) << "frame " << k;
    const SonarImage img = ds.load_frame(k);
    for (std::size_t i = 0; i < img.data.size(); ++i) {
      ASSERT_FLOAT_EQ(img.data[i], fx.images[k].data[i]);
    }
  }
  // Between samples the position is linear: frame 0 at t = 1.25 s sits a quarter of the way
  // from the 1 s sample to the 2 s one (north 11.25 → world y, east -4.875 → world x).
  const Eigen::Vector3d p_vehicle = nav.interpolate(1.25).translation();
  EXPECT_NEAR(p_vehicle.x(), -4.5 + 0.125, 1e-12);
  EXPECT_NEAR(p_vehicle.y(), 11.25, 1e-12);
  EXPECT_NEAR(p_vehicle.z(), -20, 1e-12);
}

TEST(FramesImport, TumNavigationWorksToo) {
  FramesFixture fx("frames_tum");
  Trajectory nav;
  for (int k = 0; k <= 4; ++k) {
    nav.push_back(k, yaml::pose_from_rpy(Eigen::Vector3d(k, 0, -1), 0, 0, 0.1 * k));
  }
  write_tum((fx.root / "nav.tum").string(), nav);
  FrameImportConfig cfg = fx.config();
  cfg.navigation = fx.root / "nav.tum";
  import_frames(cfg, fx.root / "ds");
  const Dataset ds = read_dataset(fx.root / "ds");
  EXPECT_TRUE(ds.T_world_sonar(2).isApprox(nav.interpolate(2.0) * fx.spec.T_vehicle_sonar, 1e-9));
}

TEST(FramesImport, FramesOutsideTheNavigationSpanFailOrAreDroppedAndCounted) {
  FramesFixture fx("frames_span");
  FrameImportConfig cfg = fx.config();
  cfg.time_offset = 7.75;  // frames at 8.75 ... 10.75 s: the last two after the navigation's 10 s
  expect_error(
      [&] { import_frames(cfg, fx.root / "ds"); },
      {"times.csv:5", "img3.png", "outside the navigation span [0, 10]", "--drop-outside"});
  EXPECT_FALSE(fs::exists(fx.root / "ds"));
  cfg.drop_outside = true;
  const FrameImportResult r = import_frames(cfg, fx.root / "ds");
  EXPECT_EQ(r.frames, 3u);
  EXPECT_EQ(r.dropped, 2u);
  EXPECT_EQ(read_dataset(fx.root / "ds").size(), 3u);
  cfg.time_offset = 100;
  expect_error([&] { import_frames(cfg, fx.root / "ds2"); }, {"no frame", "navigation span"});
  EXPECT_FALSE(fs::exists(fx.root / "ds2"));
}

TEST(FramesImport, BadInputsNameTheFileAndLeaveNothing) {
  FramesFixture fx("frames_bad");
  FrameImportConfig cfg = fx.config();
  write_file(fx.root / "times.csv", "timestamp,file\n1.0,img0.png\n2.0,img1.png\n1.5,img2.png\n");
  expect_error([&] { import_frames(cfg, fx.root / "ds"); }, {"times.csv:4", "goes backwards"});
  write_file(fx.root / "times.csv", "time,name\n1.0,img0.png\n");
  expect_error([&] { import_frames(cfg, fx.root / "ds"); }, {"times.csv:1", "timestamp,file"});
  write_file(fx.root / "times.csv", "timestamp,file\n1.0,img0.png\n2.0,missing.png\n");
  expect_error([&] { import_frames(cfg, fx.root / "ds"); }, {"missing.png", "does not exist"});
  SonarSpec other = fx.spec;
  other.range_bins = 31;
  write_sonar_image((fx.root / "images/img1.png").string(), SonarImage(31, 24), other);
  write_file(fx.root / "times.csv", "timestamp,file\n1.0,img0.png\n2.0,img1.png\n");
  expect_error([&] { import_frames(cfg, fx.root / "ds"); }, {"img1.png", "31×24"});
  write_file(fx.root / "nav.csv",
             "time,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n5,0,0,0,0,0,0\n4,0,0,0,0,0,0\n");
  expect_error([&] { import_frames(cfg, fx.root / "ds"); }, {"nav.csv:4"});
  EXPECT_FALSE(fs::exists(fx.root / "ds"));
  write_file(fx.root / "sonar.yaml",
             "sensor:\n  fov_deg: 30\n  beams: 10\n  r_min: 2\n  r_max: 1\n");
  expect_error([&] { read_sonar_description((fx.root / "sonar.yaml").string()); },
               {"sonar.yaml", "r_max"});
}

// ------------------------------------------------------------------------------ round trip

namespace {

// Our simulator's images of a sphere written as a HoloOcean recording (the reverse of the
// importer: float32 images, PoseSensor = T_world_sonar) with a Config.json describing `spec`.
void write_simulated_holoocean(const fs::path& dir, const SonarSpec& spec,
                               const std::vector<SonarImage>& images,
                               const std::vector<Eigen::Isometry3d>& poses, double hz) {
  HoloSonar s;
  s.range_bins = spec.range_bins;
  s.azimuth_bins = spec.beams();
  s.range_min = spec.r_min;
  s.range_max = spec.r_max;
  s.azimuth_deg = (spec.fov_max() - spec.fov_min()) / kDeg;
  s.elevation_deg = spec.vertical_aperture_rad / kDeg;
  s.hz = hz;
  std::vector<HoloFrame> frames;
  for (std::size_t k = 0; k < images.size(); ++k) {
    HoloFrame f;
    f.number = static_cast<int>(k);
    f.image = images[k].data;
    f.pose = poses[k].matrix();
    frames.push_back(f);
  }
  write_holoocean(dir, s, frames, "float32");
}

// Our simulator's view of a 1 m sphere from a vertical pass 2 m away (`frames` frames, `step`
// apart, centred on the sphere), written to `dir` as a HoloOcean recording.
struct SphereRecording {
  SonarSpec spec;
  std::vector<SonarImage> images;
  std::vector<Eigen::Isometry3d> poses;
};

SphereRecording make_sphere_recording(const fs::path& dir, int frames, double step) {
  SphereRecording rec;
  SonarSpec& spec = rec.spec;
  spec.name = "sim";
  spec.set_uniform_bearings(30 * kDeg, 48);
  spec.r_min = 1.0;
  spec.r_max = 3.0;
  spec.range_bins = 80;
  spec.vertical_aperture_rad = 10 * kDeg;
  spec.beam_pattern.kind = BeamPattern::Kind::Flat;  // HoloOcean has no vertical beam pattern
  Scene scene;
  scene.objects.push_back({"sphere", make_sphere(0.5, 48), 0.8});
  SimulatorConfig sim_cfg;
  sim_cfg.elevation_step_rad = 0.05 * kDeg;
  const Simulator sim(scene, spec, sim_cfg);
  for (int k = 0; k < frames; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(-2.0, 0.0, (k - 0.5 * (frames - 1)) * step);
    rec.poses.push_back(T);
    rec.images.push_back(sim.render(T, 1 + k));
  }
  write_simulated_holoocean(dir, spec, rec.images, rec.poses, 10);
  return rec;
}

}  // namespace

TEST(HoloOceanRoundTrip, SimulatedSphereSurvivesExportAndImport) {
  REQUIRE_NUMPY();
  const fs::path root = temp_dir("roundtrip");
  const SphereRecording rec = make_sphere_recording(root / "holo", 6, 0.1);
  const SonarSpec& spec = rec.spec;
  const auto& images = rec.images;
  const auto& poses = rec.poses;
  float peak = 0;
  for (const auto& im : images)
    for (float v : im.data) peak = std::max(peak, v);
  ASSERT_GT(peak, 0.0f) << "the sphere must be seen";

  HoloOceanImportConfig cfg;
  cfg.bins = HoloOceanBins::Cell;  // our centred bins are HoloOcean's cells
  import_holoocean(root / "holo", root / "ds", cfg);
  const Dataset ds = read_dataset(root / "ds");
  ASSERT_EQ(ds.size(), images.size());
  EXPECT_EQ(ds.spec.range_bins, spec.range_bins);
  ASSERT_EQ(ds.spec.beams(), spec.beams());
  for (int j = 0; j < spec.beams(); ++j) {
    EXPECT_NEAR(ds.spec.bearings_rad[j], spec.bearings_rad[j], 1e-9);
  }
  EXPECT_NEAR(ds.spec.r_min, spec.r_min, 1e-12);
  EXPECT_NEAR(ds.spec.r_max, spec.r_max, 1e-12);
  EXPECT_NEAR(ds.spec.vertical_aperture_rad, spec.vertical_aperture_rad, 1e-12);
  for (std::size_t k = 0; k < images.size(); ++k) {
    const SonarImage img = ds.load_frame(k);
    for (std::size_t i = 0; i < img.data.size(); ++i) ASSERT_EQ(img.data[i], images[k].data[i]);
    EXPECT_TRUE(ds.T_world_sonar(k).isApprox(poses[k], 1e-6));
  }
}

// ------------------------------------------------------------------------------ the CLI

TEST(ImportCli, HoloOceanAndFramesCommands) {
  REQUIRE_NUMPY();
  const fs::path root = temp_dir("cli");
  HoloSonar s;
  std::vector<HoloFrame> frames;
  place_scatterers(s, HoloOceanBins::Sample, 3, frames, 11);
  write_holoocean(root / "holo", s, frames, "uint8");
  const fs::path log = root / "log.txt";
  ASSERT_EQ(run_cli_log("import holoocean " + (root / "holo").string() + " -o " +
                            (root / "ds").string() + " -q",
                        log),
            0)
      << read_all(log);
  EXPECT_NE(read_all(log).find("imported 3 frames (uint8, 100×64, sample bins)"), std::string::npos)
      << read_all(log);
  EXPECT_EQ(read_dataset(root / "ds").size(), 3u);

  // A bad frame: one clear line, non-zero exit, no dataset.
  fs::resize_file(root / "holo/Data/002.pkl", 40);
  EXPECT_EQ(
      run_cli_log("import holoocean " + (root / "holo").string() + " -o " + (root / "ds2").string(),
                  log),
      1);
  EXPECT_NE(read_all(log).find("sonar3d: error: " + (root / "holo/Data/002.pkl").string()),
            std::string::npos)
      << read_all(log);
  EXPECT_FALSE(fs::exists(root / "ds2"));

  FramesFixture fx("cli_frames");
  const std::string args =
      "import frames --images " + (fx.root / "images").string() + " --times " +
      (fx.root / "times.csv").string() + " --nav " + (fx.root / "nav.csv").string() +
      " --nav-convention ned --angles deg --sonar " + (fx.root / "sonar.yaml").string() + " -o " +
      (fx.root / "ds").string() + " --time-offset 7.75 -q";
  EXPECT_EQ(run_cli_log(args, log), 1);
  EXPECT_NE(read_all(log).find("outside the navigation span"), std::string::npos) << read_all(log);
  ASSERT_EQ(run_cli_log(args + " --drop-outside", log), 0) << read_all(log);
  EXPECT_NE(read_all(log).find("imported 3 frames"), std::string::npos) << read_all(log);
  EXPECT_NE(read_all(log).find("dropped 2 outside the navigation span"), std::string::npos);
}

TEST(ImportCli, ReconstructRunsOnAnImportedRecording) {
  REQUIRE_NUMPY();
  // The same frames reconstructed from the imported recording and from a dataset written
  // directly: the import must not change what the reconstruction sees.
  const fs::path root = temp_dir("cli_reconstruct");
  const SphereRecording rec = make_sphere_recording(root / "holo", 61, 0.02);
  {
    DatasetWriter w(root / "direct", rec.spec, DatasetWriter::ImageFormat::Tiff);
    Trajectory nav;
    for (std::size_t k = 0; k < rec.images.size(); ++k) {
      SonarImage img = rec.images[k];
      img.timestamp = 0.1 * k;
      w.add_frame(img);
      nav.push_back(img.timestamp, rec.poses[k]);
    }
    w.set_navigation(nav);
    w.commit();
  }
  const fs::path log = root / "log.txt";
  ASSERT_EQ(run_cli_log("import holoocean " + (root / "holo").string() + " --bins cell -o " +
                            (root / "imported").string() + " -q",
                        log),
            0)
      << read_all(log);
  const MeshDistance truth(make_sphere(0.5, 48));
  double median[2];
  std::size_t points[2];
  int k = 0;
  for (const char* name : {"imported", "direct"}) {
    const fs::path ply = root / (std::string(name) + ".ply");
    ASSERT_EQ(run_cli_log("reconstruct " + (root / name).string() + " --voxel-size 0.02 -o " +
                              ply.string() + " -q",
                          log),
              0)
        << read_all(log);
    const PointCloud cloud = read_ply(ply.string());
    std::vector<double> d = truth.distances(cloud.points);
    ASSERT_GT(d.size(), 100u);
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    median[k] = d[d.size() / 2];
    points[k++] = cloud.size();
    std::printf("%s: %zu points, median distance to the sphere %.4f m\n", name, cloud.size(),
                d[d.size() / 2]);
  }
  EXPECT_LT(median[0], 0.05) << "within two range bins of the sphere";
  EXPECT_NEAR(median[0], median[1], 1e-3);
  EXPECT_NEAR(static_cast<double>(points[0]), static_cast<double>(points[1]), 0.01 * points[1]);
}
