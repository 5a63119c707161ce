// IDR/NeuS cameras_*.npz: the hand-written .npz/.npy reader on fixtures numpy wrote
// (data/video/make_neus_fixture.py), the projection-matrix decomposition, and hostile files.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/npz.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;
using sonar3d::test::expect_error;

namespace {

const fs::path kData = fs::path(SONAR3D_SOURCE_DIR) / "data" / "video";

// The fixture's cameras, as make_neus_fixture.py builds them.
Eigen::Matrix3d fixture_R_world_camera(const Eigen::Vector3d& C) {
  const Eigen::Vector3d z = (-C).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  return R;
}

Eigen::Vector3d fixture_centre(int i) {
  const double a = 2 * M_PI * i / 3;
  return {2 * std::cos(a), 2 * std::sin(a), 1.0};
}

std::vector<std::uint8_t> bytes_of(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

}  // namespace

// numpy's np.savez (stored, float64 4×4) and np.savez_compressed (deflated, float32 3×4) files
// read back to the cameras they were made from, with world_mat scaled by 1, 2.5 and −1.7.
TEST(Neus, FixturesReadBackToTheirCameras) {
  Eigen::Matrix3d K;
  K << 500, 0, 319.5, 0, 510, 239.5, 0, 0, 1;
  for (const auto& [file, tol] :
       {std::pair<const char*, double>{"cameras_neus.npz", 1e-9},
        std::pair<const char*, double>{"cameras_neus_compressed.npz", 2e-5}}) {
    SCOPED_TRACE(file);
    const auto cams = read_neus_cameras(kData / file);
    ASSERT_EQ(cams.size(), 3u);
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT((cams[i].K - K).norm(), 500 * tol) << cams[i].K;
      EXPECT_LT((cams[i].T_world_camera.translation() - fixture_centre(i)).norm(), tol);
      EXPECT_LT(
          (cams[i].T_world_camera.linear() - fixture_R_world_camera(fixture_centre(i))).norm(),
          tol);
    }
    // NeuS's normalized frame: x_norm = (x_world − c)/s with s = 1.5, c = (0.2, −0.1, 0.5).
    const auto norm = read_neus_cameras(kData / file, NeusFrame::Normalized);
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d want = (fixture_centre(i) - Eigen::Vector3d(0.2, -0.1, 0.5)) / 1.5;
      EXPECT_LT((norm[i].T_world_camera.translation() - want).norm(), tol);
      EXPECT_LT((norm[i].T_world_camera.linear() - cams[i].T_world_camera.linear()).norm(), 1e-12);
    }
    const CameraIntrinsics c = intrinsics_from_K(cams[0].K, 640, 480);
    EXPECT_NEAR(c.fx, 500, 500 * tol);
    EXPECT_NEAR(c.cy, 239.5, 500 * tol);
  }
  const auto arrays = read_npz(kData / "cameras_neus.npz");
  ASSERT_EQ(arrays.count("scale_mat_2"), 1u);
  EXPECT_EQ(arrays.at("scale_mat_2").shape, (std::vector<std::size_t>{4, 4}));
  EXPECT_EQ(arrays.at("world_mat_0").data[15], 1.0);
}

// Random cameras, any projective scale (also negative): K, R and C come back.
TEST(Neus, DecompositionRoundTrips) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix3d K;
    K << 300 + 500 * std::abs(u(rng)), 0, 320 + 50 * u(rng), 0, 300 + 500 * std::abs(u(rng)),
        240 + 50 * u(rng), 0, 0, 1;
    const Eigen::Matrix3d R_wc =
        Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized())
            .toRotationMatrix();
    const Eigen::Vector3d C(10 * u(rng), 10 * u(rng), 10 * u(rng));
    Eigen::Matrix<double, 3, 4> P;
    P << R_wc.transpose(), -R_wc.transpose() * C;
    const double lambda = (trial % 2 ? -1 : 1) * (0.01 + 100 * std::abs(u(rng)));
    P = lambda * K * P;
    Eigen::Matrix3d K2;
    Eigen::Isometry3d T;
    decompose_projection(P, &K2, &T);
    EXPECT_LT((K2 - K).norm(), 1e-8 * K.norm()) << trial;
    EXPECT_LT((T.linear() - R_wc).norm(), 1e-10) << trial;
    EXPECT_LT((T.translation() - C).norm(), 1e-9) << trial;
  }
  Eigen::Matrix<double, 3, 4> singular = Eigen::Matrix<double, 3, 4>::Zero();
  Eigen::Matrix3d K;
  Eigen::Isometry3d T;
  expect_error([&] { decompose_projection(singular, &K, &T); }, "singular");
}

// Hostile files: one clear error naming the file and the entry, no crash, no huge allocation.
TEST(Neus, HostileFilesNameFileAndEntry) {
  const fs::path tmp = test::temp_dir("neus_hostile");
  const auto good = bytes_of(kData / "cameras_neus.npz");
  auto check = [&](std::vector<std::uint8_t> b, const std::string& needle) {
    const fs::path p = tmp / "bad.npz";
    std::ofstream(p, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    expect_error([&] { read_neus_cameras(p); }, needle);
    expect_error([&] { read_neus_cameras(p); }, "bad.npz");
  };
  check({}, "not a .npz");
  check(std::vector<std::uint8_t>(good.begin(), good.begin() + good.size() / 2), "not a .npz");
  // A flipped byte inside the first entry's data: the CRC catches it, naming the entry.
  auto flipped = good;
  const std::size_t data0 =
      30 + (flipped[26] | flipped[27] << 8) + (flipped[28] | flipped[29] << 8);
  flipped[data0 + 100] ^= 0x40;
  check(flipped, "world_mat_0.npy: CRC mismatch");
  // A .npy header that lies (the CRC is checked first, so the array is corrupted in memory).
  std::vector<std::uint8_t> npy(good.begin() + data0, good.begin() + data0 + 128 + 128);
  const std::string h(npy.begin(), npy.end());
  const std::size_t s = h.find("(4, 4)");
  ASSERT_NE(s, std::string::npos);
  npy[s + 4] = '9';  // (4, 9): 36 values declared, 16 present
  expect_error([&] { parse_npy(npy.data(), npy.size(), "x.npz: world_mat_0.npy"); },
               "x.npz: world_mat_0.npy: shape declares more values");
  npy[s + 4] = '4';
  const std::size_t d = h.find("<f8");
  npy[d] = '>';
  expect_error([&] { parse_npy(npy.data(), npy.size(), "x.npy"); }, "dtype '>f8'");
  npy[d] = '<';
  const std::size_t fo = h.find("False");
  std::copy_n("True ", 5, npy.begin() + static_cast<long>(fo));
  expect_error([&] { parse_npy(npy.data(), npy.size(), "x.npy"); }, "Fortran order");
  // A huge shape over a few bytes: refused before allocating.
  const std::string huge =
      std::string("\x93NUMPY\x01\x00", 8) + std::string("\x46\x00", 2) +
      "{'descr': '<f8', 'fortran_order': False, 'shape': (999999999999, 999999999999), }    \n";
  expect_error(
      [&] {
        parse_npy(reinterpret_cast<const std::uint8_t*>(huge.data()), huge.size(), "huge.npy");
      },
      "huge.npy");
  // An archive without world_mat_0 names what is missing.
  check(bytes_of(fs::path(SONAR3D_SOURCE_DIR) / "fuzz/corpus/npz/matrix.npy"), "not a .npz");
}
