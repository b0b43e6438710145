// _core.segmentation: RANSAC plane / sphere (thesis §5.2) and table segmentation (paper 3).
// The result structs are bound directly, their Python docs written here once;
// python/scanalign/segmentation.py validates and converts inputs.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <string>

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

using PlaneResult = RansacResult<PlaneModel>;
using SphereResult = RansacResult<SphereModel>;

/// The fields every RANSAC result shares.
template <typename Model>
void bindCommon(py::class_<RansacResult<Model>>& c) {
  using R = RansacResult<Model>;
  c.def_property_readonly(
       "status", [](const R& r) { return std::string(toString(r.status)); },
       "\"success\", or \"degenerate\" (no non-degenerate sample was drawn)")
      .def_property_readonly("success", &R::success, "status == \"success\"")
      .def_property_readonly(
          "inliers", [](const R& r) { return indexArray(r.inliers); },
          "(K,) int64 input row indices (ascending) within threshold of the returned model")
      .def_readonly("iterations", &R::iterations, "hypotheses drawn (degenerate samples included)")
      .def_readonly("degenerate_samples", &R::degenerate_samples, "samples rejected as degenerate")
      .def_readonly("refined", &R::refined, "the least-squares refit was applied")
      .def_readonly("hypothesis_inliers", &R::hypothesis_inliers, "inlier count of the winning minimal-sample hypothesis");
}

/// normal . p - distance for one point (3,) or points (N, 3) (4.67), metres.
py::object signedDistance(const PlaneResult& r, const py::array_t<double, py::array::c_style | py::array::forcecast>& p) {
  if (p.ndim() == 1 && p.shape(0) == 3)
    return py::float_(r.model.signedDistance(Eigen::Vector3d(p.at(0), p.at(1), p.at(2))));
  if (p.ndim() != 2 || p.shape(1) != 3) throw py::value_error("points: expected shape (3,) or (N, 3)");
  py::array_t<double> out(p.shape(0));
  auto in = p.unchecked<2>();
  for (py::ssize_t i = 0; i < p.shape(0); ++i)
    out.mutable_data()[i] = r.model.signedDistance(Eigen::Vector3d(in(i, 0), in(i, 1), in(i, 2)));
  return std::move(out);
}

template <typename Scalar>
PlaneResult plane(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
               int num_threads, bool refine) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  const RansacSettings s = settingsFrom(threshold, max_iterations, confidence, seed, num_threads, refine);
  RansacResult<PlaneModel> r;
  {
    py::gil_scoped_release release;
    r = ransacPlane(view, s);
  }
  return r;
}

template <typename Scalar>
SphereResult sphere(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
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
  return r;
}

template <typename Scalar>
TableSegmentation table(const py::array& points, double threshold, int max_iterations, double confidence, std::uint64_t seed,
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
  return r;
}

}  // namespace

