// _core.segmentation: RANSAC plane / sphere (Kleppe, PhD thesis, NTNU 2018, §5.2) and table
// segmentation (its Paper 3, §3.1.2-3.1.3). The functions take NumPy input directly; settings
// and results are the C++ structs, their Python docs written here once.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <limits>
#include <optional>
#include <string>

#include "arrays.hpp"
#include "pickle.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign::python {

namespace {

using PlaneResult = RansacResult<PlaneModel>;
using SphereResult = RansacResult<SphereModel>;

/// ValueError unless `points` has at least `minimum` finite rows (a minimal sample).
template <typename Scalar>
void requireFinitePoints(const CloudView<Scalar>& points, std::size_t minimum, const char* fn) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < points.size && n < minimum; ++i) n += points.isFinite(i) ? 1 : 0;
  if (n < minimum)
    throw py::value_error(std::string(fn) + " needs at least " + std::to_string(minimum) + " finite points, got " +
                          std::to_string(n));
}

py::array_t<std::int64_t> indexArray(const std::vector<std::uint32_t>& v) {
  py::array_t<std::int64_t> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// Any Python int as a 64-bit seed (taken modulo 2^64, so negative seeds are accepted).
std::uint64_t seedOf(const py::int_& seed) { return PyLong_AsUnsignedLongLongMask(seed.ptr()); }

RansacSettings ransacSettings(double threshold, const py::int_& max_iterations, double confidence,
                              const py::int_& seed, int num_threads, bool refine) {
  RansacSettings s;
  s.threshold = threshold;
  s.max_iterations = boundedInt(max_iterations, "max_iterations", 1);
  s.confidence = confidence;
  s.seed = seedOf(seed);
  s.num_threads = num_threads;
  s.refine = refine;
  return s;
}

/// A 3-vector argument; ValueError naming it otherwise (finiteness is checked by validate()).
Eigen::Vector3d vec3(const py::handle& o, const char* what) {
  const auto a = py::array_t<double, py::array::forcecast>::ensure(o);
  if (!a || a.ndim() != 1 || a.shape(0) != 3)
    throw py::value_error(std::string(what) + ": expected 3 coordinates, metres");
  return {a.at(0), a.at(1), a.at(2)};
}

/// The fields every RANSAC result shares.
template <typename Model>
void bindCommon(py::class_<RansacResult<Model>>& c) {
  using R = RansacResult<Model>;
  c.def_property_readonly(
       "status", [](const R& r) { return std::string(toString(r.status)); },
       "\"success\", \"degenerate\" (no non-degenerate sample was drawn) or \"too_few_points\"")
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

/// A RANSAC model as 4 numbers: a plane (normal, distance), a sphere (center, radius); m.
Eigen::Vector4d packModel(const PlaneModel& p) { return {p.normal.x(), p.normal.y(), p.normal.z(), p.distance}; }
Eigen::Vector4d packModel(const SphereModel& s) { return {s.center.x(), s.center.y(), s.center.z(), s.radius}; }
void unpackModel(const Eigen::Vector4d& v, PlaneModel& p) { p.normal = v.head<3>(), p.distance = v[3]; }
void unpackModel(const Eigen::Vector4d& v, SphereModel& s) { s.center = v.head<3>(), s.radius = v[3]; }

template <typename Model>
void pickleRansacResult(py::module_& m, const char* name) {
  using R = RansacResult<Model>;
  pickleFields(m, name, namedEnum("status", &R::status, 3),
               field<R>(
                   "model", [](const R& r) { return packModel(r.model); },
                   [](R& r, const Eigen::Vector4d& v) { unpackModel(v, r.model); }),
               field<R>(
                   "hypothesis", [](const R& r) { return packModel(r.hypothesis); },
                   [](R& r, const Eigen::Vector4d& v) { unpackModel(v, r.hypothesis); }),
               field("inliers", &R::inliers), field("hypothesis_inliers", &R::hypothesis_inliers),
               field("iterations", &R::iterations), field("degenerate_samples", &R::degenerate_samples),
               field("refined", &R::refined));
}

void pickleSegmentation(py::module_& m) {
  pickleRansacResult<PlaneModel>(m, "PlaneResult");
  pickleRansacResult<SphereModel>(m, "SphereResult");
  using T = TableSegmentationResult;
  pickleFields(m, "TableSegmentationResult", namedEnum("status", &T::status, 3), field("plane", &T::plane),
               field<T>(
                   "objects",
                   [](const T& t) {
                     py::list l;  // one uint32 index array per cluster
                     for (const auto& c : t.objects) l.append(pickling::vectorToArray(c));
                     return l;
                   },
                   [](T& t, const py::list& l) {
                     t.objects.clear();
                     for (py::handle c : l)
                       t.objects.push_back(
                           pickling::arrayToVector<std::vector<std::uint32_t>>(c, "TableSegmentationResult: pickled state 'objects'"));
                   }),
               field("cropped_points", &T::cropped_points), field("above_points", &T::above_points));
  pickleFields(m, "RansacSettings", field("threshold", &RansacSettings::threshold),
               field("max_iterations", &RansacSettings::max_iterations),
               field("confidence", &RansacSettings::confidence), field("seed", &RansacSettings::seed),
               field("num_threads", &RansacSettings::num_threads), field("refine", &RansacSettings::refine),
               field("msac", &RansacSettings::msac));
  using S = TableSegmentationSettings;
  pickleFields(m, "TableSegmentationSettings", field("crop", &S::crop), field("crop_min", &S::crop_min),
               field("crop_max", &S::crop_max), field("plane", &S::plane), field("viewpoint", &S::viewpoint),
               field("up", &S::up), field("cluster_tolerance", &S::cluster_tolerance),
               field("min_cluster_size", &S::min_cluster_size), field("max_cluster_size", &S::max_cluster_size));
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
  py::class_<TableSegmentationResult>(m, "TableSegmentationResult", "Result of segment_table (paper 3 §3.1.2-3.1.3)")
      .def_readonly("plane", &TableSegmentationResult::plane,
                    "the table (PlaneResult, normal oriented up / towards the camera; inliers index the input)")
      .def_property_readonly(
          "objects",
          [](const TableSegmentationResult& t) {
            py::list objects;
            for (const auto& c : t.objects) objects.append(indexArray(c));
            return objects;
          },
          "one int64 index array per object (ascending input rows), largest first")
      .def_readonly("cropped_points", &TableSegmentationResult::cropped_points,
                    "finite points inside the crop box (all finite points without crop)")
      .def_readonly("above_points", &TableSegmentationResult::above_points,
                    "points left above the table before clustering")
      .def_property_readonly(
          "status", [](const TableSegmentationResult& t) { return std::string(toString(t.status)); },
          "the table plane RANSAC's status")
      .def_property_readonly("success", &TableSegmentationResult::success, "the table plane was found");
  py::class_<RansacSettings>(m, "RansacSettings", "RANSAC settings of a plane/sphere fit")
      .def(py::init<>())
      .def_readwrite("threshold", &RansacSettings::threshold, "inlier distance, m")
      .def_property(
          "max_iterations", [](const RansacSettings& s) { return s.max_iterations; },
          [](RansacSettings& s, const py::object& v) { s.max_iterations = boundedInt(v, "max_iterations", 1); },
          "most hypotheses drawn, in [1, 2^31 - 1]")
      .def_readwrite("confidence", &RansacSettings::confidence, "adaptive stop, in [0, 1]; 0 or 1 disables it")
      .def_readwrite("seed", &RansacSettings::seed, "sample k is drawn from a generator seeded by (seed, k)")
      .def_readwrite("num_threads", &RansacSettings::num_threads, "0 = all cores; never changes the result")
      .def_readwrite("refine", &RansacSettings::refine, "least-squares refit of the winner over its inliers")
      .def_readwrite("msac", &RansacSettings::msac,
                     "rank hypotheses by the MSAC cost sum min(e^2, threshold^2) (Torr and Zisserman 2000) instead "
                     "of the inlier count")
      .def("validate", [](const RansacSettings& s) { validate(s); }, "ValueError naming an invalid field");
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
      .def_readwrite("max_cluster_size", &TableSegmentationSettings::max_cluster_size, "points")
      .def("validate", [](const TableSegmentationSettings& s) { validate(s); }, "ValueError naming an invalid field");
  pickleSegmentation(m);
  const RansacSettings dr;
  m.def(
      "ransac_plane",
      [](const py::object& points, double threshold, const py::int_& max_iterations, double confidence, const py::int_& seed,
         bool refine, int num_threads) {
        const RansacSettings s = ransacSettings(threshold, max_iterations, confidence, seed, num_threads, refine);
        validate(s);
        return withCloud(points, "points", [&](auto view) {
          requireFinitePoints(view, 3, "ransac_plane");
          py::gil_scoped_release release;
          return ransacPlane(view, s);
        });
      },
      py::arg("points"), py::arg("threshold"), py::kw_only(), py::arg("max_iterations") = dr.max_iterations,
      py::arg("confidence") = dr.confidence, py::arg("seed") = 0, py::arg("refine") = dr.refine,
      py::arg("num_threads") = dr.num_threads,
      R"(The dominant plane by RANSAC with the CGA plane model (Kleppe, PhD thesis, NTNU 2018, (5.35)-(5.36)).

Args:
    points: (N, 3) float32/float64, metres; NaN/Inf rows ignored.
    threshold: E_T, metres: a point is an inlier if its distance to the plane is below it.
    max_iterations: n, the most hypotheses drawn, in [1, 2^31 - 1].
    confidence: stop once k >= log(1 - confidence) / log(1 - w^3) for the best inlier ratio w
        so far; in [0, 1], 0 or 1 disables the adaptive stop.
    seed: RNG seed, any int (sample k depends on (seed, k) only).
    refine: PCA refit over the winner's inliers, then inliers re-selected.
    num_threads: OpenMP threads for scoring hypotheses (0 = all); never changes the result.

Returns:
    PlaneResult (status "degenerate" when every sample drawn was collinear).

Raises:
    TypeError: non-float points. ValueError: shape, settings (named), fewer than 3 finite
    points. KeyboardInterrupt: Ctrl-C, checked between batches of hypotheses.)");
  m.def(
      "ransac_sphere",
      [](const py::object& points, double threshold, double min_radius, double max_radius, const py::int_& max_iterations,
         double confidence, const py::int_& seed, bool refine, int num_threads) {
        const RansacSettings s = ransacSettings(threshold, max_iterations, confidence, seed, num_threads, refine);
        validate(s);
        SphereLimits lim;
        lim.min_radius = min_radius;
        lim.max_radius = max_radius;
        return withCloud(points, "points", [&](auto view) {
          requireFinitePoints(view, 4, "ransac_sphere");
          py::gil_scoped_release release;
          return ransacSphere(view, s, lim);
        });
      },
      py::arg("points"), py::arg("threshold"), py::kw_only(), py::arg("min_radius") = 0.0,
      py::arg("max_radius") = std::numeric_limits<double>::infinity(), py::arg("max_iterations") = dr.max_iterations,
      py::arg("confidence") = dr.confidence, py::arg("seed") = 0, py::arg("refine") = dr.refine,
      py::arg("num_threads") = dr.num_threads,
      R"(A sphere by RANSAC with the CGA sphere through four points (Kleppe, PhD thesis, NTNU 2018, (4.58)-(4.60)).

A sample is degenerate (no hypothesis) when its four points lie within threshold of one
plane, or when its sphere's radius is outside [min_radius, max_radius] (metres); on planar
data the result is status "degenerate". The refit (the CGA least-squares fit, (5.31)) is kept
only when its radius is within the limits. Other arguments as ransac_plane (w^4 in the
adaptive stop); at least 4 finite points.)");
  const TableSegmentationSettings dt;
  m.def(
      "segment_table_full",
      [](const py::object& points, double threshold, const py::object& crop_min, const py::object& crop_max,
         const py::object& viewpoint, const py::object& up, double cluster_tolerance, std::int64_t min_cluster_size,
         std::optional<std::int64_t> max_cluster_size, const py::int_& max_iterations, double confidence, const py::int_& seed,
         int num_threads) {
        TableSegmentationSettings s;
        s.plane = ransacSettings(threshold, max_iterations, confidence, seed, num_threads, true);
        s.crop = !crop_min.is_none() || !crop_max.is_none();
        if (!crop_min.is_none()) s.crop_min = vec3(crop_min, "crop_min");
        if (!crop_max.is_none()) s.crop_max = vec3(crop_max, "crop_max");
        s.viewpoint = vec3(viewpoint, "viewpoint");
        if (!up.is_none()) s.up = vec3(up, "up");
        s.cluster_tolerance = cluster_tolerance;
        if (min_cluster_size < 1 || (max_cluster_size && *max_cluster_size < min_cluster_size))
          throw py::value_error("need 1 <= min_cluster_size <= max_cluster_size");
        s.min_cluster_size = static_cast<std::size_t>(min_cluster_size);
        if (max_cluster_size) s.max_cluster_size = static_cast<std::size_t>(*max_cluster_size);
        validate(s);
        return withCloud(points, "points", [&](auto view) {
          requireFinitePoints(view, 3, "segment_table");
          py::gil_scoped_release release;
          return segmentTable(view, s);
        });
      },
      py::arg("points"), py::kw_only(), py::arg("threshold") = dt.plane.threshold, py::arg("crop_min") = py::none(),
      py::arg("crop_max") = py::none(), py::arg("viewpoint") = std::make_tuple(0.0, 0.0, 0.0),
      py::arg("up") = py::none(), py::arg("cluster_tolerance") = dt.cluster_tolerance,
      py::arg("min_cluster_size") = dt.min_cluster_size, py::arg("max_cluster_size") = py::none(),
      py::arg("max_iterations") = dt.plane.max_iterations, py::arg("confidence") = dt.plane.confidence,
      py::arg("seed") = 0, py::arg("num_threads") = dt.plane.num_threads,
      R"(Table plane and object clusters (Paper 3 of Kleppe's thesis, §3.1.2-3.1.3).

(1) optional pass-through crop to a box; (2) RANSAC plane (as ransac_plane, refined) = the
table; (3) remove its inliers and every point below it (signed distance under threshold,
the normal oriented towards up or else the camera viewpoint); (4) Euclidean clustering: the
connected components of the points within cluster_tolerance of each other, by union-find over
cells (O(N log N) for any tolerance, Ctrl-C honoured); (5) clusters outside
[min_cluster_size, max_cluster_size] dropped. Each remaining cluster is one object.
The keywords fill a TableSegmentationSettings.

Args:
    points: (N, 3) float32/float64, metres (e.g. in the camera frame); NaN rows ignored.
    threshold: Delta, metres: plane inlier distance; points closer than this above the
        table are removed with it.
    crop_min, crop_max: pass-through box corners, metres (either may be None: open side;
        inf entries allowed). No crop when both are None.
    viewpoint: camera centre, metres: the table normal is oriented towards it (unless up is
        given). Points on the other side of the table are removed.
    up: optional "up" direction (any length) to orient the normal instead.
    cluster_tolerance: metres: points this close are in the same object.
    min_cluster_size, max_cluster_size: points per object kept (None: no upper limit).
    max_iterations, confidence, seed, num_threads: the plane RANSAC, as ransac_plane.

Returns:
    TableSegmentationResult: the table plane (plane.success False if no plane could be built:
    objects is then empty; after the crop too few points give status "too_few_points"),
    one int64 index array into points per object (largest first), and the point counts
    after the crop and after step (3).

Raises:
    TypeError: non-float points. ValueError: shape, settings, fewer than 3 finite points.)");
  m.def(
      "plane_from_points",
      [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) -> py::object {
        PlaneModel p;
        if (!planeFromPoints(a, b, c, p)) return py::none();
        return py::make_tuple(p.normal, p.distance);
      },
      py::arg("a"), py::arg("b"), py::arg("c"),
      "Plane through three points (metres), the dual of P_A ^ P_B ^ P_C ^ e_inf (5.35) normalised to |n| = 1: "
      "(normal, distance) with normal . p = distance, or None when the points are collinear");
  m.def(
      "sphere_from_points",
      [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
         const Eigen::Vector3d& d) -> py::object {
        SphereModel s;
        if (!sphereFromPoints(a, b, c, d, s)) return py::none();
        return py::make_tuple(s.center, s.radius);
      },
      py::arg("a"), py::arg("b"), py::arg("c"), py::arg("d"),
      "Sphere through four points (metres), the dual of P_A ^ P_B ^ P_C ^ P_D (4.58): (center, radius), or None "
      "when the points are coplanar");
  m.def(
      "dual_of_outer4",
      [](const cga5::Vec5& a, const cga5::Vec5& b, const cga5::Vec5& c, const cga5::Vec5& d) {
        return cga5::Vec5(cga5::dualOfOuter4(a, b, c, d));
      },
      "(a^b^c^d)* of four 5-vectors in the basis (e1, e2, e3, e_inf, e0)");
}

}  // namespace scanalign::python
