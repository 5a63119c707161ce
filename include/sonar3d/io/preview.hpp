#pragma once
// Viewable pictures of sonar images: the polar image (range × bearing) or the fan-shaped
// Cartesian view an operator sees, colour-mapped, as PNG.
#include <string>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

struct PreviewConfig {
  bool fan = true;         // Cartesian fan (true) or the raw polar image (false)
  int width = 800;         // fan picture width in pixels
  double max_value = 0.0;  // intensity mapped to the top of the colour map; 0 = image maximum
  double gamma = 0.5;      // display gamma (< 1 lifts weak returns)
  bool colormap = true;    // JET-like colours (as the thesis' figures) or grey
};

// The one declaration of PreviewConfig's settings (core/params.hpp): sonar3d preview's flags and
// --print-config keys.
template <class V>
void describe(PreviewConfig& c, V& v) {
  using params::param;
  v.field(c.fan, param("fan", "",
                       "the fan-shaped Cartesian view (false: the polar image, range "
                       "bins x beams)")
                     .flag("--polar"));
  v.field(c.width, param("width", "px", "fan picture width").range(16, 16384).flag("--width"));
  v.field(c.max_value, param("max_value", "",
                             "intensity at the top of the colour map (linear units; 0 = the "
                             "frame's maximum)")
                           .non_negative()
                           .flag("--max"));
  v.field(c.gamma,
          param("gamma", "", "display gamma (< 1 lifts weak returns)").positive().flag("--gamma"));
  v.field(c.colormap,
          param("colormap", "", "JET-like colours, as the thesis' figures (false: grey levels)")
              .flag("--grey"));
}

void write_preview_png(const std::string& path, const SonarImage& image, const SonarSpec& spec,
                       const PreviewConfig& config = {});

}  // namespace sonar3d
