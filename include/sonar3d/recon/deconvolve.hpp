#pragma once
// 3D reconstruction as a deconvolution (thesis ch. 5). Images taken while the sonar moves along
// its own z axis (the direction of the vertical aperture) at spacing Δz see, at every pixel
// (range r, bearing φ), the surface indicator along a vertical line at distance r blurred by the
// beam pattern over the footprint 2·r·tan(A_v/2) (eq. 5.2). Per (r, φ) column the unknowns are P
// layers of height Δz (eq. 5.26: P = N + K − 1, K from eq. 5.25) and the images are I = A*·b with
// A*_ij the mean of B(θ)² over layer j seen from frame i (eq. 5.27); b solves eq. 5.28,
//
//   min_{b ≥ 0} ‖A*·b − I‖² + λ‖b‖₁,   λ = lambda_fraction·λ_max,  λ_max = 2·max(A*ᵀI)
//
// exactly (Lawson–Hanson, recon/nnls.hpp). Around it: Z-test denoising before (sec. 5.5.4),
// de-ringing after (zero every layer seen as free space in an unoccluded view, sec. 5.5.4),
// optional occlusion resolution of the cloud (sec. 5.6.7.3) and optional second-pass kernels
// scaled by Lambertian normals or occlusions of the first reconstruction (sec. 5.6.7.1–5.6.7.2).
//
// Beyond the thesis:
//   - the pass is measured (line fit: axis angle, lateral deviation, spacing non-uniformity,
//     orientation changes) and refused beyond tolerances; the kernel uses each frame's measured
//     height, so a non-uniform spacing is modelled rather than assumed away;
//   - eq. 5.21 (rectilinear approximation) is checked and the arc-vs-chord mismatch reported;
//   - an exact-geometry mode (`exact`) models each measurement's true slant range and elevation on
//     a (horizontal distance ρ × height h) grid per bearing plane, so that wide apertures (20–30°)
//     reconstruct vertical surfaces without the gaps of Fig. 5.14.
//
// Frames of a dataset may hold several passes (e.g. the reference-object scene): they are split
// into passes where the motion jumps, and each pass is deconvolved on its own.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/recon/denoise.hpp"
#include "sonar3d/recon/nnls.hpp"
#include "sonar3d/recon/visibility.hpp"

