// Voxel-domain deconvolution (DeconvConfig::Mode::Voxel): eq. 5.27–5.28 generalised from the
// layers of a straight pass to the voxels carving leaves, for any trajectory and any sampling
// (the thesis' future work, sec. 5.8 and 4.4.6). See VoxelDeconvConfig (recon/deconvolve.hpp) and
// docs/deconvolution.md, "Any trajectory: the voxel mode".
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>

#include "deconvolve_internal.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/projector.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/recon/bracketing.hpp"
#include "sonar3d/recon/carve.hpp"

namespace sonar3d::deconv_detail {

namespace {

// The model matrix A, one row per (frame, pixel) with at least one candidate voxel, stored by
// rows (CSR): each row is the pixel's footprint, Σ_v B(θ_v)²·ρ_v.
struct VoxelSystem {
  std::vector<std::size_t> start;    // rows + 1
  std::vector<std::uint32_t> col;    // voxel
  std::vector<float> value;          // B(θ)²
  std::vector<float> y;              // measured (denoised) intensity of the row's pixel
  std::vector<std::uint32_t> voxel;  // unknown → candidate index
  std::size_t rows() const { return y.size(); }
};
constexpr std::uint32_t kDropped = std::numeric_limits<std::uint32_t>::max();

// Candidates bucketed into cubes of kBlock voxels for frustum culling: a frame projects only the
// voxels of the blocks that can reach its footprint.
constexpr int kBlock = 16;

struct Blocks {
  std::vector<Eigen::Vector3d> centre;
  double radius = 0;                   // bounding sphere of a block, m
  std::vector<std::uint32_t> start;    // blocks + 1 offsets into `voxels`
  std::vector<std::uint32_t> members;  // voxel indices, block by block
};

Blocks make_blocks(const PointCloud& cand, double voxel) {
  struct Key {
    std::int64_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      return static_cast<std::size_t>(k.x * 73856093LL ^ k.y * 19349663LL ^ k.z * 83492791LL);
    }
  };
  const double edge = kBlock * voxel;
  std::unordered_map<Key, std::uint32_t, Hash> index;
  std::vector<std::uint32_t> block_of(cand.size());
  std::vector<Key> keys;
  for (std::size_t v = 0; v < cand.size(); ++v) {
    const Eigen::Vector3d p = cand.points[v].cast<double>() / edge;
    const Key k{static_cast<std::int64_t>(std::floor(p.x())),
                static_cast<std::int64_t>(std::floor(p.y())),
                static_cast<std::int64_t>(std::floor(p.z()))};
    auto it = index.emplace(k, static_cast<std::uint32_t>(keys.size())).first;
    if (it->second == keys.size()) keys.push_back(k);
    block_of[v] = it->second;
  }
  Blocks b;
  b.radius = 0.5 * std::sqrt(3.0) * edge + voxel;
  b.centre.resize(keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    b.centre[i] = (Eigen::Vector3d(static_cast<double>(keys[i].x), static_cast<double>(keys[i].y),
                                   static_cast<double>(keys[i].z)) +
                   Eigen::Vector3d::Constant(0.5)) *
                  edge;
  }
  b.start.assign(keys.size() + 1, 0);
  for (std::uint32_t k : block_of) ++b.start[k + 1];
  for (std::size_t i = 0; i < keys.size(); ++i) b.start[i + 1] += b.start[i];
  b.members.resize(cand.size());
  std::vector<std::uint32_t> fill(b.start.begin(), b.start.end() - 1);
  for (std::size_t v = 0; v < cand.size(); ++v) {
    b.members[fill[block_of[v]]++] = static_cast<std::uint32_t>(v);
  }
  return b;
}

// Can a block (bounding sphere) reach the frame's footprint (range window, field of view,
// vertical aperture)? Conservative.
bool block_visible(const Eigen::Vector3d& c_sonar, double radius, const SonarSpec& spec) {
  const double r = c_sonar.norm();
  if (r + radius < spec.r_min || r - radius > spec.r_max) return false;
  if (r <= 2 * radius) return true;
  const Polar q = sonar_to_polar(c_sonar);
  const double margin = std::asin(std::min(1.0, radius / r));
  if (std::abs(q.elevation) > spec.theta_3db() + margin) return false;
  return q.bearing >= spec.fov_min() - margin && q.bearing <= spec.fov_max() + margin;
}

struct Entry {
  std::uint32_t pixel;  // bin · beams + beam
  std::uint32_t voxel;
  float weight;
};

VoxelSystem build_system(const std::vector<SonarImage>& denoised,
                         const std::vector<Eigen::Isometry3d>& T_world_sonar, const SonarSpec& spec,
                         const DeconvConfig& config, const BeamPattern& pattern,
                         const PointCloud& cand, const std::vector<Eigen::Vector3f>* normals,
                         Progress& bar) {
  const Blocks blocks = make_blocks(cand, config.voxel.voxel_size);
  const double theta3 = spec.theta_3db();
  const int beams = spec.beams();
  const std::size_t n = denoised.size();
  // Per frame: its rows, in pixel order (deterministic whatever the thread schedule).
  struct FrameRows {
    std::vector<std::uint32_t> row_len;
    std::vector<float> y;
    std::vector<std::uint32_t> col;
    std::vector<float> value;
  };
  std::vector<FrameRows> per_frame(n);
  const VoxelDeconvConfig& vc = config.voxel;
  // Elevation cells of the occlusion test: a voxel's angular size at mid range.
  const double cell_angle = vc.voxel_size / (0.5 * (spec.r_min + spec.r_max));
  const int cells = std::max(1, static_cast<int>(std::ceil(2 * theta3 / cell_angle)));
  const double occl_tol = 0.5 * spec.range_resolution() + vc.voxel_size;
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t f) {
    const SonarImage& im = denoised[f];
    const Eigen::Isometry3d T_sonar_world = T_world_sonar[f].inverse();
    // First return per beam: a zero pixel behind it may be a shadow (Fig. 4.5).
    std::vector<int> first(beams, spec.range_bins);
    for (int i = spec.range_bins - 1; i >= 0; --i) {
      const float* row = im.row_ptr(i);
      for (int j = 0; j < beams; ++j) {
        if (row[j] > 0.0f) first[j] = i;
      }
    }
    struct Seen {
      std::uint32_t voxel;
      int bin, beam, cell;
      float range, elevation;
    };
    std::vector<Seen> seen;
    for (std::size_t b = 0; b + 1 < blocks.start.size(); ++b) {
      if (!block_visible(T_sonar_world * blocks.centre[b], blocks.radius, spec)) continue;
      for (std::uint32_t m = blocks.start[b]; m < blocks.start[b + 1]; ++m) {
        const std::uint32_t v = blocks.members[m];
        const Polar q = sonar_to_polar(T_sonar_world * cand.points[v].cast<double>());
        if (std::abs(q.elevation) > theta3) continue;
        const int i = spec.bin_of_range(q.range);
        const int j = spec.beam_of_bearing(q.bearing);
        if (i < 0 || j < 0) continue;
        const int c = std::min(cells - 1, static_cast<int>((q.elevation + theta3) / cell_angle));
        seen.push_back({v, i, j, c, static_cast<float>(q.range), static_cast<float>(q.elevation)});
      }
    }
    // Sound does not cross a surface: a candidate with another candidate nearer on its own ray
    // (beam, elevation cell) is hidden in this frame (the occlusion kernel of sec. 5.6.7.2, with
    // the occluders taken from carving's candidates instead of a first reconstruction).
    std::vector<float> nearest;
    if (vc.occlusion_aware) {
      nearest.assign(static_cast<std::size_t>(beams) * cells, std::numeric_limits<float>::max());
      for (const Seen& e : seen) {
        float& n = nearest[static_cast<std::size_t>(e.beam) * cells + e.cell];
        n = std::min(n, e.range);
      }
    }
    std::vector<Entry> entries;
    for (const Seen& e : seen) {
      if (vc.occlusion_aware &&
          e.range > nearest[static_cast<std::size_t>(e.beam) * cells + e.cell] + occl_tol) {
        continue;
      }
      if (config.ignore_shadowed_zeros && e.bin > first[e.beam] &&
          im.row_ptr(e.bin)[e.beam] <= 0.0f) {
        continue;
      }
      double w = pattern.power(e.elevation, theta3);
      if (normals != nullptr && (*normals)[e.voxel].squaredNorm() > 0) {
        // The normal kernel (sec. 5.6.7.1): Lambert's cosine between the view and the normal.
        const Eigen::Vector3f view =
            (cand.points[e.voxel] - T_world_sonar[f].translation().cast<float>()).normalized();
        w *= std::max(kMinLambertCosine,
                      static_cast<double>(std::abs(view.dot((*normals)[e.voxel]))));
      }
      if (!(w > 0)) continue;
      entries.push_back(
          {static_cast<std::uint32_t>(e.bin * beams + e.beam), e.voxel, static_cast<float>(w)});
    }
    std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
      return a.pixel != b.pixel ? a.pixel < b.pixel : a.voxel < b.voxel;
    });
    FrameRows& fr = per_frame[f];
    fr.col.reserve(entries.size());
    fr.value.reserve(entries.size());
    for (std::size_t e = 0; e < entries.size();) {
      std::size_t e1 = e;
      while (e1 < entries.size() && entries[e1].pixel == entries[e].pixel) ++e1;
      const int i = static_cast<int>(entries[e].pixel) / beams;
      const int j = static_cast<int>(entries[e].pixel) % beams;
      fr.y.push_back(im.row_ptr(i)[j]);
      fr.row_len.push_back(static_cast<std::uint32_t>(e1 - e));
      for (; e < e1; ++e) {
        fr.col.push_back(entries[e].voxel);
        fr.value.push_back(entries[e].weight);
      }
    }
    bar.add();
  });
  // A voxel seen only in pixels without return is 0 at the optimum (A ≥ 0: any ρ_v > 0 only adds
  // to those rows' residuals), and so are its unknowns: only voxels in some return pixel stay.
  std::vector<std::uint32_t> remap(cand.size(), kDropped);
  for (const auto& fr : per_frame) {
    std::size_t e = 0;
    for (std::size_t r = 0; r < fr.y.size(); ++r) {
      const std::size_t e1 = e + fr.row_len[r];
      if (fr.y[r] > 0.0f) {
        for (; e < e1; ++e) remap[fr.col[e]] = 0;
      }
      e = e1;
    }
  }
  VoxelSystem sys;
  for (std::size_t v = 0; v < cand.size(); ++v) {
    if (remap[v] == 0) {
      remap[v] = static_cast<std::uint32_t>(sys.voxel.size());
      sys.voxel.push_back(static_cast<std::uint32_t>(v));
    }
  }
  std::size_t rows = 0, nnz = 0;
  for (auto& fr : per_frame) {  // drop the entries of the fixed voxels, then empty rows
    std::size_t e = 0, w = 0, rw = 0;
    for (std::size_t r = 0; r < fr.y.size(); ++r) {
      const std::size_t e1 = e + fr.row_len[r];
      const std::size_t w0 = w;
      for (; e < e1; ++e) {
        if (remap[fr.col[e]] == kDropped) continue;
        fr.col[w] = remap[fr.col[e]];
        fr.value[w++] = fr.value[e];
      }
      if (w > w0) {
        fr.row_len[rw] = static_cast<std::uint32_t>(w - w0);
        fr.y[rw++] = fr.y[r];
      }
    }
    fr.col.resize(w);
    fr.value.resize(w);
    fr.row_len.resize(rw);
    fr.y.resize(rw);
    rows += rw;
    nnz += w;
  }
  sys.start.reserve(rows + 1);
  sys.start.push_back(0);
  sys.y.reserve(rows);
  sys.col.reserve(nnz);
  sys.value.reserve(nnz);
  for (auto& fr : per_frame) {
    for (std::uint32_t len : fr.row_len) sys.start.push_back(sys.start.back() + len);
    sys.y.insert(sys.y.end(), fr.y.begin(), fr.y.end());
    sys.col.insert(sys.col.end(), fr.col.begin(), fr.col.end());
    sys.value.insert(sys.value.end(), fr.value.begin(), fr.value.end());
    fr = FrameRows{};  // release as we go
  }
  return sys;
}

