#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <random>

#include "scanalign/registration/kdtree.hpp"

using scanalign::CloudView;
using Tree = scanalign::LeftBalancedKdTree<float>;

namespace {

// Brute-force nearest squared distance (the oracle).
float bruteNearest(const std::vector<float>& pts, const float* q, float max_d2) {
  float best = max_d2;
  bool found = false;
  for (std::size_t i = 0; i < pts.size() / 3; ++i) {
    const float d2 = scanalign::detail::squaredDistance(q, &pts[3 * i]);
    if (d2 < best) best = d2, found = true;
  }
  return found ? best : std::numeric_limits<float>::infinity();
}

void expectMatchesBruteForce(const std::vector<float>& pts, const std::vector<float>& queries, float max_d2,
                             int stack = Tree::kMaxStack) {
  Tree tree(CloudView<float>(pts.data(), pts.size() / 3));
  for (std::size_t k = 0; k < queries.size() / 3; ++k) {
    const auto nn = tree.nearest(&queries[3 * k], max_d2, stack);
    const float expect = bruteNearest(pts, &queries[3 * k], max_d2);
    ASSERT_TRUE(nn.exact);
    if (std::isinf(expect)) {
      ASSERT_FALSE(nn.found());
    } else {
      ASSERT_TRUE(nn.found());
      ASSERT_EQ(nn.squared_distance, expect);
      // The reported original index holds a point at that distance.
      const auto idx = tree.node(nn.node).index();
      ASSERT_EQ(scanalign::detail::squaredDistance(&queries[3 * k], &pts[3 * idx]), expect);
    }
  }
}

std::vector<float> uniform(std::size_t n, std::uint32_t seed, float lo = -1.f, float hi = 1.f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> v(3 * n);
  for (auto& x : v) x = u(rng);
  return v;
}

}  // namespace

TEST(LeftSubtree, MatchesCompleteTreeShape) {
  // Node counts of the left subtree of complete binary trees, checked by hand.
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(1), 0u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(2), 1u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(3), 1u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(4), 2u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(5), 3u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(6), 3u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(7), 3u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(10), 6u);
  EXPECT_EQ(scanalign::detail::leftSubtreeSize(15), 7u);
}

TEST(KdTree, IsAValidLeftBalancedKdTree) {
  const auto pts = uniform(5000, 7);
  Tree tree(CloudView<float>(pts.data(), 5000));
  ASSERT_EQ(tree.size(), 5000u);
  EXPECT_EQ(tree.height(), 12);  // floor(log2(5000))
  // Every node splits its subtree: left descendants <= split value <= right descendants.
  std::function<void(std::size_t, int, float, bool)> check = [&](std::size_t node, int axis, float v, bool left) {
    if (node >= tree.size()) return;
    const float c = tree.node(node).p[axis];
    if (left) ASSERT_LE(c, v); else ASSERT_GE(c, v);
    check(2 * node + 1, axis, v, left);
    check(2 * node + 2, axis, v, left);
  };
  std::vector<int> seen(5000, 0);
  for (std::size_t i = 0; i < tree.size(); ++i) {
    const auto& nd = tree.node(i);
    seen[nd.index()]++;
    check(2 * i + 1, nd.axis(), nd.p[nd.axis()], true);
    check(2 * i + 2, nd.axis(), nd.p[nd.axis()], false);
  }
  for (int s : seen) ASSERT_EQ(s, 1);  // a permutation of the input
}

TEST(KdTree, NearestEqualsBruteForceOnRandomClouds) {
  for (std::size_t n : {1u, 2u, 3u, 17u, 1000u, 20000u}) {
    const auto pts = uniform(n, 11 + n);
    const auto queries = uniform(500, 99, -1.5f, 1.5f);
    expectMatchesBruteForce(pts, queries, std::numeric_limits<float>::infinity());
    expectMatchesBruteForce(pts, queries, 0.01f);  // bounded search: often nothing in range
  }
}

