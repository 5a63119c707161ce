#include "sonar3d/world/relocalize.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/world/change.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

// Points on a triangle: its edges every `spacing`, and inside about one per spacing² of area, a
// deterministic low-discrepancy set (the R2 sequence) warped uniformly onto the triangle.
void sample_triangle(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                     double spacing, std::vector<Eigen::Vector3f>& out) {
  // The edges every `spacing` (a structure's outline must fill the elevation map's cells at its
  // border, as the carved swath's does), then the inside.
  for (const auto& [p, q] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
    const int m = std::clamp(static_cast<int>(std::ceil((q - p).norm() / spacing)), 1, 100000);
    for (int k = 0; k < m; ++k) out.push_back(p + (static_cast<float>(k) / m) * (q - p));
  }
  const double area = 0.5 * (b - a).cross(c - a).norm();
  const long n =
      std::min<long>(1'000'000, static_cast<long>(std::ceil(area / (spacing * spacing))));
  constexpr double g1 = 0.7548776662466927, g2 = 0.5698402909980532;  // R2: 1/φ₂, 1/φ₂²
  for (long k = 0; k < n; ++k) {
    const double r1 = std::fmod(0.5 + g1 * static_cast<double>(k), 1.0);
    const double r2 = std::fmod(0.5 + g2 * static_cast<double>(k), 1.0);
    const double su = std::sqrt(r1);
    const float wa = static_cast<float>(1 - su), wb = static_cast<float>(su * (1 - r2)),
                wc = static_cast<float>(su * r2);
    out.push_back(wa * a + wb * b + wc * c);
  }
}

std::string read_text(const fs::path& path, std::uintmax_t max_bytes) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  require(!ec, "cannot read '" + path.string() + "'");
  require(size <= max_bytes, "'" + path.string() + "' is larger than a world model's graph.json");
  std::ifstream f(path, std::ios::binary);
  require(static_cast<bool>(f), "cannot open '" + path.string() + "' for reading");
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

// The correction's 2×4 lever on (yaw, x, y, z) at a point p of the swath: q = R(ψ)(p − c) + c + t.
Eigen::Matrix<double, 2, 4> horizontal_jacobian(const Eigen::Vector3d& p, const Eigen::Vector3d& c,
                                                double yaw) {
  const double dx = p.x() - c.x(), dy = p.y() - c.y();
  const double cs = std::cos(yaw), sn = std::sin(yaw);
  Eigen::Matrix<double, 2, 4> J;
  J << -sn * dx - cs * dy, 1, 0, 0, cs * dx - sn * dy, 0, 1, 0;
  return J;
}

PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  PointCloud out;
  out.points.reserve(cloud.size());
  const Eigen::Matrix3f R = T.linear().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  for (const auto& p : cloud.points) out.points.push_back(R * p + t);
  return out;
}

// The points of `cloud` whose (x, y) lie within [lo − margin, hi + margin].
PointCloud crop(const PointCloud& cloud, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                double margin) {
  PointCloud out;
  for (const auto& p : cloud.points) {
    if (p.x() >= lo.x() - margin && p.x() <= hi.x() + margin && p.y() >= lo.y() - margin &&
        p.y() <= hi.y() + margin) {
      out.points.push_back(p);
    }
  }
  return out;
}

void extent(const PointCloud& cloud, Eigen::Vector2d* lo, Eigen::Vector2d* hi) {
  *lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  *hi = -*lo;
  for (const auto& p : cloud.points) {
    *lo = lo->cwiseMin(p.head<2>().cast<double>());
    *hi = hi->cwiseMax(p.head<2>().cast<double>());
  }
}

Eigen::Isometry3d blend(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double w) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = (1 - w) * a.translation() + w * b.translation();
  T.linear() = Eigen::Quaterniond(a.linear())
                   .slerp(w, Eigen::Quaterniond(b.linear()))
                   .normalized()
                   .toRotationMatrix();
  return T;
}

nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json matrix_json(const Eigen::Isometry3d& T) {
  nlohmann::json m = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m.push_back(T.matrix()(r, c));
  }
  return m;
}

}  // namespace

void RelocalizeConfig::validate() const {
  params::check(*this, "relocalize");
  split.validate();
  registration.validate();
  require(registration.search_m >= registration.cell_m,
          "relocalize: registration.search_m must be at least one cell (registration.cell_m)");
}

