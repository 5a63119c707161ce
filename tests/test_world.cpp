// World models (thesis sec. 6.3.3): seabed height fields, points explained by placed models,
// pipelines between structures, the glTF scene read back by Assimp, graph.json, bad inputs.
#include <assimp/scene.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/io/gltf.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/world_model.hpp"
#include "test_support.hpp"

namespace sonar3d {
namespace {

namespace fs = std::filesystem;
using test::expect_error;
using test::temp_dir;

// A smooth synthetic seabed, m.
double terrain(double x, double y) {
  return 0.2 * std::sin(2 * M_PI * x / 6) + 0.1 * std::cos(2 * M_PI * y / 5) - 1.0;
}

// Points every `step` over [x0, x1] × [y0, y1] on `height`, jittered horizontally.
PointCloud surface_points(double x0, double x1, double y0, double y1, double step,
                          const std::function<double(double, double)>& height) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> j(-0.4 * step, 0.4 * step);
  PointCloud c;
  for (double x = x0; x <= x1; x += step) {
    for (double y = y0; y <= y1; y += step) {
      const double px = x + j(rng), py = y + j(rng);
      c.points.emplace_back(static_cast<float>(px), static_cast<float>(py),
                            static_cast<float>(height(px, py)));
    }
  }
  return c;
}

const aiNode* find_node(const aiNode* n, const std::string& name);

// A unit cube [−0.5, 0.5]² × [0, 1] (model frame: base at z = 0).
TriangleMesh cube() {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 1.0f : 0.0f);
  }
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.triangles.emplace_back(t[0], t[1], t[2]);
  return m;
}

Eigen::Isometry3d pose(double x, double y, double z, double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translate(Eigen::Vector3d(x, y, z));
  T.rotate(Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()));
  return T;
}

WorldObject object(const std::string& id, const TriangleMesh& mesh, const Eigen::Isometry3d& T) {
  WorldObject o;
  o.id = id;
  o.model = id.substr(0, id.rfind('_'));
  o.T_world_model = T;
  o.score_m = 0.1;
  o.residual_median_m = 0.01;
  o.mesh_model = std::make_shared<const TriangleMesh>(mesh);
  return o;
}

// Surface samples of the placed mesh, appended to the cloud.
void add_model_points(PointCloud& c, const TriangleMesh& mesh_model, const Eigen::Isometry3d& T) {
  for (const Eigen::Vector3f& p : sample_surface(mesh_model, 20000, 5)) {
    c.points.push_back((T * p.cast<double>()).cast<float>());
  }
}

TEST(WorldSeabed, HeightFieldOfAKnownSurfaceWithinTolerance) {
  const PointCloud c = surface_points(0, 12, 0, 10, 0.02, terrain);
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05, 0.2, 1.0};
  const WorldModel w = build_world_model(c, {}, cfg);
  ASSERT_EQ(w.seabed.size(), 3u);
  EXPECT_EQ(w.seabed_points, c.size());
  const double tolerance[3] = {0.01, 0.01, 0.03};  // grid interpolation of the sine at 1 m
  for (std::size_t k = 0; k < 3; ++k) {
    const SeabedLod& lod = w.seabed[k];
    EXPECT_NEAR(lod.cell_m, cfg.seabed.lod_cells_m[k], 1e-9);
    // A vertex per valid cell; the data cover the map but for its edge cells (the region ends
    // mid-cell): every block away from the edge is meshed, two triangles each.
    EXPECT_EQ(lod.mesh.vertices.size(), lod.heights.num_valid());
    const auto blocks = [&](int border) {
      return 2u * static_cast<std::size_t>(lod.heights.rows - 1 - 2 * border) *
             static_cast<std::size_t>(lod.heights.cols - 1 - 2 * border);
    };
    EXPECT_GE(lod.mesh.triangles.size(), blocks(1));
    EXPECT_LE(lod.mesh.triangles.size(), blocks(0));
    for (int r = 1; r + 1 < lod.heights.rows; ++r) {
      for (int c = 1; c + 1 < lod.heights.cols; ++c) ASSERT_TRUE(lod.heights.valid(r, c));
    }
    std::vector<double> err;
    for (const Eigen::Vector3f& p : sample_surface(lod.mesh, 20000, 1)) {
      err.push_back(std::abs(p.z() - terrain(p.x(), p.y())));
    }
    std::nth_element(err.begin(), err.begin() + static_cast<std::ptrdiff_t>(err.size() / 2),
                     err.end());
    EXPECT_LT(err[err.size() / 2], tolerance[k]) << "lod " << k;
    // Normals up: triangles counter-clockwise seen from above.
    for (const Eigen::Vector3i& t : lod.mesh.triangles) {
      const Eigen::Vector3f n = (lod.mesh.vertices[t[1]] - lod.mesh.vertices[t[0]])
                                    .cross(lod.mesh.vertices[t[2]] - lod.mesh.vertices[t[0]]);
      ASSERT_GT(n.z(), 0);
    }
  }
}

TEST(WorldSeabed, HolesStayHolesAndThreeValidCellsMakeOneTriangle) {
  ElevationMap m;
  m.cell_m = 1;
  m.rows = 2;
  m.cols = 3;
  m.z = {0, 0, 0, 0, 0, ElevationMap::kNoData};
  const TriangleMesh mesh = height_field_mesh(m);
  EXPECT_EQ(mesh.vertices.size(), 5u);
  EXPECT_EQ(mesh.triangles.size(), 3u);  // left block: 2, right block (3 valid): 1
  // A coarser level needs enough of its cells observed.
  ElevationMap fine;
  fine.cell_m = 0.5;
  fine.rows = fine.cols = 4;
  fine.z.assign(16, ElevationMap::kNoData);
  fine.z[0] = 1;              // block (0, 0): 1 of 4
  fine.z[2] = fine.z[3] = 2;  // block (0, 1): 2 of 4
  fine.z[6] = 4;
  const ElevationMap coarse = downsample_heights(fine, 2, 0.5);
  EXPECT_FALSE(coarse.valid(0, 0));
  ASSERT_TRUE(coarse.valid(0, 1));
  EXPECT_FLOAT_EQ(coarse.at(0, 1), 2.0f);  // median of 2, 2, 4
  EXPECT_FALSE(coarse.valid(1, 0));
}

