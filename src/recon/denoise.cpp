#include "sonar3d/recon/denoise.hpp"

#include <cmath>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void DenoiseConfig::validate() const {
  require(std::isfinite(z_threshold), "parameter 'denoise.z_threshold' must be finite");
  require_non_negative(static_threshold, "denoise.static_threshold");
}

void denoise(SonarImage& image, const std::optional<NoiseImages>& noise,
             const DenoiseConfig& config) {
  config.validate();
  const bool use_z = config.z_test && noise.has_value();
  if (use_z) {
    if (noise->mean.rows != image.rows || noise->mean.cols != image.cols ||
        noise->std.rows != image.rows || noise->std.cols != image.cols) {
      throw Error("denoise: noise statistics are " + std::to_string(noise->mean.rows) + "×" +
                  std::to_string(noise->mean.cols) + " but the image is " +
                  std::to_string(image.rows) + "×" + std::to_string(image.cols));
    }
  }
  const float T = static_cast<float>(config.z_threshold);
  const float floor = static_cast<float>(config.static_threshold);
  for (std::size_t k = 0; k < image.data.size(); ++k) {
    float v = image.data[k];
    if (use_z) {
      const float m = noise->mean.data[k];
      const float s = noise->std.data[k];
      // eq. 4.8: Z = (I - m)/σ > T keeps the pixel. A zero σ (a pixel that never varied in open
      // water) keeps anything above the mean.
      const bool keep = s > 0.0f ? (v - m) / s > T : v > m;
      v = keep ? (config.subtract_mean ? v - m : v) : 0.0f;
    }
    image.data[k] = v > floor ? v : 0.0f;
  }
}

std::optional<std::size_t> first_frame_with_return(const Dataset& dataset,
                                                   const DenoiseConfig& config) {
  config.validate();
  for (std::size_t i = 0; i < dataset.size(); ++i) {
    SonarImage img = dataset.load_frame(i);
    denoise(img, dataset.noise, config);
    for (float v : img.data) {
      if (v > 0.0f) return i;
    }
  }
  return std::nullopt;
}

}  // namespace sonar3d
