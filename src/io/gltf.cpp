#include "sonar3d/io/gltf.hpp"

#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {

constexpr int kFloat = 5126, kUnsignedByte = 5121, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

// The binary chunk under construction: buffer views appended 4-byte aligned.
struct Bin {
  std::vector<char> bytes;
  nlohmann::json views = nlohmann::json::array();
  nlohmann::json accessors = nlohmann::json::array();

  int view(const void* data, std::size_t size, int target) {
    while (bytes.size() % 4 != 0) bytes.push_back(0);
    const std::size_t offset = bytes.size();
    bytes.resize(offset + size);
    if (size > 0) std::memcpy(bytes.data() + offset, data, size);
    views.push_back(
        {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", size}, {"target", target}});
    return static_cast<int>(views.size()) - 1;
  }
  int accessor(int view, int component, std::size_t count, const char* type, bool normalized,
               nlohmann::json min = nullptr, nlohmann::json max = nullptr) {
    nlohmann::json a = {
        {"bufferView", view}, {"componentType", component}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    if (!min.is_null()) a["min"] = min;
    if (!max.is_null()) a["max"] = max;
    accessors.push_back(a);
    return static_cast<int>(accessors.size()) - 1;
  }
};

// Area-weighted vertex normals (unit; up for a vertex no triangle touches).
std::vector<Eigen::Vector3f> vertex_normals(const TriangleMesh& m) {
  std::vector<Eigen::Vector3f> n(m.vertices.size(), Eigen::Vector3f::Zero());
  for (const Eigen::Vector3i& t : m.triangles) {
    const Eigen::Vector3f a = m.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3f c = (m.vertices[static_cast<std::size_t>(t[1])] - a)
                                  .cross(m.vertices[static_cast<std::size_t>(t[2])] - a);
    for (int k = 0; k < 3; ++k) n[static_cast<std::size_t>(t[k])] += c;
  }
  for (Eigen::Vector3f& v : n) {
    const float len = v.norm();
    v = len > 0 ? Eigen::Vector3f(v / len) : Eigen::Vector3f::UnitZ();
  }
  return n;
}

void append_u32(std::string& s, std::uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);  // GLB is little-endian, as every platform sonar3d builds on
  s.append(b, 4);
}

}  // namespace

Eigen::Matrix4d enu_to_gltf() {
  Eigen::Matrix4d R = Eigen::Matrix4d::Zero();
  R(0, 0) = 1;   // x_gltf = East
  R(1, 2) = 1;   // y_gltf = Up
  R(2, 1) = -1;  // z_gltf = −North
  R(3, 3) = 1;
  return R;
}

void write_glb(const std::filesystem::path& path, const GltfScene& scene) {
  const std::string where = "glTF '" + path.string() + "'";
  Bin bin;
  nlohmann::json meshes = nlohmann::json::array(), materials = nlohmann::json::array();
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const GltfMesh& gm = scene.meshes[i];
    const TriangleMesh& m = gm.mesh;
    const std::string what = where + ": mesh " + std::to_string(i) + " '" + gm.name + "'";
    require(!m.vertices.empty() && !m.triangles.empty(), what + " is empty");
    require(gm.colors.empty() || gm.colors.size() == m.vertices.size(),
            what + ": " + std::to_string(gm.colors.size()) + " colours for " +
                std::to_string(m.vertices.size()) + " vertices");
    require(m.vertices.size() < (1ull << 31), what + ": too many vertices for glTF");
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f hi = -lo;
    for (const Eigen::Vector3f& v : m.vertices) {
      require(v.allFinite(), what + ": a vertex is not finite");
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    std::vector<std::uint32_t> idx;
    idx.reserve(m.triangles.size() * 3);
    const long long n = static_cast<long long>(m.vertices.size());
    for (const Eigen::Vector3i& t : m.triangles) {
      for (int k = 0; k < 3; ++k) {
        require(t[k] >= 0 && t[k] < n,
                what + ": a triangle refers to a vertex outside 0.." + std::to_string(n - 1));
        idx.push_back(static_cast<std::uint32_t>(t[k]));
      }
    }
    const std::vector<Eigen::Vector3f> normals = vertex_normals(m);
    nlohmann::json attributes;
    attributes["POSITION"] = bin.accessor(
        bin.view(m.vertices.data(), m.vertices.size() * 12, kArrayBuffer), kFloat,
        m.vertices.size(), "VEC3", false, {lo.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), hi.z()});
    attributes["NORMAL"] = bin.accessor(bin.view(normals.data(), normals.size() * 12, kArrayBuffer),
                                        kFloat, normals.size(), "VEC3", false);
    if (!gm.colors.empty()) {
      // Each colour padded to 4 bytes: glTF requires vertex attribute elements 4-byte aligned.
      std::vector<std::uint8_t> rgba(gm.colors.size() * 4, 255);
      for (std::size_t k = 0; k < gm.colors.size(); ++k) {
        for (int c = 0; c < 3; ++c)
          rgba[k * 4 + static_cast<std::size_t>(c)] = gm.colors[k][static_cast<std::size_t>(c)];
      }
      attributes["COLOR_0"] = bin.accessor(bin.view(rgba.data(), rgba.size(), kArrayBuffer),
                                           kUnsignedByte, gm.colors.size(), "VEC4", true);
    }
    const int indices = bin.accessor(bin.view(idx.data(), idx.size() * 4, kElementArrayBuffer),
                                     kUnsignedInt, idx.size(), "SCALAR", false);
    materials.push_back(
        {{"name", gm.name},
         {"doubleSided", true},
         {"pbrMetallicRoughness",
          {{"baseColorFactor",
            {gm.base_color[0], gm.base_color[1], gm.base_color[2], gm.base_color[3]}},
           {"metallicFactor", 0.0},
           {"roughnessFactor", 1.0}}}});
    meshes.push_back({{"name", gm.name},
                      {"primitives",
                       {{{"attributes", attributes},
                         {"indices", indices},
                         {"material", static_cast<int>(i)},
                         {"mode", 4}}}}});
  }
  nlohmann::json nodes = nlohmann::json::array();
  const int num_nodes = static_cast<int>(scene.nodes.size());
  for (std::size_t i = 0; i < scene.nodes.size(); ++i) {
    const GltfNode& n = scene.nodes[i];
    const std::string what = where + ": node " + std::to_string(i) + " '" + n.name + "'";
    require(n.matrix.allFinite(), what + ": matrix not finite");
    nlohmann::json j = {{"name", n.name}};
    if (!n.matrix.isIdentity(0)) {
      nlohmann::json m = nlohmann::json::array();
      for (int c = 0; c < 4; ++c) {  // glTF matrices are column-major
        for (int r = 0; r < 4; ++r) m.push_back(n.matrix(r, c));
      }
      j["matrix"] = m;
    }
    if (n.mesh >= 0) {
      require(n.mesh < static_cast<int>(scene.meshes.size()), what + ": mesh index out of range");
      j["mesh"] = n.mesh;
    }
    if (!n.children.empty()) {
      for (int c : n.children) {
        require(c >= 0 && c < num_nodes && c != static_cast<int>(i),
                what + ": child index out of range");
      }
      j["children"] = n.children;
    }
    nodes.push_back(j);
  }
  for (int r : scene.roots) require(r >= 0 && r < num_nodes, where + ": root index out of range");
  require(bin.bytes.size() < (1ull << 31), where + ": more than 2 GB of geometry");
  while (bin.bytes.size() % 4 != 0) bin.bytes.push_back(0);

