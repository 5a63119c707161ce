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
#include <string>
#include <vector>

#include "sonar3d/io/texture_io.hpp"
#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture.hpp"
#include "sonar3d/video/texture_mesh.hpp"

namespace sonar3d {

struct TextureFilesJob {
  std::filesystem::path cloud;  // PLY, world frame
  // Poses in the cloud's frame, from one of:
  std::filesystem::path colmap_dir;   // cameras.txt + images.txt, or
  std::filesystem::path neus_file;    // IDR/NeuS cameras_*.npz (world_mat_i for the i-th image), or
  std::filesystem::path dataset_dir;  // a dataset's camera frames, posed on its navigation
  // With dataset_dir: place the frames on this navigation (TUM) instead of the dataset's, e.g. the
  // navigation_corrected.tum of `sonar3d map`, so that the video lands where the corrected map is.
  std::filesystem::path navigation_file;
  NeusFrame neus_frame = NeusFrame::World;
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
};

// Checks `output` before any work: it may not exist, or be a PLY sonar3d wrote (replaced only
// with `overwrite`); it may not be the input cloud. Then reads the model, textures the cloud one
// frame at a time (memory: one image) and writes the output atomically. Errors name the file:
// a missing image, an image whose size is not its camera's, a camera whose distortion does not
// invert (cameras.txt and its line).
TextureFilesResult texture_cloud_files(const TextureFilesJob& job);

}  // namespace sonar3d
