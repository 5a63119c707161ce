#pragma once
// The files of video mapping (docs/video.md), below the modules that make or read them (video,
// world, change): colour images, the textured-mesh writers and the `views` convention of coloured
// clouds.
//
// Colour conventions: 8- and 16-bit images are taken as sRGB-encoded (what cameras and image tools
// write) and decoded to linear RGB, since averaging light is only meaningful in linear units;
// 32-bit float images (TIFF) are taken as linear already. Colours written to PLY and glTF files are
// 8-bit sRGB, as viewers display them (core/rgb_image.hpp).
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/rgb_image.hpp"

namespace sonar3d {

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

// A mesh with a colour per vertex, as video/texture_mesh.hpp's MeshTexturer makes it.
struct TexturedMesh {
  TriangleMesh mesh;  // the subdivided mesh, its vertices renumbered in spatial (Morton) order
  // per vertex: linear RGB, the (weighted, MeshTextureConfig::weight_by_view) mean over the
  // frames; 0 if none
  std::vector<Eigen::Vector3f> color;
  std::vector<std::uint32_t> views;  // per vertex: frames that saw it (0: no colour)
  std::size_t coloured() const;
};

// Binary PLY with float x y z, uchar red green blue (sRGB; black where no frame saw the vertex)
// and the faces; atomic. read_ply_faces() reads it back.
void write_textured_mesh_ply(const std::filesystem::path& path, const TexturedMesh& textured);
// glTF 2.0 binary: the mesh with COLOR_0 (sRGB bytes; black where no frame saw the vertex) under a
// root node turning sonar3d's ENU world (z up) into glTF's y-up frame; atomic (io/gltf.hpp).
void write_textured_mesh_glb(const std::filesystem::path& path, const TexturedMesh& textured);

}  // namespace sonar3d
