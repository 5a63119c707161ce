// core: the nearest-neighbour index (core/point_index.hpp) against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/point_index.hpp"
#include "test_support.hpp"

using namespace sonar3d;
using sonar3d::test::expect_error;

namespace {

template <class S>
using P = Eigen::Matrix<S, 3, 1>;

// A random cloud in a 2 m cube, with every tenth point repeated (duplicates) and some points on
// a coarse lattice (equal distances).
template <class S>
std::vector<P<S>> random_cloud(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<P<S>> pts;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 10 == 9) {
      pts.push_back(pts[i / 2]);
    } else if (i % 7 == 6) {
      pts.push_back(P<S>(S(0.25) * std::round(S(4) * S(u(rng))),
                         S(0.25) * std::round(S(4) * S(u(rng))),
                         S(0.25) * std::round(S(4) * S(u(rng)))));
    } else {
      pts.push_back(P<S>(S(u(rng)), S(u(rng)), S(u(rng))));
    }
  }
  return pts;
}

// The squared distance as the index computes it: ((dx² + dy²) + dz²) in S (Eigen's squaredNorm may
// add in another order and differ in the last bit).
template <class S>
S dist2(const P<S>& a, const P<S>& b) {
  S d = 0;
  for (int k = 0; k < 3; ++k) d += (a[k] - b[k]) * (a[k] - b[k]);
  return d;
}

template <class S>
S brute_nearest(const std::vector<P<S>>& pts, const P<S>& q) {
  S best = std::numeric_limits<S>::infinity();
  for (const auto& p : pts) best = std::min(best, dist2(p, q));
  return best;
}

template <class S>
std::vector<std::size_t> brute_within(const std::vector<P<S>>& pts, const P<S>& q, S r) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (dist2(pts[i], q) <= r * r) out.push_back(i);
  }
  return out;
}

template <class S>
void check_against_brute_force(std::size_t n, std::uint64_t seed) {
  const std::vector<P<S>> pts = random_cloud<S>(n, seed);
  const BasicPointIndex<S> owned(pts);
  const auto borrowed = BasicPointIndex<S>::borrow(pts);
  ASSERT_EQ(owned.size(), n);
  ASSERT_EQ(&borrowed.points(), &pts);  // read in place, not copied
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> u(-1.2, 1.2), rad(0.0, 0.4);
  for (int k = 0; k < 300; ++k) {
    // Queries in the cloud's box, on cloud points (distance 0) and on lattice nodes.
    P<S> q(S(u(rng)), S(u(rng)), S(u(rng)));
    if (k % 5 == 1) q = pts[static_cast<std::size_t>(k) % n];
    if (k % 5 == 2) q = P<S>(S(0.25), S(-0.5), S(0.75));
    const S r = S(rad(rng));
    for (const BasicPointIndex<S>* index : {&owned, &borrowed}) {
      S d2 = -1;
      const std::size_t i = index->nearest(q, &d2);
      const S best = brute_nearest(pts, q);
      EXPECT_EQ(d2, best);
      EXPECT_EQ(dist2(pts[i], q), best);

      std::size_t j = n;
      S dw = -1;
      const bool found = index->nearest_within(q, r * r, &j, &dw);
      EXPECT_EQ(found, best <= r * r);
      if (found) {
        EXPECT_EQ(dw, best);
        EXPECT_EQ(dist2(pts[j], q), best);
      } else {
        EXPECT_TRUE(std::isinf(dw));
      }

      std::vector<std::size_t> got = index->within(q, r);
      std::sort(got.begin(), got.end());
      const std::vector<std::size_t> want = brute_within(pts, q, r);
      EXPECT_EQ(got, want);
      EXPECT_EQ(index->any_within(q, r), !want.empty());

      Eigen::AlignedBox<S, 3> box(q.array() - r, q.array() + S(0.5) * r);
      std::vector<std::size_t> in = index->in_box(box);
      std::sort(in.begin(), in.end());
      std::vector<std::size_t> want_box;
      for (std::size_t m = 0; m < n; ++m) {
        if (box.contains(pts[m])) want_box.push_back(m);
      }
      EXPECT_EQ(in, want_box);
    }
  }
}

}  // namespace

