#pragma once
// What one sonar frame says about space, shared by carving and deconvolution (thesis sec. 4.4.3,
// 4.4.5, 5.5.4, 5.6.7.3): which points it sees as free (conservative reprojection, Fig. 4.5) and
// which map points are front surfaces it observed rather than shadowed (occlusion resolution,
// Fig. 4.7–4.8).
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

class Progress;

// A compact summary of a denoised frame: its pose and, per beam, the returns (non-zero pixels).
// Small enough to keep for thousands of frames (the online carver keeps one per frame): the
// returns are a bitset, about range_bins × beams / 8 bytes (30 kB for a 768-beam, 260-bin P900
// frame) instead of one byte per pixel.
struct FrameReturns {
  Eigen::Isometry3d T_world_sonar = Eigen::Isometry3d::Identity();
  int range_bins = 0;
  int beams = 0;
  // Per beam: the first range bin holding a return, or range_bins when the beam saw nothing.
  std::vector<int> first_return_bin;
  // Per beam: the last range bin holding a return, or -1 when the beam saw nothing.
  std::vector<int> last_return_bin;
  // Beam-major bitset: bit `bin` of beam j lives in words [j·words_per_beam, (j+1)·words_per_beam).
  int words_per_beam = 0;
  std::vector<std::uint64_t> return_bits;

  // True where the denoised pixel (range bin, beam) is > 0.
  bool has_return(int bin, int beam) const {
    const std::uint64_t w =
        return_bits[static_cast<std::size_t>(beam) * words_per_beam + (bin >> 6)];
    return (w >> (bin & 63)) & 1u;
  }
  // True when beam j has a return in range bins [bin0, bin1] (inclusive, clamped).
  bool any_return(int beam, int bin0, int bin1) const;
  std::size_t memory_bytes() const;  // heap + object, for memory accounting
};

// Throws Error when the image size differs from the spec or the pose is not a finite rigid
// transform.
FrameReturns summarize_frame(const SonarImage& denoised, const Eigen::Isometry3d& T_world_sonar,
                             const SonarSpec& spec);

// Conservative free space (Fig. 4.5): true when p_world lies inside the frame's footprint
// (field of view, vertical aperture, range window) in a pixel without return and no return lies
// at a shorter range on that beam.
bool seen_free(const FrameReturns& frame, const SonarSpec& spec, const Eigen::Vector3d& p_world);

struct OcclusionConfig {
  double elevation_resolution_rad = 0.1 * M_PI / 180.0;  // interval size along the aperture
  double voxel_size = 0.01;    // m: the final map keeps one point per voxel (sec. 4.4.5)
  double min_intensity = 0.0;  // keep candidates whose bound (intensity) is > this
  // A candidate shadows the directions within footprint_radius · voxel_size of its centre (its
  // angular footprint, seen from the sonar): map points are voxel samples, so a point alone
  // would leave gaps between neighbouring front voxels through which the back shows.
  double footprint_radius = 0.5;
  // A candidate is observed when no other candidate in a return pixel lies more than this many
  // range bins nearer along the same (beam, elevation interval); 0 = the pixel-exact rule.
  int range_tolerance_bins = 0;
  // Beyond the thesis: a candidate lying in an empty pixel of a frame, with no candidate of that
  // frame's return pixels nearer along its own (beam, elevation interval), was seen as free space
  // there and is dropped. The conservative rule of Fig. 4.5 never carves a voxel behind the first
  // return of its beam, even when that return came from another elevation; this test uses the
  // map to tell such a voxel from a real shadow. Costs a projection of every candidate in every
  // frame's footprint. false = the thesis' rule. Carving turns it on (CarveConfig): the riser at
  // 30° goes from 68 % outliers to 2 %; deconvolution keeps it off: there it costs coverage
  // (30°: 40 → 24 %) for a lower median (docs/carving.md, docs/deconvolution.md).
  bool refute_free = false;
  // Beyond the thesis (issue 15): after the occlusion test, drop the points no return needs
  // (explain_returns() below). A return fixes range and bearing but not elevation, so a point
  // inside an open structure that lies, in every frame, on the elevation arc of a member's return
  // is never carved nor refuted; it is a ghost when every return it lies in is explained by a
  // point of another surface that some frame pins down. false = keep them (the thesis).
  bool explain_returns = false;
  // The explanation's pin rule (explain_returns() below): a point is pinned when its surface is
  // alone in its pixel in at least this fraction of the frames that put it in a return pixel;
  // pinned points explain others and are never refuted again. Higher = fewer points pinned: fewer
  // ghosts kept (an elevation smear continuing a true face is alone with it in its pixel), less
  // true surface too. In (0, 1]; measured in docs/carving.md, "Interior ghosts".
  double explain_pin_fraction = 0.2;
  int num_threads = 0;    // 0 = all cores
  void validate() const;  // throws Error naming the field
};

