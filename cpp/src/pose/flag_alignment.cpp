// Paper 4 initial alignment with motors. See flag_alignment.hpp.
#include "scanalign/pose/flag_alignment.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <Eigen/Geometry>

namespace scanalign {

namespace {

/// Residual vector of ½(δ² + sin²(θ/2) + d²) for the motor T applied to the source flag:
/// (dX − R dY)/2, whose squared norm is sin²(θ/2) (|a − b| = 2 sin(θ/2) for unit vectors); the
/// part of the offset between the lines' feet perpendicular to ℓ̄_X (δ); and P_X − M P_Y (d).
Eigen::Matrix<double, 9, 1> residual(const NormalLineFlag& X, const NormalLineFlag& Y, const Eigen::Matrix4d& T) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  const Eigen::Vector3d d = R * Y.direction;
  const Eigen::Vector3d c = R * Y.centroid + t;
  const Eigen::Vector3d foot = R * Y.foot + t;
  Eigen::Vector3d off = foot - X.foot;
  off -= X.direction * X.direction.dot(off);
  Eigen::Matrix<double, 9, 1> r;
  r << 0.5 * (X.direction - d), off, X.centroid - c;
  return r;
}

/// exp of a twist (ω, v): rotation by |ω| about ω, then translation v (applied on the left).
Eigen::Matrix4d twist(const Eigen::Matrix<double, 6, 1>& xi) {
  Eigen::Matrix4d D = Eigen::Matrix4d::Identity();
  const Eigen::Vector3d w = xi.head<3>();
  const double a = w.norm();
  if (a > 0) D.topLeftCorner<3, 3>() = Eigen::AngleAxisd(a, w / a).toRotationMatrix();
  D.topRightCorner<3, 1>() = xi.tail<3>();
  return D;
}

/// Why a cloud's usable points (finite point, non-zero normal) cannot give a flag: fewer than
/// min_points, or collinear / coincident (the second singular value of their spread ~ 0), or
/// nullptr. Throws for a coordinate beyond kMaxFlagCoordinate.
template <typename Scalar>
std::string pointsProblem(const CloudView<Scalar>& points, const CloudView<Scalar>& normals, std::size_t min_points,
                          const char* what) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  const auto usable = [&](std::size_t i) {
    return points.isFinite(i) && normals.isFinite(i) && normals[i].template cast<double>().norm() > 0;
  };
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!usable(i)) continue;
    const Eigen::Vector3d x = points[i].template cast<double>();
    if (x.cwiseAbs().maxCoeff() > kMaxFlagCoordinate)
      throw std::invalid_argument(std::string("alignFlags: ") + what + " has coordinates beyond 1e6 m (point " +
                                  std::to_string(i) + "); the flag cost mixes metres and radians");
    mean += x;
    ++n;
  }
  if (n < min_points)
    return std::string(what) + " has " + std::to_string(n) + " usable points (finite, non-zero normal), fewer than " +
           "min_points = " + std::to_string(min_points);
  mean /= double(n);
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < points.size; ++i)
    if (usable(i)) {
      const Eigen::Vector3d d = points[i].template cast<double>() - mean;
      C += d * d.transpose();
    }
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(ev(2) > 0) || ev(1) <= 1e-12 * ev(2))
    return std::string(what) + ": the points are collinear or coincident (no surface patch to align)";
  return {};
}

/// A right-handed frame (d, u, d × u).
Eigen::Matrix3d frameOf(const Eigen::Vector3d& d, const Eigen::Vector3d& u) {
  Eigen::Matrix3d F;
  F.col(0) = d;
  F.col(1) = u;
  F.col(2) = d.cross(u);
  return F;
}

}  // namespace

template <typename Scalar>
NormalLineFlag normalLineFlag(const CloudView<Scalar>& points, const CloudView<Scalar>& normals) {
  if (points.size != normals.size)
    throw std::invalid_argument("normalLineFlag: points and normals differ in shape (" + std::to_string(points.size) +
                                " vs " + std::to_string(normals.size) + " rows)");
  if (points.size == 0) throw std::invalid_argument("normalLineFlag: empty cloud");
  NormalLineFlag f;
  Eigen::Vector3d sx = Eigen::Vector3d::Zero(), sn = Eigen::Vector3d::Zero(), sm = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i) || !normals.isFinite(i)) continue;
    const Eigen::Vector3d x = points[i].template cast<double>();
    Eigen::Vector3d n = normals[i].template cast<double>();
    const double len = n.norm();
    if (!(len > 0)) continue;
    n /= len;
    sx += x;
    sn += n;
    sm += x.cross(n);  // the dual line ℓ* in Plücker form: (direction, moment)
    ++f.count;
  }
  if (f.count == 0) throw std::invalid_argument("normalLineFlag: no point with a finite point and non-zero normal");
  const double m = static_cast<double>(f.count);
  f.centroid = sx / m;
  const Eigen::Vector3d nbar = sn / m, mbar = sm / m;
  f.mean_normal_length = nbar.norm();
  if (f.mean_normal_length > 0) {
    const double n2 = nbar.squaredNorm();
    f.pitch = nbar.dot(mbar) / n2;
    f.direction = nbar / f.mean_normal_length;
    const Eigen::Vector3d p0 = nbar.cross(mbar) / n2;  // a point of the screw's axis
    f.foot = p0 + f.direction * f.direction.dot(f.centroid - p0);
  }
  return f;
}

