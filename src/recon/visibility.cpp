#include "sonar3d/recon/visibility.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <string>

#include "carve_footprint.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

std::size_t FrameReturns::memory_bytes() const {
  return sizeof(*this) + first_return_bin.capacity() * sizeof(int) +
         last_return_bin.capacity() * sizeof(int) + return_bits.capacity() * sizeof(std::uint64_t);
}

bool FrameReturns::any_return(int beam, int bin0, int bin1) const {
  bin0 = std::max(bin0, 0);
  bin1 = std::min(bin1, range_bins - 1);
  if (bin0 > bin1 || beam < 0 || beam >= beams) return false;
  const std::uint64_t* w = &return_bits[static_cast<std::size_t>(beam) * words_per_beam];
  for (int word = bin0 >> 6; word <= (bin1 >> 6); ++word) {
    const int lo = std::max(bin0 - word * 64, 0), hi = std::min(bin1 - word * 64, 63);
    const std::uint64_t mask =
        (hi == 63 ? ~std::uint64_t{0} : ((std::uint64_t{1} << (hi + 1)) - 1)) &
        ~((std::uint64_t{1} << lo) - 1);
    if (w[word] & mask) return true;
  }
  return false;
}

FrameReturns summarize_frame(const SonarImage& denoised, const Eigen::Isometry3d& T_world_sonar,
                             const SonarSpec& spec) {
  if (denoised.rows != spec.range_bins || denoised.cols != spec.beams()) {
    throw Error("summarize_frame: the image is " + std::to_string(denoised.rows) +
                " range bins × " + std::to_string(denoised.cols) + " beams but sonar '" +
                spec.name + "' has " + std::to_string(spec.range_bins) + " × " +
                std::to_string(spec.beams()));
  }
  if (!T_world_sonar.matrix().allFinite()) {
    throw Error("summarize_frame: the pose T_world_sonar is not finite (NaN or infinite)");
  }
  if (!is_rigid(T_world_sonar)) {
    throw Error("summarize_frame: the pose T_world_sonar is not a rigid transform");
  }
  FrameReturns f;
  f.T_world_sonar = T_world_sonar;
  f.range_bins = spec.range_bins;
  f.beams = spec.beams();
  f.words_per_beam = (f.range_bins + 63) / 64;
  f.first_return_bin.assign(f.beams, f.range_bins);
  f.last_return_bin.assign(f.beams, -1);
  f.return_bits.assign(static_cast<std::size_t>(f.beams) * f.words_per_beam, 0);
  for (int i = 0; i < denoised.rows; ++i) {
    const float* row = denoised.row_ptr(i);
    for (int j = 0; j < denoised.cols; ++j) {
      if (!(row[j] > 0.0f)) continue;  // zero (or NaN): no return
      f.return_bits[static_cast<std::size_t>(j) * f.words_per_beam + (i >> 6)] |= std::uint64_t{1}
                                                                                  << (i & 63);
      if (f.first_return_bin[j] == f.range_bins) f.first_return_bin[j] = i;
      f.last_return_bin[j] = i;
    }
  }
  return f;
}

bool seen_free(const FrameReturns& frame, const SonarSpec& spec, const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d p_sonar = frame.T_world_sonar.inverse() * p_world;
  const Polar q = sonar_to_polar(p_sonar);
  if (std::abs(q.elevation) > spec.theta_3db()) return false;  // outside the aperture
  const int i = spec.bin_of_range(q.range);
  const int j = spec.beam_of_bearing(q.bearing);
  if (i < 0 || j < 0) return false;
  // Fig. 4.5: free only in front of the beam's first return (an empty pixel behind a return may
  // be a shadow).
  return i < frame.first_return_bin[j];
}

void OcclusionConfig::validate() const {
  require_positive(elevation_resolution_rad, "occlusion.elevation_resolution", "rad");
  require_positive(voxel_size, "occlusion.voxel_size", "m");
  require(std::isfinite(min_intensity), "parameter 'occlusion.min_intensity' must be finite");
  require_non_negative(footprint_radius, "occlusion.footprint_radius", "voxels");
  require(range_tolerance_bins >= 0,
          "parameter 'occlusion.range_tolerance_bins' must be >= 0, got " +
              std::to_string(range_tolerance_bins));
  require(num_threads >= 0, "parameter 'occlusion.num_threads' must be >= 0 (0 = all cores), got " +
                                std::to_string(num_threads));
}