// The one declaration of OcclusionConfig's fields (core/params.hpp). As part of carving
// (Nested<OcclusionConfig>), the voxel size and thread count are carving's.
// `explain_flag` is the flag of explain_returns (nullptr: none).
template <class V>
void describe_occlusion_own(OcclusionConfig& c, V& v, const char* explain_flag) {
  using params::param;
  v.field(c.elevation_resolution_rad,
          param("elevation_resolution_rad", "rad", "interval size along the vertical aperture")
              .positive()
              .equation("sec. 4.4.5"));
  v.field(c.min_intensity,
          param("min_intensity", "", "keep candidates whose bound (intensity) is > this")
              .range(-1e30, 1e30));
  v.field(c.footprint_radius, param("footprint_radius", "voxels",
                                    "angular footprint of a candidate that shadows others")
                                  .non_negative()
                                  .flag("--footprint-radius"));
  v.field(c.range_tolerance_bins,
          param("range_tolerance_bins", "bins",
                "a candidate is shadowed only by one more than this many range bins nearer")
              .non_negative()
              .flag("--range-tolerance"));
  v.field(c.refute_free,
          param("refute_free", "",
                "beyond the thesis: drop candidates a frame saw in an empty pixel with nothing "
                "mapped nearer on their own line of sight (free space, not shadow)")
              .flag("--no-refute-free"));
  v.field(c.explain_returns,
          param("explain_returns", "",
                "beyond the thesis: drop the points whose every return another surface explains "
                "(interior ghosts of open structures, docs/carving.md)")
              .flag(explain_flag));
  v.field(c.explain_pin_fraction,
          param("explain_pin_fraction", "",
                "with explain_returns: a point alone in its pixel in at least this fraction of "
                "its return frames is pinned (kept, explains others)")
              .range_open_low(0, 1)
              .flag("--explain-pin-fraction"));
}
template <class V>
void describe(OcclusionConfig& c, V& v) {
  using params::param;
  v.field(c.voxel_size,
          param("voxel_size", "m", "the final map keeps one point per voxel").positive());
  // A whole OcclusionConfig is deconvolution's (DeconvConfig::occlusion): its explanation is set
  // in YAML or Python only; the flag is carving's.
  describe_occlusion_own(c, v, nullptr);
  v.field(c.num_threads, param("num_threads", "", "worker threads (0 = all cores)").non_negative());
}
template <class V>
void describe(params::Nested<OcclusionConfig>& n, V& v) {
  // Carving's: the switch turns the default around — a reconstruction's carving explains by
  // default (ReconstructConfig, issue 29), a CarveConfig alone (map, survey) does not.
  describe_occlusion_own(n.c, v,
                         n.c.explain_returns ? "--no-explain-returns" : "--explain-returns");
}

// Occlusion resolution (sec. 4.4.5): for every frame, walks each beam from short to long range,
// labels map points (candidates, world frame, intensity = carved bound) as observed or shadowed
// by a nearer scatterer along the same elevation interval, and keeps the points observed in at
// least one frame, one per voxel with the lowest bound (carving rule). Only candidates lying in a
// pixel with a return take part in a frame. With config.explain_returns, drop_unexplained()
// follows. `progress`, when given, advances once per frame.
PointCloud resolve_occlusions(const PointCloud& candidates_world,
                              const std::vector<FrameReturns>& frames, const SonarSpec& spec,
                              const OcclusionConfig& config, Progress* progress = nullptr);

// Return explanation (beyond the thesis, issue 15). The occlusion rule (sec. 4.4.5) keeps every
// point that is the nearest in its elevation interval, whatever else lies in its pixel; inside an
// open structure a voxel can lie, in every frame, on the elevation arc of a member's return (a
// bound, never carved) or behind one (a possible shadow, never refuted) and stays as a ghost.
// Per frame and return pixel (range bin, beam), the points lying in it — up to 2 θ_3dB off the
// image plane, where the beam's main lobe still returns (eq. 2.8) — are split into surfaces
// along the pixel's elevation arc (runs without a gap longer than 3 voxels). A point is pinned
// when its surface is the only one in its pixel in at least config.explain_pin_fraction (0.2) of
// the frames that put it in a return pixel: nothing else can have returned there. A point that is
// not pinned is a ghost when every return pixel it lies in, in every frame, also holds a pinned
// point of another surface: each of its returns is explained without it. Ghosts are removed and the
// passes repeat (a removal can leave a surface alone and pin it) until nothing changes, at most 8
// passes. A return pixel that held points keeps one (a pinned one): no observed return is left
// unexplained. Returns per point 0 = ghost, 1 = kept, 2 = kept and pinned; config.voxel_size
// sets the gap, config.num_threads the threads. Points no frame puts in a return pixel are kept.
struct ExplainStats {
  std::size_t removed = 0;  // ghosts
  std::size_t pinned = 0;   // points alone in some return pixel
  int iterations = 0;       // passes over the frames
};
std::vector<std::uint8_t> explain_returns(const PointCloud& points_world,
                                          const std::vector<FrameReturns>& frames,
                                          const SonarSpec& spec, const OcclusionConfig& config,
                                          ExplainStats* stats = nullptr);
// Rounds of explain_returns() and, with config.refute_free, occlusion resolution again over what
// is left (the ghosts gone, the free space they hid refutes others; pinned points stay; each point
// left shields its whole voxel from that free-space test, since the members' interiors went in
// the first resolution), until a round removes nothing (at most 4). Returns the points kept with
// their intensities, colours and properties; `removed` receives how many were dropped.
PointCloud drop_unexplained(const PointCloud& points_world, const std::vector<FrameReturns>& frames,
                            const SonarSpec& spec, const OcclusionConfig& config,
                            std::size_t* removed = nullptr);

namespace detail {
// The references the fast paths must equal (tests): resolve_occlusions() without the explanation
// (with `solid_refute`, each point shielding its whole voxel from the free-space test, as the
// explanation's rounds run it) and drop_unexplained(), both without the shortcuts that skip work
// which cannot change the result (blocks of no return pixel, candidates already refuted: issue 29,
// docs/performance.md "Ghost removal").
PointCloud resolve_occlusions_reference(const PointCloud& candidates_world,
                                        const std::vector<FrameReturns>& frames,
                                        const SonarSpec& spec, const OcclusionConfig& config,
                                        bool solid_refute = false);
PointCloud drop_unexplained_reference(const PointCloud& points_world,
                                      const std::vector<FrameReturns>& frames,
                                      const SonarSpec& spec, const OcclusionConfig& config,
                                      std::size_t* removed = nullptr);
}  // namespace detail

}  // namespace sonar3d
