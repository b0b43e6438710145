// Depth renderer against analytic ray casting: planes, a sphere, near-plane clipping,
// watertight shared edges, thread independence and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/reconstruction/depth_renderer.hpp"

using scanalign::CloudView;
using scanalign::DepthImage;
using scanalign::DepthRenderSettings;
using scanalign::PinholeCamera;
using scanalign::renderDepth;

namespace {

struct TestMesh {
  std::vector<double> vertices;     // 3 per vertex
  std::vector<std::int32_t> faces;  // 3 per face
  CloudView<double> view() const { return CloudView<double>(vertices.data(), vertices.size() / 3); }
  std::int32_t add(const Eigen::Vector3d& p) {
    vertices.insert(vertices.end(), {p.x(), p.y(), p.z()});
    return static_cast<std::int32_t>(vertices.size() / 3 - 1);
  }
};

/// A planar grid: origin + i * du + j * dv for i, j in [0, n], each cell split along its
/// (0,0)-(1,1) diagonal; faces wound so that du x dv is the normal.
TestMesh gridMesh(const Eigen::Vector3d& origin, const Eigen::Vector3d& du, const Eigen::Vector3d& dv, int n) {
  TestMesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.add(origin + i * du + j * dv);
  auto id = [n](int i, int j) { return static_cast<std::int32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      m.faces.insert(m.faces.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.faces.insert(m.faces.end(), {id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return m;
}

/// UV sphere of radius r centred at c, outward winding.
TestMesh uvSphere(const Eigen::Vector3d& c, double r, int rings, int segments) {
  TestMesh m;
  const double pi = std::acos(-1.0);
  const std::int32_t north = m.add(c + Eigen::Vector3d(0, 0, r));
  for (int k = 1; k < rings; ++k) {
    const double th = pi * k / rings;
    for (int s = 0; s < segments; ++s) {
      const double ph = 2 * pi * s / segments;
      m.add(c + r * Eigen::Vector3d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  }
  const std::int32_t south = m.add(c - Eigen::Vector3d(0, 0, r));
  auto id = [&](int k, int s) { return static_cast<std::int32_t>(1 + (k - 1) * segments + (s % segments)); };
  for (int s = 0; s < segments; ++s) m.faces.insert(m.faces.end(), {north, id(1, s), id(1, s + 1)});
  for (int k = 1; k + 1 < rings; ++k)
    for (int s = 0; s < segments; ++s) {
      m.faces.insert(m.faces.end(), {id(k, s), id(k + 1, s), id(k + 1, s + 1)});
      m.faces.insert(m.faces.end(), {id(k, s), id(k + 1, s + 1), id(k, s + 1)});
    }
  for (int s = 0; s < segments; ++s) m.faces.insert(m.faces.end(), {south, id(rings - 1, s + 1), id(rings - 1, s)});
  return m;
}

PinholeCamera vga(double cx = 319.5, double cy = 239.5, double f = 500.0) { return {640, 480, f, f, cx, cy}; }

Eigen::Vector3d ray(const PinholeCamera& c, int u, int v) { return {(u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0}; }

Eigen::Matrix4d pose(double rx, double ry, double rz, const Eigen::Vector3d& t) {
  Eigen::Affine3d a = Eigen::Translation3d(t) * Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX());
  return a.matrix();
}

}  // namespace

// A tilted plane seen from a general pose: every pixel's depth equals the analytic ray-plane
// intersection, and the back-projected point lies on the plane to 1e-6 m.
TEST(DepthRenderer, TiltedPlaneMatchesAnalyticDepth) {
  // Plane in the world frame through p0 with normal n; camera looks at it from a general pose.
  const Eigen::Vector3d p0(0.1, -0.05, 0.0);
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
  const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
  const TestMesh m = gridMesh(p0 - 2.0 * a - 2.0 * b, 0.2 * a, 0.2 * b, 20);  // 4 m x 4 m, 800 triangles
  // Camera 0.6 m above the plane along its normal, tilted by a few degrees.
  Eigen::Matrix4d T_world_camera = Eigen::Matrix4d::Identity();
  Eigen::Matrix3d R;
  R.col(2) = -n;
  R.col(0) = a;
  R.col(1) = R.col(2).cross(R.col(0));
  T_world_camera.topLeftCorner<3, 3>() = R * Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 0.5, 0).normalized()).matrix();
  T_world_camera.topRightCorner<3, 1>() = p0 + 0.6 * n;
  const Eigen::Matrix4d T_camera_world = T_world_camera.inverse();
  const PinholeCamera cam = vga(321.3, 238.7, 475.0);
  const DepthImage img = renderDepth(m.view(), m.faces, cam, T_camera_world);

  // The plane in the camera frame: nc . x = dc.
  const Eigen::Vector3d nc = T_camera_world.topLeftCorner<3, 3>() * n;
  const double dc = nc.dot((T_camera_world * p0.homogeneous()).head<3>());
  double worst = 0.0, worst_cos = 0.0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d r = ray(cam, u, v);
      const double z_true = dc / nc.dot(r);
      ASSERT_GE(img.faceAt(u, v), 0) << "hole at " << u << "," << v;
      const double z = img.at(u, v);
      worst = std::max(worst, std::abs(z - z_true));
      const double cos_true = std::abs(nc.dot(r)) / r.norm();
      worst_cos = std::max(worst_cos, std::abs(img.cos_incidence[v * cam.width + u] - cos_true));
      // Back-projection lies on the plane.
      ASSERT_LT(std::abs(nc.dot(z * r) - dc), 1e-6);
    }
  EXPECT_LT(worst, 1e-6);  // float32 storage of ~0.6 m: ~3e-8
  EXPECT_LT(worst_cos, 1e-6);
}

// Pixel centres exactly on shared edges (a grid whose edges and diagonals pass through
// pixel centres): each pixel is covered by exactly one triangle -- rendering the triangles
// one at a time gives disjoint coverages whose union is the whole image.
TEST(DepthRenderer, SharedEdgesAreWatertightAndDrawnOnce) {
  const PinholeCamera cam{64, 48, 100.0, 100.0, 32.0, 24.0};
  for (int trial = 0; trial < 2; ++trial) {
    TestMesh m;
    if (trial == 0) {
      // Fronto-parallel grid at z = 1: vertices project onto integer pixel positions.
      // 10 x 12 px cells covering columns [-8, 72] and rows [-12, 84]; the diagonals pass
      // through a pixel centre every 5 columns.
      m = gridMesh({-0.4, -0.36, 1.0}, {0.1, 0, 0}, {0, 0.12, 0}, 8);
    } else {
      // A fan of triangles around a vertex at a pixel centre, with random rim angles.
      std::mt19937 rng(7);
      std::uniform_real_distribution<double> jitter(-0.2, 0.2);
      const std::int32_t centre = m.add({0.05, 0.03, 1.0});  // projects to (37, 27)
      const int k = 23;
      for (int s = 0; s < k; ++s) {
        const double ang = 2 * std::acos(-1.0) * (s + jitter(rng)) / k;
        m.add({0.05 + 2.0 * std::cos(ang), 0.03 + 2.0 * std::sin(ang), 1.0});
      }
      for (int s = 0; s < k; ++s)
        m.faces.insert(m.faces.end(), {centre, static_cast<std::int32_t>(1 + s), static_cast<std::int32_t>(1 + (s + 1) % k)});
    }
    const DepthImage all = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity());
    std::vector<int> cover(static_cast<std::size_t>(cam.width) * cam.height, 0);
    for (std::size_t f = 0; f < m.faces.size() / 3; ++f) {
      const std::vector<std::int32_t> one(m.faces.begin() + 3 * f, m.faces.begin() + 3 * f + 3);
      const DepthImage img = renderDepth(m.view(), one, cam, Eigen::Matrix4d::Identity());
      for (std::size_t p = 0; p < cover.size(); ++p)
        if (img.face_id[p] == 0) {
          ++cover[p];
          EXPECT_EQ(all.face_id[p], static_cast<std::int32_t>(f));
        }
    }
    for (std::size_t p = 0; p < cover.size(); ++p) {
      ASSERT_EQ(cover[p], 1) << "trial " << trial << " pixel " << p % cam.width << "," << p / cam.width;
      EXPECT_FLOAT_EQ(all.depth[p], 1.0f);
    }
  }
}

// Random triangles from sub-pixel to wider than the image (both the per-pixel and the
// row-span paths): a pixel centre clearly inside the projected triangle is drawn with the
// exact plane depth, one clearly outside is not.
TEST(DepthRenderer, CoverageMatchesPointInTriangle) {
  const PinholeCamera cam{160, 120, 150.0, 150.0, 79.5, 59.5};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int inside_total = 0, sizes_small = 0, sizes_large = 0;
  for (int trial = 0; trial < 300; ++trial) {
    // Screen-space size from 0.5 to 400 pixels (log-uniform), depth 0.3 .. 2 m.
    const double size = 0.5 * std::pow(800.0, unit(rng));
    (size < 8 ? sizes_small : sizes_large)++;
    const double cu = -20 + 200 * unit(rng), cv = -20 + 160 * unit(rng);
    TestMesh m;
    double px[3], py[3];
    for (int k = 0; k < 3; ++k) {
      px[k] = cu + size * (unit(rng) - 0.5);
      py[k] = cv + size * (unit(rng) - 0.5);
      const double z = 0.3 + 1.7 * unit(rng);
      m.add({(px[k] - cam.cx) / cam.fx * z, (py[k] - cam.cy) / cam.fy * z, z});
    }
    m.faces = {0, 1, 2};
    const DepthImage img = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity());
    const Eigen::Vector3d A(m.vertices[0], m.vertices[1], m.vertices[2]);
    const Eigen::Vector3d B(m.vertices[3], m.vertices[4], m.vertices[5]);
    const Eigen::Vector3d C(m.vertices[6], m.vertices[7], m.vertices[8]);
    const Eigen::Vector3d n = (B - A).cross(C - A);
    const double area = (px[1] - px[0]) * (py[2] - py[0]) - (py[1] - py[0]) * (px[2] - px[0]);
    if (std::abs(area) < 1e-6) continue;
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        // Barycentric coordinates of the pixel centre in the projected triangle.
        double b[3];
        for (int k = 0; k < 3; ++k) {
          const int i = (k + 1) % 3, j = (k + 2) % 3;
          b[k] = ((px[j] - px[i]) * (v - py[i]) - (py[j] - py[i]) * (u - px[i])) / area;
        }
        const double margin = 1e-7 * std::max(1.0, size);
        const double bmin = std::min({b[0], b[1], b[2]});
        if (bmin > margin) {
          ASSERT_EQ(img.faceAt(u, v), 0) << "trial " << trial << " pixel " << u << "," << v;
          const Eigen::Vector3d r = ray(cam, u, v);
          EXPECT_NEAR(img.at(u, v), n.dot(A) / n.dot(r), 1e-6);
          ++inside_total;
        } else if (bmin < -margin) {
          ASSERT_EQ(img.faceAt(u, v), -1) << "trial " << trial << " pixel " << u << "," << v;
        }
      }
  }
  EXPECT_GT(sizes_small, 50);
  EXPECT_GT(sizes_large, 50);
  EXPECT_GT(inside_total, 100000);
}