// g = Aᵀ(A·x − y) + shift (shift ≥ 0: the L1 term of eq. 5.28); returns ‖A·x − y‖². With
// with_data = false, y is taken as 0 (g = AᵀA·x).
double gradient(const VoxelSystem& A, const std::vector<double>& x, double shift,
                std::vector<double>& g, bool with_data = true) {
  const std::size_t V = x.size();
  tbb::enumerable_thread_specific<std::vector<double>> acc([V] { return std::vector<double>(V); });
  const double sq = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, A.rows(), 4096), 0.0,
      [&](const tbb::blocked_range<std::size_t>& r, double s) {
        std::vector<double>& a = acc.local();
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          double res = with_data ? -static_cast<double>(A.y[i]) : 0.0;
          for (std::size_t e = A.start[i]; e < A.start[i + 1]; ++e) res += A.value[e] * x[A.col[e]];
          s += res * res;
          for (std::size_t e = A.start[i]; e < A.start[i + 1]; ++e) a[A.col[e]] += A.value[e] * res;
        }
        return s;
      },
      [](double a, double b) { return a + b; });
  g.assign(V, shift);
  for (auto& a : acc) {
    for (std::size_t v = 0; v < V; ++v) g[v] += a[v];
  }
  return sq;
}

// Largest eigenvalue of AᵀA (power iteration), for the gradient step 1/L.
double lipschitz(const VoxelSystem& A, std::size_t V) {
  std::vector<double> x(V, 1.0 / std::sqrt(static_cast<double>(V))), g;
  double L = 0;
  for (int it = 0; it < 30; ++it) {
    gradient(A, x, 0.0, g, false);
    double norm = 0;
    for (double v : g) norm += v * v;
    norm = std::sqrt(norm);
    if (!(norm > 0)) break;
    L = norm;  // ‖AᵀA·x‖ with ‖x‖ = 1
    for (std::size_t v = 0; v < V; ++v) x[v] = g[v] / norm;
  }
  return L;
}

