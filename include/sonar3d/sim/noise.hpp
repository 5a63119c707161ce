#pragma once
// Sonar noise (sec. 2.5.2): per-pixel Gaussian noise from mean/std images, the parametric stripe
// model of BlueView sensors, and estimation of mean/std from open-water frames.
#include <random>
#include <vector>

#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/io/dataset.hpp"

namespace sonar3d {

// N vertical stripes (constant bearing) with Gaussian fade across bearing, over a uniform floor.
// Intensities are in the image's linear units (after gain).
struct StripeNoiseConfig {
  int count = 7;                 // N stripes, centred uniformly across the field of view
  double width_deg = 4.0;        // Gaussian σ of the fade across bearing, degrees
  double stripe_mean = 0.02;     // mean added at a stripe centre
  double stripe_std = 0.015;     // std at a stripe centre
  double floor_mean = 0.002;     // everywhere
  double floor_std = 0.002;
  double range_decay = 0.0;      // stripe strength falls as exp(-range_decay · (r - r_min)), 1/m
  void validate() const;
};

// Mean and std images of the stripe model for `spec`.
NoiseImages stripe_noise_images(const SonarSpec& spec, const StripeNoiseConfig& config);

// Adds a Gaussian draw N(mean, std) per pixel, clamping the result at 0 (intensities are
// non-negative). Sizes must agree.
void add_noise(SonarImage& image, const NoiseImages& noise, std::mt19937_64& rng);

// Per-pixel mean and (sample) standard deviation over a sequence of open-water frames, by
// Welford's algorithm. Needs >= 2 frames of equal size.
class NoiseEstimator {
 public:
  void add(const SonarImage& frame);
  std::size_t count() const { return n_; }
  NoiseImages result() const;

 private:
  std::size_t n_ = 0;
  int rows_ = 0, cols_ = 0;
  std::vector<double> mean_, m2_;
};

}  // namespace sonar3d
