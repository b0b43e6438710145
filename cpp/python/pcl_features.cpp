// Binding of the stock PCL global-registration baselines (thesis spec §7.6): one function
// that takes every setting explicitly (the Python package supplies the preset) and returns
// a plain dict, so the baselines' results can be logged without a result class.
#include <pybind11/eigen.h>

#include <cstdint>
#include <string>

#include "arrays.hpp"
#include "scanalign/features/pcl/feature_alignment.hpp"

namespace scanalign::python {

namespace {

PclDescriptor descriptorFromString(const std::string& s) {
  for (auto d : {PclDescriptor::FPFH, PclDescriptor::SHOT, PclDescriptor::ShapeContext3D, PclDescriptor::PPF})
    if (s == toString(d)) return d;
  throw py::value_error("descriptor must be 'fpfh', 'shot', '3dsc' or 'ppf', got '" + s + "'");
}

PclMatcher matcherFromString(const std::string& s) {
  for (auto m : {PclMatcher::Prerejective, PclMatcher::SacIA})
    if (s == toString(m)) return m;
  throw py::value_error("matcher must be 'prerejective' or 'sac_ia', got '" + s + "'");
}

py::dict toDict(const PclFeatureAlignmentResult& r) {
  py::dict d;
  d["T_target_source"] = py::cast(r.T_target_source);  // 4x4 float64 array (a copy)
  d["converged"] = r.converged;
  d["fitness"] = r.fitness;
  d["inlier_rmse"] = r.inlier_rmse;
  d["source_points"] = r.source_points;
  d["target_points"] = r.target_points;
  d["source_descriptors"] = r.source_descriptors;
  d["target_descriptors"] = r.target_descriptors;
  d["feature_seconds"] = r.feature_seconds;
  d["seconds"] = r.seconds;
  d["message"] = r.message;
  return d;
}

}  // namespace

void definePclFeatures(py::module_& m) {
  m.def(
      "pcl_feature_alignment",
      [](const py::array& source, const py::array& target, const std::string& descriptor, const std::string& matcher,
         double voxel_size, double normal_radius, double feature_radius, double shot_lrf_radius,
         double shape_context_min_radius, double shape_context_density_radius, int max_iterations,
         double inlier_threshold, int num_samples, int correspondence_randomness, double similarity_threshold,
         double inlier_fraction, double min_sample_distance, double ppf_angle_step, double ppf_distance_step,
         double ppf_scene_fraction, std::uint32_t seed, int num_threads) {
        const auto s = cloudView<float>(source, "source");
        const auto t = cloudView<float>(target, "target");
        PclFeatureAlignmentSettings settings;
        settings.descriptor = descriptorFromString(descriptor);
        settings.matcher = matcherFromString(matcher);
        settings.voxel_size = voxel_size;
        settings.normal_radius = normal_radius;
        settings.feature_radius = feature_radius;
        settings.shot_lrf_radius = shot_lrf_radius;
        settings.shape_context_min_radius = shape_context_min_radius;
        settings.shape_context_density_radius = shape_context_density_radius;
        settings.max_iterations = max_iterations;
        settings.inlier_threshold = inlier_threshold;
        settings.num_samples = num_samples;
        settings.correspondence_randomness = correspondence_randomness;
        settings.similarity_threshold = similarity_threshold;
        settings.inlier_fraction = inlier_fraction;
        settings.min_sample_distance = min_sample_distance;
        settings.ppf_angle_step = ppf_angle_step;
        settings.ppf_distance_step = ppf_distance_step;
        settings.ppf_scene_fraction = ppf_scene_fraction;
        settings.seed = seed;
        settings.num_threads = num_threads;
        PclFeatureAlignmentResult result;
        {
          // The arrays stay referenced by the caller's frame while the GIL is released;
          // std::invalid_argument from here becomes ValueError (pybind11's default).
          py::gil_scoped_release release;
          result = pclFeatureAlignment(s, t, settings);
        }
        return toDict(result);
      },
      py::arg("source"), py::arg("target"), py::arg("descriptor"), py::arg("matcher"), py::arg("voxel_size"),
      py::arg("normal_radius"), py::arg("feature_radius"), py::arg("shot_lrf_radius"),
      py::arg("shape_context_min_radius"), py::arg("shape_context_density_radius"), py::arg("max_iterations"),
      py::arg("inlier_threshold"), py::arg("num_samples"), py::arg("correspondence_randomness"),
      py::arg("similarity_threshold"), py::arg("inlier_fraction"), py::arg("min_sample_distance"),
      py::arg("ppf_angle_step"), py::arg("ppf_distance_step"), py::arg("ppf_scene_fraction"), py::arg("seed"),
      py::arg("num_threads"),
      "Stock PCL coarse registration of source onto target (metres): descriptor 'fpfh' | 'shot' | '3dsc' | 'ppf', "
      "matcher 'prerejective' | 'sac_ia' (ignored for 'ppf'). Returns a dict with T_target_source (4x4), "
      "converged, fitness, inlier_rmse, point and descriptor counts, feature_seconds, seconds and message.");
}

}  // namespace scanalign::python
