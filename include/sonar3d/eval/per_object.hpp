#pragma once
// Per-object evaluation of a reconstruction of a multi-object scene: each point is attributed to
// the object whose surface is nearest, then every object is scored on its own points (the thesis
// scores each reference object separately, sec. 4.5.2).
#include <string>
#include <vector>

#include "sonar3d/eval/metrics.hpp"
#include "sonar3d/sim/scene.hpp"

namespace sonar3d {

struct ObjectEval {
  std::string name;
  EvalResult result;
};

// One entry per object, then a last entry named "all" for the whole scene.
std::vector<ObjectEval> evaluate_objects(const PointCloud& cloud,
                                         const std::vector<SceneObject>& objects,
                                         const EvalConfig& config);

}  // namespace sonar3d
