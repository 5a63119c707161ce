// The sRGB transfer function (include/sonar3d/core/rgb_image.hpp).
#include "sonar3d/core/rgb_image.hpp"

#include <cmath>

namespace sonar3d {

float srgb_to_linear(float e) {
  e = std::clamp(e, 0.0f, 1.0f);
  return e <= 0.04045f ? e / 12.92f : std::pow((e + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float l) {
  l = std::clamp(l, 0.0f, 1.0f);
  return l <= 0.0031308f ? 12.92f * l : 1.055f * std::pow(l, 1.0f / 2.4f) - 0.055f;
}

std::array<std::uint8_t, 3> linear_to_srgb8(const Eigen::Vector3f& linear) {
  std::array<std::uint8_t, 3> out{};
  for (int k = 0; k < 3; ++k) {
    out[static_cast<std::size_t>(k)] =
        static_cast<std::uint8_t>(std::lround(255.0f * linear_to_srgb(linear[k])));
  }
  return out;
}

}  // namespace sonar3d
