// Mesh texturing with Embree visibility: colours back on the surfaces the camera sees, none behind
// them (also the back of a closed object), and no self-hiding at grazing angles.
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>

#include "relief_grid.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/sim/reference_objects.hpp"
#include "sonar3d/sim/scene.hpp"
#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/video/texture_mesh.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace sonar3d;
using sonar3d::test::expect_error;
using sonar3d::test::pinhole_camera;

namespace {

// Flat light and clear water: every pixel shows its object's albedo.
CameraRenderConfig albedo_light() {
  CameraRenderConfig rc;
  rc.ambient = 1.0;
  rc.attenuation_per_m = 0.0;
  return rc;
}

SceneObject object(const std::string& name, TriangleMesh mesh, const Eigen::Vector3f& color) {
  SceneObject o;
  o.name = name;
  o.mesh_world = std::move(mesh);
  o.color = color;
  return o;
}

// A red box of `size` standing on a 6 × 6 m seabed of `seabed_colour` at z = 0.
struct BoxOnSeabed {
  TriangleMesh seabed, box;
  Scene scene;
};
BoxOnSeabed box_on_seabed(const Eigen::Vector3d& size, const Eigen::Vector3f& seabed_colour) {
  BoxOnSeabed b;
  b.seabed = make_plane(6, 6);
  b.box = make_box(size.x(), size.y(), size.z());
  b.box.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.5 * size.z())));
  b.scene.objects = {object("seabed", b.seabed, seabed_colour),
                     object("box", b.box, {0.9f, 0.1f, 0.1f})};
  return b;
}

}  // namespace

TEST(TextureMesh, SubdivisionBoundsEdgesAndKeepsTheSurface) {
  const TriangleMesh box = make_box(1, 1, 1);
  const TriangleMesh s = subdivide_to_edge(box, 0.1, 1'000'000);
  for (const auto& t : s.triangles) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE((s.vertices[t[k]] - s.vertices[t[(k + 1) % 3]]).norm(), 0.1 + 1e-6);
    }
  }
  EXPECT_NEAR(s.surface_area(), box.surface_area(), 1e-4);
  EXPECT_GT(s.triangles.size(), 64 * box.triangles.size());
  expect_error([&] { subdivide_to_edge(box, 1e-4, 100000); }, "vertices");
}

