// CAD-model recognition (thesis sec. 6.3, docs/recognition.md): the 2D (sec. 6.3.2) or 3D
// (sec. 6.3.1) method on a cloud.
#include "common.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognition_3d.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;

void bind_recog(py::module_& m) {
  m.def(
      "recognize",
      [](const carray<float>& points, const std::string& catalogue, bool icp, double period_m,
         double map_cell_m, double recog_cell_m, double min_confidence, int num_threads,
         const std::string& method, bool upright) {
        require(method == "2d" || method == "3d",
                "recognize: method must be '2d' or '3d', not '" + method + "'");
        PointCloud cloud;
        cloud.points = array_to_points(points);
        RecognitionConfig cfg;
        cfg.run_icp = icp;
        cfg.scan.period_m = period_m;
        cfg.map_cell_m = map_cell_m;
        cfg.recog_cell_m = recog_cell_m;
        cfg.verification.min_confidence = min_confidence;
        cfg.num_threads = num_threads;
        cfg.scan.num_threads = num_threads;
        cfg.validate();
        Recognition3dConfig cfg3;
        cfg3.upright = upright;
        cfg3.num_threads = num_threads;
        cfg3.validate();
        const Catalogue cat = read_catalogue(catalogue);
        std::vector<ModelTemplate> models;
        RecognitionResult r;
        {
          py::gil_scoped_release release;
          for (const auto& mo : cat.models) {
            models.push_back(make_catalogue_template(cat, mo, cfg.sampling));
          }
          r = method == "3d" ? recognize_3d(cloud, models, cfg3)
                             : recognize_2d(cloud, models, cfg, false);
        }
        py::list out;
        for (const Placement& p : r.placements) {
          out.append(py::dict(
              "model"_a = p.model, "method"_a = p.method,
              "T_world_model"_a = pose_to_array(p.T_world_model), "scale"_a = p.scale,
              "score_m"_a = p.score_m, "residual_median_m"_a = p.residual.median_m,
              "residual_mean_m"_a = p.residual.mean_m, "support"_a = p.support,
              "confidence"_a = p.confidence, "yaw_ambiguous"_a = p.yaw_ambiguous,
              "verification"_a = py::dict(
                  "valid"_a = p.verification.valid, "seen"_a = p.verification.seen,
                  "explained"_a = p.verification.explained,
                  "violation"_a = p.verification.violation,
                  "unexplained"_a = p.verification.unexplained, "spill"_a = p.verification.spill,
                  "score_m3"_a = p.verification.score_m3),
              "step1_T_world_model"_a = pose_to_array(p.T_world_model_4d),
              "step1_residual_median_m"_a = p.residual_4d.median_m, "seconds"_a = p.seconds));
        }
        return out;
      },
      "points"_a, "catalogue"_a, "icp"_a = true, "period_m"_a = 0.16, "map_cell_m"_a = 0.02,
      "recog_cell_m"_a = 0.08, "min_confidence"_a = VerificationConfig{}.min_confidence,
      "num_threads"_a = 0, "method"_a = "2d", "upright"_a = true,
      "Find the catalogue's CAD models (a YAML file, docs/recognition.md) in an (N, 3) world-frame "
      "cloud and place them in 6D. method '2d' (sec. 6.3.2): ring descriptors on the elevation "
      "map, 4D search (eq. 6.9), trimmed ICP (icp, period_m, map_cell_m, recog_cell_m, "
      "min_confidence apply); method '3d' (sec. 6.3.1): spherical subspaces filtered by eq. "
      "6.4-6.7, yaw sweep + trimmed ICP in each, or a global registration with upright=False. "
      "Returns one dict per placement: model, method, T_world_model (4×4), scale (the placed "
      "model is T_world_model · scale · model; 1 unless the catalogue gives a scale_range), "
      "score_m, "
      "residual_median_m, residual_mean_m, support, confidence, verification (2d: seen, explained, "
      "violation, unexplained, score_m3), step1_T_world_model, step1_residual_median_m, "
      "seconds.");
}

}  // namespace sonar3d::python
