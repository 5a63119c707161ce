// Field mapping (thesis sec. 6.2): swaths, per-swath carving and elevation maps, registration,
// navigation correction, merged outputs.
#include "sonar3d/mapping/survey.hpp"

#include <fmt/core.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/eval/per_object.hpp"
#include "sonar3d/io/truth.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {

nlohmann::json vec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Swath clouds between MPI ranks: [error length u32, error][count u32] then per swath
// [index i32, seconds f64, points u64, xyz f32 × 3n, has intensity u8, intensity f32 × n].
template <typename T>
void put(std::string& b, const T& v) {
  b.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <typename T>
T take(const std::string& b, std::size_t& at) {
  require(at + sizeof(T) <= b.size(), "field mapping: a rank's swath message is truncated");
  T v;
  std::memcpy(&v, b.data() + at, sizeof(T));
  at += sizeof(T);
  return v;
}

std::string pack_swaths(const std::string& error, const std::vector<int>& mine,
                        const std::vector<PointCloud>& clouds, const std::vector<double>& seconds) {
  std::string b;
  put(b, static_cast<std::uint32_t>(error.size()));
  b += error;
  put(b, static_cast<std::uint32_t>(error.empty() ? mine.size() : 0));
  if (!error.empty()) return b;
  for (const int s : mine) {
    const PointCloud& c = clouds[s];
    put(b, static_cast<std::int32_t>(s));
    put(b, seconds[s]);
    put(b, static_cast<std::uint64_t>(c.size()));
    b.append(reinterpret_cast<const char*>(c.points.data()), c.size() * 3 * sizeof(float));
    put(b, static_cast<std::uint8_t>(c.has_intensity()));
    if (c.has_intensity()) {
      b.append(reinterpret_cast<const char*>(c.intensity.data()), c.size() * sizeof(float));
    }
  }
  return b;
}

// Returns the sending rank's error, if any.
std::string unpack_swaths(const std::string& b, std::vector<PointCloud>& clouds,
                          std::vector<double>& seconds) {
  std::size_t at = 0;
  const auto error_len = take<std::uint32_t>(b, at);
  require(at + error_len <= b.size(), "field mapping: a rank's swath message is truncated");
  const std::string error = b.substr(at, error_len);
  at += error_len;
  const auto count = take<std::uint32_t>(b, at);
  for (std::uint32_t k = 0; k < count; ++k) {
    const auto s = take<std::int32_t>(b, at);
    require(s >= 0 && static_cast<std::size_t>(s) < clouds.size(),
            "field mapping: a rank sent an unknown swath");
    seconds[s] = take<double>(b, at);
    const auto n = take<std::uint64_t>(b, at);
    require(n <= (b.size() - at) / (3 * sizeof(float)),
            "field mapping: a rank's swath message is truncated");
    PointCloud& c = clouds[s];
    c.points.resize(n);
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are packed xyz floats");
    std::memcpy(static_cast<void*>(c.points.data()), b.data() + at, n * 3 * sizeof(float));
    at += n * 3 * sizeof(float);
    if (take<std::uint8_t>(b, at)) {
      require(n <= (b.size() - at) / sizeof(float),
              "field mapping: a rank's swath message is truncated");
      c.intensity.resize(n);
      std::memcpy(c.intensity.data(), b.data() + at, n * sizeof(float));
      at += n * sizeof(float);
    }
  }
  return error;
}

// A swath's track: positions along its straight line (from its first frame, along the direction
// to its last) with their times, to tell when the vehicle passed over a point of its cloud.
struct SwathTrack {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero(), dir = Eigen::Vector2d::UnitX();
  std::vector<double> u, t;  // along-track position (non-decreasing), time

  double along(const Eigen::Vector2d& xy) const { return (xy - origin).dot(dir); }
  double length() const { return u.back() - u.front(); }
  double time_at(double along_m) const {
    if (along_m <= u.front()) return t.front();
    if (along_m >= u.back()) return t.back();
    const std::size_t k = static_cast<std::size_t>(std::upper_bound(u.begin(), u.end(), along_m) -
                                                   u.begin());  // 1 ≤ k < size
    const double span = u[k] - u[k - 1];
    const double w = span > 0 ? (along_m - u[k - 1]) / span : 0.0;
    return t[k - 1] + w * (t[k] - t[k - 1]);
  }
};

// Least squares xy_true ≈ M·xy + b and z_true ≈ z + dz over corresponding positions.
MapAlignment fit_alignment(const std::vector<Eigen::Vector3d>& nav,
                           const std::vector<Eigen::Vector3d>& truth) {
  MapAlignment a;
  if (nav.size() < 3) return a;
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> AtB = Eigen::Matrix<double, 3, 2>::Zero();
  double dz = 0;
  for (std::size_t i = 0; i < nav.size(); ++i) {
    const Eigen::Vector3d row(nav[i].x(), nav[i].y(), 1.0);
    AtA += row * row.transpose();
    AtB += row * truth[i].head<2>().transpose();
    dz += truth[i].z() - nav[i].z();
  }
  // A survey along one line leaves the fit singular: then a shift only.
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(AtA);
  if (lu.rank() == 3) {
    const Eigen::Matrix<double, 3, 2> X = lu.solve(AtB);
    a.M = X.topRows<2>().transpose();
    a.b = X.row(2).transpose();
  } else {
    Eigen::Vector2d shift = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < nav.size(); ++i) shift += (truth[i] - nav[i]).head<2>();
    a.b = shift / static_cast<double>(nav.size());
  }
  a.dz = dz / static_cast<double>(nav.size());
  return a;
}

// The best rigid placement of the logged (or corrected) positions onto the true ones: a turn
// and shift of (x, y) by least squares (the 2D Procrustes solution: the turn from the
// cross-covariance of the centred positions; Umeyama 1991 without scale) and the mean height
// offset.
MapAlignment fit_rigid_alignment(const std::vector<Eigen::Vector3d>& nav,
                                 const std::vector<Eigen::Vector3d>& truth) {
  MapAlignment a;
  if (nav.empty()) return a;
  Eigen::Vector2d mn = Eigen::Vector2d::Zero(), mt = Eigen::Vector2d::Zero();
  double dz = 0;
  for (std::size_t i = 0; i < nav.size(); ++i) {
    mn += nav[i].head<2>();
    mt += truth[i].head<2>();
    dz += truth[i].z() - nav[i].z();
  }
  const double n = static_cast<double>(nav.size());
  mn /= n;
  mt /= n;
  double sxx = 0, sxy = 0;  // Σ p·q and Σ p × q of the centred positions
  for (std::size_t i = 0; i < nav.size(); ++i) {
    const Eigen::Vector2d p = nav[i].head<2>() - mn, q = truth[i].head<2>() - mt;
    sxx += p.dot(q);
    sxy += p.x() * q.y() - p.y() * q.x();
  }
  const double theta = std::atan2(sxy, sxx);
  a.M << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
  a.b = mt - a.M * mn;
  a.dz = dz / n;
  return a;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

SwathTrack make_track(const Dataset& dataset, int first, int last) {
  SwathTrack tr;
  tr.origin = dataset.T_world_sonar(first).translation().head<2>();
  const Eigen::Vector2d end = dataset.T_world_sonar(last).translation().head<2>();
  if ((end - tr.origin).norm() > 1e-9) tr.dir = (end - tr.origin).normalized();
  for (int i = first; i <= last; ++i) {
    const double a = tr.along(dataset.T_world_sonar(i).translation().head<2>());
    tr.u.push_back(tr.u.empty() ? a : std::max(a, tr.u.back()));
    tr.t.push_back(dataset.frames[i].timestamp);
  }
  return tr;
}

// A piece of a swath for the drift method: its map and when the vehicle was at its middle.
struct SwathPiece {
  ElevationMap map;
  double time = 0;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
};

std::vector<SwathPiece> cut_pieces(const PointCloud& cloud, const SwathTrack& track, double piece_m,
                                   const ElevationMapConfig& map_cfg) {
  const int count = std::max(1, static_cast<int>(std::lround(track.length() / piece_m)));
  const double len = std::max(track.length(), 1e-9) / count;
  std::vector<PointCloud> parts(static_cast<std::size_t>(count));
  for (const Eigen::Vector3f& p : cloud.points) {
    const double a = track.along(p.head<2>().cast<double>()) - track.u.front();
    const int k = std::clamp(static_cast<int>(std::floor(a / len)), 0, count - 1);
    parts[k].points.push_back(p);
  }
  std::vector<SwathPiece> out;
  for (int k = 0; k < count; ++k) {
    if (parts[k].empty()) continue;
    const double mid = track.u.front() + (k + 0.5) * len;
    out.push_back({elevation_map_from_points(parts[k], map_cfg), track.time_at(mid),
                   track.origin + track.dir * mid});
  }
  return out;
}

}  // namespace

