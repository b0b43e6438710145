// Rigid transforms in one place: the check every entry point applies to a transform it is
// given, applying a transform to points, and the least-squares rotation between corresponding point sets (Kabsch 1976;
// Umeyama 1991, "Least-squares estimation of transformation parameters between two point
// patterns", eqs. 38-43), which the point-to-point ICP estimator, the SVD baseline of the
// motor estimators, correspondence RANSAC and trajectory alignment (ATE) all use.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>  // determinant()
#include <Eigen/SVD>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// Largest |R^T R - I| entry accepted as a rotation: rotations that went through float
/// (a float32 cloud's pose, a text file with 7 digits) pass, a scaled matrix does not.
inline constexpr double kRigidTolerance = 1e-5;
/// Largest |entry - target| accepted in the last row (0, 0, 0, 1).
inline constexpr double kRigidRowTolerance = 1e-9;

/// Why T is not a rigid transform, or nullptr when it is: finite, its last row
/// (0, 0, 0, 1), its upper-left 3x3 block a rotation (orthonormal to kRigidTolerance,
/// determinant +1).
inline const char* rigidProblem(const Eigen::Matrix4d& T) {
  if (!T.allFinite()) return "it has non-finite entries";
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kRigidRowTolerance)
    return "its last row (the bottom row) is not 0 0 0 1";
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kRigidTolerance)
    return "its rotation block is not orthonormal (to 1e-5)";
  if (!(R.determinant() > 0.0)) return "its rotation block is a reflection (determinant -1)";
  return nullptr;
}

inline bool isRigid(const Eigen::Matrix4d& T) { return rigidProblem(T) == nullptr; }

/// Throws std::invalid_argument naming `what` and the failed property unless isRigid(T).
inline void requireRigid(const Eigen::Matrix4d& T, const std::string& what) {
  if (const char* problem = rigidProblem(T))
    throw std::invalid_argument(what + " is not a rigid transform: " + problem);
}

/// Inverse of a rigid transform, [R^T, -R^T t]: exact for rigid input, unlike a general
/// 4x4 inverse, and cheaper.
inline Eigen::Matrix4d rigidInverse(const Eigen::Matrix4d& T) {
  Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
  inv.topLeftCorner<3, 3>() = T.topLeftCorner<3, 3>().transpose();
  inv.topRightCorner<3, 1>() = -(inv.topLeftCorner<3, 3>() * T.topRightCorner<3, 1>());
  return inv;
}

/// Applies T to every point: p' = A p + t with [A | t] the top three rows of T, evaluated in
/// double as ((A_r0 x + A_r1 y) + A_r2 z) + t_r for each row r (the order of the NumPy
/// expression p @ A.T + t without fused multiply-adds) and rounded once to Scalar. T need not be
/// rigid (a scale or shear is applied as given) but must be finite with the bottom row
/// 0 0 0 1 (within kRigidRowTolerance): a projective matrix has no meaning for points here.
/// Non-finite points give non-finite rows. `out` holds 3 Scalars a point, row-major; it may be
/// the input itself (stride 3): each point is read before it is written. Throws
/// std::invalid_argument naming `what` for a bad T.
template <typename Scalar>
void transformPoints(const Eigen::Matrix4d& T, const CloudView<Scalar>& points, Scalar* out,
                     const std::string& what = "T") {
  if (!T.allFinite()) throw std::invalid_argument(what + ": non-finite entries");
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kRigidRowTolerance)
    throw std::invalid_argument(what + ": the bottom row must be 0 0 0 1 (an affine transform)");
  if (points.size > 0 && out == nullptr) throw std::invalid_argument("transformPoints: null output");
  for (std::size_t i = 0; i < points.size; ++i) {
    const Scalar* p = points.ptr(i);
    const double x = p[0], y = p[1], z = p[2];
    double q[3];
    for (int r = 0; r < 3; ++r) {
      double s = T(r, 0) * x;
      s += T(r, 1) * y;
      s += T(r, 2) * z;
      q[r] = s + T(r, 3);
    }
    Scalar* o = out + 3 * i;
    for (int r = 0; r < 3; ++r) o[r] = static_cast<Scalar>(q[r]);
  }
}

