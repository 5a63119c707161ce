#include "sonar3d/recon/bracketing.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

#include "carve_footprint.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/recon/deconvolve.hpp"

namespace sonar3d {

namespace {

constexpr double kMaxSweepAngle = 30.0 * M_PI / 180.0;  // motion vs sonar z for an elevation pass

// One frame as the wedge test needs it.
struct FrameView {
  Eigen::Matrix3d R_sonar_world;
  Eigen::Vector3d t_world;     // sonar position
  Eigen::AlignedBox3d bounds;  // world box of the wedge
  int pass = -1;               // elevation-sweeping pass it belongs to, or -1
  bool level = false;          // outside every pass, sonar z within kMaxSweepAngle of world up
};

// What one point's wedge test in one frame gives: whether it is inside, and s = sin θ / sin θ3.
struct Sighting {
  bool inside = false;
  double s = 0;
};

class WedgeTester {
 public:
  explicit WedgeTester(const SonarSpec& spec) : g_(spec) {}
  Sighting test(const FrameView& f, const Eigen::Vector3d& p_world) const {
    const Eigen::Vector3d p = f.R_sonar_world * (p_world - f.t_world);
    const double r2 = p.squaredNorm();
    if (!(r2 > 0) || r2 < g_.r_min * g_.r_min || r2 >= g_.r_max * g_.r_max) return {};
    const double r = std::sqrt(r2);
    const double s = p.z() / r;
    if (std::abs(s) > g_.sin_theta3) return {};
    const double phi = detail::fast_atan2(p.y(), p.x());
    if (!(phi >= g_.fov_min) || !(phi <= g_.fov_max)) return {};
    return {true, s / g_.sin_theta3};
  }
  const detail::SonarGeometry& geometry() const { return g_; }

 private:
  detail::SonarGeometry g_;
};

// Points grouped into cubes of `cell` metres, so that frames are culled once per cube.
struct Cells {
  std::vector<std::vector<std::size_t>> members;
  std::vector<Eigen::AlignedBox3d> boxes;
};

Cells group_points(const std::vector<Eigen::Vector3f>& pts, double cell) {
  std::unordered_map<std::uint64_t, std::size_t> index;
  Cells c;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto q = [&](float v) {
      return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / cell)) +
                                        (1 << 20)) &
             0x1FFFFF;
    };
    const std::uint64_t key = (q(pts[i].x()) << 42) | (q(pts[i].y()) << 21) | q(pts[i].z());
    auto [it, fresh] = index.emplace(key, c.members.size());
    if (fresh) {
      c.members.emplace_back();
      c.boxes.emplace_back();
    }
    c.members[it->second].push_back(i);
    c.boxes[it->second].extend(pts[i].cast<double>());
  }
  return c;
}

std::vector<FrameView> frame_views(const std::vector<Eigen::Isometry3d>& T,
                                   const detail::SonarGeometry& g) {
  std::vector<FrameView> out(T.size());
  tbb::parallel_for(std::size_t{0}, T.size(), [&](std::size_t k) {
    out[k].R_sonar_world = T[k].linear().transpose();
    out[k].t_world = T[k].translation();
    out[k].bounds = detail::footprint_bounds_world(g, T[k]);
  });
  return out;
}

// The frames' passes that sweep the elevation: motion along ± the mean sonar z.
struct Pass {
  std::size_t first = 0, last = 0;  // inclusive frame indices
  Eigen::Vector3d origin, axis;     // axis = mean sonar z (unit); heights s = (x − origin)·axis
  double s_min = 0, s_max = 0;      // extent of the frames along the axis
};

std::vector<Pass> sweeping_passes(const std::vector<Eigen::Isometry3d>& T) {
  std::vector<Pass> out;
  if (T.size() < 3) return out;
  DeconvConfig dc;  // the pass splitting deconvolution uses (jumps, turns, reversals)
  for (const auto& [first, end] : split_passes(T, dc)) {
    if (end - first < 3) continue;
    Eigen::Vector3d z = Eigen::Vector3d::Zero();
    for (std::size_t k = first; k < end; ++k) z += T[k].linear().col(2);
    if (z.norm() < 1e-9) continue;
    z.normalize();
    const Eigen::Vector3d motion = T[end - 1].translation() - T[first].translation();
    if (motion.norm() < 1e-6) continue;
    const double c = std::abs(motion.normalized().dot(z));
    if (c < std::cos(kMaxSweepAngle)) continue;  // a level approach, an orbit: no elevation sweep
    Pass p;
    p.first = first;
    p.last = end - 1;
    p.origin = T[first].translation();
    p.axis = z;
    p.s_min = std::numeric_limits<double>::infinity();
    p.s_max = -p.s_min;
    for (std::size_t k = first; k < end; ++k) {
      const double s = (T[k].translation() - p.origin).dot(z);
      p.s_min = std::min(p.s_min, s);
      p.s_max = std::max(p.s_max, s);
    }
    out.push_back(p);
  }
  return out;
}

