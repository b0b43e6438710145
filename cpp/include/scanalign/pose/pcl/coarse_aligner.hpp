// The stock PCL 1.13 coarse registrations (FPFH, SHOT, 3DSC, PPF; the thesis's baselines,
// Kleppe, PhD thesis, NTNU 2018, §7.6) as a CoarseAligner for estimatePose/findObjects.
// Part of scanalign::pcl (needs PCL at link time; this header is PCL-free).
#pragma once

#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/pose/pose_estimation.hpp"

namespace scanalign {

/// The thesis's settings for a baseline (§7.6): 1 mm voxel grid, 30 mm normal and feature
/// radius (3DSC: 40 mm, 4 mm minimal and 8 mm density radius), 1000 RANSAC iterations and a
/// 5 mm inlier threshold; PPF: 30 mm normals.
PclFeatureAlignmentSettings thesisPclPreset(PclDescriptor descriptor, PclMatcher matcher = PclMatcher::Prerejective);

/// Aligns each view (as float32) to the finite scene points with pclFeatureAlignment.
/// Use with PoseSettings::method = CoarseMethod::External.
CoarseAligner pclCoarseAligner(const PclFeatureAlignmentSettings& settings);

}  // namespace scanalign
