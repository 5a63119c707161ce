// Core types: the sonar description, the projector, poses and trajectories, point clouds, meshes.
#include "common.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/sim/reference_objects.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

TriangleMesh to_mesh(const py::object& o) {
  if (py::isinstance<TriangleMesh>(o)) return o.cast<TriangleMesh>();
  if (py::isinstance<py::str>(o)) return load_mesh(o.cast<std::string>());
  if (py::hasattr(o, "__fspath__")) return load_mesh(py::str(o.attr("__fspath__")()));
  if (py::isinstance<py::tuple>(o) || py::isinstance<py::list>(o)) {
    const py::sequence s = o.cast<py::sequence>();
    if (s.size() == 2) {
      TriangleMesh mesh;
      mesh.vertices = array_to_points(s[0].cast<carray<float>>(), "mesh vertices");
      const auto t = s[1].cast<carray<int>>();
      if (t.ndim() != 2 || t.shape(1) != 3) throw Error("mesh triangles must be an M×3 array");
      mesh.triangles.resize(t.shape(0));
      std::copy(t.data(), t.data() + t.size(),
                mesh.triangles.empty() ? nullptr : mesh.triangles[0].data());
      for (const auto& tri : mesh.triangles) {
        if (tri.minCoeff() < 0 || tri.maxCoeff() >= static_cast<int>(mesh.vertices.size())) {
          throw Error("mesh triangles index vertices out of range");
        }
      }
      return mesh;
    }
  }
  throw Error("expected a Mesh, a (vertices N×3, triangles M×3) pair or a mesh file path");
}

namespace {

py::tuple trajectory_to_tuple(const Trajectory& t) {
  std::vector<double> times = t.times;
  const py::ssize_t n = static_cast<py::ssize_t>(times.size());
  return py::make_tuple(adopt(std::move(times), {n}), poses_to_array(t.poses));
}

Trajectory tuple_to_trajectory(const carray<double>& times, const carray<double>& poses) {
  Trajectory t;
  if (times.ndim() != 1) throw Error("times must be a 1-D array");
  t.times.assign(times.data(), times.data() + times.size());
  t.poses = array_to_poses(poses);
  if (t.poses.size() != t.times.size()) throw Error("times and poses differ in length");
  t.validate("trajectory");
  return t;
}

}  // namespace

