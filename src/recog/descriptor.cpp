// Ring descriptors, EMD and the patch scan of 2D structure recognition (thesis sec. 6.3.2.3–
// 6.3.2.6).
#include "sonar3d/recog/descriptor.hpp"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d {

void DescriptorConfig::validate() const { params::check(*this, "descriptor"); }

void ScanConfig::validate() const {
  params::check(*this, "scan");
  require(num_threads >= 0, "scan num_threads must be >= 0 (0 = all cores)");
}

std::size_t RingLayout::num_cells() const {
  std::size_t n = 0;
  for (const auto& r : rings) n += r.size();
  return n;
}

RingLayout make_ring_layout(double cell_m, double radius_m, double ring_width_m) {
  require_positive(cell_m, "ring layout cell_m", "m");
  require_positive(radius_m, "ring layout radius_m", "m");
  require_positive(ring_width_m, "ring layout ring_width_m", "m");
  const long long h = limits::checked_count(std::ceil(radius_m / cell_m), 1, 4000,
                                            "patch radius in cells", "use a coarser cell size");
  const long long n = limits::checked_count(std::ceil(radius_m / ring_width_m - 1e-9), 1, 1000,
                                            "number of rings", "use wider rings");
  RingLayout L;
  L.cell_m = cell_m;
  L.radius_m = radius_m;
  L.ring_width_m = ring_width_m;
  L.rings.resize(static_cast<std::size_t>(n));
  for (int dr = -static_cast<int>(h); dr <= h; ++dr) {
    for (int dc = -static_cast<int>(h); dc <= h; ++dc) {
      const double d = std::hypot(dr, dc) * cell_m;
      if (d > radius_m) continue;
      const int k = std::min(static_cast<int>(n) - 1, static_cast<int>(d / ring_width_m));
      L.rings[k].emplace_back(dr, dc);
    }
  }
  // A ring can be empty when rings are narrower than cells: drop empty ones.
  L.rings.erase(
      std::remove_if(L.rings.begin(), L.rings.end(), [](const auto& r) { return r.empty(); }),
      L.rings.end());
  return L;
}

