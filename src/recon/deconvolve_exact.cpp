// Exact-geometry deconvolution (beyond the thesis). The rectilinear approximation (eq. 5.21) puts
// every scatterer a column sees on the vertical line at distance r; for wide apertures the arc
// swept by the aperture bends away from that line by r·(1 − cos θ_3dB), more than a range bin,
// and vertical surfaces break into gaps (Fig. 5.14). Here every beam's vertical half-plane is a
// (ρ = horizontal distance, h = height) grid and frame k at height z_k measures, in range bin i,
//
//   I_k(i) = Σ_{cells with sqrt(ρ² + (h − z_k)²) in bin i, |θ| ≤ θ_3dB} B(θ)²·b(ρ, h),
//   θ = atan2(h − z_k, ρ),
//
// solved per beam as one NNLS (with an optional L1 term, λ per ρ block). The cells of one ρ form a
// block with the layer structure of the approximate mode (a banded Gram); blocks couple only
// through the measurements they share, so the solver is an exact block Gauss–Seidel: each block's
// NNLS is solved exactly (Lawson–Hanson, warm-started) against the residual of the others, sweeping
// from near to far ranges until the KKT conditions of the whole problem hold to `exact_tolerance`.
// Block coordinate descent converges to the optimum of a convex problem with separable
// constraints; the block matrices depend only on ρ and the frame heights, not on the bearing, so
// they are built once and shared by every beam.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>

#include "deconvolve_internal.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d::deconv_detail {

