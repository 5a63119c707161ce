#pragma once
// Semantic world models (thesis sec. 6.3.3, Fig. 6.18): a field's point cloud turned into the
// registered CAD models, a seabed surface at several levels of detail, and a graph of the
// objects and their connections — the thesis' 600 MB cloud became a 5 MB model.
//
// Frames: local ENU world (x East, y North, z up); the thesis' (North, East, Depth) are
// (y, x, −z). Placements are T_world_model. docs/world.md describes the method and its
// measurements, docs/formats.md the output directory.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

// One placement read from `sonar3d recognize`'s placements JSON (docs/recognition.md).
struct PlacementRecord {
  std::string model;
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  // The placed model is T_world_model · S(scale) · model, S uniform about the model frame's
  // origin (recognize's size search, docs/formats.md); 1 when the file does not say.
  double scale = 1;
  double score_m = 0;
  double residual_median_m = std::numeric_limits<double>::quiet_NaN();  // null in the file: NaN
  double residual_mean_m = std::numeric_limits<double>::quiet_NaN();    // null or absent: NaN
  std::string method{};  // "2d" or "3d" as recognize wrote it; empty when absent
  // How sure recognition is that the model lies there, in [0, 1] (docs/recognition.md); NaN when
  // the file does not say (files written before recognize recorded it).
  double confidence = std::numeric_limits<double>::quiet_NaN();
};

struct PlacementsFile {
  std::string path;
  std::string map, catalogue;  // the sources recorded by recognize (may be empty)
  std::vector<PlacementRecord> placements;
  // settings.min_confidence: the threshold that decided "found", in [0, 1]; NaN when absent.
  double min_confidence = std::numeric_limits<double>::quiet_NaN();
};

// Placement records allowed in one file (a count read from a file decides allocations).
constexpr std::size_t kMaxPlacements = 10'000;

// Reads a placements JSON ("format": "sonar3d-placements", version 1). Errors name the file and
// the placement index and key at fault: not JSON, another format or version, a missing or
// non-string model, a T_world_model that is not 4×4 finite numbers with a rotation block
// (orthonormal, determinant +1, within 1e-3) and a last row of 0 0 0 1, a `confidence` (per
// placement) or `settings.min_confidence` that is not a finite number in [0, 1]. Both are
// optional: a file without them is read with the confidence unknown (NaN).
PlacementsFile read_placements(const std::string& path);
// The same on a file's text (`source` names it in errors). Nesting deeper than
// limits::kMaxNestingDepth is refused.
PlacementsFile parse_placements(const std::string& text, const std::string& source);

// A placed CAD model of the world model.
struct WorldObject {
  std::string id;     // "<model>_<n>", n counting from 0 per model in placement order
  std::string model;  // catalogue name
  std::string kind = "structure";
  Eigen::Isometry3d T_world_model = Eigen::Isometry3d::Identity();
  double scale = 1;  // the placement's size (mesh_model is already scaled)
  double score_m = 0;
  double residual_median_m = std::numeric_limits<double>::quiet_NaN();
  double confidence = std::numeric_limits<double>::quiet_NaN();  // NaN: unknown (older files)
  // At or above the world's confidence threshold (or of unknown confidence with no threshold
  // asked). An unconfirmed object is kept in the world model and listed, but explains no point
  // (its points stay in the seabed), fills no footprint and is never joined by a connection.
  bool confirmed = true;
  // The catalogue mesh, model frame; shared by the objects of one model (a placements file of
  // thousands of records must not copy a mesh each).
  std::shared_ptr<const TriangleMesh> mesh_model;
};

struct SeabedConfig {
  // Levels of detail: height-field cell sizes, m, finest first; each an integer multiple (≥ 2×)
  // of the previous one. The finest is mapped from the points, each coarser one from the finest
  // by the median of its valid cells.
  std::vector<double> lod_cells_m{0.05, 0.2, 1.0};
  // A point is explained by a placed model (and left out of the seabed) when it lies inside the
  // model's bounding box (model frame) grown by this margin on every side, m.
  double margin_m = 0.1;
  // A coarse cell gets a height when at least this fraction of its fine cells hold one.
  double min_valid_fraction = 0.25;
  // No-data cells under a placed model's grown footprint are filled from their neighbours
  // (the seabed goes on under a structure); other no-data cells stay holes.
  bool fill_footprints = true;
  // Refuses height fields with more cells than this (ElevationMapConfig::max_cells).
  std::size_t max_cells = 100'000'000;
  void validate() const;  // throws Error naming the parameter
};

