// Reconstruction: denoising (thesis sec. 4.4.7), space carving (ch. 4), deconvolution (ch. 5)
// and the single reconstruct() entry point. carve(), deconvolve() and reconstruct() all run the
// library's reconstruct_dataset() and return the same Reconstruction.
#include <chrono>

#include "common.hpp"
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

Reconstruction run_reconstruct(const Dataset& dataset, ReconstructOptions options,
                               const py::object& progress) {
  ProgressArg p(progress);
  options.progress = p.terminal();
  return Reconstruction(p.run([&] { return reconstruct_dataset(dataset, options); }));
}

// A world-frame box as Python sees it: (min xyz, max xyz) or None.
py::object region_to_py(const std::optional<Eigen::AlignedBox3d>& r) {
  if (!r) return py::none();
  return py::make_tuple(Eigen::Vector3d(r->min()), Eigen::Vector3d(r->max()));
}
std::optional<Eigen::AlignedBox3d> region_from_py(const py::object& r) {
  if (r.is_none()) return std::nullopt;
  const auto t = r.cast<py::sequence>();
  if (t.size() != 2) throw Error("region must be (min xyz, max xyz) or None");
  return Eigen::AlignedBox3d(t[0].cast<Eigen::Vector3d>(), t[1].cast<Eigen::Vector3d>());
}

}  // namespace

