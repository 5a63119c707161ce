#include "sonar3d/mapping/online.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/navigation.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

namespace {

constexpr std::size_t kLatencyWindow = 1000;  // frames in the push latency statistics

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Quantile q of `v` (copied), by the nearest rank.
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::min<double>(
      static_cast<double>(v.size() - 1), std::ceil(q * static_cast<double>(v.size())) - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

const char* frame_drop_name(FrameDrop d) {
  static constexpr const char* kNames[] = {"none",    "wrong_size", "bad_pose",       "no_pose",
                                           "late",    "queue_full", "outside_window", "memory",
                                           "bad_time"};  // by FrameDrop
  return enum_name(kNames, d);
}

void OnlineMapConfig::validate() const {
  carve.validate();
  require(std::isfinite(window_m) && window_m >= 0,
          "parameter 'online.window_m' must be >= 0 m (0 = no rolling window), got " +
              std::to_string(window_m));
  require(std::isfinite(window_step_m) && window_step_m >= 0,
          "parameter 'online.window_step_m' must be >= 0 m, got " + std::to_string(window_step_m));
  require(window_m == 0 || window_step_m <= window_m,
          "parameter 'online.window_step_m' must not exceed online.window_m");
  require(std::isfinite(max_memory_bytes) && max_memory_bytes >= 0,
          "parameter 'online.max_memory_bytes' must be >= 0 (0 = no limit)");
  require(
      std::isfinite(max_lateness_s) && max_lateness_s >= 0,
      "parameter 'online.max_lateness_s' must be >= 0 s, got " + std::to_string(max_lateness_s));
  require(max_pending_images >= 1, "parameter 'online.max_pending_images' must be >= 1");
  elevation.validate();
}

std::size_t OnlineMapStats::dropped() const {
  return dropped_wrong_size + dropped_bad_pose + dropped_no_pose + dropped_late +
         dropped_queue_full + dropped_outside_window + dropped_memory + dropped_bad_time;
}

std::string OnlineMapStats::to_json() const {
  nlohmann::ordered_json j;
  j["frames_received"] = frames_received;
  j["frames_used"] = frames_used;
  j["frames_pending"] = frames_pending;
  j["out_of_order"] = out_of_order;
  j["dropped"] = {{"wrong_size", dropped_wrong_size}, {"bad_pose", dropped_bad_pose},
                  {"no_pose", dropped_no_pose},       {"late", dropped_late},
                  {"queue_full", dropped_queue_full}, {"outside_window", dropped_outside_window},
                  {"memory", dropped_memory},         {"bad_time", dropped_bad_time}};
  j["navigation_received"] = navigation_received;
  j["navigation_rejected"] = navigation_rejected;
  j["frames_kept"] = frames_kept;
  j["active_voxels"] = active_voxels;
  j["candidate_voxels"] = candidate_voxels;
  j["leaves"] = leaves;
  j["map_bytes"] = map_bytes;
  j["frame_bytes"] = frame_bytes;
  j["points"] = points;
  j["window_moves"] = window_moves;
  j["blocks_written"] = blocks_written;
  j["points_finished"] = points_finished;
  j["frames_evicted"] = frames_evicted;
  j["push_ms"] = {{"last", push_ms_last},
                  {"median", push_ms_median},
                  {"p95", push_ms_p95},
                  {"max", push_ms_max}};
  j["resolve_ms_last"] = resolve_ms_last;
  j["last_resolve"] = {{"full", last_resolve.full},       {"blocks", last_resolve.blocks},
                       {"context", last_resolve.context}, {"frames", last_resolve.frames},
                       {"cached", last_resolve.cached},   {"seconds", last_resolve.seconds}};
  return j.dump(2);
}

struct OnlineMapper::Impl {
  SonarSpec spec;
  OnlineMapConfig cfg;
  std::optional<NoiseImages> noise;
  std::unique_ptr<Carver> carver;
  mutable std::mutex mu;
  OnlineMapStats st;
  Trajectory nav;  // T_world_vehicle, the samples still needed
  struct PendingImage {
    double t;
    SonarImage image;
  };
  std::deque<PendingImage> pending;  // waiting for navigation, in arrival order
  bool any_frame = false;
  double newest_t = 0;  // newest carved frame time
  std::deque<double> push_ms;
  bool window_set = false;
  Eigen::Vector3d window_centre = Eigen::Vector3d::Zero();
  std::size_t next_block = 0;
  // Rolling window: highest z of the finished points per elevation cell (x, y index).
  struct CellHash {
    std::size_t operator()(const std::pair<std::int64_t, std::int64_t>& c) const {
      return static_cast<std::size_t>(c.first) * 73856093u ^
             static_cast<std::size_t>(c.second) * 19349663u;
    }
  };
  std::unordered_map<std::pair<std::int64_t, std::int64_t>, float, CellHash> finished_top;

  Impl(const SonarSpec& s, const OnlineMapConfig& c, std::optional<NoiseImages> n)
      : spec(s), cfg(c), noise(std::move(n)) {}

  void new_carver() { carver = std::make_unique<Carver>(spec, cfg.carve, noise); }

  double window_step() const {
    return cfg.window_step_m > 0 ? cfg.window_step_m : cfg.window_m / 4;
  }

  Eigen::AlignedBox3d window_box(const Eigen::Vector3d& c) const {
    return Eigen::AlignedBox3d(c.array() - cfg.window_m, c.array() + cfg.window_m);
  }

  // Finished points: written as one block file, their heights kept for elevation().
  void finish(const PointCloud& done) {
    if (done.empty()) return;
    st.points_finished += done.size();
    const double c = cfg.elevation.cell_m;
    for (const auto& p : done.points) {
      const std::pair<std::int64_t, std::int64_t> key{
          static_cast<std::int64_t>(std::floor(p.x() / c)),
          static_cast<std::int64_t>(std::floor(p.y() / c))};
      auto [it, fresh] = finished_top.emplace(key, p.z());
      if (!fresh) it->second = std::max(it->second, p.z());
    }
    if (cfg.output_dir.empty()) return;
    fs::create_directories(cfg.output_dir);
    char name[32];
    std::snprintf(name, sizeof name, "block_%06zu.ply", next_block++);
    write_ply((fs::path(cfg.output_dir) / name).string(), done);
    ++st.blocks_written;
  }

  void move_window(const Eigen::Vector3d& p) {
    window_centre = p;
    window_set = true;
    std::size_t dropped = 0;
    const PointCloud done = carver->evict_outside(window_box(p), &dropped);
    ++st.window_moves;
    st.frames_evicted += dropped;
    finish(done);
  }

  void count(FrameDrop d) {
    switch (d) {
      case FrameDrop::None:
        break;
      case FrameDrop::WrongSize:
        ++st.dropped_wrong_size;
        break;
      case FrameDrop::BadPose:
        ++st.dropped_bad_pose;
        break;
      case FrameDrop::NoPose:
        ++st.dropped_no_pose;
        break;
      case FrameDrop::Late:
        ++st.dropped_late;
        break;
      case FrameDrop::QueueFull:
        ++st.dropped_queue_full;
        break;
      case FrameDrop::OutsideWindow:
        ++st.dropped_outside_window;
        break;
      case FrameDrop::Memory:
        ++st.dropped_memory;
        break;
      case FrameDrop::BadTime:
        ++st.dropped_bad_time;
        break;
    }
  }

  FrameDrop check_image(double t, const SonarImage& image) const {
    if (!std::isfinite(t)) return FrameDrop::BadTime;
    if (image.rows != spec.range_bins || image.cols != spec.beams() ||
        image.data.size() != static_cast<std::size_t>(image.rows) * image.cols)
      return FrameDrop::WrongSize;
    return FrameDrop::None;
  }

  // Carves one frame whose image was checked; returns why not when it is dropped (counted).
  FrameDrop carve(double t, const SonarImage& image, const Eigen::Isometry3d& T) {
    FrameDrop d = FrameDrop::None;
    const Eigen::Vector3d p = T.translation();
    if (!T.matrix().allFinite() || !is_rigid(T) ||
        p.cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
      d = FrameDrop::BadPose;
    } else if (any_frame && t < newest_t - cfg.max_lateness_s) {
      d = FrameDrop::Late;
    } else if (cfg.max_memory_bytes > 0 &&
               static_cast<double>(carver->memory_bytes()) > cfg.max_memory_bytes) {
      d = FrameDrop::Memory;
    }
    const bool in_order = !any_frame || t >= newest_t;
    if (d == FrameDrop::None && cfg.window_m > 0 && window_set && !in_order) {
      // An out-of-order frame does not move the window: its footprint must lie inside.
      const Eigen::AlignedBox3d fb(p.array() - spec.r_max, p.array() + spec.r_max);
      if (!window_box(window_centre).contains(fb)) d = FrameDrop::OutsideWindow;
    }
    if (d != FrameDrop::None) {
      count(d);
      return d;
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (cfg.window_m > 0 && in_order &&
        (!window_set || (p - window_centre).cwiseAbs().maxCoeff() > window_step())) {
      move_window(p);
    }
    carver->integrate(image, T, "frame at t = " + std::to_string(t) + " s");
    const double ms = ms_since(t0);
    push_ms.push_back(ms);
    if (push_ms.size() > kLatencyWindow) push_ms.pop_front();
    st.push_ms_last = ms;
    ++st.frames_used;
    if (any_frame && t < newest_t) ++st.out_of_order;
    newest_t = any_frame ? std::max(newest_t, t) : t;
    any_frame = true;
    trim_navigation();
    return FrameDrop::None;
  }

  // Carves the pending images the navigation now brackets (in time order); drops those before
  // its start.
  void drain_pending() {
    if (nav.empty() || pending.empty()) return;
    std::stable_sort(pending.begin(), pending.end(),
                     [](const PendingImage& a, const PendingImage& b) { return a.t < b.t; });
    constexpr double kTol = 1e-6;  // as Trajectory::interpolate
    while (!pending.empty() && pending.front().t <= nav.times.back() + kTol) {
      PendingImage item = std::move(pending.front());
      pending.pop_front();
      if (!frame_inside_navigation(nav, item.t, true, "frame")) {
        count(FrameDrop::NoPose);
        continue;
      }
      carve(item.t, item.image, nav.interpolate(item.t) * spec.T_vehicle_sonar);
    }
  }

  // Forgets navigation no frame can need: older than both the oldest pending image and the
  // newest frame minus the lateness, keeping one sample before that to bracket.
  void trim_navigation() {
    if (nav.size() < 64) return;
    double keep_from = any_frame ? newest_t - cfg.max_lateness_s : nav.times.back();
    for (const auto& p : pending) keep_from = std::min(keep_from, p.t);
    const auto it = std::lower_bound(nav.times.begin(), nav.times.end(), keep_from);
    const std::size_t n = static_cast<std::size_t>(it - nav.times.begin());
    if (n < 32) return;  // erase in batches
    const std::size_t cut = n - 1;
    nav.times.erase(nav.times.begin(), nav.times.begin() + static_cast<std::ptrdiff_t>(cut));
    nav.poses.erase(nav.poses.begin(), nav.poses.begin() + static_cast<std::ptrdiff_t>(cut));
  }
};

OnlineMapper::OnlineMapper(const SonarSpec& spec, const OnlineMapConfig& config,
                           std::optional<NoiseImages> noise)
    : impl_(std::make_unique<Impl>(spec, config, std::move(noise))) {
  spec.validate();
  config.validate();
  require(config.window_m == 0 || config.window_m >= spec.r_max,
          "parameter 'online.window_m' (" + std::to_string(config.window_m) +
              " m) must be 0 or at least the sonar's r_max (" + std::to_string(spec.r_max) +
              " m): the current footprint must lie inside the window");
  impl_->new_carver();  // validates the carving config and the noise statistics
}

OnlineMapper::~OnlineMapper() = default;

FrameDrop OnlineMapper::push_frame(double t, const SonarImage& image,
                                   const Eigen::Isometry3d& T_world_sonar) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  ++m.st.frames_received;
  const FrameDrop d = m.check_image(t, image);
  if (d != FrameDrop::None) {
    m.count(d);
    return d;
  }
  return m.carve(t, image, T_world_sonar);
}

bool OnlineMapper::push_navigation(double t, const Eigen::Isometry3d& T_world_vehicle) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  ++m.st.navigation_received;
  if (!std::isfinite(t) || !T_world_vehicle.matrix().allFinite() || !is_rigid(T_world_vehicle) ||
      T_world_vehicle.translation().cwiseAbs().maxCoeff() > limits::kMaxCoordinate ||
      (!m.nav.empty() && !(t > m.nav.times.back()))) {
    ++m.st.navigation_rejected;
    return false;
  }
  m.nav.push_back(t, T_world_vehicle);
  m.drain_pending();
  m.trim_navigation();
  return true;
}

FrameDrop OnlineMapper::push_image(double t, const SonarImage& image) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  ++m.st.frames_received;
  const FrameDrop d = m.check_image(t, image);
  if (d != FrameDrop::None) {
    m.count(d);
    return d;
  }
  constexpr double kTol = 1e-6;
  if (m.nav.empty() || t > m.nav.times.back() + kTol) {
    // Not bracketed yet: wait for navigation (never extrapolate).
    if (m.pending.size() >= m.cfg.max_pending_images) {
      m.pending.pop_front();
      m.count(FrameDrop::QueueFull);
    }
    m.pending.push_back({t, image});
    return FrameDrop::None;
  }
  if (!frame_inside_navigation(m.nav, t, true, "frame")) {
    m.count(FrameDrop::NoPose);
    return FrameDrop::NoPose;
  }
  return m.carve(t, image, m.nav.interpolate(t) * m.spec.T_vehicle_sonar);
}

