#include "sonar3d/recon/carve.hpp"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tree/LeafManager.h>
#include <openvdb/tree/ValueAccessor.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <unordered_map>

#include "carve_footprint.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

namespace {

using TreeT = openvdb::FloatTree;
using GridT = openvdb::FloatGrid;
using LeafT = TreeT::LeafNodeType;
// Observations of each candidate, packed in an int32: how many return pixels bounded it (8 bits,
// saturating) and the range of sin θ / sin θ_3dB over them (two 12-bit fields).
using SpanTreeT = openvdb::Int32Tree;
using SpanLeafT = SpanTreeT::LeafNodeType;
using SpanAccessor = openvdb::tree::ValueAccessor<SpanTreeT, false>;
using openvdb::Coord;
using openvdb::CoordBBox;
// Unregistered accessor: one per task, created after and destroyed before any topology change.
using Accessor = openvdb::tree::ValueAccessor<TreeT, false>;

constexpr float kUnknown = std::numeric_limits<float>::infinity();  // background: no bound yet
constexpr int kLeafDim = 8;                                         // LeafT::DIM
constexpr int kNodeDim = 128;  // voxels spanned by a lowest internal node (16 leaves)
// Edge of the cubes handed to TBB tasks: small enough for an even load on a few cores (the work
// gathers around the surfaces), large enough that a task costs little more than its work.
constexpr int kTopDim = 32;
constexpr int kObsScale = 2047;  // sin θ / sin θ_3dB in [-1, 1] -> [-2047, 2047]

struct Observations {
  int count = 0, lo = 0, hi = 0;
};
std::int32_t pack_obs(const Observations& o) {
  return static_cast<std::int32_t>((static_cast<std::uint32_t>(o.count) << 24) |
                                   (static_cast<std::uint32_t>(o.hi + 2048) << 12) |
                                   static_cast<std::uint32_t>(o.lo + 2048));
}
Observations unpack_obs(std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  return {static_cast<int>(u >> 24), static_cast<int>(u & 0xFFF) - 2048,
          static_cast<int>((u >> 12) & 0xFFF) - 2048};
}  // voxels spanned by a lowest internal node (16 leaves)
constexpr double kSqrt3 = 1.7320508075688772;

// Tile extent (voxels) by tree depth (0 = root tile .. 3 = leaf voxel) of a 5-4-3 tree.
constexpr int kExtentByDepth[4] = {4096, 128, 8, 1};

void init_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

// What one top cube's task produced, applied serially once every task is done (OpenVDB trees
// are not safe for concurrent topology changes; values of existing leaves are changed in place).
struct TaskOut {
  TaskOut() = default;
  TaskOut(const TaskOut&) = delete;
  TaskOut& operator=(const TaskOut&) = delete;
  ~TaskOut() { delete spare; }
  LeafT* spare = nullptr;  // a recycled scratch leaf
  std::vector<LeafT*> new_leaves;
  std::vector<SpanLeafT*> new_span_leaves;
  std::vector<std::pair<Coord, int>> free_cubes;  // origin, edge (voxels), edge >= 8
  std::size_t voxels = 0;
};

// Carves one frame into the map. Owns nothing; lives for one integrate() call.
class FrameCarver {
 public:
  FrameCarver(const detail::SonarGeometry& g, const detail::FrameFootprint& fp,
              const SonarImage& image, double voxel_size, double margin, double pose_margin,
              const CoordBBox& clip, bool track_span, int min_observations, bool span_filter)
      : g_(g),
        fp_(fp),
        fr_(fp.frame()),
        image_(image),
        vs_(voxel_size),
        clip_(clip),
        track_span_(track_span),
        min_span_needed_(span_filter),
        min_obs_(min_observations) {
    delta_ = margin * 0.5 * kSqrt3 * vs_ + pose_margin;
    // Steps of the sonar-frame position per voxel index along world x, y, z.
    step_[0] = fp.R_sonar_world.col(0) * vs_;
    step_[1] = fp.R_sonar_world.col(1) * vs_;
    step_[2] = fp.R_sonar_world.col(2) * vs_;
    r_min2_ = g.r_min * g.r_min;
    r_max2_ = g.r_max * g.r_max;
  }

  // Processes an aligned cube of edge s >= 8 voxels.
  void process_cube(Accessor& acc, SpanAccessor& sacc, const Coord& o, int s, TaskOut& out) const {
    const CoordBBox cube(o, o.offsetBy(s - 1));
    if (!clip_.hasOverlap(cube)) return;
    if (uniform_free(acc, o, s)) return;  // free stays free: nothing can change here
    const detail::CubeClass cls = classify(o, s);
    const detail::Region region = cls.region;
    if (region == detail::Region::Outside || region == detail::Region::NoUpdate) return;
    if (region == detail::Region::Free && clip_.isInside(cube)) {
      out.free_cubes.emplace_back(o, s);
      return;
    }
    if (s == kLeafDim) {
      process_leaf(acc, sacc, o, cls, out);
      return;
    }
    const int h = s / 2;
    for (int dx = 0; dx < 2; ++dx)
      for (int dy = 0; dy < 2; ++dy)
        for (int dz = 0; dz < 2; ++dz)
          process_cube(acc, sacc, o.offsetBy(dx * h, dy * h, dz * h), h, out);
  }

 private:
  bool uniform_free(const Accessor& acc, const Coord& o, int s) const {
    const int depth = acc.getValueDepth(o);
    if (depth < 0 || depth > 2 || kExtentByDepth[depth] < s) return false;
    return acc.isValueOn(o) && acc.getValue(o) == 0.0f;
  }

  Eigen::Vector3d centre_sonar(const Coord& o, int s) const {
    const double half = 0.5 * (s - 1);
    const Eigen::Vector3d c_world((o.x() + half) * vs_, (o.y() + half) * vs_, (o.z() + half) * vs_);
    return fp_.to_sonar(c_world);
  }

  detail::CubeClass classify(const Coord& o, int s) const {
    const double r_centres = 0.5 * kSqrt3 * (s - 1) * vs_;
    return fp_.classify(centre_sonar(o, s), r_centres, r_centres + delta_);
  }

  // The leaf being updated and, lazily, its elevation-span companion.
  struct LeafCtx {
    LeafT* leaf = nullptr;
    float* v = nullptr;
    SpanAccessor* sacc = nullptr;
    Coord origin;
    SpanLeafT* span = nullptr;
    bool span_new = false, span_changed = false;
  };

  void process_leaf(Accessor& acc, SpanAccessor& sacc, const Coord& o, const detail::CubeClass& cls,
                    TaskOut& out) const {
    LeafCtx c;
    c.leaf = acc.probeLeaf(o);
    c.sacc = &sacc;
    c.origin = o;
    bool is_new = false;
    if (!c.leaf) {
      // A tile or the background: a new leaf starts from its value and state. Most such leaves
      // end up unchanged, so a spare one is recycled rather than allocated each time.
      if (!out.spare) {
        out.spare = new LeafT(o, acc.getValue(o), acc.isValueOn(o));
      } else {
        out.spare->setOrigin(o);
        out.spare->fill(acc.getValue(o), acc.isValueOn(o));
      }
      c.leaf = out.spare;
      is_new = true;
    }
    c.v = c.leaf->buffer().data();
    const bool changed = process_sub(c, o, kLeafDim, cls, out);
    bool keep_span = c.span_changed;
    if (changed && c.leaf->getValueMask().isOn()) {
      // A leaf that became wholly free collapses to a tile (its span leaf goes too).
      bool all_zero = true;
      for (openvdb::Index n = 0; n < LeafT::SIZE && all_zero; ++n) all_zero = c.v[n] == 0.0f;
      if (all_zero) {
        out.free_cubes.emplace_back(o, kLeafDim);
        if (c.span_new) delete c.span;
        return;  // a new leaf stays the spare
      }
    }
    if (is_new && changed) {
      out.new_leaves.push_back(c.leaf);
      out.spare = nullptr;
    }
    if (c.span_new) {
      if (keep_span) {
        out.new_span_leaves.push_back(c.span);
      } else {
        delete c.span;
      }
    }
  }