// The extreme surface of a pass on one side: the farthest point (along the axis) that a frame of
// the pass saw at |s| >= end_view_fraction from the other side, and its distance from the axis.
struct Extreme {
  double s = 0, r = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();  // the point, world frame
  bool set = false;
  // Farthest first, in 1 cm steps (so that the result does not depend on the order of offers);
  // among equally far points the one farthest from the axis, whose arc needs the longest pass.
  void offer(double s_new, double r_new, const Eigen::Vector3d& p_new, bool upper) {
    const auto key = [upper](double v) { return std::floor((upper ? v : -v) / 0.01); };
    if (!set || key(s_new) > key(s) || (key(s_new) == key(s) && r_new > r)) {
      s = s_new;
      r = r_new;
      p = p_new;
      set = true;
    }
  }
};

// The pass-end rule (docs/experiments.md) at one end: it should go 2·r·tan(A_v/2) past the
// extreme surface e it saw; it went past_surface. Used for the ends of passes and for the top of a
// stack of level frames.
struct EndRule {
  double rule = 0, extend = 0;
  bool lower_bound = false;
  bool stops_short =
      false;  // short by more than end_tolerance, with the space beyond in the region
};

EndRule end_rule(const Extreme& e, double past_surface, const Eigen::Vector3d& out_dir, double tan3,
                 const BracketConfig& config, const std::optional<Eigen::AlignedBox3d>& region) {
  EndRule r;
  r.rule = 2.0 * e.r * tan3;
  r.extend = r.rule - past_surface;
  // The extreme surface is the farthest point seen from beyond at end_view_fraction: when the end
  // is closer to it than that, the surface may reach farther than the frames can tell, and the
  // extension is a lower bound.
  r.lower_bound = past_surface <= config.end_view_fraction * e.r * tan3 + 0.02;
  if (r.extend <= config.end_tolerance * r.rule) return r;
  // The unbracketed space beyond that end lies outside the region (e.g. under the seabed a
  // region's floor excludes): nothing there is reconstructed, nothing to warn about.
  bool any_inside = !region;
  for (int a = 1; a <= 4 && !any_inside; ++a)
    any_inside = region->contains(e.p + 0.25 * a * r.rule * out_dir);
  r.stops_short = any_inside;
  return r;
}

template <typename F>
void run_in(int threads, F&& f) {
  tbb::task_arena arena(threads > 0 ? threads : static_cast<int>(tbb::task_arena::automatic));
  arena.execute(std::forward<F>(f));
}

}  // namespace

void BracketConfig::validate() const {
  require(std::isfinite(min_bracket) && min_bracket >= 0 && min_bracket <= 1,
          "parameter 'bracket.min_bracket' must lie in [0, 1], got " + std::to_string(min_bracket));
  require(std::isfinite(bracketed_level) && bracketed_level > 0 && bracketed_level <= 1,
          "parameter 'bracket.bracketed_level' must lie in (0, 1], got " +
              std::to_string(bracketed_level));
  require(std::isfinite(end_view_fraction) && end_view_fraction > 0 && end_view_fraction <= 1,
          "parameter 'bracket.end_view_fraction' must lie in (0, 1], got " +
              std::to_string(end_view_fraction));
  require(
      std::isfinite(end_tolerance) && end_tolerance >= 0 && end_tolerance < 1,
      "parameter 'bracket.end_tolerance' must lie in [0, 1), got " + std::to_string(end_tolerance));
  require(std::isfinite(level_view_above) && level_view_above >= 0 && level_view_above <= 1,
          "parameter 'bracket.level_view_above' must lie in [0, 1], got " +
              std::to_string(level_view_above));
  require(region_samples >= 0 && region_samples <= 100000000,
          "parameter 'bracket.region_samples' must lie in [0, 1e8], got " +
              std::to_string(region_samples));
  require(num_threads >= 0, "parameter 'bracket.num_threads' must be >= 0 (0 = all cores), got " +
                                std::to_string(num_threads));
}

