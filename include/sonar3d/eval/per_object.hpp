#pragma once
// Per-object evaluation of a reconstruction of a multi-object scene: each point is attributed to
// the object whose surface is nearest, then every object is scored on its own points (the thesis
// scores each reference object separately, sec. 4.5.2).
#include <string>
#include <vector>

#include "sonar3d/core/memory.hpp"
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

// Memory evaluate_objects() will take (core/memory.hpp), before it allocates: the surface
// samples of every object and of the whole scene (area × config.samples_per_cm2, at least 1000
// each), the coverage grid and the distances over the cloud's points, the meshes' distance
// structures. `samples_option` names the option that sets samples_per_cm2.
MemoryEstimate estimate_evaluation_memory(const PointCloud& cloud,
                                          const std::vector<SceneObject>& objects,
                                          const EvalConfig& config,
                                          const std::string& samples_option);

// Warnings (naming the flags) for radii implausible for the scene: a coverage radius of half an
// object's size or more counts every sample of it as covered by any nearby point, and an outlier
// radius that large counts no point as an outlier; usually centimetres given as metres.
std::vector<std::string> implausible_evaluation_radii(const std::vector<SceneObject>& objects,
                                                      const EvalConfig& config,
                                                      const std::string& coverage_flag,
                                                      const std::string& outlier_flag);

}  // namespace sonar3d