WorldModelCloud read_world_model_cloud(const fs::path& world_dir, double spacing_m) {
  require(spacing_m > 0 && std::isfinite(spacing_m),
          "relocalize: the structures' sample spacing must be > 0");
  const std::string where = "world model '" + world_dir.string() + "'";
  require(fs::exists(world_dir), where + " does not exist (a directory written by sonar3d world)");
  require(fs::is_directory(world_dir),
          where + " is not a directory (give the directory sonar3d world wrote)");
  const fs::path graph_path = world_dir / "graph.json";
  require(fs::is_regular_file(graph_path),
          where + " has no graph.json: not a world model directory of sonar3d world");
  nlohmann::json graph;
  try {
    graph = nlohmann::json::parse(read_text(graph_path, 256u << 20));
  } catch (const nlohmann::json::exception& e) {
    throw Error("'" + graph_path.string() + "' is not JSON: " + e.what());
  }
  require(graph.is_object() && graph.value("format", std::string()) == "sonar3d-world",
          "'" + graph_path.string() +
              "' is not a sonar3d world graph (\"format\": "
              "\"sonar3d-world\")");
  WorldModelCloud w;
  w.dir = world_dir.string();
  // The finest seabed level: its vertices are the height field's cell centres.
  const nlohmann::json* finest = nullptr;
  if (graph.contains("seabed") && graph["seabed"].is_array()) {
    for (const auto& lod : graph["seabed"]) {
      if (!lod.is_object() || !lod.contains("lod") || !lod["lod"].is_number_integer()) continue;
      if (!finest || lod["lod"].get<int>() < (*finest)["lod"].get<int>()) finest = &lod;
    }
  }
  require(finest != nullptr && finest->contains("file") && (*finest)["file"].is_string(),
          where +
              " has no seabed (graph.json lists no seabed level): relocalisation registers "
              "against the seabed");
  const fs::path seabed_path = world_dir / (*finest)["file"].get<std::string>();
  require(fs::is_regular_file(seabed_path),
          where + ": its seabed '" + seabed_path.filename().string() + "' is missing");
  w.cloud = read_ply(seabed_path.string());  // the vertices only: the faces are not needed
  w.cloud.intensity.clear();
  w.cloud.color.clear();
  w.cloud.properties.clear();
  w.seabed_points = w.cloud.size();
  require(w.seabed_points > 0, where + ": its seabed '" + seabed_path.filename().string() +
                                   "' has no vertex (an empty seabed)");
  w.seabed_cell_m = finest->value("cell_m", 0.0);
  // The confirmed structures, as placed (models/<id>.ply is in the world frame, scaled).
  if (graph.contains("objects") && graph["objects"].is_array()) {
    for (const auto& ob : graph["objects"]) {
      if (!ob.is_object() || !ob.value("confirmed", true) || !ob.contains("file") ||
          !ob["file"].is_string()) {
        continue;
      }
      const fs::path mesh_path = world_dir / ob["file"].get<std::string>();
      require(fs::is_regular_file(mesh_path),
              where + ": the model file '" + ob["file"].get<std::string>() + "' is missing");
      std::vector<std::vector<uint32_t>> f;
      const PointCloud v = read_ply_faces(mesh_path.string(), &f);
      for (const auto& tri : f) {
        for (std::size_t k = 1; k + 1 < tri.size(); ++k) {  // polygons as fans
          sample_triangle(v.points[tri[0]], v.points[tri[k]], v.points[tri[k + 1]], spacing_m,
                          w.cloud.points);
        }
      }
      ++w.structures;
    }
  }
  w.structure_points = w.cloud.size() - w.seabed_points;
  return w;
}