void defineSegmentation(py::module_& m) {
  py::class_<PlaneResult> plane_result(m, "PlaneResult",
                                       "A RANSAC plane normal . p = distance (metres), |normal| = 1, with the CGA "
                                       "plane model (thesis 5.35-5.36)");
  bindCommon(plane_result);
  plane_result
      .def_property_readonly(
          "normal", [](const PlaneResult& r) { return Eigen::Vector3d(r.model.normal); },
          "(3,) unit normal (the dual plane Pi* = n + distance e_inf)")
      .def_property_readonly(
          "distance", [](const PlaneResult& r) { return r.model.distance; },
          "signed distance of the plane from the origin along normal, m")
      .def_property_readonly(
          "hypothesis_normal", [](const PlaneResult& r) { return Eigen::Vector3d(r.hypothesis.normal); },
          "(3,) the winning minimal-sample plane's normal")
      .def_property_readonly(
          "hypothesis_distance", [](const PlaneResult& r) { return r.hypothesis.distance; },
          "the winning minimal-sample plane's distance, m")
      .def("signed_distance", &signedDistance, py::arg("points"),
           "normal . p - distance for one point (3,) or points (N, 3) (4.67), m")
      .def("__repr__", [](const PlaneResult& r) {
        return "PlaneResult(status=" + std::string(toString(r.status)) + ", normal=(" +
               std::to_string(r.model.normal.x()) + ", " + std::to_string(r.model.normal.y()) + ", " +
               std::to_string(r.model.normal.z()) + "), distance=" + std::to_string(r.model.distance) +
               ", inliers=" + std::to_string(r.inliers.size()) + ")";
      });
  py::class_<SphereResult> sphere_result(m, "SphereResult",
                                         "A RANSAC sphere |p - center| = radius (metres), the CGA sphere through "
                                         "four points (thesis 4.58-4.60)");
  bindCommon(sphere_result);
  sphere_result
      .def_property_readonly(
          "center", [](const SphereResult& r) { return Eigen::Vector3d(r.model.center); }, "(3,) centre, m")
      .def_property_readonly(
          "radius", [](const SphereResult& r) { return r.model.radius; }, "radius, m")
      .def_property_readonly(
          "hypothesis_center", [](const SphereResult& r) { return Eigen::Vector3d(r.hypothesis.center); },
          "(3,) the winning minimal-sample sphere's centre, m")
      .def_property_readonly(
          "hypothesis_radius", [](const SphereResult& r) { return r.hypothesis.radius; },
          "the winning minimal-sample sphere's radius, m")
      .def("__repr__", [](const SphereResult& r) {
        return "SphereResult(status=" + std::string(toString(r.status)) + ", center=(" +
               std::to_string(r.model.center.x()) + ", " + std::to_string(r.model.center.y()) + ", " +
               std::to_string(r.model.center.z()) + "), radius=" + std::to_string(r.model.radius) +
               ", inliers=" + std::to_string(r.inliers.size()) + ")";
      });
  py::class_<TableSegmentation>(m, "TableSegmentation", "Result of segment_table (paper 3 §3.1.2-3.1.3)")
      .def_readonly("plane", &TableSegmentation::plane,
                    "the table (PlaneResult, normal oriented up / towards the camera; inliers index the input)")
      .def_property_readonly(
          "objects",
          [](const TableSegmentation& t) {
            py::list objects;
            for (const auto& c : t.objects) objects.append(indexArray(c));
            return objects;
          },
          "one int64 index array per object (ascending input rows), largest first")
      .def_readonly("cropped_points", &TableSegmentation::cropped_points,
                    "finite points inside the crop box (all finite points without crop)")
      .def_readonly("above_points", &TableSegmentation::above_points,
                    "points left above the table before clustering")
      .def_property_readonly(
          "status", [](const TableSegmentation& t) { return std::string(toString(t.status)); },
          "the table plane RANSAC's status")
      .def_property_readonly("success", &TableSegmentation::success, "the table plane was found");
  py::class_<RansacSettings>(m, "RansacSettings", "RANSAC settings of a plane/sphere fit")
      .def(py::init<>())
      .def_readwrite("threshold", &RansacSettings::threshold, "inlier distance, m")
      .def_readwrite("max_iterations", &RansacSettings::max_iterations, "most hypotheses drawn")
      .def_readwrite("confidence", &RansacSettings::confidence, "adaptive stop; outside (0, 1) disables it")
      .def_readwrite("seed", &RansacSettings::seed, "sample k is drawn from a generator seeded by (seed, k)")
      .def_readwrite("num_threads", &RansacSettings::num_threads, "0 = all cores; never changes the result")
      .def_readwrite("refine", &RansacSettings::refine, "least-squares refit of the winner over its inliers");
  py::class_<TableSegmentationSettings>(m, "TableSegmentationSettings", "Table plane and object clusters (metres)")
      .def(py::init<>())
      .def_readwrite("crop", &TableSegmentationSettings::crop, "apply the pass-through box crop_min..crop_max")
      .def_readwrite("crop_min", &TableSegmentationSettings::crop_min, "(3,) m")
      .def_readwrite("crop_max", &TableSegmentationSettings::crop_max, "(3,) m")
      .def_readwrite("plane", &TableSegmentationSettings::plane, "RansacSettings of the table plane")
      .def_readwrite("viewpoint", &TableSegmentationSettings::viewpoint, "(3,) camera centre the normal faces, m")
      .def_readwrite("up", &TableSegmentationSettings::up, "(3,) up direction (zero: use viewpoint)")
      .def_readwrite("cluster_tolerance", &TableSegmentationSettings::cluster_tolerance, "m; linked points")
      .def_readwrite("min_cluster_size", &TableSegmentationSettings::min_cluster_size, "points")
      .def_readwrite("max_cluster_size", &TableSegmentationSettings::max_cluster_size, "points");
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
