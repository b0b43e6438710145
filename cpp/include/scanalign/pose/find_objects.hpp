// Poses of a known part in a table scene (Kleppe, PhD thesis, NTNU 2018, ch. 7; paper 3's
// segmentation, paper 5's pose): the table plane and the object clusters
// (segmentation/table_segmentation.hpp), then estimatePose (pose_estimation.hpp) per cluster.
//
// Frames and units: metres. T_scene_model maps model (CAD) coordinates into the scene frame.
#pragma once

#include <cstddef>
#include <vector>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/pose_estimation.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {

struct FindObjectsSettings {
  TableSegmentationSettings table = objectTableSettings();  ///< table plane and object clusters (m)
  std::size_t max_objects = 5;      ///< clusters tried, largest first
  PoseSettings pose;                ///< per cluster, as estimatePose
};

struct FindObjectsResult {
  std::vector<PoseResult> poses;     ///< one per object cluster, largest first
  TableSegmentationResult table;     ///< plane, clusters (indices into the scene) and counts
  double seconds = 0;                ///< wall time
};

/// Poses of a part in a table scene: table plane, clusters, estimatePose per cluster.
/// `view_ids`, `aligner` and `progress` as for estimatePose.
/// @throws std::invalid_argument for bad settings, an index out of range or a missing aligner;
///         NotBuiltError for CoarseMethod::Pcl in a build without PCL.
FindObjectsResult findObjects(const std::vector<ModelView>& views, const CloudView<double>& scene,
                              const FindObjectsSettings& settings = {}, const std::vector<int>& view_ids = {},
                              const CoarseAligner& aligner = {}, const PoseProgress& progress = {});

}  // namespace scanalign