double MapAlignment::stretch() const {
  const Eigen::Vector2d sv = Eigen::JacobiSVD<Eigen::Matrix2d>(M).singularValues();
  return sv.y() > 0 ? sv.x() / sv.y() : std::numeric_limits<double>::infinity();
}

const char* to_string(SwathAdjustMethod method) {
  return enum_name(kSwathAdjustMethodNames, method);
}

SwathAdjustMethod swath_adjust_method_from_string(const std::string& name) {
  return parse_enum<SwathAdjustMethod>(kSwathAdjustMethodNames, name, "swath adjustment method");
}

void SwathSplitConfig::validate() const {
  params::check(*this, "split");
  require(time_ranges_s.size() % 2 == 0,
          "split.time_ranges_s: give pairs of times (t0 t1 per swath), got " +
              std::to_string(time_ranges_s.size()) + " number(s)");
  for (std::size_t k = 0; k + 1 < time_ranges_s.size(); k += 2) {
    require(std::isfinite(time_ranges_s[k]) && std::isfinite(time_ranges_s[k + 1]) &&
                time_ranges_s[k] < time_ranges_s[k + 1],
            fmt::format("split.time_ranges_s: swath {} ({} to {} s) must be finite with start < "
                        "end",
                        k / 2, time_ranges_s[k], time_ranges_s[k + 1]));
  }
}

void MapSurveyConfig::validate() const {
  params::check(*this, "map");
  split.validate();
  carve.validate();
  registration.validate();
  require((fixes.empty() && known_poses.empty()) || method != SwathAdjustMethod::Consecutive,
          "field mapping: fixes and known poses need the global or drift method (the "
          "consecutive one has no adjustment to put them in)");
  for (const RecognisedStructure& r : recognised) {
    require(r.p_map.allFinite(), "field mapping: recognised structure " + std::to_string(r.index) +
                                     " has a position not finite");
  }
  for (const KnownStructurePose& k : known_poses) {
    require(k.p_world.allFinite(),
            "field mapping: known pose '" + k.id + "' has a position not finite");
  }
  if (!recognised_navigation.empty()) recognised_navigation.validate("recognised_navigation");
}

std::vector<std::pair<int, int>> split_swaths(const Dataset& dataset,
                                              const SwathSplitConfig& config) {
  config.validate();
  const int n = static_cast<int>(dataset.size());
  require(n >= 2, "field mapping: the dataset has " + std::to_string(n) +
                      " frame(s); a survey needs swaths of many frames");
  std::vector<std::pair<int, int>> swaths;
  if (!config.time_ranges_s.empty()) {
    for (std::size_t k = 0; k + 1 < config.time_ranges_s.size(); k += 2) {
      const Eigen::Vector2d r(config.time_ranges_s[k], config.time_ranges_s[k + 1]);
      int first = -1, last = -1;
      for (int i = 0; i < n; ++i) {
        const double t = dataset.frames[i].timestamp;
        if (t < r.x() || t > r.y()) continue;
        if (first < 0) first = i;
        last = i;
      }
      require(first >= 0, fmt::format("field mapping: no frame within the swath time range "
                                      "[{}, {}] s",
                                      r.x(), r.y()));
      swaths.emplace_back(first, last);
    }
    return swaths;
  }
  // Direction of travel of each frame (horizontal), from its sonar position to the next one's.
  std::vector<Eigen::Vector2d> pos(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) pos[i] = dataset.T_world_sonar(i).translation().head<2>();
  // Jumps: a step more than ten times the median step (the idealised lawnmower that jumps from
  // one line to the next, or a gap in the log) ends a run; curvature is measured within runs.
  std::vector<double> steps;
  for (int i = 0; i + 1 < n; ++i) steps.push_back((pos[i + 1] - pos[i]).norm());
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  const double jump = 10.0 * steps[steps.size() / 2];
  // Turning frames: the track's direction over the metre before a frame and over the metre after
  // it differ by more than 1 m / straight_radius (the angle an arc of that radius turns through
  // in 1 m).
  constexpr double kBaseline = 1.0;  // m
  std::vector<char> turning(static_cast<std::size_t>(n), 0);
  std::vector<double> along(static_cast<std::size_t>(n), 0.0);  // track length within a piece
  for (int a = 0; a < n;) {
    int b = a;  // [a, b]: frames without a jump between them
    while (b + 1 < n && (pos[b + 1] - pos[b]).norm() <= jump) {
      along[b + 1] = along[b] + (pos[b + 1] - pos[b]).norm();
      ++b;
    }
    for (int i = a, lo = a, hi = a; i <= b; ++i) {
      while (lo < i && along[i] - along[lo + 1] >= kBaseline) ++lo;
      hi = std::max(hi, i);
      while (hi < b && along[hi] - along[i] < kBaseline) ++hi;
      const Eigen::Vector2d before = pos[i] - pos[lo], after = pos[hi] - pos[i];
      if (before.norm() < 0.5 * kBaseline || after.norm() < 0.5 * kBaseline) continue;  // an end
      const double angle =
          std::acos(std::clamp(before.normalized().dot(after.normalized()), -1.0, 1.0));
      turning[i] = angle > kBaseline / config.straight_radius_m;
    }
    a = b + 1;
    if (a < n) along[a] = 0;
  }
  const double cos_turn = std::cos(config.turn_threshold_deg * kDeg);
  int start = 0;
  bool open = false;
  Eigen::Vector2d heading = Eigen::Vector2d::Zero();  // the current run's direction
  auto close_run = [&](int last) {
    if (open && last - start + 1 >= config.min_frames) swaths.emplace_back(start, last);
    open = false;
  };
  for (int i = 0; i < n; ++i) {
    if (turning[i]) {
      close_run(i - 1);
      continue;
    }
    if (!open) {
      open = true;
      start = i;
      heading.setZero();
    }
    if (i + 1 >= n) break;
    const Eigen::Vector2d step = pos[i + 1] - pos[i];
    if (step.norm() < 1e-9) continue;  // hovering: no direction
    const Eigen::Vector2d dir = step.normalized();
    if (heading.isZero()) {
      heading = dir;
      continue;
    }
    if (dir.dot(heading) < cos_turn) {  // a sharp turn or a jump: frame i ends the run
      close_run(i);
    }
  }
  close_run(n - 1);
  // Legs across the lines: much shorter than the lines themselves.
  auto run_length = [&](const std::pair<int, int>& r) {
    return (pos[r.second] - pos[r.first]).norm();
  };
  double longest = 0;
  for (const auto& r : swaths) longest = std::max(longest, run_length(r));
  swaths.erase(std::remove_if(swaths.begin(), swaths.end(),
                              [&](const std::pair<int, int>& r) {
                                return run_length(r) < config.min_length_fraction * longest;
                              }),
               swaths.end());
  require(!swaths.empty(),
          fmt::format("field mapping: no straight run of at least {} frames in the survey "
                      "(turn threshold {:.1f}°): give swath time ranges, or lower min_frames",
                      config.min_frames, config.turn_threshold_deg));
  return swaths;
}