TEST(KdTree, DegenerateClouds) {
  const auto queries = uniform(300, 5);
  // Duplicates: 2000 copies of 10 points.
  std::vector<float> dup;
  const auto base = uniform(10, 3);
  for (int r = 0; r < 200; ++r) dup.insert(dup.end(), base.begin(), base.end());
  expectMatchesBruteForce(dup, queries, std::numeric_limits<float>::infinity());
  // All points identical.
  std::vector<float> same(3 * 1000, 0.25f);
  expectMatchesBruteForce(same, queries, std::numeric_limits<float>::infinity());
  // A plane and a line.
  auto plane = uniform(3000, 8);
  for (std::size_t i = 0; i < 3000; ++i) plane[3 * i + 2] = 0.5f;
  expectMatchesBruteForce(plane, queries, std::numeric_limits<float>::infinity());
  auto line = uniform(3000, 9);
  for (std::size_t i = 0; i < 3000; ++i) line[3 * i + 1] = line[3 * i + 2] = line[3 * i];
  expectMatchesBruteForce(line, queries, std::numeric_limits<float>::infinity());
  // A single point.
  std::vector<float> one = {0.1f, 0.2f, 0.3f};
  expectMatchesBruteForce(one, queries, std::numeric_limits<float>::infinity());
}

TEST(KdTree, NonFinitePointsAreSkipped) {
  auto pts = uniform(100, 4);
  pts[3 * 5] = std::numeric_limits<float>::quiet_NaN();
  pts[3 * 9 + 2] = std::numeric_limits<float>::infinity();
  Tree tree(CloudView<float>(pts.data(), 100));
  EXPECT_EQ(tree.size(), 98u);
  for (std::size_t i = 0; i < tree.size(); ++i) {
    EXPECT_NE(tree.node(i).index(), 5u);
    EXPECT_NE(tree.node(i).index(), 9u);
  }
  Tree empty(CloudView<float>(pts.data(), 0));
  const float q[3] = {0, 0, 0};
  EXPECT_FALSE(empty.nearest(q, 1.f).found());
}

TEST(KdTree, ShallowStackReportsApproximation) {
  // With a 1-entry stack on a 12-level tree some searches must drop branches; a search
  // that says it is exact must agree with brute force, and the hint never changes answers.
  const auto pts = uniform(5000, 21);
  const auto queries = uniform(2000, 22);
  Tree tree(CloudView<float>(pts.data(), 5000));
  int approximate = 0;
  for (std::size_t k = 0; k < 2000; ++k) {
    const float* q = &queries[3 * k];
    const auto nn = tree.nearest(q, std::numeric_limits<float>::infinity(), 1);
    const float truth = bruteNearest(pts, q, std::numeric_limits<float>::infinity());
    if (nn.exact) {
      ASSERT_EQ(nn.squared_distance, truth);
    } else {
      ++approximate;
      ASSERT_GE(nn.squared_distance, truth);
    }
    const auto hinted = tree.nearest(q, std::numeric_limits<float>::infinity(), 20, static_cast<std::uint32_t>(k));
    ASSERT_EQ(hinted.squared_distance, truth);
  }
  EXPECT_GT(approximate, 0);
}

TEST(KdTree, RadiusSearchEqualsBruteForce) {
  const auto pts = uniform(4000, 31);
  Tree tree(CloudView<float>(pts.data(), 4000));
  const auto queries = uniform(50, 32);
  for (std::size_t k = 0; k < 50; ++k) {
    std::vector<std::uint32_t> got;
    tree.forEachInRadius(&queries[3 * k], 0.04f, [&](std::uint32_t node, float) { got.push_back(tree.node(node).index()); });
    std::vector<std::uint32_t> want;
    for (std::uint32_t i = 0; i < 4000; ++i)
      if (scanalign::detail::squaredDistance(&queries[3 * k], &pts[3 * i]) <= 0.04f) want.push_back(i);
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got, want);
  }
}