namespace {

// The drift along a found swath (see the header): its cloud, moved by the swath's correction T,
// cut into pieces along the track, each registered again (shift, height; yaw within ±0.2°), and
// the pieces' displacements fitted as a + b·(t − t_mid).
void fit_pieces(const Dataset& dataset, const PointCloud& model, const ElevationMap& model_map,
                const PointCloud& cloud, const Eigen::Isometry3d& T,
                const ChangeRegistrationConfig& reg, const RelocalizeConfig& config,
                RelocalizedSwath& sw) {
  std::vector<double> times;
  std::vector<Eigen::Vector3d> track;
  for (int i = sw.first_frame; i <= sw.last_frame; ++i) {
    const double t = dataset.frames[i].timestamp;
    times.push_back(t);
    track.push_back(T * dataset.navigation.interpolate(t).translation());
  }
  Eigen::Vector2d u = (track.back() - track.front()).head<2>();
  const double length = u.norm();
  if (!(length > 0)) return;
  u /= length;
  const int n = std::max(1, static_cast<int>(std::lround(length / config.piece_m)));
  sw.pieces = n;
  const PointCloud moved = transformed(cloud, T);
  std::vector<PointCloud> parts(static_cast<std::size_t>(n));
  for (const auto& p : moved.points) {
    const double along = (p.head<2>().cast<double>() - track.front().head<2>()).dot(u);
    const int k = std::clamp(static_cast<int>(std::floor(along / length * n)), 0, n - 1);
    parts[static_cast<std::size_t>(k)].points.push_back(p);
  }
  ChangeRegistrationConfig pc = reg;
  // Within the swath's fit, the drift leaves a piece off by at most about 1 % of half the line.
  pc.search_m = 2 * reg.cell_m + 0.005 * length;
  pc.yaw_cell_m = reg.cell_m;
  pc.yaw_search_deg = 0;  // the yaw by Gauss-Newton only, within 2 steps
  pc.yaw_step_deg = 0.1;
  pc.min_overlap_cells = std::max(50, reg.min_overlap_cells / n);
  struct PieceFit {
    double t;
    Eigen::Vector3d d;
  };
  std::vector<PieceFit> fits;
  for (int k = 0; k < n; ++k) {
    const PointCloud& part = parts[static_cast<std::size_t>(k)];
    if (part.size() < static_cast<std::size_t>(pc.min_overlap_cells)) continue;
    Eigen::Vector2d lo, hi;
    extent(part, &lo, &hi);
    ChangeRegistration rk;
    try {
      rk = register_surveys(crop(model, lo, hi, pc.search_m + 0.5), part, pc);
    } catch (const Error&) {
      continue;  // no overlap: the piece says nothing
    }
    const RegistrationFit f = registration_fit(model_map, part, rk.T_a_b, reg.inlier_fraction);
    if (static_cast<double>(f.overlap) <
        config.min_overlap_fraction * static_cast<double>(f.b_cells)) {
      continue;
    }
    // The piece's centre on the track, and the piece's displacement there.
    const double centre = (k + 0.5) / n * length;
    std::size_t best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < track.size(); ++i) {
      const double d = std::abs((track[i] - track.front()).head<2>().dot(u) - centre);
      if (d < best_d) best_d = d, best = i;
    }
    const Eigen::Vector3d q = track[best];  // T is a yaw and a shift: q.z does not matter
    fits.push_back({times[best], rk.T_a_b * q - q});
  }
  sw.pieces_used = static_cast<int>(fits.size());
  if (fits.empty()) return;
  const double m = static_cast<double>(fits.size());
  double t_mid = 0;
  for (const PieceFit& f : fits) t_mid += f.t / m;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  for (const PieceFit& f : fits) a += f.d / m;
  double stt = 0;
  for (const PieceFit& f : fits) stt += (f.t - t_mid) * (f.t - t_mid);
  // A rate from 3 pieces or more: through 2 it would follow their noise alone (nothing left to
  // check it against), on lines short enough for the drift to stay under a cell.
  if (fits.size() >= 3 && stt > 0) {
    for (const PieceFit& f : fits) b += (f.t - t_mid) * (f.d - a) / stt;
  }
  sw.drift_offset = a;
  sw.drift_rate = b;
  sw.t_mid = t_mid;
  if (fits.size() >= 3) {
    double ss = 0;
    for (const PieceFit& f : fits) {
      ss += (f.d - a - b * (f.t - t_mid)).head<2>().squaredNorm();
    }
    sw.piece_rms_m = std::sqrt(ss / (m - 2));
    const double lever = std::max(std::abs(sw.t0 - t_mid), std::abs(sw.t1 - t_mid));
    sw.sigma_pieces_m = sw.piece_rms_m * std::sqrt(1 / m + lever * lever / stt);
    if (!(sw.sigma_horizontal_m >= sw.sigma_pieces_m)) sw.sigma_horizontal_m = sw.sigma_pieces_m;
  }
}

// ---------------------------------------------------------------------------------------------
// The stages of relocalize, per swath in the order it runs them: carve the swath alone, register
// it onto the model (coarse, then refined), test the registration (found or not), its σ, the
// drift along it (fit_pieces); then, over the survey, the swaths not found borrow a correction
// and the navigation is moved.