TEST(PointIndex, FloatMatchesBruteForce) { check_against_brute_force<float>(2000, 7); }
TEST(PointIndex, DoubleMatchesBruteForce) { check_against_brute_force<double>(2000, 8); }
TEST(PointIndex, SmallCloudsMatchBruteForce) {
  // Fewer points than a leaf holds, and exactly one leaf.
  for (std::size_t n : {1, 2, 3, 16, 17}) check_against_brute_force<double>(n, 100 + n);
}

TEST(PointIndex, EmptyCloudFindsNothing) {
  const PointIndex3f index(std::vector<Eigen::Vector3f>{});
  EXPECT_TRUE(index.empty());
  std::size_t i = 7;
  float d2 = 0;
  EXPECT_FALSE(index.nearest_within(Eigen::Vector3f::Zero(), 1e9f, &i, &d2));
  EXPECT_TRUE(std::isinf(d2));
  EXPECT_EQ(i, 7u);
  EXPECT_FALSE(index.any_within(Eigen::Vector3f::Zero(), 1e9f));
  EXPECT_TRUE(index.within(Eigen::Vector3f::Zero(), 1e9f).empty());
  EXPECT_TRUE(index
                  .in_box(Eigen::AlignedBox3f(Eigen::Vector3f::Constant(-1e9f),
                                              Eigen::Vector3f::Constant(1e9f)))
                  .empty());
  expect_error([&] { index.nearest(Eigen::Vector3f::Zero()); }, "empty cloud");
}

TEST(PointIndex, BoundsAreInclusive) {
  // Points exactly at the bound are found; bound 0 finds the point itself and nothing else.
  const PointIndex3d index(std::vector<Eigen::Vector3d>{{0, 0, 0}, {1, 0, 0}, {0, 2, 0}});
  std::size_t i = 9;
  double d2 = -1;
  EXPECT_TRUE(index.nearest_within(Eigen::Vector3d(1, 0, 0), 0.0, &i, &d2));
  EXPECT_EQ(i, 1u);
  EXPECT_EQ(d2, 0.0);
  EXPECT_FALSE(index.nearest_within(Eigen::Vector3d(1, 0, 1e-9), 0.0, &i, &d2));
  EXPECT_TRUE(index.nearest_within(Eigen::Vector3d(0, 1, 0), 1.0, &i, &d2));
  EXPECT_EQ(d2, 1.0);
  EXPECT_TRUE(index.any_within(Eigen::Vector3d(0, 0, 0), 0.0));
  EXPECT_TRUE(index.any_within(Eigen::Vector3d(2, 0, 0), 1.0));
  EXPECT_FALSE(index.any_within(Eigen::Vector3d(2, 0, 0), 0.999));
  auto w = index.within(Eigen::Vector3d(0, 0, 0), 1.0);
  std::sort(w.begin(), w.end());
  EXPECT_EQ(w, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(index.within(Eigen::Vector3d(0, 2, 0), 0.0), (std::vector<std::size_t>{2}));
  auto b = index.in_box(Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 0)));
  std::sort(b.begin(), b.end());
  EXPECT_EQ(b, (std::vector<std::size_t>{0, 1, 2}));
}

TEST(PointIndex, DuplicatesAreAllReturned) {
  // Ten copies of one point: every copy is within 0 of it, the nearest is one of them.
  std::vector<Eigen::Vector3f> pts(10, Eigen::Vector3f(0.5f, -0.25f, 3.0f));
  pts.emplace_back(0, 0, 0);
  const PointIndex3f index(pts);
  EXPECT_EQ(index.within(pts[0], 0.0f).size(), 10u);
  float d2 = -1;
  EXPECT_LT(index.nearest(pts[0], &d2), 10u);
  EXPECT_EQ(d2, 0.0f);
}

TEST(PointIndex, MovedIndexKeepsAnswering) {
  std::vector<Eigen::Vector3d> pts = random_cloud<double>(500, 3);
  PointIndex3d a(pts);
  PointIndex3d b(std::move(a));
  const Eigen::Vector3d q(0.1, 0.2, 0.3);
  double d2 = 0;
  b.nearest(q, &d2);
  EXPECT_EQ(d2, brute_nearest(pts, q));
}