MemoryEstimate estimate_map_survey_memory(const Dataset& dataset, const MapSurveyConfig& config,
                                          double limit_bytes) {
  config.validate();
  const auto swaths = split_swaths(dataset, config.split);
  MemoryEstimate largest;
  std::vector<Eigen::Isometry3d> all;
  double map_cells = 0;
  for (const auto& [first, last] : swaths) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = first; i <= last; ++i) poses.push_back(dataset.T_world_sonar(i));
    MemoryEstimate e = estimate_carve_memory(dataset.spec, poses, config.carve, limit_bytes);
    if (e.total() > largest.total()) largest = e;
    const Eigen::AlignedBox3d b = footprint_bounds(dataset.spec, poses, config.carve.region);
    if (!b.isEmpty()) {
      map_cells += std::ceil(b.sizes().x() / config.cell_m + 1) *
                   std::ceil(b.sizes().y() / config.cell_m + 1);
    }
    all.insert(all.end(), poses.begin(), poses.end());
  }
  MemoryEstimate e;
  for (auto& p : largest.parts) p.what = "the largest swath's " + p.what;
  e += largest;
  const Eigen::AlignedBox3d b = footprint_bounds(dataset.spec, all, config.carve.region);
  if (!b.isEmpty()) {
    map_cells += 2 * std::ceil(b.sizes().x() / config.cell_m + 1) *
                 std::ceil(b.sizes().y() / config.cell_m + 1);
  }
  char what[160];
  std::snprintf(what, sizeof what,
                "elevation maps at %.3g m (%zu swaths, merged and uncorrected): %.3g cells",
                config.cell_m, swaths.size(), map_cells);
  e.add(what, map_cells * sizeof(float), "--resolution");
  return e;
}

