// Field mapping (thesis sec. 6.2): elevation maps, swath registration, survey mapping.
#include "common.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/position_fixes.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/mapping/swath_registration.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

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

  m.def(
      "elevation_map",
      [](const carray<float>& points, double cell_m) {
        PointCloud c;
        c.points = array_to_points(points);
        ElevationMapConfig cfg;
        cfg.cell_m = cell_m;
        return elevation_map_from_points(c, cfg);
      },
      "points"_a, "cell_m"_a = 0.02,
      "Elevation map of an (N, 3) world-frame cloud: the highest z per cell of cell_m metres.");
  m.def(
      "write_elevation_geotiff",
      [](const std::string& path, const ElevationMap& map, std::optional<double> uint16_step_m) {
        ElevationWriteOptions w;
        if (uint16_step_m) {
          w.encoding = ElevationEncoding::UInt16;
          w.uint16_step_m = *uint16_step_m;
        }
        write_elevation_geotiff(path, map, w);
      },
      "path"_a, "map"_a, "uint16_step_m"_a = py::none(),
      "GeoTIFF (float32, or uint16 with this step in metres), written atomically.");
  m.def("read_elevation_geotiff", &read_elevation_geotiff, "path"_a);
  m.def("write_elevation_png", &write_elevation_png, "path"_a, "map"_a,
        "A picture with a colour bar; returns the (min, max) height shown.");

  py::class_<SwathRegistrationConfig>(
      m, "SwathRegistrationConfig",
      "Swath registration (sec. 6.2.2.1): search_m (m), min_overlap_cells, subcell, "
      "overlap_full_cells, coarse_factor (1 = the thesis' exhaustive search), num_threads.")
      .def(py::init(&from_kwargs<SwathRegistrationConfig>))
      .def_readwrite("search_m", &SwathRegistrationConfig::search_m)
      .def_readwrite("min_overlap_cells", &SwathRegistrationConfig::min_overlap_cells)
      .def_readwrite("subcell", &SwathRegistrationConfig::subcell)
      .def_readwrite("overlap_full_cells", &SwathRegistrationConfig::overlap_full_cells)
      .def_readwrite("coarse_factor", &SwathRegistrationConfig::coarse_factor)
      .def_readwrite("num_threads", &SwathRegistrationConfig::num_threads)
      .def("__repr__", &fields_repr)
      .def("validate", &SwathRegistrationConfig::validate);

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
      [](const Dataset& dataset, const std::string& output, double cell_m, double voxel_size,
         const SwathRegistrationConfig& registration, const std::string& method, double piece_m,
         const py::object& region, const py::object& progress, const py::object& fixes,
         double fix_sigma, double fix_gate_sigma, bool fix_scale_heading) {
        MapSurveyConfig cfg;
        if (!fixes.is_none()) {
          cfg.fixes_source = fixes.cast<std::string>();
          cfg.fixes = read_position_fixes(cfg.fixes_source, FixFormat::Auto, fix_sigma);
        }
        cfg.fix_gate_sigma = fix_gate_sigma;
        cfg.fix_scale_heading = fix_scale_heading;
        cfg.cell_m = cell_m;
        cfg.piece_m = piece_m;
        cfg.carve.voxel_size = voxel_size;
        cfg.registration = registration;
        cfg.method = swath_adjust_method_from_string(method);
        if (!region.is_none()) {
          const auto t = region.cast<py::sequence>();
          if (t.size() != 2) throw Error("region must be (min xyz, max xyz) or None");
          cfg.carve.region =
              Eigen::AlignedBox3d(t[0].cast<Eigen::Vector3d>(), t[1].cast<Eigen::Vector3d>());
          validate_region(*cfg.carve.region, "region");
        }
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
          for (const FixReport& f : adj.fixes) {
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
          fx["used"] = adj.fixes.size() - py::len(rejected);
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
        return d;
      },
      "dataset"_a, "output"_a, "cell_m"_a = MapSurveyConfig().cell_m,
      "voxel_size"_a = MapSurveyConfig().carve.voxel_size,
      "registration"_a = SwathRegistrationConfig(), "method"_a = "global",
      "piece_m"_a = MapSurveyConfig().piece_m, "region"_a = py::none(), "progress"_a = py::none(),
      "fixes"_a = py::none(), "fix_sigma"_a = 0.0,
      "fix_gate_sigma"_a = MapSurveyConfig().fix_gate_sigma,
      "fix_scale_heading"_a = MapSurveyConfig().fix_scale_heading,
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
      "heading_bias_sigma_rad}.");
}

}  // namespace sonar3d::python
