// The bucket k-d tree against brute force: cold searches, and bottom-up searches from
// hints that are exact, near, far or unrelated, on volumes, surfaces and duplicates.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "scanalign/registration/bucket_kdtree.hpp"

using scanalign::BucketKdTree;
using scanalign::CloudView;
using scanalign::NearestNeighbor;

namespace {

template <typename S>
S bruteNearest(const std::vector<S>& pts, const S* q, S max_d2) {
  S best = max_d2;
  bool found = false;
  for (std::size_t i = 0; i < pts.size() / 3; ++i) {
    const S dx = pts[3 * i] - q[0], dy = pts[3 * i + 1] - q[1], dz = pts[3 * i + 2] - q[2];
    const S d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < best) best = d2, found = true;
  }
  return found ? best : std::numeric_limits<S>::infinity();
}

template <typename S>
std::vector<S> uniform(std::size_t n, std::uint32_t seed, S lo, S hi) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<S> u(lo, hi);
  std::vector<S> v(3 * n);
  for (auto& x : v) x = u(rng);
  return v;
}

// A wavy sheet sampled on a 1 mm grid with 0.2 mm noise: points on a surface, as a scan.
template <typename S>
std::vector<S> sheet(int side, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<S> noise(0, S(2e-4));
  std::vector<S> v;
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const S x = S(1e-3) * i, y = S(1e-3) * j;
      v.insert(v.end(), {x + noise(rng), y + noise(rng), S(0.01) * std::sin(S(40) * x) * std::cos(S(30) * y) + S(0.5)});
    }
  return v;
}

// Checks every query cold and with several hints; hints are tree positions.
template <typename S>
void expectExact(const std::vector<S>& pts, const std::vector<S>& queries, S max_d2, int leaf_size) {
  const BucketKdTree<S> tree(CloudView<S>(pts.data(), pts.size() / 3), leaf_size);
  ASSERT_EQ(tree.size(), pts.size() / 3);
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> any(0, static_cast<std::uint32_t>(tree.size() - 1));
  std::uint32_t previous = NearestNeighbor<S>::kNone;
  for (std::size_t k = 0; k < queries.size() / 3; ++k) {
    const S* q = &queries[3 * k];
    const S expect = bruteNearest(pts, q, max_d2);
    const auto cold = tree.nearest(q, max_d2);
    const std::uint32_t hints[] = {NearestNeighbor<S>::kNone, cold.node, any(rng), previous, 0u,
                                   static_cast<std::uint32_t>(tree.size() - 1), 1u << 31};
    for (std::uint32_t hint : hints) {
      const auto nn = tree.nearest(q, max_d2, hint);
      if (std::isinf(expect)) {
        ASSERT_FALSE(nn.found()) << "query " << k << " hint " << hint;
        ASSERT_TRUE(std::isinf(nn.squared_distance));
      } else {
        ASSERT_TRUE(nn.found()) << "query " << k << " hint " << hint;
        ASSERT_EQ(nn.squared_distance, expect) << "query " << k << " hint " << hint;
        // The reported point is at that distance and maps back to the input cloud.
        const std::uint32_t i = tree.index(nn.node);
        ASSERT_EQ(tree.squaredDistance(q, nn.node), expect);
        ASSERT_EQ(tree.x(nn.node), pts[3 * i]);
      }
    }
    previous = cold.found() ? cold.node : previous;
  }
}

}  // namespace

TEST(BucketKdTree, UniformVolumeAllLeafSizes) {
  const auto pts = uniform<float>(5000, 1, -1.f, 1.f);
  const auto queries = uniform<float>(600, 2, -1.2f, 1.2f);
  for (int leaf : {1, 2, 8, 32, 64}) {
    SCOPED_TRACE(leaf);
    expectExact(pts, queries, std::numeric_limits<float>::infinity(), leaf);
    expectExact(pts, queries, 0.01f, leaf);  // many queries have no neighbour in range
  }
}