// A blue wall 4 m in front of the camera, a red plate (a closed box) 2 m in front.
TEST(TextureMesh, ColoursVisibleSurfacesAndNothingBehind) {
  TriangleMesh wall = make_plane(8, 8);
  wall.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 4)));
  TriangleMesh plate = make_box(0.5, 0.5, 0.1);
  plate.transform(Eigen::Isometry3d(Eigen::Translation3d(0, 0, 2)));
  Scene scene;
  scene.objects = {object("wall", wall, {0.1f, 0.2f, 0.9f}),
                   object("plate", plate, {0.9f, 0.1f, 0.1f})};
  const CameraIntrinsics cam = pinhole_camera(400, 300, 300);
  const CameraRenderConfig rc = albedo_light();
  const RgbImage img = CameraRenderer(scene, rc).render(cam, Eigen::Isometry3d::Identity());
  TriangleMesh both = wall;
  both.append(plate);
  MeshTextureConfig mc;
  mc.texel_m = 0.05;
  const TexturedMesh t =
      texture_mesh(both, {CameraView{cam, Eigen::Isometry3d::Identity(), &img}}, mc);
  ASSERT_EQ(t.color.size(), t.mesh.vertices.size());
  const double shadow = 0.25 * 4.0 / 1.95;
  std::size_t hidden = 0, wall_ok = 0, front_ok = 0, back = 0;
  for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
    const Eigen::Vector3f& p = t.mesh.vertices[i];
    const double m = std::max(std::abs(p.x()), std::abs(p.y()));
    if (std::abs(p.z() - 4) < 1e-4 && m < shadow - 0.05) {
      EXPECT_EQ(t.views[i], 0u) << "hidden wall vertex " << p.transpose();
      ++hidden;
    } else if (std::abs(p.z() - 4) < 1e-4 && m > shadow + 0.05 && std::abs(p.x()) < 2.6 &&
               std::abs(p.y()) < 1.9) {
      ASSERT_EQ(t.views[i], 1u) << p.transpose();
      EXPECT_NEAR((t.color[i] - Eigen::Vector3f(0.1f, 0.2f, 0.9f)).norm(), 0, 1e-4);
      ++wall_ok;
    } else if (std::abs(p.z() - 1.95) < 1e-4 && m < 0.24) {
      ASSERT_EQ(t.views[i], 1u) << p.transpose();
      EXPECT_NEAR((t.color[i] - Eigen::Vector3f(0.9f, 0.1f, 0.1f)).norm(), 0, 1e-4);
      ++front_ok;
    } else if (std::abs(p.z() - 2.05) < 1e-4) {
      EXPECT_EQ(t.views[i], 0u) << "the plate's back " << p.transpose();
      ++back;
    }
  }
  EXPECT_GT(hidden, 100u);
  EXPECT_GT(wall_ok, 1000u);
  EXPECT_GT(front_ok, 50u);
  EXPECT_GT(back, 50u);
  // PLY with vertex colours, read back by the PLY reader.
  const fs::path dir = test::temp_dir("texture_mesh");
  write_textured_mesh_ply(dir / "m.ply", t);
  std::vector<std::vector<uint32_t>> faces;
  const PointCloud back_read = read_ply_faces((dir / "m.ply").string(), &faces);
  ASSERT_EQ(back_read.size(), t.mesh.vertices.size());
  ASSERT_EQ(faces.size(), t.mesh.triangles.size());
  ASSERT_TRUE(back_read.has_color());
  RgbImage small = img;
  small.width = 10;
  expect_error(
      [&] {
        texture_mesh(both, {CameraView{cam, Eigen::Isometry3d::Identity(), &small}});
      },
      "size");
}

// The box top seen at 11° grazing by the NeuS fixture's three cameras — what the point splats
// hid entirely at a 3 cm tolerance (test_video_cli.cpp) — takes its colour on the mesh, and the
// seabed under the box none.
TEST(TextureMesh, GrazingSurfacesDoNotHideThemselves) {
  const auto [seabed, box, scene] = box_on_seabed({0.6, 0.6, 0.6}, {0.8f, 0.7f, 0.3f});
  const CameraRenderConfig rc = albedo_light();
  const CameraRenderer renderer(scene, rc);
  const auto cams = read_neus_cameras(fs::path(SONAR3D_SOURCE_DIR) / "data/video/cameras_neus.npz");
  std::vector<RgbImage> images;
  std::vector<CameraView> views;
  for (const auto& c : cams) {
    const CameraIntrinsics k = intrinsics_from_K(c.K, 640, 480);
    images.push_back(renderer.render(k, c.T_world_camera));
  }
  for (std::size_t i = 0; i < cams.size(); ++i) {
    views.push_back({intrinsics_from_K(cams[i].K, 640, 480), cams[i].T_world_camera, &images[i]});
  }
  TriangleMesh both = seabed;
  both.append(box);
  MeshTextureConfig mc;
  mc.texel_m = 0.04;
  const TexturedMesh t = texture_mesh(both, views, mc);
  std::size_t top = 0, under = 0;
  for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
    const Eigen::Vector3f& p = t.mesh.vertices[i];
    const double m = std::max(std::abs(p.x()), std::abs(p.y()));
    if (std::abs(p.z() - 0.6) < 1e-4 && m < 0.27) {
      ASSERT_GE(t.views[i], 1u) << p.transpose();
      EXPECT_NEAR((t.color[i] - Eigen::Vector3f(0.9f, 0.1f, 0.1f)).norm(), 0, 1e-3)
          << p.transpose();
      ++top;
    } else if (std::abs(p.z()) < 1e-4 && m < 0.27) {
      EXPECT_EQ(t.views[i], 0u) << "under the box " << p.transpose();
      ++under;
    }
  }
  EXPECT_GT(top, 100u);
  EXPECT_GT(under, 50u);
}

