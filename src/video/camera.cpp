// Pinhole camera with OpenCV's distortion model: projection and its inverse.
#include "sonar3d/video/camera.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {

// Distortion of normalised coordinates (OpenCV's model, 5 coefficients).
Eigen::Vector2d distort(const CameraIntrinsics& c, const Eigen::Vector2d& xy) {
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  const double radial = 1 + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  return {x * radial + 2 * c.p1 * x * y + c.p2 * (r2 + 2 * x * x),
          y * radial + c.p1 * (r2 + 2 * y * y) + 2 * c.p2 * x * y};
}

// Its Jacobian with respect to (x, y).
Eigen::Matrix2d distort_jacobian(const CameraIntrinsics& c, const Eigen::Vector2d& xy) {
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  const double radial = 1 + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  const double dradial_dr2 = c.k1 + r2 * (2 * c.k2 + 3 * r2 * c.k3);
  Eigen::Matrix2d J;
  J(0, 0) = radial + x * dradial_dr2 * 2 * x + 2 * c.p1 * y + c.p2 * 6 * x;
  J(0, 1) = x * dradial_dr2 * 2 * y + 2 * c.p1 * x + c.p2 * 2 * y;
  J(1, 0) = y * dradial_dr2 * 2 * x + c.p1 * 2 * x + 2 * c.p2 * y;
  J(1, 1) = radial + y * dradial_dr2 * 2 * y + c.p1 * 6 * y + 2 * c.p2 * x;
  return J;
}

}  // namespace

void CameraIntrinsics::validate() const {
  require(width >= 1 && width <= 100000 && height >= 1 && height <= 100000,
          "camera: width and height must be 1 … 100000 pixels (got " + std::to_string(width) +
              " × " + std::to_string(height) + ")");
  require(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0,
          "camera: the focal lengths fx, fy must be > 0 pixels");
  require(std::isfinite(cx) && std::isfinite(cy), "camera: the principal point must be finite");
  require(std::isfinite(k1) && std::isfinite(k2) && std::isfinite(p1) && std::isfinite(p2) &&
              std::isfinite(k3),
          "camera: the distortion coefficients must be finite");
  if (!distorted()) return;
  // The model must be one-to-one over the image: the radial factor r·(1 + k1 r² + k2 r⁴ + k3 r⁶)
  // increasing out to the farthest corner (sampled finely; tangential terms are small there).
  const double u_far = std::max(std::abs(-0.5 - cx), std::abs(width - 0.5 - cx)) / fx;
  const double v_far = std::max(std::abs(-0.5 - cy), std::abs(height - 0.5 - cy)) / fy;
  const double r_max = 1.5 * std::hypot(u_far, v_far);  // distorted corners lie within this
  double prev = 0;
  for (int i = 1; i <= 2000; ++i) {
    const double r = r_max * i / 2000, r2 = r * r;
    const double d = r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3)));
    require(d > prev, "camera: the distortion (k1 " + std::to_string(k1) + ", k2 " +
                          std::to_string(k2) + ", k3 " + std::to_string(k3) +
                          ") folds over within the image (at a radius of " + std::to_string(r) +
                          " in normalised coordinates): it does not invert");
    prev = d;
  }
}

std::optional<Eigen::Vector2d> project(const CameraIntrinsics& c, const Eigen::Vector3d& p) {
  if (!(p.z() > 0) || !p.allFinite()) return std::nullopt;
  const Eigen::Vector2d d = distort(c, p.head<2>() / p.z());
  return Eigen::Vector2d(c.fx * d.x() + c.cx, c.fy * d.y() + c.cy);
}

std::optional<Eigen::Vector3d> unproject(const CameraIntrinsics& c, const Eigen::Vector2d& pixel) {
  if (!pixel.allFinite()) return std::nullopt;
  const Eigen::Vector2d target((pixel.x() - c.cx) / c.fx, (pixel.y() - c.cy) / c.fy);
  Eigen::Vector2d xy = target;
  if (c.distorted()) {
    // Newton on distort(xy) = target, from the undistorted guess; converged when the residual,
    // in pixels, is below 1e-9.
    bool converged = false;
    for (int it = 0; it < 50 && !converged; ++it) {
      const Eigen::Vector2d r = distort(c, xy) - target;
      if (std::abs(r.x() * c.fx) < 1e-9 && std::abs(r.y() * c.fy) < 1e-9) {
        converged = true;
        break;
      }
      const Eigen::Matrix2d J = distort_jacobian(c, xy);
      if (!(std::abs(J.determinant()) > 1e-12)) return std::nullopt;
      xy -= J.inverse() * r;
      if (!xy.allFinite()) return std::nullopt;
    }
    if (!converged) {
      const Eigen::Vector2d r = distort(c, xy) - target;
      if (!(std::abs(r.x() * c.fx) < 1e-9 && std::abs(r.y() * c.fy) < 1e-9)) return std::nullopt;
    }
  }
  return Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized();
}

Eigen::AlignedBox2d normalised_image_bounds(const CameraIntrinsics& c) {
  Eigen::AlignedBox2d box(
      Eigen::Vector2d((-0.5 - c.cx) / c.fx, (-0.5 - c.cy) / c.fy),
      Eigen::Vector2d((c.width - 0.5 - c.cx) / c.fx, (c.height - 0.5 - c.cy) / c.fy));
  if (!c.distorted()) return box;
  box.setEmpty();
  auto take = [&](double u, double v) {
    const auto ray = unproject(c, Eigen::Vector2d(u, v));
    if (ray && ray->z() > 0) box.extend(Eigen::Vector2d(ray->x() / ray->z(), ray->y() / ray->z()));
  };
  const int step = 8;
  for (int i = 0; i <= c.width; i += step) {
    take(std::min(i, c.width) - 0.5, -0.5);
    take(std::min(i, c.width) - 0.5, c.height - 0.5);
  }
  for (int j = 0; j <= c.height; j += step) {
    take(-0.5, std::min(j, c.height) - 0.5);
    take(c.width - 0.5, std::min(j, c.height) - 0.5);
  }
  take(c.width - 0.5, c.height - 0.5);
  // A margin of two pixels for the border sampling's step.
  box.min() -= Eigen::Vector2d(2 / c.fx, 2 / c.fy);
  box.max() += Eigen::Vector2d(2 / c.fx, 2 / c.fy);
  return box;
}

}  // namespace sonar3d
