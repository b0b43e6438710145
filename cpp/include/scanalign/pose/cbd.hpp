// Curvature-based descriptor (CBD) for coarse alignment of a CAD model to a scan
// (Kleppe, PhD thesis, NTNU 2018, ch. 6; paper 5 §III).
//
// Pipeline per cloud:
//  1. PCA of every point's radius neighbourhood (k-d tree search, paper 5 (11)): neighbour
//     count and covariance eigenvalues λ1 ≥ λ2 ≥ λ3.
//  2. Keypoints: either the thresholds of (6.4), |N_i| ≥ n_min and
//     (C_l > δ_l or C_p > δ_p or C_s > δ_s), or the automatic variant of P5 §III-B4 (the k
//     points with the lowest score C_lC_p + C_pC_s + C_sC_l, whose shape factors then set δ).
//  3. Two weighted CGA spheres per keypoint (6.8–6.11): fitted to the neighbourhood
//     with weights exp(−γ |distance to the plane Π_ij|), where Π_i1 ⊥ v2 and Π_i2 ⊥ v1 pass
//     through the keypoint; a weight uses |v·(p − p_i)|, so flipping the sign of any
//     eigenvector changes nothing.
//  4. Descriptors: (r1, d1, r2, d2) of paper 5 (sphere radius and distance from
//     the sphere centre to the keypoint, (29)–(32)) and the scalar F = (S1 + S2)·P
//     = ½(r1² − d1²) + ½(r2² − d2²) of chapter 6 (6.14–6.16).
//  5. Matching: every source keypoint is paired with its nearest target keypoints
//     in descriptor space (a k-d tree over the 4-vectors, a sorted array for F).
//
// Units: metres for points, radii and distances; γ in 1/m (the thesis's 0.2 per mm is 200 per
// m); F in m². The header is PCL-free.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/features/shape_factors.hpp"

