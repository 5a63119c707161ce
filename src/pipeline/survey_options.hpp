#pragma once
// Each survey option declared once: its YAML key (the command's flag without the dashes, '-'
// written '_'). The YAML reader, the printed configuration and the stage stamps all visit these
// lists, so the names cannot drift apart. `v.path(...)` marks a file path (relative paths in a
// configuration file are taken from the file's directory).
#include <string>

#include "sonar3d/pipeline/survey_pipeline.hpp"

namespace sonar3d {

template <class V>
void visit(SurveyImportOptions& o, V& v) {
  v("kind", o.kind);
  v.path("nav", o.nav);
  v("nav_format", o.nav_format);
  v("nav_convention", o.nav_convention);
  v("angles", o.angles);
  v("mount", o.mount);
  v("vertical_aperture_deg", o.vertical_aperture_deg);
  v("time_offset", o.time_offset);
  v("drop_outside", o.drop_outside);
  v("static", o.static_sonar);
  v("nav_source", o.nav_source);
  v("clock", o.clock);
  v("drop_partial", o.drop_partial);
  v("sonar_topic", o.sonar_topic);
  v("nav_topic", o.nav_topic);
  v("tf_topic", o.tf_topic);
  v("base_frame", o.base_frame);
  v.path("sonar", o.sonar);
  v("rate", o.rate);
  v("gains", o.gains);
  v("mirror", o.mirror);
  v("bins", o.bins);
  v("sensor", o.sensor);
  v("image_key", o.image_key);
  v("pose_key", o.pose_key);
  v("python", o.python);
}

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
std::string stage_settings(const SurveyConfig& config, const std::string& stage);
}  // namespace survey_detail

}  // namespace sonar3d