  // Cube of edge s <= 8 inside the leaf; `region` is its classification. Returns true when a
  // value or state changed.
  bool process_sub(LeafCtx& c, const Coord& o, int s, const detail::CubeClass& cls,
                   TaskOut& out) const {
    using detail::Region;
    const Region region = cls.region;
    if (region == Region::Outside || region == Region::NoUpdate) return false;
    const CoordBBox cube(o, o.offsetBy(s - 1));
    if (!clip_.hasOverlap(cube)) return false;
    if (region == Region::Free && clip_.isInside(cube)) {
      bool changed = false;
      all_of_cube(o, s, [&](openvdb::Index n) {
        if (c.v[n] != 0.0f || !c.leaf->isValueOn(n)) {
          c.v[n] = 0.0f;
          c.leaf->setActiveState(n, true);
          changed = true;
        }
        return true;
      });
      return changed;
    }
    if (s < kLeafDim && cube_free(c, o, s)) return false;  // free stays free
    if (cls.window && cls.no_carve) {
      // Nothing here can be carved (all behind the first returns): only return pixels matter.
      float min_i = 0;
      if (!fp_.window_returns(cls, &min_i)) return false;  // gaps between returns: shadow
      // eq. 4.7 with B <= 1: no bound below min_i · min 1/B² can come from this window, so a
      // cube whose voxels all hold a lower (or zero) bound cannot change (except for the span).
      if (cube_max(c, o, s) <= min_i * g_.min_inv_b2 && observations_saturated(c, o, s))
        return false;
    }
    if (s > kVoxelLevel) {
      const int h = s / 2;
      bool changed = false;
      for (int dx = 0; dx < 2; ++dx)
        for (int dy = 0; dy < 2; ++dy)
          for (int dz = 0; dz < 2; ++dz) {
            const Coord q = o.offsetBy(dx * h, dy * h, dz * h);
            changed |= process_sub(c, q, h, classify(q, h), out);
          }
      return changed;
    }
    return process_voxels(c, o, s, out);
  }

  bool process_voxels(LeafCtx& c, const Coord& o, int s, TaskOut& out) const {
    const Coord lo = Coord::maxComponent(o, clip_.min());
    const Coord hi = Coord::minComponent(o.offsetBy(s - 1), clip_.max());
    const Eigen::Vector3d p0 =
        fp_.to_sonar(Eigen::Vector3d(lo.x() * vs_, lo.y() * vs_, lo.z() * vs_));
    bool changed = false;
    for (int x = lo.x(); x <= hi.x(); ++x) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        Eigen::Vector3d p = p0 + (x - lo.x()) * step_[0] + (y - lo.y()) * step_[1];
        for (int z = lo.z(); z <= hi.z(); ++z, p += step_[2]) {
          const openvdb::Index n = LeafT::coordToOffset(Coord(x, y, z));
          if (c.v[n] == 0.0f && c.leaf->isValueOn(n)) continue;  // free stays free (min with 0)
          ++out.voxels;
          changed |= update_voxel(c, n, p);
        }
      }
    }
    return changed;
  }

  // True when further observations of the cube's candidates change no filter decision: no
  // tracking, or only a count is needed and every candidate has reached it.
  bool observations_saturated(LeafCtx& c, const Coord& o, int s) const {
    if (!track_span_) return true;
    if (min_span_needed_) return false;  // the span may still widen
    if (!c.span) c.span = c.sacc->probeLeaf(c.origin);
    if (!c.span) return false;
    return all_of_cube(o, s, [&](openvdb::Index n) {
      return c.v[n] == 0.0f ||  // free
             (c.span->isValueOn(n) && unpack_obs(c.span->getValue(n)).count >= min_obs_);
    });
  }

  // Calls f(offset) for every voxel of the sub-cube (origin o, edge s) of a leaf until f returns
  // false; returns whether it never did.
  template <typename F>
  static bool all_of_cube(const Coord& o, int s, F&& f) {
    const openvdb::Index base = LeafT::coordToOffset(o);  // (x << 6) | (y << 3) | z inside the leaf
    for (int x = 0; x < s; ++x)
      for (int y = 0; y < s; ++y) {
        const openvdb::Index row = base + (x << 6) + (y << 3);
        for (int z = 0; z < s; ++z)
          if (!f(row + z)) return false;
      }
    return true;
  }

  // True when every voxel of the cube is already known free.
  static bool cube_free(const LeafCtx& c, const Coord& o, int s) {
    return all_of_cube(o, s,
                       [&](openvdb::Index n) { return c.v[n] == 0.0f && c.leaf->isValueOn(n); });
  }

  // Largest value in the cube; +inf when a voxel is unknown.
  static float cube_max(const LeafCtx& c, const Coord& o, int s) {
    float m = 0.0f;
    if (s == kLeafDim) {
      if (!c.leaf->getValueMask().isOn()) return std::numeric_limits<float>::infinity();
      for (openvdb::Index n = 0; n < LeafT::SIZE; ++n) m = std::max(m, c.v[n]);
      return m;
    }
    const bool known = all_of_cube(o, s, [&](openvdb::Index n) {
      m = std::max(m, c.v[n]);
      return c.leaf->isValueOn(n);
    });
    return known ? m : std::numeric_limits<float>::infinity();
  }

  // Records one more return observation of voxel n, at sin θ = s.
  void note_span(LeafCtx& c, openvdb::Index n, double s, bool first) const {
    if (!c.span) {
      c.span = c.sacc->probeLeaf(c.origin);
      if (!c.span) {
        c.span = new SpanLeafT(c.origin, 0, false);
        c.span_new = true;
      }
    }
    const int q =
        static_cast<int>(std::lround(std::clamp(s / g_.sin_theta3, -1.0, 1.0) * kObsScale));
    Observations o{1, q, q};
    if (!first && c.span->isValueOn(n)) {
      const Observations old = unpack_obs(c.span->getValue(n));
      o.count = std::min(old.count + 1, 255);
      o.lo = std::min(old.lo, q);
      o.hi = std::max(old.hi, q);
    }
    c.span->setValueOn(n, pack_obs(o));
    c.span_changed = true;
  }

  // The voxel-centric carving rule for one voxel centre p (sonar frame).
  bool update_voxel(LeafCtx& c, openvdb::Index n, const Eigen::Vector3d& p) const {
    const double r2 = p.squaredNorm();
    if (!(r2 > 0) || r2 < r_min2_ || r2 >= r_max2_) return false;  // r_min may be 0
    const double r = std::sqrt(r2);
    const double s = p.z() / r;
    if (std::abs(s) > g_.sin_theta3) return false;  // outside the vertical aperture
    const double phi = detail::fast_atan2(p.y(), p.x());
    if (!(phi >= g_.fov_min) || !(phi < g_.fov_max)) return false;
    const int j = g_.beam(phi);
    const int i = std::min(static_cast<int>((r - g_.r_min) * g_.inv_dr), g_.bins - 1);
    float* v = c.v;
    const bool on = c.leaf->isValueOn(n);
    if (fr_.has_return(i, j)) {
      // eq. 4.7: the pixel bounds the reflectivity at elevation θ by I/B(θ)²; eq. 4.6: keep the
      // minimum over frames (an unknown voxel takes the bound).
      const float bound = image_.at(i, j) * g_.inv_power(s);
      if (!std::isfinite(bound)) return false;
      if (track_span_) note_span(c, n, s, !on);
      if (on && !(bound < v[n])) return false;
      v[n] = bound;
      c.leaf->setActiveState(n, true);
      return true;
    }
    if (i >= fr_.first_return_bin[j]) return false;  // empty pixel behind a return: maybe shadow
    // Fig. 4.5: an empty pixel with no return nearer on its beam carves (the whole voxel must be
    // in free space when a margin is set).
    if (delta_ > 0) {
      const double rho = std::sqrt(p.x() * p.x() + p.y() * p.y());
      if (!fp_.ball_free(r, s, rho, phi, delta_)) return false;
    }
    if (on && v[n] == 0.0f) return false;
    v[n] = 0.0f;
    c.leaf->setActiveState(n, true);
    return true;
  }

  static constexpr int kVoxelLevel = 4;  // cubes of this edge are projected voxel by voxel

  const detail::SonarGeometry& g_;
  const detail::FrameFootprint& fp_;
  const FrameReturns& fr_;
  const SonarImage& image_;
  double vs_, delta_ = 0;
  CoordBBox clip_;
  bool track_span_ = false, min_span_needed_ = false;
  int min_obs_ = 1;
  Eigen::Vector3d step_[3];
  double r_min2_, r_max2_;
};

