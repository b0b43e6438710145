// The synthetic scene's compositing and shading (synthetic/scene.hpp), against the meshes it
// is built from and an analytic checker board seen from above.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/common/look_at.hpp"
#include "scanalign/common/morton_order.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"
#include "scanalign/synthetic/builtin_part.hpp"
#include "scanalign/synthetic/scene.hpp"
#include "test_support.hpp"

using namespace scanalign;
using scanalign::test::rigid;

namespace {

struct Mesh {
  std::vector<double> vertices;
  std::vector<std::int64_t> faces;
};

Mesh blockMesh() {
  const BuiltinPartMesh m = builtinPartMesh(24);
  Mesh out;
  for (const auto& v : m.vertices) out.vertices.insert(out.vertices.end(), {v.x(), v.y(), v.z()});
  for (const auto& f : m.faces) out.faces.insert(out.faces.end(), {f[0], f[1], f[2]});
  return out;
}

/// A tetrahedron with an unused vertex (index 2), which the scene drops.
Mesh tetrahedron() {
  return {{0, 0, 0, 0.05, 0, 0, 9, 9, 9, 0, 0.05, 0, 0, 0, 0.05}, {0, 3, 1, 0, 1, 4, 0, 4, 3, 1, 3, 4}};
}

SceneObjectMesh object(const Mesh& m, const Eigen::Matrix4d& T, const Eigen::Vector3d& albedo) {
  SceneObjectMesh o;
  o.vertices = CloudView<double>(m.vertices.data(), m.vertices.size() / 3);
  o.faces = m.faces.data();
  o.n_faces = m.faces.size() / 3;
  o.T_base_object = T;
  o.albedo = albedo;
  return o;
}

}  // namespace