// 3. min ½‖Aρ − y‖² + λ/2·1ᵀρ, ρ ≥ 0 (eq. 5.28 halved): FISTA with projection onto ρ ≥ 0 and
// gradient-based adaptive restart (O'Donoghue & Candès), step 1/L. Sets vr.iterations,
// converged and relative_residual. Returns ρ, or nothing when no unknown lies in a pixel with a
// return (Aᵀy has no positive entry).
std::vector<double> solve_fista(const VoxelSystem& A, const DeconvConfig& config,
                                VoxelDeconvReport& vr, const char* label, bool progress) {
  const VoxelDeconvConfig& vc = config.voxel;
  const std::size_t V = A.voxel.size();
  std::vector<double> x(V, 0.0), x_old(V, 0.0), z(V, 0.0), g;
  gradient(A, z, 0.0, g);  // at 0: g = −Aᵀy
  double aty_max = 0, y_sq = 0;
  for (double v : g) aty_max = std::max(aty_max, -v);
  for (float v : A.y) y_sq += static_cast<double>(v) * v;
  const double shift = config.lambda_fraction * aty_max;  // λ/2, λ = f·λ_max, λ_max = 2·max Aᵀy
  const double L = V > 0 ? lipschitz(A, V) : 0.0;
  if (V == 0 || !(aty_max > 0) || !(L > 0)) return {};
  const double step = 1.0 / (1.02 * L);
  double t = 1.0;
  vr.iterations = 0;
  vr.converged = false;
  Progress bar(label, static_cast<std::size_t>(vc.max_iterations), progress);
  for (int it = 0; it < vc.max_iterations; ++it) {
    gradient(A, z, shift, g);
    x_old.swap(x);
    double dx = 0, nx = 0, restart = 0;
    for (std::size_t v = 0; v < V; ++v) {
      x[v] = std::max(0.0, z[v] - step * g[v]);
      const double d = x[v] - x_old[v];
      dx += d * d;
      nx += x[v] * x[v];
      restart += (z[v] - x[v]) * d;
    }
    vr.iterations = it + 1;
    bar.add();
    if (nx > 0 && std::sqrt(dx) <= vc.tolerance * std::sqrt(nx)) {
      vr.converged = true;
      break;
    }
    if (restart > 0) t = 1.0;  // momentum points uphill: restart
    const double t_next = 0.5 * (1.0 + std::sqrt(1.0 + 4.0 * t * t));
    const double beta = (t - 1.0) / t_next;
    for (std::size_t v = 0; v < V; ++v) z[v] = std::max(0.0, x[v] + beta * (x[v] - x_old[v]));
    t = t_next;
  }
  bar.finish();
  const double res_sq = gradient(A, x, shift, g);
  vr.relative_residual = y_sq > 0 ? std::sqrt(res_sq / y_sq) : 0.0;
  return x;
}

