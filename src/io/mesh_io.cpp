// Mesh import through Assimp 5.2 and export to PLY / OBJ.
//
// Up axis and unit (GUIDE.md sec. 3: world frame z up, metres; keep the file's declared frame):
//
//   Collada (.dae .zae)  Assimp 5.2 honours <up_axis> and <unit meter=...> itself: it scales by
//                        the unit and rotates X_UP and Z_UP files to y-up in the root node's
//                        transform (a file without <up_axis> is Y_UP by the Collada spec). We let
//                        it do that and then rotate y-up to z-up, so every Collada file arrives
//                        z-up in metres. For a Z_UP file the two rotations cancel exactly (their
//                        entries are 0 and ±1), i.e. its coordinates are kept bit for bit. Checked
//                        against bop_panel.dae (Z_UP, meter="1"): 0.5 x 0.8 x 0.36 m, base on
//                        z = 0, the same as an independent parse of the file's <matrix> and
//                        positions. (We do not set AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION: it
//                        would keep the raw coordinates of every file, so a Y_UP file would come
//                        out lying on its side, and Assimp 5.2 exposes no other way to learn the
//                        declared axis.)
//   glTF (.gltf .glb)    y up and metres by the glTF 2.0 spec; Assimp keeps the raw coordinates,
//                        so we rotate y-up to z-up.
//   FBX (.fbx)           Assimp keeps raw coordinates and reports the axis system and unit in the
//                        scene metadata (UpAxis/UpAxisSign, CoordAxis/CoordAxisSign,
//                        UnitScaleFactor in cm per unit); we apply them. Left-handed FBX axis
//                        systems are not mirrored (rare; the rotation keeps up and right).
//   everything else      (.stl .obj .ply .off ...) declare no up axis or unit: coordinates are kept
//                        as they are, read as metres and z up. An .obj exported y-up from a tool
//                        must be re-exported z-up (or rotated by the caller).
//
// "y-up to z-up" is the right-handed rotation of +90 deg about x, (x, y, z) -> (x, -z, y): +y
// becomes +z, and x is kept.
#include "sonar3d/io/mesh_io.hpp"

#include <assimp/BaseImporter.h>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/point_cloud.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

Eigen::Matrix4d to_eigen(const aiMatrix4x4& m) {
  // aiMatrix4x4 is row-major and acts on column vectors (a4, b4, c4 = translation).
  Eigen::Matrix4d M;
  M << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2, m.d3,
      m.d4;
  return M;
}

Eigen::Matrix4d y_up_to_z_up() {
  Eigen::Matrix4d R = Eigen::Matrix4d::Identity();
  R.block<3, 3>(0, 0) << 1, 0, 0,  //
      0, 0, -1,                    //
      0, 1, 0;
  return R;
}

// Reads a numeric metadata entry whatever type the importer stored it as.
bool metadata_number(const aiMetadata* meta, const char* key, double* out) {
  if (meta == nullptr) return false;
  for (unsigned i = 0; i < meta->mNumProperties; ++i) {
    if (std::string(meta->mKeys[i].C_Str()) != key) continue;
    const aiMetadataEntry& e = meta->mValues[i];
    switch (e.mType) {
      case AI_BOOL:
        *out = *static_cast<const bool*>(e.mData) ? 1.0 : 0.0;
        return true;
      case AI_INT32:
        *out = *static_cast<const int32_t*>(e.mData);
        return true;
      case AI_UINT64:
        *out = static_cast<double>(*static_cast<const uint64_t*>(e.mData));
        return true;
      case AI_FLOAT:
        *out = *static_cast<const float*>(e.mData);
        return true;
      case AI_DOUBLE:
        *out = *static_cast<const double*>(e.mData);
        return true;
      default:
        return false;
    }
  }
  return false;
}

