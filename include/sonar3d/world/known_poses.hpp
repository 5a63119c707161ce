#pragma once
// Known structure poses for the map's adjustment (issue 26 item 3, mapping/survey.hpp
// MapSurveyConfig::known_poses): the structures of a previous survey's world model, or a
// placements file (a previous recognition, or poses written from as-built drawings).
#include <string>
#include <vector>

#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/world/world_model.hpp"

namespace sonar3d {

// A world model directory (graph.json of format sonar3d-world: its confirmed objects) or a
// placements JSON (format sonar3d-placements). Errors name the path and say what is expected.
std::vector<KnownStructurePose> read_known_poses(const std::string& path);

// The navigation of the map a placements file was recognised in: `given` when not empty, else
// the navigation_corrected.tum of the map directory the file names (its "map": the directory or
// a file in it; relative to the working directory or to the placements file). An Error naming
// the file when there is none.
std::string placements_navigation(const PlacementsFile& f, const std::string& given);

// Fills `config`'s known structure poses (read_known_poses(known_poses)), the structures
// recognised in this survey's map (`placements`) and that map's navigation
// (placements_navigation(…, placements_nav)), each source recorded: `sonar3d map --known-poses`
// and Python's map_survey(known_poses=…) both.
void load_known_pose_inputs(MapSurveyConfig& config, const std::string& known_poses,
                            const std::string& placements, const std::string& placements_nav);

}  // namespace sonar3d
