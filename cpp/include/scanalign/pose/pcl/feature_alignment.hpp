// Stock PCL 1.13 global (coarse) registration baselines for CAD-model pose estimation
// (Kleppe, PhD thesis, NTNU 2018, Paper 5 §IV-A and ch. 3; Paper 3): local descriptors (FPFH,
// SHOT, 3D shape context, PFH, RSD) matched by SampleConsensusPrerejective or SAC-IA,
// point-pair features (PPF) with PCL's hash-map voting, and the global descriptors GASD and
// OUR-CVFH whose reference frames give the pose directly. The declarations are PCL-free; the
// PCL templates are compiled in cpp/src/pose/pcl/feature_alignment.cpp only.
//
// Units are metres. The result's transform maps source coordinates into the target frame
// (T_target_source: p_target = R p_source + t), as every registration in scanalign.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

enum class PclDescriptor {
  FPFH,            ///< pcl::FPFHEstimationOMP, 33 bins (Rusu 2009)
  SHOT,            ///< pcl::SHOTEstimationOMP, 352 bins (Tombari 2010)
  ShapeContext3D,  ///< pcl::ShapeContext3DEstimation, 1980 bins (Frome 2004)
  PPF,             ///< pcl::PPFEstimation + PPFHashMapSearch + PPFRegistration (Drost 2010); no matcher
  PFH,             ///< pcl::PFHEstimation, 125 bins (Rusu 2008); O(k^2) pairs per point, single-threaded in PCL
  RSD,             ///< pcl::RSDEstimation -> PrincipalRadiiRSD (r_min, r_max), 2 values (Marton 2010)
  /// pcl::GASDEstimation, shape only as in the thesis (Lima 2016): global; each cloud's canonical
  /// frame (getTransform()) gives the pose inverse(T_canonical_target) * T_canonical_source; no matcher
  GASD,
  /// VFH: OUR-CVFH (Aldoma 2012), the VFH extension with reference frames (one semi-global unique
  /// reference frame, SGURF, and a 308-bin VFH-like descriptor per smooth cluster); plain VFH gives
  /// no 6-DoF pose. Source and target SGURFs are paired by nearest descriptor, each pair gives a
  /// pose, the best-scoring one is kept; no matcher
  VFH,
};

enum class PclMatcher {
  Prerejective,  ///< pcl::SampleConsensusPrerejective (Buch 2013)
  SacIA,         ///< pcl::SampleConsensusInitialAlignment (Rusu 2009)
};

const char* toString(PclDescriptor descriptor);
const char* toString(PclMatcher matcher);

/// Largest max_iterations accepted: PCL's RANSAC loops cannot be interrupted, so a bound keeps a
/// call finite (1e9 iterations ran for more than ten minutes); 1e6 is 1000x the thesis preset.
inline constexpr int kPclMaxIterations = 1000000;

