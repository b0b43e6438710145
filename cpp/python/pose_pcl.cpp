// Bindings of the stock PCL global-registration baselines of Kleppe's thesis (PhD thesis, NTNU
// 2018, §7.6; scanalign/pose/pcl/): settings and result, the thesis presets, and the
// alignment itself (NotBuiltError in a build without PCL). PoseSettings.pcl holds the same
// settings for estimate_pose's method 'pcl'.
#include <pybind11/eigen.h>

#include <cstdint>
#include <string>

#include "arrays.hpp"
#include "pose.hpp"
#include "scanalign/pose/pcl/coarse_aligner.hpp"
#include "scanalign/pose/pcl/feature_alignment.hpp"

namespace scanalign::python {

void bindPosePcl(py::module_& m) {
  py::enum_<PclDescriptor>(m, "PclDescriptor", "PCL descriptor of a baseline")
      .value("fpfh", PclDescriptor::FPFH, "FPFHEstimationOMP, 33 bins (Rusu 2009)")
      .value("shot", PclDescriptor::SHOT, "SHOTEstimationOMP, 352 bins (Tombari 2010)")
      .value("shape_context_3d", PclDescriptor::ShapeContext3D, "ShapeContext3DEstimation, 1980 bins (Frome 2004)")
      .value("ppf", PclDescriptor::PPF, "PPF + PPFRegistration (Drost 2010); no matcher")
      .value("pfh", PclDescriptor::PFH, "PFHEstimation, 125 bins (Rusu 2008)")
      .value("rsd", PclDescriptor::RSD, "RSDEstimation, PrincipalRadiiRSD r_min/r_max (Marton 2010)")
      .value("gasd", PclDescriptor::GASD, "GASDEstimation, shape only (Lima 2016): pose from the canonical frames; no matcher")
      .value("vfh", PclDescriptor::VFH,
             "OUR-CVFH (Aldoma 2012), the VFH extension with reference frames (SGURFs); plain VFH gives no 6-DoF "
             "pose; no matcher");
  py::enum_<PclMatcher>(m, "PclMatcher", "PCL feature matcher")
      .value("prerejective", PclMatcher::Prerejective, "SampleConsensusPrerejective (Buch 2013)")
      .value("sac_ia", PclMatcher::SacIA, "SampleConsensusInitialAlignment (Rusu 2009), FPFH only");
  using S = PclFeatureAlignmentSettings;
  fieldsOf(py::class_<S>(m, "PclFeatureAlignmentSettings", "A stock PCL coarse registration (metres, radians)"))
      .field("descriptor", &S::descriptor, "", "PclDescriptor")
      .field("matcher", &S::matcher, "", "PclMatcher (ignored for PPF, GASD, VFH; sac_ia with FPFH only)")
      .field("voxel_size", &S::voxel_size, "m", "VoxelGrid leaf on both clouds first (0: none)")
      .field("normal_radius", &S::normal_radius, "m", "NormalEstimationOMP radius (3DSC: 0.04 in the thesis)")
      .field("feature_radius", &S::feature_radius, "m", "descriptor support radius (3DSC: 0.04 in the thesis)")
      .field("shot_lrf_radius", &S::shot_lrf_radius, "m", "SHOT local reference frame radius (0: feature_radius)")
      .field("shape_context_min_radius", &S::shape_context_min_radius, "m", "3DSC smallest shell (thesis: 0.004)")
      .field("shape_context_density_radius", &S::shape_context_density_radius, "m",
             "3DSC point-density radius (thesis: 0.008)")
      .field("max_iterations", &S::max_iterations, "",
             "RANSAC iterations (thesis: 1000); ValueError beyond 1000000 (PCL's loop cannot be interrupted)")
      .field("inlier_threshold", &S::inlier_threshold, "m", "RANSAC inlier distance (thesis: 0.005)")
      .field("num_samples", &S::num_samples, "", "points per RANSAC hypothesis")
      .field("correspondence_randomness", &S::correspondence_randomness, "",
             "k nearest features a sample picks from (PCL tutorial: 5)")
      .field("similarity_threshold", &S::similarity_threshold, "",
             "prerejective edge-length similarity in [0, 1) (PCL tutorial: 0.9)")
      .field("inlier_fraction", &S::inlier_fraction, "",
             "prerejective: required inlier fraction of the source (PCL tutorial: 0.25)")
      .field("min_sample_distance", &S::min_sample_distance, "m", "SAC-IA minimum distance between samples (0: PCL's)")
      .field("ppf_angle_step", &S::ppf_angle_step, "rad", "PPF angle discretisation (Drost: 12 degrees)")
      .field("ppf_distance_step", &S::ppf_distance_step, "m", "PPF distance step (0: 0.05 x source diameter)")
      .field("ppf_scene_fraction", &S::ppf_scene_fraction, "", "PPF: fraction of target points used as references")
      .field("rsd_plane_radius", &S::rsd_plane_radius, "m", "RSD: radii above count as a plane (PCL default 0.2)")
      .field("gasd_half_turns", &S::gasd_half_turns, "",
             "GASD: also score the canonical frame's three half-turns (eigenvector signs), keep the best")
      .field("vfh_eps_angle", &S::vfh_eps_angle, "rad", "OUR-CVFH: normal deviation in a smooth cluster (PCL 0.125)")
      .field("vfh_curvature_threshold", &S::vfh_curvature_threshold, "",
             "OUR-CVFH: higher-curvature points leave the clusters (PCL 0.03)")
      .field("vfh_cluster_tolerance", &S::vfh_cluster_tolerance, "m", "OUR-CVFH: point distance in a cluster (PCL 0.015)")
      .field("vfh_min_points", &S::vfh_min_points, "", "OUR-CVFH: smallest cluster, points (PCL 50)")
      .field("vfh_normal_flip", &S::vfh_normal_flip, "",
             "OUR-CVFH: also score each SGURF pair with the normal reversed (its sign is a viewpoint convention)")
      .field("seed", &S::seed, "", "seeds std::srand, which PCL's samplers use (runs are then repeatable)")
      .field("num_threads", &S::num_threads, "", "OpenMP threads for normals and descriptors, 0 = all cores")
      .settings();
  m.def("thesis_pcl_preset", &thesisPclPreset, py::arg("descriptor"), py::arg("matcher"),
        "the thesis's baseline settings for a descriptor (1 mm voxels, 30 mm radii, 3DSC 40 mm, 1000 iterations, 5 mm)");
  m.def("pcl_baseline_name", &pclBaselineName, py::arg("settings"),
        "the baseline's name as PoseResult.method reports it: 'fpfh', 'fpfh_sac_ia', 'shot', '3dsc', 'ppf', 'pfh', "
        "'rsd', 'gasd' or 'vfh'");
  using R = PclFeatureAlignmentResult;
  fieldsOf(py::class_<R>(m, "PclFeatureAlignmentResult", "Outcome of a PCL baseline"))
      .output("T_target_source", &R::T_target_source, "m", "(4, 4) maps source into target")
      .derived("transformation", [](const R& r) { return r.T_target_source; }, "m",
               "T_target_source under Open3D's name (RegistrationResult.transformation)")
      .output("converged", &R::converged, "", "PCL's hasConverged(): a hypothesis was accepted")
      .derived("found", [](const R& r) { return r.converged; }, "", "same as converged")
      .output("fitness", &R::fitness, "", "downsampled source points within inlier_threshold of the target")
      .output("inlier_rmse", &R::inlier_rmse, "m", "RMS distance of those inliers (0 when none)")
      .output("source_points", &R::source_points, "", "after the voxel grid")
      .output("target_points", &R::target_points, "", "after the voxel grid")
      .output("source_descriptors", &R::source_descriptors, "", "finite descriptors used")
      .output("target_descriptors", &R::target_descriptors, "", "finite descriptors used")
      .output("feature_seconds", &R::feature_seconds, "s", "voxel grid, normals and descriptors of both clouds")
      .output("seconds", &R::seconds, "s", "whole call")
      .output("message", &R::message, "", "why it failed")
      .result();
  m.def(
      "pcl_feature_alignment",
      [](const py::array& source, const py::array& target, const S& settings) {
        const auto s = cloudView<float>(source, "source");
        const auto t = cloudView<float>(target, "target");
        py::gil_scoped_release release;
        return pclFeatureAlignment(s, t, settings);
      },
      py::arg("source"), py::arg("target"), py::arg("settings"),
      "Stock PCL coarse registration of source onto target ((N, 3) float32, m)");
}

}  // namespace scanalign::python
