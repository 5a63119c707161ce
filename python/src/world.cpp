// World models (thesis sec. 6.3.3, docs/world.md): seabed levels of detail, placed models, graph.
#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/world/relocalize.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

void bind_world(py::module_& m) {
  bind_config<SeabedConfig>(m, "SeabedConfig",
                            "The world model's seabed: levels of detail, the margin of placed "
                            "models, filling under them (docs/world.md).")
      .def("validate", &SeabedConfig::validate);
  bind_config<ConnectionConfig>(m, "PipelineSearchConfig",
                                "The search for pipelines between placed structures: a ridge "
                                "along the line joining them (docs/world.md).")
      .def("validate", &ConnectionConfig::validate);
  bind_config<WorldModelConfig>(
      m, "WorldModelConfig",
      "A world model's settings, as `sonar3d world` runs it (its flags and --print-config keys; "
      "docs/reference.md): seabed, find_connections, pipeline_search, min_confidence.")
      .def("validate", &WorldModelConfig::validate);
  bind_config<RelocalizeConfig>(m, "RelocalizeConfig",
                                "Relocalisation against a world model, as `sonar3d relocalize` "
                                "runs it (docs/mapping.md \"Relocalisation\").")
      .def("validate", &RelocalizeConfig::validate);
  m.def(
      "relocalize",
      [](const std::string& dataset, const std::string& world,
         const std::optional<RelocalizeConfig>& config, const std::string& output, bool overwrite,
         const py::object& progress) {
        const RelocalizeConfig cfg = config ? *config : RelocalizeConfig();
        cfg.validate();
        std::unique_ptr<OutputDirectory> out;
        if (!output.empty()) {  // as the CLI: the output rule, inputs never the destination
          OutputPolicy policy;
          policy.overwrite = overwrite;
          policy.sources = {dataset, world};
          out = std::make_unique<OutputDirectory>(output, OutputKind::Relocalization, policy);
        }
        ProgressArg p(progress);
        RelocalizeResult r = p.run([&] {
          const WorldModelCloud w = read_world_model_cloud(world, cfg.model_spacing_m);
          const Dataset ds = read_dataset(dataset);
          RelocalizeResult res = relocalize(ds, w, cfg, p.terminal());
          res.dataset = dataset;
          if (out) {
            write_relocalization(out->staging(), res, cfg);
            out->commit();
          }
          return res;
        });
        py::list swaths;
        for (const RelocalizedSwath& s : r.swaths) {
          swaths.append(py::dict(
              "frames"_a = py::make_tuple(s.first_frame, s.last_frame), "found"_a = s.found,
              "reason"_a = s.reason, "borrowed"_a = s.borrowed,
              "T_model_survey"_a = pose_to_array(s.T_model_survey), "yaw_deg"_a = s.yaw_deg,
              "sigma_horizontal_m"_a = s.sigma_horizontal_m,
              "sigma_hessian_m"_a = s.sigma_hessian_m, "sigma_pieces_m"_a = s.sigma_pieces_m,
              "overlap_fraction"_a = s.overlap_fraction, "residual_m"_a = s.residual_m,
              "alternative_m"_a = s.alternative_m, "distinctiveness"_a = s.distinctiveness,
              "pieces_used"_a = s.pieces_used));
        }
        std::vector<double> times = r.navigation.times;
        const py::ssize_t n = static_cast<py::ssize_t>(times.size());
        py::dict res("found"_a = r.found, "swaths"_a = swaths,
                     "times"_a = adopt(std::move(times), {n}),
                     "poses"_a = poses_to_array(r.navigation.poses),
                     "sigma_horizontal_m"_a = r.sigma_horizontal_m, "seconds"_a = r.seconds_total);
        // With config.map_voxel_m > 0: the survey carved with the relocalised navigation.
        if (!r.map.empty()) res["map"] = points_to_array(std::move(r.map.points));
        return res;
      },
      "dataset"_a, "world"_a, "config"_a = py::none(), "output"_a = "", "overwrite"_a = false,
      "progress"_a = py::none(),
      "Relocalise a dataset (a new survey, down to one line) against a world model directory of "
      "`sonar3d world`, as `sonar3d relocalize` does: config a RelocalizeConfig; output (optional) "
      "a relocalisation directory to write (relocalization.json, navigation.tum). Returns found, "
      "per swath its correction T_model_survey (4×4), yaw_deg, sigma_horizontal_m, "
      "overlap_fraction, residual_m, distinctiveness, found and why not (reason); times and poses "
      "(N×4×4 T_world_vehicle in the world model's frame; empty when not found), "
      "sigma_horizontal_m, seconds; with config.map_voxel_m > 0 also map, the survey carved with "
      "the relocalised navigation ((N, 3), the model's frame: survey B of diff_surveys with "
      "b_in_a_frame=True).");
  m.def(
      "world_model",
      [](const carray<float>& points, const std::string& placements, const std::string& catalogue,
         const py::object& config, const std::string& connections_file, const std::string& output,
         bool glb_all_lods, const std::optional<carray<std::uint8_t>>& colors,
         const py::kwargs& settings) {
        PointCloud cloud;
        cloud.points = array_to_points(points);
        if (colors) {
          // sRGB bytes per point, as PLY red/green/blue (black: no colour, docs/world.md).
          if (colors->ndim() != 2 || colors->shape(1) != 3 ||
              static_cast<std::size_t>(colors->shape(0)) != cloud.points.size()) {
            throw Error("colors must be an N×3 uint8 array, one row per point");
          }
          cloud.color.resize(cloud.points.size());
          std::copy(colors->data(), colors->data() + colors->size(),
                    cloud.color.empty() ? nullptr : cloud.color[0].data());
        }
        WorldModelConfig cfg =
            config_with_settings<WorldModelConfig>(config, settings, "world_model");
        cfg.validate();
        const PlacementsFile p = read_placements(placements);
        cfg.min_confidence = world_confidence_threshold(p, cfg.min_confidence, "min_confidence");
        std::vector<GivenConnection> given;
        if (!connections_file.empty()) given = read_given_connections(connections_file);
        WorldModel w;
        {
          py::gil_scoped_release release;
          w = build_world_model(cloud, world_objects(p, read_catalogue(catalogue)), cfg);
          add_given_connections(w, given, connections_file, cfg.seabed.margin_m);
          if (!output.empty()) {
            WorldWriteInfo info;
            info.map = "(points)";
            info.placements = placements;
            info.catalogue = catalogue;
            info.glb_all_lods = glb_all_lods;
            write_world_model(output, w, info);
          }
        }
        py::list objects, connections, seabed;
        for (const WorldObject& o : w.objects) {
          objects.append(py::dict("id"_a = o.id, "model"_a = o.model, "kind"_a = o.kind,
                                  "T_world_model"_a = pose_to_array(o.T_world_model),
                                  "score_m"_a = o.score_m,
                                  "residual_median_m"_a = o.residual_median_m,
                                  "confidence"_a = o.confidence, "confirmed"_a = o.confirmed));
        }
        for (const Connection& c : w.connections) {
          connections.append(py::dict("from"_a = c.from, "to"_a = c.to, "kind"_a = c.kind,
                                      "length_m"_a = c.length_m, "fraction"_a = c.fraction,
                                      "found"_a = c.found, "given"_a = c.given));
        }
        for (SeabedLod& l : w.seabed) {
          const py::ssize_t nt = static_cast<py::ssize_t>(l.mesh.triangles.size());
          const py::ssize_t nc = static_cast<py::ssize_t>(l.color_points.size());
          seabed.append(py::dict(
              "lod"_a = l.lod, "cell_m"_a = l.cell_m,
              "vertices"_a = points_to_array(std::move(l.mesh.vertices)),
              "colors"_a = points_to_array(std::move(l.color)),
              "color_points"_a =
                  adopt<std::uint32_t, std::uint32_t>(std::move(l.color_points), {nc}),
              "triangles"_a = adopt<Eigen::Vector3i, int>(std::move(l.mesh.triangles), {nt, 3})));
        }
        return py::dict("objects"_a = objects, "connections"_a = connections, "seabed"_a = seabed,
                        "seabed_points"_a = w.seabed_points, "filled_cells"_a = w.filled_cells,
                        "min_confidence"_a = w.min_confidence);
      },
      "points"_a, "placements"_a, "catalogue"_a, "config"_a = py::none(), "connections"_a = "",
      "output"_a = "", "glb_all_lods"_a = false, "colors"_a = py::none(),
      "A world model (thesis sec. 6.3.3) from an (N, 3) world-frame cloud, a placements JSON "
      "(sonar3d.recognize / sonar3d recognize) and the catalogue YAML (colors: optional (N, 3) "
      "uint8 "
      "sRGB video colours per point, black = none: the seabed is then coloured): the seabed "
      "(points no "
      "placed model explains) as height-field meshes at lod_cells_m (metres, finest first), the "
      "placed models and the pipelines found between them, plus the connections given in the "
      "YAML file `connections` (docs/world.md). config: a WorldModelConfig (sonar3d world's "
      "settings; default the library's), any of its fields given as a keyword overriding it "
      "(seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]), min_confidence=0.5: placements below it "
      "stay unconfirmed objects, never connected and explaining no point; None: the placements "
      "file's settings.min_confidence, else 0). Returns a dict: objects (id, model, kind, "
      "T_world_model 4×4, score_m, residual_median_m, confidence (NaN: unknown), confirmed), "
      "min_confidence, connections (from, to, kind, length_m, "
      "fraction (NaN when not found), found, given), seabed (lod, cell_m, vertices (N, 3) float32, "
      "triangles (M, 3) int32, colors (N, 3) float32 linear RGB and color_points (N,) uint32, "
      "both empty without colors), seabed_points, filled_cells. With output, also writes that "
      "directory (world.glb, "
      "seabed_lod<k>.ply, models/, graph.json; docs/formats.md).");
}

}  // namespace sonar3d::python
