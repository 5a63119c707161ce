#pragma once
// A point cloud in one frame (normally world) with an optional per-point intensity, an optional
// colour and optional named per-point scalars (e.g. the reconstruction's elevation bracketing,
// recon/bracketing.hpp).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace sonar3d {

// A named per-point scalar, written as a PLY vertex property `float <name>`.
struct PointProperty {
  std::string name;
  std::vector<float> values;  // one per point
};

struct PointCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;           // empty, or one per point
  std::vector<PointProperty> properties;  // extra per-point scalars, each one per point
  // Empty, or one per point: 8-bit sRGB-encoded red, green, blue, as PLY viewers display them
  // (PLY properties `red green blue`, uchar).
  std::vector<std::array<std::uint8_t, 3>> color;

  // The property named `name`, or nullptr.
  const PointProperty* property(const std::string& name) const {
    for (const auto& p : properties)
      if (p.name == name) return &p;
    return nullptr;
  }

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_intensity() const { return !intensity.empty(); }
  bool has_color() const { return !color.empty(); }
};

enum class PlyFormat { Binary, Ascii };

// PLY with x y z [intensity] [red green blue] [properties...] vertex properties (coordinates
// float or double; colours uchar). Reading accepts ascii and binary_little_endian; other vertex
// properties (also colours of other types than uchar) are read into `properties`. Errors name the
// file and the header line or vertex at fault.
PointCloud read_ply(const std::string& path);
// The same, also returning the faces' vertex index lists (element `face`, list property
// `vertex_indices` or `vertex_index`); every index is checked against the vertex count. Used to
// read PLY meshes without Assimp's PLY reader (docs/formats.md, section 3).
PointCloud read_ply_faces(const std::string& path, std::vector<std::vector<uint32_t>>* faces);
void write_ply(const std::string& path, const PointCloud& cloud,
               PlyFormat format = PlyFormat::Binary);  // atomic write

// True when `path` is a PLY file that write_ply() (or video's write_textured_mesh_ply()) wrote,
// by its header comment:
// the outputs sonar3d may replace with --overwrite.
bool is_sonar3d_ply(const std::string& path);

}  // namespace sonar3d
