#pragma once
// The ground truth a simulated dataset carries (truth/ of the dataset directory, docs/formats.md):
// read here, below every module that scores against it (eval, mapping, world); written by
// sim/simulation.hpp.
#include <filesystem>
#include <vector>

#include "sonar3d/core/scene.hpp"

namespace sonar3d {

// Ground truth of a simulated dataset: the objects in truth/scene.yaml, world frame.
std::vector<SceneObject> read_truth(const std::filesystem::path& dataset_dir);

}  // namespace sonar3d