// A box half buried in the seabed, textured alone from a camera above at a slant: with the seabed
// as an occluder its buried half takes no colour, without it the buried side facing the camera
// takes the sand the camera sees there (what texturing a placed model used to do).
TEST(TextureMesh, OccludersHideTheBuriedPartAndTakeNoColour) {
  const TriangleMesh seabed = make_plane(6, 6);      // z = 0
  const TriangleMesh box = make_box(0.6, 0.6, 0.6);  // centred: its lower half below the seabed
  const Eigen::Vector3f sand(0.8f, 0.7f, 0.3f), red(0.9f, 0.1f, 0.1f);
  Scene scene;
  scene.objects = {object("seabed", seabed, sand), object("box", box, red)};
  const CameraRenderConfig rc = albedo_light();
  const CameraIntrinsics cam = pinhole_camera(320, 240, 260);
  const Eigen::Isometry3d pose = test::look_at({2.0, -1.6, 1.8}, {0, 0, 0});
  const RgbImage img = CameraRenderer(scene, rc).render(cam, pose);
  MeshTextureConfig mc;
  mc.texel_m = 0.03;
  for (const bool with_seabed : {false, true}) {
    SCOPED_TRACE(with_seabed ? "seabed as occluder" : "the box alone");
    const TexturedMesh t =
        texture_mesh(box, {CameraView{cam, pose, &img}}, mc, with_seabed ? seabed : TriangleMesh{});
    std::size_t buried = 0, buried_coloured = 0, buried_sand = 0, top = 0;
    for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
      const Eigen::Vector3f& p = t.mesh.vertices[i];
      if (p.z() < -0.02f) {
        ++buried;
        if (t.views[i] > 0) {
          ++buried_coloured;
          buried_sand += (t.color[i] - sand).norm() < 1e-3f;
        }
      } else if (p.z() > 0.3f - 1e-4f && std::abs(p.x()) < 0.27f && std::abs(p.y()) < 0.27f) {
        ASSERT_EQ(t.views[i], 1u) << p.transpose();
        EXPECT_NEAR((t.color[i] - red).norm(), 0, 1e-3) << p.transpose();
        ++top;
      }
    }
    EXPECT_GT(buried, 1000u);
    EXPECT_GT(top, 100u);
    if (with_seabed) {
      EXPECT_EQ(buried_coloured, 0u);
    } else {
      EXPECT_GT(buried_sand, 100u);  // the test has teeth: without the seabed, sand on the box
    }
  }
  // The occluders are validated like the mesh.
  TriangleMesh bad = seabed;
  bad.vertices[0].x() = std::numeric_limits<float>::quiet_NaN();
  expect_error([&] { MeshTexturer(box, mc, bad); }, "occluders");
}

