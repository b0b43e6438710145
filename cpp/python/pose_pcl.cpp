// Binding of the stock PCL global-registration baselines of Kleppe's thesis (§7.6): settings
// and result bound directly, with the thesis presets from C++.
#include <pybind11/eigen.h>

#include <cstdint>
#include <string>

#include "arrays.hpp"
#include "pickle.hpp"
#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/pose/pcl/coarse_aligner.hpp"

namespace scanalign::python {

void definePclFeatures(py::module_& m) {
  py::enum_<PclDescriptor>(m, "PclDescriptor", "PCL descriptor of a baseline")
      .value("fpfh", PclDescriptor::FPFH, "FPFHEstimationOMP, 33 bins (Rusu 2009)")
      .value("shot", PclDescriptor::SHOT, "SHOTEstimationOMP, 352 bins (Tombari 2010)")
      .value("shape_context_3d", PclDescriptor::ShapeContext3D, "ShapeContext3DEstimation, 1980 bins (Frome 2004)")
      .value("ppf", PclDescriptor::PPF, "PPF + PPFRegistration (Drost 2010); no matcher");
  py::enum_<PclMatcher>(m, "PclMatcher", "PCL feature matcher")
      .value("prerejective", PclMatcher::Prerejective, "SampleConsensusPrerejective (Buch 2013)")
      .value("sac_ia", PclMatcher::SacIA, "SampleConsensusInitialAlignment (Rusu 2009), FPFH only");
  using S = PclFeatureAlignmentSettings;
  py::class_<S>(m, "PclFeatureAlignmentSettings", "A stock PCL coarse registration (metres, radians)")
      .def(py::init<>())
      .def_readwrite("descriptor", &S::descriptor, "PclDescriptor")
      .def_readwrite("matcher", &S::matcher, "PclMatcher (ignored for PPF)")
      .def_readwrite("voxel_size", &S::voxel_size, "m; VoxelGrid leaf on both clouds first (0: none)")
      .def_readwrite("normal_radius", &S::normal_radius, "m; NormalEstimationOMP radius")
      .def_readwrite("feature_radius", &S::feature_radius, "m; descriptor support radius")
      .def_readwrite("shot_lrf_radius", &S::shot_lrf_radius, "m; SHOT local reference frame radius (0: feature_radius)")
      .def_readwrite("shape_context_min_radius", &S::shape_context_min_radius, "m; 3DSC smallest shell")
      .def_readwrite("shape_context_density_radius", &S::shape_context_density_radius, "m; 3DSC point-density radius")
      .def_readwrite("max_iterations", &S::max_iterations,
                     "RANSAC iterations (thesis: 1000); ValueError beyond 1000000 (PCL's loop cannot be interrupted)")
      .def_readwrite("inlier_threshold", &S::inlier_threshold, "m; RANSAC inlier distance (thesis: 0.005)")
      .def_readwrite("num_samples", &S::num_samples, "points per RANSAC hypothesis")
      .def_readwrite("correspondence_randomness", &S::correspondence_randomness, "k nearest features a sample picks from")
      .def_readwrite("similarity_threshold", &S::similarity_threshold, "prerejective edge-length similarity in [0, 1)")
      .def_readwrite("inlier_fraction", &S::inlier_fraction, "prerejective: required inlier fraction of the source")
      .def_readwrite("min_sample_distance", &S::min_sample_distance, "m; SAC-IA minimum distance between samples")
      .def_readwrite("ppf_angle_step", &S::ppf_angle_step, "rad; PPF angle discretisation")
      .def_readwrite("ppf_distance_step", &S::ppf_distance_step, "m; PPF distance step (0: 0.05 x source diameter)")
      .def_readwrite("ppf_scene_fraction", &S::ppf_scene_fraction, "PPF: fraction of target points used as references")
      .def_readwrite("seed", &S::seed, "seeds std::srand, which PCL's samplers use")
      .def_readwrite("num_threads", &S::num_threads, "OpenMP threads, 0 = all cores");
  pickleFields(m, "PclFeatureAlignmentSettings", field("descriptor", &S::descriptor), field("matcher", &S::matcher), field("voxel_size", &S::voxel_size), field("normal_radius", &S::normal_radius), field("feature_radius", &S::feature_radius), field("shot_lrf_radius", &S::shot_lrf_radius), field("shape_context_min_radius", &S::shape_context_min_radius), field("shape_context_density_radius", &S::shape_context_density_radius), field("max_iterations", &S::max_iterations), field("inlier_threshold", &S::inlier_threshold), field("num_samples", &S::num_samples), field("correspondence_randomness", &S::correspondence_randomness), field("similarity_threshold", &S::similarity_threshold), field("inlier_fraction", &S::inlier_fraction), field("min_sample_distance", &S::min_sample_distance), field("ppf_angle_step", &S::ppf_angle_step), field("ppf_distance_step", &S::ppf_distance_step), field("ppf_scene_fraction", &S::ppf_scene_fraction), field("seed", &S::seed), field("num_threads", &S::num_threads));
  m.def("thesis_pcl_preset", &thesisPclPreset, py::arg("descriptor"), py::arg("matcher"),
        "the thesis's baseline settings for a descriptor (1 mm voxels, 30 mm radii, 3DSC 40 mm, 1000 iterations, 5 mm)");
  using R = PclFeatureAlignmentResult;
  py::class_<R>(m, "PclFeatureAlignmentResult", "Outcome of a PCL baseline")
      .def_readonly("T_target_source", &R::T_target_source, "(4, 4) maps source into target")
      .def_property_readonly(
          "transformation", [](const R& r) { return r.T_target_source; },
          "T_target_source under Open3D's name (RegistrationResult.transformation)")
      .def_readonly("converged", &R::converged, "PCL's hasConverged(): a hypothesis was accepted")
      .def_property_readonly("found", [](const R& r) { return r.converged; }, "same as converged")
      .def_readonly("fitness", &R::fitness, "downsampled source points within inlier_threshold of the target")
      .def_readonly("inlier_rmse", &R::inlier_rmse, "m")
      .def_readonly("source_points", &R::source_points, "after the voxel grid")
      .def_readonly("target_points", &R::target_points, "after the voxel grid")
      .def_readonly("source_descriptors", &R::source_descriptors, "finite descriptors used")
      .def_readonly("target_descriptors", &R::target_descriptors, "finite descriptors used")
      .def_readonly("feature_seconds", &R::feature_seconds)
      .def_readonly("seconds", &R::seconds)
      .def_readonly("message", &R::message, "why it failed");
  pickleFields(m, "PclFeatureAlignmentResult", field("T_target_source", &R::T_target_source), field("converged", &R::converged), field("fitness", &R::fitness), field("inlier_rmse", &R::inlier_rmse), field("source_points", &R::source_points), field("target_points", &R::target_points), field("source_descriptors", &R::source_descriptors), field("target_descriptors", &R::target_descriptors), field("feature_seconds", &R::feature_seconds), field("seconds", &R::seconds), field("message", &R::message));
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
