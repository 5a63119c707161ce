#pragma once
// Structure recognition in 2D (thesis sec. 6.3.2.3–6.3.2.6): rotation-invariant descriptors of
// elevation histograms on N concentric rings, the Earth Mover's Distance between them, and the
// scan of a field's elevation map for the patch most like a model, with early abort.
#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

struct DescriptorConfig {
  double ring_width_m = 0.24;  // width of each ring (the thesis: 24 cm at 8 cm cells), m
  double bin_m = 0.01;         // depth resolution of the histograms (the thesis: 1 cm), m
  // Histogram range: the model's heights relative to its median, widened by these margins;
  // heights beyond fall in the end bins.
  double margin_m = 0.3;
  // A patch is scored only when at least this fraction of each ring's cells hold data.
  double min_valid_fraction = 0.5;
  void validate() const;
};
// The fields' one declaration (core/params.hpp).
template <class V>
void describe(DescriptorConfig& c, V& v) {
  using params::param;
  v.field(c.ring_width_m, param("ring_width_m", "m",
                                "width of each descriptor ring (the thesis: 24 cm at 8 cm cells)")
                              .positive()
                              .flag("--ring-width")
                              .equation("sec. 6.3.2.3"));
  v.field(c.bin_m, param("bin_m", "m", "depth resolution of the ring histograms (the thesis: 1 cm)")
                       .positive()
                       .flag("--bin"));
  v.field(c.margin_m, param("margin_m", "m",
                            "histogram range: the model's heights about their median widened by "
                            "this; heights beyond fall in the end bins")
                          .non_negative());
  v.field(c.min_valid_fraction,
          param("min_valid_fraction", "",
                "score a patch only when each ring has at least this fraction of its cells "
                "observed")
              .range(0, 1)
              .flag("--min-valid-fraction"));
}

// The cells of a disc of radius `radius_m` at cell size `cell_m`, by ring: offsets (drow, dcol)
// of cells whose centres lie within the disc, ring k holding centres at distance in
// [k·w, (k+1)·w) (w = ring width). N = ceil(radius / w) rings.
struct RingLayout {
  double cell_m = 0, radius_m = 0, ring_width_m = 0;
  std::vector<std::vector<Eigen::Vector2i>> rings;  // per ring, (drow, dcol)
  std::size_t num_cells() const;
};
RingLayout make_ring_layout(double cell_m, double radius_m, double ring_width_m);

// Sec. 6.3.2.3: per ring, the histogram of heights relative to the disc's median (the depth
// alignment of eq. 6.1 between two distributions: matching their signed medians), P bins of
// bin_m from z_lo; normalised to unit mass. Rings with too few data are marked invalid.
struct RingDescriptor {
  int num_bins = 0;
  double bin_m = 0.01, z_lo = 0;  // bin b covers [z_lo + b·bin, z_lo + (b+1)·bin) about the median
  double median_z = 0;            // the disc's median height (world z)
  std::vector<std::vector<float>> hist;  // per ring, num_bins masses summing to 1
  std::vector<uint8_t> valid;            // per ring
  int num_rings() const { return static_cast<int>(hist.size()); }
};

// The descriptor of the disc centred on cell (row, col) of `map`; cells with no data, outside
// the map or flagged in `removed` (same size as the map, or empty) do not count. `z_lo`,
// `num_bins`: the histogram range (from the model's descriptor). Returns false when the disc
// holds no data.
bool describe(const ElevationMap& map, const std::vector<uint8_t>& removed, int row, int col,
              const RingLayout& layout, double z_lo, int num_bins, double bin_m,
              double min_valid_fraction, RingDescriptor* out);

// The model's descriptor from its top view (background filled) centred at cell (row, col);
// the histogram range comes from the model's own heights.
RingDescriptor describe_model(const ElevationMap& top_view, int row, int col,
                              const RingLayout& layout, const DescriptorConfig& config);

// Earth Mover's Distance between two 1-D histograms of equal mass on the same bins of width
// `bin_m` (ground distance |i − j|·bin_m): the L1 distance between their cumulative sums times
// the bin width (Rubner et al. 2000; the 1-D case of the transport problem), in metres.
double emd_1d(const std::vector<float>& a, const std::vector<float>& b, double bin_m);

// The same distance by OpenCV's general transport solver (cv::EMD, Rubner et al.'s algorithm,
// ground distance |i − j|·bin_m): O(P³), for checking emd_1d and for histograms of unequal
// mass (normalised to the lighter one).
double emd_opencv(const std::vector<float>& a, const std::vector<float>& b, double bin_m);

// Sec. 6.3.2.4: the norm of the per-ring EMDs, ||(d_1 … d_N)||_2, evaluated ring by ring;
// sec. 6.3.2.6: stops as soon as the partial norm exceeds `bound` (it can only grow), returning
// +inf and the rings evaluated. Rings invalid in the patch cost the worst EMD of the range.
double ring_distance(const RingDescriptor& model, const RingDescriptor& patch, double bound,
                     int* rings_evaluated = nullptr);
// The same on squares: returns the squared norm, or +inf once a partial one exceeds bound2.
double ring_distance_sq(const RingDescriptor& model, const RingDescriptor& patch, double bound2,
                        int* rings_evaluated = nullptr);

struct ScanConfig {
  double period_m = 0.16;   // T_NE: spacing of the candidate patch centres, m
  bool early_abort = true;  // sec. 6.3.2.6
  int num_threads = 0;      // 0 = all cores
  void validate() const;
};
// num_threads is not declared: the recognition sets it from its own num_threads.
template <class V>
void describe(ScanConfig& c, V& v) {
  using params::param;
  v.field(c.period_m, param("period_m", "m", "T_NE: spacing of the candidate patch centres")
                          .positive()
                          .flag("--period")
                          .equation("eq. 6.8"));
  v.field(
      c.early_abort,
      param("early_abort", "", "stop scoring a patch once it cannot win").equation("sec. 6.3.2.6"));
}

struct ScanResult {
  bool found = false;
  int row = -1, col = -1;  // winning patch centre cell
  Eigen::Vector2d center_xy{0, 0};
  double score_m = 0;  // ||(d_1 … d_N)||_2, m
  std::size_t candidates = 0, scored = 0, aborted = 0;
  std::size_t rings_evaluated = 0;
  double seconds = 0;
};

// Sec. 6.3.2.4: every patch centre on a grid of period T_NE over the map (patch radius: the
// layout's, eq. 6.8), parallel (TBB); the lowest score wins, ties to the first centre in row-major
// order. A candidate is scored only if its score may beat `bound` (and the best so far, with
// early_abort). `excluded`: cells that may not be candidate centres (empty: none).
ScanResult scan_patches(const ElevationMap& map, const std::vector<uint8_t>& removed,
                        const std::vector<uint8_t>& excluded, const RingLayout& layout,
                        const RingDescriptor& model, double min_valid_fraction, double bound,
                        const ScanConfig& config);

}  // namespace sonar3d