/// transformPoints into a new array of 3 Scalars a point.
template <typename Scalar>
std::vector<Scalar> transformPoints(const Eigen::Matrix4d& T, const CloudView<Scalar>& points,
                                    const std::string& what = "T") {
  std::vector<Scalar> out(3 * points.size);
  transformPoints(T, points, out.data(), what);
  return out;
}

/// The rotation R maximising tr(R^T H) for a cross-covariance H = sum w (y - y_mean)
/// (x - x_mean)^T, i.e. the best rotation taking the centred x onto the centred y:
/// H = U S V^T, R = U diag(1, 1, d) V^T with d = sign(det(U V^T)) so that det R = +1
/// (Umeyama 1991, eqs. 39-43: a reflection is never returned).
struct CrossCovarianceRotation {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d singular_values = Eigen::Vector3d::Zero();  ///< of H, descending
  double d = 1.0;                                            ///< the reflection correction (+1 or -1)
  /// Singular values above `threshold` times the largest: >= 2 determines the rotation.
  int rank(double threshold) const {
    int r = 0;
    for (int k = 0; k < 3; ++k)
      if (singular_values(k) > threshold * std::max(singular_values(0), 1e-300)) ++r;
    return r;
  }
};

inline CrossCovarianceRotation rotationFromCrossCovariance(const Eigen::Matrix3d& H) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  CrossCovarianceRotation out;
  out.singular_values = svd.singularValues();
  out.d = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = out.d;
  out.R = svd.matrixU() * D * svd.matrixV().transpose();
  return out;
}

/// y ~ scale R x + t.
struct Similarity {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double scale = 1.0;
  /// The 4x4 [[scale R, t], [0, 1]]: T_target_source.
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = scale * R;
    T.topRightCorner<3, 1>() = t;
    return T;
  }
};

/// Least-squares similarity (with_scale) or rigid motion (scale 1) taking source points
/// onto their corresponding target points: minimises sum |y_i - (s R x_i + t)|^2
/// (Umeyama 1991; Horn 1987 without the scale). Any unit; the scale is s = tr(D S) /
/// var(x). Throws std::invalid_argument for sizes that differ, fewer than 3 pairs,
/// non-finite coordinates, or a degenerate configuration (coincident or collinear points:
/// the cross-covariance has rank < 2 and the rotation is not determined).
inline Similarity fitSimilarity(const CloudView<double>& source, const CloudView<double>& target,
                                bool with_scale = false) {
  const std::size_t n = source.size;
  if (target.size != n)
    throw std::invalid_argument("fitSimilarity: source and target must have equal shape, got " + std::to_string(n) +
                                " and " + std::to_string(target.size) + " points");
  if (n < 3) throw std::invalid_argument("fitSimilarity needs at least 3 point pairs, got " + std::to_string(n));
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), my = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!source.isFinite(i) || !target.isFinite(i)) throw std::invalid_argument("fitSimilarity: non-finite coordinates");
    mx += source[i];
    my += target[i];
  }
  mx /= double(n);
  my /= double(n);
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // Umeyama eq. 38, without the 1/n
  double var_x = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d xc = source[i] - mx;
    H += (target[i] - my) * xc.transpose();
    var_x += xc.squaredNorm();
  }
  const CrossCovarianceRotation rot = rotationFromCrossCovariance(H / double(n));
  const Eigen::Vector3d& sv = rot.singular_values;
  if (!(sv(0) > 0.0) || sv(1) <= 1e-12 * sv(0))
    throw std::invalid_argument("fitSimilarity: degenerate input (points coincident or collinear; the rotation is "
                                "not determined)");
  Similarity out;
  out.R = rot.R;
  out.scale = with_scale ? (sv(0) + sv(1) + rot.d * sv(2)) / (var_x / double(n)) : 1.0;
  out.t = my - out.scale * (out.R * mx);
  return out;
}

}  // namespace scanalign
