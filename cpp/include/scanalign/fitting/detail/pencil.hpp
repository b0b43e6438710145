// The symmetric-definite pencil behind the CGA sphere fit (Kleppe, PhD thesis, NTNU 2018, (5.31)-(5.34)), shared by
// fitting/sphere_fit.cpp and the curvature-based descriptor (pose/cbd.cpp). See the
// comment at the top of sphere_fit.cpp for the derivation.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace scanalign::detail {

/// Solution of A a = λ B a with the smallest positive λ, for A symmetric positive semi-definite
/// (the weighted moment matrix D) and B symmetric indefinite (the conformal metric M). With
/// A = LLᵀ (L = VΛ^½) and b = Lᵀa it is the largest-μ eigenvector of C = L⁻¹ B L⁻ᵀ, μ = 1/λ;
/// exact data (singular A) give μ → ∞ with a well-conditioned eigenvector, so they need no
/// special case (A's tiny eigenvalues are clamped at `clamp` times the largest).
template <int N>
struct PencilSolution {
  Eigen::Matrix<double, N, 1> a;             ///< the generalized eigenvector (any scale)
  double lambda;                             ///< smallest positive λ (NaN if none)
  Eigen::Matrix<double, N, 1> a_eigenvalues; ///< eigenvalues of A, ascending (degeneracy tests)
};

template <int N>
PencilSolution<N> smallestPositive(const Eigen::Matrix<double, N, N>& A, const Eigen::Matrix<double, N, N>& B,
                                   double clamp = 1e-30) {
  using Mat = Eigen::Matrix<double, N, N>;
  using Vec = Eigen::Matrix<double, N, 1>;
  Eigen::SelfAdjointEigenSolver<Mat> ea(A);
  const Vec ev = ea.eigenvalues();
  const double floor = std::max(ev(N - 1), 0.0) * clamp;
  Vec inv_sqrt;
  for (int i = 0; i < N; ++i) inv_sqrt(i) = 1.0 / std::sqrt(std::max(ev(i), floor));
  const Mat Linv_T = ea.eigenvectors() * inv_sqrt.asDiagonal();  // L⁻ᵀ with L = VΛ^½
  const Mat C = Linv_T.transpose() * B * Linv_T;
  Eigen::SelfAdjointEigenSolver<Mat> ec(C);
  const double mu = ec.eigenvalues()(N - 1);  // the largest: 1/(smallest positive λ)
  PencilSolution<N> out;
  out.a = Linv_T * ec.eigenvectors().col(N - 1);
  out.lambda = mu > 0 ? 1.0 / mu : std::numeric_limits<double>::quiet_NaN();
  out.a_eigenvalues = ev;
  return out;
}

}  // namespace scanalign::detail
