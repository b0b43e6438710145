// Area-weighted mesh sampling (common/mesh_sampling.hpp) and the built-in block's exact
// surface samples (synthetic/builtin_part.hpp), against analytic areas and surfaces.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/mesh_sampling.hpp"
#include "scanalign/synthetic/builtin_part.hpp"

using namespace scanalign;

namespace {

// The unit cube [0, 1]^3, two triangles a face, wound outwards.
const std::vector<double> kCubeVertices{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
std::vector<std::int64_t> cubeFaces() {
  const int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  std::vector<std::int64_t> f;
  for (const auto& q : quads) f.insert(f.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  return f;
}
CloudView<double> cube() { return CloudView<double>(kCubeVertices.data(), 8); }

/// |count - n p| within 5 binomial standard deviations.
void expectShare(std::size_t count, std::size_t n, double p, const char* what) {
  const double sigma = std::sqrt(n * p * (1 - p));
  EXPECT_LT(std::abs(double(count) - n * p), 5 * sigma) << what << ": " << count << " of " << n << ", expected " << n * p;
}

}  // namespace

TEST(MeshSampling, CubePointsLieExactlyOnTheirFacesWithAxisNormals) {
  const auto faces = cubeFaces();
  const std::size_t n = 60000;
  const MeshSamples s = sampleMesh(cube(), faces.data(), 12, n, 3);
  ASSERT_EQ(s.size(), n);
  std::array<std::size_t, 6> per_face{};
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = s.points[i];
    const Eigen::Vector3d& m = s.normals[i];
    int axis = 0;
    m.cwiseAbs().maxCoeff(&axis);
    ASSERT_EQ(std::abs(m[axis]), 1.0);
    ASSERT_EQ(m.cwiseAbs().sum(), 1.0);  // +-e_k exactly
    // The point keeps its face's coordinate exactly (relative to the face's first corner).
    ASSERT_EQ(p[axis], m[axis] > 0 ? 1.0 : 0.0) << p.transpose();
    ASSERT_TRUE((p.array() >= 0.0).all() && (p.array() <= 1.0).all());
    // The face index matches the side hit: -x +x -y +y -z +z are quads 4 5 2 3 0 1 of cubeFaces.
    const int quad_of_side[6] = {4, 5, 2, 3, 0, 1};
    ASSERT_EQ(s.faces[i] / 2, quad_of_side[2 * axis + (m[axis] > 0)]);
    ++per_face[static_cast<std::size_t>(s.faces[i] / 2)];
  }
  for (std::size_t f = 0; f < 6; ++f) expectShare(per_face[f], n, 1.0 / 6.0, "cube face");
  // Uniform inside a face: a 4 x 4 grid on the bottom face is filled evenly (chi-square, 15
  // degrees of freedom; 45 is far beyond its 99.9% quantile of 37.7).
  std::array<double, 16> grid{};
  std::size_t bottom = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (s.normals[i].z() < 0) {
      const int gx = std::min(3, int(s.points[i].x() * 4)), gy = std::min(3, int(s.points[i].y() * 4));
      ++grid[static_cast<std::size_t>(gx * 4 + gy)];
      ++bottom;
    }
  double chi2 = 0.0;
  for (double g : grid) chi2 += (g - bottom / 16.0) * (g - bottom / 16.0) / (bottom / 16.0);
  EXPECT_LT(chi2, 45.0);
}

TEST(MeshSampling, AreaWeightsAndTheSquareRootParametrisation) {
  // Two right triangles, areas 2 and 0.5 (ratio 4:1), and a zero-area one between them.
  const std::vector<double> v{0, 0, 0, 2, 0, 0, 0, 2, 0, 5, 0, 0, 6, 0, 0, 5, 1, 0, 9, 9, 9, 8, 8, 8};
  const std::vector<std::int64_t> f{0, 1, 2, 6, 7, 6, 3, 4, 5};
  const std::size_t n = 40000;
  const MeshSamples s = sampleMesh(CloudView<double>(v.data(), 8), f.data(), 3, n, 11);
  std::size_t first = 0, upper = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_NE(s.faces[i], 1) << "a zero-area face was drawn";
    EXPECT_EQ(s.normals[i], Eigen::Vector3d(0, 0, 1));
    EXPECT_EQ(s.points[i].z(), 0.0);
    if (s.faces[i] == 0) {
      ++first;
      // Uniform by area: half the triangle's area lies beyond x + y = sqrt(2) from the right
      // angle (without the square root, 29% of the points would).
      upper += s.points[i].x() + s.points[i].y() > std::sqrt(2.0);
      EXPECT_LE(s.points[i].x() + s.points[i].y(), 2.0 + 1e-12);
    }
  }
  expectShare(first, n, 0.8, "area 2 of 2.5");
  expectShare(upper, first, 0.5, "beyond x + y = sqrt(2)");
}

TEST(MeshSampling, Pcg64IsNumPysDefaultGenerator) {
  // numpy.random.default_rng(seed).bit_generator.random_raw() and .random(), NumPy 2.4.
  Pcg64 zero(0);
  EXPECT_EQ(zero.next(), 11749869230777074271ull);
  EXPECT_EQ(zero.next(), 4976686463289251617ull);
  EXPECT_EQ(zero.next(), 755828109848996024ull);
  Pcg64 a(12345), b(1099511627783ull);  // one and two 32-bit seed words
  EXPECT_EQ(a.next(), 4193609425186963869ull);
  EXPECT_EQ(a.next(), 5843160025838961886ull);
  EXPECT_EQ(b.next(), 15307346044642009514ull);
  EXPECT_EQ(b.next(), 4709548916763817589ull);
  Pcg64 u(0);
  EXPECT_EQ(u.uniform(), 0.6369616873214543);
  EXPECT_EQ(u.uniform(), 0.2697867137638703);
  EXPECT_EQ(u.uniform(), 0.04097352393619469);
}

