// Shape factors of a PCA neighbourhood (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3); Paper 5 eqs. (13)-(15)):
// C_l = (l1 - l2)/S, C_p = 2 (l2 - l3)/S, C_s = 3 l3/S with S = l1 + l2 + l3 and
// l1 >= l2 >= l3 >= 0 the covariance eigenvalues (m^2; any common scale cancels).
// C_l + C_p + C_s = 1 (thesis (6.1)-(6.3)). Header-only.
#pragma once

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Core>

namespace scanalign {

struct ShapeFactors {
  double linear = 0;     ///< C_l (6.1): 1 for a line
  double planar = 0;     ///< C_p (6.2): 1 for a plane
  double spherical = 0;  ///< C_s (6.3): 1 for an isotropic cloud
};

/// Shape factors of eigenvalues l1 >= l2 >= l3 >= 0 (6.1)-(6.3). The eigenvalues are sorted
/// here (descending), so any order is accepted, and scaled by the largest (any finite size
/// works, the factors are always finite). Throws std::invalid_argument for NaN/Inf, a negative
/// eigenvalue or a zero sum (no spread: the factors are undefined).
inline ShapeFactors shapeFactors(double l1, double l2, double l3) {
  if (!std::isfinite(l1) || !std::isfinite(l2) || !std::isfinite(l3))
    throw std::invalid_argument("shapeFactors: eigenvalues must be finite");
  if (l1 < 0 || l2 < 0 || l3 < 0) throw std::invalid_argument("shapeFactors: eigenvalues must be >= 0");
  double a[3] = {l1, l2, l3};
  std::sort(a, a + 3, [](double x, double y) { return x > y; });
  if (!(a[0] > 0)) throw std::invalid_argument("shapeFactors: eigenvalue sum is zero");
  // The factors are scale-free: divide by the largest first, so that eigenvalues near the top of
  // the double range (1e200 m coordinates give 1e400 m^2) cannot overflow the sum into inf/NaN.
  const double top = a[0];
  for (double& x : a) x /= top;
  const double s = a[0] + a[1] + a[2];
  return {(a[0] - a[1]) / s, 2.0 * (a[1] - a[2]) / s, 3.0 * a[2] / s};
}
inline ShapeFactors shapeFactors(const Eigen::Vector3d& lambda) { return shapeFactors(lambda[0], lambda[1], lambda[2]); }

}  // namespace scanalign
