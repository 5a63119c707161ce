#pragma once
// Per-object evaluation of a reconstruction of a multi-object scene: each point is attributed to
// the object whose surface is nearest, then every object is scored on its own points (the thesis
// scores each reference object separately, sec. 4.5.2).
#include <string>
#include <vector>

#include "sonar3d/core/scene.hpp"
#include "sonar3d/eval/metrics.hpp"

namespace sonar3d {

struct ObjectEval {
  std::string name;
  EvalResult result;
};

// One entry per object, then a last entry named "all" for the whole scene.
std::vector<ObjectEval> evaluate_objects(const PointCloud& cloud,
                                         const std::vector<SceneObject>& objects,
                                         const EvalConfig& config);

// The structures and pipelines of a site (terrain is not scored), each on the points near it —
// within its bounding box grown by `margin_m` — after every such point has been attributed to the
// nearest object, so the seabed a structure stands on is not counted as its outliers. One entry
// per scored object, in scene order. Throws Error on a negative margin.
std::vector<ObjectEval> evaluate_structures(const PointCloud& cloud,
                                            const std::vector<SceneObject>& objects,
                                            const EvalConfig& config, double margin_m = 0.5);

}  // namespace sonar3d