// Pipelines found in the map between two placed structures: the seabed along the straight line
// joining their footprint centres carries a ridge (a half-buried pipe) over most of its length.
struct ConnectionConfig {
  double station_m = 0.25;    // spacing of the cross-sections along the line, m
  double corridor_m = 0.5;    // half-width searched for the ridge's crest around the line, m
  double band_m = 1.5;        // half-width of each cross-section; beyond corridor_m: the ground
  double min_ridge_m = 0.08;  // crest at least this far above the ground's median, m
  double min_fraction = 0.6;  // of the cross-sections with data, the fraction showing a ridge
  double max_length_m = 100;  // pairs of structures farther apart are not tested, m
  void validate() const;
};

struct WorldModelConfig {
  SeabedConfig seabed;
  ConnectionConfig connections;
  bool find_connections = true;
  // Placements below this confidence are kept as unconfirmed objects (confirm_objects): never
  // connected, explaining no point. In [0, 1]; 0 confirms every placement, even of unknown
  // confidence. Unset: the placements file's own threshold (world_confidence_threshold, which
  // `sonar3d world` and the survey apply), else 0.
  std::optional<double> min_confidence;
  void validate() const;
};

// The one declaration of the world model's settings (sonar3d world's flags and --print-config
// keys, the survey's world stage, Python's WorldModelConfig; docs/reference.md).
template <class V>
void describe(SeabedConfig& c, V& v) {
  using params::param;
  v.field(c.lod_cells_m, param("lod_cells_m", "m",
                               "seabed height-field cell per level of detail, finest first; each "
                               "an integer multiple (at least 2x) of the previous, at most 8")
                             .positive()
                             .flag("--lod-cells"));
  v.field(c.margin_m, param("margin_m", "m",
                            "points within a placed model's bounding box grown by this are the "
                            "model's, not the seabed's")
                          .non_negative()
                          .flag("--margin"));
  v.field(c.min_valid_fraction,
          param("min_valid_fraction", "",
                "a coarse cell needs at least this fraction of its finest cells observed")
              .range_open_low(0, 1)
              .flag("--min-valid-fraction"));
  v.field(c.fill_footprints, param("fill_footprints", "",
                                   "fill the no-data cells under a placed model's footprint from "
                                   "around (the seabed goes on under a structure); off: holes")
                                 .flag("--no-fill"));
  v.field(
      c.max_cells,
      param("max_cells", "", "height fields with more cells than this are refused").at_least(1));
}
template <class V>
void describe(ConnectionConfig& c, V& v) {
  using params::param;
  v.field(c.station_m,
          param("station_m", "m", "spacing of the cross-sections along the line").positive());
  v.field(c.corridor_m,
          param("corridor_m", "m", "half-width searched for the ridge's crest around the line")
              .positive());
  v.field(c.band_m, param("band_m", "m",
                          "half-width of each cross-section; beyond corridor_m lies the ground")
                        .positive());
  v.field(c.min_ridge_m,
          param("min_ridge_m", "m", "a ridge's crest at least this far above the ground's median")
              .positive()
              .flag("--min-ridge"));
  v.field(c.min_fraction, param("min_fraction", "",
                                "of the cross-sections with data, the fraction showing a ridge "
                                "for a pipeline")
                              .range_open_low(0, 1)
                              .flag("--ridge-fraction"));
  v.field(
      c.max_length_m,
      param("max_length_m", "m", "pairs of structures farther apart are not tested").positive());
}
template <class V>
void describe(WorldModelConfig& c, V& v) {
  using params::param;
  v.group("seabed", c.seabed);
  v.field(c.find_connections,
          param("find_connections", "", "search for pipelines between placed structures")
              .flag("--no-connections"));
  v.group("pipeline_search", c.connections);
  v.field(c.min_confidence,
          param("min_confidence", "",
                "placements below this confidence are kept as unconfirmed objects: listed, "
                "never connected, their points left in the seabed (none: the placements file's "
                "settings.min_confidence, else 0)")
              .range(0, 1)
              .flag("--min-confidence"));
}

// The confidence threshold the world applies: `asked` when given (finite, in [0, 1], else an
// Error naming `param`), else the file's settings.min_confidence, else 0 (WorldModelConfig::
// min_confidence unset). A threshold above 0
// with a placement of unknown confidence is an Error naming the file and the placement: the
// threshold cannot be checked on it (write the placements again with sonar3d recognize).
double world_confidence_threshold(const PlacementsFile& placements, std::optional<double> asked,
                                  const std::string& param = "--min-confidence");