namespace sonar3d {

// Voxel-domain deconvolution (mode = voxel): the generalisation of eq. 5.27–5.28 to any
// trajectory (thesis sec. 5.8, 4.4.6 future work). The unknowns are the reflectivities ρ_v ≥ 0 of
// the voxels carving could not remove (its candidates, ch. 4: everything else was seen as free
// space); every pixel of every frame is one equation
//
//   I_k(i, j) = Σ_{v: centre in pixel (i, j) of frame k, |θ_kv| ≤ θ_3dB} B(θ_kv)²·ρ_v,
//
// θ_kv the elevation of voxel v seen from frame k (eq. 2.13 sampled at voxel centres; a straight
// pass gives back the layers of eq. 5.27). No assumption on the poses: orbits, lawnmowers and
// passes with any spacing. min ‖Aρ − I‖² + λ‖ρ‖₁ over ρ ≥ 0 (eq. 5.28, λ = lambda_fraction·λ_max)
// is solved by accelerated projected gradient (FISTA with adaptive restart) over the sparse A.
struct VoxelDeconvConfig {
  double voxel_size = 0.01;  // m: edge of the voxels (carving's map)
  int max_iterations = 200;  // projected-gradient iterations (measured: 200 and 1500 give the same
                             // points within 0.1 % coverage, docs/deconvolution.md)
  // Stop when an iteration changes ρ by less than this fraction of ‖ρ‖ (2-norm).
  double tolerance = 1e-4;
  // Keep voxels with ρ ≥ this fraction of the largest ρ (the iterates approach zero but do not
  // reach it in finitely many steps; 0 = every positive voxel).
  double min_relative = 0.001;
  // A lower tier (beyond the thesis, issue 15; 0 = off): a voxel whose elevation is bracketed at
  // least `bracketed` (recon/bracketing.hpp: the trajectory saw both sides of it) is kept down to
  // min_relative_bracketed·max ρ. The model has no Lambertian term, so true surfaces seen at
  // grazing incidence (a tank's top rim and base from a vertical pass) solve to 10⁻⁴–10⁻³ of the
  // brightest voxel, as faint as the ghosts left where the trajectory did not sweep the elevation
  // (past a pass' end), which bracketing tells apart; but not from the ghosts in a structure's
  // void (bracketed, never seen free). Measured (docs/deconvolution.md sec. 9), 0.0001 and 0.9:
  // jittered tank pass coverage 37.2 → 44.0 %, jittered lattice passes 62.6 → 67.4 % (outliers
  // 4.3 → 8.9 %), every orbit and jittered pass then at least carving's coverage; but the spool
  // at 20° 40.6 → 63.1 % outliers (its void), the reference objects 0.95 → 3.7 %: off by default.
  // A value ≥ min_relative has no effect.
  double min_relative_bracketed = 0.0;
  double bracketed = 0.9;
  // Carving parameters of the candidate set (docs/carving.md): candidates must be bounded by at
  // least this many frames (lowered automatically on sparse trajectories, as in carving).
  int min_observations = 2;
  // A candidate with another candidate nearer on its ray (beam, elevation cell of one voxel at
  // mid range, range tolerance Δr/2 + voxel) is left out of that frame's pixel: sound does not
  // cross a surface (the occlusion kernel of sec. 5.6.7.2, occluders = carving's candidates).
  // Measured (docs/deconvolution.md): lattice orbit median 29 → 4 cm, sphere orbit outliers
  // 18 → 10 %, and 3–10× less solve time; false = every candidate in every frame.
  bool occlusion_aware = true;
  // Candidates carving has already proven ghosts are not unknowns (beyond the thesis, issue 15):
  // the solve cannot spread a return over them, and they neither hide other candidates in the
  // occlusion model nor shield each other from the free-space test below. Two steps, in order:
  //  1. never bracketed: a candidate whose elevation no pair of frames saw from both sides,
  //     bracket (recon/bracketing.hpp) < support_min_bracket. Such a voxel lies on a return's
  //     arc beyond where the trajectory swept the elevation (above the top of an orbit's levels,
  //     past a pass' end). 0 = keep all. Skipped, with a warning, when it would leave no
  //     candidate (a trajectory that does not sweep the elevation, e.g. an orbit at one height).
  //  2. refuted (support_refute): among the front candidates of occlusion resolution (sec.
  //     4.4.5), those a frame saw in an empty pixel with nothing nearer on their own line of
  //     sight (OcclusionConfig::refute_free, carving's default): free space, not shadow.
  // Measured (docs/deconvolution.md sec. 9): lattice frame orbit 4.00 cm / 99.3 % / 39.1 % →
  // 1.00 / 99.9 / 4.9 (median / coverage / outliers); 0.5 instead of 0.1 loses 6.6 points of
  // coverage on the tank orbit (81.5 → 74.9 %, below carving's 76.4).
  double support_min_bracket = 0.1;
  bool support_refute = true;
  void validate() const;  // throws Error naming the field
};

// The one declaration of VoxelDeconvConfig's fields (core/params.hpp). In a reconstruction
// (recon/reconstruct.hpp, Nested<VoxelDeconvConfig>) the voxel size and the observation filter
// are the reconstruction's: the voxel mode's candidates are a carving of the same map.
template <class V>
void describe_voxel_deconv_own(VoxelDeconvConfig& c, V& v) {
  using params::param;
  v.field(c.max_iterations, param("max_iterations", "", "projected-gradient iterations at most")
                                .range(1, 100000)
                                .flag("--voxel-iterations"));
  v.field(c.tolerance, param("tolerance", "",
                             "stop when an iteration changes rho by less than this fraction of "
                             "its norm")
                           .range_open_low(0, 1)
                           .range_open_high(0, 1));
  v.field(c.min_relative,
          param("min_relative", "",
                "keep voxels whose reflectivity is at least this fraction of the largest "
                "(0 = every non-zero voxel)")
              .range_open_high(0, 1)
              .flag("--voxel-min-relative"));
  v.field(c.min_relative_bracketed,
          param("min_relative_bracketed", "",
                "the same fraction for voxels bracketed at least `bracketed` (0 = off; keeps "
                "faint grazing surfaces, and the ghosts in a structure's voids)")
              .range_open_high(0, 1)
              .flag("--voxel-min-relative-bracketed"));
  v.field(c.bracketed, param("bracketed", "",
                             "bracket from which a voxel is kept down to min_relative_bracketed")
                           .range(0, 1)
                           .flag("--voxel-bracketed"));
  v.field(c.occlusion_aware,
          param("occlusion_aware", "",
                "leave a candidate out of a frame's pixel when another candidate lies nearer on "
                "its ray (sound does not cross a surface)")
              .equation("sec. 5.6.7.2")
              .flag("--no-voxel-occlusion"));
  v.field(c.support_min_bracket,
          param("support_min_bracket", "",
                "leave out of the unknowns the candidates bracketed less than this (0 = keep all)")
              .range(0, 1)
              .flag("--voxel-support-bracket"));
  v.field(c.support_refute,
          param("support_refute", "",
                "leave out of the unknowns the front candidates a frame saw as free space")
              .flag("--no-voxel-refute"));
}
template <class V>
void describe(VoxelDeconvConfig& c, V& v) {
  using params::param;
  v.field(c.voxel_size,
          param("voxel_size", "m", "edge of the voxels (carving's map)").range(1e-4, 10));
  v.field(c.min_observations,
          param("min_observations", "", "candidates bounded by at least this many frames")
              .range(1, 255));
  describe_voxel_deconv_own(c, v);
}
template <class V>
void describe(params::Nested<VoxelDeconvConfig>& n, V& v) {
  describe_voxel_deconv_own(n.c, v);
}

struct DeconvConfig {
  // passes: the thesis' per-column deconvolution of straight passes along the sonar z axis (each
  // pass checked, sec. 5.6.3.1); voxel: voxel-domain NNLS over carving's candidates, for any
  // trajectory and irregular sampling (VoxelDeconvConfig); auto (the default, issue 29): passes
  // when the frames form regular passes, voxel otherwise — frames in no pass (an orbit, a pass
  // too short), a pass irregular in spacing or attitude beyond the passes mode's tolerances
  // (auto_mode_reason), or a pass the passes mode refuses or skips. DeconvReport::mode says which
  // ran, DeconvReport::mode_note why the voxel mode did.
  enum class Mode { Passes, Voxel, Auto };
  static constexpr const char* kModeNames[] = {"passes", "voxel", "auto"};  // by Mode
  Mode mode = Mode::Auto;
  VoxelDeconvConfig voxel;
  // Beam pattern of the kernel A*: sinc (eq. 2.8), flat (sec. 5.6.6: β = C inside the aperture)
  // or the sensor's own pattern (sonar.yaml beam_pattern, e.g. a measured table).
  enum class Beam { Sinc, Flat, Sensor };
  static constexpr const char* kBeamNames[] = {"sinc", "flat", "sensor"};  // by Beam
  Beam beam = Beam::Sinc;
  // λ / λ_max in [0, 1] (eq. 5.28); 0 = plain NNLS, the thesis' default; 0.5 = Table 5.1.
  double lambda_fraction = 0.0;
  // Exact-geometry mode: per bearing plane, unknowns on a (ρ, h) grid, each measurement modelled
  // with its true slant range sqrt(ρ² + (h − z_k)²) and elevation atan2(h − z_k, ρ).
  bool exact = false;

