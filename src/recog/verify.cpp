// Hypothesis verification of placed CAD models (docs/recognition.md, "Verification"): seen,
// explained, free-space violation and unexplained relief on the field's elevation map, and the
// calibrated confidence.
#include "sonar3d/recog/verify.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

void VerificationConfig::validate() const { params::check(*this, "verification"); }

double verification_confidence(const Verification& v, const VerificationConfig& c) {
  if (!v.valid) return 0.0;
  const double s = c.bias + c.w_seen * v.seen + c.w_explained * v.explained +
                   c.w_violation * v.violation + c.w_unexplained * v.unexplained +
                   c.w_spill * v.spill + c.w_evidence * v.evidence;
  return 1.0 / (1.0 + std::exp(-s));
}

Verification verify_placement(const ModelTemplate& m, const Eigen::Isometry3d& T,
                              const ElevationMap& scene, const std::vector<uint8_t>& removed,
                              const VerificationConfig& config) {
  config.validate();
  require(!scene.empty(), "verification: the scene map is empty");
  require(removed.empty() || removed.size() == scene.z.size(),
          "verification: the removed-cell mask does not match the scene map");
  Verification out;
  out.ground_z = std::numeric_limits<double>::quiet_NaN();
  const double cell = scene.cell_m;
  const double context_m = std::max(config.context_min_m, config.context_fraction * m.radius_m);
  const double ring_m =
      std::max({config.ground_ring_m, context_m, config.slip_m + config.spill_band_m});

  // The placed model's top view on the scene's grid, with the rings around its footprint.
  TopViewConfig tv;
  tv.cell_m = cell;
  tv.grid_anchor_xy = scene.origin_xy;
  tv.background_radius_m = m.radius_m + ring_m;
  tv.background_ring_m = ring_m;
  const Eigen::Vector2d center =
      (T * Eigen::Vector3d(m.center_xy.x(), m.center_xy.y(), 0)).head<2>();
  std::vector<uint8_t> fp;
  const ElevationMap v = render_placed_top_view(m, T, center, tv, &fp);
  const int dc0 = static_cast<int>(std::lround((v.origin_xy.x() - scene.origin_xy.x()) / cell));
  const int dr0 = static_cast<int>(std::lround((scene.origin_xy.y() - v.origin_xy.y()) / cell));
  auto scene_index = [&](int r, int c) -> long {
    const int rr = r + dr0, cc = c + dc0;
    if (rr < 0 || cc < 0 || rr >= scene.rows || cc >= scene.cols) return -1;
    return static_cast<long>(scene.index(rr, cc));
  };
  auto scene_at = [&](int r, int c) {
    const long i = scene_index(r, c);
    if (i < 0) return ElevationMap::kNoData;
    return (!removed.empty() && removed[static_cast<std::size_t>(i)]) ? ElevationMap::kNoData
                                                                      : scene.z[i];
  };

  // Distance of every cell to the footprint (Euclidean, m).
  cv::Mat outside(v.rows, v.cols, CV_8U);
  std::size_t fp_cells = 0, fp_taken = 0;
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      const bool in = fp[v.index(r, c)] != 0;
      outside.at<uint8_t>(r, c) = in ? 0 : 255;
      if (!in) continue;
      ++fp_cells;
      const long i = scene_index(r, c);
      if (i >= 0 && !removed.empty() && removed[static_cast<std::size_t>(i)]) ++fp_taken;
    }
  }
  if (fp_cells == 0) return out;
  out.overlap = static_cast<double>(fp_taken) / static_cast<double>(fp_cells);
  cv::Mat dist;
  cv::distanceTransform(outside, dist, cv::DIST_L2, 3);
  auto dist_m = [&](int r, int c) { return dist.at<float>(r, c) * cell; };

  // The local seabed: a plane through the scene heights in the ground ring around the footprint
  // (a 5° slope across a 3 m ring is 26 cm: a level seabed would call the uphill side relief
  // the model leaves unexplained), fitted by least squares and refitted without the cells
  // farther than 2.5 robust σ (clutter in the ring); the ring's median height when fewer than 12
  // cells hold data or the plane is steeper than 30°. ground_z is its height at the centre.
  struct RingCell {
    double x, y, z;
  };
  std::vector<RingCell> ring;
  const double rc = (v.origin_xy.y() - center.y()) / cell - 0.5;
  const double cc = (center.x() - v.origin_xy.x()) / cell - 0.5;
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      if (fp[v.index(r, c)] || dist_m(r, c) > config.ground_ring_m) continue;
      const float zs = scene_at(r, c);
      if (zs == zs) ring.push_back({(c - cc) * cell, (rc - r) * cell, zs});
    }
  }
  if (ring.empty()) return out;
  std::vector<double> heights(ring.size());
  for (std::size_t i = 0; i < ring.size(); ++i) heights[i] = ring[i].z;
  const auto mid = heights.begin() + static_cast<std::ptrdiff_t>(heights.size() / 2);
  std::nth_element(heights.begin(), mid, heights.end());
  Eigen::Vector3d plane(*mid, 0, 0);  // z = p0 + p1·x + p2·y about the footprint's centre
  if (ring.size() >= 12) {
    std::vector<uint8_t> keep(ring.size(), 1);
    Eigen::Vector3d fit = plane;
    bool ok = true;
    for (int pass = 0; pass < 2 && ok; ++pass) {
      Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
      Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
      for (std::size_t i = 0; i < ring.size(); ++i) {
        if (!keep[i]) continue;
        const Eigen::Vector3d a(1, ring[i].x, ring[i].y);
        AtA += a * a.transpose();
        Atb += a * ring[i].z;
      }
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(AtA);
      ok = ldlt.info() == Eigen::Success && std::abs(AtA.determinant()) > 1e-12;
      if (!ok) break;
      fit = ldlt.solve(Atb);
      std::vector<double> res(ring.size());
      for (std::size_t i = 0; i < ring.size(); ++i) {
        res[i] = std::abs(ring[i].z - fit.dot(Eigen::Vector3d(1, ring[i].x, ring[i].y)));
      }
      std::vector<double> sorted = res;
      const auto m = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
      std::nth_element(sorted.begin(), m, sorted.end());
      const double cut = std::max(0.02, 2.5 * 1.4826 * *m);
      std::size_t kept = 0;
      for (std::size_t i = 0; i < ring.size(); ++i) kept += keep[i] = res[i] <= cut;
      ok = kept >= 12;
    }
    if (ok && std::hypot(fit.y(), fit.z()) <= std::tan(30 * M_PI / 180)) plane = fit;
  }
  const double g = plane.x();
  out.ground_z = g;
  out.ground_dzdx = plane.y();
  out.ground_dzdy = plane.z();
  out.valid = true;
  auto ground_at = [&](int r, int c) {
    return g + plane.y() * (c - cc) * cell + plane.z() * (rc - r) * cell;
  };

  const int k = static_cast<int>(std::lround(config.slip_m / cell));
  const double tol = config.tol_m, area = cell * cell;
  auto model_top = [&](int r, int c) -> float {
    if (r < 0 || c < 0 || r >= v.rows || c >= v.cols || !fp[v.index(r, c)]) {
      return ElevationMap::kNoData;
    }
    return v.at(r, c);
  };

  // The model's relief against the scene.
  double seen = 0, agree = 0, violate = 0, intrude = 0;
  // Relief evidence: every observed footprint cell where the model stands more than
  // evidence_min_m above the seabed (all of its shape, not only its relief above relief_m),
  // weighted by that height, supported where the scene within evidence_slip_m rises at least
  // evidence_ratio of it. A rock under a small model explains its top (`explained`) but its
  // flanks fall away under the model's ends.
  const int ke = static_cast<int>(std::lround(config.evidence_slip_m / cell));
  double ev_seen = 0, ev_support = 0;
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      if (!fp[v.index(r, c)]) continue;
      const float zm = v.at(r, c);
      const double gz = ground_at(r, c);
      if (zm > gz + config.evidence_min_m && scene_at(r, c) == scene_at(r, c)) {
        const double h = zm - gz;
        float top = ElevationMap::kNoData;
        for (int dr = -ke; dr <= ke; ++dr) {
          for (int dc = -ke; dc <= ke; ++dc) {
            const float zn = scene_at(r + dr, c + dc);
            if (zn == zn && !(top >= zn)) top = zn;
          }
        }
        ev_seen += h;
        if (top - gz >= config.evidence_ratio * h) ev_support += h;
      }
      if (!(zm > gz + config.relief_m)) continue;
      const double w = (zm - gz) * area;
      out.relief_m3 += w;
      const float zs = scene_at(r, c);
      if (zs != zs) continue;  // not observed: neither for nor against
      seen += w;
      bool agrees = false;
      float highest = zs;
      for (int dr = -k; dr <= k && !agrees; ++dr) {
        for (int dc = -k; dc <= k; ++dc) {
          const float zn = scene_at(r + dr, c + dc);
          if (zn != zn) continue;
          if (std::abs(zn - zm) <= tol) {
            agrees = true;
            break;
          }
          highest = std::max(highest, zn);
        }
      }
      if (agrees) {
        agree += w;
      } else if (highest < zm - tol) {
        violate += w;  // the survey saw water where the model's top would be
      } else {
        intrude += w;
      }
    }
  }

  // The scene's relief within the footprint and the context ring, and how much of it the model
  // accounts for: a scene surface at or below a model top within the slip is explained (seen, or
  // hidden under the model).
  double scene_relief = 0, unexplained = 0;
  std::size_t band = 0, spilled = 0;
  const double band0 = config.slip_m, band1 = config.slip_m + config.spill_band_m;
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      const double d = dist_m(r, c);
      if (d > std::max(context_m, band1)) continue;
      const float zs = scene_at(r, c);
      const bool in_band = d > band0 && d <= band1 && zs == zs;
      band += in_band;
      const double gz = ground_at(r, c);
      if (!(zs > gz + config.relief_m)) continue;
      if (in_band) ++spilled;  // beyond the slip no model cell can explain it
      if (d > context_m) continue;
      const double w = (zs - gz) * area;
      scene_relief += w;
      bool explained = false;
      for (int dr = -k; dr <= k && !explained; ++dr) {
        for (int dc = -k; dc <= k; ++dc) {
          const float zm = model_top(r + dr, c + dc);
          if (zm == zm && zs <= zm + tol) {
            explained = true;
            break;
          }
        }
      }
      if (!explained) unexplained += w;
    }
  }

  out.scene_relief_m3 = scene_relief;
  if (out.relief_m3 > 0) out.seen = seen / out.relief_m3;
  if (seen > 0) {
    out.explained = agree / seen;
    out.violation = violate / seen;
    out.intrusion = intrude / seen;
  }
  out.unexplained = scene_relief > 0 ? unexplained / scene_relief : 0.0;
  out.spill = band > 0 ? static_cast<double>(spilled) / static_cast<double>(band) : 0.0;
  out.evidence = ev_seen > 0 ? ev_support / ev_seen : 0.0;
  out.score_m3 = agree - violate - unexplained;
  out.confidence = verification_confidence(out, config);
  return out;
}

