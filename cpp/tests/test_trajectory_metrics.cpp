// The header-only helpers behind the Python evaluation and mesh readers: timestamp
// association against brute force, RPE pair selection against its definition, OFF/OBJ/STL
// parsing of hand-written files with known content.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <set>
#include <string>

#include "scanalign/evaluation/associate.hpp"
#include "scanalign/evaluation/rpe_pairs.hpp"
#include "scanalign/io/mesh_text.hpp"

namespace {

using Pairs = std::vector<std::pair<std::int64_t, std::int64_t>>;

// The rule spelled out the slow way: repeatedly take the closest free pair within the bound.
Pairs bruteForceAssociation(const std::vector<double>& a, const std::vector<double>& b, double max_dt) {
  std::set<std::int64_t> used_a, used_b;
  Pairs out;
  for (;;) {
    double best = max_dt;
    std::int64_t bi = -1, bj = -1;
    for (std::size_t i = 0; i < a.size(); ++i)
      for (std::size_t j = 0; j < b.size(); ++j) {
        const double d = std::abs(a[i] - b[j]);
        if (used_a.count(i) || used_b.count(j) || d > max_dt) continue;
        if (bi < 0 || d < best) best = d, bi = static_cast<std::int64_t>(i), bj = static_cast<std::int64_t>(j);
      }
    if (bi < 0) break;
    used_a.insert(bi), used_b.insert(bj);
    out.emplace_back(bi, bj);
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(AssociateTimestamps, EqualsTheGreedyRuleIncludingTheBoundItself) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<double> a, b;
    for (int k = 0; k < 40; ++k) a.push_back(0.1 * k + jitter(rng));
    for (int k = 0; k < 35; ++k) b.push_back(0.113 * k + jitter(rng));
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(scanalign::associateTimestamps(a, b, 0.02), bruteForceAssociation(a, b, 0.02)) << "trial " << trial;
  }
  // |dt| == max_difference is a pair (the inclusive bound); just above it is not.
  EXPECT_EQ(scanalign::associateTimestamps({1.0}, {1.5}, 0.5), (Pairs{{0, 0}}));
  EXPECT_TRUE(scanalign::associateTimestamps({1.0}, {1.5000001}, 0.5).empty());
  EXPECT_THROW(scanalign::associateTimestamps({2.0, 1.0}, {1.0}, 0.1), std::invalid_argument);  // unsorted
  EXPECT_THROW(scanalign::associateTimestamps({1.0}, {1.0}, -1.0), std::invalid_argument);
}

TEST(RelativePosePairs, ConsecutiveChainAndClosestSpacing) {
  const std::vector<double> s{0, 0.4, 1.0, 1.1, 2.05, 3.0, 3.2};
  // Consecutive: each next index is the first at least delta = 1 further on.
  EXPECT_EQ(scanalign::relativePosePairs(s, 1.0, false, 0.0), (Pairs{{0, 2}, {2, 4}, {4, 6}}));
  // All pairs: per i, the j whose spacing is closest to delta, kept within tol.
  const Pairs all = scanalign::relativePosePairs(s, 1.0, true, 0.06);
  for (const auto& [i, j] : all) {
    EXPECT_LE(std::abs((s[j] - s[i]) - 1.0), 0.06);
    for (std::size_t k = i + 1; k < s.size(); ++k)
      EXPECT_LE(std::abs((s[j] - s[i]) - 1.0), std::abs((s[k] - s[i]) - 1.0) + 1e-15);
  }
  EXPECT_EQ(all.front(), (std::pair<std::int64_t, std::int64_t>{0, 2}));
}

TEST(MeshText, OffObjAndStlGiveTheSameSquare) {
  // A unit square as one quad (OFF, OBJ) is fan-triangulated into (0,1,2), (0,2,3).
  const auto off = scanalign::parseOff("OFF\n# square\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  EXPECT_EQ(off.vertices.size(), 12u);
  EXPECT_EQ(off.faces, (std::vector<std::int64_t>{0, 1, 2, 0, 2, 3}));
  const auto obj = scanalign::parseObj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
  EXPECT_EQ(obj.vertices, off.vertices);
  EXPECT_EQ(obj.faces, off.faces);
  // ASCII STL: two triangles whose shared corners are merged into 4 vertices.
  const auto stl = scanalign::parseStl(
      "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n");
  EXPECT_EQ(stl.vertices.size(), 12u);
  EXPECT_EQ(stl.faces.size(), 6u);
  EXPECT_THROW(scanalign::parseOff("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 9\n"), std::invalid_argument);
  EXPECT_THROW(scanalign::parseOff("OFF\n4 1 0\n0 0 0\n"), std::invalid_argument);  // truncated
}

}  // namespace