// The candidates of one map leaf as an occlusion block (sec. 4.4.5): voxels with a finite bound
// above `thr` that pass the observation filter (count >= min_obs, elevation span >= min_span)
// when observations are tracked (`span_tracked`). Returns false when the leaf holds none.
bool extract_block(const LeafT& leaf, const SpanLeafT* sl, bool span_tracked, float thr,
                   int min_obs, int min_span, double vs, detail::CandidateBlock& b) {
  Eigen::AlignedBox3i box;
  for (auto it = leaf.cbeginValueOn(); it; ++it) {
    const float v = *it;
    if (!(v > 0.0f && v > thr && std::isfinite(v))) continue;
    if (span_tracked) {
      if (!sl || !sl->isValueOn(it.pos())) continue;
      const Observations o = unpack_obs(sl->getValue(it.pos()));
      if (o.count < min_obs || o.hi - o.lo < min_span) continue;
    }
    const openvdb::Index n = it.pos();
    b.mask[n >> 6] |= std::uint64_t{1} << (n & 63);
    box.extend(Eigen::Vector3i(static_cast<int>(n >> 6), static_cast<int>((n >> 3) & 7),
                               static_cast<int>(n & 7)));
  }
  if (box.isEmpty()) return false;
  const Coord o = leaf.origin();
  b.origin_index = {o.x(), o.y(), o.z()};
  b.centre_world =
      (Eigen::Vector3d(o.x(), o.y(), o.z()) + 0.5 * (box.min() + box.max()).cast<double>()) * vs;
  b.radius = 0.5 * (box.max() - box.min()).cast<double>().norm() * vs + 1e-5;
  return true;
}

struct CoordHash {
  std::size_t operator()(const Coord& c) const {
    return (static_cast<std::size_t>(static_cast<std::uint32_t>(c.x())) * 73856093u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(c.y())) * 19349663u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(c.z())) * 83492791u);
  }
};

// A leaf's box of voxel indices.
CoordBBox leaf_box(const Coord& o) { return CoordBBox(o, o.offsetBy(kLeafDim - 1)); }

// The world points (voxel centres, float as snapshot() gives them) and bounds of a leaf's kept
// candidates, appended to `out`.
void emit_kept(const LeafT& leaf, const detail::BlockMask& kept, double vs, PointCloud& out) {
  const Coord o = leaf.origin();
  for (int w = 0; w < 8; ++w) {
    for (std::uint64_t bits = kept[w]; bits; bits &= bits - 1) {
      const auto n = static_cast<openvdb::Index>(w * 64 + __builtin_ctzll(bits));
      out.points.emplace_back(static_cast<float>((o.x() + static_cast<int>(n >> 6)) * vs),
                              static_cast<float>((o.y() + static_cast<int>((n >> 3) & 7)) * vs),
                              static_cast<float>((o.z() + static_cast<int>(n & 7)) * vs));
      out.intensity.push_back(leaf.getValue(n));
    }
  }
}

}  // namespace

void validate_region(const Eigen::AlignedBox3d& region, const std::string& name) {
  require(region.min().allFinite() && region.max().allFinite(),
          "parameter '" + name + "' must have finite corners");
  require((region.max().array() > region.min().array()).all(),
          "parameter '" + name + "': every max corner coordinate must exceed the min one");
}

void CarveConfig::validate() const {
  require_positive(voxel_size, "carve.voxel_size", "m");
  if (region) validate_region(*region, "carve.region");
  denoise.validate();
  occlusion.validate();
  require(std::isfinite(static_threshold), "parameter 'carve.static_threshold' must be finite");
  require(std::isfinite(carve_margin) && carve_margin >= 0 && carve_margin <= 1,
          "parameter 'carve.carve_margin' must lie in [0, 1], got " + std::to_string(carve_margin));
  require(
      std::isfinite(pose_sigma_position) && pose_sigma_position >= 0 && pose_sigma_position <= 10,
      "parameter 'carve.pose_sigma_position' must lie in [0, 10] m, got " +
          std::to_string(pose_sigma_position));
  require(std::isfinite(pose_sigma_attitude_deg) && pose_sigma_attitude_deg >= 0 &&
              pose_sigma_attitude_deg <= 30,
          "parameter 'carve.pose_sigma_attitude_deg' must lie in [0, 30] deg, got " +
              std::to_string(pose_sigma_attitude_deg));
  require(
      std::isfinite(pose_sigma_k) && pose_sigma_k > 0 && pose_sigma_k <= 10,
      "parameter 'carve.pose_sigma_k' must lie in (0, 10], got " + std::to_string(pose_sigma_k));
  require(std::isfinite(min_elevation_span) && min_elevation_span >= 0 && min_elevation_span <= 1,
          "parameter 'carve.min_elevation_span' must lie in [0, 1], got " +
              std::to_string(min_elevation_span));
  require(min_observations >= 1 && min_observations <= 255,
          "parameter 'carve.min_observations' must lie in [1, 255], got " +
              std::to_string(min_observations));
  require(num_threads >= 0, "parameter 'carve.num_threads' must be >= 0 (0 = all cores), got " +
                                std::to_string(num_threads));
  require(voxel_size >= limits::kMinVoxelSize,
          "parameter 'carve.voxel_size' must be >= 1e-05 m, got " + std::to_string(voxel_size));
  // Index space of the map: 32-bit voxel coordinates.
  if (region) {
    const double m = region->min().cwiseAbs().cwiseMax(region->max().cwiseAbs()).maxCoeff();
    require(m / voxel_size < 1e9, "parameter 'carve.region' is too large for carve.voxel_size");
  }
}

// Whether p_sonar lies in the sonar's field of view: range window, fan and vertical aperture.
bool in_wedge(const Eigen::Vector3d& p_sonar, const SonarSpec& spec) {
  const Polar q = sonar_to_polar(p_sonar);
  return q.range >= spec.r_min && q.range < spec.r_max && q.bearing >= spec.fov_min() &&
         q.bearing <= spec.fov_max() && std::abs(q.elevation) <= spec.theta_3db();
}

struct Carver::Impl {
  // Drops the span leaves of a cube that became free (nothing there is a candidate any more).
  void clear_span(const Coord& o, int s) {
    using Node1 = SpanTreeT::RootNodeType::ChildNodeType::ChildNodeType;  // 16³ leaves
    if (!span->probeConstNode<Node1>(o)) return;
    for (int x = 0; x < s; x += kLeafDim)
      for (int y = 0; y < s; y += kLeafDim)
        for (int z = 0; z < s; z += kLeafDim) {
          const Coord c = o.offsetBy(x, y, z);
          if (span->probeConstLeaf(c)) span->addTile(1, c, 0, false);
        }
  }

