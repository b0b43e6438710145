// The stock PCL 1.13 coarse registrations (FPFH, SHOT, 3DSC, PPF; the thesis's baselines,
// Kleppe, PhD thesis, NTNU 2018, §7.6) as a CoarseAligner for estimatePose, findObjects and
// findParts, which build it themselves for CoarseMethod::Pcl (PoseSettings::pcl). This header
// and its functions are PCL-free; pclFeatureAlignment itself is in scanalign::pcl (a build
// without PCL has a stub that throws NotBuiltError).
#pragma once

#include <string>

#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/pose/pose_estimation.hpp"

namespace scanalign {

/// The thesis's settings for a baseline (§7.6): 1 mm voxel grid, 30 mm normal and feature
/// radius (3DSC: 40 mm, 4 mm minimal and 8 mm density radius), 1000 RANSAC iterations and a
/// 5 mm inlier threshold; PPF: 30 mm normals.
PclFeatureAlignmentSettings thesisPclPreset(PclDescriptor descriptor, PclMatcher matcher = PclMatcher::Prerejective);

/// Aligns each view (as float32) to the finite scene points with pclFeatureAlignment.
/// estimatePose uses it for CoarseMethod::Pcl; any caller may pass it (or a wrapper of it) as
/// the aligner of CoarseMethod::External.
CoarseAligner pclCoarseAligner(const PclFeatureAlignmentSettings& settings);

/// The baseline's name as PoseResult::method reports it: the descriptor ("fpfh", "shot",
/// "3dsc", "ppf", "pfh", "rsd", "gasd", "vfh"), with "_sac_ia" for the SAC-IA matcher (PPF, GASD
/// and VFH have no matcher).
std::string pclBaselineName(const PclFeatureAlignmentSettings& settings);

/// @throws NotBuiltError when scanalign was built without PCL (before any work is done).
void requirePclBaselines(const PclFeatureAlignmentSettings& settings);

}  // namespace scanalign
