#include "sonar3d/recon/visibility.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <memory>
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
  require(explain_pin_fraction > 0 && explain_pin_fraction <= 1,
          "parameter 'occlusion.explain_pin_fraction' must be in (0, 1], got " +
              std::to_string(explain_pin_fraction));
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

struct Hit {
  std::uint32_t block;  // index into the blocks
  std::uint32_t bit;    // candidate inside the block (x << 6 | y << 3 | z)
  std::uint32_t cell;   // beam · K + elevation interval of the candidate's centre
  std::int32_t bin;     // range bin
};

void check_frames(const std::vector<const FrameReturns*>& frames, const SonarSpec& spec) {
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const auto& fr = *frames[f];
    if (fr.range_bins != spec.range_bins || fr.beams != spec.beams() ||
        static_cast<int>(fr.first_return_bin.size()) != spec.beams()) {
      throw Error("resolve_occlusions: frame " + std::to_string(f) +
                  " was summarized for another sonar (size differs from '" + spec.name + "')");
    }
  }
}

// The occlusion test (Fig. 4.7–4.8) over candidates grouped in blocks of up to 8³ (a block's
// candidates are the set bits of its mask; `position(block, bit)` gives a candidate's world
// position). Returns, per block, the mask of the candidates kept. Memory: the blocks' masks and
// two flag masks per block (observed, refuted), shared by the frames through atomic ORs, plus one
// frame's hits per thread: nothing per candidate beyond its bit.
// With `solid_refute`, every candidate shields the whole of its voxel (half its diagonal around
// its centre, not footprint_radius) from the free-space test (refute_free); the occlusion test is
// unchanged. See detail::resolve_occlusions_solid().
template <typename Position>
std::vector<detail::BlockMask> resolve_blocks(const std::vector<detail::CandidateBlock>& blocks,
                                              Position&& position,
                                              const std::vector<const FrameReturns*>& frames,
                                              const SonarSpec& spec, const OcclusionConfig& config,
                                              Progress* progress, bool solid_refute = false,
                                              bool shortcuts = true) {
  const detail::SonarGeometry g(spec);
  const double dtheta = config.elevation_resolution_rad;
  const int K = std::max(1, static_cast<int>(std::ceil(2 * g.theta3 / dtheta - 1e-9)));
  const std::size_t cells = static_cast<std::size_t>(g.beams) * K;
  const double h = config.footprint_radius * config.voxel_size;
  const double h_solid = std::max(h, 0.5 * std::sqrt(3.0) * config.voxel_size);
  solid_refute = solid_refute && config.refute_free;
  const int tol = config.range_tolerance_bins;
  const std::size_t nb = blocks.size();
  std::unique_ptr<std::atomic<std::uint64_t>[]> observed(new std::atomic<std::uint64_t>[nb * 8]);
  std::unique_ptr<std::atomic<std::uint64_t>[]> refuted(
      new std::atomic<std::uint64_t>[config.refute_free ? nb * 8 : 1]);
  for (std::size_t n = 0; n < nb * 8; ++n) observed[n].store(0, std::memory_order_relaxed);
  for (std::size_t n = 0; n < (config.refute_free ? nb * 8 : 1); ++n)
    refuted[n].store(0, std::memory_order_relaxed);
  auto flag = [](std::atomic<std::uint64_t>* m, const Hit& hit) {
    m[static_cast<std::size_t>(hit.block) * 8 + (hit.bit >> 6)].fetch_or(
        std::uint64_t{1} << (hit.bit & 63), std::memory_order_relaxed);
  };

  struct Scratch {
    std::vector<std::uint16_t> depth;   // nearest return-pixel candidate bin per (beam, interval)
    std::vector<std::uint16_t> shield;  // the same, footprints of a whole voxel (solid_refute)
    std::vector<Hit> hits;
    std::vector<Hit> empty_hits;          // candidates in empty pixels (refute_free)
    std::vector<std::uint32_t> deferred;  // blocks with no return pixel in reach (refute_free)
  };
  tbb::enumerable_thread_specific<Scratch> scratch;

  // A frame's hits are buffered up to kMaxHits per list and thread (16 MB); past that, the
  // blocks from the first one that did not fit are projected again after the depth grid is
  // complete (a wide sonar over a large structure can put tens of millions of candidates in one
  // frame's footprint). Flags are ORed, so a hit tested twice changes nothing.
  constexpr std::size_t kMaxHits = std::size_t{1} << 20;
  auto process_frame = [&](const FrameReturns& fr) {
    Scratch& sc = scratch.local();
    if (sc.depth.size() != cells) sc.depth.assign(cells, 0xFFFF);
    std::fill(sc.depth.begin(), sc.depth.end(), std::uint16_t{0xFFFF});
    if (solid_refute) sc.shield.assign(cells, 0xFFFF);
    sc.hits.clear();
    sc.empty_hits.clear();
    const detail::FrameFootprint fp(g, fr);
    const double r_min2 = g.r_min * g.r_min, r_max2 = g.r_max * g.r_max;
    auto interval = [&](double t) {
      return std::clamp(static_cast<int>((t + g.theta3) / dtheta), 0, K - 1);
    };
    auto skip_block = [&](const detail::CandidateBlock& b) {
      const Eigen::Vector3d c_sonar = fp.to_sonar(b.centre_world);
      return config.refute_free
                 ? fp.classify(c_sonar, b.radius, b.radius).region == detail::Region::Outside
                 : fp.no_return_possible(c_sonar, b.radius);
    };
    // Projects the candidates of block bi; on_return(hit, theta, phi, r, rho) for those in a
    // return pixel, on_empty(hit) for those in an empty pixel of the footprint.
    auto visit_block = [&](std::size_t bi, const detail::BlockMask& mask, auto&& on_return,
                           auto&& on_empty) {
      for (int w = 0; w < 8; ++w) {
        for (std::uint64_t bits = mask[w]; bits; bits &= bits - 1) {
          const auto bit = static_cast<std::uint32_t>(w * 64 + __builtin_ctzll(bits));
          const Eigen::Vector3d p = fp.to_sonar(position(bi, bit));
          const double r2 = p.squaredNorm();
          if (!(r2 > 0) || r2 < r_min2 || r2 >= r_max2) continue;  // the centre: no direction
          const double r = std::sqrt(r2);
          const double s = p.z() / r;
          if (std::abs(s) > g.sin_theta3) continue;
          const double phi = detail::fast_atan2(p.y(), p.x());
          if (!(phi >= g.fov_min) || !(phi < g.fov_max)) continue;
          const int j = g.beam(phi);
          const int i = std::min(static_cast<int>((r - g.r_min) * g.inv_dr), g.bins - 1);
          const double theta = g.elevation(s);
          const int k = interval(theta);
          const Hit hit{static_cast<std::uint32_t>(bi), bit, static_cast<std::uint32_t>(j * K + k),
                        i};
          if (!fr.has_return(i, j)) {  // the frame saw nothing here
            on_empty(hit);
            continue;
          }
          on_return(hit, theta, phi, r, std::max(std::sqrt(p.x() * p.x() + p.y() * p.y()), 1e-9));
        }
      }
    };
    std::size_t overflow_from = nb;  // first block whose hits were not all buffered
    sc.deferred.clear();
    for (std::size_t bi = 0; bi < nb; ++bi) {
      if (skip_block(blocks[bi])) continue;
      // A block none of whose candidates can lie in a return pixel neither splats nor is
      // observed: only the free-space test can touch it, and that needs the depth grid
      // complete, so it waits (below), where it is skipped when it cannot change.
      if (shortcuts && config.refute_free &&
          fp.no_return_possible(fp.to_sonar(blocks[bi].centre_world), blocks[bi].radius)) {
        sc.deferred.push_back(static_cast<std::uint32_t>(bi));
        continue;
      }
      visit_block(
          bi, blocks[bi].mask,
          [&](const Hit& hit, double theta, double phi, double r, double rho) {
            // Fig. 4.7: the candidate occludes every (beam, interval) cell its angular
            // footprint covers, for everything at a longer range.
            const auto bin16 = static_cast<std::uint16_t>(hit.bin);
            auto splat = [&](std::vector<std::uint16_t>& grid, double half) {
              const double a = half / r, bw = half / rho;
              const int k0 = interval(theta - a), k1 = interval(theta + a);
              const int j0 = g.beam(std::max(phi - bw, g.fov_min));
              const int j1 = g.beam(std::min(phi + bw, std::nextafter(g.fov_max, g.fov_min)));
              for (int jj = j0; jj <= j1; ++jj) {
                std::uint16_t* row = &grid[static_cast<std::size_t>(jj) * K];
                for (int kk = k0; kk <= k1; ++kk) row[kk] = std::min(row[kk], bin16);
              }
            };
            splat(sc.depth, h);
            if (solid_refute) splat(sc.shield, h_solid);
            if (overflow_from < nb) return;
            if (sc.hits.size() < kMaxHits) {
              sc.hits.push_back(hit);
            } else {
              overflow_from = bi;
            }
          },
          [&](const Hit& hit) {
            if (!config.refute_free || overflow_from < nb) return;
            if (sc.empty_hits.size() < kMaxHits) {
              sc.empty_hits.push_back(hit);
            } else {
              overflow_from = bi;
            }
          });
    }
    // Fig. 4.8: keep the front scatterers, those no nearer candidate shadows.
    auto test_return = [&](const Hit& hit) {
      if (hit.bin <= sc.depth[hit.cell] + tol) flag(observed.get(), hit);
    };
    // refute_free: nothing the frame returned lies nearer on this candidate's own line of sight,
    // yet its pixel is empty: free space, not a shadow.
    auto test_empty = [&](const Hit& hit) {
      if (config.refute_free && hit.bin < (solid_refute ? sc.shield : sc.depth)[hit.cell])
        flag(refuted.get(), hit);
    };
    for (const Hit& hit : sc.hits) test_return(hit);
    for (const Hit& hit : sc.empty_hits) test_empty(hit);
    for (std::size_t bi = overflow_from; bi < nb; ++bi) {
      if (skip_block(blocks[bi])) continue;
      if (shortcuts && config.refute_free &&
          fp.no_return_possible(fp.to_sonar(blocks[bi].centre_world), blocks[bi].radius))
        continue;  // deferred
      visit_block(
          bi, blocks[bi].mask,
          [&](const Hit& hit, double, double, double, double) { test_return(hit); }, test_empty);
    }
    // The deferred blocks: every candidate lies in an empty pixel (or outside the aperture), so
    // only the free-space test applies — and a refutation is final (a candidate refuted by one
    // frame is never kept), so the candidates some frame has already refuted need no test, and a
    // block whose every cell of its angular window already holds a candidate at or before its
    // nearest range bin cannot have one refuted here. Skipping them changes no flag.
    const std::vector<std::uint16_t>& free_grid = solid_refute ? sc.shield : sc.depth;
    for (std::uint32_t bi : sc.deferred) {
      const detail::CandidateBlock& b = blocks[bi];
      detail::BlockMask left;
      std::uint64_t any = 0;
      for (int w = 0; w < 8; ++w) {
        left[w] = b.mask[w] &
                  ~refuted[static_cast<std::size_t>(bi) * 8 + w].load(std::memory_order_relaxed);
        any |= left[w];
      }
      if (!any) continue;
      const Eigen::Vector3d c = fp.to_sonar(b.centre_world);
      const double d = c.norm(), rho = std::sqrt(c.x() * c.x() + c.y() * c.y());
      if (d > 1.01 * b.radius && rho > 1.01 * b.radius) {
        // The cells and range bins the block's candidates can fall in (conservative, as
        // FrameFootprint::classify()).
        const double alpha = detail::asin_upper(b.radius / d) + detail::kAnglePad;
        const double beta = detail::asin_upper(b.radius / rho) + detail::kAnglePad;
        const double theta_c = detail::fast_atan2(c.z(), rho),
                     phi_c = detail::fast_atan2(c.y(), c.x());
        const double lo = phi_c - beta, hi = phi_c + beta;
        if (lo >= -M_PI && hi <= M_PI && hi >= g.fov_min && lo < g.fov_max) {
          const int j0 = g.beam(std::max(lo, g.fov_min));
          const int j1 = g.beam(std::min(hi, std::nextafter(g.fov_max, g.fov_min)));
          const int k0 = interval(theta_c - alpha), k1 = interval(theta_c + alpha);
          const int i_lo = static_cast<int>(std::floor((d - b.radius - g.r_min) * g.inv_dr)) - 1;
          bool can_refute = false;
          for (int jj = j0; jj <= j1 && !can_refute; ++jj) {
            const std::uint16_t* row = &free_grid[static_cast<std::size_t>(jj) * K];
            for (int kk = k0; kk <= k1; ++kk) {
              if (i_lo < static_cast<int>(row[kk])) {
                can_refute = true;
                break;
              }
            }
          }
          if (!can_refute) continue;
        }
      }
      visit_block(
          bi, left, [&](const Hit& hit, double, double, double, double) { test_return(hit); },
          test_empty);
    }
    if (progress) progress->add();
  };

  std::unique_ptr<tbb::task_arena> arena = std::make_unique<tbb::task_arena>(
      config.num_threads > 0 ? config.num_threads : static_cast<int>(tbb::task_arena::automatic));
  arena->execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, frames.size(), 1),
                      [&](const tbb::blocked_range<std::size_t>& rg) {
                        for (std::size_t f = rg.begin(); f < rg.end(); ++f)
                          process_frame(*frames[f]);
                      });
  });
  std::vector<detail::BlockMask> kept(nb);
  for (std::size_t bi = 0; bi < nb; ++bi) {
    for (int w = 0; w < 8; ++w) {
      std::uint64_t m = observed[bi * 8 + w].load(std::memory_order_relaxed);
      if (config.refute_free) m &= ~refuted[bi * 8 + w].load(std::memory_order_relaxed);
      kept[bi][w] = m & blocks[bi].mask[w];
    }
  }
  return kept;
}

}  // namespace