TEST(WorldSeabed, PointsOnAPlacedModelAreExcluded) {
  PointCloud c = surface_points(0, 6, 0, 6, 0.02, [](double, double) { return 0.0; });
  const std::size_t ground = c.size();
  const TriangleMesh box = cube();
  const Eigen::Isometry3d T = pose(3, 3, 0, 30);
  add_model_points(c, box, T);
  const std::vector<WorldObject> objs = {object("box_0", box, T)};
  const std::vector<std::uint8_t> ex = explained_points(c, objs, 0.1);
  for (std::size_t i = ground; i < c.size(); ++i) ASSERT_TRUE(ex[i]) << "model point " << i;
  std::size_t ground_explained = 0;
  for (std::size_t i = 0; i < ground; ++i) {
    const Eigen::Vector3d q = T.inverse() * c.points[i].cast<double>();
    const bool near = std::abs(q.x()) < 0.61 && std::abs(q.y()) < 0.61;
    if (!near) {
      ASSERT_FALSE(ex[i]) << "seabed point " << i << " far from the model";
    }
    ground_explained += ex[i];
  }
  EXPECT_GT(ground_explained, 0u);  // the seabed under the footprint goes with the model

  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05, 0.2};
  const WorldModel filled = build_world_model(c, objs, cfg);
  EXPECT_GT(filled.filled_cells, 0u);
  for (const SeabedLod& lod : filled.seabed) {
    for (const Eigen::Vector3f& v : lod.mesh.vertices) ASSERT_NEAR(v.z(), 0, 1e-4);
  }
  cfg.seabed.fill_footprints = false;
  const WorldModel holes = build_world_model(c, objs, cfg);
  EXPECT_EQ(holes.filled_cells, 0u);
  for (const Eigen::Vector3f& v : holes.seabed[0].mesh.vertices) {
    const Eigen::Vector3d q = T.inverse() * v.cast<double>();
    ASSERT_FALSE(std::abs(q.x()) < 0.5 && std::abs(q.y()) < 0.5) << "a vertex under the model";
  }
}

// Two boxes with a half-buried pipe between them (radius 0.2 m, crest 0.15 m above the seabed),
// on a sloping seabed.
PointCloud pipeline_site(bool with_pipe, std::vector<WorldObject>* objs) {
  const Eigen::Vector2d a(2, 2), b(12, 8);
  const Eigen::Vector2d u = (b - a).normalized(), n(-u.y(), u.x());
  auto height = [&](double x, double y) {
    double z = 0.05 * x + 0.3 * std::sin(y / 2);  // slopes across and along the pipe
    if (with_pipe) {
      const double d = std::abs((Eigen::Vector2d(x, y) - a).dot(n));
      if (d < 0.2) z += std::sqrt(0.04 - d * d) - 0.05;
    }
    return z;
  };
  PointCloud c = surface_points(-1, 15, -1, 11, 0.03, height);
  const TriangleMesh box = cube();
  objs->clear();
  objs->push_back(object("box_0", box, pose(a.x(), a.y(), height(a.x(), a.y()), 10)));
  objs->push_back(object("box_1", box, pose(b.x(), b.y(), height(b.x(), b.y()), 40)));
  objs->push_back(object("box_2", box, pose(2, 9, height(2, 9), 0)));  // nothing joins it
  for (const WorldObject& o : *objs) add_model_points(c, *o.mesh_model, o.T_world_model);
  return c;
}

TEST(WorldConnections, APipelineRidgeJoinsTwoStructures) {
  std::vector<WorldObject> objs;
  const PointCloud c = pipeline_site(true, &objs);
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05};
  const WorldModel w = build_world_model(c, objs, cfg);
  ASSERT_EQ(w.connections.size(), 1u);
  EXPECT_EQ(w.connections[0].from, "box_0");
  EXPECT_EQ(w.connections[0].to, "box_1");
  EXPECT_EQ(w.connections[0].kind, "pipeline");
  // Centre to centre 11.7 m, less each footprint grown by the margin (0.6–0.8 m).
  EXPECT_GT(w.connections[0].length_m, 9.5);
  EXPECT_LT(w.connections[0].length_m, 11.7);
  EXPECT_GT(w.connections[0].fraction, 0.9);

  const PointCloud bare = pipeline_site(false, &objs);
  EXPECT_TRUE(build_world_model(bare, objs, cfg).connections.empty());
}