// Marks each object confirmed when its confidence is at or above `min_confidence` (thesis
// sec. 6.3.3's world model is built from the placements recognition found; a placement below
// the threshold is not one of them). An object of unknown confidence is confirmed only when the
// threshold is 0. Returns the number unconfirmed. build_world_model calls it with
// WorldModelConfig::min_confidence.
std::size_t confirm_objects(std::vector<WorldObject>& objects, double min_confidence);

struct SeabedLod {
  int lod = 0;
  double cell_m = 0;
  ElevationMap heights;  // the height field meshed (world z per cell)
  TriangleMesh mesh;     // world frame: a vertex per valid cell centre
  // Video colours (thesis sec. 6.4) when the map's cloud carries them (`sonar3d texture`), one
  // per mesh vertex: the linear-RGB mean of the coloured seabed points in the vertex's cell, and
  // how many there were (0: no colour; cells filled under structures have none). Empty when the
  // cloud has no colours.
  std::vector<Eigen::Vector3f> color;
  std::vector<std::uint32_t> color_points;
  std::size_t coloured_vertices() const;
};

struct Connection {
  std::string from, to;  // object ids
  std::string kind = "pipeline";
  // Found: from the first to the last cross-section showing the ridge. Given only: the straight
  // horizontal distance between the two footprint centres.
  double length_m = 0;
  double fraction = std::numeric_limits<double>::quiet_NaN();  // of the cross-sections with data
                                                               // that show it; NaN: not found
  bool found = false;                                          // by find_connections in the map
  bool given = false;  // by the user (read_given_connections)
};

struct WorldModel {
  std::vector<WorldObject> objects;  // confirmed and unconfirmed (WorldObject::confirmed)
  double min_confidence = 0;         // the threshold objects were confirmed by
  std::vector<Connection> connections;
  std::vector<SeabedLod> seabed;
  std::size_t cloud_points = 0, seabed_points = 0;  // seabed: the points no model explains
  std::size_t filled_cells = 0;                     // finest LOD cells filled under footprints
  // Seabed points with a video colour: a cloud's point is coloured when its `views` property
  // (sonar3d texture: the frames that coloured it) is > 0, or, without that property, when its
  // colour is not black (texture writes black where no frame saw a point).
  std::size_t coloured_seabed_points = 0;
  double seconds = 0;
};

// The objects for `placements`, meshes from `catalogue_meshes` (name → model-frame mesh, same
// order as `catalogue_names`). A placement naming a model the catalogue does not list is an
// Error naming the placements file, the placement and the catalogue.
std::vector<WorldObject> world_objects(const PlacementsFile& placements,
                                       const std::vector<std::string>& catalogue_names,
                                       const std::vector<TriangleMesh>& catalogue_meshes,
                                       const std::string& catalogue_path);

// The same with the meshes of a catalogue (recog/catalogue.hpp), loaded for the models placed.
struct Catalogue;
std::vector<WorldObject> world_objects(const PlacementsFile& placements,
                                       const Catalogue& catalogue);

// Per point: 1 when a placed model explains it (SeabedConfig::margin_m).
std::vector<std::uint8_t> explained_points(const PointCloud& cloud_world,
                                           const std::vector<WorldObject>& objects,
                                           double margin_m);

// The height field as a triangle mesh: a vertex at each valid cell's centre (x, y, z), two
// triangles per 2×2 block of valid cells (split along the diagonal with the smaller height
// difference), one where exactly three are valid; no-data cells leave holes. Counter-clockwise
// seen from above (normals up).
TriangleMesh height_field_mesh(const ElevationMap& map);

// A coarser height field: blocks of factor × factor cells, each the median of its valid cells
// when at least min_valid_fraction of them are valid, else no data.
ElevationMap downsample_heights(const ElevationMap& fine, int factor, double min_valid_fraction);

// Fills no-data cells whose centres lie in the mask by repeated averaging of their valid
// 8-neighbours (from the edge of each hole inward). Returns the number of cells filled.
std::size_t fill_holes(ElevationMap& map, const std::vector<std::uint8_t>& fill_mask);

// Pipelines between pairs of confirmed structures (ConnectionConfig), found on `seabed` (the
// seabed with the structures removed and their footprints filled); unconfirmed objects are
// never an end.
std::vector<Connection> find_connections(const ElevationMap& seabed,
                                         const std::vector<WorldObject>& objects,
                                         const ConnectionConfig& config, double margin_m);

