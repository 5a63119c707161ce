#include "sonar3d/sim/noise.hpp"

#include <cmath>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void StripeNoiseConfig::validate() const {
  require(count >= 0, "parameter 'noise.stripes.count' must be >= 0");
  require_positive(width_deg, "noise.stripes.width_deg", "deg");
  require_non_negative(stripe_mean, "noise.stripes.stripe_mean");
  require_non_negative(stripe_std, "noise.stripes.stripe_std");
  require_non_negative(floor_mean, "noise.stripes.floor_mean");
  require_non_negative(floor_std, "noise.stripes.floor_std");
  require_non_negative(range_decay, "noise.stripes.range_decay", "1/m");
}

NoiseImages stripe_noise_images(const SonarSpec& spec, const StripeNoiseConfig& c) {
  spec.validate();
  c.validate();
  NoiseImages out{SonarImage(spec.range_bins, spec.beams()),
                  SonarImage(spec.range_bins, spec.beams())};
  const double lo = spec.fov_min(), hi = spec.fov_max();
  const double sigma = c.width_deg * M_PI / 180.0;
  std::vector<double> fade(spec.beams(), 0.0);
  // sec. 2.5.2: stripes at fixed bearings, intensity fading as a Gaussian around each centre.
  for (int k = 0; k < c.count; ++k) {
    const double centre = lo + (k + 0.5) * (hi - lo) / c.count;
    for (int j = 0; j < spec.beams(); ++j) {
      const double d = (spec.bearings_rad[j] - centre) / sigma;
      fade[j] += std::exp(-0.5 * d * d);
    }
  }
  for (int i = 0; i < spec.range_bins; ++i) {
    const double decay = std::exp(-c.range_decay * (spec.range_of_bin(i) - spec.r_min));
    for (int j = 0; j < spec.beams(); ++j) {
      const double f = fade[j] * decay;
      out.mean.at(i, j) = static_cast<float>(c.floor_mean + c.stripe_mean * f);
      // Independent floor and stripe contributions: variances add.
      out.std.at(i, j) = static_cast<float>(
          std::sqrt(c.floor_std * c.floor_std + (c.stripe_std * f) * (c.stripe_std * f)));
    }
  }
  return out;
}

void add_noise(SonarImage& image, const NoiseImages& noise, std::mt19937_64& rng) {
  if (noise.mean.rows != image.rows || noise.mean.cols != image.cols ||
      noise.std.rows != image.rows || noise.std.cols != image.cols) {
    throw Error("noise images are " + std::to_string(noise.mean.rows) + "×" +
                std::to_string(noise.mean.cols) + " but the sonar image is " +
                std::to_string(image.rows) + "×" + std::to_string(image.cols));
  }
  std::normal_distribution<float> n01(0.0f, 1.0f);
  for (std::size_t k = 0; k < image.data.size(); ++k) {
    const float v = image.data[k] + noise.mean.data[k] + noise.std.data[k] * n01(rng);
    image.data[k] = v > 0.0f ? v : 0.0f;
  }
}

void NoiseEstimator::add(const SonarImage& frame) {
  if (n_ == 0) {
    rows_ = frame.rows;
    cols_ = frame.cols;
    mean_.assign(frame.data.size(), 0.0);
    m2_.assign(frame.data.size(), 0.0);
  } else if (frame.rows != rows_ || frame.cols != cols_) {
    throw Error("noise estimation: frame " + std::to_string(n_) + " is " +
                std::to_string(frame.rows) + "×" + std::to_string(frame.cols) + ", the first was " +
                std::to_string(rows_) + "×" + std::to_string(cols_));
  }
  ++n_;
  // Welford: numerically stable running mean and sum of squared deviations.
  for (std::size_t k = 0; k < frame.data.size(); ++k) {
    const double x = frame.data[k];
    const double d = x - mean_[k];
    mean_[k] += d / static_cast<double>(n_);
    m2_[k] += d * (x - mean_[k]);
  }
}

NoiseImages NoiseEstimator::result() const {
  if (n_ < 2) {
    throw Error("noise estimation needs at least 2 open-water frames, got " + std::to_string(n_));
  }
  NoiseImages out{SonarImage(rows_, cols_), SonarImage(rows_, cols_)};
  for (std::size_t k = 0; k < mean_.size(); ++k) {
    out.mean.data[k] = static_cast<float>(mean_[k]);
    out.std.data[k] = static_cast<float>(std::sqrt(m2_[k] / static_cast<double>(n_ - 1)));
  }
  return out;
}

}  // namespace sonar3d