  // --- The pass (sec. 5.6.3.1: real passes are ±2 cm off) ---
  // Refuse when the motion direction is farther than this from the sonar's z axis.
  double max_axis_angle_deg = 5.0;
  // Refuse when a frame's orientation differs from the pass mean by more than this.
  double max_rotation_deg = 2.0;
  // Refuse when a frame lies farther than this from the line along the sonar z axis (m);
  // warn above half a range bin (the deviation then moves returns by a bin).
  double max_lateral_deviation = 0.05;
  // Refuse when a frame's height deviates from the uniform grid z_0 + k·Δz by more than this
  // fraction of Δz; warn above a quarter (use_measured_heights models the deviation).
  double max_spacing_deviation = 1.0;
  // Layer height Δz of the reconstruction (m); 0 = the fitted frame spacing.
  double layer_spacing = 0.0;
  // true: kernel rows use each frame's measured height; false: the thesis' uniform z_0 + k·Δz.
  bool use_measured_heights = true;
  // Split the frames into passes where the motion jumps (several passes in one dataset).
  bool split_passes = true;
  // A jump between consecutive frames, or a retreat from the pass' extreme height (a reversal),
  // larger than max(split_jump_factor × median step, 2 × max_lateral_deviation) ends a pass.
  double split_jump_factor = 5.0;
  // Passes with fewer frames are skipped with a warning.
  int min_pass_frames = 3;
  // Reconstruct only ranges ≤ max_range (m; 0 = the sensor's r_max): a short pass cannot resolve
  // far ranges whose footprint K exceeds its frame count.
  double max_range = 0.0;
  // Warn when eq. 5.21 is violated, i.e. when the arc-vs-line mismatch r·(1 − cos θ_3dB) at the
  // farthest return exceeds this fraction of a range bin (0.5 = eq. 5.21 exactly).
  double rectilinear_warn_bins = 0.5;