// Stage 1: the swath carved on its own (as `sonar3d map` carves one, thesis ch. 4).
PointCloud carve_swath(const Dataset& dataset, const CarveConfig& carve, int s,
                       const RelocalizedSwath& sw, Progress& bar) {
  PointCloud cloud;
  {
    Carver carver(dataset.spec, carve, dataset.noise);
    integrate_frames(carver, dataset, static_cast<std::size_t>(sw.first_frame),
                     static_cast<std::size_t>(sw.last_frame), &bar);
    cloud = carver.finalize();
  }
  require(!cloud.empty(), fmt::format("relocalize: swath {} (frames {}–{}) reconstructs to no "
                                      "point: is the seabed within the sonar's range?",
                                      s, sw.first_frame, sw.last_frame));
  return cloud;
}

// A swath registered onto the model: the model near it, and the registration when they overlap.
struct ModelRegistration {
  PointCloud near;  // the model near the swath
  bool overlapped = false;
  ChangeRegistration r;                                // T_a_b: model ← swath
  Eigen::Vector3d r2_pivot = Eigen::Vector3d::Zero();  // the refinement's pivot (survey moved)
};

// Stage 2: the swath registered onto the model (sec. 6.2.2.1's search over yaw, then
// Gauss-Newton; register_surveys), then refined from that solution in a window of a few cells and
// a yaw window of two coarse steps searched five times finer (a 9 m swath's ends move 4 cm for
// 0.25°, under the coarse maps' cell); the refinement's Gauss-Newton gives σ. The model is
// cropped to the swath's extent grown by the search window and the yaw's lever arm (the
// registration maps the model at three cells per call).
ModelRegistration register_to_model(const PointCloud& model, const PointCloud& cloud,
                                    const ChangeRegistrationConfig& reg) {
  ModelRegistration m;
  Eigen::Vector2d lo, hi;
  extent(cloud, &lo, &hi);
  const double margin =
      reg.search_m + std::sin(reg.yaw_search_deg * kDeg) * 0.5 * (hi - lo).norm() + 1.0;
  m.near = crop(model, lo, hi, margin);
  try {
    require(!m.near.empty(), "no model point near the swath");
    m.r = register_surveys(m.near, cloud, reg);
    ChangeRegistrationConfig fine = reg;
    fine.search_m = 2 * reg.cell_m;
    fine.yaw_cell_m = reg.cell_m;
    fine.yaw_search_deg = 2 * reg.yaw_step_deg;
    fine.yaw_step_deg = 0.2 * reg.yaw_step_deg;
    const ChangeRegistration r2 = register_surveys(m.near, transformed(cloud, m.r.T_a_b), fine);
    m.r2_pivot = r2.pivot;
    m.r.T_a_b = r2.T_a_b * m.r.T_a_b;
    m.r.yaw_deg += r2.yaw_deg;
    m.r.covariance = r2.covariance;
    m.overlapped = true;
  } catch (const Error&) {
    m.overlapped = false;
  }
  return m;
}

// Stage 3: the tests of a registration: the swath's overlap with the model at the best pose, and
// its fit against the search window's alternatives (the pose shifted by half and all of the
// window in 8 directions): the swath is found when enough of it lies on the model and the best
// pose fits distinctly better than the others (RelocalizeConfig). Fills `sw`.
void test_registration(const ElevationMap& model_map, const PointCloud& cloud,
                       const Eigen::Isometry3d& T_model_survey, const ChangeRegistrationConfig& reg,
                       const RelocalizeConfig& config, RelocalizedSwath& sw) {
  const RegistrationFit best =
      registration_fit(model_map, cloud, T_model_survey, reg.inlier_fraction);
  sw.overlap_cells = best.overlap;
  sw.swath_cells = best.b_cells;
  sw.overlap_fraction =
      best.b_cells ? static_cast<double>(best.overlap) / static_cast<double>(best.b_cells) : 0;
  sw.residual_m = best.cost_m;
  std::vector<double> alt;
  for (const double radius : {0.5 * reg.search_m, reg.search_m}) {
    for (int k = 0; k < 8; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = radius * Eigen::Vector3d(std::cos(k * kPi / 4), std::sin(k * kPi / 4), 0);
      const RegistrationFit f =
          registration_fit(model_map, cloud, T * T_model_survey, reg.inlier_fraction);
      // Shifted off the model: as bad as no fit (the alternative is no overlap at all).
      if (f.overlap >= static_cast<std::size_t>(reg.min_overlap_cells)) {
        alt.push_back(f.cost_m);
      }
    }
  }
  if (!alt.empty()) {
    std::nth_element(alt.begin(), alt.begin() + static_cast<std::ptrdiff_t>(alt.size() / 2),
                     alt.end());
    sw.alternative_m = alt[alt.size() / 2];
    sw.distinctiveness = sw.alternative_m > 0 ? 1 - sw.residual_m / sw.alternative_m : 0;
  } else {
    sw.distinctiveness = 1;  // every alternative leaves the model: only the solution fits
  }
  if (best.overlap < static_cast<std::size_t>(reg.min_overlap_cells)) {
    sw.reason = fmt::format("{} cells overlap the model at the best pose (fewer than {})",
                            best.overlap, reg.min_overlap_cells);
  } else if (sw.overlap_fraction < config.min_overlap_fraction) {
    sw.reason = fmt::format(
        "only {:.0f} % of the swath lies on the model at the best pose (at least {:.0f} % "
        "needed)",
        100 * sw.overlap_fraction, 100 * config.min_overlap_fraction);
  } else if (sw.distinctiveness < config.min_distinctiveness) {
    sw.reason = fmt::format(
        "the best pose fits hardly better than the search window's others (distinctiveness "
        "{:.2f} < {:.2f}: a featureless overlap)",
        sw.distinctiveness, config.min_distinctiveness);
  } else {
    sw.found = true;
  }
}

