// Catalogue models prepared for recognition: 1 cm surface samples, r_model, top-view elevation
// maps (thesis sec. 6.3.1.1, 6.3.2.3).
#include "sonar3d/recog/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

void ModelSamplingConfig::validate() const { params::check(*this, "model sampling"); }

ModelTemplate make_model_template(const std::string& name, const TriangleMesh& mesh,
                                  Symmetry symmetry, int expected,
                                  const ModelSamplingConfig& config) {
  config.validate();
  require(!mesh.empty(), "model '" + name + "': the mesh has no triangles");
  ModelTemplate m;
  m.name = name;
  m.symmetry = symmetry;
  m.expected = expected;
  m.mesh = mesh;
  const Eigen::AlignedBox3f box = mesh.bounding_box();
  require(box.min().allFinite() && box.max().allFinite(),
          "model '" + name + "': the mesh has non-finite vertices");
  m.center_xy = box.center().head<2>().cast<double>();
  m.base_z = box.min().z();
  m.top_z = box.max().z();
  for (const auto& v : mesh.vertices) {
    m.radius_m = std::max(m.radius_m, (v.head<2>().cast<double>() - m.center_xy).norm());
  }
  require(m.radius_m > 0, "model '" + name + "': the mesh has no horizontal extent");

  // Area-proportional samples: ~one per spacing² of surface, at least one per triangle corner
  // region for small triangles (their centroid), each with its triangle's normal.
  const double area = mesh.surface_area();
  const double wanted = area / (config.spacing_m * config.spacing_m);
  limits::checked_count(
      wanted, 0, static_cast<double>(config.max_samples),
      "model '" + name + "': surface samples at " + std::to_string(config.spacing_m) + " m",
      "the mesh is too large for this spacing (is its unit metres?)");
  std::mt19937_64 rng(config.seed);
  std::uniform_real_distribution<double> u(0, 1);
  const double per_area = 1.0 / (config.spacing_m * config.spacing_m);
  m.points.reserve(static_cast<std::size_t>(wanted) + mesh.triangles.size());
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>(),
                          b = mesh.vertices[t[1]].cast<double>(),
                          c = mesh.vertices[t[2]].cast<double>();
    const Eigen::Vector3d cr = (b - a).cross(c - a);
    const double tri_area = 0.5 * cr.norm();
    if (!(tri_area > 0)) continue;
    const Eigen::Vector3f n = (cr / (2 * tri_area)).cast<float>();
    // Expected count area·density: its integer part, plus one with the fractional probability.
    const double expect = tri_area * per_area;
    std::size_t k = static_cast<std::size_t>(expect);
    if (u(rng) < expect - static_cast<double>(k)) ++k;
    for (std::size_t s = 0; s < k; ++s) {
      double r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
      m.points.push_back((a + r1 * (b - a) + r2 * (c - a)).cast<float>());
      m.normals.push_back(n);
    }
  }
  require(!m.points.empty(), "model '" + name + "': the mesh has no surface area");
  return m;
}

ModelTemplate make_catalogue_template(const Catalogue& catalogue, const CatalogueModel& model,
                                      const ModelSamplingConfig& config) {
  ModelTemplate m = make_model_template(model.name, load_catalogue_mesh(catalogue, model),
                                        model.symmetry, model.expected, config);
  m.scale_min = model.scale_min;
  m.scale_max = model.scale_max;
  return m;
}

