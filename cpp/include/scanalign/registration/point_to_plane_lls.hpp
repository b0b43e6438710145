// Point-to-plane ICP as a linear least-squares problem (Low 2004), the eye-in-hand
// paper (Comput. Electron. Agric. 180 (2021) 105929), §3.2.
//
// For a correspondence (s, d, n) -- source point s already moved by the current
// estimate, target point d with unit normal n -- the small-angle linearisation of
// ((R s + t - d) . n)^2 gives one row of A x = b with x = (alpha, beta, gamma, tx, ty, tz):
//     A_i = [ (s x n)^T , n^T ],   b_i = n . (d - s).
// The normal equations A^T A x = A^T b are sums of independent per-correspondence terms,
// which is what makes the estimator parallel: each thread (GPU: each work item) adds its
// 21 unique A^T A terms and 6 A^T b terms, and the partial sums are reduced by a tree.
// PCL-free so the ICP engine, the PCL plug-in and a GPU backend share it.
#pragma once

#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "scanalign/registration/correspondence_terms.hpp"

namespace scanalign {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Running sums of Low's normal equations. A value type: zero-initialised, add(), merge().
struct PointToPlaneSystem {
  std::array<double, 21> ata{};  ///< upper triangle of A^T A, row-major
  std::array<double, 6> atb{};   ///< A^T b
  double btb = 0.0;              ///< sum of b_i^2: point-to-plane residual^2 before the step (m^2)
  double count = 0.0;            ///< correspondences added

  /// Adds one correspondence: s source point (already transformed), d target point,
  /// n target unit normal, w its weight (detail::addPointToPlaneTerms, Low 2004 eqs. (8)-(10)).
  void add(const double s[3], const double d[3], const double n[3], double w = 1.0) {
    detail::addPointToPlaneTerms(ata.data(), atb.data(), btb, s, d, n, w);
    count += 1.0;
  }

  void merge(const PointToPlaneSystem& o) {
    for (int k = 0; k < 21; ++k) ata[k] += o.ata[k];
    for (int k = 0; k < 6; ++k) atb[k] += o.atb[k];
    btb += o.btb;
    count += o.count;
  }

  Matrix6d AtA() const {
    Matrix6d m;
    int k = 0;
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) m(r, c) = m(c, r) = ata[k++];
    return m;
  }
  Vector6d Atb() const { return Eigen::Map<const Vector6d>(atb.data()); }
};

/// Outcome of solving the 6x6 normal equations.
struct PointToPlaneSolve {
  Vector6d x = Vector6d::Zero();  ///< (alpha, beta, gamma) rad, (tx, ty, tz) m
  int rank = 0;                   ///< number of well-constrained directions (6 when not degenerate)
  double conditioning = 0.0;      ///< lambda_min / lambda_max of the unit-balanced A^T A (1 = ideal)
  bool degenerate = true;         ///< rank < 6: some motions are not constrained by the data
};

/// Solves A^T A x = A^T b.
///
/// Rotation columns of A carry metres and translation columns do not, so conditioning is
/// judged on the balanced matrix S A^T A S with S = diag(L, L, L, 1, 1, 1), where
/// L = sqrt(trace_rot / trace_trans) is the data's own lever arm. If
/// lambda_min / lambda_max >= `degeneracy_threshold` the full system is solved by LDLT
/// (never an explicit inverse). Otherwise the system is rank deficient -- e.g. a plane
/// leaves two translations and one rotation free -- and x is the minimum-norm solution
/// restricted to the well-constrained eigen-directions: unconstrained motions stay zero
/// instead of being driven by round-off or noise.
inline PointToPlaneSolve solvePointToPlane(const Matrix6d& AtA, const Vector6d& Atb,
                                           double degeneracy_threshold = 1e-10) {
  PointToPlaneSolve out;
  const double trace_rot = AtA(0, 0) + AtA(1, 1) + AtA(2, 2);
  const double trace_trans = AtA(3, 3) + AtA(4, 4) + AtA(5, 5);
  if (!(trace_trans > 0.0) || !std::isfinite(trace_rot) || !std::isfinite(trace_trans)) return out;
  double L = std::sqrt(trace_rot / trace_trans);
  if (!(L > 0.0)) L = 1.0;
  Vector6d scale;
  scale << L, L, L, 1.0, 1.0, 1.0;
  const Matrix6d balanced = scale.asDiagonal() * AtA * scale.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(balanced);
  if (eig.info() != Eigen::Success) return out;
  const Vector6d lambda = eig.eigenvalues();  // ascending
  const double lmax = lambda(5);
  if (!(lmax > 0.0)) return out;
  out.conditioning = std::max(0.0, lambda(0)) / lmax;
  out.rank = 0;
  for (int k = 0; k < 6; ++k)
    if (lambda(k) >= degeneracy_threshold * lmax) ++out.rank;
  out.degenerate = out.rank < 6;
  if (!out.degenerate) {
    out.x = AtA.ldlt().solve(Atb);
  } else {
    const Vector6d rhs = scale.asDiagonal() * Atb;
    Vector6d y = Vector6d::Zero();
    for (int k = 6 - out.rank; k < 6; ++k) {
      const auto v = eig.eigenvectors().col(k);
      y += v * (v.dot(rhs) / lambda(k));
    }
    out.x = scale.asDiagonal() * y;
  }
  if (!out.x.allFinite()) {
    out.x.setZero();
    out.rank = 0;
    out.degenerate = true;
  }
  return out;
}

/// Rigid transform from Low's parameters: R = Rz(gamma) Ry(beta) Rx(alpha), then the
/// translation (the same convention as PCL's constructTransformationMatrix).
inline Eigen::Matrix4d transformFromParameters(const Vector6d& x) {
  const double ca = std::cos(x(0)), sa = std::sin(x(0));
  const double cb = std::cos(x(1)), sb = std::sin(x(1));
  const double cg = std::cos(x(2)), sg = std::sin(x(2));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T(0, 0) = cg * cb;
  T(0, 1) = cg * sb * sa - sg * ca;
  T(0, 2) = cg * sb * ca + sg * sa;
  T(1, 0) = sg * cb;
  T(1, 1) = sg * sb * sa + cg * ca;
  T(1, 2) = sg * sb * ca - cg * sa;
  T(2, 0) = -sb;
  T(2, 1) = cb * sa;
  T(2, 2) = cb * ca;
  T(0, 3) = x(3);
  T(1, 3) = x(4);
  T(2, 3) = x(5);
  return T;
}

}  // namespace scanalign
