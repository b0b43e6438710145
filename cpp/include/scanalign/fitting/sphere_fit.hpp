// Sphere and circle fitting (Kleppe, PhD thesis, NTNU 2018, §5.1 and §6.3; Dorst's CGA sphere fit, Pratt's circle fit).
//
// This header does not depend on a multivector library: conformal objects are handled as
// 5-vectors of coefficients on (e1, e2, e3, e∞, e0) together with the 5x5 metric M of
// thesis (4.55), (4.60), (4.66), so that X·Y = [X]ᵀ M [Y] (5.32):
//
//   point        [p; ½p²; 1]          (4.55)
//   dual sphere  [c; ½(c² − r²); 1]   (4.60)
//   dual plane   [n; δ; 0]            (4.66), the plane n·p = δ
//
// Units are metres throughout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "scanalign/cga/vector5.hpp"
#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

// 5-vectors on (e1, e2, e3, e∞, e0), their metric M of (5.32) and up(p) (4.55) are the
// ones of scanalign/cga/vector5.hpp (cga5::Vec5, cga5::metric(), cga5::up()).
using Vector5d = cga5::Vec5;
using Matrix5d = cga5::Mat5;

/// Points (with positive weight) a sphere fit needs: four in general position determine a
/// sphere exactly, a least-squares fit needs at least five.
inline constexpr std::size_t kMinSpherePoints = 5;
/// Largest coordinate (m) a sphere fit accepts: the dual sphere holds ½(c² − r²) (4.60), which
/// overflows double precision beyond ~1e154; a larger coordinate is a std::invalid_argument
/// ("overflow"), never a result with inf coefficients.
inline constexpr double kMaxSphereCoordinate = 1e150;

struct SphereFitOptions {
  /// The result is a plane when |e0 coefficient| <= plane_tolerance * |Euclidean part| of the
  /// dual vector computed for the points centred at their centroid and scaled to unit RMS
  /// spread; i.e. when the fitted radius exceeds about 1/plane_tolerance times the extent of
  /// the data. Exactly coplanar data always gives a plane.
  double plane_tolerance = 1e-6;
};

struct SphereFitResult {
  /// The fitted dual object as a 5-vector on (e1, e2, e3, e∞, e0), normalized: a sphere as
  /// [c; ½(c² − r²); 1] (4.60), a plane as [n; δ; 0] with |n| = 1 (4.66).
  Vector5d dual = Vector5d::Zero();
  bool is_plane = false;          ///< the e0 coefficient vanished (relative to scale): a plane
  Eigen::Vector3d center = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());  ///< m (sphere only)
  double radius = std::numeric_limits<double>::quiet_NaN();  ///< m (sphere only; |r| when imaginary)
  bool imaginary = false;         ///< S*² < 0 (r² < 0): an imaginary sphere (not expected in practice, see 5.31)
  Eigen::Vector3d normal = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());  ///< unit (plane only)
  double distance = std::numeric_limits<double>::quiet_NaN();  ///< δ in n·p = δ, m, δ >= 0 (plane only)
  double rms = std::numeric_limits<double>::quiet_NaN();  ///< weighted RMS geometric residual, m
  double objective = std::numeric_limits<double>::quiet_NaN();  ///< λ = weighted mean (S*·P)²/S*² at the optimum, m² (5.27, 5.31)
  std::size_t count = 0;          ///< points used (those with positive weight)
};

/// CGA sphere fit (thesis (5.26)-(5.34); weighted: (6.5)-(6.11)).
///
/// Minimises Σ w_i (S*·P_i)²/S*² / Σ w_i; the minimiser is the eigenvector of the smallest
/// positive eigenvalue of Q = (1/Σw) Σ w_i [P_i][P_i]ᵀ M (5.31/6.6). Points with weight 0 are
/// removed (not even checked for finiteness); integer weights act like duplicated points.
///
/// Requires at least kMinSpherePoints (5) points with positive weight.
///
/// Throws std::invalid_argument for: fewer than 5 used points, a non-finite used point, a used
/// point beyond kMaxSphereCoordinate (1e150 m), a negative or non-finite weight, all weights zero, and degenerate data that does not
/// determine a sphere or plane (coincident or collinear points, points on one circle).
template <typename Scalar>
SphereFitResult fitSphere(const CloudView<Scalar>& points, const double* weights = nullptr,
                          const SphereFitOptions& options = {});

/// The fits of fitSpheres, one per group.
struct SphereFitBatchResult {
  std::vector<SphereFitResult> fits;
  std::size_t size() const { return fits.size(); }
  const SphereFitResult& operator[](std::size_t g) const { return fits[g]; }
};

/// Many independent fits: group g uses points[offsets[g] .. offsets[g+1]) (offsets has
/// n_groups + 1 non-decreasing entries, the last <= points.size). Runs in parallel (OpenMP,
/// num_threads <= 0: all). A group that cannot be fitted (any reason fitSphere throws) gets
/// count = 0 and NaN fields instead of an exception.
template <typename Scalar>
SphereFitBatchResult fitSpheres(const CloudView<Scalar>& points, const std::int64_t* offsets, std::size_t n_groups,
                                const SphereFitOptions& options = {}, int num_threads = 0);

struct CircleFitResult {
  Eigen::Vector2d center = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());  ///< m
  double radius = std::numeric_limits<double>::quiet_NaN();  ///< m
  double rms = std::numeric_limits<double>::quiet_NaN();     ///< RMS geometric residual |‖p − c‖ − r|, m
  /// a(x²+y²) + dx + ey + f = 0, normalized so that d² + e² − 4af = 1 (Pratt's constraint, 5.21).
  Eigen::Vector4d coefficients = Eigen::Vector4d::Zero();
  std::size_t count = 0;
};

/// Pratt's algebraic circle fit (thesis (5.1)-(5.25)) of 2-D points given as n
/// (x, y) pairs, row-major. Requires at least 3 finite points not on one line; throws
/// std::invalid_argument otherwise (fewer than 3, non-finite, collinear or coincident).
CircleFitResult fitCirclePratt(const double* xy, std::size_t n);

}  // namespace scanalign
