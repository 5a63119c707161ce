// The library's nearest-neighbour index (include/sonar3d/core/point_index.hpp): a nanoflann
// KD-tree (Debian's libnanoflann-dev 1.4, header only), leaves of at most 16 points.
#include "sonar3d/core/point_index.hpp"

#include <cmath>
#include <limits>
#include <nanoflann.hpp>
#include <utility>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {

// nanoflann's view of the points (owned by the index or borrowed from the caller).
template <class S>
struct Cloud {
  const std::vector<Eigen::Matrix<S, 3, 1>>* pts = nullptr;
  std::size_t kdtree_get_point_count() const { return pts->size(); }
  S kdtree_get_pt(std::size_t i, std::size_t d) const { return (*pts)[i][static_cast<int>(d)]; }
  template <class BBOX>
  bool kdtree_get_bbox(BBOX&) const {
    return false;
  }
};

// nanoflann 1.4's default index type (unsigned): the tree, its splits and so the order of equal
// distances are those the recognition's ICP was measured with.
template <class S>
using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<S, Cloud<S>>, Cloud<S>, 3>;

// The smallest bound b with `d < b` ⇔ `d ≤ d2`: nanoflann keeps a point when its distance is
// strictly below the result set's worst distance, the index's queries include the bound.
template <class S>
S inclusive(S d2) {
  return std::nextafter(d2, std::numeric_limits<S>::infinity());
}

// A result set that stops the search at the first point within the bound.
template <class S>
struct AnyResult {
  S bound;
  bool found = false;
  S worstDist() const { return bound; }
  bool full() const { return found; }
  std::size_t size() const { return found ? 1 : 0; }
  bool addPoint(S, unsigned) {
    found = true;
    return false;
  }
};

}  // namespace

template <class S>
struct BasicPointIndex<S>::Impl {
  std::vector<Point> owned;
  Cloud<S> cloud;
  std::unique_ptr<Tree<S>> tree;

  void build() {
    tree = std::make_unique<Tree<S>>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree->buildIndex();
  }

  // The points of the subtree under `node` inside [lo, hi], appended in the tree's order. A
  // node's first child holds the points with coordinate ≤ divlow along divfeat, its second those
  // with coordinate ≥ divhigh.
  template <class Node>
  void box(const Node* node, const Point& lo, const Point& hi,
           std::vector<std::size_t>& out) const {
    if (node->child1 == nullptr && node->child2 == nullptr) {
      for (auto i = node->node_type.lr.left; i < node->node_type.lr.right; ++i) {
        const std::size_t k = tree->vAcc[i];
        const Point& p = (*cloud.pts)[k];
        if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) out.push_back(k);
      }
      return;
    }
    const int f = node->node_type.sub.divfeat;
    if (lo[f] <= node->node_type.sub.divlow) box(node->child1, lo, hi, out);
    if (hi[f] >= node->node_type.sub.divhigh) box(node->child2, lo, hi, out);
  }
};

template <class S>
BasicPointIndex<S>::BasicPointIndex(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {
  impl_->build();
}

template <class S>
BasicPointIndex<S>::BasicPointIndex(std::vector<Point> points) : impl_(std::make_unique<Impl>()) {
  impl_->owned = std::move(points);
  impl_->cloud.pts = &impl_->owned;
  impl_->build();
}

template <class S>
BasicPointIndex<S> BasicPointIndex<S>::borrow(const std::vector<Point>& points) {
  auto impl = std::make_unique<Impl>();
  impl->cloud.pts = &points;
  return BasicPointIndex(std::move(impl));
}

template <class S>
BasicPointIndex<S>::~BasicPointIndex() = default;
template <class S>
BasicPointIndex<S>::BasicPointIndex(BasicPointIndex&&) noexcept = default;
template <class S>
BasicPointIndex<S>& BasicPointIndex<S>::operator=(BasicPointIndex&&) noexcept = default;

template <class S>
const std::vector<typename BasicPointIndex<S>::Point>& BasicPointIndex<S>::points() const {
  return *impl_->cloud.pts;
}

template <class S>
std::size_t BasicPointIndex<S>::nearest(const Point& p, S* dist2) const {
  require(!empty(), "point index: nearest point asked of an empty cloud");
  unsigned idx = 0;
  S d2 = 0;
  impl_->tree->knnSearch(p.data(), 1, &idx, &d2);
  if (dist2) *dist2 = d2;
  return idx;
}

template <class S>
bool BasicPointIndex<S>::nearest_within(const Point& p, S max_dist2, std::size_t* index,
                                        S* dist2) const {
  unsigned idx = 0;
  S d2 = 0;
  nanoflann::KNNResultSet<S, unsigned> result(1);
  result.init(&idx, &d2);
  d2 = inclusive(max_dist2);  // the worst distance kept: a point at exactly the bound is found
  if (!empty()) impl_->tree->findNeighbors(result, p.data(), nanoflann::SearchParams());
  if (result.size() == 0) {
    if (dist2) *dist2 = std::numeric_limits<S>::infinity();
    return false;
  }
  if (index) *index = idx;
  if (dist2) *dist2 = d2;
  return true;
}

template <class S>
bool BasicPointIndex<S>::any_within(const Point& p, S radius) const {
  if (empty()) return false;
  AnyResult<S> result{inclusive(radius * radius)};
  impl_->tree->findNeighbors(result, p.data(), nanoflann::SearchParams());
  return result.found;
}

template <class S>
std::vector<std::size_t> BasicPointIndex<S>::within(const Point& p, S radius) const {
  if (empty()) return {};
  std::vector<std::pair<unsigned, S>> found;
  impl_->tree->radiusSearch(p.data(), inclusive(radius * radius), found,
                            nanoflann::SearchParams(32, 0, false));
  std::vector<std::size_t> out(found.size());
  for (std::size_t i = 0; i < found.size(); ++i) out[i] = found[i].first;
  return out;
}

template <class S>
std::vector<std::size_t> BasicPointIndex<S>::in_box(const Eigen::AlignedBox<S, 3>& box) const {
  std::vector<std::size_t> out;
  if (empty() || box.isEmpty()) return out;
  impl_->box(impl_->tree->root_node, box.min(), box.max(), out);
  return out;
}

template class BasicPointIndex<float>;
template class BasicPointIndex<double>;

}  // namespace sonar3d
