// The steps of estimatePose that findObjects and findParts share (pose/pose_estimation.cpp):
// one part's views against a scene prepared once, candidate scoring and refinement, timing.
// Internal: not part of the API.
#pragma once

#include <chrono>
#include <vector>

#include <Eigen/Core>

#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/pose_estimation.hpp"
#include "scanalign/registration/icp.hpp"

namespace scanalign::detail {

/// Wall time since t0, s.
double secondsSince(std::chrono::steady_clock::time_point t0);

/// The view indices to try: `view_ids`, or every view when empty.
/// @throws std::invalid_argument for an index out of range.
std::vector<int> viewIds(const std::vector<ModelView>& views, const std::vector<int>& view_ids);

/// Refuses, before any work, a coarse method that cannot run: External without an aligner
/// (std::invalid_argument naming `caller`), Pcl in a build without PCL (NotBuiltError).
void requireCoarseMethod(const PoseSettings& settings, const CoarseAligner& aligner, const char* caller);

/// Fitness, coverage, inlier RMSE and score 2 fitness coverage / (fitness + coverage) of `view`
/// placed at T in `scene` (inlier distance settings.inlier_threshold), into `c`.
void scoreCandidate(const ModelView& view, const PreparedScene& scene, const PoseSettings& settings, PoseCandidate& c,
                    const Eigen::Matrix4d& T);

/// `view` refined by `icp` (target: the scene) from `init` into T, and scored (scoreCandidate).
void refineCandidate(const ModelView& view, const PreparedScene& scene, const PoseSettings& settings, Icp<double>& icp,
                     const Eigen::Matrix4d& init, PoseCandidate& c, Eigen::Matrix4d& T);

/// estimatePose on a scene already prepared (findParts prepares each cluster once for all
/// parts); `ids` already checked (viewIds), the method checked (requireCoarseMethod). Leaves
/// `seconds` to the caller.
PoseResult poseInPreparedScene(const std::vector<ModelView>& views, const std::vector<int>& ids,
                               const PreparedScene& prepared, const PoseSettings& settings,
                               const CoarseAligner& aligner, const PoseProgress& progress);

}  // namespace scanalign::detail
