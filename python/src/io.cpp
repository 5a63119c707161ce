// Datasets (read, write), the importers (HoloOcean, frames + navigation, ARIS, ROS bags, Oculus)
// with their configuration classes, navigation logs.
#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;
namespace fs = std::filesystem;

namespace {

// An import's effective settings as a dict (its config's declared fields, groups nested).
template <class C>
py::dict settings_dict(const C& config) {
  C copy = config;
  DictWriter w;
  describe(copy, w);
  return w.out;
}

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

// The destination of an importer's dataset, checked as the CLI checks it: no input (`sources`:
// the recording, a navigation or description file; empty paths skipped) is, holds or lies in it;
// an existing dataset is replaced only with `overwrite`.
void check_import_output(const std::string& output, bool overwrite,
                         const std::vector<std::string>& sources) {
  OutputPolicy policy;
  policy.overwrite = overwrite;
  for (const std::string& s : sources)
    if (!s.empty()) policy.sources.push_back(s);
  check_output_directory(output, OutputKind::Dataset, policy);
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
      "read_navigation",
      [](const std::string& path, const py::object& config, const std::string& format,
         const py::kwargs& settings) {
        const NavCsvConfig c =
            config_with_settings<NavCsvConfig>(config, settings, "read_navigation");
        const Trajectory t = read_navigation(path, c, format);
        std::vector<double> times = t.times;
        const py::ssize_t n = static_cast<py::ssize_t>(times.size());
        return py::make_tuple(adopt(std::move(times), {n}), poses_to_array(t.poses));
      },
      "path"_a, "config"_a = py::none(), "format"_a = "",
      "Reads navigation: TUM (T_world_vehicle), or CSV time,x,y,z,roll,pitch,yaw read as "
      "`config` says (a NavCsvConfig: convention 'enu' or 'ned', angles 'deg' or 'rad'; "
      "keywords set its fields: read_navigation(path, convention='ned')), as (times, "
      "T_world_vehicle poses) in our world frame (z up). format: 'tum', 'csv', or '' (by the "
      "extension).");

  // The importers' configurations, one class each, generated from their one declaration
  // (io/*.hpp, core/params.hpp): the same names, defaults, units and bounds as the command line's
  // flags and the YAML of `sonar3d import <kind> --print-config`.
  bind_config<NavCsvConfig>(m, "NavCsvConfig",
                            "How a navigation CSV (time,x,y,z,roll,pitch,yaw) is read: its frame "
                            "convention and angle unit (docs/import.md).");
  bind_config<ArisImportConfig>(
      m, "ArisImportConfig",
      "Settings of import_aris (sonar3d import aris): where the poses come from, the clock, the "
      "mounting, the vertical aperture (docs/import.md §6).")
      .def("validate", &ArisImportConfig::validate);
  bind_config<RosbagImportConfig>(
      m, "RosbagImportConfig",
      "Settings of import_rosbag (sonar3d import rosbag): topics (empty: found by message type), "
      "mounting, sensor description (docs/import.md §7).");
  bind_config<OculusImportConfig>(
      m, "OculusImportConfig",
      "Settings of import_oculus (sonar3d import oculus): navigation or a static sonar, clock, "
      "gains, mounting, vertical aperture (docs/import.md §8).")
      .def("validate", &OculusImportConfig::validate);
  bind_config<HoloOceanImportConfig>(
      m, "HoloOceanImportConfig",
      "Settings of import_holoocean (sonar3d import holoocean): pixel convention, pickle keys, "
      "frame rate (docs/import.md).")
      .def("validate", &HoloOceanImportConfig::validate);
  bind_config<FrameImportConfig>(
      m, "FrameImportConfig",
      "Settings of import_frames (sonar3d import frames): images, times, navigation and how it is "
      "read (the sensor is import_frames' `sonar`; docs/import.md).");