  SonarSpec spec;
  CarveConfig cfg;
  std::optional<NoiseImages> noise;
  std::unique_ptr<detail::SonarGeometry> geom;
  GridT::Ptr grid;
  SpanTreeT::Ptr span;  // observation records, when a filter on them is enabled
  std::vector<FrameReturns> frames;
  mutable tbb::task_arena arena;
  mutable CarveStats stats;
  CoordBBox roi;  // voxel index box of the region of interest (or everything)

  // Incremental occlusion resolution (resolve()): per frame, the voxel box its footprint covers
  // (padded by a voxel); the last n_new frames are not resolved yet; `pending` bounds the voxels
  // they changed and `removed` lists the leaves they collapsed to free tiles.
  std::vector<CoordBBox> frame_boxes;
  std::size_t n_new = 0;
  CoordBBox pending;
  std::vector<Coord> removed;
  struct Cached {
    detail::CandidateBlock block;  // the leaf's candidates (the filter as last resolved)
    detail::BlockMask kept{};      // those kept by occlusion resolution
  };
  std::unordered_map<Coord, Cached, CoordHash> cache;  // leaves holding candidates
  // Candidates of leaves evict_outside() took out, kept as occluders (never output again) while
  // a kept frame's box reaches them: a block left in the map that such a frame sees behind them
  // is still shadowed by them when it is resolved again, as in batch.
  std::unordered_map<Coord, detail::CandidateBlock, CoordHash> occluders;
  bool cache_valid = false;
  int cache_min_obs = 0;
  Carver::ResolveStats last_resolve;

  OcclusionConfig occlusion_config() const {
    OcclusionConfig occ = cfg.occlusion;
    occ.voxel_size = cfg.voxel_size;
    occ.num_threads = cfg.num_threads;
    occ.min_intensity = std::max(occ.min_intensity, cfg.static_threshold);
    return occ;
  }
  int min_span() const {
    return static_cast<int>(std::ceil(cfg.min_elevation_span * 2 * kObsScale));
  }
  void update_cache(int min_obs, Progress* progress);

  Impl(const SonarSpec& s, const CarveConfig& c, std::optional<NoiseImages> n)
      : spec(s),
        cfg(c),
        noise(std::move(n)),
        arena(c.num_threads > 0 ? c.num_threads : static_cast<int>(tbb::task_arena::automatic)) {}

  // Carves one frame; returns the voxel box it can have changed (empty when none).
  CoordBBox carve(const SonarImage& denoised, const FrameReturns& fr) {
    const detail::FrameFootprint fp(*geom, fr, &denoised);
    const double vs = cfg.voxel_size;
    const Eigen::AlignedBox3d wb = detail::footprint_bounds_world(*geom, fr.T_world_sonar);
    const double lim = 2e9;
    auto lo_idx = [&](double x) {
      return static_cast<int>(std::clamp(std::floor(x / vs), -lim, lim));
    };
    auto hi_idx = [&](double x) {
      return static_cast<int>(std::clamp(std::ceil(x / vs), -lim, lim));
    };
    CoordBBox box(Coord(lo_idx(wb.min().x()), lo_idx(wb.min().y()), lo_idx(wb.min().z())),
                  Coord(hi_idx(wb.max().x()), hi_idx(wb.max().y()), hi_idx(wb.max().z())));
    box.intersect(roi);
    if (box.empty()) return box;
    // The footprint's 32³ cubes are counted before one task (~100 bytes) is allocated for each:
    // a tiny voxel size without a region would ask for billions.
    double cubes = 1.0;
    for (int a = 0; a < 3; ++a) {
      cubes *= std::floor(static_cast<double>(box.max()[a]) / kTopDim) -
               std::floor(static_cast<double>(box.min()[a]) / kTopDim) + 1.0;
    }
    if (cubes > limits::kMaxCarveCubesPerFrame) {
      std::ostringstream os;
      os << "parameter 'carve.voxel_size' (" << vs << " m) is too fine for the volume one frame "
         << "of sonar '" << spec.name << "' covers: " << cubes << " map cubes of 32³ voxels, "
         << "more than the limit of " << limits::kMaxCarveCubesPerFrame
         << "; use a larger voxel size or a smaller region (--roi)";
      throw Error(os.str());
    }
    std::vector<Coord> tops;
    for (auto x = floor_div(box.min().x(), kTopDim) * kTopDim; x <= box.max().x(); x += kTopDim)
      for (auto y = floor_div(box.min().y(), kTopDim) * kTopDim; y <= box.max().y(); y += kTopDim)
        for (auto z = floor_div(box.min().z(), kTopDim) * kTopDim; z <= box.max().z(); z += kTopDim)
          tops.emplace_back(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z));
    // Navigation uncertainty: the largest displacement the pose error causes in the footprint.
    const double pose_margin =
        cfg.pose_sigma_k *
        (cfg.pose_sigma_position + spec.r_max * cfg.pose_sigma_attitude_deg * M_PI / 180.0);
    const FrameCarver carver(*geom, fp, denoised, vs, cfg.carve_margin, pose_margin, roi,
                             span != nullptr, cfg.min_observations, cfg.min_elevation_span > 0);
    std::vector<TaskOut> outs(tops.size());
    TreeT& tree = grid->tree();
    SpanTreeT scratch_span(0);
    SpanTreeT& span_tree = span ? *span : scratch_span;
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tops.size(), 1),
                        [&](const tbb::blocked_range<std::size_t>& rg) {
                          Accessor acc(tree);
                          SpanAccessor sacc(span_tree);
                          for (std::size_t t = rg.begin(); t < rg.end(); ++t)
                            carver.process_cube(acc, sacc, tops[t], kTopDim, outs[t]);
                        });
    });
    // Topology changes, serially.
    for (TaskOut& out : outs) {
      for (LeafT* leaf : out.new_leaves) tree.addLeaf(leaf);
      for (SpanLeafT* leaf : out.new_span_leaves) span_tree.addLeaf(leaf);
      for (const auto& [o, s] : out.free_cubes) {
        // Leaves the tile replaces (their candidates are gone: resolve() must know).
        for (int x = 0; x < s; x += kLeafDim)
          for (int y = 0; y < s; y += kLeafDim)
            for (int z = 0; z < s; z += kLeafDim)
              if (tree.probeConstLeaf(o.offsetBy(x, y, z))) removed.push_back(o.offsetBy(x, y, z));
        if (s == kNodeDim) {
          tree.addTile(2, o, 0.0f, true);
        } else if (s == kLeafDim) {
          tree.addTile(1, o, 0.0f, true);
        } else {
          for (int x = 0; x < s; x += kLeafDim)
            for (int y = 0; y < s; y += kLeafDim)
              for (int z = 0; z < s; z += kLeafDim)
                tree.addTile(1, o.offsetBy(x, y, z), 0.0f, true);
        }
        if (span) clear_span(o, s);
      }
      stats.leaf_voxels_visited += out.voxels;
    }
    return box;
  }
};

