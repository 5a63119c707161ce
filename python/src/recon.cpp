// Reconstruction: denoising (thesis sec. 4.4.7), space carving (ch. 4), deconvolution (ch. 5)
// and the single reconstruct() entry point. carve(), deconvolve() and reconstruct() all run the
// library's reconstruct_dataset() and return the same Reconstruction.
#include <chrono>

#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/deconvolve.hpp"
#include "sonar3d/recon/denoise.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

namespace {

std::optional<NoiseImages> noise_from(const py::object& mean, const py::object& std) {
  if (mean.is_none() && std.is_none()) return std::nullopt;
  if (mean.is_none() || std.is_none())
    throw Error("give both noise_mean and noise_std, or neither");
  return NoiseImages{array_to_image(mean.cast<carray<float>>(), "noise_mean"),
                     array_to_image(std.cast<carray<float>>(), "noise_std")};
}

// (points (N, 3) float32, intensity (N,) float32 or None), both moved out of the cloud.
py::tuple cloud_tuple(PointCloud&& c) {
  py::object intensity = py::none();
  if (c.has_intensity()) {
    const py::ssize_t n = static_cast<py::ssize_t>(c.intensity.size());
    intensity = adopt(std::move(c.intensity), {n});
  }
  return py::make_tuple(points_to_array(std::move(c.points)), intensity);
}

// ReconstructResult as Python sees it: arrays, and the report parsed into a dict.
struct Reconstruction {
  explicit Reconstruction(ReconstructResult&& r)
      : method(std::move(r.method)), seconds(r.seconds), notes(std::move(r.notes)) {
    for (auto& p : r.cloud.properties) {
      const py::ssize_t n = static_cast<py::ssize_t>(p.values.size());
      properties[py::str(p.name)] = adopt(std::move(p.values), {n});
    }
    py::tuple t = cloud_tuple(std::move(r.cloud));
    points = t[0];
    intensity = t[1];
    report = py::module_::import("json").attr("loads")(r.report);
  }
  py::object points, intensity, report;
  py::dict properties;  // name -> (N,) float32: "bracket", "views"
  std::string method;
  double seconds = 0;
  std::string notes;
};

Reconstruction run_reconstruct(const Dataset& dataset, ReconstructConfig options,
                               const py::object& progress) {
  ProgressArg p(progress);
  options.progress = p.terminal();
  return Reconstruction(p.run([&] { return reconstruct_dataset(dataset, options); }));
}

}  // namespace

