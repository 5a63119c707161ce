// Change detection between surveys (docs/change.md): registration, placements and heights
// compared.
#include "sonar3d/world/change.hpp"

#include <map>

#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/video/texture_files.hpp"

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
    SurveyPlacement p;
    p.model = d["model"].cast<std::string>();
    p.T_world_model = array_to_pose(d["T_world_model"].cast<carray<double>>(), "T_world_model");
    if (d.contains("confidence") && !d["confidence"].is_none()) {
      p.confidence = d["confidence"].cast<double>();
      if (!(p.confidence >= 0 && p.confidence <= 1)) {
        throw Error(std::string("diff_surveys: a placement of ") + which +
                    " has a 'confidence' that is not a number in [0, 1]");
      }
    }
    out.push_back(p);
  }
  return out;
}

// A coloured cloud given as (points (N, 3), colors (N, 3) linear RGB in [0, 1], as
// sonar3d.texture_cloud returns; 0, 0, 0 = no colour) into a PointCloud with 8-bit sRGB.
PointCloud to_colour_cloud(const py::object& arg, const std::string& which) {
  const std::string what = "diff_surveys: " + which;
  if (!py::isinstance<py::tuple>(arg) || py::len(arg) != 2) {
    throw Error(what + " must be a tuple (points (N, 3), colors (N, 3) linear RGB in [0, 1])");
  }
  const py::tuple t = arg.cast<py::tuple>();
  PointCloud c;
  c.points = array_to_points(t[0].cast<carray<float>>(), what + " points");
  const auto col = t[1].cast<carray<double>>();
  if (col.ndim() != 2 || col.shape(1) != 3 || static_cast<std::size_t>(col.shape(0)) != c.size()) {
    throw Error(what + " colors must be an N×3 array, one row per point");
  }
  c.color.resize(c.size());
  const double* v = col.data();
  for (std::size_t i = 0; i < c.size(); ++i) {
    for (std::size_t k = 0; k < 3; ++k) {
      const double x = v[3 * i + k];
      if (!std::isfinite(x) || x < 0 || x > 1) {
        throw Error(what + " colors: row " + std::to_string(i) + " has " + std::to_string(x) +
                    ", not a linear RGB value in [0, 1]");
      }
      c.color[i][k] =
          static_cast<std::uint8_t>(std::lround(255 * linear_to_srgb(static_cast<float>(x))));
    }
  }
  return c;
}

}  // namespace

void bind_change(py::module_& m) {
  bind_config<ChangeRegistrationConfig>(
      m, "ChangeRegistrationConfig",
      "Survey B registered onto survey A on elevation maps: a yaw search, sec. 6.2.2.1's shift "
      "search (eq. 6.1-6.2) per yaw, then Gauss-Newton (docs/change.md; sonar3d diff's flags).")
      .def("validate", &ChangeRegistrationConfig::validate);
  bind_config<params::Nested<ChangeRegistrationConfig>>(
      m, "RegistrationPart",
      "The registration settings of a RelocalizeConfig (a view; its threads are the "
      "relocalisation's).");
  bind_config<ColourChangeConfig>(m, "ColourChangeConfig",
                                  "Colour change between two coloured clouds (docs/change.md).")
      .def("validate", &ColourChangeConfig::validate);
  bind_config<ChangeConfig>(
      m, "ChangeConfig",
      "Change detection between two surveys, as `sonar3d diff` runs it (its flags and "
      "--print-config keys; docs/reference.md): registration, colour, then the height change "
      "map and the objects' pairing.")
      .def("validate", &ChangeConfig::validate);
  m.def(
      "diff_surveys",
      [](const carray<float>& points_a, const carray<float>& points_b, const py::list& placements_a,
         const py::list& placements_b, const std::string& catalogue, const py::object& colour_a,
         const py::object& colour_b, const py::object& config, bool b_in_a_frame,
         const py::kwargs& settings) {
        PointCloud a, b;
        a.points = array_to_points(points_a);
        b.points = array_to_points(points_b);
        const ChangeConfig cfg =
            config_with_settings<ChangeConfig>(config, settings, "diff_surveys");
        cfg.validate();
        if (colour_a.is_none() != colour_b.is_none()) {
          throw Error("diff_surveys: colour_a and colour_b go together (both surveys' colours)");
        }
        PointCloud ca, cb;
        if (!colour_a.is_none()) {
          ca = to_colour_cloud(colour_a, "colour_a");
          cb = to_colour_cloud(colour_b, "colour_b");
        }
        const bool colour = !colour_a.is_none();
        const auto pa = to_placements(placements_a, "A");
        const auto pb = to_placements(placements_b, "B");
        ObjectModels models;
        if (!catalogue.empty()) {
          std::vector<std::string> placed;
          for (const auto* list : {&pa, &pb}) {
            for (const SurveyPlacement& p : *list) placed.push_back(p.model);
          }
          models = catalogue_object_models(read_catalogue(catalogue), placed);
        }
        ChangeResult r;
        {
          py::gil_scoped_release release;
          // B relocalised against A's world model (sonar3d.relocalize's map): in A's frame.
          ChangeRegistration placed;
          placed.method = "given: B in A's frame";
          r = diff_surveys(a, b, pa, pb, models, cfg, colour ? &ca : nullptr,
                           colour ? &cb : nullptr, b_in_a_frame ? &placed : nullptr);
        }
        py::dict out = json_loads(changes_json(r));
        out["change_map"] = py::cast(r.change_map);
        if (r.colour.compared) out["colour_change_map"] = py::cast(r.colour.delta_map);
        return out;
      },
      "points_a"_a, "points_b"_a, "placements_a"_a = py::list(), "placements_b"_a = py::list(),
      "catalogue"_a = "", "colour_a"_a = py::none(), "colour_b"_a = py::none(),
      "config"_a = py::none(), "b_in_a_frame"_a = false,
      "Compare two surveys of one site ((N, 3) world-frame clouds, each in its own world): B "
      "registered onto A, placements (lists of dicts with model and T_world_model, as "
      "sonar3d.recognize returns; symmetries and sizes from the catalogue YAML if given) compared "
      "(unchanged, moved, added, removed, or uncertain when they disagree without a height "
      "change behind it), heights "
      "compared cell by cell. Returns the changes.json content as a dict (T_a_b, registration, "
      "objects, regions, thresholds, seconds; docs/change.md) plus change_map, the ElevationMap "
      "of B − A in A's frame (m). colour_a, colour_b (both or neither): each survey's coloured "
      "cloud in its own world as (points (N, 3), colors (N, 3) linear RGB in [0, 1], 0 = unseen; "
      "what texture_cloud returns): the colour change is compared too (the dict's 'colour', and "
      "colour_change_map, the colour difference per cell). config: a ChangeConfig (default: "
      "the library's, the one sonar3d diff runs); any of its fields given as a keyword "
      "(cell_m=0.05, registration=ChangeRegistrationConfig(num_threads=2)) overrides it. "
      "b_in_a_frame: B is in A's frame already (the map of sonar3d.relocalize against A's world "
      "model, RelocalizeConfig(map_voxel_m=...)): not registered (T_a_b the identity).");
}

}  // namespace sonar3d::python
