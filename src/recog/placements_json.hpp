#pragma once
// Shared by the placements files of the 2D and 3D methods (docs/recognition.md).
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <vector>

#include "sonar3d/recog/recognition.hpp"

namespace sonar3d {

// Roll, pitch, yaw in degrees with R = Rz(yaw)·Ry(pitch)·Rx(roll), as scene files give poses.
nlohmann::json rpy_deg_json(const Eigen::Isometry3d& T);

// One object per placement: model, method, T_world_model (4×4, row-major), translation, rpy_deg,
// score, residuals, support, step-1 values and times.
nlohmann::json placements_list_json(const std::vector<Placement>& placements);

}  // namespace sonar3d