double buried_fraction(const ModelTemplate& model, const Eigen::Isometry3d& T_world_model,
                       double ground_z) {
  if (!std::isfinite(ground_z)) return 0.0;
  const double base =
      (T_world_model * Eigen::Vector3d(model.center_xy.x(), model.center_xy.y(), model.base_z)).z();
  return (ground_z - base) / std::max(1e-6, model.height());
}

void mark_placed(const ModelTemplate& m, const Eigen::Isometry3d& T, const ElevationMap& map,
                 double margin, std::vector<uint8_t>& mask) {
  TopViewConfig tv;
  tv.cell_m = map.cell_m;
  tv.grid_anchor_xy = map.origin_xy;
  const Eigen::Vector2d center =
      (T * Eigen::Vector3d(m.center_xy.x(), m.center_xy.y(), 0)).head<2>();
  std::vector<uint8_t> fp;
  const ElevationMap v = render_placed_top_view(m, T, center, tv, &fp);
  const int g = static_cast<int>(std::ceil(margin / map.cell_m));
  const int dc0 = static_cast<int>(std::lround((v.origin_xy.x() - map.origin_xy.x()) / map.cell_m));
  const int dr0 = static_cast<int>(std::lround((map.origin_xy.y() - v.origin_xy.y()) / map.cell_m));
  for (int r = 0; r < v.rows; ++r) {
    for (int c = 0; c < v.cols; ++c) {
      if (!fp[v.index(r, c)]) continue;
      for (int dr = -g; dr <= g; ++dr) {
        for (int dc = -g; dc <= g; ++dc) {
          const int rr = r + dr0 + dr, cc = c + dc0 + dc;
          if (rr < 0 || cc < 0 || rr >= map.rows || cc >= map.cols) continue;
          mask[map.index(rr, cc)] = 1;
        }
      }
    }
  }
}

}  // namespace sonar3d