void bind_core(py::module_& m) {
  py::class_<SonarSpec>(
      m, "SonarSpec",
      "A 2D imaging sonar: beam bearings (rad, strictly increasing; column j of "
      "an image is bearings[j]), range window [r_min, r_max) in range_bins rows "
      "(row i centred at r_min + (i + 0.5)·Δr), vertical aperture A_v (full width, "
      "rad), beam pattern, intensity encoding and mounting T_vehicle_sonar.")
      .def(py::init<>())
      .def_static("preset", &sonar_preset, "name"_a,
                  "A sensor preset (see SonarSpec.presets()): p900-130, mb2250, aris3000, sim-*.")
      .def_static("presets", &sonar_preset_names, "Names of the sensor presets.")
      .def_static("from_yaml", &read_sonar_description, "path"_a,
                  "Reads a sensor YAML (sonar.yaml fields, top level or under 'sensor:').")
      .def_readwrite("name", &SonarSpec::name)
      .def_property(
          "bearings",
          [](py::object self) {
            const auto& s = self.cast<const SonarSpec&>();
            return view(s.bearings_rad.data(), {static_cast<py::ssize_t>(s.bearings_rad.size())},
                        self);
          },
          [](SonarSpec& s, const carray<double>& b) {
            if (b.ndim() != 1) throw Error("bearings must be a 1-D array (rad)");
            s.bearings_rad.assign(b.data(), b.data() + b.size());
          },
          "Beam bearings in rad (read-only view; assign a new array to change them).")
      .def_readwrite("r_min", &SonarSpec::r_min, "Near edge of range bin 0, m.")
      .def_readwrite("r_max", &SonarSpec::r_max, "Far edge of the last range bin, m.")
      .def_readwrite("range_bins", &SonarSpec::range_bins, "Rows of an image.")
      .def_readwrite("vertical_aperture", &SonarSpec::vertical_aperture_rad,
                     "A_v = 2·θ_3dB, full width, rad.")
      .def_property(
          "beam_pattern",
          [](const SonarSpec& s) {
            return std::string(BeamPattern::kind_name(s.beam_pattern.kind));
          },
          [](SonarSpec& s, const std::string& k) {
            s.beam_pattern.kind = BeamPattern::parse_kind(k);
          },
          "Vertical beam pattern: 'sinc' (eq. 2.8), 'flat' or 'table'.")
      .def_readwrite("bit_depth", &SonarSpec::bit_depth, "8 or 16: quantisation of stored frames.")
      .def_readwrite("intensity_scale", &SonarSpec::intensity_scale,
                     "Stored integer v means linear intensity v·intensity_scale.")
      .def_property(
          "T_vehicle_sonar", [](const SonarSpec& s) { return pose_to_array(s.T_vehicle_sonar); },
          [](SonarSpec& s, const carray<double>& T) {
            s.T_vehicle_sonar = array_to_pose(T, "T_vehicle_sonar");
          },
          "Sonar mounting on the vehicle, 4×4.")
      .def_property_readonly("beams", &SonarSpec::beams)
      .def_property_readonly("range_resolution", &SonarSpec::range_resolution, "Δr, m.")
      .def_property_readonly("fov_min", &SonarSpec::fov_min, "Lower bearing edge of beam 0, rad.")
      .def_property_readonly("fov_max", &SonarSpec::fov_max, "Upper bearing edge of the last beam.")
      .def("range_of_bin", &SonarSpec::range_of_bin, "row"_a, "Centre range of a row, m.")
      .def("bin_of_range", &SonarSpec::bin_of_range, "range"_a, "Row containing a range, or -1.")
      .def("beam_of_bearing", &SonarSpec::beam_of_bearing, "bearing"_a,
           "Beam whose bearing cell contains the bearing (rad), or -1.")
      .def("set_uniform_bearings", &SonarSpec::set_uniform_bearings, "fov"_a, "count"_a,
           "count beams uniformly over a field of view fov (rad) centred on the boresight.")
      .def("validate", &SonarSpec::validate, "Raises sonar3d.Error naming the first bad field.")
      .def("to_yaml", &sonar_spec_to_yaml, "The sensor fields as sonar.yaml text.")
      .def("__repr__", &fields_repr);

  m.def(
      "_polar_to_sonar",
      [](const carray<double>& r, const carray<double>& phi, const carray<double>& theta) {
        if (r.size() != phi.size() || r.size() != theta.size()) {
          throw Error("range, bearing and elevation differ in size");
        }
        std::vector<double> out(3 * r.size());
        for (py::ssize_t k = 0; k < r.size(); ++k) {
          const Eigen::Vector3d p = polar_to_sonar({r.data()[k], phi.data()[k], theta.data()[k]});
          for (int i = 0; i < 3; ++i) out[3 * k + i] = p[i];
        }
        return adopt(std::move(out), {r.size(), 3});
      },
      "r"_a, "bearing"_a, "elevation"_a);
  m.def(
      "_sonar_to_polar",
      [](const carray<double>& p) {
        if (p.ndim() != 2 || p.shape(1) != 3) throw Error("points must be an N×3 array");
        std::vector<double> out(3 * p.shape(0));
        for (py::ssize_t k = 0; k < p.shape(0); ++k) {
          const Polar q = sonar_to_polar({p.at(k, 0), p.at(k, 1), p.at(k, 2)});
          out[3 * k] = q.range;
          out[3 * k + 1] = q.bearing;
          out[3 * k + 2] = q.elevation;
        }
        return adopt(std::move(out), {p.shape(0), 3});
      },
      "points"_a);

  // ---- trajectories
  m.def(
      "read_tum", [](const std::string& path) { return trajectory_to_tuple(read_tum(path)); },
      "path"_a, "Reads a TUM trajectory: (times (N,), poses (N, 4, 4)).");
  m.def(
      "write_tum",
      [](const std::string& path, const carray<double>& times, const carray<double>& poses) {
        write_tum(path, tuple_to_trajectory(times, poses));
      },
      "path"_a, "times"_a, "poses"_a, "Writes a TUM trajectory atomically.");
  m.def(
      "interpolate_poses",
      [](const carray<double>& times, const carray<double>& poses, const carray<double>& query) {
        const Trajectory t = tuple_to_trajectory(times, poses);
        std::vector<Eigen::Isometry3d> out;
        for (py::ssize_t k = 0; k < query.size(); ++k)
          out.push_back(t.interpolate(query.data()[k]));
        return poses_to_array(out);
      },
      "times"_a, "poses"_a, "query"_a,
      "Poses at the query times: linear interpolation of positions and slerp of rotations "
      "(thesis sec. 4.6.1). A time outside the span raises sonar3d.Error.");
  m.def(
      "is_rigid",
      [](const carray<double>& T, double tol) {
        if (T.ndim() != 2 || T.shape(0) != 4 || T.shape(1) != 4) return false;
        Eigen::Isometry3d P;
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) P.matrix()(i, j) = T.at(i, j);
        return is_rigid(P, tol);
      },
      "T"_a, "tol"_a = 1e-6, "True for a finite 4×4 rigid transform.");

  // ---- point clouds
  m.def(
      "read_ply",
      [](const std::string& path, bool all_fields) -> py::object {
        PointCloud c = read_ply(path);
        const py::ssize_t n = static_cast<py::ssize_t>(c.points.size());
        py::object intensity = py::none();
        if (c.has_intensity()) intensity = adopt(std::move(c.intensity), {n});
        if (!all_fields) return py::make_tuple(points_to_array(std::move(c.points)), intensity);
        // Every field the cloud has: sonar3d's clouds carry intensity, texture's colours and
        // its per-point scalars (e.g. `views`), deconvolution's and carving's own properties.
        py::dict d;
        d["points"] = points_to_array(std::move(c.points));
        d["intensity"] = intensity;
        py::object colors = py::none();
        if (c.has_color())
          colors = adopt<std::array<std::uint8_t, 3>, std::uint8_t>(std::move(c.color), {n, 3});
        d["colors"] = colors;
        py::dict props;
        for (PointProperty& p : c.properties)
          props[py::str(p.name)] = adopt(std::move(p.values), {n});
        d["properties"] = props;
        return std::move(d);
      },
      "path"_a, "all_fields"_a = false,
      "Reads a PLY point cloud: (points (N, 3) float32, intensity (N,) or None); with "
      "all_fields=True a dict of every field the file has: points, intensity (N,) or None, colors "
      "(N, 3) uint8 sRGB (PLY red green blue, as `sonar3d texture` writes them) or None, and "
      "properties {name: (N,) float32} for every other per-point scalar (e.g. texture's views).");
  m.def(
      "write_ply",
      [](const std::string& path, const carray<float>& points, const py::object& intensity,
         bool binary) {
        PointCloud c;
        c.points = array_to_points(points);
        if (!intensity.is_none()) {
          const auto i = intensity.cast<carray<float>>();
          if (i.size() != points.shape(0)) throw Error("intensity must hold one value per point");
          c.intensity.assign(i.data(), i.data() + i.size());
        }
        write_ply(path, c, binary ? PlyFormat::Binary : PlyFormat::Ascii);
      },
      "path"_a, "points"_a, "intensity"_a = py::none(), "binary"_a = true,
      "Writes a PLY point cloud atomically.");

  // ---- meshes
  py::class_<TriangleMesh>(m, "Mesh", "An indexed triangle mesh, metres.")
      .def(py::init([](const py::object& vertices, const py::object& triangles) {
             return to_mesh(py::make_tuple(vertices, triangles));
           }),
           "vertices"_a, "triangles"_a)
      .def_property_readonly(
          "vertices",
          [](py::object self) {
            auto& mesh = self.cast<const TriangleMesh&>();
            return view(mesh.vertices.empty() ? nullptr : mesh.vertices[0].data(),
                        {static_cast<py::ssize_t>(mesh.vertices.size()), 3}, self);
          },
          "(N, 3) float32, read-only view.")
      .def_property_readonly(
          "triangles",
          [](py::object self) {
            auto& mesh = self.cast<const TriangleMesh&>();
            return view(mesh.triangles.empty() ? nullptr : mesh.triangles[0].data(),
                        {static_cast<py::ssize_t>(mesh.triangles.size()), 3}, self);
          },
          "(M, 3) int32 vertex indices (counter-clockwise = outward), read-only view.")
      .def("surface_area", &TriangleMesh::surface_area, "m².")
      .def(
          "bounding_box",
          [](const TriangleMesh& mesh) {
            const Eigen::AlignedBox3f b = mesh.bounding_box();
            return py::make_tuple(Eigen::Vector3f(b.min()), Eigen::Vector3f(b.max()));
          },
          "(min, max) corners.")
      .def(
          "transformed",
          [](const TriangleMesh& mesh, const carray<double>& T) {
            TriangleMesh out = mesh;
            out.transform(array_to_pose(T, "T"));
            return out;
          },
          "T"_a, "A copy with every vertex moved by the 4×4 rigid transform T.")
      .def("__len__", [](const TriangleMesh& mesh) { return mesh.triangles.size(); })
      .def("__repr__", [](const TriangleMesh& mesh) {
        return "Mesh(" + std::to_string(mesh.vertices.size()) + " vertices, " +
               std::to_string(mesh.triangles.size()) + " triangles)";
      });
  m.def("load_mesh", &load_mesh, "path"_a,
        "Loads any Assimp format (.dae .stl .obj .ply .gltf ...) in metres, z up, honouring the "
        "file's declared up axis and unit.");
  m.def(
      "save_mesh",
      [](const std::string& path, const py::object& mesh) { save_mesh(path, to_mesh(mesh)); },
      "path"_a, "mesh"_a, "Writes a mesh as PLY or OBJ (by extension), atomically.");
  m.def("reference_object", &make_reference_object, "name"_a,
        "A reference object of the thesis (Fig. 4.11): sphere, tank, pillar or riser, standing "
        "on z = 0.");
  m.def("reference_object_names", &reference_object_names);
  m.def("make_sphere", &make_sphere, "radius"_a, "segments"_a = 64,
        "Sphere centred at the origin.");
  m.def("make_box", &make_box, "sx"_a, "sy"_a, "sz"_a, "Box centred at the origin.");
  m.def("make_cylinder", &make_cylinder, "radius"_a, "height"_a, "segments"_a = 64,
        "capped"_a = true, "Cylinder standing on z = 0.");
  m.def("make_plane", &make_plane, "sx"_a, "sy"_a, "Plane z = 0, normal +z.");
}

}  // namespace sonar3d::python