namespace detail {

std::vector<BlockMask> resolve_occlusion_blocks(const std::vector<CandidateBlock>& blocks,
                                                const std::vector<FrameReturns>& frames,
                                                const SonarSpec& spec,
                                                const OcclusionConfig& config, Progress* progress) {
  return resolve_occlusion_blocks(blocks, frame_pointers(frames), spec, config, progress);
}

std::vector<const FrameReturns*> frame_pointers(const std::vector<FrameReturns>& frames) {
  std::vector<const FrameReturns*> p(frames.size());
  for (std::size_t f = 0; f < frames.size(); ++f) p[f] = &frames[f];
  return p;
}

std::vector<BlockMask> resolve_occlusion_blocks(const std::vector<CandidateBlock>& blocks,
                                                const std::vector<const FrameReturns*>& frames,
                                                const SonarSpec& spec,
                                                const OcclusionConfig& config, Progress* progress) {
  config.validate();
  spec.validate();
  check_frames(frames, spec);
  const double vs = config.voxel_size;
  return resolve_blocks(
      blocks,
      [&](std::size_t bi, std::uint32_t bit) {
        const std::array<int, 3>& o = blocks[bi].origin_index;
        auto at = [vs](int i) { return static_cast<double>(static_cast<float>(i * vs)); };
        return Eigen::Vector3d(at(o[0] + static_cast<int>(bit >> 6)),
                               at(o[1] + static_cast<int>((bit >> 3) & 7)),
                               at(o[2] + static_cast<int>(bit & 7)));
      },
      frames, spec, config, progress);
}

}  // namespace detail

