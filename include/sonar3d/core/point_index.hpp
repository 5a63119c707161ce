#pragma once
// The nearest-neighbour index of the library (issue 24, item 3): one KD-tree over 3D points for
// every module that asks "which point is nearest?", "is any point within r?", "which points are
// within r?" or "which points are in this box?" — the evaluation's coverage (thesis sec.
// 4.5.2.1 (b)), the multipass deconvolution's normals (sec. 5.6.7.1), the recognition's ICP and
// neighbourhoods (sec. 6.3.2.5). The tree is nanoflann's (Debian's libnanoflann-dev, header only),
// kept private to src/core/point_index.cpp: this header exposes Eigen and std only.
//
// Points are float (`PointIndex3f`) or double (`PointIndex3d`); squared distances are computed in
// the index's scalar as ((dx² + dy²) + dz²). The index either owns its points (constructed from a
// vector, moved in to avoid a copy) or borrows a vector the caller keeps alive and unchanged
// (`borrow`), so a large cloud already in memory is not copied again. Built once, then read-only:
// queries may run from any number of threads at once.
#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <vector>

namespace sonar3d {

template <class S>
class BasicPointIndex {
 public:
  using Scalar = S;
  using Point = Eigen::Matrix<S, 3, 1>;

  // Owns `points` (empty allowed: every query then finds nothing; nearest() throws).
  explicit BasicPointIndex(std::vector<Point> points);
  // Reads `points` in place; they must outlive the index and not change.
  static BasicPointIndex borrow(const std::vector<Point>& points);
  ~BasicPointIndex();
  BasicPointIndex(BasicPointIndex&&) noexcept;
  BasicPointIndex& operator=(BasicPointIndex&&) noexcept;
  BasicPointIndex(const BasicPointIndex&) = delete;
  BasicPointIndex& operator=(const BasicPointIndex&) = delete;

  const std::vector<Point>& points() const;
  std::size_t size() const { return points().size(); }
  bool empty() const { return points().empty(); }

  // The nearest point to p: its index, and its squared distance in *dist2 (when given). Of points
  // at the same distance, one is returned (the same one for the same cloud and query). Throws
  // Error on an empty index.
  std::size_t nearest(const Point& p, S* dist2 = nullptr) const;
  // The nearest point to p when it lies within sqrt(max_dist2) of p (d² ≤ max_dist2; max_dist2 =
  // 0 finds a point at p itself): true, its index and squared distance (as nearest() gives);
  // else false and *dist2 = +inf. Branches beyond the bound are not searched: a far query costs a
  // descent, not a search.
  bool nearest_within(const Point& p, S max_dist2, std::size_t* index, S* dist2) const;
  // Whether any point lies within `radius` of p (d ≤ radius); stops at the first one found.
  bool any_within(const Point& p, S radius) const;
  // Indices of the points within `radius` of p (d ≤ radius), in the tree's order (not sorted;
  // the same order for the same cloud and query).
  std::vector<std::size_t> within(const Point& p, S radius) const;
  // Indices of the points inside `box` (bounds included), in the tree's order.
  std::vector<std::size_t> in_box(const Eigen::AlignedBox<S, 3>& box) const;

 private:
  struct Impl;
  explicit BasicPointIndex(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

using PointIndex3f = BasicPointIndex<float>;
using PointIndex3d = BasicPointIndex<double>;

extern template class BasicPointIndex<float>;
extern template class BasicPointIndex<double>;

}  // namespace sonar3d
