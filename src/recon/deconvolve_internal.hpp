#pragma once
// Shared between the deconvolution translation units (approximate columns, exact-geometry planes,
// multipass kernels). Not installed.
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "sonar3d/core/progress.hpp"
#include "sonar3d/recon/deconvolve.hpp"

namespace sonar3d::deconv_detail {

// The data of one pass, arranged for column access.
struct PassData {
  const SonarSpec* spec = nullptr;
  PassGeometry geo;
  std::vector<double> heights;  // model heights of the frames (measured or uniform), sorted, m
  double dz = 0.0;              // layer height, m
  double theta_3db = 0.0;
  int n = 0;                   // frames
  int bin_lo = 0, bin_hi = 0;  // reconstructed range bins [bin_lo, bin_hi]
  int bins = 0;                // bin_hi − bin_lo + 1
  int beams = 0;
  // Denoised intensities: stack[(beam·bins + bin − bin_lo)·n + k], k = frame by height. A beam's
  // block (bins·n values) is contiguous: the exact mode reads it as its measurement vector.
  std::vector<float> stack;
  std::vector<char> bin_has_data;  // any non-zero pixel in that bin (any beam, any frame)
  // first_return[beam·n + k]: first range bin with a return in frame k (by height) on that beam,
  // or bins when none (from the stack: the window's own data).
  std::vector<int> first_return;
  // Per frame (by height): summary for free-space tests (empty when not needed).
  std::vector<const FrameReturns*> returns;
  std::vector<Eigen::Isometry3d> T_world_sonar;  // by height

  const float* column(int bin, int beam) const {
    return &stack[(static_cast<std::size_t>(beam) * bins + (bin - bin_lo)) * n];
  }
  // A point at horizontal distance rho from the pass axis, bearing phi, height u (pass frame).
  Eigen::Vector3d to_world(double rho, double phi, double u) const {
    return geo.T_world_pass * Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), u);
  }
};

// A reconstructed layer: one output point.
struct LayerPoint {
  Eigen::Vector3f p_world;
  float value = 0.0f;   // b
  float rho = 0.0f;     // horizontal distance from the pass axis, m
  float height = 0.0f;  // u, pass frame, m
  int beam = 0;
  int bin = 0;  // range bin (approximate mode) or ρ block (exact mode)
};

// Second-pass kernel factors (sec. 5.6.7): multiplies in place the entries A*_kp of one layer
// (at p_world, seen through `beam`) for the frames frames[0..count) (indices by height).
class KernelScaler {
 public:
  virtual ~KernelScaler() = default;
  virtual void scale(int beam, const Eigen::Vector3d& p_world, const int* frames, int count,
                     float* values) const = 0;
};

// Mean of B(θ)² over a layer [offset − dz/2, offset + dz/2] above the frame at horizontal
// distance r (θ = atan(h/r), rectilinear geometry), counting only heights inside the modelled
// footprint |h| ≤ half_width and the aperture |θ| ≤ θ_3dB.
double layer_power(const BeamPattern& pattern, double theta_3db, double r, double offset, double dz,
                   int subsamples, double half_width);

void solve_approx(const PassData& pd, const DeconvConfig& cfg, const BeamPattern& pattern,
                  const KernelScaler* scaler, PassReport& report, std::vector<LayerPoint>& out,
                  Progress* progress);

void solve_exact(const PassData& pd, const DeconvConfig& cfg, const BeamPattern& pattern,
                 PassReport& report, std::vector<LayerPoint>& out, Progress* progress);

std::unique_ptr<KernelScaler> make_multipass_scaler(const PassData& pd, const DeconvConfig& cfg,
                                                    const std::vector<LayerPoint>& first);

// Lambert (eq. 2.6) in the normal kernel (sec. 5.6.7.1): the cosine is floored so that grazing
// unknowns keep a usable column (an all-zero column cannot be estimated).
constexpr double kMinLambertCosine = 0.1;

// The normal kernel's geometry (sec. 5.6.7.1, Fig. 5.26): for each query point, the normal (SVD
// of the covariance over `radius`) at the nearest point of `pts` within `radius`; zero where no
// point there has 5 neighbours.
std::vector<Eigen::Vector3f> normals_near(const std::vector<Eigen::Vector3d>& pts, double radius,
                                          const std::vector<Eigen::Vector3f>& queries);

// The kernel's beam pattern (DeconvConfig::beam).
BeamPattern kernel_pattern(const DeconvConfig& cfg, const SonarSpec& spec);

// Voxel mode (VoxelDeconvConfig): the whole reconstruction, occlusion resolution included.
PointCloud deconvolve_voxels(const std::vector<SonarImage>& denoised,
                             const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const SonarSpec& spec, const DeconvConfig& config,
                             DeconvReport& report, bool progress);

// Zeroes (removes) every point seen as free space by an unoccluded view of the pass (sec. 5.5.4).
// Returns the number removed.
std::size_t dering(const PassData& pd, std::vector<LayerPoint>& points);

}  // namespace sonar3d::deconv_detail