namespace {

// resolve_occlusions() without the explanation, and detail::resolve_occlusions_solid().
PointCloud resolve_cloud(const PointCloud& candidates_world,
                         const std::vector<FrameReturns>& frame_list, const SonarSpec& spec,
                         const OcclusionConfig& config, Progress* progress, bool solid_refute,
                         bool shortcuts) {
  config.validate();
  spec.validate();
  const std::vector<const FrameReturns*> frames = detail::frame_pointers(frame_list);
  check_frames(frames, spec);
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
  // Blocks of the candidates' voxels; a candidate's own position (not its voxel centre) is used.
  std::vector<detail::CandidateBlock> blocks;
  std::vector<std::uint32_t> index;  // point index of each (block, bit), block-major
  std::vector<std::size_t> first;    // per block, its first entry in `index`
  for (std::size_t e = 0; e < entries.size();) {
    detail::CandidateBlock b;
    Eigen::AlignedBox3d box;
    first.push_back(index.size());
    std::size_t f = e;
    for (; f < entries.size() && entries[f].bx == entries[e].bx && entries[f].by == entries[e].by &&
           entries[f].bz == entries[e].bz;
         ++f) {
      if (f > e && entries[f].in == entries[f - 1].in) continue;  // same voxel: higher bound
      b.mask[entries[f].in >> 6] |= std::uint64_t{1} << (entries[f].in & 63);
      index.push_back(entries[f].idx);
      box.extend(candidates_world.points[entries[f].idx].cast<double>());
    }
    b.centre_world = box.center();
    b.radius = 0.5 * box.diagonal().norm() + 1e-6;
    blocks.push_back(b);
    e = f;
  }
  entries = {};
  // (block, bit) -> rank among the block's bits -> point index.
  auto point_index = [&](std::size_t bi, std::uint32_t bit) {
    std::size_t rank = 0;
    for (std::uint32_t w = 0; w < (bit >> 6); ++w)
      rank += static_cast<std::size_t>(__builtin_popcountll(blocks[bi].mask[w]));
    const std::uint64_t below =
        (bit & 63) ? (blocks[bi].mask[bit >> 6] & ((std::uint64_t{1} << (bit & 63)) - 1)) : 0;
    rank += static_cast<std::size_t>(__builtin_popcountll(below));
    return index[first[bi] + rank];
  };
  const std::vector<detail::BlockMask> kept_masks = resolve_blocks(
      blocks,
      [&](std::size_t bi, std::uint32_t bit) {
        return candidates_world.points[point_index(bi, bit)].cast<double>();
      },
      frames, spec, config, progress, solid_refute, shortcuts);

  std::vector<std::uint32_t> kept;
  for (std::size_t bi = 0; bi < blocks.size(); ++bi)
    for (int w = 0; w < 8; ++w)
      for (std::uint64_t bits = kept_masks[bi][w]; bits; bits &= bits - 1)
        kept.push_back(point_index(bi, static_cast<std::uint32_t>(w * 64 + __builtin_ctzll(bits))));
  std::sort(kept.begin(), kept.end());  // input order: deterministic output
  PointCloud out;
  out.points.reserve(kept.size());
  for (std::uint32_t n : kept) {
    out.points.push_back(candidates_world.points[n]);
    if (has_i) out.intensity.push_back(candidates_world.intensity[n]);
  }
  return out;
}

}  // namespace

PointCloud resolve_occlusions(const PointCloud& candidates_world,
                              const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                              const OcclusionConfig& config, Progress* progress) {
  PointCloud out = resolve_cloud(candidates_world, frames, spec, config, progress, false, true);
  if (config.explain_returns) return drop_unexplained(out, frames, spec, config);
  return out;
}

namespace detail {

PointCloud resolve_occlusions_solid(const PointCloud& points_world,
                                    const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                                    const OcclusionConfig& config) {
  OcclusionConfig plain = config;
  plain.explain_returns = false;
  return resolve_cloud(points_world, frames, spec, plain, nullptr, true, true);
}

PointCloud resolve_occlusions_reference(const PointCloud& candidates_world,
                                        const std::vector<FrameReturns>& frames,
                                        const SonarSpec& spec, const OcclusionConfig& config,
                                        bool solid_refute) {
  OcclusionConfig plain = config;
  plain.explain_returns = false;
  return resolve_cloud(candidates_world, frames, spec, plain, nullptr, solid_refute, false);
}

}  // namespace detail

}  // namespace sonar3d
