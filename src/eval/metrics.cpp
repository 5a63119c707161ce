// Reconstruction metrics of thesis sec. 4.5.2.1: unsigned median error (a), surface coverage
// within r_c (b), proportion of outliers beyond r_o (c) and the median-error-to-coverage ratio (d).
#include "sonar3d/eval/metrics.hpp"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <utility>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_index.hpp"

namespace sonar3d {
namespace {

using Eigen::Vector3d;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Uniform double in [0, 1) from the top 53 bits: unlike std::uniform_real_distribution, whose
// algorithm is left to the standard library, this gives the same samples on every platform.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// Median of the values (average of the two middle ones for an even count); reorders `v`.
double median_of(std::vector<double>& v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  if (v.size() % 2 == 1) return v[mid];
  return 0.5 * (v[mid] + *std::max_element(v.begin(), v.begin() + mid));
}

}  // namespace

void EvalConfig::validate() const {
  params::check(*this, "evaluate");
  require_positive(coverage_radius, "coverage_radius", "m");
  require_positive(outlier_radius, "outlier_radius", "m");
  require_positive(samples_per_cm2, "samples_per_cm2", "per cm^2");
  require_positive(histogram_max, "histogram_max", "m");
  if (histogram_bins < 1 || histogram_bins > 1000000) {
    throw Error(
        fmt::format("parameter 'histogram_bins' must be in [1, 1000000], got {}", histogram_bins));
  }
}

std::vector<Eigen::Vector3f> sample_surface(const TriangleMesh& mesh, std::size_t count,
                                            unsigned long long seed) {
  require(!mesh.empty(), "cannot sample the surface of an empty mesh (no triangles)");
  // Cumulative areas: a uniform draw in [0, total) located by binary search picks a triangle
  // with probability proportional to its area.
  std::vector<double> cumulative(mesh.triangles.size());
  double total = 0.0;
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    const Vector3d a = mesh.vertices.at(t[0]).cast<double>();
    const Vector3d b = mesh.vertices.at(t[1]).cast<double>();
    const Vector3d c = mesh.vertices.at(t[2]).cast<double>();
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative[i] = total;
  }
  if (!(total > 0.0) || !std::isfinite(total)) {
    throw Error(fmt::format("cannot sample a mesh of surface area {} m^2 ({} triangles)", total,
                            mesh.triangles.size()));
  }
  std::mt19937_64 rng(seed);
  std::vector<Eigen::Vector3f> samples;
  samples.reserve(count);
  for (std::size_t n = 0; n < count; ++n) {
    const double u = uniform01(rng) * total;
    const std::size_t i = std::min<std::size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin(),
        cumulative.size() - 1);
    const Eigen::Vector3i& t = mesh.triangles[i];
    // sqrt trick (Osada et al. 2002): barycentrics (1 - √r1, √r1 (1 - r2), √r1 r2) are uniform
    // over the triangle, where (r1, r2) uniform would crowd samples toward vertex a.
    const double s = std::sqrt(uniform01(rng));
    const double r2 = uniform01(rng);
    const Vector3d p = (1.0 - s) * mesh.vertices[t[0]].cast<double>() +
                       s * (1.0 - r2) * mesh.vertices[t[1]].cast<double>() +
                       s * r2 * mesh.vertices[t[2]].cast<double>();
    samples.push_back(p.cast<float>());
  }
  return samples;
}