std::string PassExtension::message() const {
  std::ostringstream os;
  os.precision(2);
  os << std::fixed << "pass " << pass + 1 << " (frames " << first_frame << "–" << last_frame
     << ") stops short at its " << (upper ? "upper" : "lower") << " end: it goes " << past_surface
     << " m past the surface it saw, the elevation beyond it needs 2·r·tan(A_v/2) = " << rule
     << " m (r = " << range << " m): extend it by " << (lower_bound ? "at least " : "") << extend
     << " m " << (upper ? "upward" : "downward") << " (direction " << direction.x() << ", "
     << direction.y() << ", " << direction.z()
     << "); until then the space beyond is never bracketed and may hold "
     << "ghosts (docs/carving.md)";
  return os.str();
}

std::string LevelStack::message() const {
  std::ostringstream os;
  os.precision(2);
  os << std::fixed << "the level frames (" << frames << ", sonars at z " << z_min << " to " << z_max
     << " m) stop short at their top: the highest goes " << past_surface
     << " m over the surface they saw from above, the elevation beyond it needs 2·r·tan(A_v/2) = "
     << rule << " m (r = " << range << " m): add levels up to z = " << z_max + extend << " m"
     << (lower_bound ? " or higher" : "")
     << "; until then the space above is seen from below only and may hold ghosts "
        "(docs/carving.md)";
  return os.str();
}

std::vector<std::string> BracketReport::warnings() const {
  std::vector<std::string> w;
  for (const auto& e : extensions) w.push_back(e.message());
  if (level_stack.stops_short) w.push_back(level_stack.message());
  return w;
}

std::string BracketReport::to_json() const {
  nlohmann::ordered_json j;
  j["points"] = points;
  j["kept"] = kept;
  j["min_bracket"] = min_bracket;
  j["min_bracket_auto"] = min_bracket_auto;
  j["median_bracket"] = median_bracket;
  j["region_samples"] = region_samples;
  j["sample_step"] = sample_step;
  j["unbracketed_share"] = unbracketed_share;
  j["never_bracketed_share"] = never_bracketed_share;
  if (region) {
    j["region"] = {region->min().x(), region->min().y(), region->min().z(),
                   region->max().x(), region->max().y(), region->max().z()};
  }
  j["sweeping_passes"] = passes;
  j["seconds"] = seconds;
  nlohmann::ordered_json ext = nlohmann::ordered_json::array();
  for (const auto& e : extensions) {
    nlohmann::ordered_json x;
    x["pass"] = e.pass + 1;
    x["first_frame"] = e.first_frame;
    x["last_frame"] = e.last_frame;
    x["end"] = e.upper ? "upper" : "lower";
    x["range"] = e.range;
    x["rule"] = e.rule;
    x["past_surface"] = e.past_surface;
    x["extend"] = e.extend;
    x["lower_bound"] = e.lower_bound;
    x["direction"] = {e.direction.x(), e.direction.y(), e.direction.z()};
    x["message"] = e.message();
    ext.push_back(x);
  }
  j["pass_extensions"] = ext;
  const LevelStack& ls = level_stack;
  nlohmann::ordered_json st;
  st["frames"] = ls.frames;
  st["z_min"] = ls.z_min;
  st["z_max"] = ls.z_max;
  st["sweeps"] = ls.sweeps;
  st["stops_short"] = ls.stops_short;
  if (ls.stops_short) {
    st["surface_z"] = ls.surface_z;
    st["range"] = ls.range;
    st["rule"] = ls.rule;
    st["past_surface"] = ls.past_surface;
    st["extend"] = ls.extend;
    st["lower_bound"] = ls.lower_bound;
    st["dropped"] = ls.dropped;
    st["message"] = ls.message();
  }
  j["level_stack"] = st;
  return j.dump(2);
}

namespace {

// The shared sweep: for every point, every frame whose wedge holds it (frames culled per cell by
// their wedge's bounding box). visit(i, frame index, s) is called for each sighting.
template <typename Visit>
void sweep(const std::vector<Eigen::Vector3f>& pts, const std::vector<FrameView>& frames,
           const WedgeTester& wt, Visit&& visit) {
  const Cells cells = group_points(pts, 0.25);
  tbb::parallel_for(std::size_t{0}, cells.members.size(), [&](std::size_t c) {
    std::vector<std::size_t> near;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      if (frames[k].bounds.intersects(cells.boxes[c])) near.push_back(k);
    }
    for (std::size_t i : cells.members[c]) {
      const Eigen::Vector3d p = pts[i].cast<double>();
      for (std::size_t k : near) {
        const Sighting si = wt.test(frames[k], p);
        if (si.inside) visit(i, k, si.s);
      }
    }
  });
}

}  // namespace

