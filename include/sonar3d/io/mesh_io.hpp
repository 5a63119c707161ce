#pragma once
// Meshes from every CAD format users have, through Assimp (.dae .stl .obj .ply .gltf ...).
#include <string>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

// Loads all meshes of the file's scene graph, with node transforms applied, into one mesh in
// metres with z up. The file's declared up axis and unit are honoured: a Collada file with
// <up_axis>Z_UP</up_axis> keeps its z axis up (Assimp would otherwise rotate it to y-up), and
// <unit meter="0.01"> scales to metres. Errors name the file and Assimp's reason.
TriangleMesh load_mesh(const std::string& path);

// Writes a mesh as PLY (binary) or OBJ, chosen by extension, atomically.
void save_mesh(const std::string& path, const TriangleMesh& mesh);

}  // namespace sonar3d
