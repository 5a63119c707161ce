#pragma once
// Shared by the 2D and 3D recognition methods (docs/recognition.md): the placements file, the
// yaw range of a symmetry, the tilt of a placement, the inputs' checks, the models' order.
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/recog/recognition.hpp"

namespace sonar3d {

namespace recog_internal {
using sonar3d::kDeg;
using Clock = std::chrono::steady_clock;
inline double since(Clock::time_point t) { return seconds_since(t); }
}  // namespace recog_internal

// Roll, pitch, yaw in degrees with R = Rz(yaw)·Ry(pitch)·Rx(roll), as scene files give poses.
nlohmann::json rpy_deg_json(const Eigen::Isometry3d& T);

// One object per placement: model, method, T_world_model (4×4, row-major), translation, rpy_deg,
// score, residuals, support, step-1 values and times.
nlohmann::json placements_list_json(const std::vector<Placement>& placements);

// Yaws searched for a symmetry (sec. 6.3.2.5): 0, step, 2·step, ... below 360° (none), 180°
// ("180"), or 0 alone (full).
std::vector<double> yaw_range(Symmetry s, double step_rad);

// Angle between the model's z axis and the world's, degrees.
double tilt_deg(const Eigen::Isometry3d& T);

// Errors for an empty catalogue or cloud; the thread limit (0: all cores; hold the result while
// working).
std::unique_ptr<tbb::global_control> check_recognition_inputs(
    const PointCloud& scene, const std::vector<ModelTemplate>& models, int num_threads);

// Thesis sec. 6.7 (sizes off by ±10 %): the scale of a model with a scale_range searched about
// its placement p found at scale 1 (search_scale), and p updated: scale, pose, residual on
// `local` (the structure's points), verification on `fine` (recog/scale.hpp).
void refine_placement_scale(const ModelTemplate& m, Placement& p, const ElevationMap& fine,
                            const std::vector<uint8_t>& removed_fine,
                            const std::vector<Eigen::Vector3f>& local,
                            const RecognitionConfig& config);

// Sec. 6.3.2.6: the models in decreasing horizontal size (r_model), ties in catalogue order.
std::vector<const ModelTemplate*> by_decreasing_size(const std::vector<ModelTemplate>& models);

}  // namespace sonar3d
