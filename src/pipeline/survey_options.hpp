#pragma once
// The survey options whose commands' configurations are not declared with core/params.hpp yet
// (texture, report), each declared once here: its YAML key (the command's flag without the
// dashes, '-' written '_'). The import, map, recognize and world stages use their commands' own
// declarations (survey_pipeline.hpp). The YAML reader, the printed configuration and the stage
// stamps all visit these lists, so the names cannot drift apart. `v.path(...)` marks a file path
// (relative paths in a configuration file are taken from the file's directory).
#include <string>

#include "sonar3d/pipeline/survey_pipeline.hpp"

namespace sonar3d {

template <class V>
void visit(SurveyTextureOptions& o, V& v) {
  v("point_spacing", o.point_spacing);
  v("depth_tolerance", o.depth_tolerance);
  v("max_range", o.max_range);
  v("drop_uncoloured", o.drop_uncoloured);
}

template <class V>
void visit(SurveyReportOptions& o, V& v) {
  v("max_points", o.max_points);
  v("max_total_points", o.max_total_points);
  v("max_mesh_triangles", o.max_mesh_triangles);
  v("color", o.color);
  v("error_max", o.error_max);
  v("title", o.title);
  v.path("web_dir", o.web_dir);
  v("seed", o.seed);
}

namespace survey_detail {
// The stage's options as YAML lines (its part of the printed configuration and of its stamp).
// For import with `kind` given: the kind and that kind's block only (what the import uses).
std::string stage_settings(const SurveyConfig& config, const std::string& stage,
                           const std::string& kind = "");
}  // namespace survey_detail

}  // namespace sonar3d