namespace {

struct VoxelKey {
  std::int64_t x, y, z;
  bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
VoxelKey key_of(const Eigen::Vector3f& p, double inv_size) {
  return {static_cast<std::int64_t>(std::floor(p.x() * inv_size + 0.5)),
          static_cast<std::int64_t>(std::floor(p.y() * inv_size + 0.5)),
          static_cast<std::int64_t>(std::floor(p.z() * inv_size + 0.5))};
}

// Candidates grouped in cubes so that a frame skips, in one test, those that cannot lie in one
// of its return pixels.
struct Block {
  Eigen::Vector3d centre_world;
  double radius = 0;
  std::size_t begin = 0, end = 0;  // into the sorted candidate index list
};

struct Hit {
  std::uint32_t candidate;  // index into the deduplicated candidates
  std::uint32_t cell;       // beam · K + elevation interval of the candidate's centre
  std::int32_t bin;         // range bin
};

}  // namespace

PointCloud resolve_occlusions(const PointCloud& candidates_world,
                              const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                              const OcclusionConfig& config, Progress* progress) {
  config.validate();
  spec.validate();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const auto& fr = frames[f];
    if (fr.range_bins != spec.range_bins || fr.beams != spec.beams() ||
        static_cast<int>(fr.first_return_bin.size()) != spec.beams()) {
      throw Error("resolve_occlusions: frame " + std::to_string(f) +
                  " was summarized for another sonar (size differs from '" + spec.name + "')");
    }
  }
  const bool has_i = candidates_world.has_intensity();
  if (has_i && candidates_world.intensity.size() != candidates_world.size()) {
    throw Error("resolve_occlusions: the candidate cloud has " +
                std::to_string(candidates_world.intensity.size()) + " intensities for " +
                std::to_string(candidates_world.size()) + " points");
  }