Carver::Carver(const SonarSpec& spec, const CarveConfig& config, std::optional<NoiseImages> noise)
    : impl_(std::make_unique<Impl>(spec, config, std::move(noise))) {
  spec.validate();
  config.validate();
  if (impl_->noise) {
    const auto& n = *impl_->noise;
    if (n.mean.rows != spec.range_bins || n.mean.cols != spec.beams() ||
        n.std.rows != spec.range_bins || n.std.cols != spec.beams()) {
      throw Error("carve: the noise statistics are " + std::to_string(n.mean.rows) + " × " +
                  std::to_string(n.mean.cols) + " but sonar '" + spec.name + "' images are " +
                  std::to_string(spec.range_bins) + " × " + std::to_string(spec.beams()));
    }
  }
  require(spec.range_bins < 65535,
          "carve: sonar '" + spec.name + "' has too many range bins (max 65534)");
  init_openvdb();
  impl_->geom = std::make_unique<detail::SonarGeometry>(impl_->spec);
  impl_->grid = GridT::create(kUnknown);
  impl_->grid->setName("carve_map");
  impl_->grid->setTransform(openvdb::math::Transform::createLinearTransform(config.voxel_size));
  impl_->grid->setGridClass(openvdb::GRID_UNKNOWN);
  if (config.min_elevation_span > 0 || config.min_observations > 1) {
    impl_->span = std::make_shared<SpanTreeT>(0);
  }
  if (config.region) {
    const double vs = config.voxel_size;
    const auto& r = *config.region;
    impl_->roi = CoordBBox(Coord(static_cast<int>(std::ceil(r.min().x() / vs)),
                                 static_cast<int>(std::ceil(r.min().y() / vs)),
                                 static_cast<int>(std::ceil(r.min().z() / vs))),
                           Coord(static_cast<int>(std::floor(r.max().x() / vs)),
                                 static_cast<int>(std::floor(r.max().y() / vs)),
                                 static_cast<int>(std::floor(r.max().z() / vs))));
  } else {
    impl_->roi = CoordBBox(Coord(-(1 << 30)), Coord((1 << 30) - 1));
  }
}

Carver::~Carver() = default;

void Carver::integrate(const SonarImage& image, const Eigen::Isometry3d& T_world_sonar,
                       const std::string& frame_label) {
  Impl& m = *impl_;
  const std::string who =
      frame_label.empty() ? "frame " + std::to_string(m.frames.size()) : frame_label;
  if (image.rows != m.spec.range_bins || image.cols != m.spec.beams()) {
    throw Error("carve: " + who + ": the image is " + std::to_string(image.rows) +
                " range bins × " + std::to_string(image.cols) + " beams but sonar '" + m.spec.name +
                "' has " + std::to_string(m.spec.range_bins) + " × " +
                std::to_string(m.spec.beams()));
  }
  if (!T_world_sonar.matrix().allFinite()) {
    throw Error("carve: " + who +
                ": the pose T_world_sonar is not finite (NaN or infinite); check the navigation");
  }
  if (!is_rigid(T_world_sonar)) {
    throw Error("carve: " + who + ": the pose T_world_sonar is not a rigid transform");
  }
  if (T_world_sonar.translation().cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
    throw Error("carve: " + who + ": the sonar lies more than 1e7 m from the origin");
  }
  const auto t0 = std::chrono::steady_clock::now();
  SonarImage denoised = image;
  denoise(denoised, m.noise, m.cfg.denoise);
  FrameReturns fr = summarize_frame(denoised, T_world_sonar, m.spec);
  CoordBBox box = m.carve(denoised, fr);
  if (!box.empty()) {
    box.expand(1);  // the float rounding of voxel positions (resolve())
    if (m.pending.empty()) {
      m.pending = box;
    } else {
      m.pending.expand(box);
    }
  }
  m.frame_boxes.push_back(box);
  ++m.n_new;
  m.frames.push_back(std::move(fr));
  m.stats.frames = m.frames.size();
  m.stats.integrate_seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

PointCloud Carver::snapshot() const {
  const Impl& m = *impl_;
  const TreeT& tree = m.grid->tree();
  openvdb::tree::LeafManager<const TreeT> leaves(tree);
  const float thr = static_cast<float>(m.cfg.static_threshold);
  // A candidate bounded by fewer than min_observations return pixels (an isolated noise pixel
  // that passed the Z-test) or observed over less than min_elevation_span of the aperture (never
  // bracketed by free space on both sides along its elevation arc: the ends of a pass) is
  // dropped.
  const int min_span = static_cast<int>(std::ceil(m.cfg.min_elevation_span * 2 * kObsScale));
  const int min_obs = min_observations_used();
  m.stats.min_observations_used = min_obs;
  auto keep_value = [thr](float v) { return v > 0.0f && v > thr && std::isfinite(v); };
  auto visit = [&](std::size_t l, auto&& emit) {
    const LeafT& leaf = leaves.leaf(l);
    const SpanLeafT* sl = m.span ? m.span->probeConstLeaf(leaf.origin()) : nullptr;
    for (auto it = leaf.cbeginValueOn(); it; ++it) {
      if (!keep_value(*it)) continue;
      if (m.span) {
        if (!sl || !sl->isValueOn(it.pos())) continue;
        const Observations o = unpack_obs(sl->getValue(it.pos()));
        if (o.count < min_obs || o.hi - o.lo < min_span) continue;
      }
      emit(it.getCoord(), *it);
    }
  };
  std::vector<std::size_t> counts(leaves.leafCount() + 1, 0);
  m.arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.leafCount()),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                        for (std::size_t l = rg.begin(); l < rg.end(); ++l) {
                          std::size_t c = 0;
                          visit(l, [&](const Coord&, float) { ++c; });
                          counts[l + 1] = c;
                        }
                      });
  });
  for (std::size_t l = 1; l < counts.size(); ++l) counts[l] += counts[l - 1];
  PointCloud cloud;
  cloud.points.resize(counts.back());
  cloud.intensity.resize(counts.back());
  const double vs = m.cfg.voxel_size;
  m.arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.leafCount()),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                        for (std::size_t l = rg.begin(); l < rg.end(); ++l) {
                          std::size_t k = counts[l];
                          visit(l, [&](const Coord& c, float v) {
                            cloud.points[k] = Eigen::Vector3f(static_cast<float>(c.x() * vs),
                                                              static_cast<float>(c.y() * vs),
                                                              static_cast<float>(c.z() * vs));
                            cloud.intensity[k] = v;
                            ++k;
                          });
                        }
                      });
  });
  m.stats.candidates = cloud.size();
  return cloud;
}