// Stage 4: σ of a found swath's placement from the refinement's Gauss-Newton covariance, its
// cells of cell_m/2 counted once per cell of cell_m (×4 the variance), carried to the swath's
// centre and, the worst over its frames, to the vehicle's positions (horizontal_jacobian).
void registration_sigma(const Dataset& dataset, const PointCloud& cloud, const ModelRegistration& m,
                        RelocalizedSwath& sw) {
  const ChangeRegistration& r = m.r;
  // The refinement's parameters: a small yaw about its pivot (the moved swath's centre).
  const Eigen::Matrix4d C = 4.0 * r.covariance;
  const double yaw = 0;
  Eigen::Vector3d lo = cloud.points[0].cast<double>(), hi = lo;
  for (const auto& p : cloud.points) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  const Eigen::Vector3d centre = r.T_a_b * (0.5 * (lo + hi));
  const Eigen::Matrix<double, 2, 4> Jc = horizontal_jacobian(centre, m.r2_pivot, yaw);
  const Eigen::Matrix2d Cc = Jc * C * Jc.transpose();
  sw.sigma_m = {std::sqrt(Cc(0, 0)), std::sqrt(Cc(1, 1)), std::sqrt(C(3, 3))};
  sw.sigma_yaw_deg = std::sqrt(C(0, 0)) / kDeg;
  double worst = 0;
  for (int i = sw.first_frame; i <= sw.last_frame; ++i) {
    const Eigen::Vector3d p =
        r.T_a_b * dataset.navigation.interpolate(dataset.frames[i].timestamp).translation();
    const Eigen::Matrix<double, 2, 4> J = horizontal_jacobian(p, m.r2_pivot, yaw);
    worst = std::max(worst, std::sqrt((J * C * J.transpose()).trace()));
  }
  sw.sigma_hessian_m = worst;
  sw.sigma_horizontal_m = worst;
}

// Stages 1–4 and the drift for one swath (frames `range`): carved, registered, tested, σ, pieces.
RelocalizedSwath relocalize_swath(const Dataset& dataset, const PointCloud& model,
                                  const ElevationMap& model_map, const CarveConfig& carve,
                                  const ChangeRegistrationConfig& reg,
                                  const RelocalizeConfig& config, int s,
                                  const std::pair<int, int>& range, Progress& bar) {
  RelocalizedSwath sw;
  sw.first_frame = range.first;
  sw.last_frame = range.second;
  sw.t0 = dataset.frames[sw.first_frame].timestamp;
  sw.t1 = dataset.frames[sw.last_frame].timestamp;
  auto t0 = std::chrono::steady_clock::now();
  const PointCloud cloud = carve_swath(dataset, carve, s, sw, bar);
  sw.points = cloud.size();
  sw.seconds_carving = seconds_since(t0);
  t0 = std::chrono::steady_clock::now();
  const ModelRegistration m = register_to_model(model, cloud, reg);
  if (!m.overlapped) {
    sw.reason =
        fmt::format("no overlap with the model within ±{:g} m and ±{:g} deg of the navigation",
                    reg.search_m, reg.yaw_search_deg);
  } else {
    sw.T_model_survey = m.r.T_a_b;
    sw.yaw_deg = m.r.yaw_deg;
    test_registration(model_map, cloud, m.r.T_a_b, reg, config, sw);
    if (sw.found && m.r.covariance.allFinite()) registration_sigma(dataset, cloud, m, sw);
    if (sw.found && config.piece_m > 0) {
      fit_pieces(dataset, m.near, model_map, cloud, m.r.T_a_b, reg, config, sw);
    }
  }
  sw.seconds_registration = seconds_since(t0);
  return sw;
}

