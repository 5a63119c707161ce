#pragma once
// A relief of n × n quads over a `size` × `size` m square centred on the origin, z =
// amplitude · sin(kx · x) · cos(ky · y), two triangles a quad (shared by the video tests and
// bench/bench_video.cpp; no test framework needed).
#include <cmath>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d::test {

inline TriangleMesh relief_grid(int n, double size, double amplitude, double kx, double ky) {
  TriangleMesh m;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = size * (double(i) / n - 0.5), y = size * (double(j) / n - 0.5);
      m.vertices.emplace_back(x, y, amplitude * std::sin(kx * x) * std::cos(ky * y));
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.emplace_back(a, b, d);
      m.triangles.emplace_back(a, d, c);
    }
  }
  return m;
}

}  // namespace sonar3d::test
