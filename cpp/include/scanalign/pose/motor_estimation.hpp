// Rigid motion from point correspondences (Kleppe, PhD thesis, NTNU 2018, paper 5 §III-E, (36)-(44)).
//
// Given pairs (x_k in the source frame, y_k in the target frame), both estimators return the
// least-squares rigid motion T_target_source = argmin Σ w_k |y_k − (R x_k + t)|²:
//
//  * estimateMotor: Valkenburg & Dorst's CGA estimator. The cost is written as a quadratic
//    form in the 8 coefficients of the motor M on the basis c = (1, e23, e31, e12, e1∞, e2∞,
//    e3∞, e123∞): Σ_k ⟨M̃ Y_k M X_k⟩ = mᵀ Q m with Q_ij = Σ_k ⟨c̃_i Y_k c_j X_k⟩ (36–38, the
//    quadratic form that works, not the printed reciprocal-basis form (41)).
//    Eliminating the translation block gives L′ = Q_rr − Q_rt Q_tt⁺ Q_tr (43): the rotor is
//    its top eigenvector, the translation part t = −Q_tt⁺ Q_tr r (44).
//  * estimateRigidSvd: Kabsch / Umeyama with the SVD of the cross-covariance (thesis (2.1)–
//    (2.15), with the translation corrected to t = ȳ − R x̄).
//
// Both are exact on noise-free data and agree to numerical precision on noisy data.
// Header and estimator are PCL-free; units are whatever the points are in (metres in
// scanalign).
#pragma once

#include <cstddef>
#include <string>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

struct MotorEstimationResult {
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();  ///< y ≈ R x + t
  /// The motor M = T R on (1, e23, e31, e12, e1∞, e2∞, e3∞, e123∞) with M M̃ = 1, acting as
  /// Y = M X M̃ on conformal points (thesis ch. 4, motors).
  Eigen::Matrix<double, 8, 1> motor = (Eigen::Matrix<double, 8, 1>() << 1, 0, 0, 0, 0, 0, 0, 0).finished();
  double rmse = 0.0;        ///< weighted RMS of |y_k − (R x_k + t)|, in the points' unit
  std::size_t count = 0;    ///< pairs used (weight > 0)
  bool valid = false;       ///< false: too few pairs or degenerate (collinear) data; T is identity
  std::string message;      ///< why it is not valid
};

/// Valkenburg–Dorst motor estimation from pairs source[i] <-> target[i] (paper 5 (36)-(44)). `weights`
/// (may be null) are non-negative per-pair weights. `normalize` centres and scales the data
/// before forming Q (the estimator is equivariant, so the result is the same up to rounding;
/// normalising keeps Q well conditioned for data far from the origin). Needs 3 non-collinear
/// pairs. Throws std::invalid_argument for mismatched sizes, non-finite points or bad weights.
MotorEstimationResult estimateMotor(const CloudView<double>& source, const CloudView<double>& target,
                                    const double* weights = nullptr, bool normalize = true);

/// Kabsch/SVD estimate from the same pairs (the oracle of the motor estimator; also used inside RANSAC).
MotorEstimationResult estimateRigidSvd(const CloudView<double>& source, const CloudView<double>& target,
                                       const double* weights = nullptr);

/// 4x4 rigid transform of an 8-coefficient motor (basis as above), normalised first.
Eigen::Matrix4d motorToMatrix(const Eigen::Matrix<double, 8, 1>& motor);

}  // namespace scanalign
