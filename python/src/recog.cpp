// CAD-model recognition (thesis sec. 6.3, docs/recognition.md): the 2D (sec. 6.3.2) or 3D
// (sec. 6.3.1) method on a cloud.
#include <pybind11/stl.h>

#include <optional>

#include "common.hpp"
#include "params_py.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognition_3d.hpp"
#include "sonar3d/recog/recognize.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

void bind_recog(py::module_& m) {
  // The configurations, from their one declaration (core/params.hpp; docs/reference.md).
  bind_config<DescriptorConfig>(m, "DescriptorConfig",
                                "Ring-histogram descriptors (sec. 6.3.2.3).");
  bind_config<ScanConfig>(m, "ScanConfig", "The descriptor scan (sec. 6.3.2.4).");
  bind_config<Search4dConfig>(m, "Search4dConfig", "The exhaustive 4D search (eq. 6.9).");
  bind_config<TrimmedIcpConfig>(m, "TrimmedIcpConfig", "Trimmed ICP (sec. 6.3.2.5).");
  bind_config<ModelSamplingConfig>(m, "ModelSamplingConfig", "Surface sampling of the models.");
  bind_config<VerificationConfig>(m, "VerificationConfig",
                                  "Hypothesis verification and the calibrated confidence "
                                  "(docs/recognition.md, Verification).");
  bind_config<ScaleSearchConfig>(m, "ScaleSearchConfig",
                                 "The size search of models with a scale_range.");
  bind_config<RecognitionConfig>(m, "RecognitionConfig",
                                 "The 2D method (sec. 6.3.2); its verification and num_threads "
                                 "serve both methods.");
  bind_config<Recognition3dConfig>(m, "Recognition3dConfig", "The 3D method (sec. 6.3.1).");
  bind_config<RecognizeConfig>(m, "RecognizeConfig",
                               "The recognition as `sonar3d recognize` runs it: method ('2d' or "
                               "'3d'), two_d (RecognitionConfig), three_d "
                               "(Recognition3dConfig).")
      .def("validate", &RecognizeConfig::validate);

  m.def(
      "recognize",
      [](const carray<float>& points, const std::string& catalogue,
         const std::optional<RecognizeConfig>& config, const std::optional<std::string>& method,
         const py::object& progress, const std::string& output, const std::string& mesh,
         bool overwrite) {
        RecognizeConfig cfg = config ? *config : RecognizeConfig();
        if (method) cfg.method = *method;
        cfg.validate();
        // The command's outputs, under its output rule: checked before the work.
        std::optional<RecognitionFiles> files;
        if (!output.empty()) {
          OutputPolicy policy;
          policy.overwrite = overwrite;
          policy.sources.push_back(catalogue);
          files.emplace(output, mesh, policy, "output", "mesh");
        } else if (!mesh.empty()) {
          throw Error("recognize: mesh is written beside output: give output too");
        }
        PointCloud cloud;
        cloud.points = array_to_points(points);
        const Catalogue cat = read_catalogue(catalogue);
        std::vector<ModelTemplate> models;
        ProgressArg p(progress);
        std::vector<Search3dRecord> searches3;
        const RecognitionResult r = p.run([&] {
          const ModelSamplingConfig& sampling =
              cfg.method == "3d" ? cfg.three_d.sampling : cfg.two_d.sampling;
          for (const auto& mo : cat.models) {
            models.push_back(make_catalogue_template(cat, mo, sampling));
          }
          RecognitionResult res = recognize(cloud, models, cfg, &searches3, p.terminal());
          if (files) files->write(res, searches3, models, "(points)", catalogue, cfg);
          return res;
        });
        py::list out;
        for (const Placement& p : r.placements) {
          out.append(py::dict(
              "model"_a = p.model, "method"_a = p.method,
              "T_world_model"_a = pose_to_array(p.T_world_model), "scale"_a = p.scale,
              "score_m"_a = p.score_m, "residual_median_m"_a = p.residual.median_m,
              "residual_mean_m"_a = p.residual.mean_m, "support"_a = p.support,
              "confidence"_a = p.confidence, "yaw_ambiguous"_a = p.yaw_ambiguous,
              "verification"_a = json_loads(verification_json_text(p.verification)),
              "step1_T_world_model"_a = pose_to_array(p.T_world_model_4d),
              "step1_residual_median_m"_a = p.residual_4d.median_m, "seconds"_a = p.seconds));
        }
        return out;
      },
      "points"_a, "catalogue"_a, "config"_a = py::none(), "method"_a = py::none(),
      "progress"_a = py::none(), "output"_a = "", "mesh"_a = "", "overwrite"_a = false,
      "Find the catalogue's CAD models (a YAML file, docs/recognition.md) in an (N, 3) world-frame "
      "cloud and place them in 6D, as `sonar3d recognize` does: config a RecognizeConfig (every "
      "setting the command has; method overrides its method). method '2d' (sec. 6.3.2): ring "
      "descriptors on the elevation map, 4D search (eq. 6.9), trimmed ICP; method '3d' (sec. "
      "6.3.1): spherical subspaces filtered by eq. 6.4-6.7, yaw sweep + trimmed ICP in each. "
      "progress: None, True (terminal bars) or a callable progress(done, total). output: a "
      "placements JSON to write as the command's -o does (what `sonar3d world` and world_model() "
      "read), with the placed models as a PLY mesh beside it (mesh: another .ply path); an "
      "existing file is replaced only with overwrite=True and only when sonar3d recognize wrote "
      "it. "
      "Returns one dict per placement: model, method, T_world_model (4×4), scale (the placed "
      "model is T_world_model · scale · model; 1 unless the catalogue gives a scale_range), "
      "score_m, residual_median_m, residual_mean_m, support, confidence, verification (2d: seen, "
      "explained, violation, unexplained, spill, score_m3), step1_T_world_model, "
      "step1_residual_median_m, seconds.");
}

}  // namespace sonar3d::python
