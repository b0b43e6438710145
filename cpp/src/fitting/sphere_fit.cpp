// Sphere and circle fitting (Kleppe, PhD thesis, NTNU 2018, §5.1). See sphere_fit.hpp.
//
// Numerics (thesis (5.31)-(5.34)). The CGA fit minimises
//     L(S) = (1/Σw) Σ w_i (S*·P_i)² / S*²                                     (5.27, 6.5)
// whose stationarity condition is Q[S*] = λ[S*], Q = D M, D = (1/Σw) Σ w_i [P_i][P_i]ᵀ (5.31, 6.6).
// With a = M[S*] (so S*·P = aᵀ[P] and S*² = aᵀ M a, because M² = I) this is the symmetric-
// definite pencil D a = λ M a, λ = aᵀDa / aᵀMa = L(S) (thesis (5.29)-(5.31)).
//
// The reformulation that factors D = LLᵀ and solves LᵀML y = λy, s = Ly. That misses the
// exact fit: for points exactly on a sphere (or plane) D is singular, and the solution s = M a
// with a ∈ null(D) does not lie in range(L) = range(D). We therefore use the other symmetric
// form of the same pencil: with D = LLᵀ from D's eigen-decomposition (L = VΛ^½) and b = Lᵀa,
//     C b = μ b,   C = L⁻¹ M L⁻ᵀ,   μ = 1/λ,
// C is symmetric with the inertia of M (Sylvester: four positive, one negative eigenvalue, so Q
// has exactly one negative eigenvalue, thesis (5.31)), and the smallest positive λ is the largest μ.
// As D becomes singular, μ grows without bound and its eigenvector stays well conditioned, so
// exact and nearly exact data are handled by one code path (tiny eigenvalues of D are clamped).
//
// Before all this, the points are centred at their (weighted) centroid and scaled to unit RMS
// spread. L(S) is invariant under rigid motions and scales with the square of a uniform scaling
// (thesis (6.6)), so this changes the solution only by the known similarity, which is undone at the
// end; it keeps D well scaled for data far from the origin or in any unit.
#include "scanalign/fitting/sphere_fit.hpp"
#include "scanalign/common/threads.hpp"
#include "scanalign/fitting/detail/pencil.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <omp.h>

namespace scanalign {

namespace {

constexpr double kClamp = 1e-30;       // floor for D's eigenvalues, relative to the largest
constexpr double kDegenerate = 1e-12;  // second-smallest eigenvalue of D below this (relative): no unique fit
constexpr std::size_t kMinCirclePoints = 3;

struct Normalization {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double scale = 1.0;  // RMS distance to the centroid, m
};

void checkWeight(double w, std::size_t i) {
  if (!std::isfinite(w) || w < 0)
    throw std::invalid_argument("fitSphere: weights[" + std::to_string(i) + "] is negative or not finite");
}

}  // namespace

template <typename Scalar>
SphereFitResult fitSphere(const CloudView<Scalar>& points, const double* weights, const SphereFitOptions& options) {
  if (!(options.plane_tolerance >= 0) || !std::isfinite(options.plane_tolerance))
    throw std::invalid_argument("fitSphere: plane_tolerance must be finite and >= 0");
  // Pass 1: validate, count, weighted centroid.
  std::size_t count = 0;
  double wsum = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < points.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (weights) checkWeight(w, i);
    if (w == 0) continue;  // zero weight: the point is removed
    if (!points.isFinite(i)) throw std::invalid_argument("fitSphere: points[" + std::to_string(i) +
                                  "] is not finite (give it weight 0 to remove it)");
    // The dual sphere holds 1/2 (|c|^2 - r^2) (4.60): beyond ~1e150 m it overflows to inf.
    if (points[i].template cast<double>().cwiseAbs().maxCoeff() > kMaxSphereCoordinate)
      throw std::invalid_argument("fitSphere: points[" + std::to_string(i) +
                                  "]: overflow: coordinates beyond ~1e150 m (the dual sphere squares them)");
    ++count;
    wsum += w;
    sum += w * points[i].template cast<double>();
  }
  if (points.size > 0 && count == 0 && weights) throw std::invalid_argument("fitSphere: weights are all zero");
  if (count < kMinSpherePoints)
    throw std::invalid_argument("fitSphere: need at least " + std::to_string(kMinSpherePoints) +
                                " points (with positive weight), got " + std::to_string(count));
  Normalization nz;
  nz.centroid = sum / wsum;
  double ss = 0;
  for (std::size_t i = 0; i < points.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    ss += w * (points[i].template cast<double>() - nz.centroid).squaredNorm();
  }
  nz.scale = std::sqrt(ss / wsum);
  if (!(nz.scale > 0) || !std::isfinite(nz.scale))
    throw std::invalid_argument("fitSphere: degenerate data (all points coincide)");