// Stage 5: swaths not found borrow the nearest found swath's correction (in swath order), held
// constant. `found`: the indices of the found swaths (not empty).
void borrow_corrections(const std::vector<int>& found, std::vector<RelocalizedSwath>& swaths) {
  for (std::size_t s = 0; s < swaths.size(); ++s) {
    RelocalizedSwath& sw = swaths[s];
    if (sw.found) continue;
    int nearest = found[0];
    for (int f : found) {
      if (std::abs(f - static_cast<int>(s)) < std::abs(nearest - static_cast<int>(s))) nearest = f;
    }
    sw.T_model_survey = swaths[nearest].T_model_survey;
    sw.drift_offset = swaths[nearest].correction(sw.t0).translation() -
                      sw.T_model_survey.translation();  // the nearest one's, held constant
    sw.drift_rate.setZero();
    sw.t_mid = sw.t0;
    sw.yaw_deg = swaths[nearest].yaw_deg;
    sw.borrowed = true;
  }
}

// Stage 6: the navigation moved: within a swath by its correction, in a turn by the two around
// it blended linearly in time, before the first / after the last swath by theirs.
Trajectory relocalized_navigation(const Trajectory& nav, const std::vector<RelocalizedSwath>& sws) {
  Trajectory out;
  for (std::size_t k = 0; k < nav.size(); ++k) {
    const double t = nav.times[k];
    Eigen::Isometry3d T = sws.front().correction(t);
    if (t >= sws.back().t1) {
      T = sws.back().correction(t);
    } else if (t > sws.front().t0) {
      for (std::size_t s = 0; s < sws.size(); ++s) {
        if (t >= sws[s].t0 && t <= sws[s].t1) {
          T = sws[s].correction(t);
          break;
        }
        if (s + 1 < sws.size() && t > sws[s].t1 && t < sws[s + 1].t0) {
          const double w = (t - sws[s].t1) / (sws[s + 1].t0 - sws[s].t1);
          T = blend(sws[s].correction(t), sws[s + 1].correction(t), w);
          break;
        }
      }
    }
    out.push_back(t, T * nav.poses[k]);
  }
  return out;
}

// Stage 7 (map_voxel_m > 0): the survey carved again with its relocalised navigation — each
// swath alone, as `sonar3d map` carves them (thesis ch. 4), the clouds put together — so B's map
// is in the model's frame with the drift along its lines taken out, which no rigid move of a
// cloud carved as logged could do.
PointCloud carve_relocalized(const Dataset& dataset, const RelocalizeResult& result,
                             const RelocalizeConfig& config, bool progress) {
  Dataset moved = dataset;  // frames are read on demand: only the navigation is copied
  moved.navigation = result.navigation;
  CarveConfig carve;
  carve.voxel_size = config.map_voxel_m;
  carve.num_threads = config.num_threads;
  std::size_t total_frames = 0;
  for (const RelocalizedSwath& s : result.swaths) {
    total_frames += static_cast<std::size_t>(s.last_frame - s.first_frame + 1);
  }
  Progress bar("relocalize: carving the relocalised survey", total_frames, progress);
  PointCloud map;
  for (const RelocalizedSwath& s : result.swaths) {
    Carver carver(moved.spec, carve, moved.noise);
    integrate_frames(carver, moved, static_cast<std::size_t>(s.first_frame),
                     static_cast<std::size_t>(s.last_frame), &bar);
    const PointCloud c = carver.finalize();
    map.points.insert(map.points.end(), c.points.begin(), c.points.end());
  }
  bar.finish();
  return map;
}

}  // namespace

Eigen::Isometry3d RelocalizedSwath::correction(double t) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = drift_offset + drift_rate * (std::clamp(t, t0, t1) - t_mid);
  return T * T_model_survey;
}

