// The per-frame culling of the texturers (src/video/visibility_raster.hpp: blocks_in_view):
// every point a camera sees lies in a block the frame keeps, whatever the camera (pinhole or
// distorted, inside the cloud, looking anywhere), and a narrow view skips most blocks.
#include <gtest/gtest.h>

#include <random>

#include "../src/video/visibility_raster.hpp"
#include "sonar3d/video/camera.hpp"
#include "test_support.hpp"

using namespace sonar3d;

TEST(TextureCulling, BlocksInViewKeepEveryPointInView) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> xy(-10.0f, 10.0f), z(-1.0f, 3.0f);
  std::vector<Eigen::Vector3f> raw(60000);
  for (auto& p : raw) p = {xy(rng), xy(rng), z(rng)};
  std::vector<Eigen::Vector3f> points;
  for (const int i : detail::morton_order(raw)) points.push_back(raw[i]);
  const std::size_t block = 256;
  const std::vector<Eigen::AlignedBox3f> boxes = detail::block_boxes(points, block);
  ASSERT_EQ(boxes.size(), (points.size() + block - 1) / block);

  const CameraIntrinsics pinhole = test::pinhole_camera(640, 480, 500);
  CameraIntrinsics distorted = pinhole;
  distorted.k1 = -0.2;
  distorted.k2 = 0.05;
  distorted.p1 = 0.003;
  std::uniform_real_distribution<double> at(-12.0, 12.0), height(-2.0, 6.0);
  std::size_t seen_total = 0, kept_total = 0, frames = 0;
  for (int f = 0; f < 40; ++f) {
    const CameraIntrinsics& cam = f % 2 ? distorted : pinhole;
    const Eigen::Vector3d eye(at(rng), at(rng), height(rng));
    Eigen::Vector3d target(at(rng), at(rng), height(rng));
    if ((target - eye).norm() < 0.5) target += Eigen::Vector3d(1, 0, 0);
    const Eigen::Isometry3d T_world_camera = test::look_at(eye, target);
    const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
    const double max_range = f % 3 ? 30.0 : 4.0;
    std::vector<int> kept;
    detail::blocks_in_view(boxes, cam, T_camera_world, max_range, kept);
    std::vector<bool> is_kept(boxes.size(), false);
    for (const int b : kept) is_kept[static_cast<std::size_t>(b)] = true;
    std::size_t seen = 0;
    for (std::size_t k = 0; k < points.size(); ++k) {
      const Eigen::Vector3d p = T_camera_world * points[k].cast<double>();
      if (!(p.z() > 0) || p.norm() > max_range) continue;
      const auto px = project(cam, p);
      if (!px || !in_image(cam, *px)) continue;
      ++seen;
      ASSERT_TRUE(is_kept[k / block]) << "frame " << f << ": point " << k << " seen at "
                                      << px->transpose() << " in a culled block";
    }
    seen_total += seen;
    kept_total += kept.size();
    ++frames;
  }
  EXPECT_GT(seen_total, 10000u);  // the cameras do see points
  // and skip most blocks (a 640 × 480 view of a 20 m square from inside it)
  EXPECT_LT(kept_total, frames * boxes.size() / 2);
}