Eigen::Isometry3d top_view_pose(const ModelTemplate& m, double yaw_rad,
                                const Eigen::Vector2d& center_world_xy, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translate(Eigen::Vector3d(center_world_xy.x() + t.x(), center_world_xy.y() + t.y(), t.z()));
  T.rotate(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  T.translate(Eigen::Vector3d(-m.center_xy.x(), -m.center_xy.y(), 0));
  return T;
}

ElevationMap render_top_view(const ModelTemplate& m, double yaw_rad,
                             const Eigen::Vector2d& center_world_xy, const TopViewConfig& config,
                             std::vector<uint8_t>* footprint) {
  return render_placed_top_view(m, top_view_pose(m, yaw_rad, center_world_xy), center_world_xy,
                                config, footprint);
}

ElevationMap render_placed_top_view(const ModelTemplate& m, const Eigen::Isometry3d& T,
                                    const Eigen::Vector2d& center_world_xy,
                                    const TopViewConfig& config, std::vector<uint8_t>* footprint) {
  require_positive(config.cell_m, "top view cell_m", "m");
  require_non_negative(config.background_radius_m, "top view background_radius_m", "m");
  require_non_negative(config.background_ring_m, "top view background_ring_m", "m");
  const double c = config.cell_m;
  const double R = std::max(m.radius_m, config.background_radius_m) + c;
  limits::checked_count(2 * R / c, 1, 20000, "top view of model '" + m.name + "': cells across",
                        "use a coarser cell size");
  // Corners on the anchor's grid.
  const Eigen::Vector2d& a = config.grid_anchor_xy;
  const double x0 = a.x() + std::floor((center_world_xy.x() - R - a.x()) / c) * c;
  const double x1 = a.x() + std::ceil((center_world_xy.x() + R - a.x()) / c) * c;
  const double y1 = a.y() + std::ceil((center_world_xy.y() + R - a.y()) / c) * c;
  const double y0 = a.y() + std::floor((center_world_xy.y() - R - a.y()) / c) * c;
  ElevationMap map;
  map.cell_m = c;
  map.origin_xy = {x0, y1};
  map.cols = static_cast<int>(std::lround((x1 - x0) / c));
  map.rows = static_cast<int>(std::lround((y1 - y0) / c));
  map.z.assign(static_cast<std::size_t>(map.rows) * map.cols, ElevationMap::kNoData);
  auto put = [&](int r, int col, float z) {
    if (r < 0 || col < 0 || r >= map.rows || col >= map.cols) return;
    float& o = map.at(r, col);
    if (!(o >= z)) o = z;
  };
  // Triangles rasterised at cell centres (the top surface a sonar sees from above).
  std::vector<Eigen::Vector3d> v(m.mesh.vertices.size());
  double placed_base = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < v.size(); ++i) {
    v[i] = T * m.mesh.vertices[i].cast<double>();
    placed_base = std::min(placed_base, v[i].z());
  }
  for (const auto& t : m.mesh.triangles) {
    const Eigen::Vector3d &p0 = v[t[0]], &p1 = v[t[1]], &p2 = v[t[2]];
    const double det =
        (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (p1.y() - p0.y());
    if (std::abs(det) < 1e-12) continue;  // vertical: no top area
    const double xmin = std::min({p0.x(), p1.x(), p2.x()}),
                 xmax = std::max({p0.x(), p1.x(), p2.x()});
    const double ymin = std::min({p0.y(), p1.y(), p2.y()}),
                 ymax = std::max({p0.y(), p1.y(), p2.y()});
    const int c0 = std::max(0, static_cast<int>(std::floor((xmin - x0) / c - 0.5)));
    const int c1 = std::min(map.cols - 1, static_cast<int>(std::ceil((xmax - x0) / c - 0.5)));
    const int r0 = std::max(0, static_cast<int>(std::floor((y1 - ymax) / c - 0.5)));
    const int r1 = std::min(map.rows - 1, static_cast<int>(std::ceil((y1 - ymin) / c - 0.5)));
    for (int r = r0; r <= r1; ++r) {
      const double y = y1 - (r + 0.5) * c;
      for (int col = c0; col <= c1; ++col) {
        const double x = x0 + (col + 0.5) * c;
        const double l1 =
            ((x - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (y - p0.y())) / det;
        const double l2 =
            ((p1.x() - p0.x()) * (y - p0.y()) - (x - p0.x()) * (p1.y() - p0.y())) / det;
        if (l1 < -1e-9 || l2 < -1e-9 || l1 + l2 > 1 + 1e-9) continue;
        put(r, col, static_cast<float>(p0.z() + l1 * (p1.z() - p0.z()) + l2 * (p2.z() - p0.z())));
      }
    }
  }
  // Samples splatted: an elevation map of points keeps parts thinner than a cell.
  for (const auto& p : m.points) {
    const Eigen::Vector3d w = T * p.cast<double>();
    put(static_cast<int>(std::floor((y1 - w.y()) / c)),
        static_cast<int>(std::floor((w.x() - x0) / c)), static_cast<float>(w.z()));
  }
  std::vector<uint8_t> covered(map.z.size());
  for (std::size_t i = 0; i < map.z.size(); ++i) covered[i] = map.z[i] == map.z[i];
  if (footprint) *footprint = covered;
  if (config.background_radius_m > 0) {
    // The background ring: cells within `ring` cells (chessboard distance) of the footprint,
    // i.e. the footprint dilated by a square of 2·ring + 1 cells (OpenCV's separable min/max
    // filter: on the 2 cm map a 0.42 m ring is 43 × 43 cells, which a per-cell loop over the
    // square paid for every footprint cell).
    const int ring = config.background_ring_m > 0
                         ? static_cast<int>(std::ceil(config.background_ring_m / c))
                         : -1;
    cv::Mat near_fp;
    if (ring >= 0) {
      cv::Mat fp_mask(map.rows, map.cols, CV_8U, covered.data());
      cv::dilate(fp_mask, near_fp,
                 cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * ring + 1, 2 * ring + 1)),
                 cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
    }
    const double rb2 = config.background_radius_m * config.background_radius_m;
    for (int r = 0; r < map.rows; ++r) {
      for (int col = 0; col < map.cols; ++col) {
        const std::size_t i = map.index(r, col);
        if (covered[i]) continue;
        if ((map.cell_center_xy(r, col) - center_world_xy).squaredNorm() > rb2) continue;
        if (ring >= 0 && !near_fp.at<uint8_t>(r, col)) continue;
        map.z[i] = static_cast<float>(placed_base);
      }
    }
  }
  return map;
}

}  // namespace sonar3d