  // One candidate per voxel, the lowest bound (carving rule, eq. 4.6), above the threshold; sorted
  // block-major (blocks of 8³ voxels) so that a frame skips, in one test, the blocks that cannot
  // lie in one of its return pixels.
  const double inv_vs = 1.0 / config.voxel_size;
  struct Entry {
    std::int64_t bx, by, bz;  // block
    int in;                   // voxel inside the block
    float v;
    std::uint32_t idx;
  };
  std::vector<Entry> entries;
  entries.reserve(candidates_world.size());
  for (std::size_t n = 0; n < candidates_world.size(); ++n) {
    const Eigen::Vector3f& p = candidates_world.points[n];
    if (!p.allFinite()) continue;
    const float v = has_i ? candidates_world.intensity[n] : 0.0f;
    if (has_i && !(v > config.min_intensity)) continue;
    const VoxelKey k = key_of(p, inv_vs);
    entries.push_back({k.x >> 3, k.y >> 3, k.z >> 3,
                       static_cast<int>(((k.x & 7) << 6) | ((k.y & 7) << 3) | (k.z & 7)), v,
                       static_cast<std::uint32_t>(n)});
  }
  tbb::parallel_sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return std::tie(a.bx, a.by, a.bz, a.in, a.v, a.idx) <
           std::tie(b.bx, b.by, b.bz, b.in, b.v, b.idx);
  });
  std::vector<std::uint32_t> cand;  // candidate point indices, block-major, one per voxel
  std::vector<Block> blocks;
  cand.reserve(entries.size());
  for (std::size_t e = 0; e < entries.size();) {
    Block b;
    b.begin = cand.size();
    Eigen::AlignedBox3d box;
    std::size_t f = e;
    for (; f < entries.size() && entries[f].bx == entries[e].bx && entries[f].by == entries[e].by &&
           entries[f].bz == entries[e].bz;
         ++f) {
      if (f > e && entries[f].in == entries[f - 1].in) continue;  // same voxel: higher bound
      cand.push_back(entries[f].idx);
      box.extend(candidates_world.points[entries[f].idx].cast<double>());
    }
    b.end = cand.size();
    b.centre_world = box.center();
    b.radius = 0.5 * box.diagonal().norm() + 1e-6;
    blocks.push_back(b);
    e = f;
  }
  entries = {};
  std::vector<std::uint32_t> order(cand.size());
  std::iota(order.begin(), order.end(), 0u);

  const detail::SonarGeometry g(spec);
  const double dtheta = config.elevation_resolution_rad;
  const int K = std::max(1, static_cast<int>(std::ceil(2 * g.theta3 / dtheta - 1e-9)));
  const std::size_t cells = static_cast<std::size_t>(g.beams) * K;
  const double h = config.footprint_radius * config.voxel_size;
  const int tol = config.range_tolerance_bins;

  struct Scratch {
    std::vector<std::uint16_t> depth;  // nearest return-pixel candidate bin per (beam, interval)
    std::vector<Hit> hits;
    std::vector<Hit> empty_hits;  // candidates in empty pixels (refute_free)
    std::vector<std::uint8_t> observed;
    std::vector<std::uint8_t> refuted;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;

  auto process_frame = [&](const FrameReturns& fr) {
    Scratch& sc = scratch.local();
    if (sc.depth.size() != cells) sc.depth.assign(cells, 0xFFFF);
    if (sc.observed.size() != cand.size()) sc.observed.assign(cand.size(), 0);
    if (config.refute_free && sc.refuted.size() != cand.size()) sc.refuted.assign(cand.size(), 0);
    std::fill(sc.depth.begin(), sc.depth.end(), std::uint16_t{0xFFFF});
    sc.hits.clear();
    sc.empty_hits.clear();
    const detail::FrameFootprint fp(g, fr);
    const double r_min2 = g.r_min * g.r_min, r_max2 = g.r_max * g.r_max;
    for (const Block& b : blocks) {
      const Eigen::Vector3d c_sonar = fp.to_sonar(b.centre_world);
      if (config.refute_free
              ? fp.classify(c_sonar, b.radius, b.radius).region == detail::Region::Outside
              : fp.no_return_possible(c_sonar, b.radius)) {
        continue;
      }
      for (std::size_t m = b.begin; m < b.end; ++m) {
        const std::uint32_t c = order[m];
        const Eigen::Vector3d p = fp.to_sonar(candidates_world.points[cand[c]].cast<double>());
        const double r2 = p.squaredNorm();
        if (r2 < r_min2 || r2 >= r_max2) continue;
        const double r = std::sqrt(r2);
        const double s = p.z() / r;
        if (std::abs(s) > g.sin_theta3) continue;
        const double phi = detail::fast_atan2(p.y(), p.x());
        if (!(phi >= g.fov_min) || !(phi < g.fov_max)) continue;
        const int j = g.beam(phi);
        const int i = std::min(static_cast<int>((r - g.r_min) * g.inv_dr), g.bins - 1);
        const double theta = g.elevation(s);
        auto interval = [&](double t) {
          return std::clamp(static_cast<int>((t + g.theta3) / dtheta), 0, K - 1);
        };
        const int k = interval(theta);
        if (!fr.has_return(i, j)) {  // the frame saw nothing here
          if (config.refute_free)
            sc.empty_hits.push_back({c, static_cast<std::uint32_t>(j * K + k), i});
          continue;
        }
        const double rho = std::max(std::sqrt(p.x() * p.x() + p.y() * p.y()), 1e-9);
        // Fig. 4.7: the candidate occludes every (beam, interval) cell its angular footprint
        // covers, for everything at a longer range.
        const double a = h / r, bw = h / rho;
        const int k0 = interval(theta - a), k1 = interval(theta + a);
        const int j0 = g.beam(std::max(phi - bw, g.fov_min));
        const int j1 = g.beam(std::min(phi + bw, std::nextafter(g.fov_max, g.fov_min)));
        const auto bin16 = static_cast<std::uint16_t>(i);
        for (int jj = j0; jj <= j1; ++jj) {
          std::uint16_t* row = &sc.depth[static_cast<std::size_t>(jj) * K];
          for (int kk = k0; kk <= k1; ++kk) row[kk] = std::min(row[kk], bin16);
        }
        sc.hits.push_back({c, static_cast<std::uint32_t>(j * K + k), i});
      }
    }
    // Fig. 4.8: keep the front scatterers, those no nearer candidate shadows.
    for (const Hit& hit : sc.hits) {
      if (hit.bin <= sc.depth[hit.cell] + tol) sc.observed[hit.candidate] = 1;
    }
    // refute_free: nothing the frame returned lies nearer on this candidate's own line of sight,
    // yet its pixel is empty: free space, not a shadow.
    for (const Hit& hit : sc.empty_hits) {
      if (hit.bin < sc.depth[hit.cell]) sc.refuted[hit.candidate] = 1;
    }
    if (progress) progress->add();
  };

  std::unique_ptr<tbb::task_arena> arena = std::make_unique<tbb::task_arena>(
      config.num_threads > 0 ? config.num_threads : static_cast<int>(tbb::task_arena::automatic));
  arena->execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, frames.size(), 1),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                        for (std::size_t f = rg.begin(); f < rg.end(); ++f)
                          process_frame(frames[f]);
                      });
  });

  std::vector<std::uint8_t> observed(cand.size(), 0);
  for (const Scratch& sc : scratch) {
    for (std::size_t n = 0; n < sc.observed.size(); ++n) observed[n] |= sc.observed[n];
  }
  for (const Scratch& sc : scratch) {
    for (std::size_t n = 0; n < sc.refuted.size(); ++n)
      if (sc.refuted[n]) observed[n] = 0;
  }
  std::vector<std::uint32_t> kept;
  for (std::size_t n = 0; n < cand.size(); ++n)
    if (observed[n]) kept.push_back(cand[n]);
  std::sort(kept.begin(), kept.end());  // input order: deterministic output
  PointCloud out;
  out.points.reserve(kept.size());
  for (std::uint32_t n : kept) {
    out.points.push_back(candidates_world.points[n]);
    if (has_i) out.intensity.push_back(candidates_world.intensity[n]);
  }
  return out;
}

}  // namespace sonar3d