// 4. The voxels that carry reflectivity: ρ ≥ min_relative·max ρ, or, with the lower tier on
// (min_relative_bracketed > 0), ρ ≥ min_relative_bracketed·max ρ where the voxel's elevation is
// bracketed at least `bracketed` (recon/bracketing.hpp). Sets vr.kept_bracketed.
PointCloud select_voxels(const std::vector<double>& x, const VoxelSystem& A, const PointCloud& cand,
                         const std::vector<Eigen::Isometry3d>& T_world_sonar, const SonarSpec& spec,
                         const DeconvConfig& config, VoxelDeconvReport& vr) {
  const VoxelDeconvConfig& vc = config.voxel;
  const std::size_t V = x.size();
  const double x_max = *std::max_element(x.begin(), x.end());  // > 0: Aᵀy has a positive entry
  const double keep = std::max(config.min_intensity, vc.min_relative * x_max);
  const double keep_bracketed =
      vc.min_relative_bracketed > 0
          ? std::max(config.min_intensity, vc.min_relative_bracketed * x_max)
          : keep;
  std::vector<std::uint8_t> kept(V, 0);
  vr.kept_bracketed = 0;
  std::vector<std::size_t> faint;  // between the two thresholds: kept when bracketed
  std::vector<Eigen::Vector3f> faint_points;
  for (std::size_t v = 0; v < V; ++v) {
    if (!(x[v] > 0)) continue;
    if (x[v] >= keep) {
      kept[v] = 1;
    } else if (x[v] >= keep_bracketed) {
      faint.push_back(v);
      faint_points.push_back(cand.points[A.voxel[v]]);
    }
  }
  if (!faint.empty()) {
    const std::vector<PointBracket> br =
        bracket_points(faint_points, T_world_sonar, spec, config.num_threads);
    for (std::size_t i = 0; i < faint.size(); ++i) {
      if (br[i].bracket >= vc.bracketed) {
        kept[faint[i]] = 1;
        ++vr.kept_bracketed;
      }
    }
  }
  PointCloud out;
  for (std::size_t v = 0; v < V; ++v) {
    if (kept[v]) {
      out.points.push_back(cand.points[A.voxel[v]]);
      out.intensity.push_back(static_cast<float>(x[v]));
    }
  }
  return out;
}