// The visibility raster (the default) against one Embree ray per vertex, over an occluded scene:
// a seabed with a box, a sphere and a thin plate floating over it, seen by a pinhole from above,
// a distorted camera at an angle, and a camera low over the seabed whose triangles cross its near
// plane. Hidden verdicts of the raster are exact and Visible ones hold unless a sliver thinner than
// a pixel covers the vertex: measured, no vertex differs; allowed, one in a thousand.
TEST(TextureMesh, RasterVisibilityAgreesWithRays) {
  // Every part fine (4-5 cm edges), so that vertices sample the whole surface.
  TriangleMesh scene_mesh = subdivide_to_edge(make_plane(8, 8), 0.06, 1'000'000);
  TriangleMesh box = subdivide_to_edge(make_box(0.8, 0.6, 0.7), 0.05, 1'000'000);
  box.transform(Eigen::Isometry3d(Eigen::Translation3d(-1, 0.5, 0.35)));
  TriangleMesh sphere = make_sphere(0.5, 48);
  sphere.transform(Eigen::Isometry3d(Eigen::Translation3d(1, -0.5, 0.5)));
  TriangleMesh plate = subdivide_to_edge(make_plane(1.2, 0.8), 0.05,
                                         1'000'000);  // open: its back face must occlude too
  plate.transform(Eigen::Isometry3d(Eigen::Translation3d(0.3, 1.2, 1.0)));
  scene_mesh.append(box);
  scene_mesh.append(sphere);
  scene_mesh.append(plate);

  const CameraIntrinsics pinhole = pinhole_camera(320, 240, 260);
  CameraIntrinsics distorted = pinhole;
  distorted.k1 = -0.12;
  distorted.k2 = 0.03;
  distorted.p1 = 0.002;
  using test::look_at;

  RgbImage img;
  img.width = pinhole.width;
  img.height = pinhole.height;
  img.rgb.assign(3u * img.width * img.height, 0.5f);
  const std::vector<CameraView> views = {
      {pinhole, look_at({0.2, 0.1, 4.0}, {0, 0, 0}), &img},
      {distorted, look_at({3.0, -2.5, 2.0}, {0, 0.3, 0.3}), &img},
      {pinhole, look_at({-3.5, 0.3, 0.25}, {0, 0.3, 0.5}), &img},  // the seabed runs under it
  };
  // texel 0: the vertices are the occluder's own; 3 cm: the occluder subdivided, its vertices on
  // the occluder's triangles (the raster's quick test by triangle ids, owned()).
  for (const double texel : {0.0, 0.03}) {
    MeshTextureConfig rays_config;
    rays_config.texel_m = texel;
    rays_config.raster_visibility = false;
    MeshTextureConfig raster_config = rays_config;
    raster_config.raster_visibility = true;
    for (std::size_t f = 0; f < views.size(); ++f) {
      MeshTexturer by_rays(scene_mesh, rays_config), by_raster(scene_mesh, raster_config);
      const std::size_t n_rays = by_rays.add(views[f], f);
      const std::size_t n_raster = by_raster.add(views[f], f);
      const TexturedMesh a = by_rays.result(), b = by_raster.result();
      std::size_t differ = 0, hidden = 0;
      for (std::size_t i = 0; i < a.views.size(); ++i) {
        differ += a.views[i] != b.views[i];
        hidden += a.views[i] == 0;
      }
      SCOPED_TRACE("texel " + std::to_string(texel) + " m, view " + std::to_string(f));
      EXPECT_GT(n_rays, 5000u);
      EXPECT_GT(hidden, 5000u);  // much is hidden or out of view: the test has teeth
      EXPECT_LE(static_cast<double>(differ), 0.001 * static_cast<double>(n_rays))
          << differ << " of " << n_rays << " visible vertices differ";
      EXPECT_NEAR(static_cast<double>(n_raster), static_cast<double>(n_rays), 0.001 * n_rays);
      // The raster decides most tests; rays only at silhouettes and sub-pixel triangles.
      EXPECT_GT(by_raster.raster_decided(), 4 * by_raster.rays_cast());
      EXPECT_EQ(by_rays.raster_decided(), 0u);
    }
  }
}

