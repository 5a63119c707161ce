#pragma once
// Video mapping from files (`sonar3d texture`): a point cloud, camera poses from a COLMAP text
// model, and the camera images on disk → a PLY with per-point colours.
//
// Colour conventions (docs/video.md): images are read and the output's colours written as
// io/texture_io.hpp describes (sRGB files, linear RGB inside); the sRGB helpers, RGB image I/O
// and `video_coloured` live there, below the modules that use them (video, world).
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/io/texture_io.hpp"
#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture.hpp"
#include "sonar3d/video/texture_mesh.hpp"

namespace sonar3d {

// How the poses of a NeuS file or a COLMAP model relate to the cloud's world, and when to warn
// that they may not (docs/video.md, "Camera world").
struct TexturePosesConfig {
  NeusFrame neus_frame = NeusFrame::World;
  // The poses' world against the cloud's (camera_world_transform, neus.hpp): identity, aoneus,
  // holoocean, or a rotation / rigid matrix, row-major. Applies to --neus and --colmap poses.
  std::string camera_world = "identity";
  // A coloured point (vertex) is "dark" when its colour's brightest sRGB channel is at most this
  // (a fraction of full scale): the near-black background of an object filmed in open water.
  double dark_level = 0.04;
  // Warn when more than this share of the coloured points is dark: their colour likely comes from
  // outside the object (poses in another world, or the background of masked images).
  double warn_dark_share = 0.3;
  // With a sonar navigation to compare with: warn when the median distance from a camera centre
  // to the nearest navigation position exceeds this (the camera and sonar worlds disagree).
  double warn_camera_offset_m = 1.0;
  void validate() const;  // bounds, and camera_world parses (throws Error naming the field)
};

template <class V>
void describe(TexturePosesConfig& c, V& v) {
  using params::param;
  static constexpr const char* kFrames[] = {"world", "normalized"};
  v.field(c.neus_frame, param("neus_frame", "",
                              "frame of the cloud for --neus: world (world_mat as given) or "
                              "normalized (NeuS's unit-sphere frame, x = (x_world - c)/s by "
                              "scale_mat)")
                            .choices(kFrames)
                            .flag("--neus-frame"));
  v.field(c.camera_world,
          param("camera_world", "",
                "the poses' world (--neus, --colmap) against the cloud's: identity, aoneus or "
                "holoocean ((x, y, z)_camera-world = (-y, -z, x)_sonar-world), or 9 / 12 / 16 "
                "numbers, a rotation or rigid 3x4 / 4x4 matrix, row-major, p_camera-world = "
                "M p_sonar-world")
              .flag("--camera-world"));
  v.field(c.dark_level, param("dark_level", "",
                              "a coloured point is dark when its brightest sRGB channel is at "
                              "most this fraction of full scale")
                            .range(0, 1));
  v.field(c.warn_dark_share, param("warn_dark_share", "",
                                   "warn when more than this share of coloured points is dark "
                                   "(colour from outside the object)")
                                 .range(0, 1)
                                 .flag("--warn-dark-share"));
  v.field(c.warn_camera_offset_m,
          param("warn_camera_offset_m", "m",
                "with --sonar-navigation: warn when the median distance from a camera centre to "
                "the nearest navigation position exceeds this")
              .positive()
              .flag("--warn-camera-offset"));
}

// `sonar3d texture`'s configuration: the colouring's (TextureConfig) and the poses' settings, at
// one level (--print-config).
struct TextureFilesConfig {
  TextureConfig texture;
  TexturePosesConfig poses;
};

template <class V>
void describe(TextureFilesConfig& c, V& v) {
  describe(c.texture, v);
  describe(c.poses, v);
}

struct TextureFilesJob {
  std::filesystem::path cloud;  // PLY, world frame
  // Poses in the cloud's frame, from one of:
  std::filesystem::path colmap_dir;   // cameras.txt + images.txt, or
  std::filesystem::path neus_file;    // IDR/NeuS cameras_*.npz (world_mat_i for the i-th image), or
  std::filesystem::path dataset_dir;  // a dataset's camera frames, posed on its navigation
  // With dataset_dir: place the frames on this navigation (TUM) instead of the dataset's, e.g. the
  // navigation_corrected.tum of `sonar3d map`, so that the video lands where the corrected map is.
  std::filesystem::path navigation_file;
  // With colmap_dir or neus_file: the sonar's navigation (TUM) in the cloud's world, only to check
  // that the camera centres lie near it (poses.warn_camera_offset_m).
  std::filesystem::path sonar_navigation_file;
  TexturePosesConfig poses;
  // The images named in images.txt (not used with dataset_dir); with neus_file, the image files of
  // this directory (.png .jpg .jpeg .tif .tiff) in name order, one per world_mat_i, as IDR/NeuS
  // list them.
  std::filesystem::path images_dir;
  std::filesystem::path output;  // PLY with red/green/blue
  TextureConfig config;
  // `cloud` is a mesh (any format Assimp reads): textured with MeshTexturer (Embree visibility,
  // subdivided to `mesh.texel_m`), written as a PLY mesh with vertex colours.
  bool is_mesh = false;
  MeshTextureConfig mesh;
  // With is_mesh: meshes (any format Assimp reads, same frame) that hide the mesh but take no
  // colour, e.g. the seabed_lod0.ply of `sonar3d world` under a placed model (MeshTexturer).
  std::vector<std::filesystem::path> occluders;
  bool overwrite = false;        // replace an existing sonar3d point cloud at `output`
  bool drop_uncoloured = false;  // leave out the points no frame saw (else they are black)
  bool progress = true;          // a progress bar on a terminal
};

struct TextureFilesResult {
  std::size_t points = 0;    // in the input cloud
  std::size_t coloured = 0;  // seen by at least one frame
  std::size_t frames = 0;    // images used
  std::size_t written = 0;   // points in the output
  std::size_t dark = 0;      // coloured points (vertices) whose colour is dark (poses.dark_level)
  std::size_t blind_frames = 0;  // frames that coloured no point
  // With sonar_navigation_file: the median distance from a camera centre to the nearest
  // navigation position, m (NaN without).
  double median_camera_offset_m = std::numeric_limits<double>::quiet_NaN();
  // Hints that the poses and the cloud disagree (too many dark points, camera centres far from the
  // navigation, frames that see nothing), each naming what to check; the CLI prints them.
  std::vector<std::string> warnings;
};

// Checks `output` before any work: it may not exist, or be a PLY sonar3d wrote (replaced only
// with `overwrite`); it may not be the input cloud. Then reads the model, textures the cloud one
// frame at a time (memory: one image) and writes the output atomically. Errors name the file:
// a missing image, an image whose size is not its camera's, a camera whose distortion does not
// invert (cameras.txt and its line).
TextureFilesResult texture_cloud_files(const TextureFilesJob& job);

}  // namespace sonar3d
