// Video mapping (thesis sec. 6.4, docs/video.md): cameras, simulated camera images, colouring a
// cloud or a mesh from posed images, a dataset's camera frames.
#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/video/camera_dataset.hpp"
#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/render.hpp"
#include "sonar3d/video/texture.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/video/texture_mesh.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

namespace {

// An (H, W, 3) float32 array of linear RGB as an RgbImage (copied).
RgbImage array_to_rgb(const carray<float>& a, const std::string& what) {
  if (a.ndim() != 3 || a.shape(2) != 3 || a.shape(0) < 1 || a.shape(1) < 1) {
    throw Error(what + " must be an (H, W, 3) array of linear RGB");
  }
  RgbImage img;
  img.height = static_cast<int>(a.shape(0));
  img.width = static_cast<int>(a.shape(1));
  img.rgb.assign(a.data(), a.data() + a.size());
  for (float v : img.rgb) {
    if (!std::isfinite(v)) throw Error(what + " holds a value that is not finite");
  }
  return img;
}

py::array_t<float> rgb_to_array(RgbImage&& img) {
  const py::ssize_t h = img.height, w = img.width;
  return adopt<float>(std::move(img.rgb), {h, w, 3});
}

// The views of texture_cloud/texture_mesh: a list of (camera, T_world_camera, image) tuples.
struct Views {
  std::vector<RgbImage> images;
  std::vector<CameraView> views;
};

Views views_from(const py::list& list) {
  Views v;
  v.images.reserve(list.size());
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string what = "views[" + std::to_string(i) + "]";
    const auto t = list[i].cast<py::tuple>();
    if (t.size() != 3) throw Error(what + " must be (CameraIntrinsics, T_world_camera, image)");
    const CameraIntrinsics cam = t[0].cast<CameraIntrinsics>();
    const Eigen::Isometry3d T = array_to_pose(t[1].cast<carray<double>>(), what + " pose");
    v.images.push_back(array_to_rgb(t[2].cast<carray<float>>(), what + " image"));
    v.views.push_back({cam, T, nullptr});
  }
  for (std::size_t i = 0; i < v.views.size(); ++i) v.views[i].image = &v.images[i];
  return v;
}

py::array_t<float> colors_to_array(std::vector<Eigen::Vector3f>&& c) {
  return points_to_array(std::move(c));
}

}  // namespace

