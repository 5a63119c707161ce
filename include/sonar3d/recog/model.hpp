#pragma once
// A catalogue model prepared for recognition (thesis sec. 6.3): its mesh in its own frame,
// surface samples every ~1 cm with normals (for ICP and distances), its horizontal centre and
// radius r_model, and top-view elevation maps rendered at any yaw and cell size (sec. 6.3.2.3,
// Fig. 6.15 d–f).
//
// Frames: the model frame is the mesh's (z up). A placement is T_world_model; a top view at yaw
// θ centred at world (x, y) places the model by T = Trans(x, y, 0) · Rz(θ) · Trans(−c_xy, 0),
// with c_xy the model's horizontal centre.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/params.hpp"
#include "sonar3d/mapping/elevation_map.hpp"
#include "sonar3d/recog/catalogue.hpp"

namespace sonar3d {

struct ModelSamplingConfig {
  double spacing_m = 0.01;              // surface sample spacing (the thesis samples at 1 cm), m
  std::size_t max_samples = 2'000'000;  // refuses finer sampling of huge meshes
  unsigned long long seed = 1;
  void validate() const;
};
template <class V>
void describe(ModelSamplingConfig& c, V& v) {
  using params::param;
  v.field(c.spacing_m,
          param("spacing_m", "m", "surface sample spacing of the models (the thesis: 1 cm)")
              .positive());
  v.field(c.max_samples,
          param("max_samples", "", "refuses finer sampling of huge meshes").at_least(1));
  v.field(c.seed, param("seed", "", "random seed of the surface sampling"));
}

struct ModelTemplate {
  std::string name;
  Symmetry symmetry = Symmetry::None;
  int expected = -1;
  TriangleMesh mesh;                // model frame
  Eigen::Vector2d center_xy{0, 0};  // horizontal centre (of the bounding box), model frame
  double base_z = 0, top_z = 0;     // lowest and highest z, model frame
  double radius_m = 0;              // r_model in 2D: farthest vertex from center_xy, horizontally
  std::vector<Eigen::Vector3f> points;   // surface samples, model frame
  std::vector<Eigen::Vector3f> normals;  // unit normal of each sample's triangle
  // The catalogue's scale_range (thesis sec. 6.7): the 2D method searches the model's size in
  // [scale_min, scale_max] × this template (recog/scale.hpp); [1, 1] searches none.
  double scale_min = 1, scale_max = 1;
  double height() const { return top_z - base_z; }
  bool scale_searched() const { return scale_min < 1 || scale_max > 1; }
};

ModelTemplate make_model_template(const std::string& name, const TriangleMesh& mesh_model,
                                  Symmetry symmetry, int expected,
                                  const ModelSamplingConfig& config = {});

// A catalogue entry's template: its mesh (load_catalogue_mesh), symmetry, expected count and
// scale_range.
ModelTemplate make_catalogue_template(const Catalogue& catalogue, const CatalogueModel& model,
                                      const ModelSamplingConfig& config = {});

// The placement of a top view at yaw θ centred at world (x, y), shifted by t (see above).
Eigen::Isometry3d top_view_pose(const ModelTemplate& m, double yaw_rad,
                                const Eigen::Vector2d& center_world_xy,
                                const Eigen::Vector3d& t = Eigen::Vector3d::Zero());

struct TopViewConfig {
  double cell_m = 0.08;
  // Cells within `background_radius_m` of the centre (0: none) that the model does not cover
  // get the model's base height: the seabed the model stands on (the descriptor compares discs
  // of seabed and structure). Cells farther than `background_ring_m` from the model's footprint
  // get no data even within that radius when background_ring_m > 0.
  double background_radius_m = 0;
  double background_ring_m = 0;
  // Corner of a world grid the map's cells must align with (e.g. the scene map's origin).
  Eigen::Vector2d grid_anchor_xy{0, 0};
};

// Top view of the model placed by top_view_pose(m, yaw, center): per cell the highest z
// (model frame heights, i.e. relative to the model's own z = 0) of the mesh, triangles
// rasterised at cell centres and surface samples splatted (thin parts narrower than a cell are
// kept, as an elevation map of points keeps them). The map's extent is the disc of the larger of
// r_model and background_radius_m, its corners on the anchor's grid.
ElevationMap render_top_view(const ModelTemplate& m, double yaw_rad,
                             const Eigen::Vector2d& center_world_xy, const TopViewConfig& config,
                             std::vector<uint8_t>* footprint = nullptr);

// The top view of the model placed by any T_world_model (world heights), on a map centred at
// `center_world_xy` with the extent and background rules above (background at the placed base:
// the lowest placed z).
ElevationMap render_placed_top_view(const ModelTemplate& m, const Eigen::Isometry3d& T_world_model,
                                    const Eigen::Vector2d& center_world_xy,
                                    const TopViewConfig& config,
                                    std::vector<uint8_t>* footprint = nullptr);

}  // namespace sonar3d