PointCloud OnlineMapper::cloud() {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  if (m.carver->frames() == 0) return {};
  const auto t0 = std::chrono::steady_clock::now();
  PointCloud c = m.carver->resolve();
  m.st.resolve_ms_last = ms_since(t0);
  m.st.last_resolve = m.carver->last_resolve();
  m.st.points = c.size();
  return c;
}

PointCloud OnlineMapper::candidates() const {
  const Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  return m.carver->snapshot();
}

ElevationMap OnlineMapper::elevation() {
  PointCloud pts = cloud();
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  const double c = m.cfg.elevation.cell_m;
  pts.intensity.clear();  // heights only
  for (const auto& [key, z] : m.finished_top) {
    // A point at the cell's centre: the map's corners lie on multiples of the cell size, so it
    // falls in the cell it came from.
    pts.points.emplace_back(static_cast<float>((static_cast<double>(key.first) + 0.5) * c),
                            static_cast<float>((static_cast<double>(key.second) + 0.5) * c), z);
  }
  if (pts.empty()) return {};
  ElevationMapConfig ec = m.cfg.elevation;
  ec.region_min_xy = {1, 1};
  ec.region_max_xy = {0, 0};
  return elevation_map_from_points(pts, ec);
}

std::size_t OnlineMapper::frames_used() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->st.frames_used;
}