  m.def(
      "import_holoocean",
      [](const std::string& dir, const std::string& output, const py::object& config,
         const py::object& progress, bool overwrite, const py::kwargs& settings) {
        const HoloOceanImportConfig cfg =
            config_with_settings<HoloOceanImportConfig>(config, settings, "import_holoocean");
        cfg.validate();
        check_import_output(output, overwrite, {dir});
        ProgressArg p(progress);
        const HoloOceanImportResult r =
            p.run([&] { return import_holoocean(dir, output, cfg, p.terminal()); });
        py::dict d;
        d["frames"] = r.frames;
        d["dtype"] = r.dtype;
        d["frame_rate_hz"] = r.frame_rate_hz;
        d["spec"] = r.spec;
        d["warnings"] = r.warnings;
        d["settings"] = settings_dict(cfg);
        return d;
      },
      "dir"_a, "output"_a, "config"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a HoloOcean/neusis recording (Config.json + Data/N.pkl) into a dataset, as "
      "`sonar3d import holoocean` (docs/import.md). `config`: a HoloOceanImportConfig (None: the "
      "defaults); keywords set its fields (bins='sample' | 'cell', sensor, image_key, pose_key, "
      "frame_rate_hz in Hz (0: the sensor's), python, rigid_tolerance). Returns {frames, dtype, "
      "frame_rate_hz, spec, warnings, settings}. progress: True (terminal bar) or "
      "progress(done, total).");

  m.def(
      "import_frames",
      [](const py::object& images, const py::object& times, const py::object& navigation,
         const py::object& sonar, const std::string& output, const py::object& config,
         const py::object& progress, bool overwrite, const py::kwargs& settings) {
        FrameImportConfig cfg =
            config_with_settings<FrameImportConfig>(config, settings, "import_frames");
        if (!images.is_none()) cfg.images_dir = py::str(images).cast<std::string>();
        if (!times.is_none()) cfg.times_csv = py::str(times).cast<std::string>();
        if (!navigation.is_none()) cfg.navigation = py::str(navigation).cast<std::string>();
        if (sonar.is_none()) throw Error("import_frames: give the sensor (sonar=)");
        cfg.spec = py::isinstance<SonarSpec>(sonar)
                       ? sonar.cast<SonarSpec>()
                       : read_sonar_description(py::str(sonar).cast<std::string>());
        cfg.validate();
        check_import_output(output, overwrite, {cfg.images_dir, cfg.times_csv, cfg.navigation});
        ProgressArg p(progress);
        const FrameImportResult r = p.run([&] { return import_frames(cfg, output, p.terminal()); });
        py::dict d;
        d["frames"] = r.frames;
        d["dropped"] = r.dropped;
        d["navigation_samples"] = r.navigation_samples;
        d["first_time"] = r.first_time;
        d["last_time"] = r.last_time;
        d["settings"] = settings_dict(cfg);
        return d;
      },
      "images"_a = py::none(), "times"_a = py::none(), "navigation"_a = py::none(),
      "sonar"_a = py::none(), "output"_a = "", "config"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports frame images + a 'timestamp,file' CSV + navigation (TUM or CSV) with the sensor "
      "(`sonar`: a SonarSpec or a sensor YAML path; T_vehicle_sonar is the mounting) into a "
      "dataset, as `sonar3d import frames`. images, times, navigation: paths (the config's "
      "images_dir, times_csv, navigation). `config`: a FrameImportConfig; keywords set its fields "
      "(navigation_format, navigation_csv=NavCsvConfig(convention='ned', angles='rad'), "
      "time_offset in s, drop_outside). Frames outside the navigation span raise sonar3d.Error, "
      "or are dropped and counted with drop_outside=True. Returns {frames, dropped, "
      "navigation_samples, first_time, last_time, settings}. progress: True (terminal bar) or "
      "progress(done, total).");

  m.def(
      "import_aris",
      [](const std::string& file, const std::string& output, const py::object& config,
         const py::object& progress, bool overwrite, const py::kwargs& settings) {
        const ArisImportConfig cfg =
            config_with_settings<ArisImportConfig>(config, settings, "import_aris");
        cfg.validate();
        check_import_output(output, overwrite, {file, cfg.navigation});
        ProgressArg p(progress);
        const ArisImportResult r =
            p.run([&] { return import_aris(file, output, cfg, p.terminal()); });
        py::dict d;
        d["frames"] = r.frames;
        d["dropped"] = r.dropped;
        d["samples"] = r.info.samples;
        d["beams"] = r.info.beams;
        d["system"] = std::string(aris_system_name(r.info.system));
        d["telephoto"] = r.info.telephoto;
        d["nav_source"] = std::string(kArisNavSourceNames[static_cast<int>(r.nav_source)]);
        d["first_time"] = r.first_time;
        d["last_time"] = r.last_time;
        d["spec"] = r.spec;
        d["warnings"] = r.warnings;
        d["settings"] = settings_dict(cfg);
        return d;
      },
      "file"_a, "output"_a, "config"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a Sound Metrics ARIS recording (.aris) into a dataset, as `sonar3d import aris` "
      "(docs/import.md §6). `config`: an ArisImportConfig (None: the defaults); keywords set its "
      "fields: nav_source ('auto' | 'header' | 'file' | 'static'), navigation (a TUM or CSV "
      "file), navigation_format, navigation_csv (NavCsvConfig), clock ('pc' | 'sonar'), "
      "time_offset (s), drop_outside, drop_partial, mount ([x, y, z] m + [roll, pitch, yaw] "
      "degrees: T_vehicle_sonar), vertical_aperture_deg (degrees; None: the model's). Returns "
      "{frames, dropped, samples, beams, system, telephoto, nav_source (the one used), "
      "first_time, last_time (s), spec, warnings, settings}. progress: True (terminal bar) or "
      "progress(done, total).");

