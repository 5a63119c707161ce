#pragma once
// CAD-model recognition in a reconstructed field and 6D registration (thesis sec. 6.3.2): the
// 2D elevation-map method. Per model, in decreasing size (sec. 6.3.2.6): scan the field's
// elevation map for the patch whose ring descriptor is nearest the model's (sec. 6.3.2.3–
// 6.3.2.4), register the model there by an exhaustive 4D search over (East, North, height, yaw)
// (eq. 6.9), refine the full 6D pose by trimmed ICP (sec. 6.3.2.5), accept or reject the
// placement on its residual and support, and remove the placed model's area before the next
// search.
//
// Frames: local ENU world (x East, y North, z up); the thesis' (North, East, Depth) are
// (y, x, −z). Placements are T_world_model.
#include <Eigen/Geometry>
#include <limits>
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/recog/descriptor.hpp"
#include "sonar3d/recog/icp.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recog/scale.hpp"
#include "sonar3d/recog/verify.hpp"

namespace sonar3d {

struct Search4dConfig {
  double yaw_step_deg = 5;  // the thesis' 5° steps
  // Half-width of the searched shifts around the patch centre, m; 0: √2/2·T_NE + 2 cells (the
  // farthest the structure's centre can be from the nearest patch centre, eq. 6.8, plus slack)
  // + search_radius_fraction · r_model. Beyond the thesis: the winning patch is sometimes
  // centred on a part of the structure (a riser's buoyancy, 0.8 m from its centre), which the
  // thesis' window cannot reach.
  double search_m = 0;
  double search_radius_fraction = 0.5;
  // Second pass at this finer cell size around the winner (yaw ± one step, every
  // refine_yaw_step_deg; shifts ± 1.5 coarse cells, sub-cell); 0: none.
  double refine_cell_m = 0.02;
  double refine_yaw_step_deg = 1;
  // The model's top view compared: its footprint and a ring this many cells wide of its base
  // height around it (a flat top must not match any flat seabed).
  int background_ring_cells = 1;
  // Beyond the thesis: eq. 6.1's height ζ from the model's structure (its cells standing more
  // than seabed_slack_m above its base) and held by the seabed it stands on. Per shift, the
  // seabed's height is the median of the scene over a ring this wide around the compared cells,
  // and ζ may put the model's base at most seabed_slack_m above it and at most
  // max_buried_fraction of its height (+ slack) below it. 0: the thesis' median over every cell
  // (which aligns an open frame's or a block's top with the seabed and sinks it its own height).
  double seabed_ring_m = 0.4;
  double seabed_slack_m = 0.1;
  // With seabed_ring_m > 0, the shifts and yaws are scored by the mean height difference
  // truncated at this (a robust M-estimate) instead of eq. 6.2's median, m.
  double truncate_m = 0.1;
  // With seabed_ring_m > 0: a model whose structure (standing seabed_slack_m above its base)
  // covers fewer of the scene's cells than this is searched on the fine map (refine_cell_m)
  // over the whole window: a 13 cm buoy has no shape on 8 cm cells.
  int min_coarse_cells = 16;
  // With seabed_ring_m > 0, the shifts coarse to fine: every shift_stride-th cell shift of the
  // window first, then every shift about the shift_seeds best of them and a descent to the best
  // neighbour; shift_stride 1: every cell shift (exhaustive). Measured on the benchmark's seven
  // fields: the same placements as the exhaustive search (docs/recognition.md, recog28e).
  int shift_stride = 2;
  int shift_seeds = 8;
  void validate() const;
};
template <class V>
void describe(Search4dConfig& c, V& v) {
  using params::param;
  v.field(c.yaw_step_deg,
          param("yaw_step_deg", "deg",
                "yaw step of the 4D search (with --method 3d, when given: of the yaw sweep)")
              .range_open_low(0, 180)
              .flag("--yaw-step-deg")
              .equation("eq. 6.9"));
  v.field(c.search_m, param("search_m", "m",
                            "half-width of the searched shifts about the patch centre; 0: from "
                            "T_NE and the model's radius")
                          .non_negative());
  v.field(c.search_radius_fraction,
          param("search_radius_fraction", "", "the automatic half-width adds this × r_model")
              .range(0, 2));
  v.field(c.refine_cell_m,
          param("refine_cell_m", "m", "second pass at this finer cell about the winner; 0: none")
              .non_negative());
  v.field(c.refine_yaw_step_deg,
          param("refine_yaw_step_deg", "deg", "yaw step of the second pass").positive());
  v.field(c.background_ring_cells,
          param("background_ring_cells", "",
                "cells of the model's base height compared around its footprint")
              .range(0, 100));
  v.field(c.seabed_ring_m,
          param("seabed_ring_m", "m",
                "ring around the model's top view whose median height is the seabed bounding "
                "eq. 6.1's height (0: unbounded, the thesis)")
              .range(0, 10)
              .equation("eq. 6.1"));
  v.field(c.seabed_slack_m,
          param("seabed_slack_m", "m",
                "the bounded height may float this far above the seabed and sink this much "
                "more than max_buried_fraction")
              .range(0, 10));
  v.field(c.truncate_m, param("truncate_m", "m",
                              "with seabed_ring_m > 0: shifts scored by the mean height "
                              "difference truncated at this, not eq. 6.2's median")
                            .range_open_low(0, 10)
                            .equation("eq. 6.2"));
  v.field(c.min_coarse_cells,
          param("min_coarse_cells", "",
                "with seabed_ring_m > 0: models covering fewer scan cells are searched on the fine "
                "map")
              .range(0, 1000000));
  v.field(c.shift_stride,
          param("shift_stride", "",
                "with seabed_ring_m > 0: cell shifts scored first on this lattice, then about its "
                "best (1: every shift)")
              .range(1, 16)
              .equation("eq. 6.9"));
  v.field(
      c.shift_seeds,
      param("shift_seeds", "", "best lattice shifts refined at every cell shift").range(1, 1000));
}

struct Search4dResult {
  bool found = false;
  double yaw_rad = 0;
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  double rms_m = 0;  // eq. 6.9 at the winner, divided by √(cells): the RMS height difference
  std::size_t overlap_cells = 0;
  int yaws_tried = 0;
  double seconds = 0;
};

// Eq. 6.9: for each yaw θ in the symmetry's range, the model's top view is registered onto the
// scene map around `center_xy` by the swath registration's exhaustive shift search
// (register_elevation_maps: every cell shift, ζ by the signed median of eq. 6.1); the yaw whose
// best shift leaves the lowest ||Z_model − Z_map + ζ||_2 (per cell) wins. `removed`: scene cells
// to ignore (same size as `scene`, or empty). `fine` (may be empty): the scene at
// refine_cell_m for the second pass. `max_buried_fraction`: how deep below the seabed the height
// may put the model's base, as a fraction of its height (Search4dConfig::seabed_ring_m).
Search4dResult search_4d(const ModelTemplate& model, const ElevationMap& scene,
                         const ElevationMap& fine, const Eigen::Vector2d& center_xy,
                         double period_m, const Search4dConfig& config,
                         double max_buried_fraction = 0.5);

// What a placement leaves between the scene and the placed mesh (Table 6.1): distances from the
// scene points that lie over the model (inside its oriented bounding box grown by `margin_m`
// horizontally, from `above_base_m` over its base to margin_m over its top) to the mesh. The
// recognition passes only points above the local seabed (RecognitionConfig::ground_clearance_m).
struct Residual {
  std::size_t points = 0;
  double median_m = 0, mean_m = 0;
};
Residual structure_residual(const std::vector<Eigen::Vector3f>& scene_world,
                            const ModelTemplate& model, const Eigen::Isometry3d& T_world_model,
                            double margin_m = 0.05, double above_base_m = 0.05);

struct RecognitionConfig {
  double map_cell_m = 0.02;    // the field's elevation map (registration, support), m
  double recog_cell_m = 0.08;  // Δ_NE of the descriptor scan and the 4D search (the thesis' 8 cm)
  DescriptorConfig descriptor;
  ScanConfig scan;
  Search4dConfig search;
  TrimmedIcpConfig icp;
  ModelSamplingConfig sampling;
  bool run_icp = true;
  // Acceptance of a placement ("found"):
  // Descriptor score (norm of the ring EMDs) at most this times the model's height: the EMDs
  // scale with the heights moved. A loose filter: occlusion shadows beside tall structures raise
  // the true patch's score (a 2.5 m pillar surveyed from 4 m scored 0.71 × its height), so the
  // decision rests on the registration (residual, support).
  double max_relative_score = 1.0;
  // Structure residual median at most this, m: a sanity bound only. Carved thin parts (tubes,
  // buoyancies) leave 5-7 cm at the true pose, while a model pressed into flat seabed leaves under
  // 1 cm: the residual does not tell right from wrong, the support does (docs/recognition.md).
  double max_residual_median_m = 0.1;
  // Hypothesis verification and the calibrated confidence that decides "found" (verify.hpp,
  // docs/recognition.md "Verification"): replaces the thesis' residual threshold.
  VerificationConfig verification;
  // The size search of models with a scale_range (recog/scale.hpp, docs/recognition.md "Scale");
  // its max_tilt_deg and max_icp_shift_m are taken from this config's.
  ScaleSearchConfig scale;
  // A candidate whose footprint lies more than this fraction on cells of accepted placements
  // is rejected: no region carries two placements.
  double max_overlap = 0.25;
  // Competing models whose explanation scores lie within this fraction of each other are ranked
  // by their residual median (the finer fit) instead.
  double compete_margin = 0.1;
  // At most this fraction of the model's height may lie below the local seabed (half-buried
  // structures are found; a sphere sunk to a cap looks like any rock).
  double max_buried_fraction = 0.5;
  // Trimmed ICP corrects small pitch and roll offsets (sec. 6.3.2.5): a result tilting the model
  // more than this from upright, or moving it farther than max_icp_shift_m from the 4D placement,
  // has slid onto something else (a tank laid along a pipeline); the 4D placement is kept.
  double max_tilt_deg = 10;
  double max_icp_shift_m = 0.2;
  // Beyond the thesis (eq. 6.9 searches yaw and shift of an upright model): when the seabed
  // plane fitted under the 4D search's placement (the verification's) drops more than the
  // verification's tol_m across the model's radius, and slopes less than max_tilt_deg, the scene
  // is levelled by that plane, searched again, and the placement tilted back onto the plane; the
  // verification keeps whichever pose explains the scene better, ICP starts from it (a 2.6 m
  // manifold on a 5° slope: 23 cm from end to end, placed 0.8 m off upright).
  bool level_by_seabed = true;
  int max_instances = 20;  // per model whose count is not given
  int max_rejections = 3;  // rejected scan candidates per model before giving up
  // Relief proposals (beyond the thesis' scan of sec. 6.3.2.4): the descriptor ranks a partly
  // buried structure, or a small tool among rocks, below look-alike patches, so the scan gives up
  // before reaching it. Once a model's scan has given up, every blob of relief standing
  // the model's relief threshold (model_relief_m: verification.relief_m, less for a low model)
  // above the local seabed (a grey-scale opening of the recognition map
  // over relief_window_m) whose size fits the model (its height at least half of what
  // max_buried_fraction leaves standing and at most 1.5 × the model's plus 0.1 m, its area
  // 0.25–3 × the model's footprint) is proposed to it, best-fitting first, at most
  // max_relief_proposals of them; each is registered and verified like a scan candidate. Models
  // whose footprint holds a square of the window, or that stand lower than their relief
  // threshold (they cannot raise a blob), are left to the scan (the opening cannot lift the former
  // off the seabed).
  double relief_window_m = 2.0;
  // A low model's relief threshold (issue 28, beyond the thesis): a model standing less than
  // verification.relief_m / low_relief_fraction above its base is judged on its cells standing
  // low_relief_fraction of its height above the seabed, in its relief proposals (the blobs it is
  // offered and its footprint) and in its verification (VerificationConfig::relief_m for this
  // model), bounded below by min_relief_m and by the map's noise (3 robust σ of the fine map's
  // neighbouring height differences). A 11 cm hot stab lying on the seabed has no cell 10 cm
  // above it: it was never proposed nor judged. 0: every model uses verification.relief_m.
  double low_relief_fraction = 0.5;
  double min_relief_m = 0.04;
  // Per model; 0: none. On by default since the verification's relief evidence
  // (VerificationConfig::min_evidence) refuses the false hot stab on rock that they placed in
  // the benchmark's ordnance field: 4 per model find the buried cinder block and the upright
  // sonobuoy of mixed_buried that the scan never proposes (docs/recognition.md).
  int max_relief_proposals = 4;
  // Blobs too large for the model (area above 3 × its footprint: a partly buried shell whose
  // relief merged with the pipeline beside it) are split by the model's footprint: their centres
  // where a footprint-sized matched filter peaks (recognition.cpp, split_blob_centres) are
  // proposed after the blobs that fit, at most max_relief_proposals of them. Off by default, by
  // measurement (recog28f): on the benchmark the split reached the buried mk46 of `ordnance` but
  // its 4D search slid the shell 0.5 m along its axis (not found), and on `drift` a `drum`
  // distractor was placed on a pipeline from a split peak (confidence 0.58): precision 17/18.
  bool split_relief_blobs = false;
  double removal_margin_m = 0.1;  // area removed around a placed model's footprint
  // Scene points used by ICP and the residuals: those higher than the local seabed (median
  // scene height around the footprint) plus this, m.
  double ground_clearance_m = 0.05;
  int num_threads = 0;  // 0 = all cores
  void validate() const;
};
// The 2D method's fields (the `two_d:` block of `recognize --print-config`, Python's
// RecognitionConfig).
template <class V>
void describe(RecognitionConfig& c, V& v) {
  using params::param;
  v.field(c.map_cell_m, param("map_cell_m", "m", "fine elevation map cell (registration, support)")
                            .positive()
                            .flag("--map-cell"));
  v.field(c.recog_cell_m, param("recog_cell_m", "m",
                                "scan cell Δ_NE of the descriptors and the 4D search (the "
                                "thesis' 8 cm)")
                              .positive()
                              .flag("--recog-cell")
                              .equation("sec. 6.3.2.2"));
  v.group("descriptor", c.descriptor);
  v.group("scan", c.scan);
  v.group("search", c.search);
  v.group("icp", c.icp);
  v.group("sampling", c.sampling);
  v.field(c.run_icp, param("run_icp", "", "refine by trimmed ICP after the 4D search")
                         .flag("--no-icp")
                         .equation("Table 6.1"));
  v.field(c.max_relative_score,
          param("max_relative_score", "",
                "accept patches scoring at most this times the model's height")
              .positive()
              .flag("--max-relative-score"));
  v.field(c.max_residual_median_m,
          param("max_residual_median_m", "m",
                "accept placements whose residual median is at most this (with --method 3d, "
                "when given: its threshold)")
              .positive()
              .flag("--max-residual"));
  v.group("verification", c.verification);
  v.group("scale", c.scale);
  v.field(c.max_overlap, param("max_overlap", "",
                               "a candidate lying more than this fraction on accepted "
                               "placements is rejected")
                             .range(0, 1));
  v.field(c.compete_margin,
          param("compete_margin", "",
                "competing models within this fraction of each other's score are ranked by "
                "residual")
              .range(0, 1));
  v.field(c.max_buried_fraction, param("max_buried_fraction", "",
                                       "at most this fraction of the model's height below "
                                       "the local seabed")
                                     .range(0, 1));
  v.field(c.max_tilt_deg,
          param("max_tilt_deg", "deg", "an ICP result tilting the model more is refused")
              .range(0, 180));
  v.field(c.max_icp_shift_m,
          param("max_icp_shift_m", "m", "an ICP result moving the model farther is refused")
              .non_negative());
  v.field(c.level_by_seabed,
          param("level_by_seabed", "",
                "search again on the scene levelled by the seabed plane under the placement and "
                "tilt the model onto it, when the plane drops more than verification.tol_m "
                "across the model")
              .flag("--no-level")
              .equation("eq. 6.9"));
  v.field(c.max_instances,
          param("max_instances", "", "instances per model whose count the catalogue does not give")
              .range(1, 1000));
  v.field(c.max_rejections,
          param("max_rejections", "", "rejected scan candidates per model before its scan gives up")
              .range(1, 100)
              .flag("--max-rejections"));
  v.field(c.relief_window_m, param("relief_window_m", "m", "seabed window of the relief proposals")
                                 .range_open_low(0, 50)
                                 .flag("--relief-window"));
  v.field(c.low_relief_fraction,
          param("low_relief_fraction", "",
                "a model lower than verification.relief_m / this is proposed and verified on its "
                "cells this fraction of its height above the seabed (0: never)")
              .range(0, 1));
  v.field(c.min_relief_m,
          param("min_relief_m", "m",
                "a low model's relief threshold is at least this (and the map's noise)")
              .non_negative());
  v.field(c.max_relief_proposals,
          param("max_relief_proposals", "",
                "then at most this many blobs of relief that fit the model are tried per model "
                "(0: none)")
              .range(0, 1000)
              .flag("--max-relief-proposals"));
  v.field(c.split_relief_blobs,
          param("split_relief_blobs", "",
                "blobs larger than 3 x the model's footprint are split: the peaks of a "
                "footprint-sized matched filter in them are proposed too")
              .flag("--split-blobs"));
  v.field(c.removal_margin_m,
          param("removal_margin_m", "m", "area removed around a placed model's footprint")
              .non_negative());
  v.field(c.ground_clearance_m,
          param("ground_clearance_m", "m",
                "ICP and residuals use scene points higher than the local seabed plus this")
              .non_negative());
  v.field(c.num_threads, param("num_threads", "", "worker threads (0 = all cores; both methods)")
                             .range(0, 4096)
                             .flag("--threads"));
}

struct Placement {
  std::string model;
  std::string method = "2d";
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  // The model's size (thesis sec. 6.7): the placed model is T_world_model · S(scale) · model, S a
  // uniform scale about the model frame's origin (recog/scale.hpp). 1 unless the catalogue gives
  // the model a scale_range.
  double scale = 1;
  double score_m = 0;  // descriptor score of the winning patch
  Residual residual;   // after the last step
  // The verification's terms (verify.hpp, both methods) and the calibrated confidence in [0, 1]
  // that decided "found" (at or above the config's verification.min_confidence).
  Verification verification;
  double confidence = 0;
  // Sets verification and the fields read from it (confidence, support = explained,
  // observed = seen, ground_z).
  void set_verification(const Verification& v) {
    verification = v;
    ground_z = v.ground_z;
    confidence = v.confidence;
    support = v.explained;
    observed = v.seen;
  }
  // The same placement turned 180° about the model's vertical axis (models without a symmetry):
  // its confidence, and whether the top view cannot tell the two apart (its explanation score
  // within compete_margin of this one's and its confidence above the threshold; a panel's top
  // view is often the same both ways). NaN / false when not checked.
  double turned_confidence = std::numeric_limits<double>::quiet_NaN();
  bool yaw_ambiguous = false;
  double support = 0;   // verification.explained
  double observed = 0;  // verification.seen (height-weighted fraction of the relief observed)
  double ground_z = 0;  // local seabed height around the footprint (world z), m
  // Step 1 (4D search) alone, for Table 6.1.
  Eigen::Isometry3d T_world_model_4d = Eigen::Isometry3d::Identity();
  Residual residual_4d;
  double rms_4d_m = 0;
  int icp_iterations = 0;
  bool icp_kept = false;  // whether the ICP result was kept (see max_tilt_deg)
  double seconds_scan = 0, seconds_registration = 0, seconds = 0;
  double seconds_scale = 0;  // the scale search (part of seconds_registration)
};

// Every search, accepted or not, for the log and the measurements.
struct SearchRecord {
  std::string model;
  bool accepted = false;
  std::string reason;  // why rejected (empty when accepted)
  // Where the candidate came from: the descriptor scan ("scan") or a blob of relief ("relief",
  // RecognitionConfig::max_relief_proposals; scan.center_xy is then the blob's centre).
  std::string proposal = "scan";
  ScanResult scan;
  Placement placement;  // filled when the search went as far as registration
};

struct RecognitionResult {
  std::vector<Placement> placements;
  std::vector<SearchRecord> searches;
  int map_rows = 0, map_cols = 0;  // the recognition map
  std::size_t scene_points = 0;
  double seconds_maps = 0, seconds = 0;
};

// A model's relief threshold (RecognitionConfig::low_relief_fraction): verification.relief_m,
// or for a model lower than relief_m / low_relief_fraction, low_relief_fraction of its height,
// at least min_relief_m and 3 × `noise_m` (map_height_noise).
double model_relief_m(const ModelTemplate& model, const RecognitionConfig& config, double noise_m);

// The map's height noise: 1.4826 × the median absolute difference of horizontally neighbouring
// cells' heights / √2 (a robust σ of one cell's height), m; 0 without two neighbouring cells.
double map_height_noise(const ElevationMap& map);

// The whole 2D method on a world-frame cloud. Models larger than the map are an Error naming
// them; an empty catalogue or cloud is an Error.
RecognitionResult recognize_2d(const PointCloud& scene_world,
                               const std::vector<ModelTemplate>& models,
                               const RecognitionConfig& config, bool progress = false);

// The placed models as one mesh (world frame), each at its placement's scale.
TriangleMesh placed_models_mesh(const std::vector<ModelTemplate>& models,
                                const std::vector<Placement>& placements);

// Placements as JSON (docs/recognition.md): per placement the model, T_world_model (4×4,
// row-major), scale, translation, roll/pitch/yaw in degrees, score, residual median and mean,
// support, step-1 values, method and times.
std::string placements_json(const RecognitionResult& result, const std::string& map_source,
                            const std::string& catalogue_source, const RecognitionConfig& config);

}  // namespace sonar3d
