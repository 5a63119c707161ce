// io: dataset directory v1 round trip and its bad inputs.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/dataset.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;
namespace fs = std::filesystem;

namespace {

SonarSpec small_spec() {
  SonarSpec s = sonar3d::test::small_dataset_spec();
  s.T_vehicle_sonar.translation() = Eigen::Vector3d(0.1, 0.2, -0.3);
  s.T_vehicle_sonar.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  return s;
}

SonarImage random_image(const SonarSpec& s, std::mt19937_64& rng, double t) {
  SonarImage img(s.range_bins, s.beams());
  std::uniform_real_distribution<float> u(0, 1);
  for (auto& v : img.data) v = u(rng);
  img.timestamp = t;
  return img;
}

// Writes a 3-frame dataset and returns the images written.
std::vector<SonarImage> write_small(const fs::path& dir, const SonarSpec& s) {
  std::mt19937_64 rng(1);
  DatasetWriter w(dir, s);
  std::vector<SonarImage> imgs;
  Trajectory nav;
  for (int k = 0; k < 3; ++k) {
    imgs.push_back(random_image(s, rng, 10.0 + k));
    w.add_frame(imgs.back());
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(k, 0, 0);
    nav.push_back(10.0 + k, T);
  }
  w.set_navigation(nav);
  NoiseImages n{SonarImage(s.range_bins, s.beams(), 0.01f),
                SonarImage(s.range_bins, s.beams(), 0.02f)};
  w.set_noise(n);
  w.commit();
  return imgs;
}

void replace_in_file(const fs::path& p, const std::string& from, const std::string& to) {
  std::ifstream f(p);
  std::string s((std::istreambuf_iterator<char>(f)), {});
  const auto pos = s.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  s.replace(pos, from.size(), to);
  std::ofstream(p) << s;
}

}  // namespace

TEST(Dataset, WriteReadRoundTrip) {
  const fs::path root = temp_dir("roundtrip");
  const SonarSpec s = small_spec();
  const auto imgs = write_small(root / "ds", s);
  const Dataset ds = read_dataset(root / "ds");
  EXPECT_EQ(ds.spec.name, "small");
  EXPECT_EQ(ds.spec.beams(), s.beams());
  for (int j = 0; j < s.beams(); ++j)
    EXPECT_NEAR(ds.spec.bearings_rad[j], s.bearings_rad[j], 1e-12);
  EXPECT_DOUBLE_EQ(ds.spec.r_min, s.r_min);
  EXPECT_DOUBLE_EQ(ds.spec.vertical_aperture_rad, s.vertical_aperture_rad);
  EXPECT_TRUE(ds.spec.T_vehicle_sonar.isApprox(s.T_vehicle_sonar, 1e-12));
  ASSERT_EQ(ds.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const SonarImage img = ds.load_frame(k);
    EXPECT_DOUBLE_EQ(img.timestamp, 10.0 + k);
    for (std::size_t i = 0; i < img.data.size(); ++i) {
      // 16-bit quantisation: half a step of error at most.
      ASSERT_NEAR(img.data[i], imgs[k].data[i], 0.51 * s.intensity_scale);
    }
    const Eigen::Isometry3d expected = Eigen::Translation3d(k, 0, 0) * s.T_vehicle_sonar;
    EXPECT_TRUE(ds.T_world_sonar(k).isApprox(expected, 1e-9));
  }
  ASSERT_TRUE(ds.noise.has_value());
  EXPECT_FLOAT_EQ(ds.noise->std.at(3, 4), 0.02f);
}

TEST(Dataset, NonUniformBearingTableRoundTrips) {
  const fs::path root = temp_dir("table");
  SonarSpec s = small_spec();
  for (int j = 0; j < s.beams(); ++j) s.bearings_rad[j] = 0.03 * j + 0.001 * j * j - 0.3;
  write_small(root / "ds", s);
  const Dataset ds = read_dataset(root / "ds");
  for (int j = 0; j < s.beams(); ++j)
    EXPECT_NEAR(ds.spec.bearings_rad[j], s.bearings_rad[j], 1e-12);
}

