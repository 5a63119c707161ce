#include "sonar3d/io/preview.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {

void write_preview_png(const std::string& path, const SonarImage& image, const SonarSpec& spec,
                       const PreviewConfig& config) {
  spec.validate();
  if (image.rows != spec.range_bins || image.cols != spec.beams()) {
    throw Error("preview: image size differs from the sonar description");
  }
  require(config.width >= 16 && config.width <= 16384, "preview: width must be in [16, 16384]");
  require_positive(config.gamma, "preview.gamma");
  double vmax = config.max_value;
  if (!(vmax > 0)) vmax = *std::max_element(image.data.begin(), image.data.end());
  if (!(vmax > 0)) vmax = 1.0;
  cv::Mat norm(image.rows, image.cols, CV_8U);
  for (int i = 0; i < image.rows; ++i) {
    for (int j = 0; j < image.cols; ++j) {
      const double v = std::clamp(image.at(i, j) / vmax, 0.0, 1.0);
      norm.at<uint8_t>(i, j) = static_cast<uint8_t>(std::lround(255 * std::pow(v, config.gamma)));
    }
  }
  cv::Mat out, outside;
  if (!config.fan) {
    // Polar: range grows upward as on a sonar display, bearing left to right... our columns grow
    // with bearing toward +y (left), so flip horizontally to show port on the left.
    cv::flip(norm, out, -1);
  } else {
    // Cartesian fan seen from above: sonar at the bottom centre, +x up, +y (port) to the left.
    const double lo = spec.fov_min(), hi = spec.fov_max();
    const double half = std::max(std::abs(lo), std::abs(hi));
    const double xspan = half < M_PI / 2 ? spec.r_max * std::sin(half) : spec.r_max;
    const double ymin = half < M_PI / 2 ? spec.r_min * std::cos(half) : -spec.r_max;
    const double scale = config.width / (2.0 * xspan);
    const int height = std::max(16, static_cast<int>(std::ceil((spec.r_max - std::min(0.0, ymin)) * scale)));
    cv::Mat mapx(height, config.width, CV_32F), mapy(height, config.width, CV_32F);
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < config.width; ++u) {
        const double y_left = (config.width / 2.0 - u) / scale;  // +y is left
        const double x_fwd = (height - v) / scale + std::min(0.0, ymin);
        const double r = std::hypot(x_fwd, y_left);
        const double phi = std::atan2(y_left, x_fwd);
        const int j = spec.beam_of_bearing(phi);
        const double row = (r - spec.r_min) / spec.range_resolution() - 0.5;
        if (j < 0 || row < -0.5 || row > spec.range_bins - 0.5) {
          mapx.at<float>(v, u) = -1;
          mapy.at<float>(v, u) = -1;
        } else {
          mapx.at<float>(v, u) = static_cast<float>(j);
          mapy.at<float>(v, u) = static_cast<float>(row);
        }
      }
    }
    cv::remap(norm, out, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    outside = mapx < 0;  // drawn black, so the fan's edges show
  }
  cv::Mat rgb;
  if (config.colormap) {
    cv::applyColorMap(out, rgb, cv::COLORMAP_JET);
  } else {
    rgb = out;
  }
  if (!outside.empty()) rgb.setTo(cv::Scalar::all(0), outside);
  AtomicPath tmp(path);
  const std::string tmp_png = tmp.temp().string() + ".png";
  if (!cv::imwrite(tmp_png, rgb)) throw Error("cannot write preview '" + path + "'");
  mark_png_as_sonar3d(tmp_png);  // replaceable by sonar3d only
  std::filesystem::rename(tmp_png, tmp.temp());
  tmp.commit();
}

}  // namespace sonar3d