// FBX declares its axis system and unit in the global settings, which Assimp 5.2 copies into the
// scene metadata without applying them.
Eigen::Matrix4d fbx_to_z_up_metres(const aiScene* scene) {
  const aiMetadata* meta = scene->mMetaData;
  double up = 1, up_sign = 1, coord = 0, coord_sign = 1, unit_cm = 1;
  metadata_number(meta, "UpAxis", &up);
  metadata_number(meta, "UpAxisSign", &up_sign);
  metadata_number(meta, "CoordAxis", &coord);
  metadata_number(meta, "CoordAxisSign", &coord_sign);
  metadata_number(meta, "UnitScaleFactor", &unit_cm);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  const int u = static_cast<int>(up), r = static_cast<int>(coord);
  if (u >= 0 && u < 3 && r >= 0 && r < 3 && u != r) {
    const Eigen::Vector3d up_file = (up_sign < 0 ? -1.0 : 1.0) * Eigen::Vector3d::Unit(u);
    const Eigen::Vector3d right_file = (coord_sign < 0 ? -1.0 : 1.0) * Eigen::Vector3d::Unit(r);
    // Rows: where our x, y, z come from. y = z cross x keeps the rotation proper (det = +1).
    T.block<1, 3>(0, 0) = right_file.transpose();
    T.block<1, 3>(1, 0) = up_file.cross(right_file).transpose();
    T.block<1, 3>(2, 0) = up_file.transpose();
  }
  // UnitScaleFactor is centimetres per file unit (FBX default 1 = cm).
  if (std::isfinite(unit_cm) && unit_cm > 0.0) T.block<3, 3>(0, 0) *= unit_cm * 0.01;
  return T;
}

void collect(const aiScene* scene, const aiNode* node, const Eigen::Matrix4d& parent,
             TriangleMesh* out) {
  const Eigen::Matrix4d M = parent * to_eigen(node->mTransformation);
  const Eigen::Matrix3d A = M.block<3, 3>(0, 0);
  const Eigen::Vector3d t = M.block<3, 1>(0, 3);
  // A mirroring node transform turns counter-clockwise triangles clockwise; swap to stay outward.
  const bool mirrored = A.determinant() < 0.0;
  for (unsigned k = 0; k < node->mNumMeshes; ++k) {
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[k]];
    // Only vertices used by triangles are copied, so stray points and lines (kept by Assimp in
    // separate primitive types) do not inflate the bounding box.
    std::vector<int> remap(mesh->mNumVertices, -1);
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      Eigen::Vector3i tri;
      bool valid = true;
      for (int c = 0; c < 3; ++c) {
        const unsigned vi = face.mIndices[c];
        if (vi >= mesh->mNumVertices) {
          valid = false;
          break;
        }
        if (remap[vi] < 0) {
          const aiVector3D& v = mesh->mVertices[vi];
          remap[vi] = static_cast<int>(out->vertices.size());
          out->vertices.push_back((A * Eigen::Vector3d(v.x, v.y, v.z) + t).cast<float>());
        }
        tri[c] = remap[vi];
      }
      if (!valid || tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0]) continue;
      if (mirrored) std::swap(tri[1], tri[2]);
      out->triangles.push_back(tri);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) collect(scene, node->mChildren[c], M, out);
}

// The formats we read (docs/formats.md, section 3). Assimp registers ~50 readers and, when the
// reader chosen by the extension refuses a file, tries every other one on the content: a
// corrupt .ply was then read by the OFF reader, which overflows its heap buffers (found by
// fuzz_mesh). Readers of other formats are removed from this importer.
void keep_supported_readers(Assimp::Importer& importer, const std::string& path) {
  static const std::vector<std::string> kSupported = {"dae",  "zae", "stl", "obj",
                                                      "gltf", "glb", "fbx"};
  // Only the reader of the file's own extension: content sniffing handed a corrupt .gltf to the
  // Collada reader, which then asked for 3 GB (fuzz_mesh).
  const std::string dotted = lower_extension(path);
  const std::string ext = dotted.empty() ? dotted : dotted.substr(1);
  if (std::find(kSupported.begin(), kSupported.end(), ext) == kSupported.end()) {
    throw Error("cannot load mesh '" + path + "': unsupported format '." + printable(ext) +
                "' (use .dae .zae .stl .obj .ply .gltf .glb or .fbx)");
  }
  std::vector<Assimp::BaseImporter*> drop;
  for (std::size_t i = 0; i < importer.GetImporterCount(); ++i) {
    const aiImporterDesc* d = importer.GetImporterInfo(i);
    bool keep = false;
    if (d != nullptr && d->mFileExtensions != nullptr) {
      std::istringstream exts(d->mFileExtensions);
      for (std::string e; exts >> e;) {
        keep = keep || e == ext;
      }
    }
    if (!keep) drop.push_back(importer.GetImporter(i));
  }
  for (Assimp::BaseImporter* imp : drop) {
    if (imp != nullptr && importer.UnregisterLoader(imp) == aiReturn_SUCCESS) delete imp;
  }
}

