// Meshes (load_mesh): the first byte picks the file extension (.ply .obj .stl .glb .gltf), the
// rest is the file. PLY goes through our own strict reader, the others through Assimp's readers,
// our scene validation before post-processing and the node walk.
#include "fuzz_common.hpp"
#include "sonar3d/io/mesh_io.hpp"

// Assimp in this process: load_mesh otherwise reads in a child process, where libFuzzer sees
// neither coverage nor crashes.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("SONAR3D_MESH_IN_PROCESS", "1", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  // Collada (.dae) is left out by default: Assimp 5.2's Collada parser crashes within a minute
  // (third party; load_mesh contains it in a child process, docs/fuzzing.md);
  // SONAR3D_FUZZ_MESH_EXT=.dae fuzzes it alone.
  static const char* kExt[] = {".ply", ".obj", ".stl", ".glb", ".gltf"};
  // SONAR3D_FUZZ_MESH_EXT=.obj (say) fuzzes one reader only.
  static const char* only = std::getenv("SONAR3D_FUZZ_MESH_EXT");
  const auto p =
      sonar3d::fuzz::scratch() / (std::string("mesh") + (only ? only : kExt[data[0] % 5]));
  sonar3d::fuzz::write_file(p, {reinterpret_cast<const char*>(data + 1), size - 1});
  sonar3d::fuzz::run([&] { sonar3d::load_mesh(p.string()); });
  std::filesystem::remove(p);
  return 0;
}