std::size_t OnlineMapper::frames_pending() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->pending.size();
}

OnlineMapStats OnlineMapper::stats() const {
  const Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  OnlineMapStats s = m.st;
  const CarveStats& cs = m.carver->stats();
  s.frames_pending = m.pending.size();
  s.frames_kept = m.carver->frames();
  s.active_voxels = cs.active_voxels;
  s.candidate_voxels = cs.candidate_voxels;
  s.leaves = cs.leaves;
  s.map_bytes = cs.map_bytes;
  s.frame_bytes = cs.frame_bytes;
  const std::vector<double> v(m.push_ms.begin(), m.push_ms.end());
  s.push_ms_median = quantile(v, 0.5);
  s.push_ms_p95 = quantile(v, 0.95);
  s.push_ms_max = v.empty() ? 0 : *std::max_element(v.begin(), v.end());
  return s;
}

PointCloud OnlineMapper::flush() {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  PointCloud out;
  if (m.carver->frames() > 0) out = m.carver->resolve();
  if (m.cfg.window_m > 0) m.finish(out);
  m.new_carver();
  m.window_set = false;
  return out;
}

void OnlineMapper::reset() {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  m.new_carver();
  m.st = OnlineMapStats{};
  m.nav = Trajectory{};
  m.pending.clear();
  m.any_frame = false;
  m.newest_t = 0;
  m.push_ms.clear();
  m.window_set = false;
  m.finished_top.clear();
}

const SonarSpec& OnlineMapper::spec() const { return impl_->spec; }
const OnlineMapConfig& OnlineMapper::config() const { return impl_->cfg; }
const Carver& OnlineMapper::carver() const { return *impl_->carver; }

}  // namespace sonar3d
