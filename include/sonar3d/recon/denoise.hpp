#pragma once
// Image denoising shared by every reconstruction method (thesis sec. 4.4.7): the Z-test against
// per-pixel open-water noise statistics (eq. 4.8) and a static intensity threshold. A pixel that
// fails is set to 0 ("no return"); a pixel that passes keeps its intensity, minus the noise mean
// when `subtract_mean` is set.
#include <optional>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/io/dataset.hpp"

namespace sonar3d {

struct DenoiseConfig {
  bool z_test = true;             // apply eq. 4.8 when noise statistics are available
  double z_threshold = 3.0;       // T: keep a pixel when (I - m)/σ > T
  bool subtract_mean = true;      // kept pixels become I - m (the return above the noise floor)
  double static_threshold = 0.0;  // keep a pixel only when its (denoised) intensity > this
  void validate() const;          // throws Error naming the field
};

// The one declaration of DenoiseConfig's fields (core/params.hpp).
template <class V>
void describe(DenoiseConfig& c, V& v) {
  using params::param;
  v.field(c.z_test, param("z_test", "", "apply the Z-test when the dataset has noise statistics")
                        .equation("eq. 4.8")
                        .flag("--no-z-test"));
  v.field(c.z_threshold,
          param("z_threshold", "", "T: keep a pixel when (I - m)/sigma > T, with noise statistics")
              .range(-1e6, 1e6)
              .equation("eq. 4.8")
              .flag("--z-threshold"));
  v.field(c.subtract_mean, param("subtract_mean", "",
                                 "kept pixels become I - m (the return above the noise floor)"));
  v.field(c.static_threshold,
          param("static_threshold", "", "keep a pixel only when its denoised intensity is > this")
              .non_negative()
              .equation("sec. 4.4.7")
              .flag("--image-threshold"));
}

// Denoises `image` in place. `noise` may be empty: then only the static threshold applies.
// Throws Error when noise images and the image differ in size.
void denoise(SonarImage& image, const std::optional<NoiseImages>& noise,
             const DenoiseConfig& config);

// The first frame of `dataset` holding a return: a pixel that survives denoise() with `config`
// and the dataset's noise statistics; nullopt when no frame does (nothing was ever in view, or
// everything is below the thresholds). Frames are read in order until one is found.
std::optional<std::size_t> first_frame_with_return(const Dataset& dataset,
                                                   const DenoiseConfig& config);

}  // namespace sonar3d
