#pragma once
// A polar sonar image: rows are range bins (row 0 nearest), columns are beams by increasing
// bearing. Intensities are linear float32, row-major.
#include <cstddef>
#include <vector>

namespace sonar3d {

struct SonarImage {
  int rows = 0;  // range bins
  int cols = 0;  // beams
  double timestamp = 0.0;  // s
  std::vector<float> data;

  SonarImage() = default;
  SonarImage(int rows_, int cols_, float fill = 0.0f)
      : rows(rows_), cols(cols_), data(static_cast<std::size_t>(rows_) * cols_, fill) {}

  float& at(int row, int col) { return data[static_cast<std::size_t>(row) * cols + col]; }
  float at(int row, int col) const { return data[static_cast<std::size_t>(row) * cols + col]; }
  float* row_ptr(int row) { return data.data() + static_cast<std::size_t>(row) * cols; }
  const float* row_ptr(int row) const { return data.data() + static_cast<std::size_t>(row) * cols; }
  bool empty() const { return data.empty(); }
};

}  // namespace sonar3d