  m.def(
      "import_rosbag",
      [](const std::string& bag, const std::string& output, const py::object& config,
         const py::object& progress, bool overwrite, const py::kwargs& settings) {
        RosbagImportConfig cfg =
            config_with_settings<RosbagImportConfig>(config, settings, "import_rosbag");
        params::check(cfg, "import_rosbag:");
        check_import_output(output, overwrite, {bag, cfg.sonar_description});
        ProgressArg p(progress);
        std::vector<std::string> chosen;
        const RosbagImportResult r = p.run([&] {
          // Topics not named are found by message type when unambiguous, as the CLI does.
          chosen = choose_rosbag_topics(bag, cfg);
          return import_rosbag(bag, output, cfg, p.terminal());
        });
        py::dict d;
        d["format"] = r.format;
        d["sonar_type"] = r.sonar_type;
        d["nav_type"] = r.nav_type;
        d["frames"] = r.frames;
        d["dropped"] = r.dropped;
        d["navigation_samples"] = r.navigation_samples;
        d["mounting_source"] = r.mounting_source;
        d["topics"] = chosen;
        d["spec"] = r.spec;
        d["warnings"] = r.warnings;
        d["settings"] = settings_dict(cfg);
        return d;
      },
      "bag"_a, "output"_a, "config"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a ROS 2 bag (directory or .db3) or a ROS 1 bag (.bag) into a dataset, as `sonar3d "
      "import rosbag` (docs/import.md §7). `config`: a RosbagImportConfig (None: the defaults); "
      "keywords set its fields: sonar_topic, nav_topic (empty: the one topic of a sonar / "
      "navigation type), static_sonar, tf_topic, base_frame, mount ([x, y, z] m + [roll, pitch, "
      "yaw] degrees, instead of /tf_static), sonar_description (a sensor YAML path), "
      "vertical_aperture_deg (degrees; None: the messages'), time_offset (s), drop_outside. "
      "Returns {format, sonar_type, nav_type, frames, dropped, navigation_samples, "
      "mounting_source, topics (the topics found by type), spec, warnings, settings (with the "
      "topics used)}. progress: True (terminal bar) or progress(done, total).");

  m.def(
      "import_oculus",
      [](const std::string& file, const std::string& output, const py::object& config,
         const py::object& progress, bool overwrite, const py::kwargs& settings) {
        const OculusImportConfig cfg =
            config_with_settings<OculusImportConfig>(config, settings, "import_oculus");
        cfg.validate();
        check_import_output(output, overwrite, {file, cfg.navigation});
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
        d["settings"] = settings_dict(cfg);
        return d;
      },
      "file"_a, "output"_a, "config"_a = py::none(), "progress"_a = py::none(),
      "overwrite"_a = false,
      "Imports a Blueprint Oculus raw ping stream (SimplePingResult v1/v2) into a dataset, as "
      "`sonar3d import oculus` (docs/import.md §8). `config`: an OculusImportConfig (None: the "
      "defaults); keywords set its fields: navigation (a TUM or CSV file, T_world_vehicle) or "
      "static_sonar=True, navigation_format, navigation_csv (NavCsvConfig), clock ('ping' | "
      "'rate'), rate_hz (pings/s), time_offset (s), drop_outside, gains ('keep' | 'divide'), "
      "mirror (bearings positive to starboard), mount ([x, y, z] m + [roll, pitch, yaw] degrees: "
      "T_vehicle_sonar), vertical_aperture_deg (degrees; None: the published one of the model). "
      "Returns {pings, frames, dropped, dropped_bytes (a cut last message), other_messages, "
      "version, model, has_gains, gains (min, max), first_time, last_time, spec, warnings, "
      "settings}. progress: True or progress(done, total).");
}

}  // namespace sonar3d::python