void bind_recon(py::module_& m) {
  // The configs, from their one declaration each (core/params.hpp; docs/reference.md). A *Part
  // class is a view of the part of a config that a larger one leaves to it (ReconstructConfig
  // declares the voxel size, region, denoising, observation filter, occlusion switch and threads
  // once for every method).
  bind_config<DenoiseConfig>(m, "DenoiseConfig",
                             "Denoising (sec. 4.4.7): z_test (eq. 4.8, with noise statistics), "
                             "z_threshold T, subtract_mean, static_threshold.")
      .def("validate", &DenoiseConfig::validate);
  bind_config<OcclusionConfig>(m, "OcclusionConfig", "Occlusion resolution (sec. 4.4.5).")
      .def("validate", &OcclusionConfig::validate);
  bind_config<params::Nested<OcclusionConfig>>(
      m, "OcclusionPart",
      "Carving's occlusion resolution (its voxel size and threads: carving's).");
  bind_config<params::Nested<CarveConfig>>(
      m, "CarvePart", "The settings of a ReconstructConfig that only carving has (a view).");
  bind_config<params::Nested<BracketConfig>>(
      m, "BracketPart", "The bracketing settings of a ReconstructConfig (a view).");
  bind_config<params::Nested<VoxelDeconvConfig>>(
      m, "VoxelDeconvPart", "The voxel mode's settings in a ReconstructConfig (a view).");
  bind_config<NnlsOptions>(m, "NnlsConfig", "The NNLS solver (eq. 5.28).");
  bind_config<params::Nested<DeconvConfig>>(
      m, "DeconvPart", "The settings of a ReconstructConfig that only deconvolution has (a view).");

  m.def(
      "denoise",
      [](const carray<float>& image, const py::object& noise_mean, const py::object& noise_std,
         const DenoiseConfig& config) {
        SonarImage img = array_to_image(image);
        const std::optional<NoiseImages> noise = noise_from(noise_mean, noise_std);
        config.validate();
        denoise(img, noise, config);
        return image_to_array(std::move(img));
      },
      "image"_a, "noise_mean"_a = py::none(), "noise_std"_a = py::none(),
      "config"_a = DenoiseConfig(),
      "A denoised copy of the image: pixels failing the Z-test (I − m)/σ > T (eq. 4.8, when noise "
      "statistics are given) or the static threshold become 0; kept pixels lose the noise mean "
      "when config.subtract_mean.");

  py::class_<Reconstruction>(
      m, "Reconstruction",
      "What carve(), deconvolve() and reconstruct() return: points (N, 3) float32, world frame; "
      "intensity (N,) float32 (carved reflectivity bound, or deconvolved layer intensity b); "
      "report (dict: carving statistics, or per-pass deconvolution report; 'bracketing': "
      "never-bracketed share, passes that stop short); properties (dict name -> (N,) float32: "
      "'bracket' in [0, 1], 'views'); method; seconds; "
      "notes (the method's warnings, '; '-separated). Unpacks as points, intensity, report.")
      .def_readonly("points", &Reconstruction::points)
      .def_readonly("intensity", &Reconstruction::intensity)
      .def_readonly("report", &Reconstruction::report)
      .def_readonly("method", &Reconstruction::method)
      .def_readonly("seconds", &Reconstruction::seconds)
      .def_readonly("notes", &Reconstruction::notes)
      .def_readonly("properties", &Reconstruction::properties)
      .def("__iter__",
           [](const Reconstruction& r) {
             return py::iter(py::make_tuple(r.points, r.intensity, r.report));
           })
      .def("__repr__", [](const Reconstruction& r) {
        return "Reconstruction(method=" + py::repr(py::str(r.method)).cast<std::string>() +
               ", points=" + std::to_string(py::len(r.points)) +
               ", seconds=" + py::repr(py::float_(r.seconds)).cast<std::string>() +
               ", notes=" + py::repr(py::str(r.notes)).cast<std::string>() + ")";
      });

  bind_config<CarveConfig>(
      m, "CarveConfig",
      "Space carving (ch. 4): voxel_size (m), region ((min xyz, max xyz) or None), denoise "
      "(DenoiseConfig), resolve_occlusions, occlusion (explain_returns, explain_pin_fraction, "
      "...), static_threshold, carve_margin, pose sigmas, min_elevation_span, min_observations, "
      "num_threads (0 = all cores).")
      .def("validate", &CarveConfig::validate);

  bind_config<BracketConfig>(
      m, "BracketConfig",
      "Elevation bracketing of every method's output (recon/bracketing.hpp): "
      "min_bracket (drop points bracketed less, 0 = keep all), "
      "bracketed_level, end_view_fraction, end_tolerance, region_samples, "
      "num_threads.")
      .def("validate", &BracketConfig::validate);

  py::class_<Carver>(m, "Carver",
                     "Online space carving: integrate(image, T_world_sonar) frame by frame, "
                     "snapshot() at any time, finalize() for the occlusion-resolved cloud.")
      .def(py::init([](const SonarSpec& spec, const CarveConfig& config,
                       const py::object& noise_mean, const py::object& noise_std) {
             return std::make_unique<Carver>(spec, config, noise_from(noise_mean, noise_std));
           }),
           "spec"_a, "config"_a = CarveConfig(), "noise_mean"_a = py::none(),
           "noise_std"_a = py::none())
      .def(
          "integrate",
          [](Carver& c, const carray<float>& image, const carray<double>& T,
             const std::string& label) {
            const SonarImage img = array_to_image(image);
            const Eigen::Isometry3d pose = array_to_pose(T, "T_world_sonar");
            py::gil_scoped_release release;
            c.integrate(img, pose, label);
          },
          "image"_a, "T_world_sonar"_a, "label"_a = "",
          "Denoises a raw linear image and carves it into the map.")
      .def(
          "snapshot", [](const Carver& c) { return cloud_tuple(c.snapshot()); },
          "Current candidates (points, bounds) above the static threshold.")
      .def(
          "finalize",
          [](Carver& c) {
            PointCloud cloud;
            {
              py::gil_scoped_release release;
              cloud = c.finalize();
            }
            return cloud_tuple(std::move(cloud));
          },
          "Occlusion resolution over every integrated frame: (points, reflectivity bounds).")
      .def(
          "write_vdb", [](const Carver& c, const std::string& path) { c.write_vdb(path); },
          "path"_a, "Writes the map as an OpenVDB file (grid carve_map).")
      .def_property_readonly("frames", &Carver::frames)
      .def_property_readonly("stats", [](const Carver& c) {
        const CarveStats& s = c.stats();
        py::dict d;
        d["frames"] = s.frames;
        d["integrate_seconds"] = s.integrate_seconds;
        d["occlusion_seconds"] = s.occlusion_seconds;
        d["candidates"] = s.candidates;
        d["points"] = s.points;
        d["map_bytes"] = s.map_bytes;
        d["frame_bytes"] = s.frame_bytes;
        d["min_observations_used"] = s.min_observations_used;
        d["views_per_scatterer"] = s.views_per_scatterer;
        return d;
      });

  m.def(
      "carve",
      [](const Dataset& dataset, const CarveConfig& config, const py::object& progress) {
        return run_reconstruct(dataset, ReconstructConfig::from_carve(config), progress);
      },
      "dataset"_a, "config"_a = CarveConfig(), "progress"_a = py::none(),
      "Space-carves every frame of a dataset (with its noise statistics) and resolves occlusions. "
      "Returns a Reconstruction: points (N, 3) world frame, intensity = reflectivity bounds (N,), "
      "report = the carving statistics. progress: True (terminal bars) or progress(done, total).");

  bind_config<VoxelDeconvConfig>(
      m, "VoxelDeconvConfig",
      "Voxel-mode deconvolution (any trajectory): voxel_size, min_observations, max_iterations, "
      "tolerance, min_relative, min_relative_bracketed and bracketed, occlusion_aware, "
      "support_min_bracket, support_refute.")
      .def("validate", &VoxelDeconvConfig::validate);
  bind_config<DeconvConfig>(
      m, "DeconvConfig",
      "Deconvolution (ch. 5): mode ('auto', the default: passes when the frames form regular "
      "passes, else voxel; 'passes'; 'voxel': any trajectory), voxel (VoxelDeconvConfig), beam "
      "('sinc', 'flat', 'sensor'), lambda_fraction (eq. 5.28), exact, pass tolerances, denoise, "
      "dering, resolve_occlusions, occlusion, kernel ('plain', 'normal', 'occlusion', "
      "'normal+occlusion'), nnls, num_threads ...")
      .def("validate", &DeconvConfig::validate);
  bind_config<ReconstructConfig>(
      m, "ReconstructConfig",
      "A dataset's reconstruction, whatever the method (sonar3d reconstruct's settings, "
      "docs/reference.md): method, and once for every method voxel_size, region, denoise, "
      "min_observations, resolve_occlusions, num_threads; then carve, deconv and bracket, the "
      "settings only that step has.")
      .def("validate", &ReconstructConfig::validate);

  m.def(
      "deconvolve",
      [](const Dataset& dataset, const DeconvConfig& config, const py::object& progress) {
        return run_reconstruct(dataset, ReconstructConfig::from_deconv(config), progress);
      },
      "dataset"_a, "config"_a = DeconvConfig(), "progress"_a = py::none(),
      "Deconvolves the vertical passes of a dataset (eq. 5.28). Returns a Reconstruction: points, "
      "intensity = layer intensities b, report = per-pass geometry, timings and warnings. "
      "progress: True (terminal bars) or progress(done, total).");

  m.def(
      "deconvolve_frames",
      [](const carray<float>& images, const carray<double>& poses, const SonarSpec& spec,
         const DeconvConfig& config, const py::object& progress) {
        if (images.ndim() != 3) throw Error("images must be (N, range bins, beams), denoised");
        std::vector<SonarImage> imgs;
        for (py::ssize_t k = 0; k < images.shape(0); ++k) {
          SonarImage img(static_cast<int>(images.shape(1)), static_cast<int>(images.shape(2)));
          std::copy(images.data(k, 0, 0), images.data(k, 0, 0) + img.data.size(), img.data.begin());
          imgs.push_back(std::move(img));
        }
        const auto P = array_to_poses(poses, "poses");
        ProgressArg p(progress);
        ReconstructResult r = p.run([&] {
          const auto t0 = std::chrono::steady_clock::now();
          ReconstructResult out;
          DeconvReport report;
          out.cloud = deconvolve_frames(imgs, P, spec, config, &report, p.terminal());
          out.method = "deconv";
          out.report = report.to_json();
          out.notes = report.mode_note;  // mode auto chose the voxel mode, and why
          for (const auto& w : report.warnings) out.notes += (out.notes.empty() ? "" : "; ") + w;
          out.seconds =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          return out;
        });
        return Reconstruction(std::move(r));
      },
      "images"_a, "poses"_a, "spec"_a, "config"_a = DeconvConfig(), "progress"_a = py::none(),
      "Deconvolves already denoised frames (N, rows, cols) taken at poses (N, 4, 4); returns a "
      "Reconstruction like deconvolve().");

  m.def("reconstruction_methods", &reconstruction_methods, "Names reconstruct() accepts.");
  m.def(
      "reconstruct",
      [](const Dataset& dataset, const py::object& method, const py::object& config,
         const py::object& progress, const py::kwargs& settings) {
        ReconstructConfig c =
            config_with_settings<ReconstructConfig>(config, settings, "reconstruct");
        if (!method.is_none()) {  // checked by the property
          py::cast(&c, py::return_value_policy::reference).attr("method") = method;
        }
        return run_reconstruct(dataset, c, progress);
      },
      "dataset"_a, "method"_a = py::none(), "config"_a = py::none(), "progress"_a = py::none(),
      "Reconstructs a dataset with the library's one pipeline, the one `sonar3d reconstruct` "
      "runs: the same settings give the same cloud. config: a ReconstructConfig (default: the "
      "library's; its fields are the command's flags and --print-config keys, "
      "docs/reference.md); method ('carve', 'deconv', 'deconv-l1', 'deconv-exact') and any other "
      "ReconstructConfig field given as a keyword (region=((min xyz), (max xyz)), voxel_size=...) "
      "override it. Returns a Reconstruction. progress: True (terminal bars) or "
      "progress(done, total).");
}

}  // namespace sonar3d::python