EvalResult evaluate(const PointCloud& cloud, const TriangleMesh& truth, const EvalConfig& config) {
  config.validate();
  require(!truth.empty(), "cannot evaluate against an empty ground-truth mesh (no triangles)");
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (!cloud.points[i].allFinite()) {
      throw Error(
          fmt::format("point cloud point {} is not finite ({}, {}, {}); remove it before "
                      "evaluating",
                      i, cloud.points[i].x(), cloud.points[i].y(), cloud.points[i].z()));
    }
  }
  EvalResult r;
  r.num_points = cloud.size();
  r.coverage_radius = config.coverage_radius;
  r.outlier_radius = config.outlier_radius;
  const auto bins = static_cast<std::size_t>(config.histogram_bins);
  const double bin_width = config.histogram_max / static_cast<double>(bins);
  r.histogram.assign(bins, 0);
  r.histogram_edges.resize(bins + 1);
  for (std::size_t b = 0; b < bins; ++b) r.histogram_edges[b] = static_cast<double>(b) * bin_width;
  r.histogram_edges[bins] = config.histogram_max;

  MeshDistance mesh_distance(truth);  // validates the mesh before any sampling

  // Coverage needs enough samples to resolve r_c; the count follows the surface area so that
  // coverages of different objects are comparable.
  const double area_cm2 = truth.surface_area() * 1e4;
  const auto count =
      static_cast<std::size_t>(std::max(1000.0, std::ceil(area_cm2 * config.samples_per_cm2)));
  r.num_surface_samples = count;

  if (cloud.empty()) {
    // Nothing to measure: no error, and no share of outliers among zero points (reporting 0 %
    // would rank an empty reconstruction as outlier-free).
    r.median_error = r.mean_error = r.median_to_coverage = r.outliers = kNaN;
    return r;
  }

  // (a) and (c): unsigned point-to-model distances.
  std::vector<double> errors = mesh_distance.distances(cloud.points);
  std::size_t outliers = 0;
  double sum = 0.0;
  for (const double e : errors) {
    sum += e;
    if (e > config.outlier_radius) ++outliers;
    // Clamp in double: a far outlier's e / bin_width may not fit in a size_t.
    ++r.histogram[static_cast<std::size_t>(std::min(static_cast<double>(bins - 1), e / bin_width))];
  }
  r.mean_error = sum / static_cast<double>(errors.size());
  r.outliers = static_cast<double>(outliers) / static_cast<double>(errors.size());
  r.median_error = median_of(errors);

  // (b): fraction of uniform surface samples with a reconstructed point within r_c.
  const std::vector<Eigen::Vector3f> samples = sample_surface(truth, count, config.seed);
  Eigen::AlignedBox3d domain = truth.bounding_box().cast<double>();
  domain.min().array() -= config.coverage_radius;
  domain.max().array() += config.coverage_radius;
  // Only points inside the domain can answer a query from the mesh surface (and far outliers
  // need not be indexed).
  std::vector<Vector3d> near_model;
  near_model.reserve(cloud.size());
  for (const Eigen::Vector3f& p : cloud.points) {
    if (domain.contains(p.cast<double>())) near_model.push_back(p.cast<double>());
  }
  const PointIndex3d index(std::move(near_model));
  const std::size_t covered = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, samples.size()), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& range, std::size_t n) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          if (index.any_within(samples[i].cast<double>(), config.coverage_radius)) ++n;
        }
        return n;
      },
      std::plus<>());
  r.coverage = static_cast<double>(covered) / static_cast<double>(count);

  // (d): median error in cm over coverage in %, the units of thesis Fig. 4.18.
  r.median_to_coverage = covered == 0 ? std::numeric_limits<double>::infinity()
                                      : (r.median_error * 100.0) / (r.coverage * 100.0);
  return r;
}

std::string to_json(const EvalResult& r, int indent) {
  // JSON has no NaN or infinity: undefined metrics are written as null.
  const auto number = [](double v) -> nlohmann::ordered_json {
    if (std::isfinite(v)) return v;
    return nullptr;
  };
  nlohmann::ordered_json j;
  j["num_points"] = r.num_points;
  j["num_surface_samples"] = r.num_surface_samples;
  j["median_error_m"] = number(r.median_error);
  j["mean_error_m"] = number(r.mean_error);
  j["coverage"] = number(r.coverage);
  j["outliers"] = number(r.outliers);
  j["median_to_coverage_cm_per_pct"] = number(r.median_to_coverage);
  j["coverage_radius_m"] = number(r.coverage_radius);
  j["outlier_radius_m"] = number(r.outlier_radius);
  j["histogram"]["edges_m"] = r.histogram_edges;
  j["histogram"]["counts"] = r.histogram;
  return j.dump(indent);
}

std::string to_table(const EvalResult& r, const std::string& title) {
  const auto value = [](double v, double scale, const char* unit, int decimals = 2) {
    if (std::isnan(v)) return std::string("n/a");
    return fmt::format("{:.{}f} {}", v * scale, decimals, unit);
  };
  std::string out;
  if (!title.empty()) out += title + "\n";
  const auto row = [&out](const std::string& name, const std::string& v, const std::string& note) {
    out += fmt::format("  {:<24}{:>16}{}\n", name, v, note.empty() ? "" : "   " + note);
  };
  row("points", std::to_string(r.num_points), "");
  row("surface samples", std::to_string(r.num_surface_samples), "");
  row("median error", value(r.median_error, 100.0, "cm"), "");
  row("mean error", value(r.mean_error, 100.0, "cm"), "");
  row("coverage", value(r.coverage, 100.0, "%"),
      fmt::format("(r_c = {:.1f} cm)", r.coverage_radius * 100.0));
  row("outliers", value(r.outliers, 100.0, "%"),
      fmt::format("(r_o = {:.1f} cm)", r.outlier_radius * 100.0));
  row("median / coverage", value(r.median_to_coverage, 1.0, "cm/%", 4), "");
  return out;
}

}  // namespace sonar3d