TEST(MeshSampling, SeededAndRefusingBadMeshes) {
  const auto faces = cubeFaces();
  const MeshSamples a = sampleMesh(cube(), faces.data(), 12, 9000, 7);
  const MeshSamples b = sampleMesh(cube(), faces.data(), 12, 9000, 7);
  const MeshSamples c = sampleMesh(cube(), faces.data(), 12, 9000, 8);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.faces, b.faces);
  EXPECT_NE(a.points, c.points);
  // Drawing in two calls continues the stream: the faces of the first n samples come first.
  MeshSamples twice;
  Pcg64 rng(7);
  const MeshSampler sampler(cube(), faces.data(), 12);
  sampler.draw(rng, 100, twice);
  sampler.draw(rng, 50, twice);
  EXPECT_EQ(twice.size(), 150u);
  const MeshSamples once = sampleMesh(cube(), faces.data(), 12, 100, 7);
  EXPECT_TRUE(std::equal(once.faces.begin(), once.faces.end(), twice.faces.begin()));
  EXPECT_EQ(sampleMesh(cube(), faces.data(), 12, 0, 7).size(), 0u);
  // Zero total area, no faces, an index out of range, a non-finite vertex in use.
  const std::vector<double> line{0, 0, 0, 1, 1, 1, 2, 2, 2};
  const std::vector<std::int64_t> one{0, 1, 2};
  EXPECT_THROW(sampleMesh(CloudView<double>(line.data(), 3), one.data(), 1, 10, 0), std::invalid_argument);
  EXPECT_THROW(sampleMesh(cube(), faces.data(), 0, 10, 0), std::invalid_argument);
  std::vector<std::int64_t> bad = faces;
  bad[5] = 8;
  EXPECT_THROW(sampleMesh(cube(), bad.data(), 12, 10, 0), std::invalid_argument);
  std::vector<double> nan = kCubeVertices;
  nan[4] = std::nan("");
  EXPECT_THROW(sampleMesh(CloudView<double>(nan.data(), 8), faces.data(), 12, 10, 0), std::invalid_argument);
}

TEST(BuiltinBlockSamples, LieOnTheExactSurfacesWithExactNormals) {
  // The block's analytic surfaces (builtin_part.hpp).
  const Eigen::Vector3d half(0.040, 0.025, 0.015);
  const Eigen::Vector2d boss(-0.015, 0.0);
  const double boss_radius = 0.012, boss_top = 0.030, top = 0.015;
  const Eigen::Vector3d cap(0.020, 0.006, 0.006);
  const double cap_radius = 0.015, cap_base = std::sqrt(cap_radius * cap_radius - (top - cap.z()) * (top - cap.z()));
  const std::size_t n = 20000;
  const MeshSamples s = sampleBuiltinBlock(n, 5);
  ASSERT_EQ(s.size(), n);
  std::array<std::size_t, 4> counts{};  // box, boss side, boss top, cap
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = s.points[i];
    const Eigen::Vector3d& m = s.normals[i];
    ASSERT_NEAR(m.norm(), 1.0, 1e-12);
    const double rho = (p.head<2>() - boss).norm();
    const Eigen::Vector2d radial = (p.head<2>() - boss) / boss_radius;
    const bool on_boss_side = std::abs(rho - boss_radius) < 1e-12 && p.z() >= top - 1e-12 &&
                              p.z() <= boss_top + 1e-12 && (m.head<2>() - radial).norm() < 1e-9 && m.z() == 0.0;
    const bool on_boss_top = p.z() == boss_top && rho <= boss_radius + 1e-12 && m == Eigen::Vector3d(0, 0, 1);
    const bool on_cap = std::abs((p - cap).norm() - cap_radius) < 1e-12 && p.z() >= top - 1e-12 &&
                        (m - (p - cap) / cap_radius).norm() < 1e-9;
    int axis = 0;
    m.cwiseAbs().maxCoeff(&axis);
    bool on_box = m.cwiseAbs().sum() == 1.0 && p[axis] == (m[axis] > 0 ? half[axis] : -half[axis]) &&
                  (p.cwiseAbs().array() <= half.array() + 1e-12).all();
    if (on_box && axis == 2 && m.z() > 0)  // the top face outside the boss's and the cap's circles
      on_box = rho >= boss_radius && (p.head<2>() - cap.head<2>()).norm() >= cap_base;
    ASSERT_TRUE(on_box || on_boss_side || on_boss_top || on_cap) << p.transpose() << " / " << m.transpose();
    ++counts[on_box ? 0 : on_boss_side ? 1 : on_boss_top ? 2 : 3];
  }
  // Uniform per unit area over the exact surfaces (5 sigma each).
  const double pi = 3.14159265358979323846;
  const double box = 8 * (half.x() * half.y() + half.x() * half.z() + half.y() * half.z()) -
                     pi * (boss_radius * boss_radius + cap_base * cap_base);
  const double side = 2 * pi * boss_radius * (boss_top - top), disc = pi * boss_radius * boss_radius;
  const double dome = 2 * pi * cap_radius * (cap_radius - (top - cap.z()));
  const double total = box + side + disc + dome;
  expectShare(counts[0], n, box / total, "box");
  expectShare(counts[1], n, side / total, "boss side");
  expectShare(counts[2], n, disc / total, "boss top");
  expectShare(counts[3], n, dome / total, "cap");
  // Deterministic for a seed.
  EXPECT_EQ(sampleBuiltinBlock(500, 5).points, sampleBuiltinBlock(500, 5).points);
  EXPECT_NE(sampleBuiltinBlock(500, 6).points, sampleBuiltinBlock(500, 5).points);
}