/// Settings of the PCL baselines. Defaults are the thesis preset (Paper 5 §IV-A: 1 mm voxel
/// grid, normals and features with a 30 mm radius, RANSAC with 1000 iterations and a 5 mm
/// inlier threshold), converted to metres.
struct PclFeatureAlignmentSettings {
  PclDescriptor descriptor = PclDescriptor::FPFH;
  PclMatcher matcher = PclMatcher::Prerejective;  ///< ignored for PPF, GASD and VFH; SacIA only with FPFH
  double voxel_size = 0.001;        ///< m; pcl::VoxelGrid leaf on both clouds first (0: none)
  double normal_radius = 0.03;      ///< m; pcl::NormalEstimationOMP radius (3DSC: 0.04 in the thesis)
  double feature_radius = 0.03;     ///< m; descriptor support radius (3DSC: 0.04 in the thesis)
  double shot_lrf_radius = 0.0;     ///< m; SHOT local reference frame radius (0: feature_radius)
  double shape_context_min_radius = 0.004;      ///< m; 3DSC smallest shell (thesis: 4 mm)
  double shape_context_density_radius = 0.008;  ///< m; 3DSC point-density radius (thesis: 8 mm)
  int max_iterations = 1000;        ///< RANSAC iterations (thesis: 1000), at most kPclMaxIterations
  double inlier_threshold = 0.005;  ///< m; RANSAC inlier distance (thesis: 5 mm)
  int num_samples = 3;              ///< points per RANSAC hypothesis
  int correspondence_randomness = 5;    ///< k nearest features a sample picks from (PCL tutorial: 5)
  double similarity_threshold = 0.9;    ///< prerejective edge-length similarity in [0, 1) (PCL tutorial: 0.9)
  double inlier_fraction = 0.25;        ///< prerejective: required inlier fraction of the source (PCL tutorial: 0.25)
  double min_sample_distance = 0.0;     ///< m; SAC-IA minimum distance between sampled points (0: PCL default)
  double ppf_angle_step = 12.0 * 3.14159265358979323846 / 180.0;  ///< rad; PPF angle discretisation (Drost: 12°)
  double ppf_distance_step = 0.0;   ///< m; PPF distance discretisation (0: 0.05 x the source's diameter)
  double ppf_scene_fraction = 0.1;  ///< PPF: fraction of target points used as reference points (Drost: 1/10 ... 1/5)
  double rsd_plane_radius = 0.2;    ///< m; RSD: radii above this count as a plane (r_max is capped there; PCL default 0.2)
  /// GASD: also score the three half-turns of the source's canonical frame about its axes and keep
  /// the best. The frame's axes are covariance eigenvectors: PCL orients z against the view
  /// direction (0, 0, 1) and leaves x's sign to the eigen-solver, so two views of one object agree
  /// only up to such a half-turn. false: PCL's frames alone (the stock pose).
  bool gasd_half_turns = true;
  double vfh_eps_angle = 0.125;         ///< rad; OUR-CVFH: normal deviation within a smooth cluster (PCL default 0.125)
  double vfh_curvature_threshold = 0.03;  ///< OUR-CVFH: points of higher curvature leave the clusters (PCL default 0.03)
  double vfh_cluster_tolerance = 0.015;   ///< m; OUR-CVFH: point distance within a cluster (PCL default 0.015)
  int vfh_min_points = 50;          ///< OUR-CVFH: smallest cluster, points (PCL default 50)
  /// OUR-CVFH: also score each SGURF pair with the source's normal reversed (a half-turn about
  /// the SGURF's x) and keep the best. A SGURF's z follows its cluster's mean normal, whose sign
  /// is the viewpoint convention of the normals (towards the origin): a model view in the model
  /// frame and a scan in the camera frame need not share it. false: PCL's SGURFs alone.
  bool vfh_normal_flip = true;
  std::uint32_t seed = 0;           ///< seeds std::srand, which PCL's samplers use (runs are then repeatable)
  int num_threads = 0;              ///< OpenMP threads for normals and descriptors; 0 = all cores
};

struct PclFeatureAlignmentResult {
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();  ///< maps source into target
  bool converged = false;           ///< PCL's hasConverged(): a hypothesis was accepted (GASD, VFH: a pose was computed)
  double fitness = 0.0;             ///< fraction of (downsampled) source points within inlier_threshold of the target
  double inlier_rmse = 0.0;         ///< m; RMS distance of those inliers (0 when none)
  std::size_t source_points = 0;    ///< after the voxel grid (and NaN removal)
  std::size_t target_points = 0;    ///< after the voxel grid (and NaN removal)
  std::size_t source_descriptors = 0;  ///< valid (finite) descriptors used for matching (GASD: 1; VFH: SGURFs)
  std::size_t target_descriptors = 0;
  double feature_seconds = 0.0;     ///< voxel grid + normals + descriptors of both clouds
  double seconds = 0.0;             ///< whole call (features + matching + scoring)
  std::string message;              ///< why it failed, empty on success
};

/// Coarse registration of `source` (e.g. a CAD model view) to `target` (e.g. a segmented
/// object) with a stock PCL pipeline. Normals are estimated by PCL from the points (viewpoint
/// at the origin; GASD uses none). Throws std::invalid_argument for bad settings, an empty cloud,
/// or SacIA with a local descriptor other than FPFH. Too few points or descriptors after
/// filtering (VFH: a cloud without a smooth cluster of vfh_min_points), and
/// collinear or coincident points (message "degenerate: ...": the rotation about their line is
/// undetermined), are not exceptions: converged = false and `message` says why.
PclFeatureAlignmentResult pclFeatureAlignment(const CloudView<float>& source, const CloudView<float>& target,
                                              const PclFeatureAlignmentSettings& settings = {});

}  // namespace scanalign
