#pragma once
// Readers of the JSON files `sonar3d report` shows in 3D (formats: docs/formats.md, "World model
// directory" and "Change directory"; placements.json is read by read_placements in
// world/world_model.hpp). Each parser takes the
// file's text and the path to name in errors; every error is one line naming the file and the
// key or entry at fault. Fuzzed: fuzz/fuzz_report_scene.cpp.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace sonar3d {

// graph.json of `sonar3d world` ("format": "sonar3d-world", version 1).
struct WorldGraphObject {
  std::string id, model, kind, file;  // file: relative to the world directory
  Eigen::Matrix4d T_world_model = Eigen::Matrix4d::Identity();
  double score_m = 0, residual_median_m = 0;  // NaN when null
  double confidence = 0;                      // NaN when null or absent (unknown)
  bool confirmed = true;  // at or above the world's min_confidence (absent: true, older files)
};
struct WorldConnection {
  std::string from, to, kind;
  double length_m = 0;
  bool found = true, given = false;  // found in the map (sonar3d world) / given by the user
};
struct WorldSeabedLod {
  int lod = 0;
  std::string file;
  double cell_m = 0;
  long long triangles = 0, bytes = 0;
  double median_error_m = 0;  // NaN when null (no true terrain)
};
struct WorldGraph {
  std::vector<WorldGraphObject> objects;
  std::vector<WorldConnection> connections;  // from/to are ids of objects (checked)
  std::vector<WorldSeabedLod> seabed;        // sorted by lod
  double min_confidence = 0;                 // NaN when absent (files before it was written)
  std::string source_map, source_placements, source_catalogue;
  long long bytes_total = 0, cloud_bytes = 0;
};
WorldGraph parse_world_graph(const std::string& text, const std::string& path);

// changes.json of `sonar3d diff A B` ("format": "sonar3d-changes", version 1).
struct ChangedObject {
  // unchanged | moved | added | removed | uncertain. Files of diffs before "uncertain" existed
  // wrote a one-survey recognition that the heights did not confirm as "unchanged" with one pose
  // null: it is read as "uncertain" (what it was).
  std::string id, model, status;
  std::string reason;       // why an object is uncertain (empty otherwise or when absent)
  std::string other_model;  // the other survey's model over it, when another (empty: none)
  bool has_a = false, has_b = false;
  Eigen::Matrix4d T_world_model_a = Eigen::Matrix4d::Identity();       // survey A, A's frame
  Eigen::Matrix4d T_world_model_b_in_a = Eigen::Matrix4d::Identity();  // survey B, A's frame
  double shift_m = 0, turn_deg = 0;                                    // NaN when null
  double change_area_m2 = 0;  // height change within its footprint(s); NaN when null or absent
};
struct ChangedRegion {
  long long id = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double area_m2 = 0, max_abs_change_m = 0, mean_change_m = 0;
  std::string kind;  // raised | lowered
};
struct ChangedColourRegion {  // changes.json "colour" "regions" (sonar3d diff --colour-a/-b)
  long long id = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double area_m2 = 0, max_delta = 0, mean_delta = 0;
  double height_change_fraction = 0;                        // NaN when absent
  std::array<int, 3> colour_a{0, 0, 0}, colour_b{0, 0, 0};  // 8-bit sRGB before / after
};
struct ChangeSet {
  Eigen::Matrix4d T_a_b = Eigen::Matrix4d::Identity();
  std::string registration_method;
  double registration_rms_m = 0;
  long long overlap_cells = 0;
  std::vector<ChangedObject> objects;
  std::vector<ChangedRegion> regions;
  std::string colour_space;  // empty: no colour compared ("colour" null or absent)
  std::vector<ChangedColourRegion> colour_regions;
};
ChangeSet parse_changes_json(const std::string& text, const std::string& path);

}  // namespace sonar3d