namespace {

float median_of(std::vector<float>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

bool describe(const ElevationMap& map, const std::vector<uint8_t>& removed, int row, int col,
              const RingLayout& layout, double z_lo, int num_bins, double bin_m,
              double min_valid_fraction, RingDescriptor* out) {
  thread_local std::vector<float> values;
  thread_local std::vector<int> ring_of;
  values.clear();
  ring_of.clear();
  const int K = static_cast<int>(layout.rings.size());
  for (int k = 0; k < K; ++k) {
    for (const auto& o : layout.rings[k]) {
      const int r = row + o.x(), c = col + o.y();
      if (r < 0 || c < 0 || r >= map.rows || c >= map.cols) continue;
      const std::size_t i = map.index(r, c);
      const float z = map.z[i];
      if (z != z || (!removed.empty() && removed[i])) continue;
      values.push_back(z);
      ring_of.push_back(k);
    }
  }
  if (values.empty()) return false;
  out->num_bins = num_bins;
  out->bin_m = bin_m;
  out->z_lo = z_lo;
  out->hist.assign(static_cast<std::size_t>(K),
                   std::vector<float>(static_cast<std::size_t>(num_bins), 0.f));
  out->valid.assign(static_cast<std::size_t>(K), 0);
  std::vector<int> count(static_cast<std::size_t>(K), 0);
  {
    std::vector<float> tmp = values;
    out->median_z = median_of(tmp);  // eq. 6.1: depths aligned on the signed median
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double b = std::floor((values[i] - out->median_z - z_lo) / bin_m);
    const int bi = static_cast<int>(std::clamp(b, 0.0, static_cast<double>(num_bins - 1)));
    out->hist[ring_of[i]][bi] += 1.f;
    ++count[ring_of[i]];
  }
  for (int k = 0; k < K; ++k) {
    const double need = min_valid_fraction * static_cast<double>(layout.rings[k].size());
    out->valid[k] = count[k] > 0 && count[k] >= need;
    if (count[k] > 0) {
      const float inv = 1.f / static_cast<float>(count[k]);
      for (float& h : out->hist[k]) h *= inv;
    }
  }
  return true;
}

RingDescriptor describe_model(const ElevationMap& top_view, int row, int col,
                              const RingLayout& layout, const DescriptorConfig& config) {
  config.validate();
  // The model's heights relative to its disc median set the histogram range.
  std::vector<float> v;
  for (const auto& ring : layout.rings) {
    for (const auto& o : ring) {
      const int r = row + o.x(), c = col + o.y();
      if (r < 0 || c < 0 || r >= top_view.rows || c >= top_view.cols) continue;
      const float z = top_view.at(r, c);
      if (z == z) v.push_back(z);
    }
  }
  require(!v.empty(), "model descriptor: the top view holds no data");
  const float lo = *std::min_element(v.begin(), v.end()),
              hi = *std::max_element(v.begin(), v.end());
  const float med = median_of(v);
  const double z_lo = (lo - med) - config.margin_m;
  const double z_hi = (hi - med) + config.margin_m;
  const long long bins = limits::checked_count(std::ceil((z_hi - z_lo) / config.bin_m), 1, 100000,
                                               "histogram bins", "use a coarser bin_m");
  RingDescriptor d;
  describe(top_view, {}, row, col, layout, z_lo, static_cast<int>(bins), config.bin_m, 0.0, &d);
  return d;
}

double emd_1d(const std::vector<float>& a, const std::vector<float>& b, double bin_m) {
  require(a.size() == b.size(), "emd_1d: the histograms have different bin counts");
  // 1-D EMD between equal masses: sum over bin edges of |CDF_a − CDF_b| · bin width.
  double ca = 0, cb = 0, sum = 0;
  for (std::size_t i = 0; i + 1 < a.size(); ++i) {
    ca += a[i];
    cb += b[i];
    sum += std::abs(ca - cb);
  }
  return sum * bin_m;
}

double emd_opencv(const std::vector<float>& a, const std::vector<float>& b, double bin_m) {
  require(a.size() == b.size() && !a.empty(), "emd_opencv: histograms of equal, non-zero length");
  limits::checked_count(static_cast<double>(a.size()), 1, 2000, "emd_opencv: bins",
                        "use emd_1d for long histograms");
  const int n = static_cast<int>(a.size());
  cv::Mat sa(n, 2, CV_32F), sb(n, 2, CV_32F), cost(n, n, CV_32F);
  for (int i = 0; i < n; ++i) {
    sa.at<float>(i, 0) = a[i];
    sa.at<float>(i, 1) = static_cast<float>(i);
    sb.at<float>(i, 0) = b[i];
    sb.at<float>(i, 1) = static_cast<float>(i);
    for (int j = 0; j < n; ++j) cost.at<float>(i, j) = static_cast<float>(std::abs(i - j) * bin_m);
  }
  // cv::EMD returns the work divided by the flow (the mass moved): for unit masses, the work.
  double flow_mass = 0;
  for (float v : a) flow_mass += v;
  double mb = 0;
  for (float v : b) mb += v;
  return cv::EMD(sa, sb, cv::DIST_USER, cost) * std::min(flow_mass, mb);
}

double ring_distance_sq(const RingDescriptor& model, const RingDescriptor& patch, double bound2,
                        int* rings_evaluated) {
  const int K = std::min(model.num_rings(), patch.num_rings());
  const double worst = (model.num_bins - 1) * model.bin_m;  // all mass moved end to end
  double sum2 = 0;
  for (int k = 0; k < K; ++k) {
    const double d = patch.valid[k] ? emd_1d(model.hist[k], patch.hist[k], model.bin_m) : worst;
    sum2 += d * d;
    // Sec. 6.3.2.6: the partial (squared) norm bounds the full one from below; sums of
    // non-negative terms never decrease, also in floating point.
    if (sum2 > bound2) {
      if (rings_evaluated) *rings_evaluated = k + 1;
      return std::numeric_limits<double>::infinity();
    }
  }
  if (rings_evaluated) *rings_evaluated = K;
  return sum2;
}

double ring_distance(const RingDescriptor& model, const RingDescriptor& patch, double bound,
                     int* rings_evaluated) {
  const double bound2 = std::isfinite(bound) ? bound * bound : bound;
  return std::sqrt(ring_distance_sq(model, patch, bound2, rings_evaluated));
}

ScanResult scan_patches(const ElevationMap& map, const std::vector<uint8_t>& removed,
                        const std::vector<uint8_t>& excluded, const RingLayout& layout,
                        const RingDescriptor& model, double min_valid_fraction, double bound,
                        const ScanConfig& config) {
  config.validate();
  require(!map.empty(), "patch scan: the elevation map is empty");
  require(removed.empty() || removed.size() == map.z.size(), "patch scan: mask size mismatch");
  const auto start = std::chrono::steady_clock::now();
  const int step = std::max(1, static_cast<int>(std::lround(config.period_m / map.cell_m)));
  const int nr = (map.rows + step - 1) / step, nc = (map.cols + step - 1) / step;
  std::optional<tbb::global_control> threads;
  if (config.num_threads > 0) {
    threads.emplace(tbb::global_control::max_allowed_parallelism,
                    static_cast<std::size_t>(config.num_threads));
  }
  // The best so far, shared for early abort: a candidate is dropped once its partial norm
  // exceeds it, which never drops the winner (its partial norms never exceed its own score,
  // itself <= the best so far at any time).
  const double bound2 = std::isfinite(bound) ? bound * bound : bound;
  std::atomic<double> best_so_far{bound2};  // squared norms throughout: ties compare exactly
  struct Best {
    double score = std::numeric_limits<double>::infinity();
    long index = -1;
  };
  std::mutex mutex;
  Best best;
  std::atomic<std::size_t> candidates{0}, scored{0}, aborted{0}, rings{0};
  tbb::parallel_for(
      tbb::blocked_range<long>(0, static_cast<long>(nr) * nc, 64),
      [&](const tbb::blocked_range<long>& range) {
        RingDescriptor patch;
        Best local;
        std::size_t n_cand = 0, n_scored = 0, n_abort = 0, n_rings = 0;
        for (long k = range.begin(); k != range.end(); ++k) {
          const int r = static_cast<int>(k / nc) * step + step / 2;
          const int c = static_cast<int>(k % nc) * step + step / 2;
          if (r >= map.rows || c >= map.cols) continue;
          const std::size_t i = map.index(r, c);
          if (!excluded.empty() && excluded[i]) continue;
          if (map.z[i] != map.z[i] || (!removed.empty() && removed[i])) continue;
          ++n_cand;
          if (!describe(map, removed, r, c, layout, model.z_lo, model.num_bins, model.bin_m,
                        min_valid_fraction, &patch)) {
            continue;
          }
          bool enough = true;
          for (uint8_t v : patch.valid) enough = enough && v;
          if (!enough) continue;  // too little data in some ring to judge
          ++n_scored;
          const double b = config.early_abort ? std::min(bound2, best_so_far.load()) : bound2;
          int evaluated = 0;
          const double s = ring_distance_sq(model, patch, b, &evaluated);
          n_rings += static_cast<std::size_t>(evaluated);
          if (!std::isfinite(s)) {
            ++n_abort;
            continue;
          }
          if (s < local.score || (s == local.score && k < local.index)) local = {s, k};
          double cur = best_so_far.load();
          while (s < cur && !best_so_far.compare_exchange_weak(cur, s)) {
          }
        }
        candidates += n_cand;
        scored += n_scored;
        aborted += n_abort;
        rings += n_rings;
        std::lock_guard<std::mutex> lock(mutex);
        if (local.index >= 0 &&
            (local.score < best.score || (local.score == best.score && local.index < best.index))) {
          best = local;
        }
      });
  ScanResult out;
  out.candidates = candidates;
  out.scored = scored;
  out.aborted = aborted;
  out.rings_evaluated = rings;
  if (best.index >= 0) {
    out.found = true;
    out.row = static_cast<int>(best.index / nc) * step + step / 2;
    out.col = static_cast<int>(best.index % nc) * step + step / 2;
    out.center_xy = map.cell_center_xy(out.row, out.col);
    out.score_m = std::sqrt(best.score);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace sonar3d
