#pragma once
// Viewable pictures of sonar images: the polar image (range × bearing) or the fan-shaped
// Cartesian view an operator sees, colour-mapped, as PNG.
#include <string>

#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

struct PreviewConfig {
  bool fan = true;          // Cartesian fan (true) or the raw polar image (false)
  int width = 800;          // fan picture width in pixels
  double max_value = 0.0;   // intensity mapped to the top of the colour map; 0 = image maximum
  double gamma = 0.5;       // display gamma (< 1 lifts weak returns)
  bool colormap = true;     // JET-like colours (as the thesis' figures) or grey
};

void write_preview_png(const std::string& path, const SonarImage& image, const SonarSpec& spec,
                       const PreviewConfig& config = {});

}  // namespace sonar3d
