#pragma once
// Video mapping onto a sonar point cloud (thesis sec. 6.4): every camera frame projected onto the
// points it sees, colours averaged over frames. Visibility comes from the cloud itself: each
// frame's points are splatted into a depth buffer (squares of the cloud's spacing), and a point
// further than the nearest depth at its pixel by more than a tolerance is hidden and takes no
// colour from that frame. (The thesis ray-traced an octree, which let colour leak behind
// surfaces.)
#include <Eigen/Geometry>
#include <cstdint>
#include <utility>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/video/camera.hpp"
#include "sonar3d/video/render.hpp"

namespace sonar3d {

struct CameraView {
  CameraIntrinsics camera;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  const RgbImage* image = nullptr;  // its size must match the camera's
};

struct TextureConfig {
  double point_spacing_m = 0.01;    // the cloud's spacing (its voxel size): the splat size
  double depth_tolerance_m = 0.03;  // visible when within this of the nearest depth at its pixel
  double max_range_m = 30.0;        // farther points take no colour (water: nothing to see)
  int max_splat_px = 16;            // cap on a splat's half-width, pixels
  void validate() const;            // throws Error naming the field
};

template <class V>
void describe(TextureConfig& c, V& v) {
  using params::param;
  v.field(c.point_spacing_m, param("point_spacing_m", "m",
                                   "the cloud's point spacing (the splat size of the depth "
                                   "test)")
                                 .positive()
                                 .flag("--point-spacing"));
  v.field(c.depth_tolerance_m,
          param("depth_tolerance_m", "m",
                "a point is visible within this of the nearest depth at its pixel")
              .non_negative()
              .flag("--depth-tolerance"));
  v.field(c.max_range_m,
          param("max_range_m", "m", "points farther from a camera take no colour from it")
              .positive()
              .flag("--max-range"));
  v.field(c.max_splat_px,
          param("max_splat_px", "", "cap on a splat's half-width, pixels").range(0, 256));
}

struct TexturedCloud {
  std::vector<Eigen::Vector3f> color;  // per point: mean over the frames that saw it; 0 if none
  std::vector<std::uint32_t> views;    // per point: how many frames saw it (0: no colour)
  std::size_t coloured() const;        // points with at least one view
};

TexturedCloud texture_cloud(const PointCloud& cloud, const std::vector<CameraView>& views,
                            const TextureConfig& config = {});

// The same, one frame at a time, so that a long video need not be held in memory: add() each
// view (its image may be freed afterwards), then result(). texture_cloud() is add() over all.
class CloudTexturer {
 public:
  // Copies the cloud's points (in a spatial order of its own). Throws on a bad config.
  CloudTexturer(const PointCloud& cloud, const TextureConfig& config = {});
  // Throws Error (naming the frame by `index`) when the image does not match the camera's size,
  // the camera is invalid or the pose is not finite. Returns how many points this frame coloured.
  std::size_t add(const CameraView& view, std::size_t index = 0);
  TexturedCloud result() const;

 private:
  TextureConfig config_;
  // The points in Morton order (order_[k]: the cloud's index of the k-th), in blocks of 256 with a
  // bounding box each, so that a frame only projects the blocks it may see. Per point in that
  // order: the colour sum and views over the frames so far, and this frame's pixel and depth.
  std::vector<int> order_;
  std::vector<Eigen::Vector3f> points_;
  std::vector<Eigen::AlignedBox3f> block_box_;
  std::vector<Eigen::Vector3d> sum_;
  std::vector<std::uint32_t> views_;
  std::vector<Eigen::Vector2d> pixel_;
  std::vector<float> depth_;
  std::vector<int> blocks_in_view_;              // this frame's
  std::vector<std::pair<int, int>> block_rows_;  // the rows their splats may reach (first, last)
  std::vector<float> zbuf_;                      // this frame's depth buffer
};

}  // namespace sonar3d