// A tessellated sphere against the analytic ray-sphere intersection: the inscribed mesh is
// never in front of the sphere, lies within the tessellation's sagitta behind it, and its
// silhouette is inside the sphere's and covers it up to the polygon's inset.
TEST(DepthRenderer, SphereMatchesRayCastingUpToTessellation) {
  const Eigen::Vector3d c(0.02, -0.01, 0.5);
  const double r = 0.1;
  const int rings = 96, segments = 192;
  const TestMesh m = uvSphere(c, r, rings, segments);
  const PinholeCamera cam = vga();
  const Eigen::Matrix4d T = pose(0.3, -0.2, 0.1, Eigen::Vector3d::Zero());  // rotate about the camera centre
  const Eigen::Vector3d cc = T.topLeftCorner<3, 3>() * c;                   // sphere centre in the camera frame
  const DepthImage img = renderDepth(m.view(), m.faces, cam, T);
  const double pi = std::acos(-1.0);
  // Largest distance between the sphere and the inscribed polyhedron along the normal.
  const double sagitta = r * (1.0 - std::cos(pi / rings) * std::cos(pi / segments));
  int hits = 0;
  double worst_cos = 0.0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d d = ray(cam, u, v).normalized();
      const double bq = d.dot(cc), disc = bq * bq - (cc.squaredNorm() - r * r);
      const int id = img.faceAt(u, v);
      if (disc < 0) {
        ASSERT_EQ(id, -1) << "mesh drawn outside the sphere at " << u << "," << v;
        continue;
      }
      const double t = bq - std::sqrt(disc);   // ray length to the first hit
      const double z_true = t * d.z();
      const double cos_true = -d.dot((t * d - cc) / r);
      if (id < 0) {
        // Missed pixels lie in the sliver between the sphere and the polyhedron's outline.
        EXPECT_LT(cos_true, 0.08) << u << "," << v;
        continue;
      }
      ++hits;
      const double z = img.at(u, v);
      EXPECT_GE(z, z_true - 1e-6);
      // Behind the sphere by at most the sagitta along the facet normal, i.e. about
      // sagitta / cos along the ray (the facet normal is within 2 degrees of the sphere's).
      if (cos_true > 0.2) {
        EXPECT_LE(z - z_true, sagitta / (cos_true - 0.04) * d.z() + 1e-6) << u << "," << v;
        worst_cos = std::max(worst_cos, std::abs(img.cos_incidence[v * cam.width + u] - cos_true));
      }
    }
  EXPECT_GT(hits, 20000);   // about pi (0.1 * 500 / 0.5)^2 ~ 31000 pixels
  EXPECT_LT(worst_cos, 0.04);  // flat facets of 1.9 degrees
}

