#pragma once
// Video mapping from files (`sonar3d texture`): a point cloud, camera poses from a COLMAP text
// model, and the camera images on disk → a PLY with per-point colours.
//
// Colour conventions (docs/video.md): 8- and 16-bit images are taken as sRGB-encoded (what
// cameras and image tools write) and decoded to linear RGB before averaging, since averaging
// light is only meaningful in linear units; 32-bit float images (TIFF) are taken as linear
// already. The output PLY's uchar red/green/blue are sRGB-encoded again, as viewers display them.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture.hpp"
#include "sonar3d/video/texture_mesh.hpp"

namespace sonar3d {

// The sRGB transfer function (IEC 61966-2-1) and its inverse, on [0, 1] (clamped).
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);
// A linear-RGB colour as the 8-bit sRGB bytes PLY and glTF files carry (clamped to [0, 1]).
std::array<std::uint8_t, 3> linear_to_srgb8(const Eigen::Vector3f& linear);

// Reads a colour or grey image (PNG, JPEG, TIFF ... through OpenCV) into linear RGB: 8/16-bit
// sRGB decoded, float taken as linear (it must be finite); grey replicated, alpha dropped.
// Throws Error naming the file when it cannot be read or has an unsupported pixel type.
RgbImage read_rgb_image(const std::filesystem::path& path);
// Writes a 16-bit sRGB-encoded PNG (atomic). The inverse of read_rgb_image within 1e-5.
void write_rgb_image(const std::filesystem::path& path, const RgbImage& image);

// Which points of a coloured cloud carry a video colour: those whose `views` property (written by
// sonar3d texture: the frames that coloured each point) is > 0, or, for a cloud without it, those
// whose colour is not black (texture writes black where no frame saw a point). All 0 for a cloud
// without colours. Read by sonar3d world (seabed colours) and sonar3d diff (colour change).
std::vector<std::uint8_t> video_coloured(const PointCloud& cloud);

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
