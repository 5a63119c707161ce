#include "sonar3d/eval/per_object.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
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

std::vector<ObjectEval> evaluate_structures(const PointCloud& cloud,
                                            const std::vector<SceneObject>& objects,
                                            const EvalConfig& config, double margin_m) {
  require(std::isfinite(margin_m) && margin_m >= 0, "evaluation: the margin must be >= 0 m");
  std::vector<std::unique_ptr<MeshDistance>> dist;
  for (const auto& o : objects) dist.push_back(std::make_unique<MeshDistance>(o.mesh_world));
  std::vector<ObjectEval> out;
  for (std::size_t k = 0; k < objects.size(); ++k) {
    if (objects[k].kind == ObjectKind::Terrain) continue;
    Eigen::AlignedBox3f box;
    for (const Eigen::Vector3f& v : objects[k].mesh_world.vertices) box.extend(v);
    box.min().array() -= static_cast<float>(margin_m);
    box.max().array() += static_cast<float>(margin_m);
    std::vector<std::size_t> near;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (box.contains(cloud.points[i])) near.push_back(i);
    }
    std::vector<char> mine(near.size(), 0);
    tbb::parallel_for(std::size_t(0), near.size(), [&](std::size_t j) {
      const Eigen::Vector3f& p = cloud.points[near[j]];
      const double own = dist[k]->distance(p);
      bool nearest = true;
      for (std::size_t m = 0; m < dist.size() && nearest; ++m) {
        if (m != k && dist[m]->distance(p) < own) nearest = false;
      }
      mine[j] = nearest;
    });
    PointCloud sub;
    for (std::size_t j = 0; j < near.size(); ++j) {
      if (mine[j]) sub.points.push_back(cloud.points[near[j]]);
    }
    out.push_back({objects[k].name, evaluate(sub, objects[k].mesh_world, config)});
  }
  return out;
}

}  // namespace sonar3d