  // A zero pixel behind the first return of its beam may be a shadow, not empty water (the
  // conservative rule of Fig. 4.5). true: such pixels are left out of the fit (their rows of A*
  // are dropped per column), so the solver does not explain occlusions with ghost layers;
  // false: every pixel is data (the thesis). Approximate mode only: the exact mode shares its
  // block matrices between beams and uses every pixel (a majorise–minimise variant was measured
  // slower and no better, docs/deconvolution.md).
  bool ignore_shadowed_zeros = true;

  // --- Processing steps ---
  DenoiseConfig denoise;           // before (sec. 5.5.4), with the dataset's noise statistics
  bool dering = true;              // after: zero layers seen as free space (sec. 5.5.4)
  bool resolve_occlusions = true;  // post-reconstruction occlusion resolution (sec. 5.6.7.3)
  OcclusionConfig occlusion;
  // true: the occlusion voxel (one point kept per voxel) is min(Δr, Δz) so that resolution does
  // not coarsen the reconstruction (e.g. 3 mm ARIS bins); false: occlusion.voxel_size.
  bool occlusion_auto_voxel = true;
  // Multipass kernels (sec. 5.6.7): a second deconvolution whose kernel is scaled by the
  // Lambertian cosine between the view and normals of the first cloud (Normal), zeroed where the
  // first cloud occludes the view (Occlusion), or both. Approximate mode and voxel mode (there the
  // normal kernel only: its own occlusion model, VoxelDeconvConfig::occlusion_aware, is on).
  enum class Kernel { Plain, Normal, Occlusion, NormalOcclusion };
  static constexpr const char* kKernelNames[] = {"plain", "normal", "occlusion",
                                                 "normal+occlusion"};  // by Kernel
  Kernel kernel = Kernel::Plain;
  double normal_radius = 0.05;                 // m: SVD neighbourhood for normals (thesis: 5 cm)
  double occlusion_elevation_step_deg = 0.25;  // elevation resolution of the occlusion test

  // --- Numerics ---
  int subsamples = 8;          // integration points per layer for the mean of B(θ)² (eq. 5.22)
  double min_intensity = 0.0;  // drop reconstructed layers with b ≤ this
  // Drop a layer whose largest predicted return max_k A*_kp·b_p is below this fraction of the
  // column's largest measurement: the NNLS fits the model mismatch (Lambertian ρ ignored by
  // eq. 5.27, arc vs line) with faint layers, mostly at the pass ends and in shadows where
  // de-ringing cannot reach. 0 = keep every non-zero layer (the thesis). Measured: it does not
  // separate those ghosts (they lie in columns of weak data), hence off.
  double min_relative_intensity = 0.0;
  // Keep only layers within this distance (m) beyond the lowest and highest frame heights; < 0
  // keeps all P = N + K − 1 layers (eq. 5.26). Layers beyond the pass ends are seen by part of
  // their footprint only, from one side, and there the solver turns viewpoint-dependent returns
  // (grazing Lambertian surfaces, which A* ignores, eq. 5.27) into ghost layers.
  double max_extrapolation = 0.1;
  NnlsOptions nnls;
  int exact_max_sweeps = 40;      // exact mode: block Gauss–Seidel sweeps over ρ
  double exact_tolerance = 1e-3;  // exact mode: stop when the KKT violation ≤ this·max|Aᵀy|
  // Exact mode: true = the KKT violation of every ρ block is measured against the block's own
  // largest Aᵀy, so that blocks of weak returns (grazing surfaces, 1000× below the brightest
  // return of the plane) are solved to the same relative accuracy; false = against the beam
  // plane's largest Aᵀy, which leaves such blocks at 0 as already "optimal". Measured
  // (docs/deconvolution.md sec. 6): true wins at 10° (pillar, riser coverage ×2) and loses at 30°
  // on the pillar and riser (the weak blocks it solves are mostly ghosts there); hence off.
  bool exact_block_tolerance = false;
  int exact_range_subsamples = 2;  // exact mode: ρ integration points per cell
  // Exact mode: model the Lambertian term that A* (eq. 5.27) leaves out. Each (ρ, h) cell holds
  // three non-negative unknowns, the reflectivity of a surface facing the pass axis (weight
  // × cos θ), facing up (× −sin θ, seen only from frames above it) and facing down (× sin θ, seen
  // only from below); the output point is their sum. Without it, horizontal surfaces seen at
  // grazing incidence (brighter the steeper the view) are fitted with ghost cells above them and
  // caps are "seen" from behind. 3× the unknowns: slower.
  bool exact_lambertian = false;
  int num_threads = 0;  // 0 = all cores (TBB)

