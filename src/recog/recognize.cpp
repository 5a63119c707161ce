#include "sonar3d/recog/recognize.hpp"

#include "sonar3d/core/error.hpp"

namespace sonar3d {

Recognition3dConfig RecognizeConfig::effective_3d() const {
  Recognition3dConfig c = three_d;
  c.verification = two_d.verification;  // one --min-confidence for both methods
  c.num_threads = two_d.num_threads;
  return c;
}

void RecognizeConfig::validate() const {
  require(method == "2d" || method == "3d",
          "recognize: method (--method) must be '2d' or '3d', not '" + printable(method) + "'");
  if (method == "3d") {
    effective_3d().validate();
  } else {
    two_d.validate();
  }
}

RecognitionResult recognize(const PointCloud& scene_world, const std::vector<ModelTemplate>& models,
                            const RecognizeConfig& config, std::vector<Search3dRecord>* searches3,
                            bool progress) {
  config.validate();
  if (config.method == "3d") {
    return recognize_3d(scene_world, models, config.effective_3d(), searches3, progress);
  }
  RecognitionConfig c = config.two_d;
  c.scan.num_threads = c.num_threads;
  return recognize_2d(scene_world, models, c, progress);
}

std::string recognize_json(const RecognitionResult& result,
                           const std::vector<Search3dRecord>& searches3,
                           const std::string& map_source, const std::string& catalogue_source,
                           const RecognizeConfig& config) {
  if (config.method == "3d") {
    return placements_json_3d(result, searches3, map_source, catalogue_source,
                              config.effective_3d());
  }
  return placements_json(result, map_source, catalogue_source, config.two_d);
}

}  // namespace sonar3d