// Issue 28: `world` connects only placements at or above the confidence threshold. The pipeline
// site's two boxes are joined by a ridge; with box_1 below the threshold no connection is drawn
// to it (the ridge is still there), its points stay in the seabed, it is kept and listed as
// unconfirmed (graph.json, a grey node in world.glb), and a connection given to it is refused.
TEST(WorldConnections, NoConnectionToAPlacementBelowTheThreshold) {
  std::vector<WorldObject> objs;
  const PointCloud c = pipeline_site(true, &objs);
  objs[0].confidence = 0.9;
  objs[1].confidence = 0.3;
  objs[2].confidence = 0.8;
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05};
  cfg.min_confidence = 0.2;  // all three confirmed: the ridge joins box_0 and box_1
  const WorldModel all = build_world_model(c, objs, cfg);
  ASSERT_EQ(all.connections.size(), 1u);
  EXPECT_EQ(all.connections[0].to, "box_1");

  cfg.min_confidence = 0.5;
  WorldModel w = build_world_model(c, objs, cfg);
  EXPECT_TRUE(w.connections.empty()) << w.connections[0].from << " - " << w.connections[0].to;
  ASSERT_EQ(w.objects.size(), 3u);
  EXPECT_TRUE(w.objects[0].confirmed);
  EXPECT_FALSE(w.objects[1].confirmed);
  EXPECT_TRUE(w.objects[2].confirmed);
  EXPECT_DOUBLE_EQ(w.min_confidence, 0.5);
  // The points box_1 would explain (its 20,000 surface samples and the seabed within its grown
  // box) are not explained by it: they stay in the seabed.
  const std::vector<std::uint8_t> by_box_1 = explained_points(c, {objs[1]}, cfg.seabed.margin_m);
  const auto n1 = static_cast<std::size_t>(std::count(by_box_1.begin(), by_box_1.end(), 1));
  EXPECT_GE(n1, 20000u);
  EXPECT_EQ(w.seabed_points, all.seabed_points + n1);
  // A placement of unknown confidence is unconfirmed under any threshold above 0.
  std::vector<WorldObject> unknown = objs;
  unknown[1].confidence = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(build_world_model(c, unknown, cfg).connections.empty());
  EXPECT_EQ(confirm_objects(unknown, 0.0), 0u);  // threshold 0: every placement, as before

  const fs::path d = temp_dir("unconfirmed");
  write_text_file((d / "c.yaml").string(), "connections:\n  - {from: box_0, to: box_1}\n");
  expect_error(
      [&] {
        add_given_connections(w, read_given_connections((d / "c.yaml").string()),
                              (d / "c.yaml").string(), cfg.seabed.margin_m);
      },
      "c.yaml:2: 'box_1' is an unconfirmed placement (confidence 0.30 below the threshold 0.50)");
  EXPECT_TRUE(w.connections.empty());

  write_world_model(d / "W", w, {});
  const nlohmann::json g = nlohmann::json::parse(read_text_file((d / "W" / "graph.json").string()));
  EXPECT_DOUBLE_EQ(g["min_confidence"].get<double>(), 0.5);
  EXPECT_EQ(g["objects"][1]["confirmed"], false);
  EXPECT_DOUBLE_EQ(g["objects"][1]["confidence"].get<double>(), 0.3);
  EXPECT_EQ(g["objects"][0]["confirmed"], true);
  EXPECT_TRUE(g["connections"].empty());
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile((d / "W" / "world.glb").string(), 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  EXPECT_NE(find_node(scene->mRootNode, "box_1 (unconfirmed)"), nullptr);
  EXPECT_NE(find_node(scene->mRootNode, "box_0"), nullptr);
}

// Connections the user gives: a pair also found keeps its measured length and is marked given;
// a pair not found gets the distance between the footprint centres; bad files name file:line.
TEST(WorldConnections, GivenConnectionsJoinTheFoundOnes) {
  std::vector<WorldObject> objs;
  const PointCloud c = pipeline_site(true, &objs);  // box_0 - box_1 joined; box_2 on its own
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05};
  WorldModel w = build_world_model(c, objs, cfg);
  ASSERT_EQ(w.connections.size(), 1u);
  const double found_length = w.connections[0].length_m;
  const fs::path d = temp_dir("given");
  write_text_file((d / "c.yaml").string(),
                  "connections:\n"
                  "  - {from: box_1, to: box_0}  # the pipeline found in the map\n"
                  "  - {from: box_0, to: box_2, kind: cable}\n");
  const std::vector<GivenConnection> given = read_given_connections((d / "c.yaml").string());
  ASSERT_EQ(given.size(), 2u);
  EXPECT_EQ(given[1].line, 3);
  EXPECT_EQ(given[1].kind, "cable");
  add_given_connections(w, given, (d / "c.yaml").string(), cfg.seabed.margin_m);
  ASSERT_EQ(w.connections.size(), 2u);
  EXPECT_TRUE(w.connections[0].found && w.connections[0].given);
  EXPECT_DOUBLE_EQ(w.connections[0].length_m, found_length);
  const Connection& cable = w.connections[1];
  EXPECT_TRUE(cable.given && !cable.found);
  EXPECT_EQ(cable.from, "box_0");
  EXPECT_EQ(cable.to, "box_2");
  EXPECT_EQ(cable.kind, "cable");
  EXPECT_TRUE(std::isnan(cable.fraction));
  const Eigen::Vector3d a =
      w.objects[0].T_world_model * w.objects[0].mesh_model->bounding_box().center().cast<double>();
  const Eigen::Vector3d b =
      w.objects[2].T_world_model * w.objects[2].mesh_model->bounding_box().center().cast<double>();
  EXPECT_NEAR(cable.length_m, (b - a).head<2>().norm(), 1e-9);

  auto refused = [&](const std::string& text, std::initializer_list<const char*> needles) {
    write_text_file((d / "bad.yaml").string(), text);
    WorldModel copy = w;
    for (const char* needle : needles) {
      expect_error(
          [&] {
            add_given_connections(copy, read_given_connections((d / "bad.yaml").string()),
                                  (d / "bad.yaml").string(), cfg.seabed.margin_m);
          },
          needle);
    }
  };
  refused("connections:\n  - {from: box_0, to: tank_9}\n",
          {"bad.yaml:2", "'tank_9' names no placed object", "box_0, box_1, box_2"});
  refused("connections:\n  - {from: box_0, to: box_0}\n", {"bad.yaml:2", "to itself"});
  refused("connections:\n  - {from: box_0, to: box_1}\n  - {from: box_1, to: box_0}\n",
          {"bad.yaml:3", "given twice", "line 2"});
  refused("connections:\n  - {from: box_0, too: box_1}\n", {"bad.yaml:2", "too"});
  refused("connections:\n  - {from: box_0}\n", {"bad.yaml:2", "'from' and 'to'"});
  refused("connections:\n  - [box_0, box_1]\n", {"bad.yaml:2", "is a map"});
  refused("pipes: []\n", {"bad.yaml", "no 'connections' list"});
  refused("connections: [\n", {"bad.yaml", "malformed YAML"});
  expect_error([&] { read_given_connections((d / "none.yaml").string()); }, "none.yaml");
}