// Colours weighted by view (the default): a red frame 1 m over a plane, head-on, and a blue frame
// from 3.6 m at a slant. Each vertex both see takes (w_red·red + w_blue·blue) / (w_red + w_blue)
// with w = |cos θ| / range², here mostly red; with weight_by_view = false the plain mean.
TEST(TextureMesh, ColoursWeightedByViewingAngleAndRange) {
  const TriangleMesh plane = make_plane(2, 2);  // z = 0, normal +z
  const CameraIntrinsics cam = pinhole_camera(320, 240, 260);
  auto uniform = [&](const Eigen::Vector3f& c) {
    RgbImage img;
    img.width = cam.width;
    img.height = cam.height;
    img.rgb.resize(3u * cam.width * cam.height);
    for (std::size_t k = 0; k < img.rgb.size(); ++k) img.rgb[k] = c[static_cast<int>(k % 3)];
    return img;
  };
  const Eigen::Vector3f red(0.8f, 0.1f, 0.1f), blue(0.1f, 0.1f, 0.8f);
  const RgbImage red_img = uniform(red), blue_img = uniform(blue);
  const Eigen::Vector3d eye_red(0, 0, 1), eye_blue(0, -3, 2);
  const std::vector<CameraView> views = {{cam, test::look_at(eye_red, {0, 0, 0}), &red_img},
                                         {cam, test::look_at(eye_blue, {0, 0, 0}), &blue_img}};
  for (const bool weighted : {true, false}) {
    MeshTextureConfig mc;
    mc.texel_m = 0.05;
    mc.weight_by_view = weighted;
    const TexturedMesh t = texture_mesh(plane, views, mc);
    std::size_t both = 0;
    double red_share_min = 1;
    for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
      if (t.views[i] != 2) continue;
      const Eigen::Vector3d p = t.mesh.vertices[i].cast<double>();
      auto weight = [&](const Eigen::Vector3d& eye) {
        const double r = (p - eye).norm();
        return weighted ? std::max(0.01, std::abs((p - eye).z()) / r) / (r * r) : 1.0;
      };
      const double wr = weight(eye_red), wb = weight(eye_blue);
      const Eigen::Vector3f expected =
          ((wr * red.cast<double>() + wb * blue.cast<double>()) / (wr + wb)).cast<float>();
      ASSERT_NEAR((t.color[i] - expected).norm(), 0, 1e-4) << p.transpose();
      red_share_min = std::min(red_share_min, wr / (wr + wb));
      ++both;
    }
    EXPECT_GT(both, 100u);
    if (weighted) {
      EXPECT_GT(red_share_min, 0.85);  // the near, head-on frame dominates
    }
  }
}

// The raster pays only when it settles most tests. A fine wavy relief (2 cm triangles) seen at a
// slant leaves many of its tests to rays; then the next 7 frames go straight to the rays (exact)
// and the 9th tries the raster again. Seen from above, the raster settles almost every test and
// is used on every frame. Visibility is the same either way (rays are the reference).
TEST(TextureMesh, FramesWhereTheRasterDecidesLittleGoToRays) {
  // 6 × 6 m, 2 cm quads, waves 0.15 m high
  const TriangleMesh relief = test::relief_grid(300, 6.0, 0.15, 4.0, 3.0);
  const CameraIntrinsics cam = pinhole_camera(320, 240, 260);
  RgbImage img;
  img.width = cam.width;
  img.height = cam.height;
  img.rgb.assign(3u * img.width * img.height, 0.5f);
  const CameraView slant{cam, test::look_at({-3.4, 0, 1.2}, {3, 0, -0.2}), &img};
  const CameraView above{cam, test::look_at({0.1, 0.05, 1.5}, {0, 0, 0}), &img};
  MeshTextureConfig cfg;
  cfg.texel_m = 0;
  MeshTextureConfig rays_cfg = cfg;
  rays_cfg.raster_visibility = false;

  MeshTexturer t(relief, cfg), by_rays(relief, rays_cfg);
  std::size_t decided = 0, rays = 0;
  for (int f = 0; f < 9; ++f) {
    const std::size_t seen = t.add(slant, f), seen_by_rays = by_rays.add(slant, f);
    const std::size_t d = t.raster_decided() - decided, r = t.rays_cast() - rays;
    decided = t.raster_decided();
    rays = t.rays_cast();
    SCOPED_TRACE("slanted frame " + std::to_string(f));
    EXPECT_GT(seen, 10000u);
    EXPECT_NEAR(static_cast<double>(seen), static_cast<double>(seen_by_rays), 0.001 * seen);
    if (f == 0 || f == 8) {  // the raster, which leaves more than a third to rays
      EXPECT_GT(d, 0u);
      EXPECT_GT(3 * r, d + r) << d << " decided by the raster, " << r << " rays";
    } else {  // rays only: each vertex in view one ray
      EXPECT_EQ(d, 0u);
      EXPECT_GT(r, seen);
    }
  }
  MeshTexturer top(relief, cfg);
  for (int f = 0; f < 3; ++f) {
    const std::size_t d0 = top.raster_decided(), r0 = top.rays_cast();
    EXPECT_GT(top.add(above, f), 3000u);
    const std::size_t d = top.raster_decided() - d0, r = top.rays_cast() - r0;
    EXPECT_GT(d, 20 * r) << "frame " << f << ": " << d << " decided by the raster, " << r
                         << " rays";
  }
}

