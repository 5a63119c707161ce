#pragma once
// Colour images and the sRGB transfer function: the types every module that touches colour shares
// (video mapping, the simulator's camera, world models, change detection). Reading and writing
// them is io/texture_io.hpp.
//
// Colour conventions (docs/video.md): inside sonar3d colours are linear RGB, since averaging light
// is only meaningful in linear units; 8- and 16-bit files are sRGB-encoded, as cameras, image tools
// and viewers expect.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace sonar3d {

// A colour image: linear RGB in [0, 1], row-major from the top-left pixel, 3 floats per pixel;
// with the range (m) of what each pixel sees, +inf where it sees nothing.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<float> rgb;
  std::vector<float> range_m;
  Eigen::Vector3f at(int u, int v) const {
    const std::size_t k = 3 * (static_cast<std::size_t>(v) * width + u);
    return {rgb[k], rgb[k + 1], rgb[k + 2]};
  }
  // Bilinear between pixel centres (pixel coordinates as in video/camera.hpp), clamped at the
  // edges.
  Eigen::Vector3f sample(const Eigen::Vector2d& pixel) const {
    const double x = std::clamp(pixel.x(), 0.0, static_cast<double>(width - 1));
    const double y = std::clamp(pixel.y(), 0.0, static_cast<double>(height - 1));
    const int u0 = static_cast<int>(x), v0 = static_cast<int>(y);  // x, y ≥ 0: the floors
    const int u1 = std::min(u0 + 1, width - 1), v1 = std::min(v0 + 1, height - 1);
    const float a = static_cast<float>(x - u0), b = static_cast<float>(y - v0);
    return (1 - a) * (1 - b) * at(u0, v0) + a * (1 - b) * at(u1, v0) + (1 - a) * b * at(u0, v1) +
           a * b * at(u1, v1);
  }
};

// The sRGB transfer function (IEC 61966-2-1) and its inverse, on [0, 1] (clamped).
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);
// A linear-RGB colour as the 8-bit sRGB bytes PLY and glTF files carry (clamped to [0, 1]).
std::array<std::uint8_t, 3> linear_to_srgb8(const Eigen::Vector3f& linear);

}  // namespace sonar3d