// A small world written to disk: three boxes on the synthetic terrain.
struct SmallWorld {
  WorldModel world;
  WorldWriteResult written;
  fs::path dir;
};

SmallWorld write_small_world(const std::string& name) {
  PointCloud c = surface_points(0, 8, 0, 6, 0.03, terrain);
  const TriangleMesh box = cube();
  std::vector<WorldObject> objs = {object("box_0", box, pose(2, 2, terrain(2, 2), 20)),
                                   object("box_1", box, pose(6, 4, terrain(6, 4), -35))};
  objs.push_back(object("tank_0", make_reference_object("tank"), pose(5, 1.5, -1, 0)));
  for (const WorldObject& o : objs) add_model_points(c, *o.mesh_model, o.T_world_model);
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05, 0.2, 1.0};
  SmallWorld s;
  s.world = build_world_model(c, objs, cfg);
  s.dir = temp_dir(name) / "W";
  WorldWriteInfo info;
  info.map = "map.ply";
  info.placements = "placements.json";
  info.catalogue = "cat.yaml";
  info.cloud_bytes = 123456789;
  info.seabed_error_m = {0.01, 0.02, std::numeric_limits<double>::quiet_NaN()};
  s.written = write_world_model(s.dir, s.world, info);
  return s;
}

const aiNode* find_node(const aiNode* n, const std::string& name) {
  if (name == n->mName.C_Str()) return n;
  for (unsigned i = 0; i < n->mNumChildren; ++i) {
    if (const aiNode* f = find_node(n->mChildren[i], name)) return f;
  }
  return nullptr;
}

Eigen::Matrix4d to_eigen(const aiMatrix4x4& m) {
  Eigen::Matrix4d e;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) e(r, c) = m[static_cast<unsigned>(r)][static_cast<unsigned>(c)];
  }
  return e;
}

