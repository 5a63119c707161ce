// Cameras for video mapping: projection and its inverse with OpenCV distortion, COLMAP text
// models read and written with their conventions, bad inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/video/camera.hpp"
#include "sonar3d/video/colmap.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::temp_dir;

namespace {

CameraIntrinsics gopro_like() {
  CameraIntrinsics c;
  c.width = 1280;
  c.height = 960;
  c.fx = 900;
  c.fy = 905;
  c.cx = 641.3;
  c.cy = 478.9;
  c.k1 = -0.12;
  c.k2 = 0.03;
  c.p1 = 0.0008;
  c.p2 = -0.0005;
  c.k3 = -0.002;
  return c;
}

}  // namespace

// A known 3D point to a pixel and back: the ray through the pixel passes through the point, over
// the whole image, with and without distortion; a point behind the camera has no pixel.
TEST(Camera, ProjectionRoundTrips) {
  for (const bool distorted : {false, true}) {
    SCOPED_TRACE(distorted);
    CameraIntrinsics c = gopro_like();
    if (!distorted) c.k1 = c.k2 = c.p1 = c.p2 = c.k3 = 0;
    c.validate();
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.5, c.width - 0.5), v(-0.5, c.height - 0.5),
        depth(0.3, 20.0);
    for (int k = 0; k < 500; ++k) {
      const Eigen::Vector2d px(u(rng), v(rng));
      const auto ray = unproject(c, px);
      ASSERT_TRUE(ray.has_value()) << px.transpose();
      EXPECT_NEAR(ray->norm(), 1.0, 1e-12);
      const Eigen::Vector3d p = *ray * depth(rng);
      const auto back = project(c, p);
      ASSERT_TRUE(back.has_value());
      EXPECT_NEAR((*back - px).norm(), 0.0, 1e-6) << px.transpose();
      EXPECT_TRUE(in_image(c, *back));
    }
    EXPECT_FALSE(project(c, {0.1, 0.2, -1.0}).has_value());
    EXPECT_FALSE(project(c, {0.1, 0.2, 0.0}).has_value());
    // The optical axis meets the principal point.
    EXPECT_NEAR((*project(c, {0, 0, 3}) - Eigen::Vector2d(c.cx, c.cy)).norm(), 0.0, 1e-12);
  }
  // Undistorted pinhole by hand: (0.5, −0.25, 2) → (fx·0.25 + cx, fy·(−0.125) + cy).
  CameraIntrinsics p;
  p.width = 640;
  p.height = 480;
  p.fx = 500;
  p.fy = 400;
  p.cx = 320;
  p.cy = 240;
  EXPECT_NEAR((*project(p, {0.5, -0.25, 2}) - Eigen::Vector2d(445, 190)).norm(), 0, 1e-12);
  EXPECT_FALSE(in_image(p, {640, 10}));
  EXPECT_TRUE(in_image(p, {639.4, -0.4}));
}

// Distortion that folds over within the image does not invert: a clear error naming it.
TEST(Camera, BadIntrinsicsNameTheProblem) {
  CameraIntrinsics c = gopro_like();
  c.k1 = -1.5;  // r·(1 − 1.5 r²) turns back at r = 0.47, inside this image's corners
  expect_error([&] { c.validate(); }, "does not invert");
  c = gopro_like();
  c.fx = 0;
  expect_error([&] { c.validate(); }, "focal");
  c = gopro_like();
  c.width = 0;
  expect_error([&] { c.validate(); }, "width");
  c = gopro_like();
  c.k2 = std::nan("");
  expect_error([&] { c.validate(); }, "distortion");
}

