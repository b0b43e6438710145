// A part's surface as findParts uses it (pose/part_identification.cpp, pose/part_instances.cpp):
// every view merged, and the search of the instances of several parts in one object cluster.
// Internal: not part of the API.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/part_identification.hpp"
#include "scanalign/pose/pose_estimation.hpp"

namespace scanalign::detail {

/// A part's visible surface from every view, model frame: points and normals (a view's normals
/// face its camera: outward on a closed mesh).
struct PartSurface {
  std::vector<double> points, normals;
  CloudView<double> cloud() const { return {points.data(), points.size() / 3}; }
  CloudView<double> normalCloud() const { return {normals.data(), normals.size() / 3}; }
};

/// Every view's points merged, at most about max_points (every k-th point).
PartSurface partSurface(const std::vector<ModelView>& views, std::size_t max_points);

/// A pose refined against the part's whole surface: the scene's points onto the merged views,
/// point-to-plane ICP with correspondences within polish_distance; kept only while it stays
/// the same pose (same_pose_angle, same_pose_distance).
Eigen::Matrix4d polishOnSurface(const Eigen::Matrix4d& T_scene_model, const PartSurface& surface,
                                const CloudView<double>& scene, const FindPartsSettings& settings);

/// A part's sizes for the size gate (m): all its views together, and its smallest tried view.
struct PartSize {
  double whole = 0, smallest_view = 0;
};

/// The largest extent of a cloud along its principal axes (m): rotation invariant and never
/// more than the cloud's diameter, so a view of a part is never larger than the part.
double principalExtent(const CloudView<double>& cloud);

/// What findParts knows of the parts, computed once per call.
struct PartCatalogue {
  std::vector<std::vector<ModelView>> const& models;
  std::vector<PartSymmetry> const& symmetries;   ///< one per part
  std::vector<std::vector<int>> const& view_ids;  ///< views tried, per part
  std::vector<PoseSettings> const& settings;      ///< partPoseSettings, per part
  std::vector<PartSize> const& sizes;             ///< per part
  std::vector<PartSurface> const& coarse_surfaces;  ///< ~4000 points: table check, instance tests
  std::vector<PartSurface> const& surfaces;         ///< ~40000 points: polish
};

/// Every part's views aligned to one cloud, prepared once (normals, CBD once per distinct
/// radius). A part is skipped (its message says why) when the cloud is smaller than
/// min_size_ratio x its smallest view, or, with `upper_size_gate`, larger than max_size_ratio
/// x the part. Poses through the table (`plane`, null: no table) are dropped.
struct PartPoses {
  PreparedScene prepared;        ///< the cloud at the first part's CBD radius
  std::vector<PoseResult> parts;  ///< per part
  std::vector<bool> tried;        ///< per part: not skipped by the size gate
  double size = 0;                ///< the cloud's principal extent, m
};
PartPoses poseEveryPart(const PartCatalogue& parts, const CloudView<double>& cloud, const PlaneModel* plane,
                        const FindPartsSettings& settings, bool upper_size_gate, const CoarseAligner& aligner,
                        const PoseProgress& progress);

/// The instances of the parts in one object cluster beyond `whole`, the cluster judged as one
/// part (FindPartsSettings::max_instances): when `whole` is found, the points it leaves
/// unexplained; else the whole cluster. Rounds of hypotheses (every view of every part) on
/// the points no instance has claimed, each verified against the cluster and accepted
/// greedily, best first, so that each point is explained by at most one instance.
/// `indices`: the cluster's points in `scene`; `plane`: the table (null: no table check). When
/// it finds instances, `whole` (found) keeps as its indices only the points it explains.
std::vector<PartDetection> findInstances(const PartCatalogue& parts, const CloudView<double>& scene,
                                         const std::vector<std::uint32_t>& indices, PartDetection& whole,
                                         const PlaneModel* plane, const FindPartsSettings& settings,
                                         const CoarseAligner& aligner, const PoseProgress& progress);

}  // namespace scanalign::detail