TEST(WorldGltf, ParsesBackWithTheRightNodesTransformsAndVertices) {
  const SmallWorld s = write_small_world("gltf");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile((s.dir / "world.glb").string(), 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  const aiNode* root = find_node(scene->mRootNode, "world (ENU z-up to glTF y-up)");
  ASSERT_NE(root, nullptr);
  EXPECT_TRUE(to_eigen(root->mTransformation).isApprox(enu_to_gltf(), 1e-9));
  // Default: the coarsest seabed and one node per placed model.
  EXPECT_EQ(root->mNumChildren, 1u + s.world.objects.size());
  const aiNode* seabed = find_node(root, "seabed_lod2");
  ASSERT_NE(seabed, nullptr);
  EXPECT_EQ(find_node(root, "seabed_lod0"), nullptr);
  ASSERT_EQ(seabed->mNumMeshes, 1u);
  EXPECT_EQ(scene->mMeshes[seabed->mMeshes[0]]->mNumVertices,
            s.world.seabed[2].mesh.vertices.size());
  EXPECT_EQ(scene->mMeshes[seabed->mMeshes[0]]->mNumFaces, s.world.seabed[2].mesh.triangles.size());
  for (const WorldObject& o : s.world.objects) {
    const aiNode* n = find_node(root, o.id);
    ASSERT_NE(n, nullptr) << o.id;
    EXPECT_TRUE(to_eigen(n->mTransformation).isApprox(o.T_world_model.matrix(), 1e-6)) << o.id;
    ASSERT_EQ(n->mNumMeshes, 1u);
    const aiMesh* m = scene->mMeshes[n->mMeshes[0]];
    EXPECT_EQ(m->mNumVertices, o.mesh_model->vertices.size());
    EXPECT_EQ(m->mNumFaces, o.mesh_model->triangles.size());
    // A model vertex through node and root: the world point, y up.
    const aiVector3D v = m->mVertices[0];
    const Eigen::Vector4d p_gltf =
        enu_to_gltf() * o.T_world_model.matrix() * Eigen::Vector4d(v.x, v.y, v.z, 1);
    const Eigen::Vector3d p_world = o.T_world_model * o.mesh_model->vertices[0].cast<double>();
    EXPECT_NEAR(p_gltf.y(), p_world.z(), 1e-5);
    EXPECT_NEAR(p_gltf.z(), -p_world.y(), 1e-5);
  }
  // sonar3d's own mesh loader turns glTF's y-up back: the scene in the ENU world frame.
  const TriangleMesh loaded = load_mesh((s.dir / "world.glb").string());
  TriangleMesh expected = s.world.seabed[2].mesh;
  for (const WorldObject& o : s.world.objects) {
    TriangleMesh placed = *o.mesh_model;
    placed.transform(o.T_world_model);
    expected.append(placed);
  }
  // (Vertex counts differ: load_mesh joins identical vertices.)
  EXPECT_TRUE(loaded.bounding_box().min().isApprox(expected.bounding_box().min(), 1e-4f));
  EXPECT_TRUE(loaded.bounding_box().max().isApprox(expected.bounding_box().max(), 1e-4f));
  // The two boxes share one mesh.
  EXPECT_EQ(find_node(root, "box_0")->mMeshes[0], find_node(root, "box_1")->mMeshes[0]);
  EXPECT_EQ(scene->mNumMeshes, 3u);
}

TEST(WorldGltf, AllLevelsOfDetailOnRequest) {
  GltfScene scene;
  scene.meshes.push_back(
      {"cube", cube(), std::vector<std::array<std::uint8_t, 3>>(8, {255, 0, 0}), {1, 1, 1, 1}});
  scene.nodes.push_back({"a", 0, pose(1, 2, 3, 45).matrix(), {1}});
  scene.nodes.push_back({"b", 0, Eigen::Matrix4d::Identity(), {}});
  scene.roots = {0};
  const fs::path p = temp_dir("glbcolor") / "c.glb";
  write_glb(p, scene);
  Assimp::Importer importer;
  const aiScene* s = importer.ReadFile(p.string(), 0);
  ASSERT_NE(s, nullptr) << importer.GetErrorString();
  ASSERT_EQ(s->mNumMeshes, 1u);
  ASSERT_TRUE(s->mMeshes[0]->HasVertexColors(0));
  EXPECT_NEAR(s->mMeshes[0]->mColors[0][0].r, 1.0, 1e-6);
  EXPECT_NEAR(s->mMeshes[0]->mColors[0][0].g, 0.0, 1e-6);
  const aiNode* b = find_node(s->mRootNode, "b");
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(std::string(b->mParent->mName.C_Str()), "a");
  // Bad scenes are refused before anything is written.
  scene.nodes[1].mesh = 5;
  expect_error([&] { write_glb(temp_dir("glbbad") / "x.glb", scene); }, "mesh index");
  scene.nodes[1].mesh = 0;
  scene.meshes[0].colors.pop_back();
  expect_error([&] { write_glb(temp_dir("glbbad2") / "x.glb", scene); }, "7 colours for 8");
}

// Video colours of a coloured cloud (sonar3d texture) carried to the seabed: each vertex the
// mean of its cell's coloured points; black points (no frame saw them) and a placed model's
// points give none; written to the PLYs, world.glb (COLOR_0) and graph.json.
TEST(WorldSeabed, VideoColoursOfTheCloudColourTheSeabed) {
  PointCloud c = surface_points(0, 8, 0, 6, 0.03, terrain);
  for (const Eigen::Vector3f& p : c.points) {
    // West half sand-red, east half blue; the strip 6 < y no frame saw (black).
    const bool unseen = p.y() > 5.0f;
    c.color.push_back(unseen         ? std::array<std::uint8_t, 3>{0, 0, 0}
                      : p.x() < 4.0f ? std::array<std::uint8_t, 3>{200, 60, 40}
                                     : std::array<std::uint8_t, 3>{30, 70, 220});
  }
  const std::vector<WorldObject> objs = {object("box_0", cube(), pose(2, 2, terrain(2, 2), 0))};
  const std::size_t before = c.size();
  add_model_points(c, *objs[0].mesh_model, objs[0].T_world_model);
  c.color.resize(c.size(), {0, 255, 0});  // the box is green: it must not reach the seabed
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.1, 0.5};
  const WorldModel w = build_world_model(c, objs, cfg);
  EXPECT_GT(w.coloured_seabed_points, before / 2);
  for (const SeabedLod& lod : w.seabed) {
    ASSERT_EQ(lod.color.size(), lod.mesh.vertices.size());
    std::size_t red = 0, blue = 0, none = 0;
    for (std::size_t v = 0; v < lod.mesh.vertices.size(); ++v) {
      const Eigen::Vector3f& p = lod.mesh.vertices[v];
      const bool edge = std::abs(p.x() - 4.0f) < lod.cell_m || std::abs(p.y() - 5.0f) < lod.cell_m;
      if (edge) continue;  // cells straddling a colour boundary average both
      if (p.y() > 5.0f) {
        EXPECT_EQ(lod.color_points[v], 0u) << p.transpose();
        ++none;
        continue;
      }
      if (lod.color_points[v] == 0) continue;  // a cell filled under the box
      const Eigen::Vector3f want =
          p.x() < 4.0f ? Eigen::Vector3f(200, 60, 40) : Eigen::Vector3f(30, 70, 220);
      Eigen::Vector3f srgb;
      for (int k = 0; k < 3; ++k) srgb[k] = 255.0f * linear_to_srgb(lod.color[v][k]);
      EXPECT_LT((srgb - want).cwiseAbs().maxCoeff(), 1.0f) << p.transpose();
      ++(p.x() < 4.0f ? red : blue);
    }
    EXPECT_GT(red, 10u);
    EXPECT_GT(blue, 10u);
    EXPECT_GT(none, 10u);
  }
  const fs::path dir = temp_dir("colours") / "W";
  write_world_model(dir, w, {});
  std::vector<std::vector<std::uint32_t>> faces;
  const PointCloud ply = read_ply_faces((dir / "seabed_lod0.ply").string(), &faces);
  ASSERT_TRUE(ply.has_color());
  EXPECT_EQ(faces.size(), w.seabed[0].mesh.triangles.size());
  const nlohmann::json g = nlohmann::json::parse(read_text_file((dir / "graph.json").string()));
  EXPECT_EQ(g["seabed"][1]["coloured_vertices"], w.seabed[1].coloured_vertices());
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile((dir / "world.glb").string(), 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  const aiNode* seabed = find_node(scene->mRootNode, "seabed_lod1");
  ASSERT_NE(seabed, nullptr);
  ASSERT_EQ(seabed->mNumMeshes, 1u);
  EXPECT_TRUE(scene->mMeshes[seabed->mMeshes[0]]->HasVertexColors(0));

  // With a `views` property (sonar3d texture writes it) a black point seen by a camera is a
  // black surface, not an unseen one: the strip takes colour (black).
  PointProperty views{"views", std::vector<float>(c.size(), 1.0f)};
  c.properties.push_back(views);
  const WorldModel seen = build_world_model(c, objs, cfg);
  EXPECT_EQ(seen.coloured_seabed_points, seen.seabed_points);
  for (std::size_t v = 0; v < seen.seabed[0].mesh.vertices.size(); ++v) {
    if (seen.seabed[0].mesh.vertices[v].y() > 5.1f) {
      EXPECT_GT(seen.seabed[0].color_points[v], 0u);
      EXPECT_EQ(seen.seabed[0].color[v], Eigen::Vector3f::Zero());
    }
  }
  c.properties.clear();

  // A cloud without colours gives none.
  c.color.clear();
  EXPECT_TRUE(build_world_model(c, objs, cfg).seabed[0].color.empty());
}

TEST(WorldGraph, JsonFieldsAndFiles) {
  const SmallWorld s = write_small_world("graph");
  const nlohmann::json g = nlohmann::json::parse(read_text_file((s.dir / "graph.json").string()));
  EXPECT_EQ(g["format"], "sonar3d-world");
  EXPECT_EQ(g["version"], 1);
  ASSERT_EQ(g["objects"].size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const nlohmann::json& o = g["objects"][i];
    const WorldObject& w = s.world.objects[i];
    EXPECT_EQ(o["id"], w.id);
    EXPECT_EQ(o["model"], w.model);
    EXPECT_EQ(o["kind"], "structure");
    ASSERT_EQ(o["T_world_model"].size(), 16u);
    for (int k = 0; k < 16; ++k) {
      EXPECT_NEAR(o["T_world_model"][static_cast<std::size_t>(k)].get<double>(),
                  w.T_world_model.matrix()(k / 4, k % 4), 1e-12);
    }
    EXPECT_DOUBLE_EQ(o["score_m"].get<double>(), 0.1);
    EXPECT_DOUBLE_EQ(o["residual_median_m"].get<double>(), 0.01);
    EXPECT_EQ(o["file"], "models/" + w.id + ".ply");
    // The PLY is the model in the world frame.
    const PointCloud ply = read_ply((s.dir / o["file"].get<std::string>()).string());
    ASSERT_EQ(ply.size(), w.mesh_model->vertices.size());
    EXPECT_TRUE(ply.points[0].isApprox(
        (w.T_world_model * w.mesh_model->vertices[0].cast<double>()).cast<float>(), 1e-5f));
  }
  EXPECT_EQ(g["objects"][2]["model"], "tank");
  EXPECT_TRUE(g["connections"].is_array());
  ASSERT_EQ(g["seabed"].size(), 3u);
  std::uintmax_t total = fs::file_size(s.dir / "world.glb");
  for (std::size_t k = 0; k < 3; ++k) {
    const nlohmann::json& l = g["seabed"][k];
    EXPECT_EQ(l["lod"], static_cast<int>(k));
    EXPECT_EQ(l["file"], "seabed_lod" + std::to_string(k) + ".ply");
    EXPECT_NEAR(l["cell_m"].get<double>(), s.world.seabed[k].cell_m, 1e-12);
    EXPECT_EQ(l["triangles"], s.world.seabed[k].mesh.triangles.size());
    EXPECT_EQ(l["bytes"], fs::file_size(s.dir / l["file"].get<std::string>()));
    total += l["bytes"].get<std::uintmax_t>();
  }
  EXPECT_DOUBLE_EQ(g["seabed"][0]["median_error_m"].get<double>(), 0.01);
  EXPECT_TRUE(g["seabed"][2]["median_error_m"].is_null());
  for (const auto& o : g["objects"]) total += fs::file_size(s.dir / o["file"].get<std::string>());
  EXPECT_EQ(g["bytes_total"], total);
  EXPECT_EQ(g["cloud_bytes"], 123456789);
  EXPECT_EQ(g["source"]["map"], "map.ply");
  EXPECT_EQ(g["source"]["placements"], "placements.json");
  EXPECT_EQ(g["source"]["catalogue"], "cat.yaml");
  // The directory is not written over.
  expect_error([&] { write_world_model(s.dir, s.world, {}); }, "exists");
}

// A placements file as sonar3d recognize writes it.
std::string placements_text(const std::string& model, const std::string& matrix) {
  return R"({"format": "sonar3d-placements", "version": 1, "map": "m", "catalogue": "c",
             "placements": [{"model": ")" +
         model + R"(", "T_world_model": )" + matrix +
         R"(, "score_m": 0.3, "residual_median_m": null}]})";
}
const char* kYaw90 = "[[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]";

TEST(WorldInputs, PlacementsReadAndRefused) {
  const fs::path d = temp_dir("placements");
  write_text_file((d / "p.json").string(), placements_text("tank", kYaw90));
  const PlacementsFile p = read_placements((d / "p.json").string());
  ASSERT_EQ(p.placements.size(), 1u);
  EXPECT_EQ(p.placements[0].model, "tank");
  EXPECT_TRUE(p.placements[0].T_world_model.isApprox(pose(1, 2, 3, 90), 1e-12));
  EXPECT_DOUBLE_EQ(p.placements[0].score_m, 0.3);
  EXPECT_TRUE(std::isnan(p.placements[0].residual_median_m));
  EXPECT_EQ(p.map, "m");

  // A model the catalogue does not list.
  expect_error([&] { world_objects(p, {"riser"}, {cube()}, "cat.yaml"); },
               "placement 0 names model 'tank', which catalogue 'cat.yaml' does not list");
  const std::vector<WorldObject> ok = world_objects(p, {"riser", "tank"}, {cube(), cube()}, "c");
  ASSERT_EQ(ok.size(), 1u);
  EXPECT_EQ(ok[0].id, "tank_0");

  auto refused = [&](const std::string& text, const std::string& needle) {
    write_text_file((d / "bad.json").string(), text);
    expect_error([&] { read_placements((d / "bad.json").string()); }, needle);
  };
  refused("{", "not valid JSON");
  refused("[]", "not a JSON object");
  refused(R"({"format": "other", "version": 1, "placements": []})", "sonar3d-placements");
  refused(R"({"format": "sonar3d-placements", "version": 2, "placements": []})", "version");
  refused(placements_text("tank", "[[1, 0, 0], [0, 1, 0]]"), "placement 0: T_world_model");
  refused(placements_text("tank", "[[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"),
          "not a rotation");
  refused(placements_text("tank", "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]"),
          "last row");
  refused(placements_text("", kYaw90), "'model' must be a non-empty string");
  expect_error([&] { read_placements((d / "missing.json").string()); }, "no such file");
}

// Confidence (issue 28): read per placement and from settings.min_confidence; the threshold the
// world applies (asked, else the file's, else 0); bad values are one line naming the file, the
// placement and the key.
TEST(WorldInputs, ConfidenceReadAndRefused) {
  const fs::path d = temp_dir("confidence");
  auto file = [](const std::string& c0, const std::string& c1, const std::string& settings) {
    return R"({"format": "sonar3d-placements", "version": 1, )" + settings +
           R"("placements": [{"model": "tank", "T_world_model": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])" +
           c0 +
           R"(}, {"model": "tank", "T_world_model": [[1,0,0,5],[0,1,0,0],[0,0,1,0],[0,0,0,1]])" +
           c1 + "}]}";
  };
  const std::string path = (d / "p.json").string();
  write_text_file(path, file(R"(, "confidence": 0.82)", R"(, "confidence": 0.31)",
                             R"("settings": {"min_confidence": 0.6}, )"));
  const PlacementsFile p = read_placements(path);
  EXPECT_DOUBLE_EQ(p.placements[0].confidence, 0.82);
  EXPECT_DOUBLE_EQ(p.placements[1].confidence, 0.31);
  EXPECT_DOUBLE_EQ(p.min_confidence, 0.6);
  EXPECT_DOUBLE_EQ(world_confidence_threshold(p, std::nullopt), 0.6);  // the file's
  EXPECT_DOUBLE_EQ(world_confidence_threshold(p, 0.25), 0.25);         // asked
  std::vector<WorldObject> objs = world_objects(p, {"tank"}, {cube()}, "c.yaml");
  EXPECT_DOUBLE_EQ(objs[1].confidence, 0.31);
  EXPECT_EQ(confirm_objects(objs, 0.6), 1u);
  EXPECT_TRUE(objs[0].confirmed);
  EXPECT_FALSE(objs[1].confirmed);
  expect_error([&] { world_confidence_threshold(p, 1.5); },
               "--min-confidence: 1.5 is not a confidence in [0, 1]");

  // An older file: no confidence, no threshold: read as before (unknown, threshold 0); asking
  // for a threshold on it is refused, naming the file and the placement.
  write_text_file(path, file("", "", ""));
  const PlacementsFile old = read_placements(path);
  EXPECT_TRUE(std::isnan(old.placements[0].confidence));
  EXPECT_TRUE(std::isnan(old.min_confidence));
  EXPECT_DOUBLE_EQ(world_confidence_threshold(old, std::nullopt), 0.0);
  EXPECT_DOUBLE_EQ(world_confidence_threshold(old, 0.0), 0.0);
  expect_error([&] { world_confidence_threshold(old, 0.5); },
               "placements '" + path + "': placement 0 has no 'confidence'");

  auto refused = [&](const std::string& text, const std::string& needle) {
    write_text_file((d / "bad.json").string(), text);
    try {
      read_placements((d / "bad.json").string());
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(needle), std::string::npos) << what;
      EXPECT_NE(what.find((d / "bad.json").string()), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;  // one line
    }
  };
  refused(file(R"(, "confidence": 0.5)", R"(, "confidence": 1.5)", ""),
          "placement 1: 'confidence' is 1.5, not a number in [0, 1]");
  refused(file(R"(, "confidence": -0.2)", "", ""),
          "placement 0: 'confidence' is -0.2, not a number in [0, 1]");
  refused(file(R"(, "confidence": "high")", "", ""),
          "placement 0: 'confidence' must be a number in [0, 1], not string");
  refused(file("", "", R"("settings": {"min_confidence": 2}, )"),
          "settings: 'min_confidence' is 2, not a number in [0, 1]");
}

TEST(WorldInputs, EmptyMapAndBadConfigRefused) {
  expect_error([&] { build_world_model(PointCloud{}, {}, {}); }, "holds no points");
  WorldModelConfig cfg;
  cfg.seabed.lod_cells_m = {0.05, 0.12};
  expect_error([&] { cfg.validate(); }, "not an integer multiple");
  cfg.seabed.lod_cells_m = {};
  expect_error([&] { cfg.validate(); }, "lod_cells_m");
  cfg = {};
  cfg.connections.band_m = 0.2;
  expect_error([&] { cfg.validate(); }, "band_m");
  // Every point on a model: nothing left for the seabed.
  PointCloud c;
  add_model_points(c, cube(), pose(0, 0, 0, 0));
  expect_error([&] { build_world_model(c, {object("box_0", cube(), pose(0, 0, 0, 0))}, {}); },
               "no seabed left");
}

#ifdef SONAR3D_CLI
TEST(WorldCli, BuildsAWorldModelAndRefusesBadInputs) {
  const fs::path d = temp_dir("cli");
  PointCloud c = surface_points(0, 8, 0, 6, 0.03, terrain);
  add_model_points(c, make_reference_object("tank"), pose(4, 3, -1, 90));
  write_ply((d / "map.ply").string(), c);
  write_text_file((d / "cat.yaml").string(),
                  "models:\n  - {name: tank, reference: tank, symmetry: full}\n");
  write_text_file((d / "p.json").string(),
                  placements_text("tank",
                                  "[[0, -1, 0, 4], [1, 0, 0, 3], [0, 0, 1, -1], "
                                  "[0, 0, 0, 1]]"));
  const std::string common = (d / "map.ply").string() + " --placements " + (d / "p.json").string() +
                             " --catalogue " + (d / "cat.yaml").string();
  test::CliRun r =
      test::run_cli(d, "world " + common + " -o " + (d / "W").string() + " --lod-cells 0.05,0.25");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("seabed lod1: 0.25 m cells"), std::string::npos) << r.out;
  for (const char* f :
       {"world.glb", "graph.json", "seabed_lod0.ply", "seabed_lod1.ply", "models/tank_0.ply"}) {
    EXPECT_TRUE(fs::is_regular_file(d / "W" / f)) << f;
  }
  // The output exists now: refused, left as it was.
  r = test::run_cli(d, "world " + common + " -o " + (d / "W").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("exists"), std::string::npos) << r.out;
  // A placement naming a model the catalogue lacks.
  write_text_file((d / "cat2.yaml").string(), "models:\n  - {name: pillar, reference: pillar}\n");
  r = test::run_cli(d, "world " + (d / "map.ply").string() + " --placements " +
                           (d / "p.json").string() + " --catalogue " + (d / "cat2.yaml").string() +
                           " -o " + (d / "W2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("names model 'tank'"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "W2"));
  // A missing file is a usage error naming it.
  r = test::run_cli(d, "world " + (d / "nothing.ply").string() + " --placements " +
                           (d / "p.json").string() + " --catalogue " + (d / "cat.yaml").string() +
                           " -o " + (d / "W3").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("nothing.ply"), std::string::npos) << r.out;
  // An empty map.
  write_ply((d / "empty.ply").string(), PointCloud{});
  r = test::run_cli(d, "world " + (d / "empty.ply").string() + " --placements " +
                           (d / "p.json").string() + " --catalogue " + (d / "cat.yaml").string() +
                           " -o " + (d / "W4").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("holds no points"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "W4"));
  // --colours: the map's cloud coloured (as sonar3d texture writes it) colours the seabed; a
  // cloud with other points is refused.
  PointCloud coloured = c;
  coloured.color.assign(c.size(), {120, 100, 60});
  write_ply((d / "coloured.ply").string(), coloured);
  r = test::run_cli(d, "world " + common + " --colours " + (d / "coloured.ply").string() + " -o " +
                           (d / "W6").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("seabed points carry a video colour"), std::string::npos) << r.out;
  EXPECT_TRUE(read_ply((d / "W6" / "seabed_lod0.ply").string()).has_color());
  coloured.points.pop_back();
  coloured.color.pop_back();
  write_ply((d / "fewer.ply").string(), coloured);
  r = test::run_cli(d, "world " + common + " --colours " + (d / "fewer.ply").string() + " -o " +
                           (d / "W7").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("fewer.ply' holds"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "W7"));
  r = test::run_cli(d, "world " + common + " --colours " + (d / "map.ply").string() + " -o " +
                           (d / "W8").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("carries no colours"), std::string::npos) << r.out;

  // Confidence (issue 28): below the file's threshold the tank is unconfirmed and says so;
  // --min-confidence overrides the file's; a bad confidence is one line naming file and key.
  const std::string T = "[[0, -1, 0, 4], [1, 0, 0, 3], [0, 0, 1, -1], [0, 0, 0, 1]]";
  auto conf_file = [&](const std::string& conf, const std::string& min) {
    return R"({"format": "sonar3d-placements", "version": 1, "settings": {"min_confidence": )" +
           min + R"(}, "placements": [{"model": "tank", "T_world_model": )" + T +
           R"(, "confidence": )" + conf + "}]}";
  };
  write_text_file((d / "pc.json").string(), conf_file("0.3", "0.5"));
  const std::string with_conf = (d / "map.ply").string() + " --placements " +
                                (d / "pc.json").string() + " --catalogue " +
                                (d / "cat.yaml").string();
  r = test::run_cli(d, "world " + with_conf + " -o " + (d / "C1").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("0 placed models"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("unconfirmed: tank_0 (confidence 0.30 < 0.50)"), std::string::npos) << r.out;
  r = test::run_cli(d, "world " + with_conf + " --min-confidence 0.25 -o " + (d / "C2").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("1 placed models"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("unconfirmed"), std::string::npos) << r.out;
  r = test::run_cli(d, "world " + with_conf + " --min-confidence 1.2 -o " + (d / "C3").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--min-confidence must lie in [0, 1], got 1.2"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  write_text_file((d / "pc.json").string(), conf_file("1.3", "0.5"));
  r = test::run_cli(d, "world " + with_conf + " -o " + (d / "C4").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("pc.json': placement 0: 'confidence' is 1.3, not a number in [0, 1]"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_FALSE(fs::exists(d / "C3") || fs::exists(d / "C4"));

  // A connection given that names no object: refused, nothing written.
  write_text_file((d / "con.yaml").string(), "connections:\n  - {from: tank_0, to: riser_0}\n");
  r = test::run_cli(d, "world " + common + " --connections " + (d / "con.yaml").string() + " -o " +
                           (d / "W5").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("con.yaml:2: 'riser_0' names no placed object"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "W5"));
}
#endif

}  // namespace
}  // namespace sonar3d
