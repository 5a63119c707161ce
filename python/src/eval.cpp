// Evaluation against CAD ground truth (thesis sec. 4.5.2.1).
#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/eval/per_object.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

py::dict result_dict(const EvalResult& r) {
  py::dict d;
  d["num_points"] = r.num_points;
  d["num_surface_samples"] = r.num_surface_samples;
  d["median_error"] = r.median_error;
  d["mean_error"] = r.mean_error;
  d["coverage"] = r.coverage;
  d["outliers"] = r.outliers;
  d["median_to_coverage"] = r.median_to_coverage;
  d["coverage_radius"] = r.coverage_radius;
  d["outlier_radius"] = r.outlier_radius;
  std::vector<double> edges = r.histogram_edges;
  std::vector<std::size_t> counts = r.histogram;
  const py::ssize_t ne = static_cast<py::ssize_t>(edges.size());
  const py::ssize_t nc = static_cast<py::ssize_t>(counts.size());
  d["histogram_edges"] = adopt(std::move(edges), {ne});
  d["histogram"] = adopt(std::move(counts), {nc});
  return d;
}

namespace {

PointCloud cloud_from(const carray<float>& points) {
  PointCloud c;
  c.points = array_to_points(points);
  return c;
}

}  // namespace

void bind_eval(py::module_& m) {
  bind_config<EvalConfig>(m, "EvalConfig",
                          "Metric settings (sec. 4.5.2.1): r_c, r_o, surface samples, histogram, "
                          "seed; sonar3d evaluate's flags and --print-config keys "
                          "(docs/reference.md).")
      .def("validate", &EvalConfig::validate);

  m.def(
      "evaluate",
      [](const carray<float>& points, const py::object& mesh, const EvalConfig& config) {
        const PointCloud cloud = cloud_from(points);
        const TriangleMesh truth = to_mesh(mesh);
        EvalResult r;
        {
          py::gil_scoped_release release;
          r = evaluate(cloud, truth, config);
        }
        return result_dict(r);
      },
      "points"_a, "mesh"_a, "config"_a = EvalConfig(),
      "Scores a world-frame cloud (N×3) against a mesh (Mesh, (vertices, triangles) or a file): "
      "{median_error, mean_error (m), coverage, outliers (fractions), median_to_coverage (cm per "
      "%), histogram ...}.");

  m.def(
      "evaluate_dataset",
      [](const carray<float>& points, const py::object& dataset, const EvalConfig& config) {
        const PointCloud cloud = cloud_from(points);
        const std::string dir = py::isinstance<Dataset>(dataset)
                                    ? dataset.cast<const Dataset&>().root.string()
                                    : py::str(dataset).cast<std::string>();
        std::vector<ObjectEval> res;
        {
          py::gil_scoped_release release;
          res = evaluate_objects(cloud, read_truth(dir), config);
        }
        py::dict out;
        for (const auto& o : res) out[py::str(o.name)] = result_dict(o.result);
        return out;
      },
      "points"_a, "dataset"_a, "config"_a = EvalConfig(),
      "Per-object scores against a simulated dataset's truth/ (a Dataset or its directory): "
      "{object name: metrics, ..., 'all': metrics}.");

  m.def(
      "point_to_mesh_distance",
      [](const carray<float>& points, const py::object& mesh) {
        const auto pts = array_to_points(points);
        const MeshDistance md(to_mesh(mesh));
        std::vector<double> d;
        {
          py::gil_scoped_release release;
          d = md.distances(pts);
        }
        const py::ssize_t n = static_cast<py::ssize_t>(d.size());
        return adopt(std::move(d), {n});
      },
      "points"_a, "mesh"_a, "Unsigned distance (m) from each point to the mesh surface.");
}

}  // namespace sonar3d::python