// A floor crossing the camera plane (vertices behind the camera and in front): only the part
// beyond the near plane is drawn, with exact depth; a triangle wholly behind draws nothing.
TEST(DepthRenderer, NearPlaneClipsTrianglesCrossingIt) {
  const PinholeCamera cam = vga();
  const double h = 0.1;  // floor at y = +0.1 (below the camera: y points down)
  TestMesh m;
  const auto a = m.add({-3.0, h, -1.0}), b = m.add({3.0, h, -1.0}), c = m.add({3.0, h, 5.0}), d = m.add({-3.0, h, 5.0});
  m.faces = {a, b, c, a, c, d};
  // A triangle behind the camera that would project into the image if not dropped.
  const auto e = m.add({-0.1, -0.1, -0.5}), f = m.add({0.1, -0.1, -0.5}), g = m.add({0.0, 0.1, -0.5});
  m.faces.insert(m.faces.end(), {e, f, g});
  for (double near : {1e-3, 0.3}) {
    DepthRenderSettings s;
    s.near_clip = near;
    const DepthImage img = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity(), s);
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        const Eigen::Vector3d r = ray(cam, u, v);
        const int id = img.faceAt(u, v);
        ASSERT_NE(id, 2);
        bool expect_hit = false;
        double z_true = 0.0;
        if (r.y() > 0) {
          z_true = h / r.y();
          const double x = z_true * r.x();
          // Well inside the floor's extent and clear of the near plane (pixel-size margins).
          if (z_true > near * 1.02 && z_true < 4.9 && std::abs(x) < 2.9) expect_hit = true;
          if (z_true < near * 0.98 || z_true > 5.1 || std::abs(x) > 3.1) ASSERT_EQ(id, -1) << u << "," << v;
        } else {
          ASSERT_EQ(id, -1) << u << "," << v;
        }
        if (expect_hit) {
          ASSERT_GE(id, 0) << u << "," << v << " near " << near;
          ASSERT_NEAR(img.at(u, v), z_true, 1e-6 * z_true + 1e-7);
        }
      }
  }
}