// The candidates (points and bounds) where keep[v] is set.
PointCloud select_candidates(const PointCloud& cand, const std::vector<std::uint8_t>& keep) {
  PointCloud out;
  for (std::size_t v = 0; v < cand.size(); ++v) {
    if (!keep[v]) continue;
    out.points.push_back(cand.points[v]);
    out.intensity.push_back(cand.intensity[v]);
  }
  return out;
}

// Leaves out of the unknowns the candidates carving has already proven ghosts
// (VoxelDeconvConfig::support_min_bracket, support_refute): never bracketed in elevation, then
// seen as free space among the front candidates (refute_free, docs/carving.md).
PointCloud prune_support(PointCloud cand, const std::vector<Eigen::Isometry3d>& T_world_sonar,
                         const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                         const DeconvConfig& config, DeconvReport& report) {
  const VoxelDeconvConfig& vc = config.voxel;
  VoxelDeconvReport& vr = report.voxel;
  if (vc.support_min_bracket > 0) {
    const std::vector<PointBracket> br =
        bracket_points(cand.points, T_world_sonar, spec, config.num_threads);
    std::vector<std::uint8_t> keep(cand.size());
    std::size_t kept = 0;
    for (std::size_t v = 0; v < cand.size(); ++v) {
      keep[v] = br[v].bracket >= vc.support_min_bracket;
      kept += keep[v];
    }
    if (kept == 0) {
      report.warnings.push_back(
          "voxel mode: no candidate is bracketed in elevation (bracket >= " +
          std::to_string(vc.support_min_bracket).substr(0, 4) +
          ", deconv.voxel.support_min_bracket): the trajectory does not sweep the vertical "
          "aperture, so every candidate stays an unknown");
    } else {
      vr.unbracketed = cand.size() - kept;
      cand = select_candidates(cand, keep);
    }
  }
  if (vc.support_refute && !cand.empty()) {
    // Occlusion resolution without and with the free-space test: the front candidates the test
    // drops were seen in an empty pixel with nothing nearer on their own line of sight. Both
    // results are subsequences of `cand`, in order, one point per voxel.
    OcclusionConfig plain = config.occlusion;
    plain.voxel_size = vc.voxel_size;
    plain.num_threads = config.num_threads;
    plain.refute_free = false;
    plain.explain_returns = false;
    OcclusionConfig refuting = plain;
    refuting.refute_free = true;
    const PointCloud front = resolve_occlusions(cand, frames, spec, plain);
    const PointCloud kept = resolve_occlusions(cand, frames, spec, refuting);
    std::vector<std::uint8_t> keep(cand.size(), 1);
    for (std::size_t v = 0, f = 0, k = 0; v < cand.size(); ++v) {
      const bool in_front = f < front.size() && front.points[f] == cand.points[v];
      const bool in_kept = k < kept.size() && kept.points[k] == cand.points[v];
      f += in_front;
      k += in_kept;
      if (in_front && !in_kept) {
        keep[v] = 0;
        ++vr.refuted;
      }
    }
    if (vr.refuted > 0) cand = select_candidates(cand, keep);
  }
  return cand;
}

}  // namespace

