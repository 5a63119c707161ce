#pragma once
// A catalogue of CAD models to look for in a map (thesis sec. 6.3): a YAML file listing, per
// model, its mesh (a file Assimp reads, or one of sonar3d's procedural reference objects), its
// name, the symmetry that sets the yaw range searched (sec. 6.3.2.5) and optionally how many to
// expect. Format (docs/recognition.md):
//
//   models:
//     - name: riser
//       mesh: meshes/riser.dae     # relative to the catalogue file; or `reference: riser`
//       symmetry: none             # none (yaw in [0°, 360°)), 180 ([0°, 180°)), full (any yaw)
//       expected: 1                # optional: how many lie in the scene
//       scale: 1.0                 # optional: multiplies the mesh (rough models, ±10 % tests)
//       scale_range: [0.9, 1.1]    # optional: the size is searched within this range of `scale`
//                                  # (thesis sec. 6.7, sizes off by ±10 %); default [1, 1]
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

enum class Symmetry {
  None,  // no symmetry about the vertical axis: yaw searched over [0°, 360°)
  Half,  // unchanged by a 180° turn: yaw searched over [0°, 180°)
  Full   // unchanged by any turn (a vertical cylinder): yaw not searched
};
const char* symmetry_name(Symmetry s);  // "none", "180", "full"

struct CatalogueModel {
  std::string name;
  std::string mesh_path;  // resolved against the catalogue's directory; empty with `reference`
  std::string reference;  // a procedural reference object (sphere, tank, pillar, riser)
  Symmetry symmetry = Symmetry::None;
  int expected = -1;   // -1: unknown (as many as are found)
  double scale = 1.0;  // applied to the mesh
  // The range within which recognition searches the size of the (scaled) mesh, as factors of
  // it: [1, 1] (the default) searches none. Within [kMinScaleSearch, kMaxScaleSearch].
  double scale_min = 1.0, scale_max = 1.0;
  int line = 0;  // 1-based line of the entry in the catalogue, for messages
};

struct Catalogue {
  std::string path;  // the file read
  std::vector<CatalogueModel> models;
};

// Catalogue entries allowed per file and instances allowed per model (a count read from a file
// decides loops and allocations).
constexpr int kMaxCatalogueModels = 1000;
constexpr int kMaxExpectedInstances = 1000;
// Bounds of a model's scale_range: the scale search refines a size off by tens of percent around
// a pose found at scale 1 (docs/recognition.md, "Scale"), it does not find a model of any size.
constexpr double kMinScaleSearch = 0.5;
constexpr double kMaxScaleSearch = 2.0;

// Parses and validates a catalogue file without loading meshes. Errors name the file, line and
// key: a missing or empty `models` list, unknown keys, both or neither of mesh/reference, an
// unknown symmetry, duplicate names, a non-positive scale, a negative count, a scale_range that
// is not two finite numbers, is inverted or lies outside [kMinScaleSearch, kMaxScaleSearch].
Catalogue read_catalogue(const std::string& path);

// The model's mesh in its own frame (metres, z up), scaled. Errors name the catalogue, the
// model and the mesh file (missing, unreadable, empty).
TriangleMesh load_catalogue_mesh(const Catalogue& catalogue, const CatalogueModel& model);

}  // namespace sonar3d
