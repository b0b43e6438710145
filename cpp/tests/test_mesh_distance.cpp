// Exact point-to-mesh distance (evaluation/mesh_distance.hpp) against brute force over all
// triangles with Ericson's closest-point routine written out independently, and analytic cases.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "scanalign/evaluation/mesh_distance.hpp"

using namespace scanalign;
using Eigen::Vector3d;

namespace {

/// Closest point by the barycentric case analysis of Ericson, Real-Time Collision Detection
/// (2005), §5.1.5: the reference the index is checked against (non-degenerate triangles).
Vector3d ericsonClosest(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

struct Mesh {
  std::vector<double> v;
  std::vector<std::int64_t> f;
  CloudView<double> view() const { return CloudView<double>(v.data(), v.size() / 3); }
  Vector3d vertex(std::int64_t i) const { return Vector3d(v[3 * i], v[3 * i + 1], v[3 * i + 2]); }
  std::size_t faces() const { return f.size() / 3; }
};

double bruteForce(const Mesh& m, const Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < m.faces(); ++t) {
    const Vector3d q = ericsonClosest(p, m.vertex(m.f[3 * t]), m.vertex(m.f[3 * t + 1]), m.vertex(m.f[3 * t + 2]));
    best = std::min(best, (q - p).norm());
  }
  return best;
}

Mesh randomSoup(std::mt19937& rng, int nv, int nf) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_int_distribution<std::int64_t> pick(0, nv - 1);
  Mesh m;
  for (int i = 0; i < 3 * nv; ++i) m.v.push_back(g(rng));
  while (static_cast<int>(m.faces()) < nf) {
    const std::int64_t a = pick(rng), b = pick(rng), c = pick(rng);
    if (a != b && b != c && a != c) m.f.insert(m.f.end(), {a, b, c});
  }
  return m;
}

}  // namespace

TEST(MeshDistance, MatchesBruteForceOnRandomSoups) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.5);
  for (int leaf : {1, 4, 9}) {
    const Mesh m = randomSoup(rng, 300, 500);
    const MeshDistanceIndex index(m.view(), m.f.data(), m.faces(), leaf);
    EXPECT_EQ(index.numFaces(), m.faces());
    std::vector<double> pts;
    for (int i = 0; i < 3 * 400; ++i) pts.push_back(g(rng));
    std::vector<double> d(400);
    index.distances(CloudView<double>(pts.data(), 400), d.data());
    for (int i = 0; i < 400; ++i) {
      const Vector3d p(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
      EXPECT_NEAR(d[i], bruteForce(m, p), 1e-12) << "leaf " << leaf << " point " << i;
    }
  }
}

TEST(MeshDistance, ClosestPointLiesOnTheReportedTriangleAtTheReportedDistance) {
  std::mt19937 rng(8);
  const Mesh m = randomSoup(rng, 100, 150);
  const MeshDistanceIndex index(m.view(), m.f.data(), m.faces());
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Vector3d p(g(rng), g(rng), g(rng));
    const MeshClosestPoint c = index.closest(p);
    ASSERT_GE(c.triangle, 0);
    const std::int64_t* f = &m.f[3 * c.triangle];
    const Vector3d q = ericsonClosest(p, m.vertex(f[0]), m.vertex(f[1]), m.vertex(f[2]));
    EXPECT_NEAR((c.point - q).norm(), 0.0, 1e-12);
    EXPECT_NEAR(std::sqrt(c.squared_distance), (p - c.point).norm(), 1e-12);
  }
}

TEST(MeshDistance, AnalyticSquareAndPointsOnTheSurface) {
  const Mesh m{{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}};
  const MeshDistanceIndex index(m.view(), m.f.data(), m.faces());
  // above the square: the height; beside it: the in-plane offset and the height combined
  EXPECT_NEAR(std::sqrt(index.closest({0.3, 0.6, -0.7}).squared_distance), 0.7, 1e-15);
  EXPECT_NEAR(std::sqrt(index.closest({1.3, 1.4, 1.2}).squared_distance), std::sqrt(0.09 + 0.16 + 1.44), 1e-15);
  EXPECT_NEAR(std::sqrt(index.closest({0.5, -2.0, 0.0}).squared_distance), 2.0, 1e-15);
  // vertices, edge points (the shared diagonal too) and face points are at distance 0
  for (const Vector3d& p : {Vector3d(1, 1, 0), Vector3d(0, 0, 0), Vector3d(0.25, 0.25, 0), Vector3d(1, 0.3, 0),
                            Vector3d(0.2, 0.7, 0)})
    EXPECT_LT(index.closest(p).squared_distance, 1e-30);
}

TEST(MeshDistance, DegenerateTrianglesAreTheirEdges) {
  // a repeated vertex and three collinear vertices: the distance is to the segment
  const Mesh m{{0, 0, 0, 2, 0, 0, 1, 0, 0}, {0, 1, 0, 0, 2, 1}};
  for (std::size_t nf : {1u, 2u}) {
    const MeshDistanceIndex index(m.view(), m.f.data() + 3 * (nf - 1), 1);
    EXPECT_NEAR(std::sqrt(index.closest({1.5, 3.0, 4.0}).squared_distance), 5.0, 1e-14);
    EXPECT_NEAR(std::sqrt(index.closest({-3.0, 4.0, 0.0}).squared_distance), 5.0, 1e-14);
    EXPECT_NEAR(std::sqrt(index.closest({5.0, 0.0, 4.0}).squared_distance), 5.0, 1e-14);
  }
}

TEST(MeshDistance, NonFiniteQueriesGiveNaNAndEmptyQueriesNothing) {
  const Mesh m{{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}};
  const MeshDistanceIndex index(m.view(), m.f.data(), m.faces());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> pts{0.1, 0.1, 1.0, nan, 0, 0, 0, std::numeric_limits<double>::infinity(), 0};
  std::vector<double> d(3);
  std::vector<std::int64_t> tri(3);
  std::vector<double> q(9);
  index.closestPoints(CloudView<double>(pts.data(), 3), d.data(), tri.data(), q.data(), 2);
  EXPECT_NEAR(d[0], 1.0, 1e-15);
  EXPECT_EQ(tri[0], 0);
  EXPECT_TRUE(std::isnan(d[1]) && std::isnan(d[2]) && std::isnan(q[3]));
  EXPECT_EQ(tri[1], -1);
  index.distances(CloudView<double>(), nullptr);  // no points: nothing to write
  EXPECT_THROW(index.distances(CloudView<double>(pts.data(), 1), d.data(), -1), std::invalid_argument);
}

TEST(MeshDistance, RejectsBadMeshesNamingTheArgument) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Mesh m{{0, 0, 0, 1, 0, 0, 0, 1, 0, nan, 0, 0}, {0, 1, 2, 0, 1, 3, 0, 1, 4, 0, -1, 2}};
  auto build = [&](std::size_t first, std::size_t n, int leaf = 4) {
    MeshDistanceIndex(m.view(), m.f.data() + 3 * first, n, leaf);
  };
  EXPECT_NO_THROW(build(0, 1));  // the non-finite vertex 3 is unused
  auto message = [&](std::size_t first, std::size_t n, int leaf = 4) {
    try {
      build(first, n, leaf);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message(1, 1).find("vertices"), std::string::npos);
  EXPECT_NE(message(2, 1).find("faces: vertex indices"), std::string::npos);
  EXPECT_NE(message(3, 1).find("faces: vertex indices"), std::string::npos);
  EXPECT_NE(message(0, 0).find("no triangles"), std::string::npos);
  EXPECT_NE(message(0, 1, 0).find("leaf_size"), std::string::npos);
}