PointCloud deconvolve_voxels(const std::vector<SonarImage>& denoised,
                             const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const SonarSpec& spec, const DeconvConfig& config,
                             DeconvReport& report, bool progress) {
  const VoxelDeconvConfig& vc = config.voxel;
  VoxelDeconvReport& vr = report.voxel;
  PointCloud out;
  tbb::task_arena arena(config.num_threads > 0 ? config.num_threads : tbb::task_arena::automatic);
  arena.execute([&] {
    // 1. Candidates: carving (ch. 4) removes every voxel seen as free space; what is left bounds
    //    the support of ρ. The frames are denoised already (only the static threshold applies).
    auto t0 = std::chrono::steady_clock::now();
    CarveConfig cc;
    cc.voxel_size = vc.voxel_size;
    cc.denoise = config.denoise;
    cc.denoise.z_test = false;
    cc.min_observations = vc.min_observations;
    cc.resolve_occlusions = false;
    cc.num_threads = config.num_threads;
    Carver carver(spec, cc);
    {
      Progress bar("carve", denoised.size(), progress);
      for (std::size_t f = 0; f < denoised.size(); ++f) {
        carver.integrate(denoised[f], T_world_sonar[f], "frame " + std::to_string(f));
        bar.add();
      }
      bar.finish();
    }
    PointCloud cand = carver.snapshot();
    vr.candidates = cand.size();
    if (cand.empty()) {
      vr.seconds_carve = seconds_since(t0);
      report.warnings.push_back("voxel mode: carving left no candidate (no return in any frame)");
      return;
    }
    cand =
        prune_support(std::move(cand), T_world_sonar, carver.frame_returns(), spec, config, report);
    vr.seconds_carve = seconds_since(t0);
    require(cand.size() < std::numeric_limits<std::uint32_t>::max(),
            "voxel deconvolution: " + std::to_string(cand.size()) +
                " candidate voxels exceed 2^32; use a larger deconv.voxel.voxel_size or a region");

    // 2.–4., once with the kernel of eq. 2.13 and, with the normal kernel, again with Lambert's
    // cosine at the normals of the first solution (sec. 5.6.7.1). Returns false (warning given)
    // when no candidate lies in a pixel with a return.
    const BeamPattern pattern = kernel_pattern(config, spec);
    bool capped = false;  // a solve stopped at the iteration cap: said once
    auto solve_and_select = [&](const std::vector<Eigen::Vector3f>* normals) -> bool {
      // 2. The model A (eq. 2.13 at voxel centres, eq. 5.27 generalised).
      t0 = std::chrono::steady_clock::now();
      VoxelSystem A;
      {
        Progress bar(normals ? "voxel model (normals)" : "voxel model", denoised.size(), progress);
        A = build_system(denoised, T_world_sonar, spec, config, pattern, cand, normals, bar);
        bar.finish();
      }
      vr.equations = A.rows();
      vr.nonzeros = A.col.size();
      vr.seconds_build += seconds_since(t0);
      // 3. The solve.
      t0 = std::chrono::steady_clock::now();
      vr.unknowns = A.voxel.size();
      const std::vector<double> x =
          solve_fista(A, config, vr, normals ? "voxel solve (normals)" : "voxel solve", progress);
      vr.seconds_solve += seconds_since(t0);
      if (x.empty()) {
        report.warnings.push_back("voxel mode: no candidate voxel lies in a pixel with a return");
        return false;
      }
      report.seconds_solve = vr.seconds_carve + vr.seconds_build + vr.seconds_solve;
      if (!vr.converged && !capped) {
        report.warnings.push_back("voxel mode: stopped at the iteration cap (" +
                                  std::to_string(vc.max_iterations) +
                                  ", deconv.voxel.max_iterations) before the tolerance");
      }
      capped = capped || !vr.converged;
      // 4. The voxels that carry reflectivity.
      out = select_voxels(x, A, cand, T_world_sonar, spec, config, vr);
      return true;
    };
    if (!solve_and_select(nullptr)) return;
    if (config.kernel == DeconvConfig::Kernel::Occlusion ||
        config.kernel == DeconvConfig::Kernel::NormalOcclusion) {  // mode auto fell back to voxel
      report.warnings.push_back(
          "voxel mode: the occlusion kernel is not used (the voxel mode's own occlusion model, "
          "deconv.voxel.occlusion_aware, takes its place)");
    }
    if ((config.kernel == DeconvConfig::Kernel::Normal ||
         config.kernel == DeconvConfig::Kernel::NormalOcclusion) &&
        !out.empty()) {
      // The normal kernel (sec. 5.6.7.1) on voxels: normals over the first solution's voxels
      // (config.normal_radius), Lambert's cosine in every frame's weights, solved again. (The
      // occlusion kernel of sec. 5.6.7.2 is the voxel mode's own occlusion model.)
      const auto tm = std::chrono::steady_clock::now();
      std::vector<Eigen::Vector3d> first;
      first.reserve(out.size());
      for (const auto& p : out.points) first.push_back(p.cast<double>());
      const std::vector<Eigen::Vector3f> normals =
          normals_near(first, config.normal_radius, cand.points);
      report.seconds_multipass = seconds_since(tm);
      if (!solve_and_select(&normals)) return;
    }
    vr.points_solved = out.size();
    report.points_before_occlusion = out.size();

    // 5. Occlusion resolution (sec. 5.6.7.3) with the frames' return summaries.
    if (config.resolve_occlusions && !out.empty()) {
      t0 = std::chrono::steady_clock::now();
      OcclusionConfig oc = config.occlusion;
      if (oc.num_threads == 0) oc.num_threads = config.num_threads;
      if (config.occlusion_auto_voxel) oc.voxel_size = vc.voxel_size;
      out = resolve_occlusions(out, carver.frame_returns(), spec, oc);
      report.seconds_occlusion = seconds_since(t0);
    }
  });
  return out;
}

}  // namespace sonar3d::deconv_detail