// The pipeline of relocalisation: each swath on its own (relocalize_swath), then the corrections
// of the swaths not found and the moved navigation (stages above).
RelocalizeResult relocalize(const Dataset& dataset, const WorldModelCloud& world,
                            const RelocalizeConfig& config, bool progress) {
  config.validate();
  const auto t_start = std::chrono::steady_clock::now();
  require(dataset.size() > 0, "relocalize: the dataset has no frame");
  require(!world.cloud.empty(), "relocalize: the world model has no point");
  RelocalizeResult result;
  result.world = world.dir;
  result.world_points = world.cloud.size();

  const std::vector<std::pair<int, int>> ranges = split_swaths(dataset, config.split);

  ChangeRegistrationConfig reg = config.registration;
  reg.num_threads = config.num_threads;
  reg.validate();

  // The model's map at the registration cell, for the found/not-found tests.
  ElevationMapConfig mc;
  mc.cell_m = reg.cell_m;
  const ElevationMap model_map = elevation_map_from_points(world.cloud, mc);

  CarveConfig carve;
  carve.voxel_size = config.voxel_m;
  carve.num_threads = config.num_threads;

  std::size_t total_frames = 0;
  for (const auto& r : ranges) total_frames += static_cast<std::size_t>(r.second - r.first + 1);
  Progress bar("relocalize: carving", total_frames, progress);
  for (std::size_t s = 0; s < ranges.size(); ++s) {
    const RelocalizedSwath sw = relocalize_swath(dataset, world.cloud, model_map, carve, reg,
                                                 config, static_cast<int>(s), ranges[s], bar);
    result.seconds_carving += sw.seconds_carving;
    result.seconds_registration += sw.seconds_registration;
    result.swaths.push_back(sw);
  }
  bar.finish();

  std::vector<int> found;
  for (std::size_t s = 0; s < result.swaths.size(); ++s) {
    if (result.swaths[s].found) found.push_back(static_cast<int>(s));
  }
  result.found = !found.empty();
  if (result.found) {
    double worst = 0;
    for (int s : found) worst = std::max(worst, result.swaths[s].sigma_horizontal_m);
    result.sigma_horizontal_m = worst;
    borrow_corrections(found, result.swaths);
    result.navigation = relocalized_navigation(dataset.navigation, result.swaths);
    if (config.map_voxel_m > 0) {
      const auto t_map = std::chrono::steady_clock::now();
      result.map = carve_relocalized(dataset, result, config, progress);
      result.map_voxel_m = config.map_voxel_m;
      result.seconds_map = seconds_since(t_map);
      require(!result.map.empty(),
              "relocalize: the survey carved with its relocalised navigation has no point");
    }
  }
  result.seconds_total = seconds_since(t_start);
  return result;
}

std::string relocalization_json(const RelocalizeResult& r, const RelocalizeConfig& config) {
  nlohmann::json j;
  j["format"] = "sonar3d-relocalization";
  j["version"] = 1;
  j["found"] = r.found;
  j["dataset"] = r.dataset;
  j["world"] = r.world;
  j["world_points"] = r.world_points;
  j["navigation"] = r.found ? nlohmann::json("navigation.tum") : nlohmann::json(nullptr);
  j["map"] = r.map.empty() ? nlohmann::json(nullptr) : nlohmann::json("merged.ply");
  j["map_voxel_m"] = r.map.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.map_voxel_m);
  j["map_points"] = r.map.size();
  j["sigma_horizontal_m"] = number_or_null(r.sigma_horizontal_m);
  nlohmann::json swaths = nlohmann::json::array();
  for (const RelocalizedSwath& s : r.swaths) {
    nlohmann::json o;
    o["frames"] = {s.first_frame, s.last_frame};
    o["time_s"] = {s.t0, s.t1};
    o["points"] = s.points;
    o["found"] = s.found;
    o["reason"] = s.found ? nlohmann::json(nullptr) : nlohmann::json(s.reason);
    o["borrowed"] = s.borrowed;
    const Eigen::Vector3d t = s.T_model_survey.translation();
    o["T_model_survey"] = matrix_json(s.T_model_survey);
    o["shift_m"] = {t.x(), t.y(), t.z()};
    o["yaw_deg"] = s.yaw_deg;
    o["sigma_m"] = {number_or_null(s.sigma_m.x()), number_or_null(s.sigma_m.y()),
                    number_or_null(s.sigma_m.z())};
    o["sigma_yaw_deg"] = number_or_null(s.sigma_yaw_deg);
    o["sigma_horizontal_m"] = number_or_null(s.sigma_horizontal_m);
    o["sigma_hessian_m"] = number_or_null(s.sigma_hessian_m);
    o["sigma_pieces_m"] = number_or_null(s.sigma_pieces_m);
    o["drift"] = {{"offset_m", {s.drift_offset.x(), s.drift_offset.y(), s.drift_offset.z()}},
                  {"rate_m_per_s", {s.drift_rate.x(), s.drift_rate.y(), s.drift_rate.z()}},
                  {"t_mid_s", s.t_mid},
                  {"pieces", s.pieces},
                  {"pieces_used", s.pieces_used},
                  {"rms_m", number_or_null(s.piece_rms_m)}};
    o["overlap_cells"] = s.overlap_cells;
    o["swath_cells"] = s.swath_cells;
    o["overlap_fraction"] = s.overlap_fraction;
    o["residual_m"] = number_or_null(s.residual_m);
    o["alternative_m"] = number_or_null(s.alternative_m);
    o["distinctiveness"] = s.distinctiveness;
    o["seconds"] = {{"carving", s.seconds_carving}, {"registration", s.seconds_registration}};
    swaths.push_back(o);
  }
  j["swaths"] = swaths;
  j["criterion"] = {{"min_overlap_cells", config.registration.min_overlap_cells},
                    {"min_overlap_fraction", config.min_overlap_fraction},
                    {"min_distinctiveness", config.min_distinctiveness},
                    {"search_m", config.registration.search_m},
                    {"yaw_search_deg", config.registration.yaw_search_deg}};
  j["seconds"] = {{"carving", r.seconds_carving},
                  {"registration", r.seconds_registration},
                  {"map", r.seconds_map},
                  {"total", r.seconds_total}};
  return j.dump(2) + "\n";
}