std::vector<PointBracket> bracket_points(const std::vector<Eigen::Vector3f>& points_world,
                                         const std::vector<Eigen::Isometry3d>& T_world_sonar,
                                         const SonarSpec& spec, int num_threads) {
  spec.validate();
  const WedgeTester wt(spec);
  std::vector<PointBracket> out(points_world.size());
  std::vector<float> lo(points_world.size(), 0.0f), hi(points_world.size(), 0.0f);
  run_in(num_threads, [&] {
    const std::vector<FrameView> frames = frame_views(T_world_sonar, wt.geometry());
    // Each point belongs to one cell, hence to one task: no two tasks write the same slot.
    sweep(points_world, frames, wt, [&](std::size_t i, std::size_t, double s) {
      ++out[i].views;
      lo[i] = std::min(lo[i], static_cast<float>(s));
      hi[i] = std::max(hi[i], static_cast<float>(s));
    });
  });
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].bracket = std::clamp(std::min(-lo[i], hi[i]), 0.0f, 1.0f);
  }
  return out;
}

BracketReport assess_bracketing(PointCloud& cloud,
                                const std::vector<Eigen::Isometry3d>& T_world_sonar,
                                const SonarSpec& spec, const BracketConfig& config,
                                const std::optional<Eigen::AlignedBox3d>& region) {
  config.validate();
  spec.validate();
  const auto t0 = std::chrono::steady_clock::now();
  BracketReport rep;
  rep.points = cloud.size();
  const WedgeTester wt(spec);
  const double tan3 = std::tan(0.5 * spec.vertical_aperture_rad);

  run_in(config.num_threads, [&] {
    std::vector<FrameView> frames = frame_views(T_world_sonar, wt.geometry());
    const std::vector<Pass> passes = sweeping_passes(T_world_sonar);
    rep.passes = passes.size();
    for (std::size_t p = 0; p < passes.size(); ++p)
      for (std::size_t k = passes[p].first; k <= passes[p].last; ++k)
        frames[k].pass = static_cast<int>(p);
    // The level frames: a stack of them at several heights sweeps the elevation level by level.
    LevelStack& stack = rep.level_stack;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      const double up = T_world_sonar[k].linear().col(2).z();
      frames[k].level = frames[k].pass < 0 && up >= std::cos(kMaxSweepAngle);
      if (!frames[k].level) continue;
      const double z = frames[k].t_world.z();
      stack.z_min = stack.frames == 0 ? z : std::min(stack.z_min, z);
      stack.z_max = stack.frames == 0 ? z : std::max(stack.z_max, z);
      ++stack.frames;
    }
    // A stack sweeps when its heights span the aperture's height at the nearest range (points
    // there are seen at both edges); one orbit at one height (or bobbing about it) does not, and
    // keeps everything: it carves the arcs from other azimuths instead.
    stack.sweeps =
        stack.frames >= 3 && stack.z_max - stack.z_min >= 2.0 * wt.geometry().r_min * tan3;

    // Per point: bracket and views over every frame; per pass: the extreme surface it saw.
    const std::size_t n = cloud.size();
    std::vector<float> lo(n, 0.0f), hi(n, 0.0f), views(n, 0.0f);
    const float f = static_cast<float>(config.end_view_fraction);
    tbb::combinable<std::vector<Extreme>> upper(
        [&] { return std::vector<Extreme>(passes.size()); });
    tbb::combinable<std::vector<Extreme>> lower(
        [&] { return std::vector<Extreme>(passes.size()); });
    // The stack's extreme surface: the highest point a level frame saw from above at |s| >= f.
    tbb::combinable<Extreme> stack_top;
    std::vector<unsigned char> level_seen(stack.sweeps ? n : 0, 0);
    sweep(cloud.points, frames, wt, [&](std::size_t i, std::size_t k, double s) {
      views[i] += 1.0f;
      lo[i] = std::min(lo[i], static_cast<float>(s));
      hi[i] = std::max(hi[i], static_cast<float>(s));
      if (stack.sweeps && frames[k].level) {
        level_seen[i] = 1;
        if (s <= -f) {
          const Eigen::Vector3d q = cloud.points[i].cast<double>();
          stack_top.local().offer(q.z(), (q - frames[k].t_world).norm(), q, true);
        }
      }
      const int pi = frames[k].pass;
      if (pi < 0 || std::abs(s) < f) return;
      const Pass& ps = passes[pi];
      const Eigen::Vector3d q = cloud.points[i].cast<double>();
      const Eigen::Vector3d d = q - ps.origin;
      const double h = d.dot(ps.axis);
      const double r = (d - h * ps.axis).norm();
      // Seen from above (s < 0): the frame lies beyond the point toward +z, so the point bounds
      // the pass' upper extreme surface; seen from below, the lower one.
      if (s < 0) {
        upper.local()[pi].offer(h, r, q, true);
      } else {
        lower.local()[pi].offer(h, r, q, false);
      }
    });
    std::vector<float> bracket(n);
    for (std::size_t i = 0; i < n; ++i)
      bracket[i] = std::clamp(std::min(-lo[i], hi[i]), 0.0f, 1.0f);
    if (n > 0) {
      std::vector<float> b = bracket;
      std::nth_element(b.begin(), b.begin() + n / 2, b.end());
      rep.median_bracket = b[n / 2];
    }

    // Pass ends (the rule of docs/experiments.md: a pass runs 2·r·tan(A_v/2) past the surface).
    // short_ends: per end that stops short and leads up or level, its extreme surface point and
    // the way out (world).
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> short_ends;
    for (std::size_t p = 0; p < passes.size(); ++p) {
      Extreme up, down;
      upper.combine_each([&](const std::vector<Extreme>& v) {
        if (v[p].set) up.offer(v[p].s, v[p].r, v[p].p, true);
      });
      lower.combine_each([&](const std::vector<Extreme>& v) {
        if (v[p].set) down.offer(v[p].s, v[p].r, v[p].p, false);
      });
      const Pass& ps = passes[p];
      for (int side = 0; side < 2; ++side) {
        const Extreme& e = side == 0 ? up : down;
        if (!e.set) continue;
        const bool is_upper = side == 0;
        PassExtension x;
        x.pass = p;
        x.first_frame = ps.first;
        x.last_frame = ps.last;
        x.upper = is_upper;
        x.range = e.r;
        x.past_surface = is_upper ? ps.s_max - e.s : e.s - ps.s_min;
        x.direction = is_upper ? ps.axis : Eigen::Vector3d(-ps.axis);
        const EndRule r = end_rule(e, x.past_surface, x.direction, tan3, config, region);
        if (!r.stops_short) continue;
        x.rule = r.rule;
        x.extend = r.extend;
        x.lower_bound = r.lower_bound;
        rep.extensions.push_back(x);
        // The automatic filter looks beyond ends that lead into the water column only: below a
        // pass that starts over the seabed lies the seabed, seen from above only — never
        // bracketed, like a ghost, but real (ghost_half_buried.yaml, 20°, long passes: 8.1 %
        // coverage when a short lower end turned the filter on everywhere, 48.5 % now;
        // docs/carving.md, "Ghost removal by default").
        if (x.direction.z() >= 0) short_ends.push_back({e.p, x.direction});
      }
    }

    // The stack's top level, by the same rule as a pass' upper end (world z: the level frames'
    // sonar z is within kMaxSweepAngle of up).
    Extreme top;
    stack_top.combine_each([&](const Extreme& e) {
      if (e.set) top.offer(e.s, e.r, e.p, true);
    });
    if (stack.sweeps && top.set) {
      stack.surface_z = top.s;
      stack.range = top.r;
      stack.past_surface = stack.z_max - top.s;
      const EndRule r =
          end_rule(top, stack.past_surface, Eigen::Vector3d::UnitZ(), tan3, config, region);
      stack.rule = r.rule;
      stack.extend = r.extend;
      stack.lower_bound = r.lower_bound;
      stack.stops_short = r.stops_short;
    }

    // The region: the never-bracketed share of what the frames saw.
    std::optional<Eigen::AlignedBox3d> box = region;
    if (!box && n > 0) {
      Eigen::AlignedBox3d b;
      for (const auto& q : cloud.points) b.extend(q.cast<double>());
      box = b;
    }
    if (box && config.region_samples > 0) {
      const Eigen::Vector3d size = box->sizes().cwiseMax(1e-6);
      const double step = std::cbrt(size.prod() / config.region_samples);
      Eigen::Vector3i cnt;
      for (int a = 0; a < 3; ++a)
        cnt[a] = std::max(1, static_cast<int>(std::ceil(size[a] / std::max(step, 1e-9))));
      std::vector<Eigen::Vector3f> samples;
      samples.reserve(static_cast<std::size_t>(cnt.x()) * cnt.y() * cnt.z());
      for (int x = 0; x < cnt.x(); ++x)
        for (int y = 0; y < cnt.y(); ++y)
          for (int z = 0; z < cnt.z(); ++z) {
            const Eigen::Vector3d q = box->min() + Eigen::Vector3d((x + 0.5) * size.x() / cnt.x(),
                                                                   (y + 0.5) * size.y() / cnt.y(),
                                                                   (z + 0.5) * size.z() / cnt.z());
            samples.push_back(q.cast<float>());
          }
      std::vector<float> slo(samples.size(), 0.0f), shi(samples.size(), 0.0f);
      std::vector<unsigned char> seen(samples.size(), 0);
      sweep(samples, frames, wt, [&](std::size_t i, std::size_t, double s) {
        seen[i] = 1;
        slo[i] = std::min(slo[i], static_cast<float>(s));
        shi[i] = std::max(shi[i], static_cast<float>(s));
      });
      std::size_t observed = 0, unbracketed = 0, never = 0;
      for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!seen[i]) continue;
        ++observed;
        const float b = std::clamp(std::min(-slo[i], shi[i]), 0.0f, 1.0f);
        unbracketed += b < config.bracketed_level;
        never += b <= 0.0f;
      }
      rep.region = box;
      rep.region_samples = observed;
      rep.sample_step = std::cbrt(size.prod() / std::max<double>(1.0, samples.size()));
      if (observed > 0) {
        rep.unbracketed_share = static_cast<double>(unbracketed) / observed;
        rep.never_bracketed_share = static_cast<double>(never) / observed;
      }
    }

    // Attach, then filter.
    cloud.properties.erase(std::remove_if(cloud.properties.begin(), cloud.properties.end(),
                                          [](const PointProperty& p) {
                                            return p.name == "bracket" || p.name == "views";
                                          }),
                           cloud.properties.end());
    cloud.properties.push_back({"bracket", bracket});
    cloud.properties.push_back({"views", views});
    // The filter: min_bracket everywhere; else, with auto_min_bracket, bracketed_level beyond
    // each pass end that stops short (past its extreme surface along the way out), where its
    // unbracketed ghost arcs lie — a seabed under the passes, seen from above only, stays.
    rep.min_bracket = config.min_bracket;
    if (rep.min_bracket == 0 && config.auto_min_bracket && !short_ends.empty()) {
      rep.min_bracket = config.bracketed_level;
      rep.min_bracket_auto = true;
    }
    // Over a stack that stops short: the points above its extreme surface that level frames saw
    // and no frame saw from above at level_view_above or more (nor from nowhere below: a point
    // seen edge-on only stays).
    const bool stack_filter =
        config.min_bracket == 0 && config.auto_min_bracket && stack.stops_short;
    auto above_stack = [&](std::size_t i) {
      return stack_filter && level_seen[i] && hi[i] > 0 &&
             -lo[i] < static_cast<float>(config.level_view_above) &&
             cloud.points[i].z() > stack.surface_z;
    };
    auto beyond_short_end = [&](std::size_t i) {
      const Eigen::Vector3d q = cloud.points[i].cast<double>();
      for (const auto& [p, dir] : short_ends)
        if ((q - p).dot(dir) > 0) return true;
      return false;
    };
    if (rep.min_bracket > 0 || stack_filter) {
      PointCloud kept;
      kept.properties = cloud.properties;
      for (auto& p : kept.properties) p.values.clear();
      for (std::size_t i = 0; i < n; ++i) {
        if (rep.min_bracket > 0 && bracket[i] < rep.min_bracket &&
            (!rep.min_bracket_auto || beyond_short_end(i))) {
          continue;
        }
        if (above_stack(i)) {
          ++stack.dropped;
          continue;
        }
        kept.points.push_back(cloud.points[i]);
        if (cloud.has_intensity()) kept.intensity.push_back(cloud.intensity[i]);
        for (std::size_t a = 0; a < kept.properties.size(); ++a)
          kept.properties[a].values.push_back(cloud.properties[a].values[i]);
      }
      cloud = std::move(kept);
    }
  });
  rep.kept = cloud.size();
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace sonar3d
