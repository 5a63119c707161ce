// Online maps (issue 25, mapping/online.hpp): OnlineMapper, so a notebook or a custom driver can
// feed frames as they arrive and query the map at any time.
#include "sonar3d/mapping/online.hpp"

#include "common.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

namespace {

// (points (N, 3) float32, intensity (N,) float32 or None), moved out of the cloud.
py::tuple online_cloud_tuple(PointCloud&& c) {
  py::object intensity = py::none();
  if (c.has_intensity()) {
    const py::ssize_t n = static_cast<py::ssize_t>(c.intensity.size());
    intensity = adopt(std::move(c.intensity), {n});
  }
  return py::make_tuple(points_to_array(std::move(c.points)), intensity);
}

std::optional<NoiseImages> online_noise(const py::object& mean, const py::object& std) {
  if (mean.is_none() && std.is_none()) return std::nullopt;
  if (mean.is_none() || std.is_none())
    throw Error("give both noise_mean and noise_std, or neither");
  return NoiseImages{array_to_image(mean.cast<carray<float>>(), "noise_mean"),
                     array_to_image(std.cast<carray<float>>(), "noise_std")};
}

// A 4×4 pose as given, NaN and all: the mapper counts bad poses instead of raising (a live
// stream must not stop on one bad navigation message).
Eigen::Isometry3d raw_pose(const carray<double>& a, const std::string& what) {
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw Error(what + " must be a 4×4 matrix");
  Eigen::Isometry3d T;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) T.matrix()(i, j) = a.at(i, j);
  return T;
}

}  // namespace

void bind_online(py::module_& m) {
  py::class_<OnlineMapConfig>(
      m, "OnlineMapConfig",
      "Online map (docs/online.md): carve (CarveConfig, the batch settings; carve.region is the "
      "region of interest), window_m (rolling window half-size around the sonar, m; 0 = off; at "
      "least r_max), window_step_m (0 = window_m/4), output_dir (finished blocks as PLY), "
      "max_memory_bytes (0 = no limit), max_lateness_s, max_pending_images, elevation_cell_m.")
      .def(py::init(&from_kwargs<OnlineMapConfig>))
      .def_readwrite("carve", &OnlineMapConfig::carve)
      .def_readwrite("window_m", &OnlineMapConfig::window_m)
      .def_readwrite("window_step_m", &OnlineMapConfig::window_step_m)
      .def_readwrite("output_dir", &OnlineMapConfig::output_dir)
      .def_readwrite("max_memory_bytes", &OnlineMapConfig::max_memory_bytes)
      .def_readwrite("max_lateness_s", &OnlineMapConfig::max_lateness_s)
      .def_readwrite("max_pending_images", &OnlineMapConfig::max_pending_images)
      .def_property(
          "elevation_cell_m", [](const OnlineMapConfig& c) { return c.elevation.cell_m; },
          [](OnlineMapConfig& c, double v) { c.elevation.cell_m = v; })
      .def("__repr__", &fields_repr)
      .def("validate", &OnlineMapConfig::validate);

  py::class_<OnlineMapper>(
      m, "OnlineMapper",
      "Online space carving: push_frame(t, image, T_world_sonar), or push_navigation(t, "
      "T_world_vehicle) and push_image(t, image) (poses interpolated, never extrapolated); "
      "cloud(), elevation() and stats at any time. Push methods return '' when the frame was "
      "carved or queued, else the reason it was dropped (counted in stats).")
      .def(py::init([](const SonarSpec& spec, const OnlineMapConfig& config,
                       const py::object& noise_mean, const py::object& noise_std) {
             return std::make_unique<OnlineMapper>(spec, config,
                                                   online_noise(noise_mean, noise_std));
           }),
           "spec"_a, "config"_a = OnlineMapConfig(), "noise_mean"_a = py::none(),
           "noise_std"_a = py::none())
      .def(
          "push_frame",
          [](OnlineMapper& o, double t, const carray<float>& image, const carray<double>& T) {
            const SonarImage img = array_to_image(image);
            const Eigen::Isometry3d pose = raw_pose(T, "T_world_sonar");
            FrameDrop d;
            {
              py::gil_scoped_release release;
              d = o.push_frame(t, img, pose);
            }
            return std::string(d == FrameDrop::None ? "" : frame_drop_name(d));
          },
          "t"_a, "image"_a, "T_world_sonar"_a)
      .def(
          "push_navigation",
          [](OnlineMapper& o, double t, const carray<double>& T) {
            const Eigen::Isometry3d pose = raw_pose(T, "T_world_vehicle");
            py::gil_scoped_release release;
            return o.push_navigation(t, pose);
          },
          "t"_a, "T_world_vehicle"_a,
          "A navigation sample; False (counted) when not finite, not rigid or not after the "
          "previous one.")
      .def(
          "push_image",
          [](OnlineMapper& o, double t, const carray<float>& image) {
            const SonarImage img = array_to_image(image);
            FrameDrop d;
            {
              py::gil_scoped_release release;
              d = o.push_image(t, img);
            }
            return std::string(d == FrameDrop::None ? "" : frame_drop_name(d));
          },
          "t"_a, "image"_a)
      .def(
          "cloud",
          [](OnlineMapper& o) {
            PointCloud c;
            {
              py::gil_scoped_release release;
              c = o.cloud();
            }
            return online_cloud_tuple(std::move(c));
          },
          "(points, bounds) of the map now, occlusion-resolved incrementally: the batch cloud "
          "of the same frames.")
      .def(
          "candidates", [](const OnlineMapper& o) { return online_cloud_tuple(o.candidates()); },
          "Candidates before occlusion resolution.")
      .def(
          "elevation",
          [](OnlineMapper& o) {
            py::gil_scoped_release release;
            return o.elevation();
          },
          "ElevationMap of the map (and of the blocks a rolling window finished).")
      .def(
          "flush",
          [](OnlineMapper& o) {
            PointCloud c;
            {
              py::gil_scoped_release release;
              c = o.flush();
            }
            return online_cloud_tuple(std::move(c));
          },
          "Finishes every block in memory (written with a rolling window), returns them.")
      .def("reset", &OnlineMapper::reset)
      .def_property_readonly("stats",
                             [](const OnlineMapper& o) { return json_loads(o.stats().to_json()); })
      .def_property_readonly("config", &OnlineMapper::config);
}

}  // namespace sonar3d::python