TEST(BucketKdTree, ScanLikeSurfaceWithQueriesOffTheSurface) {
  // Queries 0-2 mm off a noisy 1 mm sheet, as ICP sources near a model: the bottom-up
  // search from hints is exercised where cells are thin.
  const auto pts = sheet<float>(120, 3);
  std::vector<float> queries;
  std::mt19937 rng(4);
  std::normal_distribution<float> off(0.f, 1e-3f);
  for (std::size_t i = 0; i < pts.size() / 3; i += 7)
    queries.insert(queries.end(), {pts[3 * i] + off(rng), pts[3 * i + 1] + off(rng), pts[3 * i + 2] + off(rng)});
  for (int leaf : {4, 8, 32}) {
    SCOPED_TRACE(leaf);
    expectExact(pts, queries, 4e-4f, leaf);
  }
}

TEST(BucketKdTree, DoublePrecisionAndDuplicates) {
  auto pts = uniform<double>(2000, 5, 0.0, 1.0);
  const std::vector<double> copy(pts.begin(), pts.begin() + 600);  // 200 exact duplicates
  pts.insert(pts.end(), copy.begin(), copy.end());
  for (int i = 0; i < 100; ++i) pts.insert(pts.end(), {0.5, 0.5, 0.5});  // a pile on one spot
  auto queries = uniform<double>(400, 6, -0.1, 1.1);
  queries.insert(queries.end(), {0.5, 0.5, 0.5, 0.5, 0.5, 0.5 + 1e-9});
  expectExact(pts, queries, std::numeric_limits<double>::infinity(), 8);
  expectExact(pts, queries, 1e-3, 8);
}

TEST(BucketKdTree, LatticeWithTiedCoordinates) {
  // A 1 mm lattice (as a voxel-gridded model): thousands of points share each coordinate
  // value, so the median selection meets its pivot value many times over.
  std::vector<float> pts;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 30; ++j)
      for (int k = 0; k < 12; ++k) pts.insert(pts.end(), {0.001f * float(i), 0.001f * float(j), 0.001f * float(k)});
  for (int i = 0; i < 300; ++i) pts.insert(pts.end(), {0.02f, 0.015f, 0.006f});  // and a pile
  const auto queries = uniform<float>(800, 9, -0.002f, 0.042f);
  for (int leaf : {1, 8, 32, 64}) {
    SCOPED_TRACE(leaf);
    expectExact(pts, queries, std::numeric_limits<float>::infinity(), leaf);
    expectExact(pts, queries, 1e-6f, leaf);
  }
}

TEST(BucketKdTree, SkipsNonFiniteAndKeepsIndices) {
  std::vector<float> pts = {0, 0, 0, NAN, 1, 1, 1, 1, 1, INFINITY, 0, 0, 2, 2, 2};
  BucketKdTree<float> tree(CloudView<float>(pts.data(), 5), 1);
  ASSERT_EQ(tree.size(), 3u);
  const float q[3] = {1.9f, 2.1f, 2.f};
  const auto nn = tree.nearest(q, 100.f);
  ASSERT_TRUE(nn.found());
  EXPECT_EQ(tree.index(nn.node), 4u);
  BucketKdTree<float> empty(CloudView<float>(pts.data(), 0));
  EXPECT_TRUE(empty.empty());
  EXPECT_FALSE(empty.nearest(q, 100.f).found());
  EXPECT_THROW(BucketKdTree<float>(CloudView<float>(pts.data(), 5), 0), std::invalid_argument);
  EXPECT_THROW(BucketKdTree<float>(CloudView<float>(pts.data(), 5), 65), std::invalid_argument);
}

TEST(BucketKdTree, HeightIsLogarithmic) {
  const auto pts = uniform<float>(100000, 8, 0.f, 1.f);
  BucketKdTree<float> tree(CloudView<float>(pts.data(), pts.size() / 3), 8);
  // Median splits: ceil(log2(100000 / 8)) = 14 levels below the root.
  EXPECT_EQ(tree.height(), 14);
  EXPECT_LT(tree.memoryBytes(), 60u * 100000u);
}