namespace {

struct Block {
  double rho = 0.0;
  int K = 1;
  int P = 0;         // layers
  int classes = 1;   // unknowns per layer: 1, or 3 with exact_lambertian (facing ρ, up, down)
  int unknowns = 0;  // P·classes; unknown q is layer q / classes, class q % classes
  double first_layer = 0.0;
  int bin_first = 0, bin_last = -1;  // range bins its cells reach (absolute)
  SparseColumns A;                   // rows: (bin − bin_lo)·n + k; columns: layers
  // Row view (CSR) of the rows [bin_first, bin_last] for Aᵀr over the non-zero residual only.
  std::vector<int> row_start;
  std::vector<int> row_col;
  std::vector<float> row_val;
  BandMatrix gram;
};

struct Entry {
  int row;
  float w;
};

// Lambertian factor of normal class c for a ray at elevation θ (θ > 0: the cell is above the
// frame). Class 0: a surface facing the pass axis (normal −ρ̂: cos(incidence) = cos θ); class 1:
// facing up (normal +ĥ), seen only from frames above it (cos(incidence) = −sin θ > 0); class 2:
// facing down, seen only from below. A surface tilted by α toward up is cos α·class 0 + sin α·
// class 1 up to the −sin α·sin θ of the frames below (|θ| ≤ θ_3dB keeps that small).
double class_factor(int c, double theta) {
  switch (c) {
    case 0:
      return std::cos(theta);
    case 1:
      return std::max(0.0, -std::sin(theta));
    default:
      return std::max(0.0, std::sin(theta));
  }
}

// Builds the block of cells at horizontal distance rho. Row order: (bin − bin_lo)·n + k.
// classes = 1: the reflectivity model of eq. 2.13 without the Lambertian term (as A*, eq. 5.27);
// classes = 3: each cell holds three unknowns, one per normal class (class_factor).
Block build_block(const PassData& pd, const BeamPattern& pattern, double rho, int s_h, int s_rho,
                  int classes) {
  const SonarSpec& spec = *pd.spec;
  const int n = pd.n;
  const double dz = pd.dz;
  const double dr = spec.range_resolution();
  const double th3 = pd.theta_3db;
  const double tan3 = std::tan(th3);
  Block B;
  B.rho = rho;
  B.K = footprint_layers(rho, 2.0 * th3, dz);
  const double z0 = pd.heights.front();
  B.P = static_cast<int>(std::lround((pd.heights.back() - z0) / dz)) + B.K;
  B.first_layer = z0 - 0.5 * (B.K - 1) * dz;
  B.classes = classes;
  B.unknowns = B.P * classes;
  const int P = B.P;

  bool uniform = true;
  for (int k = 0; k < n && uniform; ++k) {
    uniform = std::abs((pd.heights[k] - z0) / dz - k) < 1e-9;
  }
  // Contributions of one cell (layer offset dh above the frame) to the bins: sub-sampled over
  // the cell (s_rho × s_h points), each point binned by its true slant range.
  std::vector<double> acc(static_cast<std::size_t>(spec.range_bins) * classes, 0.0);
  std::vector<char> hit(spec.range_bins, 0);
  std::vector<int> touched;
  // outv[c]: (bin, weight) of class c.
  auto cell = [&](double dh, std::vector<std::vector<std::pair<int, float>>>& outv) {
    outv.assign(classes, {});
    touched.clear();
    const double w0 = 1.0 / (s_h * s_rho);
    for (int a = 0; a < s_rho; ++a) {
      const double rr = rho + ((a + 0.5) / s_rho - 0.5) * dr;
      if (rr <= 0) continue;
      for (int c = 0; c < s_h; ++c) {
        const double h = dh + ((c + 0.5) / s_h - 0.5) * dz;
        const double theta = std::atan2(h, rr);
        if (std::abs(theta) > th3) continue;  // traced aperture only
        const int i = spec.bin_of_range(std::hypot(rr, h));
        if (i < pd.bin_lo || i > pd.bin_hi) continue;
        if (!hit[i]) {
          hit[i] = 1;
          touched.push_back(i);
        }
        // The sensor integrates over elevation (eq. 2.13): a cell of height Δz at distance ρ'
        // spans dθ = cos²θ·Δz/ρ', so its weight is B(θ)²·cos²θ (ρ/ρ' keeps the block's scale).
        const double ct = std::cos(theta);
        const double w = w0 * pattern.power(theta, th3) * ct * ct * (rho / rr);
        if (classes == 1) {
          acc[i] += w;
        } else {
          // eq. 2.6: Lambertian backscatter ∝ cos(incidence), zero for a surface facing away.
          for (int c = 0; c < classes; ++c) {
            acc[static_cast<std::size_t>(i) * classes + c] += w * class_factor(c, theta);
          }
        }
      }
    }
    std::sort(touched.begin(), touched.end());
    for (int i : touched) {
      for (int c = 0; c < classes; ++c) {
        double& a = acc[static_cast<std::size_t>(i) * classes + c];
        if (a > 0) outv[c].emplace_back(i, static_cast<float>(a));
        a = 0.0;
      }
      hit[i] = 0;
    }
  };

  // Per unknown q (layer q / classes), the frames whose aperture can reach it.
  const int U = B.unknowns;
  std::vector<std::vector<Entry>> cols(U);
  std::vector<std::vector<std::pair<int, float>>> tmp;
  if (uniform) {
    // Shift invariance: the contribution depends on d = p − k only.
    const int dmax = static_cast<int>(std::ceil((rho * tan3 + dz) / dz)) + B.K;
    std::vector<std::vector<std::vector<std::pair<int, float>>>> stencil(2 * dmax + 1);
    for (int d = -dmax; d <= dmax; ++d) {
      // layer p = k + d is at u_p − z_k = (d − (K − 1)/2)·Δz.
      cell((d - 0.5 * (B.K - 1)) * dz, tmp);
      stencil[d + dmax] = tmp;
    }
    for (int p = 0; p < P; ++p) {
      for (int k = std::max(0, p - dmax); k <= std::min(n - 1, p + dmax); ++k) {
        for (int c = 0; c < classes; ++c) {
          for (const auto& [i, w] : stencil[p - k + dmax][c]) {
            cols[p * classes + c].push_back({(i - pd.bin_lo) * n + k, w});
          }
        }
      }
    }
  } else {
    for (int p = 0; p < P; ++p) {
      const double u = B.first_layer + p * dz;
      const double reach = rho * tan3 + dz;
      const auto lo = std::lower_bound(pd.heights.begin(), pd.heights.end(), u - reach);
      const auto hi = std::upper_bound(pd.heights.begin(), pd.heights.end(), u + reach);
      for (auto it = lo; it != hi; ++it) {
        const int k = static_cast<int>(it - pd.heights.begin());
        cell(u - *it, tmp);
        for (int c = 0; c < classes; ++c) {
          for (const auto& [i, w] : tmp[c])
            cols[p * classes + c].push_back({(i - pd.bin_lo) * n + k, w});
        }
      }
    }
  }
  B.bin_first = spec.range_bins;
  B.bin_last = -1;
  SparseColumns& A = B.A;
  A.rows = pd.bins * n;
  A.cols = U;
  A.start.assign(U + 1, 0);
  for (int p = 0; p < U; ++p) {
    std::sort(cols[p].begin(), cols[p].end(),
              [](const Entry& a, const Entry& b) { return a.row < b.row; });
    A.start[p + 1] = A.start[p] + static_cast<int>(cols[p].size());
    for (const Entry& e : cols[p]) {
      A.row.push_back(e.row);
      A.value.push_back(e.w);
      const int bin = e.row / n + pd.bin_lo;
      B.bin_first = std::min(B.bin_first, bin);
      B.bin_last = std::max(B.bin_last, bin);
    }
  }
  if (B.bin_last < B.bin_first) return B;  // sees nothing in the window
  // CSR over the local rows [bin_first, bin_last].
  const int row0 = (B.bin_first - pd.bin_lo) * n;
  const int nrows = (B.bin_last - B.bin_first + 1) * n;
  B.row_start.assign(nrows + 1, 0);
  for (int e = 0; e < A.nonzeros(); ++e) ++B.row_start[A.row[e] - row0 + 1];
  for (int r = 0; r < nrows; ++r) B.row_start[r + 1] += B.row_start[r];
  B.row_col.resize(A.nonzeros());
  B.row_val.resize(A.nonzeros());
  std::vector<int> fill(B.row_start.begin(), B.row_start.end() - 1);
  for (int p = 0; p < U; ++p) {
    for (int e = A.start[p]; e < A.start[p + 1]; ++e) {
      const int at = fill[A.row[e] - row0]++;
      B.row_col[at] = p;
      B.row_val[at] = A.value[e];
    }
  }
  B.gram = BandMatrix::gram(A);
  return B;
}

}  // namespace