// Poses and intrinsics written as COLMAP text and read back are the same, with COLMAP's
// conventions: world → camera quaternions and translations in images.txt, pixel centres at +0.5.
TEST(Colmap, TextModelsRoundTrip) {
  const fs::path dir = temp_dir("colmap");
  PosedImages posed;
  posed.cameras[1] = gopro_like();
  const CameraIntrinsics pin = test::pinhole_camera(640, 480, 500);
  posed.cameras[7] = pin;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> a(-3.1, 3.1), x(-20, 20);
  for (int k = 0; k < 6; ++k) {
    PosedImage im;
    im.id = 10 + k;
    im.camera_id = k % 2 ? 7 : 1;
    im.name = k == 3 ? "left cam/frame 3.png" : "frame_" + std::to_string(k) + ".png";
    im.T_world_camera.linear() = (Eigen::AngleAxisd(a(rng), Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(a(rng), Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    im.T_world_camera.translation() = Eigen::Vector3d(x(rng), x(rng), x(rng));
    posed.images.push_back(im);
  }
  write_colmap_text(posed, dir);
  // COLMAP's conventions in the files themselves.
  std::ifstream cams(dir / "cameras.txt");
  const std::string text((std::istreambuf_iterator<char>(cams)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("7 PINHOLE 640 480 500 500 320 240"), std::string::npos) << text;
  EXPECT_NE(text.find("1 FULL_OPENCV"), std::string::npos) << text;
  const PosedImages back = read_colmap_text(dir);
  ASSERT_EQ(back.cameras.size(), 2u);
  EXPECT_NEAR(back.cameras.at(7).cx, 319.5, 1e-12);
  EXPECT_NEAR(back.cameras.at(1).k3, -0.002, 1e-15);
  EXPECT_NEAR(back.cameras.at(1).p1, 0.0008, 1e-15);
  ASSERT_EQ(back.images.size(), posed.images.size());
  for (std::size_t k = 0; k < posed.images.size(); ++k) {
    EXPECT_EQ(back.images[k].id, posed.images[k].id);
    EXPECT_EQ(back.images[k].camera_id, posed.images[k].camera_id);
    EXPECT_EQ(back.images[k].name, posed.images[k].name);
    EXPECT_NEAR((back.images[k].T_world_camera.matrix() - posed.images[k].T_world_camera.matrix())
                    .cwiseAbs()
                    .maxCoeff(),
                0.0, 1e-9);
  }
  // A hand-written COLMAP model: camera at (1, 2, 3) looking along world +x (its +z), 2D points
  // on the line after each image, comments and an empty points line.
  std::ofstream(dir / "cameras.txt", std::ios::trunc)
      << "# comment\n3 SIMPLE_RADIAL 100 80 90 50.5 40.5 0.01\n";
  // R (world → camera) maps world +x to camera +z, world −z to camera +y (down), world −y to +x.
  // Camera centre C = (1, 2, 3): t = −R·C = −(−2, −3, 1) = (2, 3, −1).
  const Eigen::Matrix3d R = (Eigen::Matrix3d() << 0, -1, 0, 0, 0, -1, 1, 0, 0).finished();
  const Eigen::Quaterniond q(R);
  std::ofstream(dir / "images.txt", std::ios::trunc)
      << "# header\n"
      << "5 " << q.w() << " " << q.x() << " " << q.y() << " " << q.z() << " 2 3 -1 3 a.jpg\n"
      << "12.5 7.25 -1 3.0 4.0 17\n"
      << "6 1 0 0 0 0 0 0 3 b.jpg\n"
      << "\n";
  const PosedImages hand = read_colmap_text(dir);
  ASSERT_EQ(hand.images.size(), 2u);
  EXPECT_NEAR((hand.images[0].T_world_camera.translation() - Eigen::Vector3d(1, 2, 3)).norm(), 0,
              1e-6);
  EXPECT_NEAR((hand.images[0].T_world_camera.linear().col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 0,
              1e-6);  // the optical axis along world +x
  EXPECT_NEAR(hand.cameras.at(3).cx, 50.0, 1e-12);
  EXPECT_NEAR(hand.cameras.at(3).k1, 0.01, 1e-15);
  EXPECT_EQ(hand.images[1].name, "b.jpg");
  // Images must exist where the user says they are.
  fs::create_directories(dir / "img");
  std::ofstream(dir / "img" / "a.jpg") << "x";
  expect_error([&] { check_images_exist(hand, dir / "img"); }, "b.jpg");
  std::ofstream(dir / "img" / "b.jpg") << "x";
  EXPECT_NO_THROW(check_images_exist(hand, dir / "img"));
}

// Bad COLMAP files: one clear error naming the file and line.
TEST(Colmap, BadModelsNameFileAndLine) {
  const fs::path dir = temp_dir("colmap_bad");
  const std::string good_cam = "1 PINHOLE 640 480 500 500 320 240\n";
  const std::string good_img = "1 1 0 0 0 0 0 0 1 a.png\n\n";
  auto check = [&](const std::string& cams, const std::string& imgs, const std::string& needle) {
    std::ofstream(dir / "cameras.txt", std::ios::trunc) << cams;
    std::ofstream(dir / "images.txt", std::ios::trunc) << imgs;
    expect_error([&] { read_colmap_text(dir); }, needle);
  };
  check("1 OPENCV_FISHEYE 640 480 500 500 320 240 0 0 0 0\n", good_img, "OPENCV_FISHEYE");
  check("1 PINHOLE 640 480 500 500 320\n", good_img, "cameras.txt:1: camera model PINHOLE takes 4");
  check("1 PINHOLE 640 480 500 nan 320 240\n", good_img, "finite");
  check("1 PINHOLE 0 480 500 500 320 240\n", good_img, "width");
  check("1 FULL_OPENCV 640 480 500 500 320 240 0 0 0 0 0 0.1 0 0\n", good_img, "k4");
  check(good_cam + good_cam, good_img, "defined twice");
  check("# nothing\n", good_img, "no camera");
  check(good_cam, "1 1 0 0 0 0 0 0 2 a.png\n\n", "camera 2");
  check(good_cam, "1 0 0 0 0 0 0 0 1 a.png\n\n", "quaternion is zero");
  check(good_cam, "1 2 0 0 0 0 0 0 1 a.png\n\n", "norm");
  check(good_cam, "1 1 0 0 0 0 0 1e300 1 a.png\n\n", "1e7");
  check(good_cam, "# c\n1 1 0 0 0 0 0 0\n", "images.txt:2: expected IMAGE_ID");
  check(good_cam, good_img + good_img, "listed twice");
  check(good_cam, "# none\n", "no image");
  check(good_cam, "-1 1 0 0 0 0 0 0 1 a.png\n\n", "IMAGE_ID");
  fs::remove(dir / "images.txt");
  expect_error([&] { read_colmap_text(dir); }, "images.txt");
}

namespace {

// A blue wall 4 m in front of a camera at the origin (looking along world +z), a red plate 2 m
// in front, half a metre across; 200 × 150 pixels.
struct WallScene {
  Scene scene;
  CameraIntrinsics camera;
  WallScene() {
    SceneObject wall;
    wall.name = "wall";
    wall.mesh_world = make_plane(8.0, 8.0);
    wall.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 4)));
    wall.color = {0.1f, 0.2f, 0.9f};
    SceneObject plate;
    plate.name = "plate";
    plate.mesh_world = make_box(0.5, 0.5, 0.1);
    plate.mesh_world.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 2)));
    plate.color = {0.9f, 0.1f, 0.1f};
    scene.objects = {wall, plate};
    camera.width = 200;
    camera.height = 150;
    camera.fx = camera.fy = 150;
    camera.cx = 99.5;
    camera.cy = 74.5;
  }
};