PointCloud Carver::finalize(Progress* progress) {
  Impl& m = *impl_;
  if (m.frames.empty()) throw Error("carve: nothing to finalize: no frame was integrated");
  if (!m.cfg.resolve_occlusions) {
    PointCloud candidates = snapshot();
    m.stats.points = candidates.size();
    return candidates;
  }
  OcclusionConfig occ = m.cfg.occlusion;
  occ.voxel_size = m.cfg.voxel_size;
  occ.num_threads = m.cfg.num_threads;
  occ.min_intensity = std::max(occ.min_intensity, m.cfg.static_threshold);
  const auto t0 = std::chrono::steady_clock::now();
  // The candidates stay in the map: each leaf holding some becomes one block (its origin and a
  // 512-bit mask), so occlusion resolution needs a few hundred bytes per leaf, not a point and a
  // sort entry per candidate (the never-carved interior of a large structure holds tens of
  // millions of candidates: docs/carving.md, "Memory").
  const TreeT& tree = m.grid->tree();
  openvdb::tree::LeafManager<const TreeT> leaves(tree);
  const float thr = static_cast<float>(occ.min_intensity);
  const int min_span = static_cast<int>(std::ceil(m.cfg.min_elevation_span * 2 * kObsScale));
  const int min_obs = min_observations_used();
  m.stats.min_observations_used = min_obs;
  const double vs = m.cfg.voxel_size;
  std::vector<detail::CandidateBlock> all(leaves.leafCount());
  std::vector<std::uint8_t> used(leaves.leafCount(), 0);
  m.arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, leaves.leafCount(), [&](std::size_t l) {
      const LeafT& leaf = leaves.leaf(l);
      const SpanLeafT* sl = m.span ? m.span->probeConstLeaf(leaf.origin()) : nullptr;
      if (extract_block(leaf, sl, m.span != nullptr, thr, min_obs, min_span, vs, all[l]))
        used[l] = 1;
    });
  });
  std::vector<detail::CandidateBlock> blocks;
  std::vector<std::size_t> leaf_of;
  std::size_t candidates = 0;
  for (std::size_t l = 0; l < all.size(); ++l) {
    if (!used[l]) continue;
    for (auto w : all[l].mask) candidates += static_cast<std::size_t>(__builtin_popcountll(w));
    blocks.push_back(all[l]);
    leaf_of.push_back(l);
  }
  all = {};
  used = {};
  m.stats.candidates = candidates;
  m.stats.occlusion_bytes = blocks.capacity() * sizeof(detail::CandidateBlock) +
                            blocks.size() * (3 * sizeof(detail::BlockMask) + sizeof(std::size_t));
  const std::vector<detail::BlockMask> kept =
      detail::resolve_occlusion_blocks(blocks, m.frames, m.spec, occ, progress);
  PointCloud out;
  for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
    const LeafT& leaf = leaves.leaf(leaf_of[bi]);
    const Coord o = leaf.origin();
    for (int w = 0; w < 8; ++w) {
      for (std::uint64_t bits = kept[bi][w]; bits; bits &= bits - 1) {
        const auto n = static_cast<openvdb::Index>(w * 64 + __builtin_ctzll(bits));
        out.points.emplace_back(static_cast<float>((o.x() + static_cast<int>(n >> 6)) * vs),
                                static_cast<float>((o.y() + static_cast<int>((n >> 3) & 7)) * vs),
                                static_cast<float>((o.z() + static_cast<int>(n & 7)) * vs));
        out.intensity.push_back(leaf.getValue(n));
      }
    }
  }
  if (occ.explain_returns) out = drop_unexplained(out, m.frames, m.spec, occ, &m.stats.ghosts);
  m.stats.occlusion_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.stats.points = out.size();
  return out;
}

void Carver::Impl::update_cache(int min_obs, Progress* progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const OcclusionConfig occ = occlusion_config();
  const float thr = static_cast<float>(occ.min_intensity);
  const int mspan = min_span();
  const double vs = cfg.voxel_size;
  const TreeT& tree = grid->tree();
  const bool full = !cache_valid || min_obs != cache_min_obs;
  last_resolve = Carver::ResolveStats{};
  last_resolve.full = full;
  if (!full && n_new == 0 && pending.empty() && removed.empty()) {
    last_resolve.cached = cache.size();
    return;  // nothing changed since the last resolution
  }
  // 1. The candidates of the leaves the new frames can have changed (all, when full), compared
  // with the cached ones: `changed` lists the leaves whose candidate set differs.
  openvdb::tree::LeafManager<const TreeT> leaves(tree);
  std::vector<detail::CandidateBlock> fresh(leaves.leafCount());
  std::vector<std::uint8_t> state(leaves.leafCount(), 0);  // 1 = in the changed box, 2 = + has
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, leaves.leafCount(), [&](std::size_t l) {
      const LeafT& leaf = leaves.leaf(l);
      if (!full && !pending.hasOverlap(leaf_box(leaf.origin()))) return;
      const SpanLeafT* sl = span ? span->probeConstLeaf(leaf.origin()) : nullptr;
      state[l] =
          extract_block(leaf, sl, span != nullptr, thr, min_obs, mspan, vs, fresh[l]) ? 2 : 1;
    });
  });
  std::vector<Coord> changed;
  if (full) cache.clear();
  for (const Coord& o : removed) {
    if (cache.erase(o)) changed.push_back(o);
  }
  for (std::size_t l = 0; l < leaves.leafCount(); ++l) {
    if (!state[l]) continue;
    const Coord o = leaves.leaf(l).origin();
    auto it = cache.find(o);
    if (state[l] == 1) {  // no candidate left here
      if (it != cache.end()) {
        cache.erase(it);
        changed.push_back(o);
      }
      continue;
    }
    if (it == cache.end()) {
      cache.emplace(o, Cached{fresh[l], {}});
      changed.push_back(o);
    } else if (it->second.block.mask != fresh[l].mask) {
      it->second.block = fresh[l];
      changed.push_back(o);
    } else {
      it->second.block = fresh[l];
    }
  }
  fresh = {};
  state = {};
  removed.clear();
  const std::size_t nf = frames.size();
  const std::size_t first_new = nf - std::min(n_new, nf);
  // 2. The frames whose results can change: the new ones, and the old ones that see a changed
  // leaf (their depth grids changed). The blocks to redo, D, lie in their footprints (or are
  // changed leaves). 3. Every frame that sees D tests it; all the candidates in those frames'
  // footprints are occluders (E).
  std::vector<const FrameReturns*> use;
  CoordBBox dbox, ebox;
  if (full) {
    use = detail::frame_pointers(frames);
  } else {
    CoordBBox cbox;
    // Changed leaves bucketed in 128³ cells for the frame tests.
    std::unordered_map<Coord, CoordBBox, CoordHash> cells;
    for (const Coord& o : changed) {
      const CoordBBox lb = leaf_box(o);
      cbox.expand(lb);
      const Coord cell(static_cast<int>(floor_div(o.x(), kNodeDim)),
                       static_cast<int>(floor_div(o.y(), kNodeDim)),
                       static_cast<int>(floor_div(o.z(), kNodeDim)));
      auto [it, fresh_cell] = cells.emplace(cell, lb);
      if (!fresh_cell) it->second.expand(lb);
    }
    if (!changed.empty()) dbox = cbox;
    auto sees_changed = [&](const CoordBBox& fb) {
      if (changed.empty() || fb.empty() || !cbox.hasOverlap(fb)) return false;
      for (const auto& [cell, cb] : cells)
        if (cb.hasOverlap(fb)) return true;
      return false;
    };
    for (std::size_t f = 0; f < nf; ++f) {
      const CoordBBox& fb = frame_boxes[f];
      if (fb.empty()) continue;
      if (f >= first_new || sees_changed(fb)) {
        if (dbox.empty()) {
          dbox = fb;
        } else {
          dbox.expand(fb);
        }
      }
    }
    if (!dbox.empty()) {
      for (std::size_t f = 0; f < nf; ++f) {
        const CoordBBox& fb = frame_boxes[f];
        if (fb.empty() || !fb.hasOverlap(dbox)) continue;
        use.push_back(&frames[f]);
        if (ebox.empty()) {
          ebox = fb;
        } else {
          ebox.expand(fb);
        }
      }
    }
  }
  // 4. Resolve D against those frames with E as occluders; keep D's results.
  std::vector<detail::CandidateBlock> blocks;
  std::vector<Cached*> target;  // per block: the cache entry to update (null: context only)
  for (auto& [o, c] : cache) {
    const CoordBBox lb = leaf_box(o);
    if (full || (!ebox.empty() && ebox.hasOverlap(lb))) {
      blocks.push_back(c.block);
      target.push_back(full || dbox.hasOverlap(lb) ? &c : nullptr);
    }
  }
  for (const auto& [o, b] : occluders) {
    if (cache.count(o)) continue;  // mapped again (a revisit): the live block counts
    if (full || (!ebox.empty() && ebox.hasOverlap(leaf_box(o)))) {
      blocks.push_back(b);
      target.push_back(nullptr);
    }
  }
  std::size_t redo = 0;
  for (Cached* t : target) {
    if (t) {
      t->kept = {};
      ++redo;
    }
  }
  if (!blocks.empty() && !use.empty()) {
    const std::vector<detail::BlockMask> kept =
        detail::resolve_occlusion_blocks(blocks, use, spec, occ, progress);
    for (std::size_t b = 0; b < blocks.size(); ++b)
      if (target[b]) target[b]->kept = kept[b];
  }
  cache_valid = true;
  cache_min_obs = min_obs;
  n_new = 0;
  pending = CoordBBox();
  last_resolve.blocks = redo;
  last_resolve.context = blocks.size();
  last_resolve.frames = use.size();
  last_resolve.cached = cache.size();
  last_resolve.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