void write_relocalization(const fs::path& dir, const RelocalizeResult& result,
                          const RelocalizeConfig& config) {
  fs::create_directories(dir);
  if (result.found) write_tum((dir / "navigation.tum").string(), result.navigation);
  if (!result.map.empty()) write_ply((dir / "merged.ply").string(), result.map);
  const fs::path json = dir / "relocalization.json";
  std::ofstream f(json, std::ios::binary | std::ios::trunc);
  f << relocalization_json(result, config);
  f.close();
  require(static_cast<bool>(f), "failed writing '" + json.string() + "' (disk full?)");
}

bool is_relocalization_dir(const fs::path& path) {
  return fs::is_directory(path) && fs::is_regular_file(path / "relocalization.json");
}

RelocalizedSurvey read_relocalized_survey(const fs::path& dir) {
  const std::string where = "relocalisation directory '" + dir.string() + "'";
  const fs::path json_path = dir / "relocalization.json";
  require(fs::is_regular_file(json_path),
          where + " has no relocalization.json (a directory written by sonar3d relocalize)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_text(json_path, 256u << 20));
  } catch (const nlohmann::json::exception& e) {
    throw Error("'" + json_path.string() + "' is not JSON: " + e.what());
  }
  require(j.is_object() && j.value("format", std::string()) == "sonar3d-relocalization",
          "'" + json_path.string() +
              "' is not a relocalisation (\"format\": \"sonar3d-relocalization\")");
  require(j.value("found", false),
          where + ": the survey was not found in its world model (nothing to compare)");
  require(j.contains("map") && j["map"].is_string() && fs::is_regular_file(dir / "merged.ply"),
          where +
              " has no merged.ply: relocalise with --map-resolution (e.g. 0.02) to carve the "
              "survey with its relocalised navigation");
  RelocalizedSurvey r;
  r.dir = dir.string();
  r.world = j.value("world", std::string());
  // The map the world model was built from, as its graph.json records it.
  const fs::path graph = fs::path(r.world) / "graph.json";
  if (!r.world.empty() && fs::is_regular_file(graph)) {
    try {
      const nlohmann::json g = nlohmann::json::parse(read_text(graph, 256u << 20));
      if (g.contains("source") && g["source"].is_object() && g["source"].contains("map") &&
          g["source"]["map"].is_string()) {
        r.world_map = g["source"]["map"].get<std::string>();
      }
    } catch (const nlohmann::json::exception&) {
      r.world_map.clear();  // unknown: the caller registers B onto A as usual
    }
  }
  r.cloud = read_ply((dir / "merged.ply").string());
  return r;
}

bool relocalized_against(const RelocalizedSurvey& b, const std::string& a) {
  if (b.world_map.empty() || a.empty()) return false;
  // A map directory and its merged.ply are one survey.
  auto survey = [](fs::path p) {
    std::error_code ec;
    if (fs::is_regular_file(p) && p.filename() == "merged.ply") p = p.parent_path();
    const fs::path c = fs::weakly_canonical(p, ec);
    return ec ? p.lexically_normal() : c;
  };
  return survey(b.world_map) == survey(a);
}

}  // namespace sonar3d