PointCloud grid(double half, double z, double step) {
  PointCloud c;
  for (double x = -half; x <= half + 1e-9; x += step) {
    for (double y = -half; y <= half + 1e-9; y += step) {
      c.points.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    }
  }
  return c;
}

}  // namespace

// The simulated camera sees the plate in front of the wall, in their colours, with the range of
// each pixel; light falls off with range through the water.
TEST(CameraRender, SeesObjectsInTheirColours) {
  WallScene w;
  CameraRenderConfig cfg;
  cfg.ambient = 1.0;  // flat lighting, no water: the albedo itself
  cfg.attenuation_per_m = 0.0;
  const RgbImage img = CameraRenderer(w.scene, cfg).render(w.camera, Eigen::Isometry3d::Identity());
  // Centre: the plate's front face at 1.95 m; a corner: the wall at 4 m along its ray.
  EXPECT_NEAR((img.at(100, 75) - Eigen::Vector3f(0.9f, 0.1f, 0.1f)).norm(), 0, 1e-6);
  EXPECT_NEAR(img.range_m[75 * 200 + 100], 1.95, 0.01);
  EXPECT_NEAR((img.at(5, 5) - Eigen::Vector3f(0.1f, 0.2f, 0.9f)).norm(), 0, 1e-6);
  const auto ray = unproject(w.camera, {5, 5});
  EXPECT_NEAR(img.range_m[5 * 200 + 5], 4.0 / ray->z(), 0.01);
  // With water, the wall is darker than the plate relative to their albedo: exp(−2·c·r).
  cfg.attenuation_per_m = 0.2;
  cfg.ambient = 1.0;
  const RgbImage dim = CameraRenderer(w.scene, cfg).render(w.camera, Eigen::Isometry3d::Identity());
  EXPECT_NEAR(dim.at(100, 75).x() / 0.9f, std::exp(-2 * 0.2 * 1.95), 0.01);
  EXPECT_NEAR(dim.at(5, 5).z() / 0.9f, std::exp(-2 * 0.2 * 4.0 / ray->z()), 0.01);
  cfg.ambient = 2;
  expect_error([&] { CameraRenderer(w.scene, cfg); }, "ambient");
}