void solve_exact(const PassData& pd, const DeconvConfig& cfg, const BeamPattern& pattern,
                 PassReport& report, std::vector<LayerPoint>& out, Progress* progress) {
  const SonarSpec& spec = *pd.spec;
  const int n = pd.n;
  const double dr = spec.range_resolution();
  const double th3 = pd.theta_3db;

  // ρ blocks: from the nearest horizontal distance the aperture can map into the window
  // (r_min·cos θ_3dB) to the far range; only those reaching a bin holding data anywhere.
  const int m_lo = static_cast<int>(std::floor((spec.r_min * std::cos(th3) - spec.r_min) / dr));
  std::vector<int> ms;
  for (int m = m_lo; m <= pd.bin_hi; ++m) {
    const double rho = spec.r_min + (m + 0.5) * dr;
    if (rho < dr) continue;
    const int first = std::max(pd.bin_lo, m);
    const int last = std::min(
        pd.bin_hi,
        spec.bin_of_range(std::min(rho / std::cos(th3) + dr, std::nextafter(spec.r_max, 0.0))));
    bool any = false;
    for (int i = first; i <= last && !any; ++i) any = pd.bin_has_data[i - pd.bin_lo];
    if (any) ms.push_back(m);
  }
  std::vector<Block> blocks(ms.size());
  tbb::parallel_for(std::size_t{0}, ms.size(), [&](std::size_t b) {
    blocks[b] = build_block(pd, pattern, spec.r_min + (ms[b] + 0.5) * dr, cfg.subsamples,
                            cfg.exact_range_subsamples, cfg.exact_lambertian ? 3 : 1);
  });

  std::vector<std::vector<LayerPoint>> per_beam(pd.beams);
  std::atomic<std::size_t> solved{0}, unconverged{0};
  std::atomic<int> max_sweeps{0}, max_iter{0};
  std::mutex kkt_mutex;
  double worst_kkt = 0.0;

  tbb::parallel_for(
      tbb::blocked_range<int>(0, pd.beams, 1), [&](const tbb::blocked_range<int>& rg) {
        NnlsSolver solver;
        std::vector<double> R(static_cast<std::size_t>(pd.bins) * n);
        std::vector<std::vector<double>> bv(blocks.size());
        std::vector<double> g, c, b_old, half_lambda, scale;
        std::vector<char> beam_bin(pd.bins);
        std::vector<std::size_t> active;
        for (int beam = rg.begin(); beam < rg.end(); ++beam) {
          const float* y = &pd.stack[static_cast<std::size_t>(beam) * pd.bins * n];
          bool any = false;
          for (int i = 0; i < pd.bins; ++i) {
            bool a = false;
            for (int k = 0; k < n && !a; ++k) a = y[static_cast<std::size_t>(i) * n + k] > 0.0f;
            beam_bin[i] = a;
            any = any || a;
          }
          if (!any) {
            if (progress) progress->add();
            continue;
          }
          for (std::size_t q = 0; q < R.size(); ++q) R[q] = y[q];
          // Blocks reaching a bin with data in this beam; the others stay at 0 (their gradient
          // Aᵀ(residual) ≤ 0 since the residual is ≤ 0 wherever the data is 0).
          active.clear();
          for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
            const Block& B = blocks[bi];
            bool a = false;
            for (int i = B.bin_first; i <= B.bin_last && !a; ++i) a = beam_bin[i - pd.bin_lo];
            if (a) active.push_back(bi);
          }
          // g = A_mᵀ·R over the non-zero residual rows of the block.
          auto block_gradient = [&](const Block& B, std::vector<double>& out_g) {
            out_g.assign(B.unknowns, 0.0);
            const int row0 = (B.bin_first - pd.bin_lo) * n;
            const int nrows = static_cast<int>(B.row_start.size()) - 1;
            for (int r = 0; r < nrows; ++r) {
              const double v = R[row0 + r];
              if (v == 0.0) continue;
              for (int e = B.row_start[r]; e < B.row_start[r + 1]; ++e) {
                out_g[B.row_col[e]] += B.row_val[e] * v;
              }
            }
          };
          // λ per ρ block, as per column in the approximate mode: λ_m = f·λ_max,m with
          // λ_max,m = 2·max(A_mᵀy) (a weighted L1 term; one λ for the whole beam would let its
          // strongest return silence the weak ones).
          double cmax = 0.0;
          half_lambda.assign(blocks.size(), 0.0);
          scale.assign(blocks.size(), 0.0);
          for (std::size_t bi : active) {
            block_gradient(blocks[bi], g);
            double m = 0.0;
            for (double v : g) m = std::max(m, v);
            half_lambda[bi] = cfg.lambda_fraction * m;
            scale[bi] = m;
            cmax = std::max(cmax, m);
            bv[bi].assign(blocks[bi].unknowns, 0.0);
          }
          if (!(cmax > 0.0)) {
            if (progress) progress->add();
            continue;
          }
          // KKT scale per block: the beam plane's max(Aᵀy), or with exact_block_tolerance the
          // block's own (floored at 1e-6 of the plane's, against rounding), so that a block of
          // weak returns (grazing surfaces) is solved as accurately as a bright one.
          for (std::size_t bi : active) {
            scale[bi] = cfg.exact_block_tolerance ? std::max(scale[bi], 1e-6 * cmax) : cmax;
          }
          const double tol = cfg.exact_tolerance;  // on the violation relative to the scale
          int sweep = 0;
          double viol = 0.0;
          bool beam_unconverged = false;
          for (; sweep < cfg.exact_max_sweeps; ++sweep) {
            viol = 0.0;
            for (std::size_t bi : active) {
              const Block& B = blocks[bi];
              std::vector<double>& b = bv[bi];
              const double hl = half_lambda[bi];
              block_gradient(B, g);  // A_mᵀ·R, R = y − Σ A b (this block included)
              // KKT violation of this block before its update: w = g − λ/2.
              double block_viol = 0.0;
              for (int p = 0; p < B.unknowns; ++p) {
                const double w = g[p] - hl;
                block_viol = std::max(block_viol, b[p] > 0 ? std::abs(w) : std::max(0.0, w));
              }
              block_viol /= scale[bi];
              viol = std::max(viol, block_viol);
              // A block already optimal (to tolerance) against the others' residual keeps its b:
              // later sweeps only revisit the blocks that the others' updates disturbed.
              if (block_viol <= tol) continue;
              // Block subproblem: min ‖A_m b − (R + A_m b_m)‖² + λ·1ᵀb: c = g + Q·b_m − λ/2.
              c.assign(B.unknowns, 0.0);
              const int bw = B.gram.bandwidth();
              const int U = B.unknowns;
              for (int p = 0; p < U; ++p) {
                c[p] += g[p] - hl;
                const double bp = b[p];
                if (bp == 0.0) continue;
                c[p] += B.gram.upper(p, 0) * bp;
                for (int d = 1; d <= bw && p + d < U; ++d) c[p + d] += B.gram.upper(p, d) * bp;
                for (int d = 1; d <= bw && p - d >= 0; ++d) c[p - d] += B.gram.upper(p - d, d) * bp;
              }
              b_old = b;
              const NnlsStats st = solver.solve(B.gram, c.data(), b.data(), cfg.nnls);
              if (!st.converged) beam_unconverged = true;
              int cur = max_iter.load();
              while (st.iterations > cur && !max_iter.compare_exchange_weak(cur, st.iterations)) {
              }
              // R −= A_m·(b − b_old)
              for (int p = 0; p < B.unknowns; ++p) {
                const double delta = b[p] - b_old[p];
                if (delta == 0.0) continue;
                for (int e = B.A.start[p]; e < B.A.start[p + 1]; ++e) {
                  R[B.A.row[e]] -= B.A.value[e] * delta;
                }
              }
            }
            if (viol <= tol) break;
          }
          ++solved;
          if (beam_unconverged || viol > tol) ++unconverged;
          {
            int cur = max_sweeps.load();
            const int s = std::min(sweep + 1, cfg.exact_max_sweeps);
            while (s > cur && !max_sweeps.compare_exchange_weak(cur, s)) {
            }
            std::lock_guard<std::mutex> lock(kkt_mutex);
            worst_kkt = std::max(worst_kkt, viol);
          }
          const double phi = spec.bearings_rad[beam];
          for (std::size_t bi : active) {
            const Block& B = blocks[bi];
            // The largest measurement this block explains (relative threshold, as per column in the
            // approximate mode).
            float ymax = 0.0f;
            const std::size_t r0 = static_cast<std::size_t>(B.bin_first - pd.bin_lo) * n;
            const std::size_t r1 = static_cast<std::size_t>(B.bin_last - pd.bin_lo + 1) * n;
            for (std::size_t q = r0; q < r1; ++q) ymax = std::max(ymax, y[q]);
            const double min_contribution = cfg.min_relative_intensity * ymax;
            for (int p = 0; p < B.P; ++p) {
              // One point per layer: b summed over the normal classes.
              const int q0 = p * B.classes, q1 = q0 + B.classes;
              double v = 0.0;
              for (int q = q0; q < q1; ++q) v += bv[bi][q];
              if (!(v > cfg.min_intensity)) continue;
              if (min_contribution > 0) {
                double predicted = 0.0;  // largest return the layer predicts
                for (int q = q0; q < q1; ++q) {
                  for (int e = B.A.start[q]; e < B.A.start[q + 1]; ++e) {
                    predicted = std::max(predicted, B.A.value[e] * bv[bi][q]);
                  }
                }
                if (predicted < min_contribution) continue;
              }
              LayerPoint lp;
              const double u = B.first_layer + p * pd.dz;
              lp.p_world = pd.to_world(B.rho, phi, u).cast<float>();
              lp.value = static_cast<float>(v);
              lp.rho = static_cast<float>(B.rho);
              lp.height = static_cast<float>(u);
              lp.beam = beam;
              lp.bin = static_cast<int>(std::lround((B.rho - spec.r_min) / dr - 0.5));
              per_beam[beam].push_back(lp);
            }
          }
          if (progress) progress->add();
        }
      });
  // Exact mode: a "column" is a whole beam plane.
  report.columns += static_cast<std::size_t>(pd.beams);
  report.columns_solved += solved.load();
  report.unconverged += unconverged.load();
  report.max_iterations = std::max(report.max_iterations, max_iter.load());
  report.exact_sweeps = std::max(report.exact_sweeps, max_sweeps.load());
  report.exact_kkt = std::max(report.exact_kkt, worst_kkt);
  for (auto& v : per_beam) out.insert(out.end(), v.begin(), v.end());
}

}  // namespace sonar3d::deconv_detail