namespace scanalign {

/// How keypoints are chosen ((6.4), paper 5 §III-B4).
enum class CbdKeypointMode {
  Thresholds,  ///< (6.4) with the given δ's and n_min
  Automatic,   ///< the num_keypoints lowest-score points (P5 §III-B4); δ's derived from them
};

/// Which descriptor the matcher compares (paper 5 (32), (6.18)).
enum class CbdDescriptorVariant {
  RadiusDistance,  ///< (r1, d1, r2, d2), error Σ (r_k − r_l)² + (d_k − d_l)² (P5 (29)–(32))
  Scalar,          ///< F = (S1 + S2)·P, error (F_k − F_l)² (6.17–6.18)
};

/// δ_l, δ_p, δ_s of (6.4): a point is a keypoint if any shape factor exceeds its δ. A δ ≥ 1
/// disables that factor (a shape factor never exceeds 1; with the inclusive comparison, δ > 1).
struct ShapeThresholds {
  double linear = 0.3;     ///< δ_l (thesis Fig 6.3: 0.3)
  double planar = 1.0;     ///< δ_p (thesis: 1, i.e. planar points are never keypoints)
  double spherical = 0.3;  ///< δ_s (thesis: 0.3)
};

struct CbdSettings {
  double radius = 0.0063;      ///< m; neighbourhood radius r (P5 §IV-A: 6.3 mm)
  double gamma = 200.0;        ///< 1/m; plane-distance weight exp(−γ|d|) (P5: w = 0.2 per mm)
  /// n_min: fewer neighbours (the point included) is never a keypoint (P5: 200, for Zivid
  /// clouds with ~0.2 mm spacing). 0 = automatic: half the median neighbour count of the cloud,
  /// at least 5, for clouds of any density.
  int min_neighbors = 200;
  /// Thresholds by default: on CAD parts dominated by flat faces, the automatic mode's lowest
  /// scores are pure plane points whose spheres are all flat, and matching fails (measured on
  /// the CGAL fandisk views, see bench/experiments/paper5.py); (6.4) with δ_p = 1 keeps edges and corners.
  CbdKeypointMode keypoint_mode = CbdKeypointMode::Thresholds;
  int num_keypoints = 2000;    ///< k of the automatic mode (P5: 2000)
  ShapeThresholds thresholds;  ///< δ's of the Thresholds mode
  /// Cap on keypoints per cloud in the Thresholds mode (and when thresholds derived from another
  /// cloud are applied): the lowest-score ones are kept. 0 = no cap. Default: P5's 2000.
  int max_keypoints = 2000;
  /// m; a fitted sphere larger than this (or a plane) is "flat": r = d = max_sphere_radius and
  /// its F term is 0. Guards the (r, d) descriptor against the arbitrary radius of planar
  /// patches (paper 5 notes it is unstable for planar surfaces).
  double max_sphere_radius = 1.0;
  CbdDescriptorVariant variant = CbdDescriptorVariant::RadiusDistance;
  int num_threads = 0;         ///< OpenMP threads; 0 = all cores
};

/// Whether two settings give the same keypoints and descriptors: every field but
/// num_threads (the features do not depend on the thread count).
bool sameDescriptors(const CbdSettings& a, const CbdSettings& b);

/// PCA summary of one point's neighbourhood.
struct NeighbourhoodPca {
  std::uint32_t count = 0;  ///< points within the radius, the point itself included
  Eigen::Vector3d eigenvalues = Eigen::Vector3d::Zero();  ///< λ1 ≥ λ2 ≥ λ3 ≥ 0 of Σ (p − p̄)(p − p̄)ᵀ, m²
};

/// The weighted CGA sphere of one keypoint and plane ((6.8)-(6.11)).
struct CbdSphere {
  /// Dual sphere [c; ½(c² − r²); 1] on (e1, e2, e3, e∞, e0) in the cloud's frame (a flat one
  /// is stored as the dual plane [n; δ; 0] with |n| = 1).
  Eigen::Matrix<double, 5, 1> dual = Eigen::Matrix<double, 5, 1>::Zero();
  double radius = 0;    ///< r, m (max_sphere_radius when flat)
  double distance = 0;  ///< d = |c − p_i|, m (max_sphere_radius when flat)
  bool flat = false;    ///< the fit was a plane or larger than max_sphere_radius
};

/// Keypoints and descriptors of one cloud.
struct CbdFeatures {
  std::vector<std::uint32_t> keypoints;          ///< indices into the input cloud
  std::vector<Eigen::Vector4d> descriptors;      ///< (r1, d1, r2, d2) per keypoint, m
  std::vector<double> scalar;                    ///< F per keypoint, m² (6.16)
  std::vector<CbdSphere> sphere1, sphere2;       ///< S_i1 (plane ⊥ v2), S_i2 (plane ⊥ v1)
  std::vector<Eigen::Matrix3d> axes;             ///< columns v1, v2, v3 of each keypoint's PCA
  ShapeThresholds thresholds;                    ///< δ's used (derived ones in the automatic mode)
  std::size_t points_with_min_neighbors = 0;     ///< points with |N_i| ≥ n_min
  int min_neighbors = 0;                         ///< n_min used (resolved when the setting is 0)
  double seconds = 0;                            ///< wall time
};

/// Largest coordinate and radius (m) the CBD functions accept: the neighbourhood scatter and
/// the conformal points square coordinate differences, which overflow double precision beyond
/// ~1e154; a larger value is a std::invalid_argument ("overflow"), never a NaN descriptor.
inline constexpr double kMaxCbdCoordinate = 1e100;

/// PCA of every point's neighbourhood of radius `radius` (m), by k-d tree radius search
/// (paper 5 (11)). Non-finite points get count 0. Parallel over points. Throws
/// std::invalid_argument for a bad radius or a coordinate beyond kMaxCbdCoordinate.
template <typename Scalar>
std::vector<NeighbourhoodPca> neighbourhoodPca(const CloudView<Scalar>& points, double radius, int num_threads = 0);

/// Shape factors of one neighbourhood (6.1)–(6.3); zero spread gives all zeros.
ShapeFactors shapeFactorsOf(const NeighbourhoodPca& pca);

/// Score C_lC_p + C_pC_s + C_sC_l of the automatic mode (P5 §III-B4): 0 on a pure line, plane
/// or sphere, 1/3 at C_l = C_p = C_s; points with count < min_neighbors score 1/3 (the maximum).
double keypointScore(const NeighbourhoodPca& pca, int min_neighbors);

/// Indices of the points that pass (6.4): count ≥ min_neighbors and any shape factor > its δ
/// (≥ when `inclusive`, which makes the derived δ's reproduce their keypoints).
/// Ascending order.
std::vector<std::uint32_t> selectKeypoints(const std::vector<NeighbourhoodPca>& pca, const ShapeThresholds& thresholds,
                                           int min_neighbors, bool inclusive = false);

/// Automatic keypoints (P5 §III-B4): the `k` points with the lowest score (ascending index
/// order), and the δ's they imply: each keypoint lowers the δ of its largest shape factor to
/// that factor's value; a group no keypoint belongs to keeps δ = 2 (disabled). Applying the δ's with inclusive = true to the same
/// cloud selects (a superset of, and with distinct scores exactly) these keypoints.
std::vector<std::uint32_t> automaticKeypoints(const std::vector<NeighbourhoodPca>& pca, int k, int min_neighbors,
                                              ShapeThresholds* thresholds);

/// Full CBD of a cloud. `thresholds_override` (may be null) forces the Thresholds mode with
/// these δ's (inclusive), e.g. δ's derived from the model cloud applied to the scene
/// (paper 5 §III-B4). Throws std::invalid_argument for bad settings or a coordinate / radius
/// beyond kMaxCbdCoordinate; every descriptor returned is finite.
template <typename Scalar>
CbdFeatures computeCbd(const CloudView<Scalar>& points, const CbdSettings& settings,
                       const ShapeThresholds* thresholds_override = nullptr);

/// Descriptor correspondences: for every source keypoint, its `k` nearest target keypoints in
/// descriptor space (variant as in the settings). Returns pairs (source keypoint position,
/// target keypoint position) into the features' keypoint arrays, with their descriptor errors.
struct CbdMatches {
  std::vector<std::uint32_t> source;  ///< positions in source.keypoints
  std::vector<std::uint32_t> target;  ///< positions in target.keypoints
  std::vector<double> error;          ///< e(k, l) of (32) or g of (6.18)
};
CbdMatches matchCbd(const CbdFeatures& source, const CbdFeatures& target, CbdDescriptorVariant variant, int k = 1,
                    int num_threads = 0);

}  // namespace scanalign