TEST(SceneComposition, ObjectsAndTableBecomeOneMeshThatMapsBackToItsSources) {
  const Mesh block = blockMesh(), tet = tetrahedron();
  const Eigen::Matrix4d T0 = rigid(0, 0, 0.7, 0.45, 0.05, 0.015), T1 = rigid(0.1, -0.2, 0.3, 0.6, 0.1, 0.02);
  SceneTable table;
  table.size = {0.6, 0.4};
  table.center = {0.5, 0.1};
  table.height = -0.01;
  const std::vector<SceneObjectMesh> objects{object(block, T0, {0.2, 0.4, 0.9}), object(tet, T1, {0.9, 0.1, 0.1})};
  const SceneMesh s = composeScene(objects, &table);
  const std::size_t nb = block.faces.size() / 3, nt = tet.faces.size() / 3;
  ASSERT_EQ(s.faceCount(), nb + nt + 2);
  ASSERT_EQ(s.object_faces, nb + nt);
  ASSERT_EQ(s.faces.size(), 3 * s.faceCount());
  EXPECT_EQ(s.vertices.size(), block.vertices.size() / 3 + 4 + 4);  // the tetrahedron's unused vertex dropped
  // Every face is its source face moved by its object's pose (an independent affine product).
  for (std::size_t f = 0; f < s.faceCount(); ++f) {
    const int k = s.face_object[f];
    if (k < 0) continue;
    const Mesh& m = k == 0 ? block : tet;
    const Eigen::Affine3d A(k == 0 ? T0 : T1);
    const auto src = static_cast<std::size_t>(s.face_source[f]);
    for (int c = 0; c < 3; ++c) {
      const auto v = static_cast<std::size_t>(m.faces[3 * src + c]);
      const Eigen::Vector3d want = A * Eigen::Vector3d(m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]);
      ASSERT_LT((s.vertices[static_cast<std::size_t>(s.faces[3 * f + c])] - want).norm(), 1e-15);
    }
    EXPECT_EQ(s.albedo[f], k == 0 ? Eigen::Vector3d(0.2, 0.4, 0.9) : Eigen::Vector3d(0.9, 0.1, 0.1));
  }
  // Each object's faces: a permutation of its own, in the Morton order of their centroids, and
  // its vertices numbered by first use.
  std::size_t begin = 0, next_vertex = 0;
  for (int k = 0; k < 2; ++k) {
    const Mesh& m = k == 0 ? block : tet;
    const std::size_t n = m.faces.size() / 3;
    std::vector<double> centroids;
    const CloudView<double> own(m.vertices.data(), m.vertices.size() / 3);
    const std::vector<double> moved = transformPoints(k == 0 ? T0 : T1, own);
    for (std::size_t f = 0; f < n; ++f)
      for (int r = 0; r < 3; ++r) {
        double sum = 0.0;
        for (int c = 0; c < 3; ++c) sum += moved[3 * static_cast<std::size_t>(m.faces[3 * f + c]) + r];
        centroids.push_back(sum / 3.0);
      }
    std::vector<std::int64_t> order;
    std::vector<std::pair<std::uint64_t, std::int64_t>> keyed;
    mortonOrder(CloudView<double>(centroids.data(), n), order, keyed);
    EXPECT_TRUE(std::equal(order.begin(), order.end(), s.face_source.begin() + static_cast<std::ptrdiff_t>(begin)));
    for (std::size_t f = begin; f < begin + n; ++f) {
      EXPECT_EQ(s.face_object[f], k);
      for (int c = 0; c < 3; ++c) {
        const auto v = static_cast<std::size_t>(s.faces[3 * f + c]);
        ASSERT_LE(v, next_vertex);
        if (v == next_vertex) ++next_vertex;
      }
    }
    begin += n;
  }
  EXPECT_EQ(next_vertex, s.vertices.size() - 4);
  // The table: its corners, two faces facing up, owner -1, sources 0 and 1.
  const std::vector<Eigen::Vector2d> corners{{0.2, -0.1}, {0.8, -0.1}, {0.8, 0.3}, {0.2, 0.3}};
  for (std::size_t f = nb + nt; f < s.faceCount(); ++f) {
    EXPECT_EQ(s.face_object[f], -1);
    EXPECT_EQ(s.face_source[f], static_cast<std::int64_t>(f - nb - nt));
    EXPECT_EQ(s.normals[f], Eigen::Vector3d(0, 0, 1));
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d& v = s.vertices[static_cast<std::size_t>(s.faces[3 * f + c])];
      EXPECT_EQ(v.z(), -0.01);
      EXPECT_TRUE(std::any_of(corners.begin(), corners.end(),
                              [&](const Eigen::Vector2d& c) { return (c - v.head<2>()).norm() < 1e-15; }))
          << v.transpose();
    }
  }
  // Unit right-hand normals.
  for (std::size_t f = 0; f < s.faceCount(); ++f) {
    const Eigen::Vector3d& a = s.vertices[static_cast<std::size_t>(s.faces[3 * f])];
    const Eigen::Vector3d& b = s.vertices[static_cast<std::size_t>(s.faces[3 * f + 1])];
    const Eigen::Vector3d& c = s.vertices[static_cast<std::size_t>(s.faces[3 * f + 2])];
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    EXPECT_NEAR(s.normals[f].norm(), 1.0, 1e-12);
    EXPECT_NEAR(s.normals[f].dot(cross), cross.norm(), 1e-12 * cross.norm());
  }
  // No table; bad objects.
  EXPECT_EQ(composeScene(objects, nullptr).faceCount(), nb + nt);
  Mesh bad = tet;
  bad.faces[4] = 5;
  EXPECT_THROW(composeScene({object(bad, T1, {1, 1, 1})}, nullptr), std::invalid_argument);
  Eigen::Matrix4d nan = T1;
  nan(0, 3) = std::nan("");
  EXPECT_THROW(composeScene({object(tet, nan, {1, 1, 1})}, nullptr), std::invalid_argument);
}

