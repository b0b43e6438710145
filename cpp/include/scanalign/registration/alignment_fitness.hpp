// How well two clouds fit once one is moved onto the other: the fitness and inlier RMSE of
// a registration (Open3D's evaluate_registration; the scores of Kleppe, PhD thesis, NTNU
// 2018, §7.4: fitness of a model view on the object, and the object's coverage).
#pragma once

#include <utility>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// Fraction of finite source points whose nearest target point, after T_target_source, is
/// closer than `threshold` (m), and the RMS distance of those points (m). (0, 0) for an
/// empty source or target.
/// @throws std::invalid_argument for a threshold that is not finite and > 0, or a
///         non-finite transform.
template <typename Scalar>
std::pair<double, double> alignmentFitness(const CloudView<Scalar>& source, const CloudView<Scalar>& target,
                                           const Eigen::Matrix4d& T_target_source, double threshold,
                                           int num_threads = 0);

}  // namespace scanalign