// Finite and within ±1e7 m (Embree, used by the simulator and the evaluation, asserts on
// coordinates beyond ~1e18; docs/formats.md, section 5).
void check_vertices(const TriangleMesh& mesh, const std::string& path) {
  for (const auto& v : mesh.vertices) {
    if (!v.allFinite()) {
      throw Error("cannot load mesh '" + path + "': it has non-finite vertex coordinates");
    }
    if (v.cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
      throw Error("cannot load mesh '" + path +
                  "': a vertex lies more than 1e7 from the origin (check the file's unit)");
    }
  }
}

bool starts_with_ply(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char magic[3] = {};
  return f.read(magic, 3) && std::string(magic, 3) == "ply";
}

// PLY meshes are read by our own strict reader (sonar3d's own mesh output is PLY): Assimp 5.2's
// PLY reader loops forever on a header without "end_header" and corrupts its heap on some
// malformed files (both found by fuzz_mesh). Polygons are fanned into triangles; only vertices
// used by a triangle are kept, as in collect().
TriangleMesh load_ply_mesh(const std::string& path) {
  std::vector<std::vector<uint32_t>> faces;
  const PointCloud cloud = read_ply_faces(path, &faces);  // errors name the file
  TriangleMesh mesh;
  std::vector<int> remap(cloud.points.size(), -1);
  auto vertex = [&](uint32_t i) {
    if (remap[i] < 0) {
      remap[i] = static_cast<int>(mesh.vertices.size());
      mesh.vertices.push_back(cloud.points[i]);
    }
    return remap[i];
  };
  for (const auto& face : faces) {
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      const uint32_t a = face[0], b = face[k], c = face[k + 1];
      if (a == b || b == c || c == a) continue;
      const int ia = vertex(a), ib = vertex(b), ic = vertex(c);  // in order: file order kept
      mesh.triangles.emplace_back(ia, ib, ic);
    }
  }
  if (mesh.triangles.empty()) {
    throw Error("cannot load mesh '" + path + "': it contains no triangles");
  }
  check_vertices(mesh, path);
  return mesh;
}