  nlohmann::json gltf = {{"asset", {{"version", "2.0"}, {"generator", "sonar3d"}}},
                         {"scene", 0},
                         {"scenes", {{{"nodes", scene.roots}}}},
                         {"nodes", nodes}};
  if (!meshes.empty()) {
    gltf["meshes"] = meshes;
    gltf["materials"] = materials;
    gltf["accessors"] = bin.accessors;
    gltf["bufferViews"] = bin.views;
    gltf["buffers"] = {{{"byteLength", bin.bytes.size()}}};
  }
  std::string json = gltf.dump();
  while (json.size() % 4 != 0) json.push_back(' ');  // the JSON chunk is padded with spaces

  std::string header;
  const std::size_t total = 12 + 8 + json.size() + (bin.bytes.empty() ? 0 : 8 + bin.bytes.size());
  append_u32(header, 0x46546C67);  // "glTF"
  append_u32(header, 2);
  append_u32(header, static_cast<std::uint32_t>(total));
  append_u32(header, static_cast<std::uint32_t>(json.size()));
  append_u32(header, 0x4E4F534A);  // "JSON"

  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    require(static_cast<bool>(f), "cannot open " + where + " for writing");
    f.write(header.data(), static_cast<std::streamsize>(header.size()));
    f.write(json.data(), static_cast<std::streamsize>(json.size()));
    if (!bin.bytes.empty()) {
      std::string chunk;
      append_u32(chunk, static_cast<std::uint32_t>(bin.bytes.size()));
      append_u32(chunk, 0x004E4942);  // "BIN\0"
      f.write(chunk.data(), 8);
      f.write(bin.bytes.data(), static_cast<std::streamsize>(bin.bytes.size()));
    }
    f.close();
    require(static_cast<bool>(f), "failed writing " + where + " (disk full?)");
  }
  out.commit();
}

}  // namespace sonar3d
