// Closed-form point-to-point alignment with dual number quaternions: Walker, Shao & Volz,
// "Estimating 3-D location parameters using dual number quaternions", CVGIP: Image
// Understanding 54(3) (1991) 358-367. The eye-in-hand paper's (Comput. Electron. Agric. 180
// (2021) 105929) variant (b), "ICP k-d tree, dual quaternion", and the estimator of PCL's
// TransformationEstimationDualQuaternion.
//
// The motion is the unit dual quaternion r + eps s (real part r: the rotation, dual part
// s = t r: the translation t). With unit weights, Walker's cost for point pairs (x_i source,
// y_i target, each a pure quaternion (v, 0)) is
//   E = r^T C1 r + s^T C2 s + s^T C3 r + const,
//   C1 = -2 sum Q(y_i)^T W(x_i),   C2 = n I,   C3 = 2 sum (W(x_i) - Q(y_i)),
// with Q and W the left- and right-multiplication matrices of eqs. (15)-(16). Minimising
// over s (the constraint r^T s = 0 then holds by itself, Q and W of pure quaternions being
// skew) leaves max r^T A r over unit r with
//   A = 1/2 (C3^T (C2 + C2^T)^-1 C3 - C1 - C1^T),   s = -(C2 + C2^T)^-1 C3 r,
// so r is A's eigenvector of the largest eigenvalue and t = W(r)^T s (vector part).
// C1 is bilinear and C3 linear in the points, so all three come from the running sums of
// PointToPointSystem (sum x, sum y, sum x y^T, n): the same sums, reduced the same way across
// threads, as the SVD estimator's; the two are two closed forms of one least-squares problem.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "scanalign/registration/point_to_point.hpp"

namespace scanalign {

namespace dual_quaternion_detail {

/// Quaternions are (x, y, z, w): vector part first, as Walker writes them.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d K;
  K << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return K;
}

/// Q(r) p = r p (Walker eq. 15).
inline Eigen::Matrix4d Q(const Eigen::Vector4d& r) {
  Eigen::Matrix4d M;
  M.topLeftCorner<3, 3>() = r(3) * Eigen::Matrix3d::Identity() + skew(r.head<3>());
  M.topRightCorner<3, 1>() = r.head<3>();
  M.bottomLeftCorner<1, 3>() = -r.head<3>().transpose();
  M(3, 3) = r(3);
  return M;
}

/// W(r) p = p r (Walker eq. 16).
inline Eigen::Matrix4d W(const Eigen::Vector4d& r) {
  Eigen::Matrix4d M = Q(r);
  M.topLeftCorner<3, 3>() -= 2.0 * skew(r.head<3>());
  return M;
}

}  // namespace dual_quaternion_detail

/// Least-squares rigid transform T minimising sum |T s_i - d_i|^2 by Walker et al.'s dual
/// quaternion solution (see the top of this file). Same answer, rank and degeneracy rule as
/// solvePointToPoint: the rank is that of the centred cross-covariance, judged against the
/// spreads of the matched points; rank < 2 (coincident or collinear points) is degenerate and
/// the step is the translation of the means only. (A's top eigen-gap, 4 (sigma_2 + sign(det H)
/// sigma_3) in H's singular values, closes with that rank too, but its rounding scales with
/// the raw sums rather than the spreads, so the rule reads the singular values directly and
/// both estimators flag the same inputs.)
inline PointToPointSolve solveDualQuaternion(const PointToPointSystem& sys, double degeneracy_threshold = 1e-10) {
  using namespace dual_quaternion_detail;
  PointToPointSolve out;
  if (sys.count < 1.0) return out;
  const double n = sys.count;
  const Eigen::Vector3d sum_x = Eigen::Map<const Eigen::Vector3d>(sys.sum_s.data());
  const Eigen::Vector3d sum_y = Eigen::Map<const Eigen::Vector3d>(sys.sum_d.data());
  const Eigen::Matrix3d M = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(sys.sum_sd.data());

  // Degeneracy: solvePointToPoint's rule on the same centred cross-covariance, same arithmetic.
  const Eigen::Vector3d ms = sum_x / n, md = sum_y / n;
  const Eigen::Matrix3d H = M - n * ms * md.transpose();
  out.rank = pointToPointRank(sys, Eigen::JacobiSVD<Eigen::Matrix3d>(H).singularValues(), degeneracy_threshold);
  out.degenerate = out.rank < 2;
  if (out.degenerate) {
    out.T.topRightCorner<3, 1>() = md - ms;
    return out;
  }

  // sum Q(y_i)^T W(x_i) = [[M + M^T - tr(M) I, z], [z^T, tr M]], M = sum x_i y_i^T,
  // z = sum x_i x y_i: the pure-quaternion products expanded and summed.
  Eigen::Matrix4d QtW;
  QtW.topLeftCorner<3, 3>() = M + M.transpose() - M.trace() * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d z(M(1, 2) - M(2, 1), M(2, 0) - M(0, 2), M(0, 1) - M(1, 0));
  QtW.topRightCorner<3, 1>() = z;
  QtW.bottomLeftCorner<1, 3>() = z.transpose();
  QtW(3, 3) = M.trace();
  const Eigen::Matrix4d C1 = -2.0 * QtW;
  const Eigen::Matrix4d C2 = n * Eigen::Matrix4d::Identity();
  Eigen::Vector4d X, Y;
  X << sum_x, 0.0;
  Y << sum_y, 0.0;
  const Eigen::Matrix4d C3 = 2.0 * (W(X) - Q(Y));  // sum of a linear map is the map of the sum
  const Eigen::Matrix4d C22_inv = (C2 + C2.transpose()).inverse();
  const Eigen::Matrix4d A = 0.5 * (C3.transpose() * C22_inv * C3 - C1 - C1.transpose());

  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(A);  // eigenvalues ascending
  const Eigen::Vector4d r = eig.eigenvectors().col(3);
  const Eigen::Vector4d s = -C22_inv * C3 * r;
  // W(r)^T Q(r) = [[R, 0], [0, 1]]: the rotation r v r* of a pure quaternion v.
  out.T.topLeftCorner<3, 3>() = (W(r).transpose() * Q(r)).topLeftCorner<3, 3>();
  out.T.topRightCorner<3, 1>() = (W(r).transpose() * s).head<3>();
  return out;
}

}  // namespace scanalign
