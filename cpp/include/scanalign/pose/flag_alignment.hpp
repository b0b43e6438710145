// Initial alignment with motors (Kleppe, PhD thesis, NTNU 2018, paper 4 §2): a global, correspondence-free
// coarse alignment of two partial views of the same surface.
//
// Each cloud {x_i, n̂_i} gives a flag f = ℓ̄ + P: the centroid P = C((1/m)Σ x_i) and the average
// of the normal lines ℓ_i = (x_i + e0)∧n̂_i∧e∞. The mean of the dual lines is a screw A + b e∞
// whose axis (A∧b_∥ = 0) is the average line ℓ̄; in Plücker terms the screw is
// (n̄, m̄) = (1/m)Σ(n̂_i, x_i × n̂_i) and the axis is the line with direction n̄ through
// n̄ × m̄ / |n̄|². The motor M with f_X = M f_Y M̃ minimises
//     ½(ε_ℓ + ε_P) = ½(δ² + sin²(θ/2) + d²)
// (θ, δ: angle and offset between ℓ̄_X and M ℓ̄_Y M̃; d: distance between P_X and M P_Y M̃),
// solved by Levenberg–Marquardt on the motor manifold (updates M ← exp(B) M with a 6-dof
// bivector B), started from the closed-form motor that maps one flag onto the other.
//
// Restriction (paper 4 §2): on a closed surface the unit normals sum to zero, the average line is
// undefined, and the method refuses (valid = false) when |n̄| < min_mean_normal_length.
// Units: metres and radians, mixed without weights as in the thesis.
#pragma once

#include <string>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// The flag of one cloud: its centroid and average normal line.
struct NormalLineFlag {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();   ///< m
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  ///< unit direction of ℓ̄
  Eigen::Vector3d foot = Eigen::Vector3d::Zero();       ///< m; the point of ℓ̄ closest to the centroid
  double mean_normal_length = 0.0;  ///< |n̄| in [0, 1]: 1 for a plane, 0 for a closed surface
  double pitch = 0.0;               ///< m; n̄·m̄/|n̄|² of the averaged screw (0 for a pure line)
  std::size_t count = 0;            ///< points used (finite point and normal)
};

/// Flag of a cloud with unit normals (normals need not be exactly unit; they are normalised).
/// Throws std::invalid_argument for mismatched sizes or no usable point.
template <typename Scalar>
NormalLineFlag normalLineFlag(const CloudView<Scalar>& points, const CloudView<Scalar>& normals);

struct FlagAlignmentSettings {
  /// Refuse when |n̄| of either cloud is below this (closed surfaces, paper 4 §2).
  double min_mean_normal_length = 0.05;
  /// Refuse when the centroid is closer than this (m) to the average line: the rotation
  /// about the line is then undetermined.
  double min_centroid_offset = 1e-6;
  /// Refuse when either cloud has fewer usable points (finite point, non-zero normal): the
  /// average line of a handful of normals says nothing about the surface.
  std::size_t min_points = 10;
  int max_iterations = 100;        ///< LM iterations
  double tolerance = 1e-12;        ///< stop when the cost decreases by less than this (relative)
};

struct FlagAlignmentResult {
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();  ///< maps source into target (f_target = M f_source M̃)
  bool valid = false;
  int iterations = 0;
  double cost = 0.0;          ///< ½(δ² + sin²(θ/2) + d²) at the solution (m² and rad mixed)
  NormalLineFlag source_flag, target_flag;
  std::string message;        ///< why it refused
};

/// Largest coordinate (m) align_flags accepts: the cost mixes metres and radians without weights
/// (paper 4), so far from the thesis's scale (parts of centimetres to metres) the radian terms
/// vanish below the rounding of the metre terms and the rotation is not determined.
inline constexpr double kMaxFlagCoordinate = 1e6;

/// Throws std::invalid_argument for bad settings or inputs (mismatched sizes, no usable point, a
/// coordinate beyond kMaxFlagCoordinate); refusals (fewer than min_points usable points,
/// collinear or coincident points, a closed surface, an undetermined rotation, a non-finite
/// result) are reported through valid = false with the reason in message.
template <typename Scalar>
FlagAlignmentResult alignFlags(const CloudView<Scalar>& source, const CloudView<Scalar>& source_normals,
                               const CloudView<Scalar>& target, const CloudView<Scalar>& target_normals,
                               const FlagAlignmentSettings& settings = {});

}  // namespace scanalign