  // Pass 2: D = (1/Σw) Σ w [P][P]ᵀ of the normalized points (5.31, 6.6).
  Matrix5d D = Matrix5d::Zero();
  for (std::size_t i = 0; i < points.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    const Vector5d P = cga5::up((points[i].template cast<double>() - nz.centroid) / nz.scale);
    D.noalias() += w * P * P.transpose();
  }
  D /= wsum;

  const Matrix5d M = cga5::metric();
  const detail::PencilSolution<5> sol = detail::smallestPositive<5>(D, M, kClamp);
  if (sol.a_eigenvalues(1) <= kDegenerate * sol.a_eigenvalues(4))
    throw std::invalid_argument(
        "fitSphere: degenerate data (collinear or coincident points, or points on one circle): no unique sphere");
  const Vector5d s = M * sol.a;  // [S*] in normalized coordinates (5.31)

  SphereFitResult out;
  out.count = count;
  out.objective = sol.lambda * nz.scale * nz.scale;  // λ scales with the square of the length unit
  const double e_norm = s.head<3>().norm();
  const double s0 = s(4), sinf = s(3);
  if (std::abs(s0) <= options.plane_tolerance * e_norm) {
    // Plane [n; δ; 0] (4.66): n·q = δ' for q = (p − m)/σ, hence n·p = σδ' + n·m.
    out.is_plane = true;
    Eigen::Vector3d n = s.head<3>() / e_norm;
    double delta = nz.scale * sinf / e_norm + n.dot(nz.centroid);
    if (delta < 0 || (delta == 0 && n.z() < 0)) n = -n, delta = -delta;
    out.normal = n;
    out.distance = delta;
    out.dual << n, delta, 0.0;
    double r2 = 0;
    for (std::size_t i = 0; i < points.size; ++i) {
      const double w = weights ? weights[i] : 1.0;
      if (w == 0) continue;
      const double d = n.dot(points[i].template cast<double>()) - delta;  // up(p)·Π* = n·p − δ (thesis (4.67))
      r2 += w * d * d;
    }
    out.rms = std::sqrt(r2 / wsum);
    return out;
  }
  // Sphere: rescale so that the e0 coefficient is 1 (4.60); r² = S*²/(−e∞·S*)² (4.61).
  const Eigen::Vector3d c_n = s.head<3>() / s0;
  const double r2_n = c_n.squaredNorm() - 2.0 * sinf / s0;
  out.imaginary = r2_n < 0;
  out.center = nz.centroid + nz.scale * c_n;
  out.radius = nz.scale * std::sqrt(std::abs(r2_n));
  const double r2 = out.imaginary ? -out.radius * out.radius : out.radius * out.radius;
  out.dual << out.center, 0.5 * (out.center.squaredNorm() - r2), 1.0;
  if (out.imaginary) return out;  // no geometric residual for an imaginary sphere
  double acc = 0;
  for (std::size_t i = 0; i < points.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    const double d = (points[i].template cast<double>() - out.center).norm() - out.radius;
    acc += w * d * d;
  }
  out.rms = std::sqrt(acc / wsum);
  return out;
}

template <typename Scalar>
SphereFitBatchResult fitSpheres(const CloudView<Scalar>& points, const std::int64_t* offsets, std::size_t n_groups,
                                const SphereFitOptions& options, int num_threads) {
  if (n_groups > 0 && offsets == nullptr) throw std::invalid_argument("fitSpheres: null offsets");
  for (std::size_t g = 0; g < n_groups; ++g)
    if (offsets[g] < 0 || offsets[g + 1] < offsets[g] || static_cast<std::size_t>(offsets[g + 1]) > points.size)
      throw std::invalid_argument("fitSpheres: offsets must be non-decreasing, >= 0 and <= the number of points");
  SphereFitBatchResult batch;
  std::vector<SphereFitResult>& out = batch.fits;
  out.resize(n_groups);
  const long long n = static_cast<long long>(n_groups);
#pragma omp parallel for schedule(dynamic, 64) num_threads(resolveThreads(num_threads))
  for (long long g = 0; g < n; ++g) {
    const std::size_t begin = static_cast<std::size_t>(offsets[g]);
    const std::size_t size = static_cast<std::size_t>(offsets[g + 1]) - begin;
    try {
      const CloudView<Scalar> view(size ? points.ptr(begin) : nullptr, size, points.stride);
      out[static_cast<std::size_t>(g)] = fitSphere(view, nullptr, options);
    } catch (const std::invalid_argument&) {
      out[static_cast<std::size_t>(g)] = SphereFitResult{};  // count = 0, NaN fields
      out[static_cast<std::size_t>(g)].dual.setConstant(std::numeric_limits<double>::quiet_NaN());
    }
  }
  return batch;
}

