// Memory of a carving run, estimated before the map is allocated (issue 29 item 5): from the
// sonar's footprint, the poses, the region and the voxel size.
//
// The map is an OpenVDB tree whose free space collapses into tiles (carve.hpp), so what it
// stores densely is where the map is not uniform: the boundary of the observed volume (known /
// unknown voxels) and the candidate surfaces. The boundary is computed here on a coarse grid of
// the observed volume (the union of the frames' footprints, inside the region), from which
//   leaves        = boundary faces × (cell / leaf edge)²   (8³-voxel blocks cut by the boundary)
//   lower nodes   = volume / (128 v)³ + boundary faces × (cell / 128 v)²
//   upper nodes   = the same with 4096 v
// each at the byte size OpenVDB gives its node type. The candidates add to it (the surfaces the
// frames will show are not known before reading them): on the README tour's scene at 1 cm the
// boundary is 0.6 of the measured map (docs/carving.md, "Memory").
#include <openvdb/openvdb.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "carve_footprint.hpp"
#include "sonar3d/core/memory.hpp"
#include "sonar3d/recon/carve.hpp"
#include "sonar3d/recon/visibility.hpp"

namespace sonar3d {

namespace {

using TreeT = openvdb::FloatTree;
using LeafT = TreeT::LeafNodeType;
using Node1 = TreeT::RootNodeType::ChildNodeType::ChildNodeType;  // 128³ voxels
using Node2 = TreeT::RootNodeType::ChildNodeType;                 // 4096³ voxels
using SpanLeafT = openvdb::Int32Tree::LeafNodeType;

// The observed volume on a coarse grid: cells whose centre lies in some frame's footprint.
struct Coverage {
  double cell = 0;
  double inside_cells = 0;  // volume / cell³
  double faces = 0;         // faces between an inside cell and an outside one (or the grid edge)
};

Coverage observed_volume(const SonarSpec& spec, const std::vector<Eigen::Isometry3d>& poses,
                         const std::optional<Eigen::AlignedBox3d>& region) {
  Coverage cov;
  const detail::SonarGeometry g(spec);
  Eigen::AlignedBox3d all;
  std::vector<Eigen::AlignedBox3d> boxes;
  for (const auto& T : poses) {
    boxes.push_back(detail::footprint_bounds_world(g, T));
    all.extend(boxes.back());
  }
  if (region) all = all.intersection(*region);
  if (all.isEmpty()) return cov;
  // About 2^18 cells over the box; the frames whose poses differ by less than half a cell (in
  // position, and at r_max in attitude) from one already marked mark the same cells.
  const Eigen::Vector3d ext = all.sizes();
  const double cell = std::max(std::cbrt(ext.prod() / 262144.0), 1e-6);
  cov.cell = cell;
  Eigen::Vector3i n;
  for (int a = 0; a < 3; ++a) n[a] = std::max(1, static_cast<int>(std::ceil(ext[a] / cell)));
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (!kept.empty()) {
      const auto& a = poses[kept.back()];
      const auto& b = poses[i];
      const double dp = (a.translation() - b.translation()).norm();
      const double da = Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
      if (dp + g.r_max * da < 0.5 * cell) continue;
    }
    kept.push_back(i);
  }
  const auto nx = static_cast<std::size_t>(n.x()), ny = static_cast<std::size_t>(n.y()),
             nz = static_cast<std::size_t>(n.z());
  std::vector<std::uint8_t> in(nx * ny * nz, 0);
  auto centre = [&](std::size_t x, std::size_t y, std::size_t z) {
    return Eigen::Vector3d(all.min().x() + (x + 0.5) * cell, all.min().y() + (y + 0.5) * cell,
                           all.min().z() + (z + 0.5) * cell);
  };
  // One task per z slice: every frame whose box reaches it marks its cells (no shared writes).
  tbb::parallel_for(std::size_t(0), nz, [&](std::size_t z) {
    for (std::size_t k : kept) {
      const Eigen::AlignedBox3d& b = boxes[k];
      const double zc = all.min().z() + (z + 0.5) * cell;
      if (zc < b.min().z() || zc > b.max().z()) continue;
      auto lo = [&](int a) {
        return static_cast<std::size_t>(
            std::clamp(std::floor((b.min()[a] - all.min()[a]) / cell), 0.0, double(n[a] - 1)));
      };
      auto hi = [&](int a) {
        return static_cast<std::size_t>(
            std::clamp(std::ceil((b.max()[a] - all.min()[a]) / cell), 0.0, double(n[a] - 1)));
      };
      const Eigen::Isometry3d T_sonar_world = poses[k].inverse();
      for (std::size_t y = lo(1); y <= hi(1); ++y) {
        for (std::size_t x = lo(0); x <= hi(0); ++x) {
          std::uint8_t& c = in[(z * ny + y) * nx + x];
          if (c) continue;
          const Eigen::Vector3d p = T_sonar_world * centre(x, y, z);
          const double r = p.norm();
          if (r < g.r_min || r >= g.r_max) continue;
          const double phi = std::atan2(p.y(), p.x());
          if (phi < g.fov_min || phi > g.fov_max) continue;
          if (std::abs(p.z()) > r * g.sin_theta3) continue;
          c = 1;
        }
      }
    }
  });
  double inside = 0, faces = 0;
  auto at = [&](long x, long y, long z) -> bool {
    if (x < 0 || y < 0 || z < 0 || x >= n.x() || y >= n.y() || z >= n.z()) return false;
    return in[(static_cast<std::size_t>(z) * ny + static_cast<std::size_t>(y)) * nx +
              static_cast<std::size_t>(x)];
  };
  for (long z = 0; z < n.z(); ++z)
    for (long y = 0; y < n.y(); ++y)
      for (long x = 0; x < n.x(); ++x) {
        if (!at(x, y, z)) continue;
        inside += 1;
        faces += !at(x - 1, y, z) + !at(x + 1, y, z) + !at(x, y - 1, z) + !at(x, y + 1, z) +
                 !at(x, y, z - 1) + !at(x, y, z + 1);
      }
  cov.inside_cells = inside;
  cov.faces = faces;
  return cov;
}

// Bytes of the map's nodes for a voxel edge `v` over the observed volume `cov`.
struct MapBytes {
  double leaves = 0, bytes = 0;
};
MapBytes map_bytes(const Coverage& cov, double v) {
  const double c = cov.cell;
  const double volume = cov.inside_cells * c * c * c, area = cov.faces * c * c;
  auto blocks = [&](double edge) {  // blocks of this edge holding the volume or cut by its boundary
    return std::ceil(volume / (edge * edge * edge) + area / (edge * edge));
  };
  const double leaf_edge = LeafT::DIM * v;
  MapBytes m;
  m.leaves = std::ceil(area / (leaf_edge * leaf_edge));
  const double leaf_bytes = sizeof(LeafT) + LeafT::SIZE * sizeof(float);
  m.bytes = m.leaves * leaf_bytes + blocks(Node1::DIM * v) * sizeof(Node1) +
            blocks(Node2::DIM * v) * sizeof(Node2);
  return m;
}

std::string fmt_count(double n) {
  char buf[32];
  if (n >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.1f M", n / 1e6);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f", n);
  }
  return buf;
}

}  // namespace