void bind_video(py::module_& m) {
  py::class_<CameraIntrinsics>(
      m, "CameraIntrinsics",
      "A pinhole camera with OpenCV's distortion (docs/video.md): width, height (pixels), fx, fy, "
      "cx, cy (pixels; pixel (0, 0) is the top-left pixel's centre), k1, k2, p1, p2, k3. Camera "
      "frame: +z forward, +x right, +y down.")
      .def(py::init(&from_kwargs<CameraIntrinsics>))
      .def_readwrite("width", &CameraIntrinsics::width)
      .def_readwrite("height", &CameraIntrinsics::height)
      .def_readwrite("fx", &CameraIntrinsics::fx)
      .def_readwrite("fy", &CameraIntrinsics::fy)
      .def_readwrite("cx", &CameraIntrinsics::cx)
      .def_readwrite("cy", &CameraIntrinsics::cy)
      .def_readwrite("k1", &CameraIntrinsics::k1)
      .def_readwrite("k2", &CameraIntrinsics::k2)
      .def_readwrite("p1", &CameraIntrinsics::p1)
      .def_readwrite("p2", &CameraIntrinsics::p2)
      .def_readwrite("k3", &CameraIntrinsics::k3)
      .def("__repr__", &fields_repr)
      .def("validate", &CameraIntrinsics::validate)
      .def(
          "project",
          [](const CameraIntrinsics& c, const carray<double>& p) -> py::object {
            if (p.size() != 3) throw Error("project: p_camera must hold 3 values");
            const auto px = project(c, Eigen::Vector3d(p.data()[0], p.data()[1], p.data()[2]));
            if (!px) return py::none();
            return py::make_tuple(px->x(), px->y());
          },
          "p_camera"_a, "The pixel (u, v) of a camera-frame point (m), or None behind the camera.");

  // From their one declaration (core/params.hpp; docs/reference.md "texture").
  bind_config<TextureConfig>(m, "TextureConfig",
                             "Colouring a cloud: point_spacing_m (the splat size of the depth "
                             "test), depth_tolerance_m, max_range_m, max_splat_px.")
      .def("validate", &TextureConfig::validate);
  bind_config<TexturePosesConfig>(
      m, "TexturePosesConfig",
      "How the poses of a NeuS file or COLMAP model relate to the cloud's world (`sonar3d "
      "texture`'s neus_frame, camera_world) and when to warn that they may not "
      "(docs/video.md \"Camera world\").")
      .def("validate", &TexturePosesConfig::validate);
  m.def(
      "camera_world_transform",
      [](const std::string& spec) -> Eigen::Matrix4d {
        return camera_world_transform(spec).matrix();
      },
      "spec"_a,
      "The 4×4 T_cameraworld_world (p_camera-world = T · p_world) of a camera-world spec: "
      "'identity', 'aoneus' or 'holoocean' ((x, y, z)_camera-world = (-y, -z, x)_sonar-world), "
      "or 9 / 12 / 16 numbers (a rotation or rigid 3×4 / 4×4 matrix, row-major); docs/video.md.");

  py::class_<MeshTextureConfig>(m, "MeshTextureConfig",
                                "Colouring a mesh: texel_m (subdivision edge length, 0 = as is), "
                                "max_range_m, max_vertices, raster_visibility, weight_by_view "
                                "(colours weighted by |cos θ| / range², else a plain mean), "
                                "silhouette_weight (a frame seeing a vertex within a pixel of the "
                                "outline counts this many times less).")
      .def(py::init(&from_kwargs<MeshTextureConfig>))
      .def_readwrite("texel_m", &MeshTextureConfig::texel_m)
      .def_readwrite("max_range_m", &MeshTextureConfig::max_range_m)
      .def_readwrite("max_vertices", &MeshTextureConfig::max_vertices)
      .def_readwrite("raster_visibility", &MeshTextureConfig::raster_visibility)
      .def_readwrite("weight_by_view", &MeshTextureConfig::weight_by_view)
      .def_readwrite("silhouette_weight", &MeshTextureConfig::silhouette_weight)
      .def("__repr__", &fields_repr)
      .def("validate", &MeshTextureConfig::validate);

  m.def(
      "render_camera",
      [](const py::list& meshes, const py::list& colors, const CameraIntrinsics& camera,
         const carray<double>& T_world_camera, double ambient, double attenuation_per_m) {
        if (meshes.size() != colors.size()) {
          throw Error("render_camera: one colour per mesh is needed");
        }
        Scene scene;
        for (std::size_t i = 0; i < meshes.size(); ++i) {
          SceneObject o;
          o.name = "object" + std::to_string(i);
          o.mesh_world = meshes[i].cast<TriangleMesh>();
          const auto c = colors[i].cast<carray<float>>();
          if (c.size() != 3) throw Error("render_camera: a colour is 3 values (linear RGB)");
          o.color = Eigen::Vector3f(c.data()[0], c.data()[1], c.data()[2]);
          scene.objects.push_back(std::move(o));
        }
        CameraRenderConfig rc;
        rc.ambient = ambient;
        rc.attenuation_per_m = attenuation_per_m;
        const Eigen::Isometry3d T = array_to_pose(T_world_camera, "T_world_camera");
        RgbImage img;
        {
          py::gil_scoped_release release;
          img = CameraRenderer(scene, rc).render(camera, T);
        }
        return rgb_to_array(std::move(img));
      },
      "meshes"_a, "colors"_a, "camera"_a, "T_world_camera"_a,
      "ambient"_a = CameraRenderConfig{}.ambient,
      "attenuation_per_m"_a = CameraRenderConfig{}.attenuation_per_m,
      "A simulated camera image (H, W, 3) float32 linear RGB of world-frame meshes (TriangleMesh) "
      "with linear-RGB colours, lit by a lamp on the camera, dimmed by the water "
      "(docs/video.md).");

  m.def(
      "texture_cloud",
      [](const carray<float>& points, const py::list& views, const TextureConfig& config) {
        PointCloud cloud;
        cloud.points = array_to_points(points);
        const Views v = views_from(views);
        TexturedCloud t;
        {
          py::gil_scoped_release release;
          t = texture_cloud(cloud, v.views, config);
        }
        const py::ssize_t n = static_cast<py::ssize_t>(t.views.size());
        return py::make_tuple(colors_to_array(std::move(t.color)),
                              adopt<std::uint32_t>(std::move(t.views), {n}));
      },
      "points"_a, "views"_a, "config"_a = TextureConfig{},
      "Colour an (N, 3) world-frame cloud from views, a list of (CameraIntrinsics, "
      "T_world_camera 4×4, image (H, W, 3) float32 linear RGB). Returns (colors (N, 3) linear "
      "RGB mean over the frames that saw each point, views (N,) uint32: how many; 0 = none).");

  m.def(
      "texture_mesh",
      [](const TriangleMesh& mesh, const py::list& views, const MeshTextureConfig& config,
         const TriangleMesh& occluders) {
        const Views v = views_from(views);
        TexturedMesh t;
        {
          py::gil_scoped_release release;
          t = texture_mesh(mesh, v.views, config, occluders);
        }
        const py::ssize_t n = static_cast<py::ssize_t>(t.views.size());
        return py::make_tuple(py::cast(std::move(t.mesh)), colors_to_array(std::move(t.color)),
                              adopt<std::uint32_t>(std::move(t.views), {n}));
      },
      "mesh"_a, "views"_a, "config"_a = MeshTextureConfig{}, "occluders"_a = TriangleMesh{},
      "Colour a world-frame TriangleMesh's vertices (subdivided to config.texel_m) from views as "
      "texture_cloud's; visibility against the mesh itself and `occluders` (a TriangleMesh that "
      "hides it but takes no colour, e.g. the seabed). Returns (the subdivided mesh, colors "
      "(V, 3) linear RGB, views (V,) uint32).");

  m.def(
      "read_camera_frames",
      [](const std::string& dataset) {
        const CameraDataset ds = read_camera_dataset(dataset);
        py::list frames;
        for (std::size_t i = 0; i < ds.size(); ++i) {
          frames.append(py::dict("index"_a = ds.frames[i].index,
                                 "timestamp"_a = ds.frames[i].timestamp,
                                 "file"_a = ds.image_path(i).string(),
                                 "T_world_camera"_a = pose_to_array(ds.T_world_camera(i))));
        }
        return py::dict("camera"_a = ds.rig.intrinsics,
                        "T_vehicle_camera"_a = pose_to_array(ds.rig.T_vehicle_camera),
                        "frames"_a = frames);
      },
      "dataset"_a,
      "A dataset's camera frames (its camera/ part, docs/formats.md): {camera: "
      "CameraIntrinsics, T_vehicle_camera, frames: [{index, timestamp, file, T_world_camera}]}, "
      "poses from the dataset's navigation.");

  m.def(
      "read_rgb_image", [](const std::string& path) { return rgb_to_array(read_rgb_image(path)); },
      "path"_a,
      "An image file as (H, W, 3) float32 linear RGB (8/16-bit decoded from sRGB, float as is).");
}

}  // namespace sonar3d::python
