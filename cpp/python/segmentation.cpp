// _core.segmentation: RANSAC plane / sphere (thesis §5.2) and table segmentation (paper 3).
// Results come back as dicts; python/scanalign/segmentation.py validates inputs and wraps
// them in dataclasses.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "scanalign/fitting/ransac.hpp"

namespace scanalign::python {

namespace {

py::array_t<std::int64_t> indexArray(const std::vector<std::uint32_t>& v) {
  py::array_t<std::int64_t> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

RansacSettings settingsFrom(double threshold, int max_iterations, double confidence, std::uint64_t seed,
                            int num_threads, bool refine) {
  RansacSettings s;
  s.threshold = threshold;
  s.max_iterations = max_iterations;
  s.confidence = confidence;
  s.seed = seed;
  s.num_threads = num_threads;
  s.refine = refine;
  return s;
}

template <typename Model>
py::dict common(const RansacResult<Model>& r) {
  py::dict d;
  d["status"] = toString(r.status);
  d["inliers"] = indexArray(r.inliers);
  d["hypothesis_inliers"] = r.hypothesis_inliers;
  d["iterations"] = r.iterations;
  d["degenerate_samples"] = r.degenerate_samples;
  d["refined"] = r.refined;
  return d;
}

py::dict planeDict(const RansacResult<PlaneModel>& r) {
  py::dict d = common(r);
  d["normal"] = r.model.normal;
  d["distance"] = r.model.distance;
  d["hypothesis_normal"] = r.hypothesis.normal;
  d["hypothesis_distance"] = r.hypothesis.distance;
  return d;
}

py::dict sphereDict(const RansacResult<SphereModel>& r) {
  py::dict d = common(r);
  d["center"] = r.model.center;
  d["radius"] = r.model.radius;
  d["hypothesis_center"] = r.hypothesis.center;
  d["hypothesis_radius"] = r.hypothesis.radius;
  return d;
}

template <typename Scalar>
py::dict plane(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
               int num_threads, bool refine) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  const RansacSettings s = settingsFrom(threshold, max_iterations, confidence, seed, num_threads, refine);
  RansacResult<PlaneModel> r;
  {
    py::gil_scoped_release release;
    r = ransacPlane(view, s);
  }
  return planeDict(r);
}

template <typename Scalar>
py::dict sphere(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
                int num_threads, bool refine, double min_radius, double max_radius) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  const RansacSettings s = settingsFrom(threshold, max_iterations, confidence, seed, num_threads, refine);
  SphereLimits lim;
  lim.min_radius = min_radius;
  lim.max_radius = max_radius;
  RansacResult<SphereModel> r;
  {
    py::gil_scoped_release release;
    r = ransacSphere(view, s, lim);
  }
  return sphereDict(r);
}

template <typename Scalar>
py::dict table(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
               int num_threads, bool refine, const py::object& crop_min, const py::object& crop_max,
               const Eigen::Vector3d& viewpoint, const Eigen::Vector3d& up, double cluster_tolerance,
               std::size_t min_cluster_size, std::size_t max_cluster_size) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  TableSegmentationSettings s;
  s.plane = settingsFrom(threshold, max_iterations, confidence, seed, num_threads, refine);
  if (!crop_min.is_none() || !crop_max.is_none()) {
    s.crop = true;
    if (!crop_min.is_none()) s.crop_min = py::cast<Eigen::Vector3d>(crop_min);
    if (!crop_max.is_none()) s.crop_max = py::cast<Eigen::Vector3d>(crop_max);
  }
  s.viewpoint = viewpoint;
  s.up = up;
  s.cluster_tolerance = cluster_tolerance;
  s.min_cluster_size = min_cluster_size;
  s.max_cluster_size = max_cluster_size;
  TableSegmentation r;
  {
    py::gil_scoped_release release;
    r = segmentTable(view, s);
  }
  py::dict d;
  d["status"] = toString(r.status);
  d["plane"] = planeDict(r.plane);
  py::list objects;
  for (const auto& c : r.objects) objects.append(indexArray(c));
  d["objects"] = objects;
  d["cropped_points"] = r.cropped_points;
  d["above_points"] = r.above_points;
  return d;
}

}  // namespace

void defineSegmentation(py::module_& m) {
  m.def("ransac_plane_f32", &plane<float>);
  m.def("ransac_plane_f64", &plane<double>);
  m.def("ransac_sphere_f32", &sphere<float>);
  m.def("ransac_sphere_f64", &sphere<double>);
  m.def("segment_table_f32", &table<float>);
  m.def("segment_table_f64", &table<double>);
  m.def(
      "plane_from_points",
      [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) -> py::object {
        PlaneModel p;
        if (!planeFromPoints(a, b, c, p)) return py::none();
        return py::make_tuple(p.normal, p.distance);
      },
      "Plane through 3 points (5.35) as (normal, distance), None if collinear");
  m.def(
      "sphere_from_points",
      [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
         const Eigen::Vector3d& d) -> py::object {
        SphereModel s;
        if (!sphereFromPoints(a, b, c, d, s)) return py::none();
        return py::make_tuple(s.center, s.radius);
      },
      "Sphere through 4 points (4.58) as (center, radius), None if coplanar");
  m.def(
      "dual_of_outer4",
      [](const cga5::Vec5& a, const cga5::Vec5& b, const cga5::Vec5& c, const cga5::Vec5& d) {
        return cga5::Vec5(cga5::dualOfOuter4(a, b, c, d));
      },
      "(a^b^c^d)* of four 5-vectors in the basis (e1, e2, e3, e_inf, e0)");
}

}  // namespace scanalign::python