std::string implausible_voxel_size(const SonarSpec& spec, double voxel_size,
                                   const std::optional<Eigen::AlignedBox3d>& region,
                                   const std::string& flag) {
  const double beam = spec.r_max * (spec.fov_max() - spec.fov_min()) / std::max(1, spec.beams());
  const double cell = std::max(spec.range_resolution(), beam);
  char buf[400];
  if (voxel_size > 10 * cell) {
    std::snprintf(buf, sizeof buf,
                  "%s %.4g m is %.0f times the sonar's resolution cell (%.3g m: range bin %.3g m, "
                  "beam width %.3g m at %.3g m): structures shrink to a voxel or two; is it in "
                  "centimetres? (%s %.4g is %.4g cm)",
                  flag.c_str(), voxel_size, voxel_size / cell, cell, spec.range_resolution(), beam,
                  spec.r_max, flag.c_str(), voxel_size / 100, voxel_size);
    return buf;
  }
  if (region) {
    const double smallest = region->sizes().minCoeff();
    if (voxel_size > 0.25 * smallest) {
      std::snprintf(buf, sizeof buf,
                    "%s %.4g m is more than a quarter of the region's smallest extent (%.3g m): "
                    "the region holds %.0f voxel(s) across; is it in centimetres? (%s %.4g is "
                    "%.4g cm)",
                    flag.c_str(), voxel_size, smallest, std::floor(smallest / voxel_size),
                    flag.c_str(), voxel_size / 100, voxel_size);
      return buf;
    }
  }
  return "";
}

Eigen::AlignedBox3d footprint_bounds(const SonarSpec& spec,
                                     const std::vector<Eigen::Isometry3d>& poses,
                                     const std::optional<Eigen::AlignedBox3d>& region) {
  const detail::SonarGeometry g(spec);
  Eigen::AlignedBox3d all;
  for (const auto& T : poses) all.extend(detail::footprint_bounds_world(g, T));
  if (region) all = all.intersection(*region);
  return all;
}

MemoryEstimate estimate_carve_memory(const SonarSpec& spec,
                                     const std::vector<Eigen::Isometry3d>& poses,
                                     const CarveConfig& config, double limit_bytes) {
  MemoryEstimate e;
  const Coverage cov = observed_volume(spec, poses, config.region);
  const double v = config.voxel_size;
  const MapBytes m = map_bytes(cov, v);
  char what[200];
  std::snprintf(what, sizeof what,
                "carving map at %.3g m: %s leaves of 8³ voxels on the %.3g m² boundary of the "
                "%.3g m³ observed%s",
                v, fmt_count(m.leaves).c_str(), cov.faces * cov.cell * cov.cell,
                cov.inside_cells * cov.cell * cov.cell * cov.cell,
                config.region ? " inside the region" : " volume");
  e.add(what, m.bytes, config.region ? "--voxel-size, --roi" : "--voxel-size");
  // Per-frame return summaries (visibility.hpp), kept for occlusion resolution.
  const double words = std::ceil(spec.range_bins / 64.0);
  const double per_frame = sizeof(FrameReturns) + spec.beams() * (2.0 * sizeof(int) + 8.0 * words);
  e.add("frame summaries of " + std::to_string(poses.size()) + " frames",
        per_frame * static_cast<double>(poses.size()));
  if (limit_bytes > 0 && e.total() > limit_bytes && cov.faces > 0) {
    // The smallest voxel edge that fits (the map shrinks as the voxel grows).
    double lo = v, hi = v;
    auto total_at = [&](double vv) { return map_bytes(cov, vv).bytes + e.parts.back().bytes; };
    while (total_at(hi) > limit_bytes && hi < 1e3) hi *= 2;
    if (total_at(hi) <= limit_bytes) {
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        (total_at(mid) > limit_bytes ? lo : hi) = mid;
      }
      char buf[80];
      std::snprintf(buf, sizeof buf, "--voxel-size %.2g fits", hi * 1.05);
      e.advice = buf;
    }
  }
  return e;
}

}  // namespace sonar3d