// Everything the post-processing steps and collect() index: meshes, faces, vertices and the
// node tree. Throws naming the file and what is wrong.
void validate_scene(const aiScene* scene, const std::string& path) {
  auto fail = [&](const std::string& what) {
    throw Error("cannot load mesh '" + path + "': " + what + " (the file is corrupt)");
  };
  if (scene->mRootNode == nullptr) fail("the file has no scene graph");
  if (scene->mNumMeshes > 0 && scene->mMeshes == nullptr) fail("mesh table missing");
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    if (mesh == nullptr) fail("mesh " + std::to_string(m) + " is missing");
    if (mesh->mNumVertices > 0 && mesh->mVertices == nullptr) {
      fail("mesh " + std::to_string(m) + " has no vertex array");
    }
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        fail("mesh " + std::to_string(m) + " vertex " + std::to_string(v) + " is not finite");
      }
    }
    if (mesh->mNumFaces > 0 && mesh->mFaces == nullptr) {
      fail("mesh " + std::to_string(m) + " has no face array");
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices == 0 || face.mIndices == nullptr) {
        fail("mesh " + std::to_string(m) + " face " + std::to_string(f) + " has no vertex");
      }
      for (unsigned c = 0; c < face.mNumIndices; ++c) {
        if (face.mIndices[c] >= mesh->mNumVertices) {
          fail("mesh " + std::to_string(m) + " face " + std::to_string(f) + " refers to vertex " +
               std::to_string(face.mIndices[c]) + " of " + std::to_string(mesh->mNumVertices));
        }
      }
    }
  }
  // The node tree, iteratively (a deep tree must not overflow the stack) and with a cap on the
  // number of visits (a node listed as its own descendant would loop).
  // collect() recurses, so the depth is bounded too.
  std::vector<std::pair<const aiNode*, int>> todo{{scene->mRootNode, 0}};
  std::size_t visits = 0;
  while (!todo.empty()) {
    const auto [node, depth] = todo.back();
    todo.pop_back();
    if (++visits > 1000000) fail("the node tree has more than a million nodes or a cycle");
    if (depth > 1000) fail("the node tree is more than 1000 levels deep");
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      if (node->mMeshes == nullptr || node->mMeshes[k] >= scene->mNumMeshes) {
        fail("node '" + printable(node->mName.C_Str()) + "' refers to a mesh that does not exist");
      }
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) {
      if (node->mChildren == nullptr || node->mChildren[c] == nullptr) {
        fail("node '" + printable(node->mName.C_Str()) + "' has a missing child");
      }
      todo.emplace_back(node->mChildren[c], depth + 1);
    }
  }
}

void put_le(std::ostream& os, const void* data, size_t size) {
  // PLY binary_little_endian regardless of the host's byte order.
  const auto* bytes = static_cast<const unsigned char*>(data);
  const uint16_t probe = 1;
  const bool host_little = *reinterpret_cast<const unsigned char*>(&probe) == 1;
  if (host_little) {
    os.write(reinterpret_cast<const char*>(bytes), static_cast<std::streamsize>(size));
  } else {
    for (size_t i = size; i-- > 0;) os.put(static_cast<char>(bytes[i]));
  }
}

void write_ply(std::ostream& os, const TriangleMesh& mesh) {
  os << "ply\nformat binary_little_endian 1.0\ncomment sonar3d mesh, metres, z up\n"
     << "element vertex " << mesh.vertices.size() << "\n"
     << "property float x\nproperty float y\nproperty float z\n"
     << "element face " << mesh.triangles.size() << "\n"
     << "property list uchar int vertex_indices\nend_header\n";
  for (const auto& v : mesh.vertices) {
    for (int c = 0; c < 3; ++c) put_le(os, &v[c], sizeof(float));
  }
  for (const auto& t : mesh.triangles) {
    const unsigned char n = 3;
    os.put(static_cast<char>(n));
    for (int c = 0; c < 3; ++c) {
      const int32_t i = t[c];
      put_le(os, &i, sizeof(i));
    }
  }
}

void write_obj(std::ostream& os, const TriangleMesh& mesh) {
  os << "# sonar3d mesh, metres, z up\n";
  // 9 significant digits round-trip a float exactly.
  os << std::setprecision(9);
  for (const auto& v : mesh.vertices) os << "v " << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
  for (const auto& t : mesh.triangles) {
    os << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';  // OBJ is 1-based
  }
}

}  // namespace

namespace {
TriangleMesh load_mesh_isolated(const std::string& path);
TriangleMesh load_mesh_assimp(const std::string& path);
}  // namespace

TriangleMesh load_mesh(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    throw Error("cannot load mesh '" + path + "': no such file");
  }
  if (!fs::is_regular_file(path, ec)) {
    throw Error("cannot load mesh '" + path + "': not a regular file");
  }

  if (starts_with_ply(path) || lower_extension(path) == ".ply") return load_ply_mesh(path);
  // SONAR3D_MESH_IN_PROCESS=1 keeps Assimp in this process (fuzz_mesh: libFuzzer needs the
  // coverage and the crash where it happens).
  const char* in_process = std::getenv("SONAR3D_MESH_IN_PROCESS");
  if (in_process != nullptr && std::string(in_process) == "1") return load_mesh_assimp(path);
  return load_mesh_isolated(path);
}

