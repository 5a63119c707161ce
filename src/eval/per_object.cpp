#include "sonar3d/eval/per_object.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
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

MemoryEstimate estimate_evaluation_memory(const PointCloud& cloud,
                                          const std::vector<SceneObject>& objects,
                                          const EvalConfig& config,
                                          const std::string& samples_option) {
  config.validate();
  auto samples_of = [&](double area_m2) {
    return std::max(1000.0, std::ceil(area_m2 * 1e4 * config.samples_per_cm2));
  };
  double samples = 0, area = 0, mesh_bytes = 0;
  for (const auto& o : objects) {
    const double a = o.mesh_world.surface_area();
    samples += samples_of(a);
    area += a;
    mesh_bytes += static_cast<double>(o.mesh_world.triangles.size() * sizeof(Eigen::Vector3i) +
                                      o.mesh_world.vertices.size() * sizeof(Eigen::Vector3f));
  }
  samples += samples_of(area);  // the whole scene ("all")
  MemoryEstimate e;
  char what[160];
  std::snprintf(what, sizeof what, "%.3g surface samples over %.3g m² at %.3g per cm²", samples,
                area, config.samples_per_cm2);
  e.add(what, samples * sizeof(Eigen::Vector3f), samples_option);
  // Per scoring (each object, then all): the coverage index (core/point_index.hpp) holds each
  // point as a double vector, with its tree (a 4-byte index a point and the nodes, about a
  // leaf of up to 16 points each: 16 bytes a point is an upper bound); the distances are one
  // double per point.
  const double n = static_cast<double>(cloud.size());
  e.add("coverage index and distances over " + std::to_string(cloud.size()) + " points",
        n * (sizeof(Eigen::Vector3d) + 16 + 2 * sizeof(double)));
  // Distance structures, each object's then all's: Embree's copy of the vertices and triangles,
  // and its BVH, counted as large as the copy.
  e.add("mesh distance structures", 2 * 2 * mesh_bytes);
  return e;
}

std::vector<std::string> implausible_evaluation_radii(const std::vector<SceneObject>& objects,
                                                      const EvalConfig& config,
                                                      const std::string& coverage_flag,
                                                      const std::string& outlier_flag) {
  std::vector<std::string> out;
  // The smallest object's size (its bounding box's longest edge) is the scene's finest scale.
  double size = std::numeric_limits<double>::infinity();
  std::string name;
  for (const auto& o : objects) {
    if (o.mesh_world.triangles.empty()) continue;
    const double s = o.mesh_world.bounding_box().sizes().cast<double>().maxCoeff();
    if (s < size) {
      size = s;
      name = o.name;
    }
  }
  if (!std::isfinite(size) || size <= 0) return out;
  auto check = [&](double r, const std::string& flag, const char* effect) {
    if (r < 0.5 * size) return;
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "%s %.4g m is at least half the size of object '%s' (%.3g m across): %s; is it "
                  "in centimetres? (%s %.4g is %.4g cm)",
                  flag.c_str(), r, printable(name).c_str(), size, effect, flag.c_str(), r / 100, r);
    out.push_back(buf);
  };
  check(config.coverage_radius, coverage_flag,
        "any point near the object covers all of it, so coverage says nothing");
  check(config.outlier_radius, outlier_flag, "no point near the object can be an outlier");
  return out;
}

}  // namespace sonar3d