  void validate() const;                         // throws Error naming the field
  static Beam parse_beam(const std::string& s);  // sinc | flat | sensor
  static const char* beam_name(Beam b);
  // plain | normal | occlusion | normal+occlusion
  static Kernel parse_kernel(const std::string& s);
  static const char* kernel_name(Kernel k);
  static Mode parse_mode(const std::string& s);  // passes | voxel | auto
  static const char* mode_name(Mode m);
};

// The one declaration of DeconvConfig's fields (core/params.hpp). describe_deconv_own lists those
// only deconvolution has; a reconstruction declares denoising, occlusion resolution and threads
// once for every method and describes its deconvolution as Nested<DeconvConfig>.
template <class V>
void describe_deconv_own(DeconvConfig& c, V& v) {
  using params::param;
  v.field(c.mode, param("mode", "",
                        "passes: straight passes along the sonar z axis (the thesis); voxel: any "
                        "trajectory (NNLS over carving's candidate voxels); auto: passes when the "
                        "frames form regular passes, voxel otherwise (a note says why)")
                      .choices(DeconvConfig::kModeNames)
                      .flag("--deconv-mode"));
  params::Nested<VoxelDeconvConfig> voxel{c.voxel};
  v.group("voxel", voxel);
  v.field(c.beam, param("beam", "",
                        "kernel beam pattern: sinc (eq. 2.8), flat (sec. 5.6.6) or sensor (the "
                        "sonar.yaml's pattern)")
                      .choices(DeconvConfig::kBeamNames)
                      .flag("--beam"));
  v.field(c.lambda_fraction,
          param("lambda_fraction", "", "L1 weight as a fraction of lambda_max (0.5 = Table 5.1)")
              .range(0, 1)
              .equation("eq. 5.28")
              .flag("--lambda"));
  v.field(c.exact, param("exact", "",
                         "exact slant-range geometry on a (horizontal distance x height) grid per "
                         "bearing plane, for wide apertures")
                       .flag("--exact"));
  v.field(c.max_axis_angle_deg,
          param("max_axis_angle_deg", "deg",
                "refuse passes whose motion is farther than this from the sonar z axis")
              .range_open_low(0, 90)
              .range_open_high(0, 90)
              .equation("sec. 5.6.3.1")
              .flag("--max-axis-angle-deg"));
  v.field(c.max_rotation_deg,
          param("max_rotation_deg", "deg",
                "refuse passes whose frames turn farther than this from the pass mean")
              .range_open_low(0, 180)
              .range_open_high(0, 180));
  v.field(c.max_lateral_deviation,
          param("max_lateral_deviation", "m",
                "refuse passes whose frames lie farther than this from a straight line")
              .positive()
              .flag("--max-lateral"));
  v.field(c.max_spacing_deviation,
          param("max_spacing_deviation", "",
                "refuse passes whose heights deviate from a uniform grid by more than this "
                "fraction of the spacing")
              .positive());
  v.field(
      c.layer_spacing,
      param("layer_spacing", "m", "layer height (0 = the fitted frame spacing)").non_negative());
  v.field(c.use_measured_heights,
          param("use_measured_heights", "",
                "kernel rows use each frame's measured height (false: the uniform grid)"));
  v.field(c.split_passes,
          param("split_passes", "", "split the frames into passes where the motion jumps"));
  v.field(c.split_jump_factor,
          param("split_jump_factor", "", "a jump larger than this many median steps ends a pass")
              .range_open_low(1, 1e9));
  v.field(c.min_pass_frames,
          param("min_pass_frames", "", "passes with fewer frames are skipped").range(2, 1e9));
  v.field(c.max_range,
          param("max_range", "m", "reconstruct only ranges up to this (0 = the sensor's r_max)")
              .non_negative());
  v.field(c.rectilinear_warn_bins,
          param("rectilinear_warn_bins", "bins",
                "warn when the arc-versus-line mismatch exceeds this fraction of a range bin")
              .positive()
              .equation("eq. 5.21"));
  v.field(c.ignore_shadowed_zeros,
          param("ignore_shadowed_zeros", "",
                "leave zero pixels behind a beam's first return out of the fit (they may be "
                "shadow)"));
  v.field(c.dering, param("dering", "", "zero the layers seen as free space")
                        .equation("sec. 5.5.4")
                        .flag("--no-dering"));
  v.group("occlusion", c.occlusion);
  v.field(
      c.occlusion_auto_voxel,
      param("occlusion_auto_voxel", "",
            "the occlusion voxel is min(range bin, layer height) (false: occlusion.voxel_size)"));
  v.field(c.kernel, param("kernel", "",
                          "a second solve whose kernel is scaled by Lambert's cosine at the "
                          "normals of the first (normal), zeroed where the first occludes the "
                          "view (occlusion), both, or none (plain)")
                        .choices(DeconvConfig::kKernelNames)
                        .equation("sec. 5.6.7")
                        .flag("--kernel"));
  v.field(c.normal_radius,
          param("normal_radius", "m", "neighbourhood of the normals' SVD").positive());
  v.field(c.occlusion_elevation_step_deg,
          param("occlusion_elevation_step_deg", "deg", "elevation resolution of the occlusion test")
              .positive());
  v.field(c.subsamples,
          param("subsamples", "", "integration points per layer for the mean of B(theta)^2")
              .range(1, 64)
              .equation("eq. 5.22"));
  v.field(c.min_intensity,
          param("min_intensity", "", "drop reconstructed layers with b <= this").non_negative());
  v.field(c.min_relative_intensity,
          param("min_relative_intensity", "",
                "drop a layer whose largest predicted return is below this fraction of its "
                "column's largest measurement (0 = keep all)")
              .range_open_high(0, 1));
  v.field(c.max_extrapolation,
          param("max_extrapolation", "m",
                "keep only layers within this distance beyond the lowest and highest frames "
                "(< 0 = all)")
              .range(-1e9, 1e9));
  v.group("nnls", c.nnls);
  v.field(
      c.exact_max_sweeps,
      param("exact_max_sweeps", "", "exact mode: block Gauss-Seidel sweeps at most").range(1, 1e9));
  v.field(c.exact_tolerance,
          param("exact_tolerance", "", "exact mode: stop when the KKT violation is below this")
              .range_open_low(0, 1)
              .range_open_high(0, 1));
  v.field(c.exact_block_tolerance,
          param("exact_block_tolerance", "",
                "exact mode: measure each range block's KKT violation against its own data")
              .flag("--exact-block-tolerance"));
  v.field(c.exact_range_subsamples,
          param("exact_range_subsamples", "", "exact mode: integration points per cell")
              .range(1, 16)
              .flag("--exact-range-subsamples"));
  v.field(c.exact_lambertian,
          param("exact_lambertian", "",
                "exact mode with the Lambertian term: three normal classes per cell (implies "
                "exact in a reconstruction)")
              .flag("--exact-lambertian"));
}
template <class V>
void describe(DeconvConfig& c, V& v) {
  using params::param;
  v.group("denoise", c.denoise);
  v.field(c.resolve_occlusions,
          param("resolve_occlusions", "", "post-reconstruction occlusion resolution")
              .equation("sec. 5.6.7.3"));
  v.field(c.num_threads, param("num_threads", "", "worker threads (0 = all cores)").non_negative());
  describe_deconv_own(c, v);
}
template <class V>
void describe(params::Nested<DeconvConfig>& n, V& v) {
  describe_deconv_own(n.c, v);
}

// The straight pass a set of frames is approximated by (sec. 5.4, 5.6.3.1).
struct PassGeometry {
  std::vector<std::size_t> frames;  // frame indices (into the caller's list), by increasing height
  std::vector<double> heights;      // measured height of each along the pass axis, m
  // Pass frame: origin at the centroid of the positions, rotation = mean sonar orientation; its
  // +z is the pass axis (the sonar's z). Heights are z coordinates in this frame.
  Eigen::Isometry3d T_world_pass = Eigen::Isometry3d::Identity();
  double spacing = 0.0;           // fitted Δz between consecutive frames, m
  double axis_angle_rad = 0.0;    // motion direction (line fit) vs the sonar z axis
  double max_rotation_rad = 0.0;  // largest orientation difference from the mean
  double max_lateral = 0.0;       // m, distance of positions from the pass axis line
  double rms_lateral = 0.0;
  double max_spacing_error = 0.0;  // m, |height − (z_0 + k·Δz)|
  double rms_spacing_error = 0.0;
  bool descending = false;  // frames were recorded moving toward −z
  std::vector<std::string> warnings;
};

// Fits the pass to the poses (T_world_sonar per frame) and checks it against the tolerances of
// `config`. Throws Error with the measured figures when the motion is not along the sonar z axis,
// the orientation changes, the lateral or spacing deviation is too large, or the frames are too
// few. `where` prefixes messages (e.g. "pass 2 (frames 261–521)").
PassGeometry analyze_pass(const std::vector<Eigen::Isometry3d>& T_world_sonar,
                          const DeconvConfig& config, const std::string& where = "pass");

// Splits frames (in recording order) into passes: [first, last) ranges, at jumps of the motion.
std::vector<std::pair<std::size_t, std::size_t>> split_passes(
    const std::vector<Eigen::Isometry3d>& T_world_sonar, const DeconvConfig& config);

// Mode::Auto's choice from the poses alone: empty when the passes mode applies, else why not, in
// one line: frames in no pass of min_pass_frames or more, a pass that analyze_pass refuses
// (spacing, attitude, axis, lateral deviation beyond the tolerances), or one pass broken in two by
// a gap or a jolt (the next part continues along the same line in the same direction).
std::string auto_mode_reason(const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const DeconvConfig& config);

// eq. 5.25: K = ⌊2·r·tan(A_v/2)/Δz⌋, at least 1 (a footprint thinner than a layer still sees it).
int footprint_layers(double range, double vertical_aperture_rad, double dz);
// Arc-vs-chord mismatch of the rectilinear approximation at range r (m): a scatterer on the
// vertical line at distance r seen at the aperture edge is at slant range r/cos θ_3dB, not r.
// eq. 5.21 holds when it is ≤ Δr/2.
double rectilinear_mismatch(double range, double theta_3db_rad);
// Largest aperture (full width, rad) satisfying eq. 5.21 at range r with range resolution dr.
double rectilinear_max_aperture(double range, double range_resolution);

// The kernel A* of one column (eq. 5.27) at range r for frames at `heights` (sorted, m) and
// layers u_p = heights[0] + (p − (K − 1)/2)·Δz. The footprint of frame k is modelled as K whole
// layers, |u − z_k| ≤ K·Δz/2 (eq. 5.25); A*_kp is the mean of B(atan((u − z_k)/r))² over the
// part of layer p inside it (and inside |θ| ≤ θ_3dB). A uniform pass gives rows of K layers
// k..k+K−1 and P = N + K − 1 (eq. 5.26); a frame between layer positions overlaps K + 1 layers.
struct ColumnKernel {
  int K = 1;
  int layers = 0;            // P
  double first_layer = 0.0;  // u_0, m (pass frame)
  double dz = 0.0;
  SparseColumns A;  // frames × layers
  BandMatrix gram;  // A*ᵀA*
  double layer_height(int p) const { return first_layer + p * dz; }
};
ColumnKernel build_column_kernel(double range, const std::vector<double>& heights, double dz,
                                 const BeamPattern& pattern, double theta_3db, int subsamples);

struct PassReport {
  std::size_t first_frame = 0;  // in the caller's frame list
  std::size_t frames = 0;
  double spacing = 0.0;  // m
  double axis_angle_deg = 0.0;
  double max_rotation_deg = 0.0;
  double max_lateral = 0.0;                   // m
  double rms_lateral = 0.0;                   // m
  double max_spacing_error = 0.0;             // m
  double rms_spacing_error = 0.0;             // m
  int K_min = 0, K_max = 0;                   // eq. 5.25 over the reconstructed range window
  double rectilinear_mismatch_bins = 0.0;     // at the far range, in range bins
  double rectilinear_max_aperture_deg = 0.0;  // eq. 5.21 at the far range
  std::size_t columns = 0;          // (range, bearing) columns, or beams × ρ blocks in exact mode
  std::size_t columns_solved = 0;   // non-empty ones
  std::size_t unconverged = 0;      // NNLS (or exact-mode sweeps) that hit their iteration cap
  int max_iterations = 0;           // largest NNLS outer iteration count
  int exact_sweeps = 0;             // exact mode: largest sweep count over beams
  double exact_kkt = 0.0;           // exact mode: worst relative KKT violation at exit
  std::size_t points_solved = 0;    // non-zero layers
  std::size_t points_deringed = 0;  // removed by de-ringing
  std::vector<std::string> warnings;
};

// Collapses warnings that repeat for many passes ("pass N (frames A–B): what") into one line per
// distinct "what": "36 passes, pass 1 (frames 0–0) … pass 36 (frames 35–35): what". Other
// warnings are kept as they are, in order.
std::vector<std::string> summarize_pass_warnings(const std::vector<std::string>& warnings);

// Voxel mode (VoxelDeconvConfig): size of the problem and convergence.
struct VoxelDeconvReport {
  std::size_t candidates = 0;   // carving's candidates
  std::size_t unbracketed = 0;  // of them, left out as never bracketed (support_min_bracket)
  std::size_t refuted = 0;      // of them, left out as seen free (support_refute)
  std::size_t unknowns = 0;     // candidates in at least one pixel with a return (the others are 0)
  std::size_t equations = 0;    // pixels with at least one candidate (rows of A)
  std::size_t nonzeros = 0;     // entries of A
  int iterations = 0;           // projected-gradient iterations
  bool converged = false;       // stopped on the tolerance, not the iteration cap
  double relative_residual = 0;    // ‖Aρ − I‖ / ‖I‖ at exit
  std::size_t points_solved = 0;   // voxels kept (ρ above min_relative·max ρ, or bracketed)
  std::size_t kept_bracketed = 0;  // of them, below min_relative·max ρ, kept as bracketed
  double seconds_carve = 0;        // candidates (carving)
  double seconds_build = 0;        // A
  double seconds_solve = 0;
};

struct DeconvReport {
  std::string mode = "passes";  // the mode that ran ("passes" or "voxel")
  // Mode::Auto ran the voxel mode: one line saying so and why (empty otherwise).
  std::string mode_note;
  std::vector<PassReport> passes;
  VoxelDeconvReport voxel;  // mode "voxel"
  std::size_t frames = 0;
  std::size_t points = 0;  // in the output cloud
  std::size_t points_before_occlusion = 0;
  double seconds_load = 0.0;   // reading + denoising (deconvolve_dataset only)
  double seconds_solve = 0.0;  // kernels + NNLS
  double seconds_dering = 0.0;
  double seconds_multipass = 0.0;
  double seconds_occlusion = 0.0;
  double seconds_total = 0.0;
  std::vector<std::string> warnings;  // all passes' warnings, prefixed by the pass
  // One line per pass + totals, then summarize_pass_warnings() unless `with_warnings` is false
  // (the CLI prints those on stderr).
  std::string to_text(bool with_warnings = true) const;
  std::string to_json(int indent = 2) const;
};

// Deconvolves denoised frames with their poses: splits passes, solves every column, de-rings,
// optional second pass and occlusion resolution. Frames must match spec. Output: world frame,
// intensity = b (layers with b > min_intensity). Throws Error naming the pass on bad motion.
PointCloud deconvolve_frames(const std::vector<SonarImage>& denoised,
                             const std::vector<Eigen::Isometry3d>& T_world_sonar,
                             const SonarSpec& spec, const DeconvConfig& config,
                             DeconvReport* report = nullptr, bool progress = false);

// Reads every frame of the dataset, denoises it (config.denoise with the dataset's noise
// statistics) and calls deconvolve_frames.
PointCloud deconvolve_dataset(const Dataset& dataset, const DeconvConfig& config, bool progress,
                              DeconvReport* report = nullptr);

}  // namespace sonar3d