namespace {

// Assimp's part of load_mesh. Runs in a child process (load_mesh_isolated).
TriangleMesh load_mesh_assimp(const std::string& path) {
  Assimp::Importer importer;
  keep_supported_readers(importer, path);
  // Keep Collada's up-axis handling on (see the top of this file) and say so explicitly.
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, false);
  // We keep positions only. Dropping normals, texture coordinates and colours first lets
  // aiProcess_JoinIdenticalVertices weld vertices by position, so faces that a CAD export split
  // at hard edges or UV seams share their vertices again (bop_panel.dae: 12386 -> 2613 vertices).
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS,
                              aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                  aiComponent_COLORS | aiComponent_TEXCOORDS |
                                  aiComponent_BONEWEIGHTS);
  // Node transforms are applied by walking the node tree ourselves (in double precision, with
  // instanced meshes repeated), rather than with aiProcess_PreTransformVertices.
  const unsigned flags = aiProcess_RemoveComponent | aiProcess_Triangulate |
                         aiProcess_JoinIdenticalVertices | aiProcess_SortByPType;
  // Read with validation only, check the data ourselves, then post-process: Assimp's
  // post-processing steps trust the indices (a PLY face "3 0 1 100000000" crashed them).
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  if (scene == nullptr) {
    std::string why = importer.GetErrorString();
    for (char& c : why) {
      if (c == '\n' || c == '\r') c = ' ';
    }
    throw Error("cannot load mesh '" + path + "': " + why +
                " (is it a valid mesh file in a format Assimp reads?)");
  }
  validate_scene(scene, path);
  scene = importer.ApplyPostProcessing(flags);
  if (scene == nullptr) {
    throw Error("cannot load mesh '" + path + "': " + importer.GetErrorString());
  }
  if (scene->mRootNode == nullptr) {
    throw Error("cannot load mesh '" + path + "': the file has no scene graph");
  }

  const std::string ext = lower_extension(path);
  Eigen::Matrix4d T_root = Eigen::Matrix4d::Identity();
  if (ext == ".dae" || ext == ".zae" || ext == ".gltf" || ext == ".glb") {
    T_root = y_up_to_z_up();
  } else if (ext == ".fbx") {
    T_root = fbx_to_z_up_metres(scene);
  }

  TriangleMesh mesh;
  collect(scene, scene->mRootNode, T_root, &mesh);
  if (mesh.triangles.empty()) {
    throw Error("cannot load mesh '" + path + "': it contains no triangles (" +
                std::to_string(scene->mNumMeshes) + " mesh(es) of points or lines only)");
  }
  check_vertices(mesh, path);
  return mesh;
}

