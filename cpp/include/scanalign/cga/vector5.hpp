// The small 5-vector algebra of conformal vectors (Kleppe, PhD thesis, NTNU 2018, (4.54)-(4.66), the matrix form
// (5.32)): points, dual spheres and dual planes as coefficients on (e1, e2, e3, e∞, e0),
// without a multivector library. Shared by the RANSAC models (fitting/ransac.hpp) and the
// inverse kinematics (kinematics/ik.cpp); the general algebra is scanalign/cga/multivector.hpp.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>

namespace scanalign {
namespace cga5 {

using Vec5 = Eigen::Matrix<double, 5, 1>;  ///< coefficients of (e1, e2, e3, e_inf, e0)
using Mat5 = Eigen::Matrix<double, 5, 5>;

/// Conformal point up(p) = p + p^2/2 e_inf + e0 (4.54-4.55).
inline Vec5 up(const Eigen::Vector3d& p) {
  Vec5 v;
  v << p, 0.5 * p.squaredNorm(), 1.0;
  return v;
}
/// Dual sphere S* = up(c) - r^2/2 e_inf (4.59)-(4.60); r2 = r^2 (negative: imaginary).
inline Vec5 dualSphere(const Eigen::Vector3d& c, double r2) {
  Vec5 v;
  v << c, 0.5 * (c.squaredNorm() - r2), 1.0;
  return v;
}
/// Dual plane Pi* = n + delta e_inf (4.65)-(4.66): the plane n . x = delta.
inline Vec5 dualPlane(const Eigen::Vector3d& n, double delta) {
  Vec5 v;
  v << n, delta, 0.0;
  return v;
}
/// The origin e0.
inline Vec5 e0() {
  Vec5 v = Vec5::Zero();
  v[4] = 1.0;
  return v;
}
/// The point at infinity e_inf.
inline Vec5 eInf() {
  Vec5 v = Vec5::Zero();
  v[3] = 1.0;
  return v;
}
/// The metric M = diag(I3, [[0,-1],[-1,0]]) of (5.32): a . b = [a]^T M [b]; e0 . e_inf = -1
/// (4.45). M is its own inverse.
inline Mat5 metric() {
  Mat5 M = Mat5::Zero();
  M(0, 0) = M(1, 1) = M(2, 2) = 1.0;
  M(3, 4) = M(4, 3) = -1.0;
  return M;
}
/// Inner product of two vectors, [a]^T M [b] (M = metric(), written out).
inline double inner(const Vec5& a, const Vec5& b) {
  return a.head<3>().dot(b.head<3>()) - a[3] * b[4] - a[4] * b[3];
}
/// Dual (A*, (4.50)) of the 4-blade a ^ b ^ c ^ d, a vector. In five dimensions the
/// outer product of four vectors is determined by the five 4x4 minors of the matrix with
/// rows a, b, c, d; the dual maps it to the vector v with v . x = det[a; b; c; d; x] for
/// every x, i.e. v = M * cofactors (M^-1 = M). The sign convention reproduces the
/// worked example (the orientation of (4.64) depends on the dual convention): the dual of up(0,0,1)^up(1,0,1)^up(0,1,1)^e_inf is
/// -(e3 + e_inf).
inline Vec5 dualOfOuter4(const Vec5& a, const Vec5& b, const Vec5& c, const Vec5& d) {
  // cof_j = det[a; b; c; d; e_j] = (-1)^(4+j) * minor_j (drop column j).
  Eigen::Matrix<double, 4, 5> A;
  A.row(0) = a.transpose();
  A.row(1) = b.transpose();
  A.row(2) = c.transpose();
  A.row(3) = d.transpose();
  Vec5 cof;
  for (int j = 0; j < 5; ++j) {
    Eigen::Matrix4d minor;
    for (int col = 0, k = 0; col < 5; ++col)
      if (col != j) minor.col(k++) = A.col(col);
    cof[j] = ((4 + j) % 2 == 0 ? 1.0 : -1.0) * minor.determinant();
  }
  // v = M cof: v . x = [v]^T M [x] = cof^T [x] = det[a; b; c; d; x].
  Vec5 v;
  v << cof.head<3>(), -cof[4], -cof[3];
  return v;
}

}  // namespace cga5
}  // namespace scanalign
