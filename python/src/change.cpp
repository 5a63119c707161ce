// Change detection between surveys (docs/change.md): registration, placements and heights
// compared.
#include "sonar3d/world/change.hpp"

#include <map>

#include "common.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

namespace {

std::vector<SurveyPlacement> to_placements(const py::list& list, const char* which) {
  std::vector<SurveyPlacement> out;
  for (const auto& item : list) {
    const py::dict d = item.cast<py::dict>();
    if (!d.contains("model") || !d.contains("T_world_model")) {
      throw Error(std::string("diff_surveys: each placement of ") + which +
                  " needs 'model' and 'T_world_model' (as sonar3d.recognize returns)");
    }
    out.push_back({d["model"].cast<std::string>(),
                   array_to_pose(d["T_world_model"].cast<carray<double>>(), "T_world_model")});
  }
  return out;
}

}  // namespace

void bind_change(py::module_& m) {
  m.def(
      "diff_surveys",
      [](const carray<float>& points_a, const carray<float>& points_b, const py::list& placements_a,
         const py::list& placements_b, const std::string& catalogue, double cell_m, double k_sigma,
         double tolerance_m, double min_area_m2, double search_m, double yaw_search_deg,
         int num_threads) {
        PointCloud a, b;
        a.points = array_to_points(points_a);
        b.points = array_to_points(points_b);
        ChangeConfig cfg;
        cfg.cell_m = cell_m;
        cfg.k_sigma = k_sigma;
        cfg.tolerance_m = tolerance_m;
        cfg.min_area_m2 = min_area_m2;
        cfg.registration.search_m = search_m;
        cfg.registration.yaw_search_deg = yaw_search_deg;
        cfg.registration.num_threads = num_threads;
        cfg.validate();
        const auto pa = to_placements(placements_a, "A");
        const auto pb = to_placements(placements_b, "B");
        std::map<std::string, Symmetry> symmetries;
        if (!catalogue.empty()) symmetries = catalogue_symmetries(read_catalogue(catalogue));
        ChangeResult r;
        {
          py::gil_scoped_release release;
          r = diff_surveys(a, b, pa, pb, symmetries, cfg);
        }
        py::dict out = py::module_::import("json").attr("loads")(changes_json(r));
        out["change_map"] = py::cast(r.change_map);
        return out;
      },
      "points_a"_a, "points_b"_a, "placements_a"_a = py::list(), "placements_b"_a = py::list(),
      "catalogue"_a = "", "cell_m"_a = 0.04, "k_sigma"_a = 5.0, "tolerance_m"_a = 0.1,
      "min_area_m2"_a = 0.05, "search_m"_a = 0.6, "yaw_search_deg"_a = 2.0, "num_threads"_a = 0,
      "Compare two surveys of one site ((N, 3) world-frame clouds, each in its own world): B "
      "registered onto A, placements (lists of dicts with model and T_world_model, as "
      "sonar3d.recognize returns; symmetries from the catalogue YAML if given) compared, heights "
      "compared cell by cell. Returns the changes.json content as a dict (T_a_b, registration, "
      "objects, regions, thresholds, seconds; docs/change.md) plus change_map, the ElevationMap "
      "of B − A in A's frame (m).");
}

}  // namespace sonar3d::python