PointCloud Carver::resolve(Progress* progress) {
  Impl& m = *impl_;
  if (m.frames.empty()) throw Error("carve: nothing to resolve: no frame was integrated");
  if (!m.cfg.resolve_occlusions) {
    PointCloud candidates = snapshot();
    m.stats.points = candidates.size();
    return candidates;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const int min_obs = min_observations_used();
  m.stats.min_observations_used = min_obs;
  m.update_cache(min_obs, progress);
  // The cloud in finalize()'s order: the map's leaves in tree order, bits ascending.
  const TreeT& tree = m.grid->tree();
  openvdb::tree::LeafManager<const TreeT> leaves(tree);
  std::vector<const Impl::Cached*> entry(leaves.leafCount(), nullptr);
  std::size_t candidates = 0;
  for (std::size_t l = 0; l < leaves.leafCount(); ++l) {
    auto it = m.cache.find(leaves.leaf(l).origin());
    if (it == m.cache.end()) continue;
    entry[l] = &it->second;
    for (auto w : it->second.block.mask)
      candidates += static_cast<std::size_t>(__builtin_popcountll(w));
  }
  PointCloud out;
  for (std::size_t l = 0; l < leaves.leafCount(); ++l)
    if (entry[l]) emit_kept(leaves.leaf(l), entry[l]->kept, m.cfg.voxel_size, out);
  const OcclusionConfig occ = m.occlusion_config();
  if (occ.explain_returns) out = drop_unexplained(out, m.frames, m.spec, occ, &m.stats.ghosts);
  m.stats.candidates = candidates;
  m.stats.occlusion_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.stats.points = out.size();
  return out;
}

const Carver::ResolveStats& Carver::last_resolve() const { return impl_->last_resolve; }

PointCloud Carver::evict_outside(const Eigen::AlignedBox3d& keep, std::size_t* frames_dropped) {
  validate_region(keep, "keep");
  Impl& m = *impl_;
  if (frames_dropped) *frames_dropped = 0;
  PointCloud out;
  if (m.frames.empty()) return out;
  const double vs = m.cfg.voxel_size;
  // The kept voxels, grown to whole leaves: a leaf partly inside stays whole.
  auto lo = [&](double x) {
    const auto i = static_cast<std::int64_t>(std::floor(std::clamp(x / vs, -1e9, 1e9)));
    return static_cast<int>(floor_div(i, kLeafDim) * kLeafDim);
  };
  auto hi = [&](double x) {
    const auto i = static_cast<std::int64_t>(std::ceil(std::clamp(x / vs, -1e9, 1e9)));
    return static_cast<int>(floor_div(i, kLeafDim) * kLeafDim + kLeafDim - 1);
  };
  const CoordBBox kbox(Coord(lo(keep.min().x()), lo(keep.min().y()), lo(keep.min().z())),
                       Coord(hi(keep.max().x()), hi(keep.max().y()), hi(keep.max().z())));
  if (m.cfg.resolve_occlusions) {
    const int min_obs = min_observations_used();
    m.stats.min_observations_used = min_obs;
    m.update_cache(min_obs, nullptr);
  }
  TreeT& tree = m.grid->tree();
  {
    // Finished leaves, in tree order.
    openvdb::tree::LeafManager<const TreeT> leaves(tree);
    const float thr = static_cast<float>(m.occlusion_config().min_intensity);
    const int min_obs = m.cfg.resolve_occlusions ? m.cache_min_obs : min_observations_used();
    for (std::size_t l = 0; l < leaves.leafCount(); ++l) {
      const LeafT& leaf = leaves.leaf(l);
      if (kbox.hasOverlap(leaf_box(leaf.origin()))) continue;
      if (m.cfg.resolve_occlusions) {
        auto it = m.cache.find(leaf.origin());
        if (it == m.cache.end()) continue;
        emit_kept(leaf, it->second.kept, vs, out);
      } else {
        detail::CandidateBlock b;
        const SpanLeafT* sl = m.span ? m.span->probeConstLeaf(leaf.origin()) : nullptr;
        if (extract_block(leaf, sl, m.span != nullptr, thr, min_obs, m.min_span(), vs, b))
          emit_kept(leaf, b.mask, vs, out);
      }
    }
  }
  for (auto it = m.cache.begin(); it != m.cache.end();) {
    if (kbox.hasOverlap(leaf_box(it->first))) {
      ++it;
    } else {
      m.occluders.emplace(it->first, it->second.block);
      it = m.cache.erase(it);
    }
  }
  tree.clip(kbox);
  if (m.span) m.span->clip(kbox);
  m.removed.erase(std::remove_if(m.removed.begin(), m.removed.end(),
                                 [&](const Coord& o) { return !kbox.hasOverlap(leaf_box(o)); }),
                  m.removed.end());
  if (!m.pending.empty()) m.pending.intersect(kbox);
  // Frames that see nothing left. The unresolved (newest) frames stay in order at the end.
  std::size_t w = 0;
  const std::size_t nf = m.frames.size(), first_new = nf - std::min(m.n_new, nf);
  std::size_t kept_new = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    const bool keep_frame = !m.frame_boxes[f].empty() && m.frame_boxes[f].hasOverlap(kbox);
    if (!keep_frame) continue;
    if (f >= first_new) ++kept_new;
    if (w != f) {
      m.frames[w] = std::move(m.frames[f]);
      m.frame_boxes[w] = m.frame_boxes[f];
    }
    ++w;
  }
  if (frames_dropped) *frames_dropped = nf - w;
  m.frames.resize(w);
  m.frame_boxes.resize(w);
  m.n_new = kept_new;
  // Occluders no kept frame can see any more.
  CoordBBox reach;
  for (const CoordBBox& fb : m.frame_boxes) {
    if (fb.empty()) continue;
    if (reach.empty()) {
      reach = fb;
    } else {
      reach.expand(fb);
    }
  }
  for (auto it = m.occluders.begin(); it != m.occluders.end();) {
    if (!reach.empty() && reach.hasOverlap(leaf_box(it->first))) {
      ++it;
    } else {
      it = m.occluders.erase(it);
    }
  }
  return out;
}

void Carver::write_vdb(const std::string& path, const PointCloud* surface) const {
  const Impl& m = *impl_;
  init_openvdb();
  openvdb::GridPtrVec grids;
  GridT::Ptr map = m.grid->deepCopy();
  // Unknown voxels are the inactive ones; a background of 0 reads better in viewers than +inf.
  openvdb::tools::changeBackground(map->tree(), 0.0f);
  map->setName("carve_map");
  map->insertMeta("description", openvdb::StringMetadata(
                                     "sonar3d space carving map: active 0 = free, active v > 0 "
                                     "= reflectivity bound (eq. 4.6), inactive = unknown"));
  grids.push_back(map);
  if (surface) {
    GridT::Ptr s = GridT::create(0.0f);
    s->setName("surface");
    s->setTransform(openvdb::math::Transform::createLinearTransform(m.cfg.voxel_size));
    auto acc = s->getAccessor();
    const double inv = 1.0 / m.cfg.voxel_size;
    for (std::size_t n = 0; n < surface->size(); ++n) {
      const Eigen::Vector3f& p = surface->points[n];
      const Coord c(static_cast<int>(std::floor(p.x() * inv + 0.5)),
                    static_cast<int>(std::floor(p.y() * inv + 0.5)),
                    static_cast<int>(std::floor(p.z() * inv + 0.5)));
      acc.setValueOn(c, surface->has_intensity() ? surface->intensity[n] : 1.0f);
    }
    grids.push_back(s);
  }
  AtomicPath out(path);
  try {
    openvdb::io::File file(out.temp().string());
    openvdb::MetaMap meta;  // is_sonar3d_output(OutputKind::VoxelMap) looks for it
    meta.insertMeta("creator", openvdb::StringMetadata("sonar3d-voxel-map"));
    file.write(grids, meta);
    file.close();
  } catch (const openvdb::Exception& e) {
    throw Error("cannot write '" + path + "': " + e.what());
  }
  out.commit();
}

