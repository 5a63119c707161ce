#pragma once
// The survey's configuration as the stage stamps hold it (survey_config.cpp).
#include <string>

#include "sonar3d/pipeline/survey_pipeline.hpp"

namespace sonar3d {

namespace survey_detail {
// The stage's options as YAML lines (its part of the printed configuration and of its stamp).
// For import with `kind` given: the kind and that kind's block only (what the import uses).
std::string stage_settings(const SurveyConfig& config, const std::string& stage,
                           const std::string& kind = "");
}  // namespace survey_detail

}  // namespace sonar3d