// A textured scene in front of a simulated camera gets its colours back; the part of the wall
// hidden behind the plate, and what lies outside the picture, get none.
TEST(Texture, ColoursBackAndNoneWhereHidden) {
  WallScene w;
  CameraRenderConfig cfg;
  cfg.ambient = 1.0;
  cfg.attenuation_per_m = 0.0;
  const RgbImage img = CameraRenderer(w.scene, cfg).render(w.camera, Eigen::Isometry3d::Identity());
  PointCloud cloud = grid(3.0, 4.0, 0.02);  // the wall, beyond the picture at its sides
  const std::size_t wall_points = cloud.size();
  const PointCloud plate = grid(0.24, 1.95, 0.02);  // the plate's front face
  cloud.points.insert(cloud.points.end(), plate.points.begin(), plate.points.end());
  TextureConfig tc;
  tc.point_spacing_m = 0.02;
  const TexturedCloud t =
      texture_cloud(cloud, {CameraView{w.camera, Eigen::Isometry3d::Identity(), &img}}, tc);
  // The plate's shadow on the wall: its 0.25 m half-width at 1.95 m seen at 4 m.
  const double shadow = 0.25 * 4.0 / 1.95;
  // The picture's edge at 4 m: u = ±100 px → x = ±100·4/150.
  const double edge = 99.5 * 4.0 / 150;
  std::size_t hidden = 0, seen = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    const bool on_wall = i < wall_points;
    const double m = std::max(std::abs(p.x()), std::abs(p.y()));
    if (on_wall && m < shadow - 0.05) {
      EXPECT_EQ(t.views[i], 0u) << "hidden wall point " << p.transpose() << " took a colour";
      ++hidden;
    } else if (on_wall && m > shadow + 0.05 && std::abs(p.x()) < edge - 0.05 &&
               std::abs(p.y()) < 74.5 * 4.0 / 150 - 0.05) {
      ASSERT_EQ(t.views[i], 1u) << p.transpose();
      EXPECT_NEAR((t.color[i] - Eigen::Vector3f(0.1f, 0.2f, 0.9f)).norm(), 0, 1e-4);
      ++seen;
    } else if (!on_wall && m < 0.2) {
      ASSERT_EQ(t.views[i], 1u) << p.transpose();
      EXPECT_NEAR((t.color[i] - Eigen::Vector3f(0.9f, 0.1f, 0.1f)).norm(), 0, 1e-4);
      ++seen;
    } else if (on_wall && std::abs(p.x()) > edge + 0.05) {
      EXPECT_EQ(t.views[i], 0u) << "outside the picture: " << p.transpose();
    }
  }
  EXPECT_GT(hidden, 500u);
  EXPECT_GT(seen, 5000u);
  // Bad input: an image that is not the camera's.
  RgbImage small = img;
  small.width = 10;
  expect_error(
      [&] {
        texture_cloud(cloud, {CameraView{w.camera, Eigen::Isometry3d::Identity(), &small}}, tc);
      },
      "size");
  tc.point_spacing_m = 0;
  expect_error([&] { texture_cloud(cloud, {}, tc); }, "point_spacing_m");
}