CircleFitResult fitCirclePratt(const double* xy, std::size_t n) {
  if (n > 0 && xy == nullptr) throw std::invalid_argument("fitCirclePratt: null data");
  if (n < kMinCirclePoints)
    throw std::invalid_argument("fitCirclePratt: need at least 3 points, got " + std::to_string(n));
  Eigen::Vector2d m = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(xy[2 * i]) || !std::isfinite(xy[2 * i + 1]))
      throw std::invalid_argument("fitCirclePratt: point " + std::to_string(i) + " is not finite");
    m += Eigen::Vector2d(xy[2 * i], xy[2 * i + 1]);
  }
  m /= static_cast<double>(n);
  double ss = 0;
  for (std::size_t i = 0; i < n; ++i) ss += (Eigen::Vector2d(xy[2 * i], xy[2 * i + 1]) - m).squaredNorm();
  const double scale = std::sqrt(ss / static_cast<double>(n));
  if (!(scale > 0)) throw std::invalid_argument("fitCirclePratt: degenerate data (all points coincide)");

  // M = (1/n) ZᵀZ with rows z = [x²+y², x, y, 1] of the normalized points; N is Pratt's
  // constraint matrix, cᵀNc = d² + e² − 4af (5.21–5.23). Solve Mc = λNc for the smallest
  // positive λ (5.24–5.25), in the symmetric form described at the top of this file.
  Eigen::Matrix4d Mz = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d q = (Eigen::Vector2d(xy[2 * i], xy[2 * i + 1]) - m) / scale;
    Eigen::Vector4d z(q.squaredNorm(), q.x(), q.y(), 1.0);
    Mz.noalias() += z * z.transpose();
  }
  Mz /= static_cast<double>(n);
  Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
  N(1, 1) = N(2, 2) = 1.0;
  N(0, 3) = N(3, 0) = -2.0;
  const detail::PencilSolution<4> sol = detail::smallestPositive<4>(Mz, N, kClamp);
  if (sol.a_eigenvalues(1) <= kDegenerate * sol.a_eigenvalues(3))
    throw std::invalid_argument("fitCirclePratt: degenerate data (coincident points, or three collinear points)");
  Eigen::Vector4d c = sol.a;
  const double norm = c.dot(N * c);  // > 0 for the smallest positive λ
  c /= std::sqrt(norm);
  const double a = c(0), d = c(1), e = c(2);
  // |a| is 1/(2r') for the unit-constraint normalization: a ≈ 0 means a line (r → ∞).
  if (std::abs(a) <= 1e-9)
    throw std::invalid_argument("fitCirclePratt: the points are collinear (the best fit is a line)");
  const Eigen::Vector2d cn(-d / (2 * a), -e / (2 * a));
  const double rn = 1.0 / (2 * std::abs(a));  // r² = (d² + e² − 4af)/(4a²) = 1/(4a²)
  CircleFitResult out;
  out.count = n;
  out.center = m + scale * cn;
  out.radius = scale * rn;
  // Coefficients in the original units: substitute q = (p − m)/s and renormalize.
  {
    const double A = a / (scale * scale);
    const Eigen::Vector2d DE = Eigen::Vector2d(d, e) / scale - 2 * A * m;
    const double F = c(3) + A * m.squaredNorm() - (d * m.x() + e * m.y()) / scale;
    Eigen::Vector4d k(A, DE.x(), DE.y(), F);
    const double kn = DE.squaredNorm() - 4 * A * F;
    out.coefficients = kn > 0 ? Eigen::Vector4d(k / std::sqrt(kn)) : k;
  }
  double acc = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = (Eigen::Vector2d(xy[2 * i], xy[2 * i + 1]) - out.center).norm() - out.radius;
    acc += r * r;
  }
  out.rms = std::sqrt(acc / static_cast<double>(n));
  return out;
}

template SphereFitResult fitSphere<float>(const CloudView<float>&, const double*, const SphereFitOptions&);
template SphereFitResult fitSphere<double>(const CloudView<double>&, const double*, const SphereFitOptions&);
template SphereFitBatchResult fitSpheres<float>(const CloudView<float>&, const std::int64_t*, std::size_t,
                                                const SphereFitOptions&, int);
template SphereFitBatchResult fitSpheres<double>(const CloudView<double>&, const std::int64_t*, std::size_t,
                                                 const SphereFitOptions&, int);

}  // namespace scanalign
