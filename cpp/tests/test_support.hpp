// Shared test fixtures: analytic surfaces with exact normals and random rigid motions.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>

namespace scanalign::test {

struct Surface {
  std::vector<float> points;   // 3 per point
  std::vector<float> normals;  // 3 per point, unit
  std::size_t size() const { return points.size() / 3; }
};

/// A wavy height field z = h(x, y) plus a sphere: constrains all 6 degrees of freedom.
inline Surface wavySurfaceWithSphere(int grid = 120, double extent = 0.2, std::uint32_t seed = 1) {
  Surface s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const double step = extent / grid;
  for (int i = 0; i < grid; ++i)
    for (int j = 0; j < grid; ++j) {
      const double x = -extent / 2 + (i + 0.5 + jitter(rng)) * step;
      const double y = -extent / 2 + (j + 0.5 + jitter(rng)) * step;
      const double z = 0.6 + 0.01 * std::sin(40 * x) * std::cos(30 * y) + 0.2 * x * x;
      const double dzdx = 0.01 * 40 * std::cos(40 * x) * std::cos(30 * y) + 0.4 * x;
      const double dzdy = -0.01 * 30 * std::sin(40 * x) * std::sin(30 * y);
      Eigen::Vector3d n(-dzdx, -dzdy, 1.0);
      n.normalize();
      n = -n;  // face the camera at the origin
      for (double v : {x, y, z}) s.points.push_back(float(v));
      for (int k = 0; k < 3; ++k) s.normals.push_back(float(n[k]));
    }
  const Eigen::Vector3d c(0.03, -0.02, 0.55);
  const double r = 0.03;
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 4000; ++k) {
    Eigen::Vector3d u(g(rng), g(rng), g(rng));
    u.normalize();
    const Eigen::Vector3d p = c + r * u;
    for (int a = 0; a < 3; ++a) s.points.push_back(float(p[a]));
    for (int a = 0; a < 3; ++a) s.normals.push_back(float(u[a]));
  }
  return s;
}

inline Eigen::Matrix4d rigid(double rx, double ry, double rz, double tx, double ty, double tz) {
  Eigen::Affine3d a = Eigen::Translation3d(tx, ty, tz) * Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX());
  return a.matrix();
}

inline std::vector<float> transformed(const std::vector<float>& pts, const Eigen::Matrix4d& T) {
  std::vector<float> out(pts.size());
  for (std::size_t i = 0; i < pts.size() / 3; ++i) {
    const Eigen::Vector3d p(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
    const Eigen::Vector3d q = T.topLeftCorner<3, 3>() * p + T.topRightCorner<3, 1>();
    for (int k = 0; k < 3; ++k) out[3 * i + k] = float(q[k]);
  }
  return out;
}

inline double rotationError(const Eigen::Matrix4d& A, const Eigen::Matrix4d& B) {
  const Eigen::Matrix3d R = A.topLeftCorner<3, 3>().transpose() * B.topLeftCorner<3, 3>();
  return std::acos(std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0));
}
inline double translationError(const Eigen::Matrix4d& A, const Eigen::Matrix4d& B) {
  return (A.topRightCorner<3, 1>() - B.topRightCorner<3, 1>()).norm();
}

}  // namespace scanalign::test