TEST(Dataset, UncommittedWriterLeavesNothing) {
  const fs::path root = temp_dir("atomic");
  {
    DatasetWriter w(root / "ds", small_spec());
    std::mt19937_64 rng(1);
    w.add_frame(random_image(small_spec(), rng, 0));
    SonarImage wrong(3, 3);
    EXPECT_THROW(w.add_frame(wrong), Error);  // size disagrees with the spec
  }
  EXPECT_TRUE(fs::is_empty(root)) << "a failed write must leave no dataset behind";
}

TEST(Dataset, BadInputsGiveClearErrors) {
  const fs::path root = temp_dir("bad");
  const SonarSpec s = small_spec();
  expect_error([&] { read_dataset(root / "none"); }, "not a directory");
  fs::create_directories(root / "empty");
  expect_error([&] { read_dataset(root / "empty"); }, "sonar.yaml is missing");

  auto fresh = [&](const std::string& name) {
    const fs::path d = root / name;
    write_small(d, s);
    return d;
  };
  // Malformed YAML names the line.
  fs::path d = fresh("yaml");
  replace_in_file(d / "sonar.yaml", "range_bins: 40", "range_bins: [40");
  expect_error([&] { read_dataset(d); }, "sonar.yaml:");
  // A wrong type names the key and its line.
  d = fresh("type");
  replace_in_file(d / "sonar.yaml", "r_max: 2.5", "r_max: far");
  expect_error([&] { read_dataset(d); }, "sensor.r_max");
  // Apertures of 0 and 180 degrees.
  d = fresh("ap0");
  replace_in_file(d / "sonar.yaml", "vertical_aperture_deg:", "vertical_aperture_deg: 0 #");
  expect_error([&] { read_dataset(d); }, "vertical_aperture_deg");
  d = fresh("ap180");
  replace_in_file(d / "sonar.yaml", "vertical_aperture_deg:", "vertical_aperture_deg: 180 #");
  expect_error([&] { read_dataset(d); }, "vertical_aperture_deg");
  // Unknown key.
  d = fresh("unknown");
  replace_in_file(d / "sonar.yaml", "r_max:", "rmax_typo: 3\n  r_max:");
  expect_error([&] { read_dataset(d); }, "rmax_typo");
  // Image size disagrees with sonar.yaml.
  d = fresh("size");
  replace_in_file(d / "sonar.yaml", "range_bins: 40", "range_bins: 41");
  expect_error([&] { read_dataset(d); }, "noise images must be 41×16");
  d = fresh("framesize");
  {
    SonarSpec other = s;
    other.range_bins = 41;
    write_sonar_image((d / "frames/000000.png").string(), SonarImage(41, 16), other);
    const Dataset ds = read_dataset(d);
    expect_error([&] { ds.load_frame(0); }, "000000.png' is 41×16");
  }
  // Corrupt image.
  d = fresh("corrupt");
  std::ofstream(d / "frames/000001.png", std::ios::trunc) << "garbage";
  {
    const Dataset ds = read_dataset(d);
    expect_error([&] { ds.load_frame(1); }, "000001.png");
  }
  // A frame outside the navigation span has no pose.
  d = fresh("nopose");
  replace_in_file(d / "frames.csv", "2,12,", "2,99,");
  {
    const Dataset ds = read_dataset(d);
    EXPECT_NO_THROW(ds.T_world_sonar(1));
    expect_error([&] { ds.T_world_sonar(2); }, "frame 2 has no pose");
  }
  // NaN pose in the navigation.
  d = fresh("nanpose");
  replace_in_file(d / "navigation.tum", "\n11 1 0 0", "\n11 nan 0 0");
  expect_error([&] { read_dataset(d); }, "navigation.tum:3");
  // Timestamps going backwards in frames.csv.
  d = fresh("backwards");
  replace_in_file(d / "frames.csv", "1,11,", "1,9,");
  expect_error([&] { read_dataset(d); }, "frames.csv:3");
  // Version from the future.
  d = fresh("version");
  replace_in_file(d / "sonar.yaml", "version: 1", "version: 7");
  expect_error([&] { read_dataset(d); }, "version 7");
}