namespace {

// Known structure poses (issue 26 item 3): each recognised structure matched to the nearest
// known pose of its model (greedily, closest pairs first, each known pose once), then turned
// into a constraint of the adjustment: the swath that passed closest over it (in the navigation
// of the map it was recognised in), the time it did, the vehicle's logged position then and the
// lever from the vehicle to the structure carried back into the logged frame (that map turned
// its rays by its heading correction: T_map_vehicle·T_logged_vehicle⁻¹).
void add_known_structures(const Dataset& dataset, const MapSurveyConfig& config,
                          MapSurveyResult& result, AbsoluteConstraints& absolute) {
  if (config.recognised.empty() || config.known_poses.empty()) {
    for (const RecognisedStructure& r : config.recognised) {
      result.recognised_unmatched.push_back(r.index);
    }
    return;
  }
  struct Pair {
    double d;
    std::size_t r, k;
  };
  std::vector<Pair> pairs;
  for (std::size_t r = 0; r < config.recognised.size(); ++r) {
    for (std::size_t k = 0; k < config.known_poses.size(); ++k) {
      if (config.recognised[r].model != config.known_poses[k].model) continue;
      const double d =
          (config.recognised[r].p_map - config.known_poses[k].p_world).head<2>().norm();
      if (d <= config.known_pose_match_m) pairs.push_back({d, r, k});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
  std::vector<bool> r_used(config.recognised.size(), false), k_used(config.known_poses.size());
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Pair& p : pairs) {
    if (r_used[p.r] || k_used[p.k]) continue;
    r_used[p.r] = k_used[p.k] = true;
    matches.emplace_back(p.r, p.k);
  }
  for (std::size_t r = 0; r < config.recognised.size(); ++r) {
    if (!r_used[r]) result.recognised_unmatched.push_back(config.recognised[r].index);
  }
  std::sort(matches.begin(), matches.end());
  const Trajectory& map_nav =
      config.recognised_navigation.empty() ? dataset.navigation : config.recognised_navigation;
  for (const auto& [r, k] : matches) {
    const RecognisedStructure& rec = config.recognised[r];
    const KnownStructurePose& known = config.known_poses[k];
    // The frame of a swath whose vehicle passed closest over the structure, in the map's frame.
    int best_swath = -1;
    double best_d = std::numeric_limits<double>::infinity(), best_t = 0;
    for (std::size_t s = 0; s < result.swaths.size(); ++s) {
      for (int i = result.swaths[s].first_frame; i <= result.swaths[s].last_frame; ++i) {
        const double t = dataset.frames[i].timestamp;
        const double d = (map_nav.interpolate(t).translation() - rec.p_map).head<2>().norm();
        if (d < best_d) {
          best_d = d;
          best_swath = static_cast<int>(s);
          best_t = t;
        }
      }
    }
    const Eigen::Isometry3d T_map = map_nav.interpolate(best_t);
    const Eigen::Isometry3d T_logged = dataset.navigation.interpolate(best_t);
    const Eigen::Matrix3d R_map_logged = T_map.linear() * T_logged.linear().transpose();
    AbsoluteFix a;
    a.time = best_t;
    a.p_world = known.p_world;
    a.has_z = false;
    a.sigma_m = config.known_pose_sigma_m;
    a.line = rec.index;
    a.name = known.id.empty() ? known.model : known.id;
    a.p_logged = T_logged.translation();
    a.lever = R_map_logged.transpose() * (rec.p_map - T_map.translation());
    a.swath_a = a.swath_b = best_swath;
    a.time_a = a.time_b = best_t;
    MapSurveyResult::KnownPoseMatch m;
    m.model = rec.model;
    m.id = a.name;
    m.recognised_index = rec.index;
    m.p_map = rec.p_map;
    m.p_world = known.p_world;
    m.swath = best_swath;
    m.time = best_t;
    m.constraint = absolute.fixes.size();
    result.known_matches.push_back(m);
    absolute.fixes.push_back(a);
  }
}

}  // namespace

namespace {

// ---------------------------------------------------------------------------------------------
// The stages of map_survey (thesis sec. 6.2), in the order it runs them (docs/design.md, "Field
// mapping: the stages of map_survey"): carve each swath (on MPI ranks or here), map each swath,
// register ties, place the ties and fixes in time, adjust the navigation, score it against a
// simulated truth, correct the navigation, merge the swaths, score the structures, write the
// record. Each stage reads what the ones before it returned; map_survey reads as that list.

// Stage 1: one swath carved on its own (space carving, thesis ch. 4): the cost of field mapping,
// the part spread over MPI ranks.
PointCloud carve_swath(const Dataset& dataset, const MapSurveyConfig& config,
                       const std::vector<std::pair<int, int>>& ranges, int s, Progress& bar) {
  Carver carver(dataset.spec, config.carve, dataset.noise);
  integrate_frames(carver, dataset, static_cast<std::size_t>(ranges[s].first),
                   static_cast<std::size_t>(ranges[s].second), &bar);
  PointCloud cloud = carver.finalize();
  require(!cloud.empty(), fmt::format("field mapping: swath {} (frames {}–{}) reconstructs to "
                                      "no point: is the seabed within the sonar's range?",
                                      s, ranges[s].first, ranges[s].second));
  return cloud;
}

// Swath clouds carved ahead of mapping (under MPI), with their carving times.
struct CarvedSwaths {
  std::vector<PointCloud> clouds;  // by swath; empty where not carved ahead
  std::vector<double> seconds;     // by swath, 0 where not carved ahead
};

// Stage 1 under MPI: rank r carves the swaths s ≡ r (mod ranks) and sends their clouds to rank 0,
// which does everything else (registration needs every swath) and alone writes the output.
// Returns false on the other ranks: their part is done. A rank's error is raised on rank 0 after
// the exchange (and on that rank), so that no rank hangs.
bool carve_swaths_on_ranks(const Dataset& dataset, const MapSurveyConfig& config,
                           const std::vector<std::pair<int, int>>& ranges, const MpiSession& mpi,
                           Progress& bar, CarvedSwaths& carved) {
  const int num_swaths = static_cast<int>(ranges.size());
  const int rank = mpi.rank(), ranks = mpi.size();
  std::string error;
  std::vector<int> mine;
  try {
    for (int s = rank; s < num_swaths; s += ranks) {
      const auto t0 = std::chrono::steady_clock::now();
      carved.clouds[s] = carve_swath(dataset, config, ranges, s, bar);
      carved.seconds[s] = seconds_since(t0);
      mine.push_back(s);
    }
  } catch (const Error& e) {
    error = e.what();  // reported by rank 0 after the exchange: the others must not hang
  }
  const std::vector<std::string> all =
      mpi.gather_to_root(pack_swaths(error, mine, carved.clouds, carved.seconds));
  if (rank != 0) {
    if (!error.empty()) throw Error(error);
    return false;
  }
  for (std::size_t r = 0; r < all.size(); ++r) {
    if (r == 0) continue;  // rank 0's own clouds are already here
    const std::string e = unpack_swaths(all[r], carved.clouds, carved.seconds);
    if (error.empty() && !e.empty()) error = e;
  }
  if (!error.empty()) throw Error(error);
  for (int s = 0; s < num_swaths; ++s) {  // the other ranks' frames, done
    if (s % ranks != 0) bar.add(static_cast<std::size_t>(ranges[s].second - ranges[s].first + 1));
  }
  return true;
}

// What stage 2 keeps of each swath for the stages after it.
struct SwathMaps {
  std::vector<ElevationMap> maps;               // the swath's elevation map (sec. 6.2.1)
  std::vector<SwathTrack> tracks;               // its straight track, to time its points
  std::vector<std::vector<SwathPiece>> pieces;  // the drift method's pieces
};

// Stage 2: each swath on its own: carved (one process: here, one swath in memory at a time;
// MPI: taken from its rank), mapped, written to swaths/, then let go of (memory follows a swath).
// Appends each swath's SwathInfo to `swaths`.
SwathMaps map_swaths(const Dataset& dataset, const MapSurveyConfig& config,
                     const std::vector<std::pair<int, int>>& ranges, bool carved_ahead,
                     CarvedSwaths& carved, Progress& bar, const ElevationMapConfig& map_cfg,
                     const fs::path& tmp, std::vector<SwathInfo>& swaths) {
  SwathMaps m;
  const int num_swaths = static_cast<int>(ranges.size());
  for (int s = 0; s < num_swaths; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    SwathInfo info;
    info.first_frame = ranges[s].first;
    info.last_frame = ranges[s].second;
    info.t0 = dataset.frames[info.first_frame].timestamp;
    info.t1 = dataset.frames[info.last_frame].timestamp;
    const PointCloud cloud =
        carved_ahead ? std::move(carved.clouds[s]) : carve_swath(dataset, config, ranges, s, bar);
    carved.clouds[s] = PointCloud{};
    ElevationMap map = elevation_map_from_points(cloud, map_cfg);
    m.tracks.push_back(make_track(dataset, info.first_frame, info.last_frame));
    if (config.method == SwathAdjustMethod::Drift) {
      m.pieces.push_back(cut_pieces(cloud, m.tracks.back(), config.piece_m, map_cfg));
    }
    info.points = cloud.size();
    info.map_cells = map.num_valid();
    const std::string stem = fmt::format("swaths/swath_{:02d}", s);
    write_ply((tmp / (stem + ".ply")).string(), cloud);
    write_elevation_geotiff((tmp / (stem + ".tif")).string(), map);
    write_elevation_png((tmp / (stem + ".png")).string(), map);
    info.seconds = seconds_since(t0) + carved.seconds[s];
    swaths.push_back(info);
    m.maps.push_back(std::move(map));
  }
  return m;
}

// Stage 3: ties between swath maps (sec. 6.2.2.1, eq. 6.1–6.2): every pair whose maps can overlap
// (global), consecutive pairs only (the thesis), or each piece of the later swath against the
// whole of the earlier one, timed where each swath passed over it (drift).
std::vector<SwathTie> register_ties(const MapSurveyConfig& config, const SwathMaps& m) {
  std::vector<SwathTie> ties;
  const int num_swaths = static_cast<int>(m.maps.size());
  for (int a = 0; a < num_swaths; ++a) {
    for (int b = a + 1; b < num_swaths; ++b) {
      if (config.method == SwathAdjustMethod::Consecutive && b != a + 1) continue;
      if (!maps_may_overlap(m.maps[a], m.maps[b], config.registration.search_m)) continue;
      if (config.method == SwathAdjustMethod::Drift) {
        // Each piece of b against the whole of a, timed where each swath passed over it.
        for (const SwathPiece& piece : m.pieces[b]) {
          if (!maps_may_overlap(m.maps[a], piece.map, config.registration.search_m)) continue;
          SwathTie tie;
          try {
            tie = register_elevation_maps(m.maps[a], piece.map, config.registration);
          } catch (const Error&) {
            continue;  // too little overlap: no tie
          }
          tie.reference = a;
          tie.moving = b;
          tie.time_moving = piece.time;
          tie.time_reference = m.tracks[a].time_at(m.tracks[a].along(piece.centre));
          ties.push_back(tie);
        }
        continue;
      }
      SwathTie tie;
      try {
        tie = register_elevation_maps(m.maps[a], m.maps[b], config.registration);
      } catch (const Error& e) {
        if (config.method == SwathAdjustMethod::Consecutive) {
          throw Error(fmt::format("field mapping: swaths {} and {}: {}", a, b, e.what()));
        }
        continue;  // too little overlap: no tie
      }
      tie.reference = a;
      tie.moving = b;
      ties.push_back(tie);
    }
  }
  return ties;
}

// Stage 3, continued: where each swath's vehicle was when it passed abeam of a tie (the drift
// method's pieces carry the times; a whole-swath tie is taken at the middle of the two maps'
// common extent): the navigation model with absolute references scales the vehicle's
// displacements, not the sonar's rays (SwathTie::nav_separation).
void set_nav_separations(const Dataset& dataset, const SwathMaps& m, std::vector<SwathTie>& ties) {
  for (SwathTie& tie : ties) {
    double ta = tie.time_reference, tb = tie.time_moving;
    if (!std::isfinite(ta) || !std::isfinite(tb)) {
      const ElevationMap &A = m.maps[tie.reference], &B = m.maps[tie.moving];
      const Eigen::Vector2d lo(
          std::max(A.origin_xy.x(), B.origin_xy.x()),
          std::max(A.origin_xy.y() - A.rows * A.cell_m, B.origin_xy.y() - B.rows * B.cell_m));
      const Eigen::Vector2d hi(
          std::min(A.origin_xy.x() + A.cols * A.cell_m, B.origin_xy.x() + B.cols * B.cell_m),
          std::min(A.origin_xy.y(), B.origin_xy.y()));
      const Eigen::Vector2d centre = 0.5 * (lo + hi);
      ta = m.tracks[tie.reference].time_at(m.tracks[tie.reference].along(centre));
      tb = m.tracks[tie.moving].time_at(m.tracks[tie.moving].along(centre));
    }
    tie.nav_separation = (dataset.navigation.interpolate(ta).translation() -
                          dataset.navigation.interpolate(tb).translation())
                             .head<2>();
  }
}

// Stage 4: absolute fixes (issue 26), each tied to the swath correction at its time as the
// corrected navigation interpolates it (correction_at below): the swath's own within it, the two
// swaths' across a turn, the first's before and the last's after. Fixes outside the survey's time
// span are counted in `result` and left out.
void add_position_fixes(const Dataset& dataset, const MapSurveyConfig& config,
                        MapSurveyResult& result, AbsoluteConstraints& absolute) {
  if (config.fixes.empty()) return;
  const int num_swaths = static_cast<int>(result.swaths.size());
  result.fixes_given = config.fixes.size();
  const double t_first = dataset.frames.front().timestamp;
  const double t_last = dataset.frames.back().timestamp;
  const auto& sw = result.swaths;
  for (const PositionFix& f : config.fixes) {
    if (f.time < t_first || f.time > t_last) {
      ++result.fixes_outside;
      continue;
    }
    AbsoluteFix a;
    a.time = f.time;
    a.p_world = f.p;
    a.has_z = f.has_z;
    a.sigma_m = f.sigma_m;
    a.line = f.line;
    a.p_logged = dataset.navigation.interpolate(f.time).translation();
    const double t = f.time;
    a.swath_a = a.swath_b = num_swaths - 1;
    a.time_a = a.time_b = std::min(t, sw.back().t1);
    if (t <= sw.front().t0) {
      a.swath_a = a.swath_b = 0;
      a.time_a = a.time_b = sw.front().t0;
    } else {
      for (int s = 0; s + 1 < num_swaths; ++s) {
        if (t <= sw[s].t1) {
          a.swath_a = a.swath_b = s;
          a.time_a = a.time_b = t;
          break;
        }
        if (t < sw[s + 1].t0) {
          a.swath_a = s;
          a.swath_b = s + 1;
          a.time_a = sw[s].t1;
          a.time_b = sw[s + 1].t0;
          a.weight_b = (t - sw[s].t1) / std::max(1e-12, sw[s + 1].t0 - sw[s].t1);
          break;
        }
      }
    }
    absolute.fixes.push_back(a);
  }
  require(!absolute.fixes.empty(),
          fmt::format("field mapping: all {} fixes{} lie outside the survey's time span [{}, "
                      "{}] s: are they on the navigation's clock?",
                      config.fixes.size(),
                      config.fixes_source.empty() ? "" : " of '" + config.fixes_source + "'",
                      t_first, t_last));
}

// Stage 4: the absolute constraints of the adjustment: position fixes, then known structure
// poses (add_known_structures).
AbsoluteConstraints absolute_constraints(const Dataset& dataset, const MapSurveyConfig& config,
                                         MapSurveyResult& result) {
  AbsoluteConstraints absolute;
  absolute.pivot = dataset.navigation.poses.front().translation();
  absolute.estimate_scale_heading = config.fix_scale_heading;
  absolute.gate_sigma = config.fix_gate_sigma;
  add_position_fixes(dataset, config, result, absolute);
  add_known_structures(dataset, config, result, absolute);
  return absolute;
}

// The drift method's timing of each swath: its time span, speed along its track and the track
// length of the turn to the next swath.
std::vector<SwathTiming> swath_timing(const Dataset& dataset, const std::vector<SwathInfo>& swaths,
                                      const std::vector<SwathTrack>& tracks) {
  const int num_swaths = static_cast<int>(swaths.size());
  std::vector<SwathTiming> timing;
  for (int s = 0; s < num_swaths; ++s) {
    SwathTiming w;
    w.t0 = swaths[s].t0;
    w.t1 = swaths[s].t1;
    w.speed_mps = w.t1 > w.t0 ? tracks[s].length() / (w.t1 - w.t0) : 0.0;
    if (s + 1 < num_swaths) {  // the track length of the turn to the next swath
      for (int i = swaths[s].last_frame; i < swaths[s + 1].first_frame; ++i) {
        w.gap_to_next_m +=
            (dataset.T_world_sonar(i + 1).translation() - dataset.T_world_sonar(i).translation())
                .head<2>()
                .norm();
      }
    }
    timing.push_back(w);
  }
  return timing;
}

// Stage 5: the navigation adjusted to the ties (and the absolute constraints, when any): the
// thesis' accumulation of consecutive ties, one robust least-squares adjustment of every tie
// (global), or with a drift rate per swath (drift).
SwathAdjustment adjust_navigation(const Dataset& dataset, const MapSurveyConfig& config,
                                  const MapSurveyResult& result, const SwathMaps& m,
                                  const AbsoluteConstraints* absolute) {
  const int num_swaths = static_cast<int>(result.swaths.size());
  if (config.method == SwathAdjustMethod::Drift) {
    return adjust_swaths_drift(swath_timing(dataset, result.swaths, m.tracks), result.ties,
                               config.adjustment, absolute);
  }
  if (config.method == SwathAdjustMethod::Consecutive) {
    return accumulate_consecutive(num_swaths, result.ties);
  }
  return adjust_swaths(num_swaths, result.ties, config.adjustment, 0, absolute);
}

// What the correction adds to the logged navigation of swath s at time t: the swath correction
// and, with fixes, the navigation model (scale error, heading bias).
Eigen::Vector3d nav_delta(const Dataset& dataset, const SwathAdjustment& adj, int s, double t) {
  if (!adj.has_fixes) return adj.correction(s, t);
  const Eigen::Vector3d p = dataset.navigation.interpolate(t).translation();
  return adj.corrected(s, t, p) - p;
}

// Stage 6 (simulated drift): each swath's navigation error before and after correction, from the
// true trajectory the simulator kept: the exact correction (the mean over the swath's frames of
// true − logged position) and the mean per-frame errors, relative to the error where swath 0
// starts (the gauge every method shares); with fixes the world frame is the gauge: nothing is
// taken out. Returns that gauge error e0.
Eigen::Vector3d score_swath_navigation(const Dataset& dataset, const Trajectory& truth,
                                       const SwathAdjustment& adj, std::vector<SwathInfo>& swaths) {
  const int num_swaths = static_cast<int>(swaths.size());
  std::vector<Eigen::Vector3d> err(static_cast<std::size_t>(num_swaths));
  for (int s = 0; s < num_swaths; ++s) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    const SwathInfo& w = swaths[s];
    for (int i = w.first_frame; i <= w.last_frame; ++i) {
      const double t = dataset.frames[i].timestamp;
      sum += truth.interpolate(t).translation() - dataset.navigation.interpolate(t).translation();
    }
    err[s] = sum / static_cast<double>(w.last_frame - w.first_frame + 1);
  }
  // Per frame: the navigation's error before and after correction, relative to the error
  // where swath 0 starts (the gauge every method shares).
  // With fixes the world frame is the gauge: nothing is taken out.
  const double t_gauge = swaths[0].t0;
  const Eigen::Vector3d e0 =
      adj.has_fixes ? Eigen::Vector3d::Zero()
                    : Eigen::Vector3d(truth.interpolate(t_gauge).translation() -
                                      dataset.navigation.interpolate(t_gauge).translation());
  for (int s = 0; s < num_swaths; ++s) {
    SwathInfo& w = swaths[s];
    w.has_truth = true;
    w.true_offset = adj.has_fixes ? err[s] : Eigen::Vector3d(err[s] - err[0]);
    for (int i = w.first_frame; i <= w.last_frame; ++i) {
      const double t = dataset.frames[i].timestamp;
      const Eigen::Vector3d e =
          truth.interpolate(t).translation() - dataset.navigation.interpolate(t).translation() - e0;
      const Eigen::Vector3d left = e - nav_delta(dataset, adj, s, t);
      w.error_before += Eigen::Vector2d(e.head<2>().norm(), std::abs(e.z()));
      w.error_after += Eigen::Vector2d(left.head<2>().norm(), std::abs(left.z()));
    }
    w.error_before /= static_cast<double>(w.last_frame - w.first_frame + 1);
    w.error_after /= static_cast<double>(w.last_frame - w.first_frame + 1);
  }
  return e0;
}

// Stage 6, continued: the map's placement in the world, as logged and corrected — the affine
// (fit_alignment) and rigid (fit_rigid_alignment) placements onto the true positions — and the
// errors within it: per swath, means over its frames; over the survey, medians over frames
// (MapSurveyResult::navigation_before/after). e0: score_swath_navigation's gauge.
void score_map_placement(const Dataset& dataset, const Trajectory& truth,
                         const SwathAdjustment& adj, const Eigen::Vector3d& e0,
                         MapSurveyResult& result) {
  const int num_swaths = static_cast<int>(result.swaths.size());
  std::vector<Eigen::Vector3d> logged_p, corrected_p, true_p;
  for (int s = 0; s < num_swaths; ++s) {
    for (int i = result.swaths[s].first_frame; i <= result.swaths[s].last_frame; ++i) {
      const double t = dataset.frames[i].timestamp;
      logged_p.push_back(dataset.navigation.interpolate(t).translation());
      corrected_p.push_back(logged_p.back() + nav_delta(dataset, adj, s, t));
      true_p.push_back(truth.interpolate(t).translation());
    }
  }
  result.has_alignment = true;
  result.alignment_before = fit_alignment(logged_p, true_p);
  result.alignment_after = fit_alignment(corrected_p, true_p);
  result.rigid_before = fit_rigid_alignment(logged_p, true_p);
  result.rigid_after = fit_rigid_alignment(corrected_p, true_p);
  std::vector<double> abs_b, abs_a, rigid_b, rigid_a, affine_b, affine_a, world_b, world_a;
  std::size_t k = 0;
  for (int s = 0; s < num_swaths; ++s) {
    SwathInfo& w = result.swaths[s];
    for (int i = w.first_frame; i <= w.last_frame; ++i, ++k) {
      const Eigen::Vector3d rb = result.rigid_before.apply(logged_p[k]) - true_p[k];
      const Eigen::Vector3d ra = result.rigid_after.apply(corrected_p[k]) - true_p[k];
      const Eigen::Vector3d fb = result.alignment_before.apply(logged_p[k]) - true_p[k];
      const Eigen::Vector3d fa = result.alignment_after.apply(corrected_p[k]) - true_p[k];
      w.rigid_error_before += Eigen::Vector2d(rb.head<2>().norm(), std::abs(rb.z()));
      w.rigid_error_after += Eigen::Vector2d(ra.head<2>().norm(), std::abs(ra.z()));
      w.affine_error_before += Eigen::Vector2d(fb.head<2>().norm(), std::abs(fb.z()));
      w.affine_error_after += Eigen::Vector2d(fa.head<2>().norm(), std::abs(fa.z()));
      rigid_b.push_back(rb.head<2>().norm());
      rigid_a.push_back(ra.head<2>().norm());
      affine_b.push_back(fb.head<2>().norm());
      affine_a.push_back(fa.head<2>().norm());
      const double t = dataset.frames[i].timestamp;
      const Eigen::Vector3d e = true_p[k] - logged_p[k] - e0;
      abs_b.push_back(e.head<2>().norm());
      abs_a.push_back((e - nav_delta(dataset, adj, s, t)).head<2>().norm());
      world_b.push_back((true_p[k] - logged_p[k]).head<2>().norm());
      world_a.push_back((true_p[k] - corrected_p[k]).head<2>().norm());
    }
    const double n = static_cast<double>(w.last_frame - w.first_frame + 1);
    w.rigid_error_before /= n;
    w.rigid_error_after /= n;
    w.affine_error_before /= n;
    w.affine_error_after /= n;
  }
  result.navigation_before = {median_of(abs_b), median_of(rigid_b), median_of(affine_b),
                              median_of(world_b)};
  result.navigation_after = {median_of(abs_a), median_of(rigid_a), median_of(affine_a),
                             median_of(world_a)};
}

// Stage 7: the corrected navigation's swath correction at time t: a swath's offset over its time
// span, linear across the turns between swaths, held before the first and after the last.
Eigen::Vector3d correction_at(const std::vector<SwathInfo>& sw, const SwathAdjustment& adj,
                              double t) {
  const int num_swaths = static_cast<int>(sw.size());
  if (t <= sw.front().t0) return adj.correction(0, sw.front().t0);
  for (int s = 0; s + 1 < num_swaths; ++s) {
    if (t <= sw[s].t1) return adj.correction(s, t);
    if (t < sw[s + 1].t0) {
      const double w = (t - sw[s].t1) / std::max(1e-12, sw[s + 1].t0 - sw[s].t1);
      return (1 - w) * adj.correction(s, sw[s].t1) + w * adj.correction(s + 1, sw[s + 1].t0);
    }
  }
  return adj.correction(num_swaths - 1, std::min(t, sw.back().t1));
}

// The attitude's correction with fixes: the turn by minus the heading bias, about z.
Eigen::Matrix3d heading_correction(const SwathAdjustment& adj) {
  return Eigen::AngleAxisd(-adj.heading_bias_rad(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// Stage 7: the corrected navigation: with fixes, the navigation model first (positions scaled and
// turned about the pivot, the attitude turned by the heading bias's correction), then the swath
// correction at each pose's time (correction_at).
Trajectory correct_navigation(const Dataset& dataset, const std::vector<SwathInfo>& swaths,
                              const SwathAdjustment& adj) {
  const Eigen::Matrix3d R_heading = heading_correction(adj);
  Trajectory corrected = dataset.navigation;
  for (std::size_t k = 0; k < corrected.size(); ++k) {
    Eigen::Isometry3d& T = corrected.poses[k];
    T.translation() = adj.apply_navigation_model(T.translation()) +
                      correction_at(swaths, adj, corrected.times[k]);
    if (adj.has_fixes) T.linear() = R_heading * T.linear();
  }
  return corrected;
}

// The merged field's clouds: as corrected and as logged.
struct MergedField {
  PointCloud merged, logged;
};

// Stage 8: the merged field, as logged and corrected (the swath clouds read back from swaths/,
// one at a time): each point moved by the correction at the time the vehicle passed over it
// (constant but for drift); with fixes, the vehicle's corrected position plus the ray from it
// turned by the heading correction (the sonar's ranges carry no DVL scale).
MergedField merge_swaths(const Dataset& dataset, const SwathAdjustment& adj,
                         const std::vector<SwathTrack>& tracks, const fs::path& tmp) {
  const Eigen::Matrix3d R_heading = heading_correction(adj);
  MergedField f;
  const int num_swaths = static_cast<int>(tracks.size());
  for (int s = 0; s < num_swaths; ++s) {
    const PointCloud c = read_ply((tmp / fmt::format("swaths/swath_{:02d}.ply", s)).string());
    for (const Eigen::Vector3f& p : c.points) {
      // The correction at the time the vehicle passed over the point (constant but for drift).
      const double t = tracks[s].time_at(tracks[s].along(p.head<2>().cast<double>()));
      f.logged.points.push_back(p);
      if (!adj.has_fixes) {
        f.merged.points.push_back(p + adj.correction(s, t).cast<float>());
        continue;
      }
      // The vehicle's corrected position, and the ray from it turned by the heading correction
      // (the sonar's ranges carry no DVL scale).
      const Eigen::Vector3d n = dataset.navigation.interpolate(t).translation();
      f.merged.points.push_back(
          (adj.corrected(s, t, n) + R_heading * (p.cast<double>() - n)).cast<float>());
    }
  }
  return f;
}

// Stage 8, continued: merged.ply and the merged elevation maps (merged.tif, merged.png,
// merged_uncorrected.png).
void write_merged_field(const MergedField& f, const ElevationMapConfig& map_cfg,
                        const fs::path& tmp) {
  write_ply((tmp / "merged.ply").string(), f.merged);
  const ElevationMap merged_map = elevation_map_from_points(f.merged, map_cfg);
  write_elevation_geotiff((tmp / "merged.tif").string(), merged_map);
  write_elevation_png((tmp / "merged.png").string(), merged_map);
  write_elevation_png((tmp / "merged_uncorrected.png").string(),
                      elevation_map_from_points(f.logged, map_cfg));
}

// Stage 9 (simulated site): the structures against their CAD (eval/per_object.hpp), as logged
// and corrected, each map placed in the world first by the affine alignment (when the true
// navigation tells how).
std::vector<StructureEval> score_structures(const Dataset& dataset, const MapSurveyResult& result,
                                            const MergedField& f) {
  std::vector<StructureEval> out;
  const std::vector<SceneObject> objects = read_truth(dataset.root);
  const EvalConfig eval_cfg;
  // Each map placed in the world first (when the true navigation tells how).
  auto placed = [&](const PointCloud& c, const MapAlignment& a) {
    if (!result.has_alignment) return c;
    PointCloud out;
    out.points.reserve(c.size());
    for (const Eigen::Vector3f& p : c.points) {
      out.points.push_back(a.apply(p.cast<double>()).cast<float>());
    }
    return out;
  };
  const std::vector<ObjectEval> before =
      evaluate_structures(placed(f.logged, result.alignment_before), objects, eval_cfg);
  const std::vector<ObjectEval> after =
      evaluate_structures(placed(f.merged, result.alignment_after), objects, eval_cfg);
  for (std::size_t k = 0; k < after.size(); ++k) {
    StructureEval e;
    e.name = after[k].name;
    for (const SceneObject& o : objects) {
      if (o.name == e.name) e.kind = o.kind;
    }
    e.before = before[k].result;
    e.after = after[k].result;
    out.push_back(e);
  }
  return out;
}

// Stage 10, the record (summary.json, ties.json): one function per block.

// Every tie, whether the adjustment used it and its residual there.
nlohmann::json ties_json(const MapSurveyResult& result) {
  nlohmann::json ties = nlohmann::json::array();
  for (std::size_t k = 0; k < result.ties.size(); ++k) {
    const SwathTie& t = result.ties[k];
    nlohmann::json j = {{"reference", t.reference},
                        {"moving", t.moving},
                        {"shift_m", vec3(t.t)},
                        {"score_m", t.score_m},
                        {"overlap_cells", t.overlap_cells},
                        {"confidence", t.confidence},
                        {"used", static_cast<bool>(result.adjustment.tie_used[k])},
                        {"residual_m", result.adjustment.tie_residual_m[k]},
                        {"seconds", t.seconds}};
    if (std::isfinite(t.time_moving)) {  // the drift method's pieces: where they were measured
      j["time_reference_s"] = t.time_reference;
      j["time_moving_s"] = t.time_moving;
    }
    ties.push_back(j);
  }
  return ties;
}

// Every swath: its frames, size, correction and, with truth, its errors.
nlohmann::json swaths_json(const MapSurveyConfig& config, const MapSurveyResult& result) {
  nlohmann::json swaths = nlohmann::json::array();
  for (const SwathInfo& s : result.swaths) {
    nlohmann::json j = {{"frames", {s.first_frame, s.last_frame}},
                        {"time_s", {s.t0, s.t1}},
                        {"points", s.points},
                        {"map_cells", s.map_cells},
                        {"offset_m", vec3(s.offset)},
                        {"seconds", s.seconds}};
    if (config.method == SwathAdjustMethod::Drift) j["rate_mps"] = {s.rate.x(), s.rate.y()};
    if (s.has_truth) {
      // Before: the drift left as logged; after: what the correction leaves (horizontal, up),
      // means over the swath's frames.
      j["true_offset_m"] = vec3(s.true_offset);
      j["error_before_m"] = {s.error_before.x(), s.error_before.y()};
      j["error_after_m"] = {s.error_after.x(), s.error_after.y()};
      j["rigid_error_before_m"] = {s.rigid_error_before.x(), s.rigid_error_before.y()};
      j["rigid_error_after_m"] = {s.rigid_error_after.x(), s.rigid_error_after.y()};
      j["affine_error_before_m"] = {s.affine_error_before.x(), s.affine_error_before.y()};
      j["affine_error_after_m"] = {s.affine_error_after.x(), s.affine_error_after.y()};
    }
    swaths.push_back(j);
  }
  return swaths;
}

// The structures' scores against their CAD, before and after correction.
nlohmann::json structures_json(const MapSurveyResult& result) {
  nlohmann::json structures = nlohmann::json::array();
  auto scores = [](const EvalResult& r) {
    return nlohmann::json{{"points", r.num_points},
                          {"median_error_m", r.median_error},
                          {"mean_error_m", r.mean_error},
                          {"coverage", r.coverage},
                          {"outliers", r.outliers}};
  };
  for (const StructureEval& e : result.structures) {
    structures.push_back({{"name", e.name},
                          {"kind", to_string(e.kind)},
                          {"before", scores(e.before)},
                          {"after", scores(e.after)}});
  }
  return structures;
}

// "alignment": the affine placement the structures are scored after (its scale is what it
// hides); "rigid_alignment": the turn and shift the within-map errors are measured after;
// "navigation_error": the medians over frames.
void add_truth_json(const MapSurveyResult& result, nlohmann::json& summary) {
  auto alignment = [](const MapAlignment& a) {
    return nlohmann::json{
        {"matrix", {{a.M(0, 0), a.M(0, 1)}, {a.M(1, 0), a.M(1, 1)}}},
        {"shift_m", {a.b.x(), a.b.y(), a.dz}},
        {"scale", a.scale()},
        {"stretch", a.stretch()},
        {"turn_deg", std::atan2(a.M(1, 0) - a.M(0, 1), a.M(0, 0) + a.M(1, 1)) * 180 / M_PI}};
  };
  summary["alignment"] = {{"before", alignment(result.alignment_before)},
                          {"after", alignment(result.alignment_after)}};
  summary["rigid_alignment"] = {{"before", alignment(result.rigid_before)},
                                {"after", alignment(result.rigid_after)}};
  auto nav = [](const NavigationError& e) {
    return nlohmann::json{{"absolute_m", e.absolute_m},
                          {"world_m", e.world_m},
                          {"within_map_m", e.rigid_m},
                          {"after_affine_m", e.affine_m}};
  };
  summary["navigation_error"] = {{"before", nav(result.navigation_before)},
                                 {"after", nav(result.navigation_after)},
                                 {"statistic", "median over frames, horizontal"}};
}

// The absolute references: what was used, what was rejected (and why: its residual in σ), and
// the navigation model they made observable.
void add_fixes_json(const MapSurveyConfig& config, const MapSurveyResult& result,
                    nlohmann::json& summary) {
  const SwathAdjustment& adj = result.adjustment;
  nlohmann::json rejected = nlohmann::json::array();
  std::size_t n_rejected = 0, n_fixes = 0;
  double sum_sq = 0;
  for (const FixReport& f : adj.fixes) {
    if (!f.name.empty()) continue;  // a known structure pose: add_known_poses_json
    ++n_fixes;
    if (f.rejected) {
      ++n_rejected;
      rejected.push_back({{"time_s", f.time},
                          {"line", f.line},
                          {"residual_m", f.residual_m},
                          {"residual_sigma", f.normalized}});
    } else {
      sum_sq += f.normalized * f.normalized;
    }
  }
  const std::size_t used = n_fixes - n_rejected;
  auto num_or_null = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; };
  if (!config.fixes.empty()) {
    summary["fixes"] = {
        {"file", config.fixes_source},
        {"given", result.fixes_given},
        {"outside_time_span", result.fixes_outside},
        {"used", used},
        {"rejected", n_rejected},
        {"gate_sigma", config.fix_gate_sigma},
        {"rounds", adj.fix_rounds},
        {"rms_residual_sigma", used ? std::sqrt(sum_sq / static_cast<double>(used)) : 0.0},
        {"rejected_fixes", rejected}};
  }
  summary["navigation_model"] = {
      {"estimated", adj.estimated_scale_heading},
      {"scale_error", adj.scale_error()},
      {"scale_error_sigma", num_or_null(adj.scale_error_sigma)},
      {"heading_bias_deg", adj.heading_bias_rad() * 180 / M_PI},
      {"heading_bias_sigma_deg", num_or_null(adj.heading_bias_sigma_rad * 180 / M_PI)},
      {"placement_sigma_m",
       {num_or_null(adj.placement_sigma_m.x()), num_or_null(adj.placement_sigma_m.y())}},
      {"pivot_m", vec3(adj.pivot)},
      {"model",
       "p_logged - pivot = (1 + scale_error) R(heading_bias) (p_true - pivot), horizontal; "
       "heading_bias counter-clockwise about z (ENU)"}};
}

// Known structure poses: every match, its residual and whether the gate rejected it.
void add_known_poses_json(const MapSurveyConfig& config, const MapSurveyResult& result,
                          nlohmann::json& summary) {
  nlohmann::json matches = nlohmann::json::array();
  std::size_t n_rejected = 0;
  for (const MapSurveyResult::KnownPoseMatch& m : result.known_matches) {
    const FixReport& f = result.adjustment.fixes.at(m.constraint);
    n_rejected += f.rejected;
    matches.push_back({{"model", m.model},
                       {"known_id", m.id},
                       {"recognised_index", m.recognised_index},
                       {"recognised_m", vec3(m.p_map)},
                       {"known_m", vec3(m.p_world)},
                       {"swath", m.swath},
                       {"time_s", m.time},
                       {"residual_m", f.residual_m},
                       {"residual_sigma", f.normalized},
                       {"rejected", f.rejected}});
  }
  summary["known_poses"] = {{"file", config.known_poses_source},
                            {"placements", config.recognised_source},
                            {"known", config.known_poses.size()},
                            {"recognised", config.recognised.size()},
                            {"matched", result.known_matches.size()},
                            {"used", result.known_matches.size() - n_rejected},
                            {"rejected", n_rejected},
                            {"recognised_unmatched", result.recognised_unmatched},
                            {"sigma_m", config.known_pose_sigma_m},
                            {"match_radius_m", config.known_pose_match_m},
                            {"gate_sigma", config.fix_gate_sigma},
                            {"matches", matches}};
}

// Stage 10: summary.json's content: the settings, swaths, ties and timing, then the blocks that
// apply (truth, fixes, known poses, structures). with_fixes: the adjustment had absolute
// constraints.
nlohmann::json survey_summary(const Dataset& dataset, const MapSurveyConfig& config,
                              const MapSurveyResult& result, const nlohmann::json& ties,
                              bool with_fixes) {
  nlohmann::json summary = {{"dataset", dataset.root.string()},
                            {"method", to_string(config.method)},
                            {"cell_m", config.cell_m},
                            {"voxel_m", config.carve.voxel_size},
                            {"search_m", config.registration.search_m},
                            {"swaths", swaths_json(config, result)},
                            {"ties", ties},
                            {"merged_points", result.merged_points},
                            {"seconds",
                             {{"carving", result.seconds_carving},
                              {"registration", result.seconds_registration},
                              {"total", result.seconds_total}}}};
  if (result.has_alignment) add_truth_json(result, summary);
  if (with_fixes) add_fixes_json(config, result, summary);
  if (!config.known_poses.empty() || !config.recognised.empty()) {
    add_known_poses_json(config, result, summary);
  }
  if (!result.structures.empty()) {
    summary["structures"] = structures_json(result);
    summary["structure_eval"] = {{"coverage_radius_m", EvalConfig().coverage_radius},
                                 {"outlier_radius_m", EvalConfig().outlier_radius}};
  }
  return summary;
}

}  // namespace

// The pipeline of field mapping (thesis sec. 6.2); each stage is a function above, named in
// docs/design.md ("Field mapping: the stages of map_survey").
MapSurveyResult map_survey(const Dataset& dataset, const MapSurveyConfig& config,
                           const fs::path& out_dir, bool progress, const MpiSession* mpi) {
  config.validate();
  const auto t_start = std::chrono::steady_clock::now();
  require(!fs::exists(out_dir), "field mapping: '" + out_dir.string() +
                                    "' already exists: choose a new output directory");
  const std::vector<std::pair<int, int>> ranges = split_swaths(dataset, config.split);
  const int num_swaths = static_cast<int>(ranges.size());
  require(num_swaths >= 2, "field mapping: the survey has one swath only (frames " +
                               std::to_string(ranges[0].first) + "–" +
                               std::to_string(ranges[0].second) +
                               "): registration needs at least two overlapping swaths");

  // 1. Carving: under MPI, every rank's swaths now; in one process, each swath as step 2 maps it.
  const int rank = mpi ? mpi->rank() : 0, ranks = mpi ? mpi->size() : 1;
  std::size_t total_frames = 0;
  for (const auto& r : ranges) total_frames += static_cast<std::size_t>(r.second - r.first + 1);
  Progress bar("map: carving swaths", total_frames, progress && rank == 0);
  CarvedSwaths carved;
  carved.clouds.resize(static_cast<std::size_t>(num_swaths));
  carved.seconds.assign(static_cast<std::size_t>(num_swaths), 0.0);
  const auto t_carve = std::chrono::steady_clock::now();
  if (ranks > 1 && !carve_swaths_on_ranks(dataset, config, ranges, *mpi, bar, carved)) {
    return MapSurveyResult{};  // not rank 0: its swaths are sent
  }

  AtomicPath out(out_dir);
  const fs::path tmp = out.temp();
  fs::create_directories(tmp / "swaths");
  MapSurveyResult result;
  ElevationMapConfig map_cfg;
  map_cfg.cell_m = config.cell_m;
  // 2. Each swath on its own: carve, map, write, let go of the carver.
  const SwathMaps maps =
      map_swaths(dataset, config, ranges, ranks > 1, carved, bar, map_cfg, tmp, result.swaths);
  bar.finish();
  result.seconds_carving = seconds_since(t_carve);

  // 3. Ties between the swath maps, placed in time on the logged navigation.
  const auto t_reg = std::chrono::steady_clock::now();
  result.ties = register_ties(config, maps);
  set_nav_separations(dataset, maps, result.ties);
  // 4. Absolute constraints: position fixes and known structure poses.
  const AbsoluteConstraints absolute = absolute_constraints(dataset, config, result);
  const bool with_fixes = !absolute.fixes.empty();
  // 5. The navigation adjusted: the swath corrections.
  result.adjustment =
      adjust_navigation(dataset, config, result, maps, with_fixes ? &absolute : nullptr);
  result.seconds_registration = seconds_since(t_reg);
  const SwathAdjustment& adj = result.adjustment;
  for (int s = 0; s < num_swaths; ++s) {
    result.swaths[s].offset = adj.correction(s, result.swaths[s].t0);
    if (static_cast<std::size_t>(s) < adj.rates.size()) result.swaths[s].rate = adj.rates[s];
  }

  // 6. Simulated drift: the navigation scored against the true trajectory the simulator kept.
  const fs::path truth_nav = dataset.truth_dir() / "navigation.tum";
  if (fs::exists(truth_nav)) {
    const Trajectory truth = read_tum(truth_nav.string());
    const Eigen::Vector3d e0 = score_swath_navigation(dataset, truth, adj, result.swaths);
    score_map_placement(dataset, truth, adj, e0, result);
  }

  // 7. Corrected navigation.
  write_tum((tmp / "navigation_corrected.tum").string(),
            correct_navigation(dataset, result.swaths, adj));

  // 8. Merged field, as logged and corrected.
  const MergedField merged = merge_swaths(dataset, adj, maps.tracks, tmp);
  result.merged_points = merged.merged.size();
  write_merged_field(merged, map_cfg, tmp);

  // 9. Simulated site: the structures against their CAD, as logged and corrected.
  if (fs::exists(dataset.truth_dir() / "scene.yaml")) {
    result.structures = score_structures(dataset, result, merged);
  }

  // 10. The record.
  const nlohmann::json ties = ties_json(result);
  write_text_file((tmp / "ties.json").string(), ties.dump(2) + "\n");
  result.seconds_total = seconds_since(t_start);
  const nlohmann::json summary = survey_summary(dataset, config, result, ties, with_fixes);
  write_text_file((tmp / "summary.json").string(), summary.dump(2) + "\n");
  out.commit();
  return result;
}

}  // namespace sonar3d
