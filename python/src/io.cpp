// Datasets (read, write), HoloOcean, frames + navigation and Oculus imports, navigation logs.
#include "common.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;
namespace fs = std::filesystem;

namespace {

py::dict object_dict(const SceneObject& o) {
  py::dict d;
  d["name"] = o.name;
  d["mesh"] = o.mesh_world;
  d["reflectivity"] = o.reflectivity;
  d["kind"] = to_string(o.kind);
  return d;
}

std::optional<NoiseImages> noise_from(const py::object& mean, const py::object& std) {
  if (mean.is_none() && std.is_none()) return std::nullopt;
  if (mean.is_none() || std.is_none())
    throw Error("give both noise_mean and noise_std, or neither");
  NoiseImages n{array_to_image(mean.cast<carray<float>>(), "noise_mean"),
                array_to_image(std.cast<carray<float>>(), "noise_std")};
  return n;
}

}  // namespace

void bind_io(py::module_& m) {
  py::class_<Dataset>(m, "Dataset",
                      "A dataset directory v1 (docs/formats.md), opened by read_dataset(). Frames "
                      "load on demand.")
      .def_property_readonly("root", [](const Dataset& d) { return d.root.string(); })
      .def_property_readonly(
          "spec", [](const Dataset& d) { return d.spec; }, "The sensor (a copy on each access).")
      .def("__len__", &Dataset::size)
      .def_property_readonly(
          "timestamps",
          [](const Dataset& d) {
            std::vector<double> t;
            for (const auto& f : d.frames) t.push_back(f.timestamp);
            const py::ssize_t n = static_cast<py::ssize_t>(t.size());
            return adopt(std::move(t), {n});
          },
          "Frame times, s (navigation clock).")
      .def_property_readonly(
          "files",
          [](const Dataset& d) {
            std::vector<std::string> f;
            for (const auto& r : d.frames) f.push_back(r.file);
            return f;
          },
          "Frame files relative to root.")
      .def(
          "frame",
          [](const Dataset& d, long i) {
            if (i < 0) i += static_cast<long>(d.size());
            if (i < 0) throw py::index_error("frame index out of range");
            SonarImage img = d.load_frame(static_cast<std::size_t>(i));
            return image_to_array(std::move(img));
          },
          "i"_a, "Frame i as a float32 array (range bins × beams) of linear intensities.")
      .def(
          "frames",
          [](const Dataset& d, const py::object& indices) {
            std::vector<std::size_t> idx;
            if (indices.is_none()) {
              for (std::size_t i = 0; i < d.size(); ++i) idx.push_back(i);
            } else {
              for (auto v : indices) idx.push_back(v.cast<std::size_t>());
            }
            const std::size_t per = static_cast<std::size_t>(d.spec.range_bins) * d.spec.beams();
            std::vector<float> all(per * idx.size());
            {
              py::gil_scoped_release release;
              for (std::size_t k = 0; k < idx.size(); ++k) {
                const SonarImage img = d.load_frame(idx[k]);
                std::copy(img.data.begin(), img.data.end(), all.begin() + k * per);
              }
            }
            return adopt(std::move(all),
                         {static_cast<py::ssize_t>(idx.size()), d.spec.range_bins, d.spec.beams()});
          },
          "indices"_a = py::none(),
          "Frames stacked into one (N, range bins, beams) float32 array (all, or the indices).")
      .def(
          "pose", [](const Dataset& d, std::size_t i) { return pose_to_array(d.T_world_sonar(i)); },
          "i"_a, "T_world_sonar of frame i: navigation interpolated at its time × T_vehicle_sonar.")
      .def(
          "poses",
          [](const Dataset& d) {
            std::vector<Eigen::Isometry3d> p;
            for (std::size_t i = 0; i < d.size(); ++i) p.push_back(d.T_world_sonar(i));
            return poses_to_array(p);
          },
          "T_world_sonar of every frame, (N, 4, 4).")
      .def_property_readonly(
          "navigation",
          [](const Dataset& d) {
            std::vector<double> t = d.navigation.times;
            const py::ssize_t n = static_cast<py::ssize_t>(t.size());
            return py::make_tuple(adopt(std::move(t), {n}), poses_to_array(d.navigation.poses));
          },
          "(times, T_world_vehicle poses) of navigation.tum.")
      .def_property_readonly(
          "noise_mean",
          [](py::object self) -> py::object {
            const auto& d = self.cast<const Dataset&>();
            if (!d.noise) return py::none();
            return view(d.noise->mean.data.data(), {d.noise->mean.rows, d.noise->mean.cols}, self);
          },
          "Per-pixel open-water noise mean (read-only view), or None.")
      .def_property_readonly(
          "noise_std",
          [](py::object self) -> py::object {
            const auto& d = self.cast<const Dataset&>();
            if (!d.noise) return py::none();
            return view(d.noise->std.data.data(), {d.noise->std.rows, d.noise->std.cols}, self);
          },
          "Per-pixel open-water noise standard deviation (read-only view), or None.")
      .def_property_readonly("has_truth", &Dataset::has_truth)
      .def(
          "truth",
          [](const Dataset& d) {
            py::list out;
            for (const auto& o : read_truth(d.root)) out.append(object_dict(o));
            return out;
          },
          "Ground-truth objects of a simulated dataset: [{name, mesh, reflectivity}], world frame.")
      .def("__repr__", [](const Dataset& d) {
        return "Dataset('" + d.root.string() + "', " + std::to_string(d.size()) + " frames)";
      });

  m.def("read_dataset", &read_dataset, "path"_a,
        "Opens a dataset directory (sonar.yaml, frames.csv, navigation.tum, noise/).");

  m.def(
      "write_dataset",
      [](const std::string& path, const SonarSpec& spec, const py::object& images,
         const py::object& poses, const py::object& timestamps, const py::object& navigation,
         const std::string& format, const py::object& noise_mean, const py::object& noise_std) {
        std::vector<SonarImage> imgs;
        for (auto im : images) imgs.push_back(array_to_image(im.cast<carray<float>>()));
        std::vector<double> t(imgs.size());
        if (timestamps.is_none()) {
          for (std::size_t k = 0; k < t.size(); ++k) t[k] = static_cast<double>(k);
        } else {
          const auto ts = timestamps.cast<carray<double>>();
          if (static_cast<std::size_t>(ts.size()) != imgs.size()) {
            throw Error("timestamps must hold one time per image");
          }
          t.assign(ts.data(), ts.data() + ts.size());
        }
        Trajectory nav;
        if (!poses.is_none()) {
          if (!navigation.is_none()) throw Error("give poses or navigation, not both");
          const auto P = array_to_poses(poses.cast<carray<double>>(), "poses");
          if (P.size() != imgs.size()) throw Error("poses must hold one pose per image");
          // navigation holds T_world_vehicle = T_world_sonar · T_vehicle_sonar⁻¹.
          for (std::size_t k = 0; k < P.size(); ++k) {
            nav.push_back(t[k], P[k] * spec.T_vehicle_sonar.inverse());
          }
        } else if (!navigation.is_none()) {
          const auto tup = navigation.cast<py::tuple>();
          const auto nt = tup[0].cast<carray<double>>();
          nav.times.assign(nt.data(), nt.data() + nt.size());
          nav.poses = array_to_poses(tup[1].cast<carray<double>>(), "navigation poses");
        } else {
          throw Error(
              "give poses (T_world_sonar per image) or navigation (times, T_world_vehicle)");
        }
        const auto noise = noise_from(noise_mean, noise_std);
        py::gil_scoped_release release;
        DatasetWriter w(path, spec,
                        format == "tiff" ? DatasetWriter::ImageFormat::Tiff
                        : format == "png"
                            ? DatasetWriter::ImageFormat::Png
                            : throw Error("format must be 'png' or 'tiff', got '" + format + "'"));
        for (std::size_t k = 0; k < imgs.size(); ++k) {
          imgs[k].timestamp = t[k];
          w.add_frame(imgs[k]);
        }
        w.set_navigation(nav);
        if (noise) w.set_noise(*noise);
        w.commit();
      },
      "path"_a, "spec"_a, "images"_a, "poses"_a = py::none(), "timestamps"_a = py::none(),
      "navigation"_a = py::none(), "format"_a = "png", "noise_mean"_a = py::none(),
      "noise_std"_a = py::none(),
      "Writes a dataset atomically. images: (N, rows, cols) array or a list of 2-D arrays of "
      "linear intensities; poses: (N, 4, 4) T_world_sonar (stored as navigation T_world_vehicle = "
      "T_world_sonar · T_vehicle_sonar⁻¹ at the timestamps, default 0, 1, 2 ... s), or navigation "
      "= (times, T_world_vehicle poses); format 'png' (quantised to spec.bit_depth) or 'tiff' "
      "(float32, lossless); optional noise statistics.");

  m.def(
      "import_holoocean",
      [](const std::string& dir, const std::string& output, const std::string& bins,
         const std::string& sensor, double rate, const std::string& python,
         const std::string& image_key, const std::string& pose_key, const py::object& progress,
         bool overwrite) {
        OutputPolicy policy;  // as the CLI: the recording is never the destination
        policy.overwrite = overwrite;
        policy.sources = {dir};
        check_output_directory(output, OutputKind::Dataset, policy);
        HoloOceanImportConfig cfg;
        cfg.bins = parse_holoocean_bins(bins);
        cfg.sensor = sensor;
        cfg.frame_rate_hz = rate;
        cfg.python = python;
        cfg.image_key = image_key;
        cfg.pose_key = pose_key;
        ProgressArg p(progress);
        const HoloOceanImportResult r =
            p.run([&] { return import_holoocean(dir, output, cfg, p.terminal()); });
        py::dict d;
        d["frames"] = r.frames;
        d["dtype"] = r.dtype;
        d["frame_rate_hz"] = r.frame_rate_hz;
        d["spec"] = r.spec;
        d["warnings"] = r.warnings;
        return d;
      },
      "dir"_a, "output"_a, "bins"_a = "sample", "sensor"_a = "", "rate"_a = 0.0, "python"_a = "",
      "image_key"_a = "", "pose_key"_a = "PoseSensor", "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a HoloOcean/neusis recording (Config.json + Data/N.pkl) into a dataset; see "
      "docs/import.md. bins: 'sample' (neusis: row i at RangeMin + i·Δr) or 'cell' (HoloOcean's "
      "renderer cells). Returns {frames, dtype, frame_rate_hz, spec, warnings}. progress: True "
      "(terminal bar) or progress(done, total).");

  m.def(
      "read_navigation",
      [](const std::string& path, const std::string& convention, bool degrees,
         const std::string& format) {
        NavCsvConfig c;
        c.convention = parse_nav_convention(convention);
        c.degrees = degrees;
        const Trajectory t = read_navigation(path, c, format);
        std::vector<double> times = t.times;
        const py::ssize_t n = static_cast<py::ssize_t>(times.size());
        return py::make_tuple(adopt(std::move(times), {n}), poses_to_array(t.poses));
      },
      "path"_a, "convention"_a = "enu", "degrees"_a = true, "format"_a = "",
      "Reads navigation (TUM, or CSV time,x,y,z,roll,pitch,yaw in the 'enu' or 'ned' convention) "
      "as (times, T_world_vehicle poses) in our world frame (z up).");

  m.def(
      "import_frames",
      [](const std::string& images, const std::string& times, const std::string& navigation,
         const py::object& sonar, const std::string& output, const std::string& convention,
         bool degrees, const std::string& nav_format, double time_offset, bool drop_outside,
         const py::object& progress, bool overwrite) {
        OutputPolicy policy;  // as the CLI: no input is, holds or lies in the destination
        policy.overwrite = overwrite;
        policy.sources = {images, times, navigation};
        check_output_directory(output, OutputKind::Dataset, policy);
        FrameImportConfig cfg;
        cfg.images_dir = images;
        cfg.times_csv = times;
        cfg.navigation = navigation;
        cfg.navigation_format = nav_format;
        cfg.navigation_csv.convention = parse_nav_convention(convention);
        cfg.navigation_csv.degrees = degrees;
        cfg.spec = py::isinstance<SonarSpec>(sonar)
                       ? sonar.cast<SonarSpec>()
                       : read_sonar_description(py::str(sonar).cast<std::string>());
        cfg.time_offset = time_offset;
        cfg.drop_outside = drop_outside;
        ProgressArg p(progress);
        const FrameImportResult r = p.run([&] { return import_frames(cfg, output, p.terminal()); });
        py::dict d;
        d["frames"] = r.frames;
        d["dropped"] = r.dropped;
        d["navigation_samples"] = r.navigation_samples;
        d["first_time"] = r.first_time;
        d["last_time"] = r.last_time;
        return d;
      },
      "images"_a, "times"_a, "navigation"_a, "sonar"_a, "output"_a, "convention"_a = "enu",
      "degrees"_a = true, "nav_format"_a = "", "time_offset"_a = 0.0, "drop_outside"_a = false,
      "progress"_a = py::none(), "overwrite"_a = false,
      "Imports frame images + a 'timestamp,file' CSV + navigation (TUM or CSV) with the sensor "
      "(a SonarSpec or a sensor YAML path; T_vehicle_sonar is the mounting) into a dataset. "
      "Frames outside the navigation span raise sonar3d.Error, or are dropped and counted with "
      "drop_outside=True. progress: True (terminal bar) or progress(done, total).");

  m.def(
      "import_oculus",
      [](const std::string& file, const std::string& output, const py::object& navigation,
         bool static_sonar, const std::string& convention, bool degrees,
         const std::string& nav_format, const std::string& clock, double rate, double time_offset,
         bool drop_outside, const std::string& gains, bool mirror, const py::object& mount,
         double vertical_aperture_deg, const py::object& progress, bool overwrite) {
        OutputPolicy policy;  // as the CLI: the stream and the navigation are never the output
        policy.overwrite = overwrite;
        policy.sources = {file};
        OculusImportConfig cfg;
        if (!navigation.is_none()) {
          cfg.navigation = py::str(navigation).cast<std::string>();
          policy.sources.push_back(cfg.navigation);
        }
        check_output_directory(output, OutputKind::Dataset, policy);
        cfg.static_sonar = static_sonar;
        cfg.navigation_format = nav_format;
        cfg.navigation_csv.convention = parse_nav_convention(convention);
        cfg.navigation_csv.degrees = degrees;
        cfg.clock = parse_oculus_clock(clock);
        cfg.rate_hz = rate;
        cfg.time_offset = time_offset;
        cfg.drop_outside = drop_outside;
        cfg.gains = parse_oculus_gains(gains);
        cfg.mirror = mirror;
        if (!mount.is_none()) cfg.T_vehicle_sonar = array_to_pose(mount.cast<carray<double>>());
        cfg.vertical_aperture_rad = vertical_aperture_deg * M_PI / 180.0;
        ProgressArg p(progress);
        const OculusImportResult r =
            p.run([&] { return import_oculus(file, output, cfg, p.terminal()); });
        py::dict d;
        d["pings"] = r.pings;
        d["frames"] = r.frames;
        d["dropped"] = r.dropped;
        d["dropped_bytes"] = r.dropped_bytes;
        d["other_messages"] = r.other_messages;
        d["version"] = r.version;
        d["model"] = r.model;
        d["has_gains"] = r.has_gains;
        if (r.has_gains) d["gains"] = py::make_tuple(r.gain_min, r.gain_max);
        d["first_time"] = r.first_time;
        d["last_time"] = r.last_time;
        d["spec"] = r.spec;
        d["warnings"] = r.warnings;
        return d;
      },
      "file"_a, "output"_a, "navigation"_a = py::none(), "static"_a = false, "convention"_a = "enu",
      "degrees"_a = true, "nav_format"_a = "", "clock"_a = "ping", "rate"_a = 0.0,
      "time_offset"_a = 0.0, "drop_outside"_a = false, "gains"_a = "keep", "mirror"_a = false,
      "mount"_a = py::none(), "vertical_aperture_deg"_a = 0.0, "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a Blueprint Oculus raw ping stream (SimplePingResult v1/v2) into a dataset, as "
      "`sonar3d import oculus` (docs/import.md §8). navigation: a TUM or CSV file "
      "(T_world_vehicle), or static=True for a fixed sonar; clock 'ping' (pingStartTime) or "
      "'rate' (i / rate, pings/s); time_offset in s; gains 'keep' or 'divide'; mirror=True when "
      "bearings are positive to starboard; mount: 4x4 T_vehicle_sonar; vertical_aperture_deg: "
      "full aperture in degrees (0 = the published one of the model). Returns {pings, frames, "
      "dropped, dropped_bytes (a cut last message), other_messages, version, model, has_gains, "
      "gains (min, max), first_time, last_time, spec, warnings}. progress: True or "
      "progress(done, total).");
}

}  // namespace sonar3d::python
