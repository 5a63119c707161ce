// Mesh import/export (io/mesh_io) and procedural meshes (sim/reference_objects).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/mesh.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/sim/reference_objects.hpp"

namespace fs = std::filesystem;
using sonar3d::TriangleMesh;

namespace {

constexpr double kPi = 3.14159265358979323846;

const std::string kMeshDir = std::string(SONAR3D_SOURCE_DIR) + "/data/meshes/";

// Divergence theorem: V = 1/6 sum a . (b x c). Positive iff the closed surface faces outward.
double signed_volume(const TriangleMesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3d a = m.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = m.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = m.vertices[t[2]].cast<double>();
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

// Closed and consistently oriented: each directed edge occurs once and its reverse once, i.e. every
// edge is shared by exactly two triangles that traverse it in opposite directions.
bool closed_and_oriented(const TriangleMesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    if (count != 1) return false;
    const auto reverse = directed.find({edge.second, edge.first});
    if (reverse == directed.end() || reverse->second != 1) return false;
  }
  return true;
}

Eigen::Vector3d extent(const TriangleMesh& m) { return m.bounding_box().sizes().cast<double>(); }

// A per-test path in the temp directory (tests run in parallel processes under ctest).
fs::path temp_path(const std::string& suffix) {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  return fs::temp_directory_path() / ("sonar3d_test_mesh_" + std::string(info->name()) + "_" +
                                      std::to_string(::getpid()) + suffix);
}

void write_file(const fs::path& path, const std::string& contents) {
  std::ofstream f(path, std::ios::binary);
  f << contents;
  ASSERT_TRUE(f.good()) << path;
}

// A minimal Collada 1.4.1 document holding `m` in a single node; `up_axis` empty omits the tag.
std::string collada_document(const TriangleMesh& m, const std::string& up_axis, double meter) {
  std::ostringstream os;
  os << R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="u" meter=")"
     << meter << "\"/>";
  if (!up_axis.empty()) os << "<up_axis>" << up_axis << "</up_axis>";
  os << R"(</asset>
  <library_geometries><geometry id="g" name="g"><mesh>
    <source id="g-pos"><float_array id="g-pos-array" count=")"
     << 3 * m.vertices.size() << "\">";
  for (const auto& v : m.vertices) os << v.x() << ' ' << v.y() << ' ' << v.z() << ' ';
  os << R"(</float_array>
      <technique_common><accessor source="#g-pos-array" count=")"
     << m.vertices.size() << R"(" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="g-vtx"><input semantic="POSITION" source="#g-pos"/></vertices>
    <triangles count=")"
     << m.triangles.size() << R"("><input semantic="VERTEX" source="#g-vtx" offset="0"/><p>)";
  for (const auto& t : m.triangles) os << t[0] << ' ' << t[1] << ' ' << t[2] << ' ';
  os << R"(</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s" name="s">
    <node id="n" name="n"><instance_geometry url="#g"/></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
)";
  return os.str();
}

std::string base64(const std::string& bytes) {
  static const char* kTable = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t n = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) n |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) n |= static_cast<unsigned char>(bytes[i + 2]);
    out += kTable[(n >> 18) & 63];
    out += kTable[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kTable[n & 63] : '=';
  }
  return out;
}

// A minimal glTF 2.0 document (y up, metres by the spec) with `m` embedded as a data URI.
std::string gltf_document(const TriangleMesh& m) {
  std::string buffer;
  Eigen::Vector3f lo = m.bounding_box().min(), hi = m.bounding_box().max();
  for (const auto& v : m.vertices) buffer.append(reinterpret_cast<const char*>(v.data()), 12);
  const size_t index_offset = buffer.size();
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = static_cast<uint32_t>(t[k]);
      buffer.append(reinterpret_cast<const char*>(&i), 4);
    }
  }
  std::ostringstream os;
  os << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": )"
     << buffer.size() << R"(, "uri": "data:application/octet-stream;base64,)" << base64(buffer)
     << R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": )"
     << index_offset << R"(},
                  {"buffer": 0, "byteOffset": )"
     << index_offset << R"(, "byteLength": )" << buffer.size() - index_offset << R"(}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": )"
     << m.vertices.size() << R"(, "type": "VEC3", "min": [)" << lo.x() << ", " << lo.y() << ", "
     << lo.z() << "], \"max\": [" << hi.x() << ", " << hi.y() << ", " << hi.z() << R"(]},
                {"bufferView": 1, "componentType": 5125, "count": )"
     << 3 * m.triangles.size() << R"(, "type": "SCALAR"}]}
)";
  return os.str();
}