// At a model's outline the image's pixels mix it with what lies behind. A red box on a blue seabed
// (an occluder), seen at a slant: with the raster, every coloured box vertex takes red alone (the
// pixels showing the seabed are not read, and such frames count 1000 times less), while one ray
// per vertex, which knows no outline, lets blue into the vertices along it. A sphere of 5 cm
// facets, subdivided to 2 cm, seen whole: the vertices near a facet's edge (whose pixels show the
// next facet, its plane passing just in front of them) and those of the far side (behind the
// near side, beside the triangles their pixels show) are settled by the raster, not left to rays.
TEST(TextureMesh, OutlineVerticesTakeTheModelsPixelsOnly) {
  const auto [seabed, box, scene] = box_on_seabed({0.8, 0.6, 0.5}, {0.1f, 0.2f, 0.9f});
  const CameraIntrinsics cam = pinhole_camera(320, 240, 260);
  const CameraRenderConfig rc = albedo_light();
  std::vector<Eigen::Isometry3d> poses = {test::look_at({-2.2, -1.1, 1.6}, {0, 0, 0.2}),
                                          test::look_at({1.9, -1.6, 1.4}, {0, 0, 0.2}),
                                          test::look_at({0.4, 2.3, 2.0}, {0, 0, 0.2})};
  std::vector<RgbImage> images;
  for (const auto& T : poses) images.push_back(CameraRenderer(scene, rc).render(cam, T));
  std::vector<CameraView> views;
  for (std::size_t f = 0; f < poses.size(); ++f) views.push_back({cam, poses[f], &images[f]});
  MeshTextureConfig mc;
  mc.texel_m = 0.02;
  const Eigen::Vector3f red(0.9f, 0.1f, 0.1f);
  auto off_red = [&](const TexturedMesh& t, double tolerance) {
    std::size_t coloured = 0, off = 0;
    for (std::size_t i = 0; i < t.mesh.vertices.size(); ++i) {
      if (t.views[i] == 0) continue;
      ++coloured;
      off += (t.color[i] - red).norm() > tolerance;
    }
    EXPECT_GT(coloured, 2000u);
    return off;
  };
  EXPECT_EQ(off_red(texture_mesh(box, views, mc, seabed), 1e-3), 0u);
  MeshTextureConfig rays = mc;
  rays.raster_visibility = false;
  EXPECT_GT(off_red(texture_mesh(box, views, rays, seabed), 0.05), 20u);

  const TriangleMesh sphere = make_sphere(0.5, 64);  // ~5 cm facets, ~4 px at 3 m
  MeshTexturer t(sphere, mc);
  RgbImage grey;
  grey.width = cam.width;
  grey.height = cam.height;
  grey.rgb.assign(3u * grey.width * grey.height, 0.5f);
  EXPECT_GT(t.add({cam, test::look_at({0.3, -2.9, 0.8}, {0, 0, 0}), &grey}), 5000u);
  EXPECT_GT(t.raster_decided(), 3 * t.rays_cast())  // 4.3×; 1.9× before these two rules
      << t.raster_decided() << " decided by the raster, " << t.rays_cast() << " rays";
}
