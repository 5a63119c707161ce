#pragma once
// A small glTF 2.0 binary (.glb) writer for world models (thesis sec. 6.3.3, Fig. 6.18): indexed
// triangle meshes with positions, normals and optional vertex colours, one material per mesh,
// and a node tree with 4×4 matrices (glTF 2.0 spec, "GLB File Format Specification"). Written
// directly rather than through Assimp's exporter: the few structures needed are simple, and the
// node matrices, materials and accessor bounds are then exactly what sonar3d put there (the tests
// read the file back with Assimp's glTF2 importer).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

struct GltfMesh {
  std::string name;
  TriangleMesh mesh;  // in the frame of the node(s) that use it
  // Empty, or one 8-bit sRGB colour per vertex (written as COLOR_0, normalised unsigned bytes).
  std::vector<std::array<std::uint8_t, 3>> colors;
  Eigen::Vector4f base_color{0.8f, 0.8f, 0.8f, 1.0f};  // material baseColorFactor, linear RGBA
};

struct GltfNode {
  std::string name;
  int mesh = -1;                                         // index into GltfScene::meshes, or -1
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();  // node-to-parent transform
  std::vector<int> children;                             // indices into GltfScene::nodes
};

struct GltfScene {
  std::vector<GltfMesh> meshes;
  std::vector<GltfNode> nodes;
  std::vector<int> roots;  // the scene's root nodes
};

// The rotation from sonar3d's world frame (local ENU, z up) to glTF's y-up frame:
// x_gltf = East, y_gltf = Up, z_gltf = −North (right-handed).
Eigen::Matrix4d enu_to_gltf();

// Writes `scene` as one .glb (JSON chunk + one binary buffer), atomically. Throws Error on
// an index out of range, a non-finite vertex or matrix, a colour count that does not match the
// vertices, or a scene too large for glTF's 32-bit byte lengths.
void write_glb(const std::filesystem::path& path, const GltfScene& scene);

}  // namespace sonar3d