// A 1 x 2 x 3 m box (x, y, z) with a corner at the origin: distinct extents show any axis swap.
TriangleMesh corner_box() {
  TriangleMesh m = sonar3d::make_box(1.0, 2.0, 3.0);
  m.transform(Eigen::Isometry3d(Eigen::Translation3d(0.5, 1.0, 1.5)));
  return m;
}

void expect_extent(const TriangleMesh& m, const Eigen::Vector3d& expected, double tol) {
  const Eigen::Vector3d e = extent(m);
  EXPECT_NEAR(e.x(), expected.x(), tol);
  EXPECT_NEAR(e.y(), expected.y(), tol);
  EXPECT_NEAR(e.z(), expected.z(), tol);
}

// Runs f, expects a sonar3d::Error whose message contains every string in `needles`.
template <typename F>
void expect_error_mentioning(F&& f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "expected sonar3d::Error";
  } catch (const sonar3d::Error& e) {
    for (const auto& n : needles) {
      EXPECT_NE(std::string(e.what()).find(n), std::string::npos)
          << "message '" << e.what() << "' does not mention '" << n << "'";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// load_mesh

// bop_panel.dae declares <up_axis>Z_UP</up_axis> and <unit meter="1"/>. Its node matrices turn
// the 0.8 x 0.5 x 0.36 m geometry a quarter turn about z, so in the file's own z-up frame it is
// 0.5 x 0.8 x 0.36 m (x, y, z) with its base on z = 0 (checked by an independent parse of the
// <matrix> and <float_array> elements). Had Assimp's rotation to y-up been kept it would be
// 0.5 x 0.36 x 0.8 m and centred on z = 0.
TEST(MeshIo, BopPanelKeepsZUpAndMetres) {
  const TriangleMesh m = sonar3d::load_mesh(kMeshDir + "bop_panel.dae");
  ASSERT_FALSE(m.empty());
  const Eigen::AlignedBox3f box = m.bounding_box();
  expect_extent(m, {0.5, 0.8, 0.36}, 0.01);
  EXPECT_NEAR(box.min().z(), 0.0, 1e-4);
  EXPECT_NEAR(box.max().z(), 0.36, 0.01);
  EXPECT_NEAR(box.center().x(), 0.0, 0.01);
  EXPECT_NEAR(box.center().y(), 0.0, 0.01);
  // Vertices are welded by position (normals and UVs dropped), not one per face corner.
  EXPECT_LT(m.vertices.size(), m.triangles.size());
}

// Every shared mesh is a Z_UP, meter="1" Blender export; expected extents come from the file
// contents (positions and node matrices), so loading must not rotate or scale them.
TEST(MeshIo, SharedMeshesLoadInTheirDeclaredFrame) {
  struct Case {
    const char* file;
    Eigen::Vector3d size;
  };
  const Case cases[] = {{"hot_stab.dae", {0.515, 0.0602, 0.1122}},
                        {"munkholmen_seabed.dae", {2386.02, 1478.55, 65.35}},
                        {"sonobuoy.dae", {0.1263, 0.127, 0.9133}},
                        {"valve.dae", {0.1449, 0.145, 0.05}}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.file);
    const TriangleMesh m = sonar3d::load_mesh(kMeshDir + c.file);
    EXPECT_GT(m.triangles.size(), 100u);
    expect_extent(m, c.size, std::max(0.002, 1e-4 * c.size.maxCoeff()));
  }
}

TEST(MeshIo, ColladaUpAxisAndUnitAreHonoured) {
  const TriangleMesh box = corner_box();  // file coordinates: 1 x 2 x 3
  struct Case {
    const char* up_axis;
    double meter;
    Eigen::Vector3d size;  // expected in our z-up frame, metres
  };
  const Case cases[] = {
      {"Z_UP", 1.0, {1, 2, 3}},            // kept as is
      {"Z_UP", 0.01, {0.01, 0.02, 0.03}},  // centimetres
      {"Y_UP", 1.0, {1, 3, 2}},            // file +y becomes +z
      {"", 1.0, {1, 3, 2}},                // no <up_axis>: Y_UP by the Collada spec
      {"X_UP", 1.0, {2, 3, 1}},            // file +x becomes +z
      {"Y_UP", 0.001, {0.001, 0.003, 0.002}},
  };
  const fs::path path = temp_path(".dae");
  for (const auto& c : cases) {
    SCOPED_TRACE(std::string("up_axis '") + c.up_axis + "' meter " + std::to_string(c.meter));
    write_file(path, collada_document(box, c.up_axis, c.meter));
    const TriangleMesh m = sonar3d::load_mesh(path.string());
    ASSERT_EQ(m.triangles.size(), 12u);
    expect_extent(m, c.size, 1e-5);
    // The conversions are rotations: the box keeps its outward orientation.
    EXPECT_NEAR(signed_volume(m), c.size.prod(), 1e-6 * std::max(1.0, c.size.prod()));
  }
  // The declared up direction points up after loading: the Y_UP box lies on z >= 0 because its
  // y range [0, 2] became our z range.
  write_file(path, collada_document(box, "Y_UP", 1.0));
  const Eigen::AlignedBox3f b = sonar3d::load_mesh(path.string()).bounding_box();
  EXPECT_NEAR(b.min().z(), 0.0, 1e-6);
  EXPECT_NEAR(b.max().z(), 2.0, 1e-6);
  fs::remove(path);
}

TEST(MeshIo, GltfIsYUpAndBecomesZUp) {
  const fs::path path = temp_path(".gltf");
  write_file(path, gltf_document(corner_box()));
  const TriangleMesh m = sonar3d::load_mesh(path.string());
  fs::remove(path);
  ASSERT_EQ(m.triangles.size(), 12u);
  expect_extent(m, {1, 3, 2}, 1e-5);
  EXPECT_NEAR(m.bounding_box().min().z(), 0.0, 1e-6);
  EXPECT_NEAR(signed_volume(m), 6.0, 1e-5);
}

TEST(MeshIo, MissingFileThrowsNamingPath) {
  const std::string path = temp_path("_does_not_exist.dae").string();
  expect_error_mentioning([&] { sonar3d::load_mesh(path); }, {path, "no such file"});
}

TEST(MeshIo, CorruptFileThrowsNamingPath) {
  const fs::path path = temp_path(".dae");
  write_file(path, "this is not a Collada file \x01\x02\x03 <<<< garbage >>>>\n");
  expect_error_mentioning([&] { sonar3d::load_mesh(path.string()); }, {path.string()});
  fs::remove(path);
}

TEST(MeshIo, TruncatedColladaThrowsNamingPath) {
  const fs::path path = temp_path(".dae");
  const std::string doc = collada_document(corner_box(), "Z_UP", 1.0);
  write_file(path, doc.substr(0, doc.size() / 2));
  expect_error_mentioning([&] { sonar3d::load_mesh(path.string()); }, {path.string()});
  fs::remove(path);
}

TEST(MeshIo, FileWithoutTrianglesThrowsNamingPath) {
  const fs::path path = temp_path(".obj");
  write_file(path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2\nl 2 3\n");
  expect_error_mentioning([&] { sonar3d::load_mesh(path.string()); }, {path.string()});
  fs::remove(path);
}

TEST(MeshIo, SaveLoadRoundTripPlyAndObj) {
  const TriangleMesh box = corner_box();
  for (const char* ext : {".ply", ".obj", ".PLY"}) {
    SCOPED_TRACE(ext);
    const fs::path path = temp_path(ext);
    sonar3d::save_mesh(path.string(), box);
    const TriangleMesh m = sonar3d::load_mesh(path.string());
    fs::remove(path);
    // No declared up axis in PLY or OBJ: coordinates come back exactly as written.
    EXPECT_EQ(m.triangles.size(), box.triangles.size());
    EXPECT_EQ(m.vertices.size(), box.vertices.size());
    EXPECT_TRUE(m.bounding_box().min().isApprox(box.bounding_box().min(), 1e-6));
    EXPECT_TRUE(m.bounding_box().max().isApprox(box.bounding_box().max(), 1e-6));
    EXPECT_NEAR(m.surface_area(), box.surface_area(), 1e-6);
    EXPECT_NEAR(signed_volume(m), 6.0, 1e-6);  // winding (outward normals) preserved
    EXPECT_TRUE(closed_and_oriented(m));
  }
}

TEST(MeshIo, SaveRoundTripKeepsACurvedMesh) {
  const TriangleMesh tank = sonar3d::make_reference_tank();
  const fs::path path = temp_path(".ply");
  sonar3d::save_mesh(path.string(), tank);
  const TriangleMesh m = sonar3d::load_mesh(path.string());
  fs::remove(path);
  EXPECT_EQ(m.triangles.size(), tank.triangles.size());
  EXPECT_NEAR(m.surface_area(), tank.surface_area(), 1e-6 * tank.surface_area());
  EXPECT_NEAR(signed_volume(m), signed_volume(tank), 1e-6);
}

TEST(MeshIo, SaveIsAtomicAndChecksItsArguments) {
  const fs::path dir = temp_path("_dir");
  fs::create_directories(dir);
  sonar3d::save_mesh((dir / "a.obj").string(), corner_box());
  sonar3d::save_mesh((dir / "a.obj").string(), sonar3d::make_box(1, 1, 1));  // replaces
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"a.obj"});  // no temporary left behind
  EXPECT_NEAR(signed_volume(sonar3d::load_mesh((dir / "a.obj").string())), 1.0, 1e-6);

  const std::string stl = (dir / "a.stl").string();
  expect_error_mentioning([&] { sonar3d::save_mesh(stl, corner_box()); }, {stl, ".ply"});
  const std::string nodir = (dir / "missing" / "a.ply").string();
  EXPECT_THROW(sonar3d::save_mesh(nodir, corner_box()), sonar3d::Error);
  TriangleMesh bad = corner_box();
  bad.triangles.emplace_back(0, 1, 99);
  expect_error_mentioning([&] { sonar3d::save_mesh((dir / "b.ply").string(), bad); }, {"b.ply"});
  EXPECT_FALSE(fs::exists(dir / "b.ply"));
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Primitives: area against the analytic value, closed and outward (volume > 0 and analytic).

TEST(Primitives, Sphere) {
  const double r = 0.7;
  const TriangleMesh m = sonar3d::make_sphere(r, 64);
  EXPECT_TRUE(closed_and_oriented(m));
  EXPECT_NEAR(m.surface_area() / (4 * kPi * r * r), 1.0, 0.01);
  EXPECT_NEAR(signed_volume(m) / (4.0 / 3.0 * kPi * r * r * r), 1.0, 0.01);
  expect_extent(m, {2 * r, 2 * r, 2 * r}, 1e-5);
  EXPECT_TRUE(m.bounding_box().center().isZero(1e-5));
}

TEST(Primitives, CylinderCappedAndOpen) {
  const double r = 0.3, h = 1.5;
  const TriangleMesh m = sonar3d::make_cylinder(r, h, 64);
  EXPECT_TRUE(closed_and_oriented(m));
  EXPECT_NEAR(m.surface_area() / (2 * kPi * r * h + 2 * kPi * r * r), 1.0, 0.01);
  EXPECT_NEAR(signed_volume(m) / (kPi * r * r * h), 1.0, 0.01);
  EXPECT_NEAR(m.bounding_box().min().z(), 0.0, 1e-7);
  EXPECT_NEAR(m.bounding_box().max().z(), h, 1e-6);

  const TriangleMesh open = sonar3d::make_cylinder(r, h, 64, false);
  EXPECT_FALSE(closed_and_oriented(open));
  EXPECT_NEAR(open.surface_area() / (2 * kPi * r * h), 1.0, 0.01);
  // Outward side: each triangle's normal points away from the axis.
  for (const auto& t : open.triangles) {
    const Eigen::Vector3f a = open.vertices[t[0]], b = open.vertices[t[1]], c = open.vertices[t[2]];
    const Eigen::Vector3f n = (b - a).cross(c - a);
    const Eigen::Vector3f centroid = (a + b + c) / 3.0f;
    EXPECT_GT(n.x() * centroid.x() + n.y() * centroid.y(), 0.0f);
  }
}

TEST(Primitives, Box) {
  const TriangleMesh m = sonar3d::make_box(1.0, 2.0, 3.0);
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_TRUE(closed_and_oriented(m));
  EXPECT_NEAR(m.surface_area(), 2 * (2 + 3 + 6), 1e-5);
  EXPECT_NEAR(signed_volume(m), 6.0, 1e-5);
  expect_extent(m, {1, 2, 3}, 1e-6);
  EXPECT_TRUE(m.bounding_box().center().isZero(1e-6));
}

TEST(Primitives, Torus) {
  const double R = 1.0, r = 0.25;
  const TriangleMesh m = sonar3d::make_torus(R, r, 96, 48);
  EXPECT_TRUE(closed_and_oriented(m));
  EXPECT_NEAR(m.surface_area() / (4 * kPi * kPi * R * r), 1.0, 0.01);
  EXPECT_NEAR(signed_volume(m) / (2 * kPi * kPi * R * r * r), 1.0, 0.01);
  expect_extent(m, {2 * (R + r), 2 * (R + r), 2 * r}, 1e-5);
  // Default tessellation is still within 1 % in area.
  const TriangleMesh coarse = sonar3d::make_torus(R, r);
  EXPECT_NEAR(coarse.surface_area() / (4 * kPi * kPi * R * r), 1.0, 0.01);
}

TEST(Primitives, FrustumAndPyramid) {
  const double b = 2.0, t = 0.6, h = 2.0;
  const TriangleMesh m = sonar3d::make_frustum(b, t, h);
  EXPECT_TRUE(closed_and_oriented(m));
  const double slant = std::hypot(h, 0.5 * (b - t));
  EXPECT_NEAR(m.surface_area(), b * b + t * t + 4 * 0.5 * (b + t) * slant, 1e-5);
  EXPECT_NEAR(signed_volume(m), h / 3 * (b * b + t * t + b * t), 1e-5);
  EXPECT_NEAR(m.bounding_box().min().z(), 0.0, 1e-7);

  const TriangleMesh pyramid = sonar3d::make_frustum(b, 0.0, h);
  EXPECT_TRUE(closed_and_oriented(pyramid));
  EXPECT_NEAR(signed_volume(pyramid), h / 3 * b * b, 1e-5);
}

TEST(Primitives, PlaneFacesUp) {
  const TriangleMesh m = sonar3d::make_plane(3.0, 2.0);
  EXPECT_NEAR(m.surface_area(), 6.0, 1e-6);
  for (const auto& t : m.triangles) {
    const Eigen::Vector3f n =
        (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
    EXPECT_GT(n.z(), 0.0f);
  }
  EXPECT_EQ(m.bounding_box().sizes().z(), 0.0f);
}

TEST(Primitives, InvalidParametersAreNamed) {
  expect_error_mentioning([] { sonar3d::make_sphere(-1.0); }, {"radius"});
  expect_error_mentioning([] { sonar3d::make_cylinder(1.0, 1.0, 2); }, {"segments"});
  expect_error_mentioning([] { sonar3d::make_box(1.0, 0.0, 1.0); }, {"sy"});
  expect_error_mentioning([] { sonar3d::make_torus(0.5, 0.5); }, {"minor_radius"});
  expect_error_mentioning([] { sonar3d::make_frustum(1.0, -0.1, 1.0); }, {"top_width"});
  expect_error_mentioning([] { sonar3d::make_plane(NAN, 1.0); }, {"sx"});
}

// ---------------------------------------------------------------------------------------------
// Reference objects (thesis sec. 4.5.1, Fig. 4.11): sizes documented in reference_objects.cpp.

TEST(ReferenceObjects, SizesBaseAndOrientation) {
  struct Case {
    const char* name;
    Eigen::Vector3d size;
  };
  const Case cases[] = {{"sphere", {1.0, 1.0, 1.0}},
                        {"tank", {0.5, 0.5, 1.2}},
                        {"pillar", {2.0, 2.0, 2.5}},
                        {"riser", {2.0, 1.0, 2.0}}};
  ASSERT_EQ(sonar3d::reference_object_names().size(), std::size(cases));
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const TriangleMesh m = sonar3d::make_reference_object(c.name);
    const Eigen::AlignedBox3f box = m.bounding_box();
    expect_extent(m, c.size, 1e-4);
    EXPECT_NEAR(box.min().z(), 0.0, 1e-6);     // stands on z = 0
    EXPECT_NEAR(box.center().x(), 0.0, 1e-4);  // centred on the z axis
    EXPECT_NEAR(box.center().y(), 0.0, 1e-4);
    EXPECT_LT(m.triangles.size(), 40000u);
    // Built from closed outward parts: every edge paired, positive volume.
    EXPECT_TRUE(closed_and_oriented(m));
    EXPECT_GT(signed_volume(m), 0.0);
  }
}

TEST(ReferenceObjects, ThesisDimensions) {
  // Fig. 4.11-a: 1 m diameter sphere.
  const TriangleMesh sphere = sonar3d::make_reference_sphere();
  EXPECT_NEAR(sphere.surface_area() / (kPi * 1.0 * 1.0), 1.0, 0.01);
  EXPECT_NEAR(signed_volume(sphere) / (kPi / 6.0), 1.0, 0.01);
  // Fig. 4.11-b: 50 cm diameter tank; the body is the widest part at mid-height.
  const TriangleMesh tank = sonar3d::make_reference_tank();
  float tank_width_at_half = 0.0f;
  for (const auto& v : tank.vertices) {
    if (v.z() < 1.0f) tank_width_at_half = std::max(tank_width_at_half, 2 * v.head<2>().norm());
  }
  EXPECT_NEAR(tank_width_at_half, 0.5, 1e-4);
  // Fig. 4.11-c: 2 m wide base, 60 cm wide top.
  const TriangleMesh pillar = sonar3d::make_reference_pillar();
  const float top = pillar.bounding_box().max().z();
  Eigen::AlignedBox3f top_face;
  for (const auto& v : pillar.vertices) {
    if (v.z() > top - 1e-4f) top_face.extend(v);
  }
  EXPECT_NEAR(top_face.sizes().x(), 0.6, 1e-4);
  EXPECT_NEAR(top_face.sizes().y(), 0.6, 1e-4);
  // Fig. 4.11-d: 40 cm diameter buoyancies; vertices at 0.2 m from the axis x = 0.8 m.
  const TriangleMesh riser = sonar3d::make_reference_riser();
  int on_buoyancy = 0;
  for (const auto& v : riser.vertices) {
    if (std::abs(std::hypot(v.x() - 0.8f, v.y()) - 0.2f) < 1e-4f && v.z() > 1.0f) ++on_buoyancy;
  }
  EXPECT_GE(on_buoyancy, 64);
}

TEST(ReferenceObjects, ByNameMatchesFunctionsAndUnknownNamesAreListed) {
  EXPECT_EQ(sonar3d::make_reference_object("riser").triangles.size(),
            sonar3d::make_reference_riser().triangles.size());
  expect_error_mentioning([] { sonar3d::make_reference_object("bottle"); },
                          {"bottle", "sphere", "tank", "pillar", "riser"});
}

}  // namespace