std::size_t Carver::frames() const { return impl_->frames.size(); }

std::size_t Carver::memory_bytes() const {
  const Impl& m = *impl_;
  std::size_t b = static_cast<std::size_t>(m.grid->memUsage()) +
                  (m.span ? static_cast<std::size_t>(m.span->memUsage()) : 0);
  b += m.frames.capacity() * sizeof(FrameReturns) + m.frame_boxes.capacity() * sizeof(CoordBBox);
  for (const auto& f : m.frames) b += f.memory_bytes() - sizeof(FrameReturns);
  b += m.cache.size() * (sizeof(Impl::Cached) + sizeof(Coord) + 2 * sizeof(void*)) +
       m.cache.bucket_count() * sizeof(void*);
  b += m.occluders.size() * (sizeof(detail::CandidateBlock) + sizeof(Coord) + 2 * sizeof(void*)) +
       m.occluders.bucket_count() * sizeof(void*);
  return b;
}

int Carver::min_observations_used() const {
  // The number of frames that see a scatterer: for up to 256 frames spread over the sequence,
  // the point on the boresight at mid range, counted in every frame's field of view. The median
  // is independent of the frame order and of what the scene holds (only poses are used).
  const Impl& m = *impl_;
  const std::size_t n = m.frames.size();
  m.stats.views_per_scatterer = 0;
  if (n < 2) return 1;  // one frame: nothing can be seen twice
  std::vector<Eigen::Isometry3d> T_sonar_world(n);
  for (std::size_t j = 0; j < n; ++j) T_sonar_world[j] = m.frames[j].T_world_sonar.inverse();
  const double r_mid = 0.5 * (m.spec.r_min + m.spec.r_max);
  const std::size_t samples = std::min<std::size_t>(n, 256);
  std::vector<int> views(samples, 0);
  m.arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, samples, [&](std::size_t s) {
      const std::size_t k = s * n / samples;
      const Eigen::Vector3d p_world = m.frames[k].T_world_sonar * Eigen::Vector3d(r_mid, 0, 0);
      for (std::size_t j = 0; j < n; ++j) views[s] += in_wedge(T_sonar_world[j] * p_world, m.spec);
    });
  });
  std::nth_element(views.begin(), views.begin() + samples / 2, views.end());
  const int median = views[samples / 2];
  m.stats.views_per_scatterer = median;
  return std::max(1, std::min(m.cfg.min_observations, median));
}
const std::vector<FrameReturns>& Carver::frame_returns() const { return impl_->frames; }
const SonarSpec& Carver::spec() const { return impl_->spec; }
const CarveConfig& Carver::config() const { return impl_->cfg; }

const CarveStats& Carver::stats() const {
  const Impl& m = *impl_;
  m.stats.map_bytes = static_cast<std::size_t>(m.grid->memUsage()) +
                      (m.span ? static_cast<std::size_t>(m.span->memUsage()) : 0);
  std::size_t fb = m.frames.capacity() * sizeof(FrameReturns);
  for (const auto& f : m.frames) fb += f.memory_bytes() - sizeof(FrameReturns);
  m.stats.frame_bytes = fb;
  const TreeT& tree = m.grid->tree();
  m.stats.active_voxels = static_cast<std::size_t>(tree.activeVoxelCount());
  m.stats.leaves = static_cast<std::size_t>(tree.leafCount());
  std::size_t cand = 0;
  for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf)
    for (auto it = leaf->cbeginValueOn(); it; ++it) cand += *it > 0.0f;
  m.stats.candidate_voxels = cand;
  return m.stats;
}

void integrate_dataset(Carver& carver, const Dataset& ds, bool progress) {
  if (ds.size() == 0) {
    throw Error("dataset '" + ds.root.string() + "' has no frames: nothing to reconstruct");
  }
  Progress bar("carve", ds.size(), progress);
  integrate_frames(carver, ds, 0, ds.size() - 1, &bar);
  bar.finish();
}

void integrate_frames(Carver& carver, const Dataset& ds, std::size_t first, std::size_t last,
                      Progress* bar) {
  require(first <= last && last < ds.size(), "integrate_frames: frames " + std::to_string(first) +
                                                 "–" + std::to_string(last) +
                                                 " do not lie in dataset '" + ds.root.string() +
                                                 "' (" + std::to_string(ds.size()) + " frames)");
  struct Item {
    std::size_t i = 0;
    SonarImage image;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  };
  std::size_t next = first;
  const int threads = carver.config().num_threads;
  tbb::task_arena arena(threads > 0 ? threads : static_cast<int>(tbb::task_arena::automatic));
  // No exception may leave a filter: TBB then cancels the pipeline and leaks the items already
  // in flight between filters (seen under LeakSanitizer with a missing middle frame). Errors are
  // kept instead, the input stops, and the first frame's error in frame order is rethrown.
  std::mutex error_mutex;
  std::exception_ptr error;
  std::size_t error_frame = ds.size();
  std::atomic<bool> failed{false};
  auto keep_error = [&](std::size_t i) {
    std::lock_guard<std::mutex> lock(error_mutex);
    if (i < error_frame) {
      error_frame = i;
      error = std::current_exception();
    }
    failed = true;
  };
  arena.execute([&] {
    tbb::parallel_pipeline(
        static_cast<std::size_t>(2 * arena.max_concurrency() + 2),
        tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                            [&](tbb::flow_control& fc) -> std::size_t {
                                              if (failed || next > last) {
                                                fc.stop();
                                                return 0;
                                              }
                                              return next++;
                                            }) &
            tbb::make_filter<std::size_t, std::shared_ptr<Item>>(
                tbb::filter_mode::parallel,
                [&](std::size_t i) -> std::shared_ptr<Item> {
                  if (failed) return nullptr;
                  try {
                    auto item = std::make_shared<Item>();
                    item->i = i;
                    item->image = ds.load_frame(i);  // errors name the file
                    item->T = ds.T_world_sonar(i);   // errors name the frame
                    return item;
                  } catch (...) {
                    keep_error(i);
                    return nullptr;
                  }
                }) &
            tbb::make_filter<std::shared_ptr<Item>, void>(
                tbb::filter_mode::serial_in_order, [&](const std::shared_ptr<Item>& item) {
                  if (!item || failed) return;
                  try {
                    carver.integrate(item->image, item->T,
                                     "frame " + std::to_string(ds.frames[item->i].index) + " (" +
                                         ds.frames[item->i].file + ")");
                    if (bar) bar->add();
                  } catch (...) {
                    keep_error(item->i);
                  }
                }));
  });
  if (error) std::rethrow_exception(error);
}

std::size_t peak_rss_bytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("VmHWM:", 0) == 0) {
      std::istringstream is(line.substr(6));
      std::size_t kb = 0;
      is >> kb;
      return kb * 1024;
    }
  }
  return 0;
}

}  // namespace sonar3d
