// Closed-form point-to-point alignment (Horn 1987 / Umeyama 1991 without scale) from
// running sums, so it reduces across threads like the point-to-plane system.
#pragma once

#include <array>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/SVD>

#include "scanalign/common/rigid.hpp"
#include "scanalign/registration/correspondence_terms.hpp"

namespace scanalign {

struct PointToPointSystem {
  double count = 0.0;
  std::array<double, 3> sum_s{}, sum_d{};
  std::array<double, 9> sum_sd{};  ///< sum of s d^T, row-major
  double sum_ss = 0.0, sum_dd = 0.0;  ///< sum of |s|^2 and of |d|^2 (m^2): the scale of the spreads

  void add(const double s[3], const double d[3]) {
    count += 1.0;
    detail::addPointPairTerms(sum_s.data(), sum_d.data(), sum_sd.data(), sum_ss, sum_dd, s, d);
  }
  void merge(const PointToPointSystem& o) {
    count += o.count;
    for (int k = 0; k < 3; ++k) {
      sum_s[k] += o.sum_s[k];
      sum_d[k] += o.sum_d[k];
    }
    for (int k = 0; k < 9; ++k) sum_sd[k] += o.sum_sd[k];
    sum_ss += o.sum_ss;
    sum_dd += o.sum_dd;
  }
};

struct PointToPointSolve {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();  ///< maps source to target
  int rank = 0;             ///< rank of the cross-covariance (>= 2 determines the rotation)
  bool degenerate = true;   ///< collinear or coincident points: rotation not determined
};

/// The rank of the centred cross-covariance of `sys` from its singular values, by the rule
/// solvePointToPoint states (shared with solveDualQuaternion, dual_quaternion.hpp).
inline int pointToPointRank(const PointToPointSystem& sys, const Eigen::Vector3d& singular_values,
                            double degeneracy_threshold) {
  const Eigen::Vector3d ms = Eigen::Map<const Eigen::Vector3d>(sys.sum_s.data()) / sys.count;
  const Eigen::Vector3d md = Eigen::Map<const Eigen::Vector3d>(sys.sum_d.data()) / sys.count;
  const double spread_s = sys.sum_ss - sys.count * ms.squaredNorm();  // tr C_s
  const double spread_d = sys.sum_dd - sys.count * md.squaredNorm();  // tr C_d
  int rank = 0;
  if (spread_s > 1e-12 * sys.sum_ss && spread_d > 1e-12 * sys.sum_dd)
    for (int k = 0; k < 3; ++k)
      if (singular_values(k) > degeneracy_threshold * std::sqrt(spread_s * spread_d)) ++rank;
  return rank;
}

/// Least-squares rigid transform T minimising sum |T s_i - d_i|^2 (Kabsch/Umeyama):
/// the rotation of the cross-covariance (common/rigid.hpp), t = d_mean - R s_mean.
///
/// Rank: singular values of the cross-covariance H above `degeneracy_threshold` times
/// sqrt(tr C_s tr C_d), the bound |H| <= sqrt(tr C_s tr C_d) (Cauchy-Schwarz) of the spreads
/// C_s, C_d of the source and matched target points; 0 when either spread is no larger than
/// the rounding of its centring (1e-12 of the raw second moment: coincident points). Judged
/// against the largest singular value instead, coincident points -- whose H is pure
/// rounding -- looked like rank 3 and their arbitrary "rotation" was applied and reported
/// converged. Rank < 2 (coincident or collinear points) leaves the rotation undetermined:
/// degenerate, and the step is the translation of the means only.
inline PointToPointSolve solvePointToPoint(const PointToPointSystem& sys, double degeneracy_threshold = 1e-10) {
  PointToPointSolve out;
  if (sys.count < 1.0) return out;
  const Eigen::Vector3d ms = Eigen::Map<const Eigen::Vector3d>(sys.sum_s.data()) / sys.count;
  const Eigen::Vector3d md = Eigen::Map<const Eigen::Vector3d>(sys.sum_d.data()) / sys.count;
  const Eigen::Matrix3d sum_sd = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(sys.sum_sd.data());
  // sum (s - s_mean)(d - d_mean)^T, transposed: the target-by-source cross-covariance.
  const Eigen::Matrix3d H = sum_sd - sys.count * ms * md.transpose();
  const CrossCovarianceRotation rot = rotationFromCrossCovariance(H.transpose());
  out.rank = pointToPointRank(sys, rot.singular_values, degeneracy_threshold);
  out.degenerate = out.rank < 2;
  const Eigen::Matrix3d R = out.degenerate ? Eigen::Matrix3d::Identity() : rot.R;
  out.T.topLeftCorner<3, 3>() = R;
  out.T.topRightCorner<3, 1>() = md - R * ms;
  return out;
}

}  // namespace scanalign