// Occlusion, far plane, back-face culling and -1 / NaN / 0 for empty pixels.
TEST(DepthRenderer, OcclusionFarPlaneAndCulling) {
  const PinholeCamera cam{32, 24, 30.0, 30.0, 15.5, 11.5};
  TestMesh m = gridMesh({-1, -1, 1.0}, {2, 0, 0}, {0, 2, 0}, 1);  // faces 0, 1 at z = 1, normal +z (back to camera)
  TestMesh front = gridMesh({-0.1, -0.1, 0.5}, {0, 0.2, 0}, {0.2, 0, 0}, 1);  // faces 2, 3 at z = 0.5, normal -z
  const auto base = static_cast<std::int32_t>(m.vertices.size() / 3);
  m.vertices.insert(m.vertices.end(), front.vertices.begin(), front.vertices.end());
  for (auto i : front.faces) m.faces.push_back(i + base);
  const DepthImage img = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity());
  const int uc = 15, vc = 11;  // near the optical axis: the small front square occludes
  EXPECT_GE(img.faceAt(uc, vc), 2);
  EXPECT_NEAR(img.at(uc, vc), 0.5f, 1e-7);
  EXPECT_GT(img.cos_incidence[vc * cam.width + uc], 0.99f);  // front face
  EXPECT_LE(img.faceAt(0, 0), 1);
  EXPECT_LT(img.cos_incidence[0], 0.0f);  // the far square shows its back
  DepthRenderSettings s;
  s.cull_backfaces = true;
  const DepthImage culled = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity(), s);
  EXPECT_EQ(culled.faceAt(0, 0), -1);
  EXPECT_TRUE(std::isnan(culled.at(0, 0)));
  EXPECT_EQ(culled.cos_incidence[0], 0.0f);
  EXPECT_GE(culled.faceAt(uc, vc), 2);
  s = {};
  s.far_clip = 0.8;
  const DepthImage far = renderDepth(m.view(), m.faces, cam, Eigen::Matrix4d::Identity(), s);
  EXPECT_EQ(far.faceAt(0, 0), -1);
  EXPECT_GE(far.faceAt(uc, vc), 2);
}

