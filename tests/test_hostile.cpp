// Hostile inputs (issue 10, item 7): malformed or tiny-but-huge files and configurations must
// fail with one line naming the file or key, never crash, loop or exhaust memory. Each test here
// reproduces an input found by fuzzing the tree before the fix.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/yaml_config.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/sim/trajectory_gen.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;
namespace fs = std::filesystem;

namespace {

void write_file(const fs::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}

// Expects f() to throw sonar3d::Error whose message contains every needle and is one line.
void expect_one_line_error(const std::function<void()>& f,
                           std::initializer_list<std::string> needles) {
  try {
    f();
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    for (const auto& n : needles) EXPECT_NE(m.find(n), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not a sonar3d::Error: " << e.what();
  }
}

// A scene with one sphere and the given trajectory block.
std::string scene_yaml(const std::string& trajectory, const std::string& sensor_extra = "") {
  return "sensor:\n  preset: sim-10deg\n" + sensor_extra +
         "objects:\n  - name: ball\n    primitive: {type: sphere, radius: 0.5}\n"
         "trajectory:\n" +
         trajectory;
}

SonarSpec small_spec() { return sonar3d::test::small_dataset_spec(); }

// A dataset of `frames` frames (1 s apart from t = 10 s).
void write_small(const fs::path& dir, const SonarSpec& s, int frames = 3) {
  DatasetWriter w(dir, s);
  Trajectory nav;
  for (int k = 0; k < frames; ++k) {
    SonarImage img(s.range_bins, s.beams(), 0.25f);
    img.timestamp = 10.0 + k;
    w.add_frame(img);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(k, 0, 0);
    nav.push_back(10.0 + k, T);
  }
  w.set_navigation(nav);
  w.commit();
}

std::string read_text(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}

void replace_in_file(const fs::path& p, const std::string& from, const std::string& to) {
  std::string s = read_text(p);
  const auto pos = s.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  s.replace(pos, from.size(), to);
  write_file(p, s);
}

std::string binary_ply_header(const std::string& count, const std::string& props) {
  return "ply\nformat binary_little_endian 1.0\nelement vertex " + count + "\n" + props +
         "end_header\n";
}

std::string floats(std::initializer_list<float> v) {
  std::string s(v.size() * 4, '\0');
  std::memcpy(s.data(), v.begin(), s.size());
  return s;
}

const char* kXyz = "property float x\nproperty float y\nproperty float z\n";

}  // namespace

// ------------------------------------------------------------------------------ meshes

TEST(HostileMesh, FaceIndexOutOfRangeIsAnErrorNotACrash) {
  const fs::path d = temp_dir("mesh");
  const fs::path p = d / "bad.ply";
  write_file(p,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 100000000\n");
  expect_one_line_error([&] { load_mesh(p.string()); }, {"bad.ply"});
  // A valid one still loads.
  write_file(p,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(load_mesh(p.string()).triangles.size(), 1u);
}

// ------------------------------------------------------------------------------ PLY point clouds

TEST(HostilePly, HugeVertexCountIsCheckedAgainstTheFileSize) {
  const fs::path p = temp_dir("plyhuge") / "c.ply";
  write_file(p, binary_ply_header("1000000000", kXyz) + std::string(5700, '\0'));
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply", "1000000000 vertices"});
}

TEST(HostilePly, CountsMustBeWholeNumbers) {
  const fs::path p = temp_dir("plycount") / "c.ply";
  for (const std::string bad : {"1e309", ".inf", "-1", "1.5", "0x10", "99999999999999999999"}) {
    write_file(p, binary_ply_header(bad, kXyz) + floats({1, 2, 3}));
    expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply:3", "count"});
  }
}

TEST(HostilePly, TrailingDataAndRetypedPropertiesAreRejected) {
  const fs::path p = temp_dir("plytrail") / "c.ply";
  write_file(p, binary_ply_header("1", kXyz) + floats({1, 2, 3}));
  EXPECT_EQ(read_ply(p.string()).size(), 1u);
  write_file(p, binary_ply_header("1", kXyz) + floats({1, 2, 3, 4}));
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply", "unexpected data"});
  // "float z" retyped "double z": the data no longer fill the file exactly.
  write_file(p, binary_ply_header("2", "property float x\nproperty float y\nproperty double z\n") +
                    floats({1, 2, 3, 4, 5, 6}));
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply"});
  // Non-finite values, binary and ascii.
  write_file(p, binary_ply_header("1", kXyz + std::string("property float intensity\n")) +
                    floats({1, 2, 3, std::numeric_limits<float>::infinity()}));
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply", "not finite"});
  write_file(
      p, "ply\nformat ascii 1.0\nelement vertex 1\n" + std::string(kXyz) + "end_header\n1 nan 3\n");
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply", "not a finite number"});
  write_file(p, "ply\nformat ascii 1.0\nelement vertex 1\n" + std::string(kXyz) +
                    "end_header\n1 1e309 3\n");
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply"});
  // A face element after the vertices is walked, and must end the file exactly.
  const std::string face_hdr =
      "property float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\n";
  std::string face(1, '\3');
  face += std::string(12, '\0');
  write_file(p, binary_ply_header("3", face_hdr) + floats({0, 0, 0, 1, 0, 0, 0, 1, 0}) + face);
  EXPECT_EQ(read_ply(p.string()).size(), 3u);
  write_file(p,
             binary_ply_header("3", face_hdr) + floats({0, 0, 0, 1, 0, 0, 0, 1, 0}) + face + "x");
  expect_one_line_error([&] { read_ply(p.string()); }, {"c.ply", "unexpected data"});
}

TEST(HostilePly, OwnOutputStillReads) {
  const fs::path d = temp_dir("plyown");
  PointCloud c;
  c.points = {Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(4, 5, 6)};
  c.intensity = {0.5f, 0.25f};
  write_ply((d / "b.ply").string(), c, PlyFormat::Binary);
  write_ply((d / "a.ply").string(), c, PlyFormat::Ascii);
  for (const char* n : {"a.ply", "b.ply"}) {
    const PointCloud r = read_ply((d / n).string());
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r.points[1], c.points[1]);
    EXPECT_EQ(r.intensity[1], 0.25f);
  }
}

// ------------------------------------------------------------------------------ scene YAML

TEST(HostileScene, TinySpacingsFailWithTheKeyNotASegfault) {
  const fs::path d = temp_dir("spacing");
  const fs::path p = d / "scene.yaml";
  write_file(p, scene_yaml("  type: straight\n  start: [-3, 0, -5e9]\n  end: [-3, 0, 5e9]\n"
                           "  spacing: 1e-10\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); },
                        {"scene.yaml", "trajectory", "spacing"});
  write_file(p, scene_yaml("  type: straight\n  start: [-3, 0, 0]\n  end: [-3, 0, 1]\n"
                           "  spacing: 1e-10\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "spacing"});
  write_file(p, scene_yaml("  type: lawnmower\n  x: [-1, 1]\n  y: [-1, 1]\n  z: 2\n"
                           "  line_spacing: 1e-300\n  spacing: 0.5\n"));
  const auto t0 = std::chrono::steady_clock::now();
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "line_spacing"});
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  write_file(p, scene_yaml("  type: lawnmower\n  x: [-1, 1]\n  y: [-1, 1]\n  z: 2\n"
                           "  line_spacing: 0.5\n  spacing: 1e-10\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "spacing"});
  write_file(p, scene_yaml("  type: orbit\n  center: [0, 0, 0]\n  radius: 3\n"
                           "  count: 1000000000\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "count"});
}

TEST(HostileScene, SensorLimits) {
  const fs::path d = temp_dir("sensor");
  const fs::path p = d / "scene.yaml";
  const std::string orbit = "  type: orbit\n  center: [0, 0, 0]\n  radius: 3\n  count: 4\n";
  write_file(p, scene_yaml(orbit, "  r_max: 1e308\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "r_max"});
  write_file(p, scene_yaml(orbit, "  vertical_aperture_deg: 1e-300\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); },
                        {"scene.yaml", "vertical_aperture_deg"});
  write_file(p, scene_yaml(orbit, "  fov_deg: 60\n  beams: 2000000000\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "beams"});
  write_file(p, scene_yaml(orbit, "  range_bins: 2000000000\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "range_bins"});
  write_file(p, scene_yaml(orbit, "  fov_deg: 60\n  beams: 16000\n  range_bins: 60000\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "pixels"});
}

TEST(HostileScene, FarAwayPositionsAreRejectedBeforeEmbree) {
  const fs::path d = temp_dir("far");
  const fs::path p = d / "scene.yaml";
  write_file(p, scene_yaml("  type: straight\n  start: [1e19, 0, 0]\n  end: [1e19, 0, 1]\n"
                           "  spacing: 0.5\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); }, {"scene.yaml", "1e7 m"});
  Scene scene;
  SceneObject o;
  o.name = "far";
  o.mesh_world.vertices = {Eigen::Vector3f(1e19f, 0, 0), Eigen::Vector3f(1e19f, 1, 0),
                           Eigen::Vector3f(1e19f, 0, 1)};
  o.mesh_world.triangles = {Eigen::Vector3i(0, 1, 2)};
  scene.objects.push_back(o);
  SonarSpec s = small_spec();
  expect_one_line_error([&] { Simulator sim(scene, s, SimulatorConfig{}); }, {"far", "1e7 m"});
  scene.objects[0].mesh_world.vertices = {Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(1, 1, 0),
                                          Eigen::Vector3f(1, 0, 1)};
  Simulator sim(scene, s, SimulatorConfig{});
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = 1e19;
  expect_one_line_error([&] { sim.render(T, 1); }, {"1e7 m"});
}

TEST(HostileYaml, DuplicateKeysAndDoublePosesAreRejected) {
  const fs::path d = temp_dir("dupkey");
  const fs::path p = d / "scene.yaml";
  write_file(p, scene_yaml("  type: orbit\n  center: [0, 0, 0]\n  radius: 3\n  count: 4\n"
                           "  radius: 5\n"));
  expect_one_line_error([&] { load_simulation_setup(p.string()); },
                        {"scene.yaml:11", "duplicate key 'radius'", "line 9"});
  write_file(p,
             "sensor:\n  preset: sim-10deg\n"
             "objects:\n  - name: ball\n    primitive: {type: sphere, radius: 0.5}\n"
             "    pose: {translation: [0, 0, 0], rpy_deg: [0, 0, 90],"
             " quaternion: [0, 0, 0, 1]}\n"
             "trajectory:\n  type: orbit\n  center: [0, 0, 0]\n  radius: 3\n  count: 4\n");
  expect_one_line_error([&] { load_simulation_setup(p.string()); },
                        {"scene.yaml:6", "rpy_deg", "quaternion"});
  // Aliases are visited once: a "billion laughs" document is cheap to check.
  std::string laughs = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (char c = 'b'; c <= 'k'; ++c) {
    laughs += std::string(1, c) + ": &" + c + " [";
    for (int k = 0; k < 10; ++k) laughs += std::string(k ? ", " : "") + "*" + char(c - 1);
    laughs += "]\n";
  }
  write_file(p, laughs);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NO_THROW(yaml::load_file(p.string()));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
}

// ------------------------------------------------------------------------------ datasets

TEST(HostileDataset, EightBitFrameInASixteenBitDataset) {
  const fs::path d = temp_dir("bits");
  SonarSpec s = small_spec();
  write_small(d / "ds", s);
  SonarSpec s8 = s;
  s8.bit_depth = 8;
  s8.intensity_scale = 1.0 / 255;
  write_sonar_image((d / "ds/frames/000001.png").string(), SonarImage(40, 16, 0.5f), s8);
  const Dataset ds = read_dataset(d / "ds");
  EXPECT_NO_THROW(ds.load_frame(0));
  expect_one_line_error([&] { ds.load_frame(1); }, {"000001.png", "8-bit", "bit_depth 16"});
}

TEST(HostileDataset, DuplicateFrameIndices) {
  const fs::path d = temp_dir("dupidx");
  write_small(d / "ds", small_spec());
  replace_in_file(d / "ds/frames.csv", "\n1,", "\n0,");
  expect_one_line_error([&] { read_dataset(d / "ds"); }, {"frames.csv:3", "index 0", "line 2"});
}

TEST(HostileDataset, CorruptPngIsOneQuietLine) {
  const fs::path d = temp_dir("png");
  write_small(d / "ds", small_spec());
  const fs::path f = d / "ds/frames/000001.png";
  std::string png = read_text(f);
  png[png.size() / 2] ^= 0x5A;  // inside the image data: a CRC error
  write_file(f, png);
  const Dataset ds = read_dataset(d / "ds");
  testing::internal::CaptureStderr();
  expect_one_line_error([&] { ds.load_frame(1); }, {"000001.png", "corrupt PNG"});
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  // A PNG header claiming a huge image is refused before decoding.
  std::string big = read_text(d / "ds/frames/000000.png");
  big[16] = 0x7F;  // width 0x7Fxxxxxx (the CRC check comes first)
  write_file(f, big);
  expect_one_line_error([&] { ds.load_frame(1); }, {"000001.png"});
}

// ------------------------------------------------------------------------------ carving

TEST(HostileCarve, VoxelSizeLimits) {
  const SonarSpec s = small_spec();
  CarveConfig c;
  c.voxel_size = 1e-300;
  expect_one_line_error([&] { Carver k(s, c); }, {"carve.voxel_size"});
  c.voxel_size = 1e-4;  // 2.5 m range: ~3e6 cubes of 32³ voxels for one frame
  Carver k(s, c);
  SonarImage img(s.range_bins, s.beams(), 0.0f);
  expect_one_line_error([&] { k.integrate(img, Eigen::Isometry3d::Identity()); },
                        {"carve.voxel_size", "--roi"});
}

TEST(HostileCarve, MissingMiddleFrameFailsCleanly) {
  // Under LeakSanitizer this leaked the pipeline's in-flight items before the fix.
  const fs::path d = temp_dir("carvemiss");
  write_small(d / "ds", small_spec(), 24);
  fs::remove(d / "ds/frames/000011.png");
  const Dataset ds = read_dataset(d / "ds");
  CarveConfig c;
  c.voxel_size = 0.05;
  c.num_threads = 2;
  Carver k(ds.spec, c);
  expect_one_line_error([&] { integrate_dataset(k, ds, false); }, {"000011.png"});
}

// ------------------------------------------------------------------------------ HoloOcean

namespace {
const char* kHoloConfig = R"({"agents": [{"agent_name": "auv0", "sensors": [
  {"sensor_type": "PoseSensor"},
  {"sensor_type": "ImagingSonar", "Hz": 10, "configuration": {"RangeBins": 4,
   "AzimuthBins": 4, "RangeMin": 0.5, "RangeMax": 4.5, "Azimuth": 60, "Elevation": 12}}]}]})";

bool have_numpy() {
  return std::system((pickle_python() + " -c 'import numpy' > /dev/null 2>&1").c_str()) == 0;
}
}  // namespace

TEST(HostileHoloOcean, DeepOrOverflowingJsonNamesTheFile) {
  const fs::path d = temp_dir("json");
  const fs::path p = d / "Config.json";
  write_file(p, std::string(200000, '[') + std::string(200000, ']'));
  expect_one_line_error([&] { read_holoocean_config(p); }, {"Config.json", "nested"});
  write_file(p, R"({"agents": [], "x": 1e309})");
  expect_one_line_error([&] { read_holoocean_config(p); }, {"Config.json", "1e309"});
  write_file(p, kHoloConfig);
  EXPECT_EQ(read_holoocean_config(p).range_bins, 4);
}

TEST(HostileHoloOcean, PickleMemoryBombsFailWithinTheBudget) {
  if (!have_numpy()) GTEST_SKIP() << "python3 with numpy is not available";
  const fs::path d = temp_dir("pickle");
  const std::vector<std::pair<std::string, std::string>> bombs = {
      // LONG_BINPUT 0x10000000: the memo grows to twice that index (4.2 GB before the fix).
      {"memo", std::string("\x80\x02N\x72\x00\x00\x00\x10.", 9)},
      // bytearray(3000000000) (32 bytes), allowed by the class filter.
      {"bytearray", std::string("\x80\x02", 2) + "cbuiltins\nbytearray\n" +
                        std::string("\x8a\x05\x00\x5e\xd0\xb2\x00\x85R.", 10)},
  };
  for (const auto& bomb : bombs) {
    const std::string& name = bomb.first;  // not a structured binding: lambdas capture it
    const std::string& bytes = bomb.second;
    const fs::path dir = d / name;
    fs::create_directories(dir / "Data");
    write_file(dir / "Config.json", kHoloConfig);
    write_file(dir / "Data/0.pkl", bytes);
    const auto t0 = std::chrono::steady_clock::now();
    expect_one_line_error([&] { import_holoocean(dir, d / (name + "_out"), {}, false); },
                          {"0.pkl", "memory"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
    EXPECT_FALSE(fs::exists(d / (name + "_out")));
  }
}

TEST(HostileMesh, PlyHeaderWithoutEndHeaderDoesNotHang) {
  // Assimp's PLY reader looped forever on this (found by fuzz_mesh).
  const fs::path p = temp_dir("plyhang") / "m.ply";
  write_file(p,
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nelem\x03OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n"
             "3 0 1 3\nnd_header\n0 0 0\n");
  expect_one_line_error([&] { load_mesh(p.string()); }, {"m.ply:7", "header"});
}

TEST(HostileMesh, OnlySupportedReadersSeeTheFile) {
  // A corrupt .ply that Assimp handed to its OFF reader, which overflowed its heap (fuzz_mesh).
  const fs::path d = temp_dir("offheap");
  const std::string bad("  02\n1 3\x03OFF\n4 4 0\n0 0 02\n1 3\n", 29);
  write_file(d / "m.ply", bad);
  expect_one_line_error([&] { load_mesh((d / "m.ply").string()); }, {"m.ply"});
  write_file(d / "m.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  expect_one_line_error([&] { load_mesh((d / "m.off").string()); }, {"m.off"});
}

TEST(HostileMesh, PlyMeshesUseTheStrictReader) {
  const fs::path d = temp_dir("plymesh");
  // A quad fanned into two triangles; an unused vertex is dropped.
  write_file(d / "q.ply",
             "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n9 9 9\n4 0 1 2 3\n");
  const TriangleMesh m = load_mesh((d / "q.ply").string());
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.vertices.size(), 4u);
  // Big-endian binary, one triangle.
  std::string be =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  auto put_be = [&](const void* p, int n) {
    for (int i = n - 1; i >= 0; --i) be.push_back(static_cast<const char*>(p)[i]);
  };
  for (float v : {0.f, 0.f, 0.f, 2.f, 0.f, 0.f, 0.f, 3.f, 0.f}) put_be(&v, 4);
  be.push_back('\3');
  for (int32_t i : {0, 1, 2}) put_be(&i, 4);
  write_file(d / "be.ply", be);
  const TriangleMesh b = load_mesh((d / "be.ply").string());
  ASSERT_EQ(b.triangles.size(), 1u);
  EXPECT_EQ(b.vertices[1].x(), 2.f);
  EXPECT_EQ(b.vertices[2].y(), 3.f);
  // A face index beyond the vertices names the file.
  write_file(d / "bad.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expect_one_line_error([&] { load_mesh((d / "bad.ply").string()); }, {"bad.ply", "vertex 7"});
}

TEST(HostileMesh, FarVerticesAreRejectedAtLoading) {
  const fs::path d = temp_dir("farmesh");
  write_file(d / "far.obj", "v 0 0 0\nv 1e19 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_one_line_error([&] { load_mesh((d / "far.obj").string()); }, {"far.obj", "1e7"});
  write_file(d / "far.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1e19 0 0\n0 1 0\n3 0 1 2\n");
  expect_one_line_error([&] { load_mesh((d / "far.ply").string()); }, {"far.ply", "1e7"});
}

TEST(HostileMesh, OnlyTheExtensionsReaderReadsTheFile) {
  // A Collada document named .gltf reached the Collada reader through Assimp's content sniffing.
  const fs::path d = temp_dir("sniff");
  write_file(d / "m.gltf",
             "<?xml version=\"1.0\"?><COLLADA xmlns=\"http://www.collada.org/2005/11/"
             "COLLADASchema\" version=\"1.4.1\"></COLLADA>\n");
  expect_one_line_error([&] { load_mesh((d / "m.gltf").string()); }, {"m.gltf"});
  write_file(d / "m.xyz", "solid t\nendsolid t\n");
  expect_one_line_error([&] { load_mesh((d / "m.xyz").string()); }, {"m.xyz", "unsupported"});
}

// Assimp 5.2's Collada reader crashes on this file (found by fuzz_mesh, fuzz/findings/): it runs
// in a child process, so the crash is one Error naming the file, and the caller lives on.
TEST(HostileMesh, AssimpCrashBecomesAnError) {
  const fs::path dir = sonar3d::test::temp_dir("assimp_crash");
  const fs::path bad = dir / "crash.dae";
  fs::copy_file(fs::path(SONAR3D_SOURCE_DIR) / "fuzz/findings/assimp-5.2-collada-segv.dae.bin",
                bad);
  try {
    sonar3d::load_mesh(bad.string());
    FAIL() << "a malformed Collada file must not load";
  } catch (const sonar3d::Error& e) {
    EXPECT_NE(std::string(e.what()).find("crash.dae"), std::string::npos) << e.what();
  }
  // Good meshes still come back whole through the child process.
  const sonar3d::TriangleMesh valve =
      sonar3d::load_mesh(std::string(SONAR3D_SOURCE_DIR) + "/data/meshes/valve.dae");
  EXPECT_GT(valve.triangles.size(), 100u);
  fs::remove_all(dir);
}