template <typename Scalar>
FlagAlignmentResult alignFlags(const CloudView<Scalar>& source, const CloudView<Scalar>& source_normals,
                               const CloudView<Scalar>& target, const CloudView<Scalar>& target_normals,
                               const FlagAlignmentSettings& s) {
  if (!(s.min_mean_normal_length >= 0 && s.min_mean_normal_length < 1))
    throw std::invalid_argument("alignFlags: min_mean_normal_length must be in [0, 1)");
  if (!(s.min_centroid_offset >= 0) || !std::isfinite(s.min_centroid_offset))
    throw std::invalid_argument("alignFlags: min_centroid_offset must be finite and >= 0");
  if (s.max_iterations < 0 || !(s.tolerance >= 0)) throw std::invalid_argument("alignFlags: bad LM settings");
  FlagAlignmentResult out;
  out.source_flag = normalLineFlag(source, source_normals);
  out.target_flag = normalLineFlag(target, target_normals);
  for (const std::string& problem : {pointsProblem(source, source_normals, s.min_points, "source"),
                                     pointsProblem(target, target_normals, s.min_points, "target")})
    if (!problem.empty()) {
      out.message = problem;
      return out;
    }
  const NormalLineFlag &Y = out.source_flag, &X = out.target_flag;
  for (const NormalLineFlag* f : {&X, &Y})
    if (f->mean_normal_length < s.min_mean_normal_length) {
      out.message = "the normals average to nearly zero (|mean normal| = " + std::to_string(f->mean_normal_length) +
                    "): a closed surface has no average normal line; use a single-view (partial) cloud";
      return out;
    }
  const Eigen::Vector3d uX = X.centroid - X.foot, uY = Y.centroid - Y.foot;
  if (uX.norm() < s.min_centroid_offset || uY.norm() < s.min_centroid_offset) {
    out.message = "the centroid lies on the average normal line: the rotation about the line is undetermined";
    return out;
  }
  // Closed-form start: the rotation maps (ℓ̄_Y direction, offset to the centroid) onto ℓ̄_X's,
  // and the translation maps the centroids.
  const Eigen::Matrix3d R0 = frameOf(X.direction, uX.normalized()) * frameOf(Y.direction, uY.normalized()).transpose();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R0;
  T.topRightCorner<3, 1>() = X.centroid - R0 * Y.centroid;
  // Levenberg–Marquardt on the motor manifold: M ← exp(B) M.
  auto cost = [&](const Eigen::Matrix4d& M) { return 0.5 * residual(X, Y, M).squaredNorm(); };
  double c = cost(T), mu = 1e-3;
  int it = 0;
  for (; it < s.max_iterations && c > 0; ++it) {
    const Eigen::Matrix<double, 9, 1> r = residual(X, Y, T);
    Eigen::Matrix<double, 9, 6> J;
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Zero();
      const double h = 1e-7;
      e(k) = h;
      J.col(k) = (residual(X, Y, twist(e) * T) - residual(X, Y, twist(-e) * T)) / (2 * h);
    }
    const Eigen::Matrix<double, 6, 6> A = J.transpose() * J;
    const Eigen::Matrix<double, 6, 1> g = J.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 20 && !improved; ++tries) {
      Eigen::Matrix<double, 6, 6> Am = A;
      Am.diagonal() += mu * (A.diagonal().array() + 1e-12).matrix();
      const Eigen::Matrix<double, 6, 1> step = -Am.ldlt().solve(g);
      const Eigen::Matrix4d Tn = twist(step) * T;
      const double cn = cost(Tn);
      if (cn < c) {
        const double rel = (c - cn) / std::max(c, 1e-300);
        T = Tn;
        c = cn;
        mu = std::max(mu * 0.3, 1e-12);
        improved = true;
        if (rel < s.tolerance) it = s.max_iterations;  // converged
      } else {
        mu *= 10;
      }
    }
    if (!improved) break;
  }
  // Re-orthonormalise the rotation accumulated over the updates.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(T.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.topLeftCorner<3, 3>() = svd.matrixU() * svd.matrixV().transpose();
  out.T_target_source = T;
  out.iterations = std::min(it, s.max_iterations);
  out.cost = cost(T);
  if (!T.allFinite() || !std::isfinite(out.cost)) {
    out.T_target_source.setIdentity();
    out.message = "the alignment did not give a finite motor";
    return out;
  }
  out.valid = true;
  return out;
}

#define SCANALIGN_INSTANTIATE(S)                                                                          \
  template NormalLineFlag normalLineFlag<S>(const CloudView<S>&, const CloudView<S>&);                    \
  template FlagAlignmentResult alignFlags<S>(const CloudView<S>&, const CloudView<S>&, const CloudView<S>&, \
                                             const CloudView<S>&, const FlagAlignmentSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
