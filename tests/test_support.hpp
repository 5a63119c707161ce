#pragma once
// Helpers shared by the GoogleTest suites.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/scene.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/video/camera.hpp"

namespace sonar3d::test {

// A whole file as bytes, and bytes written over a file (for the binary-format tests).
inline std::string read_all(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}
inline void write_all(const std::filesystem::path& p, const std::string& bytes) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}
// `v`'s bytes at offset `at` of `bytes` (little-endian, as the formats and every machine we build
// for).
template <class T>
void poke(std::string& bytes, std::size_t at, T v) {
  std::memcpy(&bytes[at], &v, sizeof v);
}
#ifdef SONAR3D_CLI
// The command line `sonar3d ARGS`, its standard output and error into `log`; the exit status.
inline int run_cli_log(const std::string& args, const std::filesystem::path& log) {
  const std::string cmd = std::string(SONAR3D_CLI) + " " + args + " > " + log.string() + " 2>&1";
  return WEXITSTATUS(std::system(cmd.c_str()));
}
// The same with standard output and error kept apart, in `dir`/stdout.txt and stderr.txt.
struct CliRunSplit {
  int code;
  std::string out, err;
};
inline CliRunSplit run_cli_captured(const std::filesystem::path& dir, const std::string& args) {
  const std::filesystem::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd =
      std::string(SONAR3D_CLI) + " " + args + " > " + out.string() + " 2> " + err.string();
  const int status = std::system(cmd.c_str());
  return {WEXITSTATUS(status), read_all(out), read_all(err)};
}
#endif

// A 30 cm sphere (48 segments) centred at (0, 0, 0.5), reflectivity 0.8: the small object of the
// deconvolution tests.
// The downward-looking sonar of the small field scenes (MB2250-like: 1° × 80°, 1–4 m), with the
// simulation's ray spacing: the scene files' "sensor:" and "simulation:" blocks.
inline const std::string kDownwardSonarYaml = R"(sensor:
  fov_deg: 80
  beams: 160
  r_min: 1.0
  r_max: 4.0
  range_bins: 150
  vertical_aperture_deg: 1
  T_vehicle_sonar: {rpy_deg: [0, 90, 0]}
simulation: {elevation_step_deg: 0.1}
)";

inline Scene sphere_scene() {
  Scene scene;
  SceneObject o;
  o.name = "sphere";
  o.mesh_world = make_sphere(0.3, 48);
  o.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.5)));
  o.reflectivity = 0.8;
  scene.objects.push_back(o);
  return scene;
}

// A reduced 20° sensor for fast carving tests: 30° × 20°, 60 beams, 1–4 m in 2 cm bins.
inline SonarSpec reduced_spec_20deg() {
  SonarSpec s;
  s.name = "test-20deg";
  s.set_uniform_bearings(30 * M_PI / 180, 60);
  s.r_min = 1.0;
  s.r_max = 4.0;
  s.range_bins = 150;
  s.vertical_aperture_rad = 20 * M_PI / 180;
  return s;
}

// The simulator as the carving tests run it: rays every `step_deg` in elevation, jittered, gain 2.
inline SimulatorConfig jittered_sim_config(double step_deg) {
  SimulatorConfig c;
  c.elevation_step_rad = step_deg * M_PI / 180;
  c.jitter = true;
  c.gain = 2.0;
  return c;
}

// Circles around the world z axis: `levels` circles of radius `radius` at heights z0, z0 + dz, …,
// `per_level` sonar poses each facing the axis (sonar x toward it, z up), every other circle
// turned by half a step.
inline std::vector<Eigen::Isometry3d> orbit_poses(double radius, int levels, int per_level,
                                                  double z0, double dz) {
  std::vector<Eigen::Isometry3d> poses;
  for (int level = 0; level < levels; ++level) {
    for (int k = 0; k < per_level; ++k) {
      const double a = (k + 0.5 * (level % 2)) * 2 * M_PI / per_level;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = Eigen::AngleAxisd(a + M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T.translation() =
          Eigen::Vector3d(radius * std::cos(a), radius * std::sin(a), z0 + dz * level);
      poses.push_back(T);
    }
  }
  return poses;
}

// A camera at `eye` looking at `target` in OpenCV axes (+z forward, +x right, +y down), the world
// z up (its image's "up" is the world's +z where it can be).
inline Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(z.dot(up)) > 0.99) up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

// A pinhole `width` × `height` pixels with focal length `f` pixels, centred.
inline CameraIntrinsics pinhole_camera(int width, int height, double f) {
  CameraIntrinsics cam;
  cam.width = width;
  cam.height = height;
  cam.fx = cam.fy = f;
  cam.cx = 0.5 * (width - 1);
  cam.cy = 0.5 * (height - 1);
  return cam;
}

// A fresh, empty directory for the running test: unique per suite, test and `name`, so that
// ctest -j can run the test executables side by side.
inline std::filesystem::path temp_dir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path p =
      std::filesystem::temp_directory_path() /
      ("sonar3d_test_" + std::string(info ? info->test_suite_name() : "x") + "_" + name);
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

// A small sonar for dataset tests: 16 beams over 0.5 rad, 40 range bins over 0.5–2.5 m, 0.2 rad
// vertical aperture.
inline SonarSpec small_dataset_spec() {
  SonarSpec s;
  s.name = "small";
  s.set_uniform_bearings(0.5, 16);
  s.r_min = 0.5;
  s.r_max = 2.5;
  s.range_bins = 40;
  s.vertical_aperture_rad = 0.2;
  return s;
}

// Expects f() to throw sonar3d::Error whose message contains `needle`.
inline void expect_error(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "expected an error mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

#ifdef SONAR3D_CLI
// The command-line tool run with `args`; its exit code and what it printed (stdout and stderr
// together, in `dir`/cli.log).
struct CliRun {
  int code;
  std::string out;
};

inline CliRun run_cli(const std::filesystem::path& dir, const std::string& args) {
  const std::string log = (dir / "cli.log").string();
  const int rc =
      std::system((std::string(SONAR3D_CLI) + " " + args + " > " + log + " 2>&1").c_str());
  std::ifstream in(log);
  return {WEXITSTATUS(rc),
          std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>())};
}
#endif

}  // namespace sonar3d::test