void bind_recon(py::module_& m) {
  py::class_<DenoiseConfig>(m, "DenoiseConfig",
                            "Denoising (sec. 4.4.7): z_test (eq. 4.8, with noise statistics), "
                            "z_threshold T, subtract_mean, static_threshold.")
      .def(py::init(&from_kwargs<DenoiseConfig>))
      .def_readwrite("z_test", &DenoiseConfig::z_test)
      .def_readwrite("z_threshold", &DenoiseConfig::z_threshold)
      .def_readwrite("subtract_mean", &DenoiseConfig::subtract_mean)
      .def_readwrite("static_threshold", &DenoiseConfig::static_threshold)
      .def("__repr__", &fields_repr)
      .def("validate", &DenoiseConfig::validate);

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

  py::class_<CarveConfig>(
      m, "CarveConfig",
      "Space carving (ch. 4): voxel_size (m), region ((min xyz, max xyz) or None), denoise "
      "(DenoiseConfig), resolve_occlusions, static_threshold, carve_margin, explain_returns, "
      "explain_pin_fraction, min_elevation_span, min_observations, num_threads (0 = all cores).")
      .def(py::init(&from_kwargs<CarveConfig>))
      .def_readwrite("voxel_size", &CarveConfig::voxel_size)
      .def_property(
          "region", [](const CarveConfig& c) { return region_to_py(c.region); },
          [](CarveConfig& c, const py::object& r) { c.region = region_from_py(r); })
      .def_readwrite("denoise", &CarveConfig::denoise)
      .def_readwrite("resolve_occlusions", &CarveConfig::resolve_occlusions)
      .def_readwrite("static_threshold", &CarveConfig::static_threshold)
      .def_readwrite("carve_margin", &CarveConfig::carve_margin)
      .def_readwrite("pose_sigma_position", &CarveConfig::pose_sigma_position)
      .def_readwrite("pose_sigma_attitude_deg", &CarveConfig::pose_sigma_attitude_deg)
      .def_readwrite("pose_sigma_k", &CarveConfig::pose_sigma_k)
      .def_property(
          "explain_returns", [](const CarveConfig& c) { return c.occlusion.explain_returns; },
          [](CarveConfig& c, bool v) { c.occlusion.explain_returns = v; })
      .def_property(
          "explain_pin_fraction",
          [](const CarveConfig& c) { return c.occlusion.explain_pin_fraction; },
          [](CarveConfig& c, double v) { c.occlusion.explain_pin_fraction = v; })
      .def_readwrite("min_elevation_span", &CarveConfig::min_elevation_span)
      .def_readwrite("min_observations", &CarveConfig::min_observations)
      .def_readwrite("num_threads", &CarveConfig::num_threads)
      .def("__repr__", &fields_repr)
      .def("validate", &CarveConfig::validate);

  py::class_<BracketConfig>(m, "BracketConfig",
                            "Elevation bracketing of every method's output (recon/bracketing.hpp): "
                            "min_bracket (drop points bracketed less, 0 = keep all), "
                            "bracketed_level, end_view_fraction, end_tolerance, region_samples, "
                            "num_threads.")
      .def(py::init(&from_kwargs<BracketConfig>))
      .def_readwrite("min_bracket", &BracketConfig::min_bracket)
      .def_readwrite("bracketed_level", &BracketConfig::bracketed_level)
      .def_readwrite("end_view_fraction", &BracketConfig::end_view_fraction)
      .def_readwrite("end_tolerance", &BracketConfig::end_tolerance)
      .def_readwrite("region_samples", &BracketConfig::region_samples)
      .def_readwrite("num_threads", &BracketConfig::num_threads)
      .def("__repr__", &fields_repr)
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
        ReconstructOptions o;
        o.method = "carve";
        o.carve = config;
        return run_reconstruct(dataset, o, progress);
      },
      "dataset"_a, "config"_a = CarveConfig(), "progress"_a = py::none(),
      "Space-carves every frame of a dataset (with its noise statistics) and resolves occlusions. "
      "Returns a Reconstruction: points (N, 3) world frame, intensity = reflectivity bounds (N,), "
      "report = the carving statistics. progress: True (terminal bars) or progress(done, total).");

  py::class_<VoxelDeconvConfig>(
      m, "VoxelDeconvConfig",
      "Voxel-mode deconvolution (any trajectory): voxel_size, "
      "max_iterations, tolerance, min_relative, min_relative_bracketed and bracketed (faint voxels "
      "kept when bracketed in elevation), min_observations, occlusion_aware, "
      "support_min_bracket (leave never-bracketed candidates out, 0 = keep), support_refute")
      .def(py::init(&from_kwargs<VoxelDeconvConfig>))
      .def_readwrite("voxel_size", &VoxelDeconvConfig::voxel_size)
      .def_readwrite("max_iterations", &VoxelDeconvConfig::max_iterations)
      .def_readwrite("tolerance", &VoxelDeconvConfig::tolerance)
      .def_readwrite("min_relative", &VoxelDeconvConfig::min_relative)
      .def_readwrite("min_relative_bracketed", &VoxelDeconvConfig::min_relative_bracketed)
      .def_readwrite("bracketed", &VoxelDeconvConfig::bracketed)
      .def_readwrite("min_observations", &VoxelDeconvConfig::min_observations)
      .def_readwrite("occlusion_aware", &VoxelDeconvConfig::occlusion_aware)
      .def_readwrite("support_min_bracket", &VoxelDeconvConfig::support_min_bracket)
      .def_readwrite("support_refute", &VoxelDeconvConfig::support_refute)
      .def("__repr__", &fields_repr)
      .def("validate", &VoxelDeconvConfig::validate);

  py::class_<DeconvConfig>(m, "DeconvConfig",
                           "Deconvolution (ch. 5): mode ('auto', the default: passes "
                           "when the frames form regular passes, else voxel; 'passes'; 'voxel': "
                           "any trajectory), voxel (VoxelDeconvConfig), beam ('sinc', 'flat', 'sensor'), "
                           "lambda_fraction (eq. 5.28), exact, pass tolerances, denoise, dering, "
                           "resolve_occlusions, kernel ('plain', 'normal', 'occlusion', "
                           "'normal+occlusion'), max_range, num_threads ...")
      .def(py::init(&from_kwargs<DeconvConfig>))
      .def_property(
          "beam",
          [](const DeconvConfig& c) { return std::string(DeconvConfig::beam_name(c.beam)); },
          [](DeconvConfig& c, const std::string& s) { c.beam = DeconvConfig::parse_beam(s); })
      .def_property(
          "mode",
          [](const DeconvConfig& c) { return std::string(DeconvConfig::mode_name(c.mode)); },
          [](DeconvConfig& c, const std::string& s) { c.mode = DeconvConfig::parse_mode(s); })
      .def_readwrite("voxel", &DeconvConfig::voxel)
      .def_property(
          "kernel",
          [](const DeconvConfig& c) { return std::string(DeconvConfig::kernel_name(c.kernel)); },
          [](DeconvConfig& c, const std::string& s) { c.kernel = DeconvConfig::parse_kernel(s); })
      .def_readwrite("lambda_fraction", &DeconvConfig::lambda_fraction)
      .def_readwrite("exact", &DeconvConfig::exact)
      .def_readwrite("exact_lambertian", &DeconvConfig::exact_lambertian)
      .def_readwrite("exact_block_tolerance", &DeconvConfig::exact_block_tolerance)
      .def_readwrite("exact_range_subsamples", &DeconvConfig::exact_range_subsamples)
      .def_readwrite("max_axis_angle_deg", &DeconvConfig::max_axis_angle_deg)
      .def_readwrite("max_rotation_deg", &DeconvConfig::max_rotation_deg)
      .def_readwrite("max_lateral_deviation", &DeconvConfig::max_lateral_deviation)
      .def_readwrite("max_spacing_deviation", &DeconvConfig::max_spacing_deviation)
      .def_readwrite("layer_spacing", &DeconvConfig::layer_spacing)
      .def_readwrite("use_measured_heights", &DeconvConfig::use_measured_heights)
      .def_readwrite("split_passes", &DeconvConfig::split_passes)
      .def_readwrite("min_pass_frames", &DeconvConfig::min_pass_frames)
      .def_readwrite("max_range", &DeconvConfig::max_range)
      .def_readwrite("denoise", &DeconvConfig::denoise)
      .def_readwrite("dering", &DeconvConfig::dering)
      .def_readwrite("resolve_occlusions", &DeconvConfig::resolve_occlusions)
      .def_readwrite("subsamples", &DeconvConfig::subsamples)
      .def_readwrite("min_intensity", &DeconvConfig::min_intensity)
      .def_readwrite("min_relative_intensity", &DeconvConfig::min_relative_intensity)
      .def_readwrite("num_threads", &DeconvConfig::num_threads)
      .def("__repr__", &fields_repr)
      .def("validate", &DeconvConfig::validate);

  m.def(
      "deconvolve",
      [](const Dataset& dataset, const DeconvConfig& config, const py::object& progress) {
        ReconstructOptions o;
        o.method = "deconv";
        o.deconv = config;
        return run_reconstruct(dataset, o, progress);
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
      [](const Dataset& dataset, const std::string& method, const py::object& carve,
         const py::object& deconv, const py::object& region, int num_threads,
         const py::object& progress, const py::object& bracket) {
        ReconstructOptions o;
        o.method = method;
        o.region = region_from_py(region);
        if (!carve.is_none()) o.carve = carve.cast<CarveConfig>();
        if (!deconv.is_none()) o.deconv = deconv.cast<DeconvConfig>();
        if (!bracket.is_none()) o.bracket = bracket.cast<BracketConfig>();
        o.num_threads = num_threads;
        return run_reconstruct(dataset, o, progress);
      },
      "dataset"_a, "method"_a = "carve", "carve"_a = py::none(), "deconv"_a = py::none(),
      "region"_a = py::none(), "num_threads"_a = 0, "progress"_a = py::none(),
      "bracket"_a = py::none(),
      "Reconstructs a dataset with one of reconstruction_methods() ('carve', 'deconv', ...) and "
      "the given CarveConfig / DeconvConfig (default: the library's). region: (min xyz, max xyz) "
      "in the world frame (m) or None; carving maps only inside it, the other methods keep the "
      "points inside it. num_threads > 0 overrides the configs'. Returns a Reconstruction, as "
      "carve() and deconvolve() do. progress: True (terminal bars) or progress(done, total). "
      "bracket: BracketConfig (e.g. min_bracket to drop unbracketed ghosts).");
}

}  // namespace sonar3d::python