TEST(DepthRenderer, ResultIsIndependentOfThreadCount) {
  TestMesh m = uvSphere({0, 0, 0.6}, 0.15, 60, 120);
  const TestMesh floor = gridMesh({-1, 0.1, 0}, {0.1, 0, 0}, {0, 0, 0.1}, 20);
  const auto base = static_cast<std::int32_t>(m.vertices.size() / 3);
  m.vertices.insert(m.vertices.end(), floor.vertices.begin(), floor.vertices.end());
  for (auto i : floor.faces) m.faces.push_back(i + base);
  const Eigen::Matrix4d T = pose(0.1, 0.2, 0.3, {0.01, 0.02, 0.03});
  DepthRenderSettings s;
  s.num_threads = 1;
  const DepthImage one = renderDepth(m.view(), m.faces, vga(), T, s);
  s.num_threads = 4;
  const DepthImage four = renderDepth(m.view(), m.faces, vga(), T, s);
  EXPECT_EQ(one.face_id, four.face_id);
  EXPECT_EQ(0, std::memcmp(one.depth.data(), four.depth.data(), one.depth.size() * sizeof(float)));
  // float vertices render the same surface (to float rounding of the input).
  std::vector<float> vf(m.vertices.begin(), m.vertices.end());
  const DepthImage single = renderDepth(CloudView<float>(vf.data(), vf.size() / 3), m.faces, vga(), T, s);
  int differ = 0;
  for (std::size_t p = 0; p < one.depth.size(); ++p) {
    if (single.face_id[p] != one.face_id[p]) {
      ++differ;
    } else if (one.face_id[p] >= 0) {
      EXPECT_NEAR(single.depth[p], one.depth[p], 1e-6);
    }
  }
  EXPECT_LT(differ, 50);  // only pixels on edges may change owner
}

TEST(DepthRenderer, NonFiniteVerticesSkipTheirFaces) {
  TestMesh m = gridMesh({-1, -1, 1.0}, {2, 0, 0}, {0, 2, 0}, 1);
  m.vertices[3 * 1] = std::numeric_limits<double>::quiet_NaN();  // vertex 1 is used by face 0 only
  const DepthImage img = renderDepth(m.view(), m.faces, {32, 24, 30, 30, 15.5, 11.5}, Eigen::Matrix4d::Identity());
  int face1 = 0;
  for (auto id : img.face_id) {
    EXPECT_NE(id, 0);
    face1 += id == 1;
  }
  EXPECT_GT(face1, 300);
}

TEST(DepthRenderer, BadInputThrows) {
  const TestMesh m = gridMesh({-1, -1, 1.0}, {2, 0, 0}, {0, 2, 0}, 1);
  const Eigen::Matrix4d I = Eigen::Matrix4d::Identity();
  const PinholeCamera cam = vga();
  auto faces = m.faces;
  faces[4] = 4;  // only 4 vertices
  EXPECT_THROW(renderDepth(m.view(), faces, cam, I), std::invalid_argument);
  faces[4] = -1;
  EXPECT_THROW(renderDepth(m.view(), faces, cam, I), std::invalid_argument);
  faces.pop_back();
  EXPECT_THROW(renderDepth(m.view(), faces, cam, I), std::invalid_argument);  // not a multiple of 3
  Eigen::Matrix4d T = I;
  T(0, 3) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, T), std::invalid_argument);
  T = I;
  T(0, 0) = 2.0;  // a scale, not a rotation
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, T), std::invalid_argument);
  T = I;
  T(3, 0) = 0.5;  // projective bottom row (e.g. a transposed pose)
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, T), std::invalid_argument);
  T = I;
  T(2, 2) = -1.0;  // reflection
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, T), std::invalid_argument);
  for (PinholeCamera bad : {PinholeCamera{0, 480, 500, 500, 320, 240}, PinholeCamera{640, -1, 500, 500, 320, 240},
                            PinholeCamera{640, 480, 0, 500, 320, 240}, PinholeCamera{640, 480, 500, -5, 320, 240},
                            PinholeCamera{640, 480, 500, 500, std::nan(""), 240}})
    EXPECT_THROW(renderDepth(m.view(), m.faces, bad, I), std::invalid_argument);
  DepthRenderSettings s;
  s.near_clip = 0.0;
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, I, s), std::invalid_argument);
  s.near_clip = 1.0;
  s.far_clip = 0.5;
  EXPECT_THROW(renderDepth(m.view(), m.faces, cam, I, s), std::invalid_argument);
  // An empty mesh is valid: nothing is hit.
  const DepthImage empty = renderDepth(m.view(), std::vector<std::int32_t>{}, cam, I);
  EXPECT_TRUE(std::isnan(empty.depth[0]));
  EXPECT_EQ(empty.face_id[100], -1);
}
