#include "sonar3d/eval/per_object.hpp"

#include <tbb/parallel_for.h>

#include <limits>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

std::vector<ObjectEval> evaluate_objects(const PointCloud& cloud,
                                         const std::vector<SceneObject>& objects,
                                         const EvalConfig& config) {
  if (objects.empty()) throw Error("evaluation: the ground truth has no object");
  std::vector<std::unique_ptr<MeshDistance>> dist;
  for (const auto& o : objects) dist.push_back(std::make_unique<MeshDistance>(o.mesh_world));
  std::vector<int> owner(cloud.size(), 0);
  tbb::parallel_for(std::size_t(0), cloud.size(), [&](std::size_t i) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < dist.size(); ++k) {
      const double d = dist[k]->distance(cloud.points[i]);
      if (d < best) {
        best = d;
        owner[i] = static_cast<int>(k);
      }
    }
  });
  std::vector<ObjectEval> out;
  TriangleMesh all;
  for (std::size_t k = 0; k < objects.size(); ++k) {
    PointCloud sub;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (owner[i] != static_cast<int>(k)) continue;
      sub.points.push_back(cloud.points[i]);
      if (cloud.has_intensity()) sub.intensity.push_back(cloud.intensity[i]);
    }
    out.push_back({objects[k].name, evaluate(sub, objects[k].mesh_world, config)});
    all.append(objects[k].mesh_world);
  }
  out.push_back({"all", evaluate(cloud, all, config)});
  return out;
}

}  // namespace sonar3d