TEST(SceneShading, TwoSidedLambertColoursAndTheTableCheckerSeenFromAbove) {
  const Mesh tet = tetrahedron();
  SceneTable table;  // 0.6 x 0.6 at (0.5, 0), z = 0, 5 cm squares
  const SceneMesh s = composeScene({object(tet, rigid(0, 0, 0, 0.52, 0.03, 0.0), {0.75, 0.45, 0.2})}, &table);
  const Eigen::Vector3d light = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  const double ambient = 0.3;
  const SceneColors colors = sceneColors(s, table, light, ambient);
  ASSERT_EQ(colors.faceCount(), s.faceCount());
  const auto byte = [](double c) { return static_cast<int>(std::floor(255.0 * c + 0.5)); };
  for (std::size_t f = 0; f < s.faceCount(); ++f) {
    const double intensity = ambient + (1 - ambient) * std::abs(s.normals[f].dot(light));
    const Eigen::Vector3d alt = s.face_object[f] < 0 ? table.checker_colors[1] : s.albedo[f];
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(colors.albedo[3 * f + c], byte(s.albedo[f][c] * intensity), 0);
      EXPECT_NEAR(colors.alternate[3 * f + c], byte(alt[c] * intensity), 0);
    }
  }
  for (int c = 0; c < 3; ++c) EXPECT_EQ(colors.albedo[3 * s.faceCount() + c], 0);  // the background
  EXPECT_THROW(sceneColors(s, table, 2.0 * light, ambient), std::invalid_argument);
  EXPECT_THROW(sceneColors(s, table, light, 1.5), std::invalid_argument);

  // A camera 0.5 m above the table looking straight down: every table pixel's colour follows
  // the parity of the checker square under it, computed from the pixel's ray here.
  const PinholeIntrinsics K{160, 120, 150.0, 150.0, 79.5, 59.5};
  const Eigen::Matrix4d T_base_camera = lookAt(Eigen::Vector3d(0.5, 0.0, 0.5), Eigen::Vector3d(0.5, 0.0, 0.0),
                                               Eigen::Vector3d::UnitY());
  std::vector<float> depth(160 * 120);
  std::vector<std::int32_t> face_id(depth.size());
  const DepthRenderResult out{depth.data(), face_id.data(), nullptr};
  std::vector<double> vd;
  for (const auto& v : s.vertices) vd.insert(vd.end(), {v.x(), v.y(), v.z()});
  renderDepth(CloudView<double>(vd.data(), s.vertices.size()), s.faces.data(), s.faceCount(), K,
              rigidInverse(T_base_camera), DepthRenderSettings{}, out);
  std::vector<std::uint8_t> rgb(3 * depth.size());
  shadeScene(colors, table, K, T_base_camera, depth.data(), face_id.data(), rgb.data());
  const Eigen::Matrix3d R = T_base_camera.topLeftCorner<3, 3>();
  const Eigen::Vector3d o = T_base_camera.topRightCorner<3, 1>();
  int table_pixels = 0, odd = 0, object_pixels = 0;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * K.width + u;
      const std::uint8_t* px = &rgb[3 * i];
      if (face_id[i] < 0) {
        EXPECT_TRUE(px[0] == 0 && px[1] == 0 && px[2] == 0);
        continue;
      }
      const auto f = static_cast<std::size_t>(face_id[i]);
      if (f < s.object_faces) {
        ++object_pixels;
        EXPECT_TRUE(std::equal(px, px + 3, &colors.albedo[3 * f]));
        continue;
      }
      // The table point under the pixel: its ray meets z = 0.
      const Eigen::Vector3d d = R * Eigen::Vector3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
      const Eigen::Vector3d hit = o - (o.z() / d.z()) * d;
      const double gx = (hit.x() - table.center.x()) / table.checker_size;
      const double gy = (hit.y() - table.center.y()) / table.checker_size;
      if (std::abs(gx - std::round(gx)) < 1e-4 || std::abs(gy - std::round(gy)) < 1e-4) continue;  // on a line
      const bool is_odd = static_cast<long>(std::floor(gx) + std::floor(gy)) % 2 != 0;
      ++table_pixels;
      odd += is_odd;
      EXPECT_TRUE(std::equal(px, px + 3, is_odd ? &colors.alternate[3 * f] : &colors.albedo[3 * f])) << u << " " << v;
    }
  EXPECT_GT(table_pixels, 10000);
  EXPECT_GT(odd, 3000);
  EXPECT_GT(object_pixels, 20);
  // Distorted intrinsics (the renderer's images are pinhole) and malformed colours.
  PinholeIntrinsics D = K;
  D.distortion.k1 = 0.1;
  EXPECT_THROW(shadeScene(colors, table, D, T_base_camera, depth.data(), face_id.data(), rgb.data()),
               std::invalid_argument);
  SceneColors short_colors = colors;
  short_colors.alternate.pop_back();
  EXPECT_THROW(shadeScene(short_colors, table, K, T_base_camera, depth.data(), face_id.data(), rgb.data()),
               std::invalid_argument);
  face_id[0] = static_cast<std::int32_t>(s.faceCount());
  EXPECT_THROW(shadeScene(colors, table, K, T_base_camera, depth.data(), face_id.data(), rgb.data()),
               std::invalid_argument);
}
