#pragma once
// Reconstruction quality against CAD ground truth (thesis sec. 4.5.2.1): unsigned median error,
// surface coverage within r_c, outliers beyond r_o, median/coverage ratio.
#include <memory>
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"

namespace sonar3d {

struct EvalConfig {
  double coverage_radius = 0.03;  // r_c, m
  double outlier_radius = 0.10;   // r_o, m
  double samples_per_cm2 =
      1.0;                      // uniform surface samples for coverage (> 0; never fewer than 1000)
  double histogram_max = 0.20;  // m, last histogram edge (larger errors go in the last bin)
  int histogram_bins = 40;
  unsigned long long seed = 1;  // surface sampling seed
  void validate() const;        // throws Error naming the field
};

// The one declaration of EvalConfig's settings (core/params.hpp): sonar3d evaluate's flags and
// its --print-config keys, the Python class sonar3d.EvalConfig.
template <class V>
void describe(EvalConfig& c, V& v) {
  using params::param;
  v.field(c.coverage_radius,
          param("coverage_radius", "m", "r_c: a surface sample is covered with a point within it")
              .positive()
              .equation("sec. 4.5.2.1")
              .flag("--coverage-radius"));
  v.field(c.outlier_radius, param("outlier_radius", "m", "r_o: a point farther is an outlier")
                                .positive()
                                .equation("sec. 4.5.2.1")
                                .flag("--outlier-radius"));
  v.field(c.samples_per_cm2,
          param("samples_per_cm2", "",
                "uniform surface samples per cm^2 for coverage (never fewer than 1000)")
              .positive()
              .flag("--samples-per-cm2"));
  v.field(c.histogram_max,
          param("histogram_max", "m", "last edge of the error histogram (larger errors: last bin)")
              .positive());
  v.field(c.histogram_bins,
          param("histogram_bins", "", "bins of the error histogram").range(1, 1e6));
  v.field(c.seed, param("seed", "", "surface sampling seed").flag("--seed"));
}

// Units: metres for errors and radii, fractions in [0, 1] for coverage and outliers. An empty
// cloud gives num_points 0, coverage 0, NaN outliers/median/mean/ratio (null in JSON).
struct EvalResult {
  std::size_t num_points = 0;
  std::size_t num_surface_samples = 0;
  double median_error = 0;  // m, unsigned
  double mean_error = 0;    // m
  double coverage = 0;      // fraction in [0, 1] of surface samples with a point within r_c
  double outliers = 0;      // fraction in [0, 1] of points farther than r_o
  // median_error in cm divided by coverage in %, i.e. cm per %, as the thesis plots it (Fig. 4.18);
  // lower is better; +inf when no surface sample is covered (null in JSON).
  double median_to_coverage = 0;
  double coverage_radius =
      0;                      // m, r_c used (copied from the config so results are self-describing)
  double outlier_radius = 0;  // m, r_o used
  std::vector<double> histogram_edges;  // m, bins+1 edges
  std::vector<std::size_t> histogram;   // counts per bin
};

// Exact unsigned distance from points to a triangle mesh (closest point on the triangles, via an
// Embree point query on a BVH), built once and queried many times; thread-safe queries.
// Throws Error on an empty mesh, an out-of-range index or a non-finite vertex. A non-finite query
// point gives NaN.
class MeshDistance {
 public:
  explicit MeshDistance(const TriangleMesh& mesh);
  ~MeshDistance();
  MeshDistance(const MeshDistance&) = delete;
  MeshDistance& operator=(const MeshDistance&) = delete;
  double distance(const Eigen::Vector3f& p) const;
  std::vector<double> distances(const std::vector<Eigen::Vector3f>& points) const;  // parallel

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Uniform random samples on the mesh surface (area-weighted triangle choice, uniform barycentric),
// `count` of them, from `seed`: same seed, same points. Throws Error if the mesh has no area.
std::vector<Eigen::Vector3f> sample_surface(const TriangleMesh& mesh, std::size_t count,
                                            unsigned long long seed);

// Evaluates `cloud` (world frame) against `truth` (world frame). Throws Error on an empty mesh.
// An empty cloud gives coverage 0 and NaN errors, outliers and ratio.
EvalResult evaluate(const PointCloud& cloud, const TriangleMesh& truth, const EvalConfig& config);

std::string to_json(const EvalResult& r, int indent = 2);
std::string to_table(const EvalResult& r, const std::string& title = "");

}  // namespace sonar3d
