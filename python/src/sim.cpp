// Simulation: whole runs from a scene file, or images rendered from objects + sensor + poses.
#include <memory>

#include "common.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/sim/noise.hpp"
#include "sonar3d/sim/simulation.hpp"
#include "sonar3d/sim/simulator.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

namespace {

// Objects as a list of Mesh / (vertices, triangles) / {"mesh", "reflectivity", "name"} entries.
Scene scene_from(const py::object& objects, double default_reflectivity) {
  Scene scene;
  int k = 0;
  for (auto item : objects) {
    SceneObject o;
    o.name = "object" + std::to_string(k++);
    o.reflectivity = default_reflectivity;
    py::object obj = py::reinterpret_borrow<py::object>(item);
    if (py::isinstance<py::dict>(obj)) {
      const py::dict d = obj.cast<py::dict>();
      if (!d.contains("mesh")) throw Error("an object dict needs a 'mesh' entry");
      o.mesh_world = to_mesh(d["mesh"]);
      if (d.contains("reflectivity")) o.reflectivity = d["reflectivity"].cast<double>();
      if (d.contains("name")) o.name = d["name"].cast<std::string>();
    } else {
      o.mesh_world = to_mesh(obj);
    }
    if (!(o.reflectivity >= 0 && o.reflectivity <= 1)) {
      throw Error("object '" + o.name + "': reflectivity must lie in [0, 1]");
    }
    scene.objects.push_back(std::move(o));
  }
  if (scene.objects.empty()) throw Error("the scene has no object");
  return scene;
}

}  // namespace

void bind_sim(py::module_& m) {
  py::class_<SimulatorConfig>(m, "SimulatorConfig",
                              "Ray-tracing settings (thesis sec. 2.5.2): elevation_step (θ_res, "
                              "rad), rays_per_beam, jitter (eq. 2.14–2.15), gain, num_threads "
                              "(0 = all cores).")
      .def(py::init([](py::kwargs kw) {
        SimulatorConfig c;
        py::object o = py::cast(&c, py::return_value_policy::reference);
        for (auto item : kw) py::setattr(o, item.first, item.second);
        return c;
      }))
      .def_readwrite("elevation_step", &SimulatorConfig::elevation_step_rad)
      .def_readwrite("rays_per_beam", &SimulatorConfig::rays_per_beam)
      .def_readwrite("jitter", &SimulatorConfig::jitter)
      .def_readwrite("gain", &SimulatorConfig::gain)
      .def_readwrite("num_threads", &SimulatorConfig::num_threads)
      .def("__repr__", &fields_repr)
      .def("validate", &SimulatorConfig::validate);

  m.def(
      "simulate",
      [](const std::string& scene, const std::string& output, const py::object& seed,
         const py::object& progress, bool overwrite) {
        // As the CLI: never replace what sonar3d did not write; a dataset only when asked.
        OutputPolicy policy;
        policy.overwrite = overwrite;
        policy.sources = {scene};
        check_output_directory(output, OutputKind::Dataset, policy);
        SimulationSetup setup = load_simulation_setup(scene);
        if (!seed.is_none()) setup.seed = seed.cast<unsigned long long>();
        ProgressArg p(progress);
        const SimulationStats st =
            p.run([&] { return simulate_dataset(setup, output, p.terminal()); });
        py::dict d;
        d["frames"] = st.frames;
        d["rays"] = st.rays;
        d["seconds"] = st.seconds;
        return d;
      },
      "scene"_a, "output"_a, "seed"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Simulates a scene file (docs/formats.md) into a dataset directory with truth/, atomically. "
      "Returns {frames, rays, seconds}. progress: True (terminal bar) or progress(done, total).");

  py::class_<Simulator>(m, "Simulator",
                        "Renders noise-free sonar images of objects (thesis eq. 2.13): "
                        "Simulator(objects, spec, config=SimulatorConfig()), objects a list of "
                        "Mesh, (vertices, triangles) or {'mesh', 'reflectivity', 'name'}.")
      .def(py::init([](const py::object& objects, const SonarSpec& spec,
                       const SimulatorConfig& config, double reflectivity) {
             const Scene scene = scene_from(objects, reflectivity);
             py::gil_scoped_release release;
             return std::make_unique<Simulator>(scene, spec, config);
           }),
           "objects"_a, "spec"_a, "config"_a = SimulatorConfig(), "reflectivity"_a = 0.5)
      .def(
          "render",
          [](const Simulator& s, const carray<double>& T_world_sonar, unsigned long long seed) {
            const Eigen::Isometry3d T = array_to_pose(T_world_sonar, "T_world_sonar");
            SonarImage img;
            {
              py::gil_scoped_release release;
              img = s.render(T, seed);
            }
            return image_to_array(std::move(img));
          },
          "T_world_sonar"_a, "seed"_a = 1,
          "One linear float32 image (range bins × beams) seen from the 4×4 pose; the seed drives "
          "the ray jitter.")
      .def(
          "render_many",
          [](const Simulator& s, const carray<double>& poses, unsigned long long seed) {
            const auto P = array_to_poses(poses, "poses");
            const SonarSpec& spec = s.spec();
            const std::size_t per = static_cast<std::size_t>(spec.range_bins) * spec.beams();
            std::vector<float> all(per * P.size());
            {
              py::gil_scoped_release release;
              for (std::size_t k = 0; k < P.size(); ++k) {
                const SonarImage img = s.render(P[k], seed + k);
                std::copy(img.data.begin(), img.data.end(), all.begin() + k * per);
              }
            }
            return adopt(std::move(all),
                         {static_cast<py::ssize_t>(P.size()), spec.range_bins, spec.beams()});
          },
          "poses"_a, "seed"_a = 1,
          "Images for (N, 4, 4) poses stacked as (N, range bins, beams); frame k uses seed + k.")
      .def_property_readonly(
          "spec", [](const Simulator& s) { return s.spec(); }, "The sensor (a copy).")
      .def_property_readonly("rays_per_image", &Simulator::rays_per_image);

  m.def(
      "add_noise",
      [](const carray<float>& image, const carray<float>& mean, const carray<float>& std,
         unsigned long long seed) {
        SonarImage img = array_to_image(image);
        const NoiseImages n{array_to_image(mean, "mean"), array_to_image(std, "std")};
        if (n.mean.rows != img.rows || n.mean.cols != img.cols || n.std.rows != img.rows ||
            n.std.cols != img.cols) {
          throw Error("noise mean and std must have the image's shape");
        }
        std::mt19937_64 rng(seed);
        add_noise(img, n, rng);
        return image_to_array(std::move(img));
      },
      "image"_a, "mean"_a, "std"_a, "seed"_a = 1,
      "A copy of the image with per-pixel Gaussian noise N(mean, std), clamped at 0.");
}

}  // namespace sonar3d::python