// A connection the user knows (from drawings, or an earlier survey), in a YAML file:
//   connections:
//     - {from: riser_0, to: tank_0, kind: pipeline}   # kind optional, default pipeline
// `from` and `to` are object ids as the world model names them ("<model>_<n>", graph.json).
struct GivenConnection {
  std::string from, to, kind = "pipeline";
  int line = 0;  // 1-based line in the file, for errors
};
constexpr std::size_t kMaxGivenConnections = 100'000;
// Errors (one line, naming the file and line): not YAML, no `connections` list, an entry that
// is not a map, unknown keys, `from`/`to` missing or empty, more than kMaxGivenConnections.
std::vector<GivenConnection> read_given_connections(const std::string& path);

// Adds the given connections to the world's. An id that names no object or an unconfirmed one
// (below the confidence threshold), a connection from an object to itself, or a pair given
// twice is an Error naming the file and line. A pair also found
// in the map keeps its measured length and fraction and is marked given too; a pair not found
// gets the straight horizontal distance between the footprint centres (SeabedConfig::margin_m
// boxes) as its length.
void add_given_connections(WorldModel& world, const std::vector<GivenConnection>& given,
                           const std::string& source, double margin_m);

// Takes the video colours (and `views`) of `coloured` — the same cloud coloured by `sonar3d
// texture`, read from `source` — into `cloud`. The two must hold the same points in the same
// order (texture without --drop-uncoloured keeps them); otherwise an Error naming `source`.
void take_video_colours(PointCloud& cloud, const PointCloud& coloured, const std::string& source);

// Memory build_world_model and write_world_model will take for this cloud (core/memory.hpp),
// before anything is allocated: each seabed level of detail's height field, mesh, colours and
// the writers' copies over the cloud's horizontal extent (parts name --lod-cells).
MemoryEstimate estimate_world_model_memory(const PointCloud& cloud_world,
                                           const WorldModelConfig& config);

// The whole world model from a world-frame cloud and its placed objects (confirmed ones explain
// points and are connected; unconfirmed ones are only carried along). An empty cloud, or a cloud
// that every placed model explains entirely, is an Error.
WorldModel build_world_model(const PointCloud& cloud_world, std::vector<WorldObject> objects,
                             const WorldModelConfig& config);

// Ground truth for the seabed's error, from a simulated dataset (truth/scene.yaml, objects of
// kind terrain) and, when the map directory's summary.json records it, the map's placement in
// the world (MapAlignment, docs/mapping.md), which no mapping can observe.
struct SeabedTruth {
  TriangleMesh terrain_world;
  bool has_alignment = false;
  Eigen::Matrix2d M = Eigen::Matrix2d::Identity();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double dz = 0;
  std::string dataset;
};
// `dataset`: a simulated dataset directory; empty: the one named by map_dir/summary.json, if
// any. Returns nullopt when there is no truth to use; errors (a dataset without terrain, an
// unreadable summary) name the file.
std::optional<SeabedTruth> find_seabed_truth(const std::filesystem::path& map_path,
                                             const std::filesystem::path& dataset);

struct SeabedError {
  double median_m = 0;            // with the map's placement taken out when known
  double median_as_mapped_m = 0;  // as the map lies in the world
  std::size_t samples = 0;
};
// Unsigned distances from uniform samples of `mesh` (about `samples`, seeded) to the truth
// terrain, median.
SeabedError seabed_error(const TriangleMesh& mesh, const SeabedTruth& truth,
                         std::size_t samples = 200'000, unsigned long long seed = 1);

struct WorldWriteInfo {
  std::string map, placements, catalogue;  // sources, recorded in graph.json
  std::uintmax_t cloud_bytes = 0;          // size of the point cloud file the model replaces
  std::vector<double> seabed_error_m;      // per LOD (NaN: not measured), or empty
  bool glb_all_lods = false;  // world.glb carries every LOD (default: the coarsest only)
};

struct WorldWriteResult {
  std::vector<std::uintmax_t> seabed_bytes;  // per LOD PLY
  std::uintmax_t glb_bytes = 0, models_bytes = 0, bytes_total = 0;
};

// Writes the world model directory (docs/formats.md, "World model directory"): world.glb,
// seabed_lod<k>.ply, models/<id>.ply, graph.json; atomically as a whole. `dir` must not exist
// or be an empty directory.
WorldWriteResult write_world_model(const std::filesystem::path& dir, const WorldModel& world,
                                   const WorldWriteInfo& info);

}  // namespace sonar3d
