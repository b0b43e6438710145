// Coarse alignment with the curvature-based descriptor (thesis ch. 6, paper 5): CBD keypoints
// and descriptors on both clouds (pose/cbd.hpp), nearest-descriptor matches, RANSAC over
// the matches with a motor refit (correspondence_ransac.hpp), then a score of the whole source
// cloud against the target. Refine the result with ICP (registration/icp.hpp).
#pragma once

#include <cstddef>
#include <string>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/pose/cbd.hpp"
#include "scanalign/pose/correspondence_ransac.hpp"

namespace scanalign {

struct CbdAlignmentSettings {
  CbdSettings cbd;                        ///< descriptor settings, used for both clouds
  /// Robust pose from the matches. 10000 hypotheses by default (not the baselines' 1000):
  /// descriptor matches on noisy data are mostly outliers, and a hypothesis costs microseconds.
  CorrespondenceRansacSettings ransac = [] {
    CorrespondenceRansacSettings r;
    r.max_iterations = 10000;
    return r;
  }();
  int matches_per_keypoint = 1;           ///< k nearest target descriptors per source keypoint
  /// Sequential RANSAC: after each hypothesis its inlier pairs are removed and RANSAC runs again
  /// on the rest, up to this many hypotheses; the one whose whole source cloud lies best on the
  /// target (fitness, then RMSE) wins. On a part that looks alike after a half turn, the pairs
  /// matched to the wrong twin can outnumber the right ones, so the largest consensus alone
  /// picks the flipped pose; the right one is among the next hypotheses. 1: classic RANSAC.
  int hypotheses = 3;
  /// Spec §7.2: derive δ's from the source's automatic keypoints and apply them to the target
  /// (capped by cbd.max_keypoints, if set). false: each cloud picks its own keypoints.
  bool target_thresholds_from_source = false;
};

struct CbdAlignmentResult {
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();  ///< maps source into target
  bool found = false;                 ///< RANSAC found a consistent set of matches
  double fitness = 0.0;               ///< finite source points within ransac.inlier_threshold of the target / all finite source points
  double inlier_rmse = 0.0;           ///< m, over those points
  std::size_t source_keypoints = 0, target_keypoints = 0;
  std::size_t matches = 0;            ///< descriptor matches fed to RANSAC
  std::size_t match_inliers = 0;      ///< matches consistent with the pose
  double feature_seconds = 0, match_seconds = 0, ransac_seconds = 0, seconds = 0;
  std::string message;                ///< why nothing was found (no keypoints, no consensus, ...)
};

/// Throws std::invalid_argument for bad settings; empty clouds, no keypoints or no consensus
/// are reported through found = false and message.
template <typename Scalar>
CbdAlignmentResult alignCbd(const CloudView<Scalar>& source, const CloudView<Scalar>& target,
                            const CbdAlignmentSettings& settings = {});

/// The same with both clouds' features computed beforehand (computeCbd with settings.cbd), so
/// that a scene's features serve every model view. settings.target_thresholds_from_source is
/// not used here (the caller chose the thresholds).
template <typename Scalar>
CbdAlignmentResult alignCbd(const CloudView<Scalar>& source, const CbdFeatures& source_features,
                            const CloudView<Scalar>& target, const CbdFeatures& target_features,
                            const CbdAlignmentSettings& settings);

}  // namespace scanalign