bool write_all(int fd, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

bool read_all(int fd, void* data, std::size_t size) {
  char* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = ::read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

// Assimp 5.2 (Debian) still crashes, or allocates whatever a count asks for, on some malformed
// files of the formats we read with it (docs/fuzzing.md, fuzz/findings/). Its readers therefore
// run in a child process under an address-space limit; the child sends the mesh back through a
// pipe. A crash or exhausted memory in the child becomes one Error naming the file.
TriangleMesh load_mesh_isolated(const std::string& path) {
  std::error_code ec;
  const std::uintmax_t file_bytes = fs::file_size(path, ec);
  int fds[2];
  if (::pipe(fds) != 0) throw Error("cannot load mesh '" + path + "': pipe() failed");
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error("cannot load mesh '" + path + "': fork() failed");
  }
  if (pid == 0) {  // child: read, send, leave without running the parent's atexit handlers
    ::close(fds[0]);
    // 1 GB plus 64 bytes of address space per byte of file beyond what the process maps now.
    struct rlimit lim;
    const double budget = 1024.0 * 1024 * 1024 + 64.0 * static_cast<double>(file_bytes);
    std::size_t mapped = 0;
    if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
      unsigned long pages = 0;
      if (std::fscanf(f, "%lu", &pages) == 1)
        mapped = pages * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
      std::fclose(f);
    }
    lim.rlim_cur = lim.rlim_max = static_cast<rlim_t>(mapped + budget);
    ::setrlimit(RLIMIT_AS, &lim);
    std::uint8_t status = 1;
    std::string message;
    TriangleMesh mesh;
    try {
      mesh = load_mesh_assimp(path);
      status = 0;
    } catch (const Error& e) {
      message = e.what();
    } catch (const std::bad_alloc&) {
      message = "cannot load mesh '" + path + "': it asks for more memory than its " +
                std::to_string(file_bytes) + " bytes justify (a malformed count?)";
    } catch (const std::exception& e) {
      message = "cannot load mesh '" + path + "': " + e.what();
    }
    bool ok = write_all(fds[1], &status, 1);
    if (status == 0) {
      const std::uint64_t nv = mesh.vertices.size(), nt = mesh.triangles.size();
      ok = ok && write_all(fds[1], &nv, sizeof nv) && write_all(fds[1], &nt, sizeof nt) &&
           write_all(fds[1], mesh.vertices.data(), nv * sizeof(Eigen::Vector3f)) &&
           write_all(fds[1], mesh.triangles.data(), nt * sizeof(Eigen::Vector3i));
    } else {
      const std::uint64_t n = message.size();
      ok = ok && write_all(fds[1], &n, sizeof n) && write_all(fds[1], message.data(), n);
    }
    ::close(fds[1]);
    ::_exit(ok ? 0 : 3);
  }
  ::close(fds[1]);
  std::uint8_t status = 255;
  TriangleMesh mesh;
  std::string message;
  bool got = read_all(fds[0], &status, 1);
  if (got && status == 0) {
    std::uint64_t nv = 0, nt = 0;
    got = read_all(fds[0], &nv, sizeof nv) && read_all(fds[0], &nt, sizeof nt) &&
          nv <= (1ull << 31) && nt <= (1ull << 31);
    if (got) {
      mesh.vertices.resize(nv);
      mesh.triangles.resize(nt);
      got = read_all(fds[0], mesh.vertices.data(), nv * sizeof(Eigen::Vector3f)) &&
            read_all(fds[0], mesh.triangles.data(), nt * sizeof(Eigen::Vector3i));
    }
  } else if (got) {
    std::uint64_t n = 0;
    got = read_all(fds[0], &n, sizeof n) && n <= 65536;
    if (got) {
      message.resize(n);
      got = read_all(fds[0], message.data(), n);
    }
  }
  ::close(fds[0]);
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(wstatus)) {
    throw Error("cannot load mesh '" + path + "': the mesh reader (Assimp) crashed on it (signal " +
                std::to_string(WTERMSIG(wstatus)) + "): the file is malformed");
  }
  if (!got) {
    throw Error("cannot load mesh '" + path + "': the mesh reader (Assimp) failed on it");
  }
  if (status != 0) throw Error(message);
  return mesh;
}

}  // namespace

void save_mesh(const std::string& path, const TriangleMesh& mesh) {
  const std::string ext = lower_extension(path);
  if (ext != ".ply" && ext != ".obj") {
    throw Error("cannot save mesh '" + path + "': unsupported extension '" + ext +
                "' (use .ply or .obj)");
  }
  const int n = static_cast<int>(mesh.vertices.size());
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    if (t.minCoeff() < 0 || t.maxCoeff() >= n) {
      throw Error("cannot save mesh '" + path + "': triangle " + std::to_string(i) +
                  " refers to a vertex outside 0.." + std::to_string(n - 1));
    }
  }

  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path + "' for writing");
    if (ext == ".ply") {
      write_ply(f, mesh);
    } else {
      write_obj(f, mesh);
    }
    f.close();
    if (!f) throw Error("failed writing mesh '" + path + "' (disk full?)");
  }
  out.commit();
}

}  // namespace sonar3d
