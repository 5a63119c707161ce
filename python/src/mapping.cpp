// Field mapping (thesis sec. 6.2): elevation maps, swath registration, survey mapping.
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/position_fixes.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/mapping/swath_registration.hpp"
#include "sonar3d/world/known_poses.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;
namespace fs = std::filesystem;

void bind_mapping(py::module_& m) {
  py::class_<ElevationMap>(m, "ElevationMap",
                           "Highest height z per horizontal cell (sec. 6.2.1), local ENU: z is a "
                           "rows × cols float32 array (NaN = no data), row 0 the northern edge; "
                           "origin_xy the north-west corner (m), cell_m the cell size (m).")
      .def(py::init([](const carray<float>& z, const Eigen::Vector2d& origin_xy, double cell_m) {
             if (z.ndim() != 2) throw Error("ElevationMap: z must be a rows × cols array");
             ElevationMap e;
             e.rows = static_cast<int>(z.shape(0));
             e.cols = static_cast<int>(z.shape(1));
             e.origin_xy = origin_xy;
             e.cell_m = cell_m;
             e.z.assign(z.data(), z.data() + z.size());
             return e;
           }),
           "z"_a, "origin_xy"_a, "cell_m"_a)
      .def_property_readonly("z",
                             [](const ElevationMap& e) {
                               std::vector<float> z = e.z;
                               return adopt(std::move(z), {static_cast<py::ssize_t>(e.rows),
                                                           static_cast<py::ssize_t>(e.cols)});
                             })
      .def_property_readonly("origin_xy", [](const ElevationMap& e) { return e.origin_xy; })
      .def_readonly("cell_m", &ElevationMap::cell_m)
      .def_readonly("rows", &ElevationMap::rows)
      .def_readonly("cols", &ElevationMap::cols)
      .def("num_valid", &ElevationMap::num_valid)
      .def("__repr__", &fields_repr);

  bind_config<ElevationMapConfig>(
      m, "ElevationMapConfig",
      "An elevation map's settings (sec. 6.2.1; sonar3d elevation's `map:` block, "
      "docs/reference.md).")
      .def("validate", &ElevationMapConfig::validate);
  bind_config<ElevationWriteOptions>(
      m, "ElevationWriteOptions",
      "How an elevation map is stored in a GeoTIFF (sonar3d elevation's `geotiff:` block): "
      "float32, or uint16 with uint16_step_m.");
  m.def(
      "elevation_map",
      [](const carray<float>& points, const py::object& config, const py::kwargs& settings) {
        PointCloud c;
        c.points = array_to_points(points);
        const ElevationMapConfig cfg =
            config_with_settings<ElevationMapConfig>(config, settings, "elevation_map");
        return elevation_map_from_points(c, cfg);
      },
      "points"_a, "config"_a = py::none(),
      "Elevation map of an (N, 3) world-frame cloud: the highest z per cell (sec. 6.2.1). "
      "config: an ElevationMapConfig, or its settings as keywords (cell_m=0.05).");
  m.def(
      "write_elevation_geotiff",
      [](const std::string& path, const ElevationMap& map, const py::object& config,
         const py::kwargs& settings) {
        const ElevationWriteOptions w = config_with_settings<ElevationWriteOptions>(
            config, settings, "write_elevation_geotiff");
        write_elevation_geotiff(path, map, w);
      },
      "path"_a, "map"_a, "config"_a = py::none(),
      "GeoTIFF, written atomically: float32, or uint16 with uint16_step_m metres per step "
      "(config: an ElevationWriteOptions, or uint16_step_m= as a keyword).");
  m.def("read_elevation_geotiff", &read_elevation_geotiff, "path"_a);
  m.def("write_elevation_png", &write_elevation_png, "path"_a, "map"_a,
        "A picture with a colour bar; returns the (min, max) height shown.");

  bind_config<SwathRegistrationConfig>(
      m, "SwathRegistrationConfig",
      "Swath registration (sec. 6.2.2.1, eq. 6.1-6.2): the shift search between two elevation "
      "maps (docs/reference.md).")
      .def("validate", &SwathRegistrationConfig::validate);
  bind_config<params::Nested<SwathRegistrationConfig>>(
      m, "SwathRegistrationPart",
      "The registration settings of a MapSurveyConfig (a view; its threads are the map's).");
  bind_config<SwathAdjustmentConfig>(
      m, "SwathAdjustmentConfig",
      "The robust adjustment of the swath offsets from every tie (docs/mapping.md).")
      .def("validate", &SwathAdjustmentConfig::validate);
  bind_config<SwathSplitConfig>(
      m, "SwathSplitConfig",
      "A survey split into swaths at its turns, or by explicit time ranges (docs/mapping.md).")
      .def("validate", &SwathSplitConfig::validate);
  bind_config<MapSurveyConfig>(
      m, "MapSurveyConfig",
      "Field mapping, as `sonar3d map` runs it (its flags and --print-config keys; "
      "docs/reference.md): elevation map cell, carving voxel and region, adjustment method, "
      "swath split, registration, adjustment, carving.")
      .def("validate", &MapSurveyConfig::validate);

  py::class_<SwathTie>(m, "SwathTie",
                       "A registered pair: t = (dx, dy, dz) moving the moving map onto the "
                       "reference (m), score_m (eq. 6.2), overlap_cells, confidence (0-1).")
      .def_readonly("reference", &SwathTie::reference)
      .def_readonly("moving", &SwathTie::moving)
      .def_property_readonly("t", [](const SwathTie& t) { return t.t; })
      .def_readonly("score_m", &SwathTie::score_m)
      .def_readonly("overlap_cells", &SwathTie::overlap_cells)
      .def_readonly("confidence", &SwathTie::confidence)
      .def_readonly("seconds", &SwathTie::seconds)
      .def("__repr__", &fields_repr);

  m.def(
      "register_elevation_maps",
      [](const ElevationMap& reference, const ElevationMap& moving,
         const SwathRegistrationConfig& config) {
        py::gil_scoped_release release;
        return register_elevation_maps(reference, moving, config);
      },
      "reference"_a, "moving"_a, "config"_a = SwathRegistrationConfig(),
      "Eq. 6.1-6.2 over every shift within ±search_m: the shift and height offset moving "
      "`moving` onto `reference`.");

  m.def(
      "map_survey",
      [](const Dataset& dataset, const std::string& output, const py::object& fixes,
         double fix_sigma, const py::object& known_poses, const py::object& placements,
         const py::object& placements_nav, const py::object& progress, const py::object& config,
         const py::kwargs& settings) {
        MapSurveyConfig cfg = config_with_settings<MapSurveyConfig>(config, settings, "map_survey");
        cfg.registration.num_threads = cfg.carve.num_threads;
        require(fix_sigma == 0 || !fixes.is_none(), "fix_sigma: give fixes as well");
        if (!fixes.is_none()) {
          cfg.fixes_source = fixes.cast<std::string>();
          cfg.fixes = read_position_fixes(cfg.fixes_source, FixFormat::Auto, fix_sigma);
        }
        require(known_poses.is_none() == placements.is_none(),
                "known_poses and placements go together: the known poses, and the structures "
                "recognised in this survey's map");
        require(placements_nav.is_none() || !placements.is_none(),
                "placements_nav: give placements as well");
        if (!known_poses.is_none()) {  // as sonar3d map --known-poses
          load_known_pose_inputs(
              cfg, known_poses.cast<std::string>(), placements.cast<std::string>(),
              placements_nav.is_none() ? std::string() : placements_nav.cast<std::string>());
        }
        cfg.validate();
        ProgressArg p(progress);
        const MapSurveyResult r =
            p.run([&] { return map_survey(dataset, cfg, output, p.terminal()); });
        py::list offsets, rates;
        for (const SwathInfo& s : r.swaths) {
          offsets.append(s.offset);
          rates.append(s.rate);
        }
        py::dict d;
        d["offsets"] = offsets;
        d["rates"] = rates;
        d["ties"] = r.ties;
        d["merged_points"] = r.merged_points;
        d["seconds"] = r.seconds_total;
        py::list structures;  // simulated sites: each structure against its CAD
        for (const StructureEval& e : r.structures) {
          py::dict s;
          s["name"] = e.name;
          s["kind"] = to_string(e.kind);
          s["before"] = result_dict(e.before);
          s["after"] = result_dict(e.after);
          structures.append(s);
        }
        d["structures"] = structures;
        if (!cfg.fixes.empty()) {  // the absolute references and the navigation model
          const SwathAdjustment& adj = r.adjustment;
          py::list rejected;
          std::size_t n_fixes = 0;
          for (const FixReport& f : adj.fixes) {
            if (!f.name.empty()) continue;  // a known structure pose: in the summary
            ++n_fixes;
            if (!f.rejected) continue;
            py::dict e;
            e["time_s"] = f.time;
            e["line"] = f.line;
            e["residual_m"] = f.residual_m;
            e["residual_sigma"] = f.normalized;
            rejected.append(e);
          }
          py::dict fx;
          fx["given"] = r.fixes_given;
          fx["outside_time_span"] = r.fixes_outside;
          fx["used"] = n_fixes - py::len(rejected);
          fx["rejected"] = rejected;
          d["fixes"] = fx;
          py::dict nm;
          nm["estimated"] = adj.estimated_scale_heading;
          nm["scale_error"] = adj.scale_error();
          nm["scale_error_sigma"] = adj.scale_error_sigma;
          nm["heading_bias_rad"] = adj.heading_bias_rad();
          nm["heading_bias_sigma_rad"] = adj.heading_bias_sigma_rad;
          d["navigation_model"] = nm;
        }
        // Everything the CLI writes: OUTPUT/summary.json (docs/formats.md), known poses included.
        std::ifstream in(fs::path(output) / "summary.json");
        std::stringstream text;
        text << in.rdbuf();
        d["summary"] = json_loads(text.str());
        return d;
      },
      "dataset"_a, "output"_a, "fixes"_a = py::none(), "fix_sigma"_a = 0.0,
      "known_poses"_a = py::none(), "placements"_a = py::none(), "placements_nav"_a = py::none(),
      "progress"_a = py::none(), "config"_a = py::none(),
      "Field mapping (sec. 6.2; `sonar3d map`): writes `output` (swath maps, ties, corrected "
      "navigation, merged cloud and map) and returns {offsets: per-swath (dx, dy, dz) at the "
      "swath's "
      "start, rates: per-swath horizontal drift rates (m/s, method 'drift'), ties, "
      "merged_points, seconds, structures: simulated sites' structures and pipelines scored "
      "against their CAD as logged (before) and corrected (after)}. `fixes`: a position fixes file "
      "(`sonar3d map --fixes`: CSV time_s,x_m,y_m[,z_m],sigma_m, or TUM with `fix_sigma` in "
      "metres) placing the map in the world; then the dict also holds fixes {given, "
      "outside_time_span, used, rejected: [{time_s, line, residual_m, residual_sigma}]} and "
      "navigation_model {estimated, scale_error, scale_error_sigma, heading_bias_rad, "
      "heading_bias_sigma_rad}. `known_poses` (a world model directory or placements JSON) with "
      "`placements` (structures recognised in a map of this dataset) and optionally "
      "`placements_nav` (that map's navigation, TUM): known structure poses as constraints "
      "(`sonar3d map --known-poses`). 'summary' holds output/summary.json as the CLI writes it "
      "(docs/formats.md). `config`: a MapSurveyConfig (or None for the defaults); keyword "
      "settings set its fields (cell_m=0.05, method='drift', region=((x0, y0, z0), (x1, y1, "
      "z1)), ...), an unknown one is an error listing the fields. `progress`: None, True "
      "(terminal bars) or a callable progress(done, total).");
}

}  // namespace sonar3d::python
