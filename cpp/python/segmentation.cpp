// _core.segmentation: RANSAC plane / sphere (Kleppe, PhD thesis, NTNU 2018, §5.2) and table
// segmentation (its Paper 3, §3.1.2-3.1.3). The functions take NumPy input directly; settings
// and results are the C++ structs, their Python docs written here once.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <limits>
#include <optional>
#include <string>
#include <type_traits>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/segmentation/cylinder.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"
#include "warnings.hpp"

namespace scanalign::python {

namespace {

using PlaneResult = RansacResult<PlaneModel>;
using SphereResult = RansacResult<SphereModel>;
using CylinderResult = RansacResult<CylinderModel>;

/// ValueError unless `points` has at least `minimum` finite rows (a minimal sample).
template <typename Scalar>
void requireFinitePoints(const CloudView<Scalar>& points, std::size_t minimum, const char* fn) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < points.size && n < minimum; ++i) n += points.isFinite(i) ? 1 : 0;
  if (n < minimum)
    throw py::value_error(std::string(fn) + " needs at least " + std::to_string(minimum) + " finite points, got " +
                          std::to_string(n));
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
  const auto a = checkedAs<double>(o, what, kReals);
  if (a.ndim() != 1 || a.shape(0) != 3)
    throw py::value_error(std::string(what) + ": expected 3 coordinates, metres");
  return {a.at(0), a.at(1), a.at(2)};
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

/// Int64 indices of uint32 ones (NumPy code indexes with int64), and back (checked).
std::vector<std::int64_t> wideIndices(const std::vector<std::uint32_t>& v) { return {v.begin(), v.end()}; }
std::vector<std::uint32_t> narrowIndices(const py::handle& h, const std::string& where) {
  const std::vector<std::int64_t> v = fields::Conv<std::vector<std::int64_t>>::set(h, where);
  std::vector<std::uint32_t> out;
  out.reserve(v.size());
  for (const std::int64_t i : v) {
    if (i < 0 || i > std::int64_t{0xFFFFFFFF})
      throw py::value_error(where + ": index " + std::to_string(i) + " out of range");
    out.push_back(static_cast<std::uint32_t>(i));
  }
  return out;
}

/// The field table of a RANSAC result: the fields every one shares, then the model's own
/// (`model_fields` adds them), then the table is finished.
template <typename Model, typename ModelFields>
void bindRansacResult(py::class_<RansacResult<Model>> cls, ModelFields model_fields) {
  using R = RansacResult<Model>;
  auto table = fieldsOf(cls);
  table.name("status", &R::status, 3, "",
             "'success', 'degenerate' (no non-degenerate sample was drawn) or 'too_few_points'", false)
      .derived("success", [](const R& r) { return r.success(); }, "", "status == 'success'")
      .field(
          "inliers", [](const R& r) { return wideIndices(r.inliers); },
          [](R& r, py::handle h) { r.inliers = narrowIndices(h, "inliers"); }, "",
          "(K,) int64 input row indices (ascending) within threshold of the returned model", false)
      .output("iterations", &R::iterations, "", "hypotheses drawn (degenerate samples included)")
      .output("degenerate_samples", &R::degenerate_samples, "", "samples rejected as degenerate")
      .output("refined", &R::refined, "", "the least-squares refit was applied")
      .output("hypothesis_inliers", &R::hypothesis_inliers, "", "inlier count of the winning minimal-sample hypothesis");
  model_fields(table);
  table.result();
}

}  // namespace

void defineSegmentation(py::module_& m) {
  py::class_<PlaneResult> plane_result(m, "PlaneResult",
                                       "A RANSAC plane normal . p = distance (metres), |normal| = 1, with the CGA "
                                       "plane model (thesis 5.35-5.36)");
  plane_result
      .def("signed_distance", &signedDistance, py::arg("points"),
           "normal . p - distance for one point (3,) or points (N, 3) (4.67), m")
      .def("__repr__", [](const PlaneResult& r) {
        return "PlaneResult(status=" + std::string(toString(r.status)) + ", normal=(" +
               std::to_string(r.model.normal.x()) + ", " + std::to_string(r.model.normal.y()) + ", " +
               std::to_string(r.model.normal.z()) + "), distance=" + std::to_string(r.model.distance) +
               ", inliers=" + std::to_string(r.inliers.size()) + ")";
      });
  bindRansacResult(plane_result, [](auto& t) {
    using R = PlaneResult;
    t.field(
         "normal", [](const R& r) { return r.model.normal; }, [](R& r, const Eigen::Vector3d& v) { r.model.normal = v; },
         "", "(3,) unit normal (the dual plane Pi* = n + distance e_inf)", false)
        .field(
            "distance", [](const R& r) { return r.model.distance; }, [](R& r, double v) { r.model.distance = v; },
            "m", "signed distance of the plane from the origin along normal", false)
        .field(
            "hypothesis_normal", [](const R& r) { return r.hypothesis.normal; },
            [](R& r, const Eigen::Vector3d& v) { r.hypothesis.normal = v; }, "",
            "(3,) the winning minimal-sample plane's normal", false)
        .field(
            "hypothesis_distance", [](const R& r) { return r.hypothesis.distance; },
            [](R& r, double v) { r.hypothesis.distance = v; }, "m", "the winning minimal-sample plane's distance",
            false);
  });
  py::class_<SphereResult> sphere_result(m, "SphereResult",
                                         "A RANSAC sphere |p - center| = radius (metres), the CGA sphere through "
                                         "four points (thesis 4.58-4.60)");
  sphere_result.def("__repr__", [](const SphereResult& r) {
    return "SphereResult(status=" + std::string(toString(r.status)) + ", center=(" +
           std::to_string(r.model.center.x()) + ", " + std::to_string(r.model.center.y()) + ", " +
           std::to_string(r.model.center.z()) + "), radius=" + std::to_string(r.model.radius) +
           ", inliers=" + std::to_string(r.inliers.size()) + ")";
  });
  bindRansacResult(sphere_result, [](auto& t) {
    using R = SphereResult;
    t.field(
         "center", [](const R& r) { return r.model.center; }, [](R& r, const Eigen::Vector3d& v) { r.model.center = v; },
         "m", "(3,) centre", false)
        .field(
            "radius", [](const R& r) { return r.model.radius; }, [](R& r, double v) { r.model.radius = v; }, "m",
            "radius", false)
        .field(
            "hypothesis_center", [](const R& r) { return r.hypothesis.center; },
            [](R& r, const Eigen::Vector3d& v) { r.hypothesis.center = v; }, "m",
            "(3,) the winning minimal-sample sphere's centre", false)
        .field(
            "hypothesis_radius", [](const R& r) { return r.hypothesis.radius; },
            [](R& r, double v) { r.hypothesis.radius = v; }, "m", "the winning minimal-sample sphere's radius", false);
  });
  py::class_<CylinderResult> cylinder_result(m, "CylinderResult",
                                             "A RANSAC cylinder |(p - point) x axis| = radius (metres) from two "
                                             "oriented points (Schnabel et al. 2007), refitted by least squares");
  cylinder_result
      .def(
          "surface_distance",
          [](const CylinderResult& r, const py::array_t<double, py::array::c_style | py::array::forcecast>& p) {
            if (p.ndim() != 2 || p.shape(1) != 3) throw py::value_error("points: expected shape (N, 3), metres");
            py::array_t<double> out(p.shape(0));
            auto in = p.unchecked<2>();
            for (py::ssize_t i = 0; i < p.shape(0); ++i)
              out.mutable_data()[i] = r.model.surfaceDistance(Eigen::Vector3d(in(i, 0), in(i, 1), in(i, 2)));
            return out;
          },
          py::arg("points"), "| |(p - point) x axis| - radius | of points (N, 3), m")
      .def("__repr__", [](const CylinderResult& r) {
        const auto& c = r.model;
        return "CylinderResult(status=" + std::string(toString(r.status)) + ", point=(" + std::to_string(c.point.x()) +
               ", " + std::to_string(c.point.y()) + ", " + std::to_string(c.point.z()) + "), axis=(" +
               std::to_string(c.axis.x()) + ", " + std::to_string(c.axis.y()) + ", " + std::to_string(c.axis.z()) +
               "), radius=" + std::to_string(c.radius) + ", inliers=" + std::to_string(r.inliers.size()) + ")";
      });
  bindRansacResult(cylinder_result, [](auto& t) {
    using R = CylinderResult;
    t.field(
         "point", [](const R& r) { return r.model.point; }, [](R& r, const Eigen::Vector3d& v) { r.model.point = v; },
         "m", "(3,) a point of the axis (after a refit: the foot of the inliers' centroid)", false)
        .field(
            "axis", [](const R& r) { return r.model.axis; }, [](R& r, const Eigen::Vector3d& v) { r.model.axis = v; },
            "", "(3,) unit axis direction (sign arbitrary)", false)
        .field(
            "radius", [](const R& r) { return r.model.radius; }, [](R& r, double v) { r.model.radius = v; }, "m",
            "radius", false)
        .field(
            "hypothesis_point", [](const R& r) { return r.hypothesis.point; },
            [](R& r, const Eigen::Vector3d& v) { r.hypothesis.point = v; }, "m",
            "(3,) the winning two-point cylinder's axis point", false)
        .field(
            "hypothesis_axis", [](const R& r) { return r.hypothesis.axis; },
            [](R& r, const Eigen::Vector3d& v) { r.hypothesis.axis = v; }, "", "(3,) its axis", false)
        .field(
            "hypothesis_radius", [](const R& r) { return r.hypothesis.radius; },
            [](R& r, double v) { r.hypothesis.radius = v; }, "m", "its radius", false);
  });
  using T = TableSegmentationResult;
  fieldsOf(py::class_<T>(m, "TableSegmentationResult", "Result of segment_table (paper 3 §3.1.2-3.1.3)"))
      .name("status", &T::status, 3, "", "the table plane RANSAC's status", false)
      .derived("success", [](const T& t) { return t.success(); }, "", "the table plane was found")
      .output("plane", &T::plane, "",
              "the table (PlaneResult, normal oriented up / towards the camera; inliers index the input)")
      .field(
          "objects",
          [](const T& t) {
            std::vector<Eigen::Matrix<std::int64_t, Eigen::Dynamic, 1>> objects;  // shown as int64 arrays
            for (const auto& c : t.objects) {
              objects.emplace_back(static_cast<Eigen::Index>(c.size()));
              std::copy(c.begin(), c.end(), objects.back().data());
            }
            return objects;
          },
          [](T& t, py::handle h) {
            if (!py::isinstance<py::list>(h) && !py::isinstance<py::tuple>(h))
              fields::wrongType("TableSegmentationResult.objects", "a list of index arrays", h);
            std::vector<std::vector<std::uint32_t>> objects;
            for (py::handle c : h) objects.push_back(narrowIndices(c, "TableSegmentationResult.objects"));
            t.objects = std::move(objects);
          },
          "", "one int64 index array per object (ascending input rows), largest first", false)
      .output("cropped_points", &T::cropped_points, "",
              "finite points inside the crop box (all finite points without crop)")
      .output("above_points", &T::above_points, "", "points left above the table before clustering")
      .output("warning", &T::warning, "",
              "empty, or why the result is suspect (an up that puts the viewpoint below the table); also raised as "
              "a UserWarning")
      .result();
  using RS = RansacSettings;
  fieldsOf(py::class_<RS>(m, "RansacSettings",
                          "RANSAC settings of a plane/sphere fit. validate() raises ValueError naming a bad field."))
      .field("threshold", &RS::threshold, "m", "inlier distance E_T: a point is an inlier if its error is below it")
      .field("max_iterations", &RS::max_iterations, "", "most hypotheses drawn, in [1, 2^31 - 1]")
      .field("confidence", &RS::confidence, "", "adaptive stop, in [0, 1]; 0 or 1 disables it")
      .field("seed", &RS::seed, "", "sample k is drawn from a generator seeded by (seed, k)")
      .field("num_threads", &RS::num_threads, "", "0 = all cores; never changes the result")
      .field("refine", &RS::refine, "", "least-squares refit of the winner over its inliers")
      .field("msac", &RS::msac, "",
             "rank hypotheses by the MSAC cost sum min(e^2, threshold^2) (Torr and Zisserman 2000) instead of the "
             "inlier count")
      .settings()
      .def("validate", [](const RS& s) { validate(s); }, "ValueError naming an invalid field");
  using CS = CylinderSettings;
  fieldsOf(py::class_<CS>(m, "CylinderSettings",
                          "Cylinder RANSAC settings (metres, radians). validate() raises ValueError naming a bad field."))
      .field("ransac", &CS::ransac, "", "RansacSettings (threshold: inlier distance from the surface)")
      .field("min_radius", &CS::min_radius, "m", "smallest radius a hypothesis may have")
      .field("max_radius", &CS::max_radius, "m", "largest radius a hypothesis may have")
      .field("max_normal_angle", &CS::max_normal_angle, "rad",
             "an inlier's normal lies within this angle of the direction from the axis")
      .field("normal_radius", &CS::normal_radius, "m", "PCA normal radius when no normals are given")
      .settings()
      .def("validate", [](const CS& c) { validate(c); }, "ValueError naming an invalid field");
  using TS = TableSegmentationSettings;
  fieldsOf(py::class_<TS>(m, "TableSegmentationSettings",
                          "Table plane and object clusters (metres). validate() raises ValueError naming a bad field."))
      .field("crop", &TS::crop, "", "apply the pass-through box crop_min..crop_max")
      .field("crop_min", &TS::crop_min, "m", "(3,) lower corner of the crop box (-inf: open side)")
      .field("crop_max", &TS::crop_max, "m", "(3,) upper corner of the crop box (inf: open side)")
      .field("plane", &TS::plane, "", "RansacSettings of the table plane (threshold = Delta)")
      .field("viewpoint", &TS::viewpoint, "m",
             "(3,) the sensor's centre in the cloud's frame, which the table normal faces unless up is given; None: "
             "the origin (a cloud in its camera frame)")
      .field("up", &TS::up, "",
             "(3,) up direction the table normal faces (zero: face the viewpoint); one that puts the viewpoint below "
             "the table gives a warning")
      .field("cluster_tolerance", &TS::cluster_tolerance, "m", "points this close are linked into one object")
      .field("min_cluster_size", &TS::min_cluster_size, "", "objects with fewer points are dropped")
      .field("max_cluster_size", &TS::max_cluster_size, "", "objects with more points are dropped")
      .settings()
      .def("validate", [](const TS& s) { validate(s); }, "ValueError naming an invalid field");
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
  const CylinderSettings dc;
  m.def(
      "ransac_cylinder",
      [](const py::object& points, double threshold, const py::object& normals, double min_radius, double max_radius,
         double max_normal_angle, double normal_radius, const py::int_& max_iterations, double confidence,
         const py::int_& seed, bool refine, int num_threads) {
        CylinderSettings s;
        s.ransac = ransacSettings(threshold, max_iterations, confidence, seed, num_threads, refine);
        s.min_radius = min_radius;
        s.max_radius = max_radius;
        s.max_normal_angle = max_normal_angle;
        s.normal_radius = normal_radius;
        validate(s);
        return withCloud(points, "points", [&](auto view) {
          using Scalar = std::remove_const_t<std::remove_pointer_t<decltype(view.data)>>;
          requireFinitePoints(view, 2, "ransac_cylinder");
          if (normals.is_none()) {
            py::gil_scoped_release release;
            return ransacCylinder(view, s);
          }
          const py::array held = asCloudArray<Scalar>(normals, "normals");  // converted to the points' precision
          const auto nv = cloudView<Scalar>(held, "normals");
          if (nv.size != view.size) throw py::value_error("normals: need one (3,) normal per point");
          py::gil_scoped_release release;
          return ransacCylinder(view, nv, s);
        });
      },
      py::arg("points"), py::arg("threshold"), py::kw_only(), py::arg("normals") = py::none(),
      py::arg("min_radius") = dc.min_radius, py::arg("max_radius") = dc.max_radius,
      py::arg("max_normal_angle") = dc.max_normal_angle, py::arg("normal_radius") = dc.normal_radius,
      py::arg("max_iterations") = dr.max_iterations, py::arg("confidence") = dr.confidence, py::arg("seed") = 0,
      py::arg("refine") = dr.refine, py::arg("num_threads") = dr.num_threads,
      R"(A cylinder by RANSAC from two oriented points (Schnabel, Wahl and Klein 2007; PCL's SACMODEL_CYLINDER).

The axis of two points' normals is n1 x n2 through the closest points of their normal lines;
a sample is degenerate when the normals are within ~1 degree of parallel, the two points'
distances from that axis differ by more than threshold, or the radius is outside
[min_radius, max_radius]. A point is an inlier when it lies within threshold of the surface and
its normal within max_normal_angle of the radial direction (so a table under a mug is not). The
winner is refitted by geometric least squares (fit_cylinder) when refine, and the inliers
re-selected. Other arguments as ransac_plane (w^2 in the adaptive stop).

Args:
    points: (N, 3) float32/float64, metres; NaN/Inf rows ignored.
    threshold: metres, the inlier distance from the surface.
    normals: (N, 3) of the same dtype (any length or sign), or None: PCA normals of radius
        normal_radius (metres). Rows with a non-finite or zero normal are ignored.
    min_radius, max_radius: metres. max_normal_angle: radians, in (0, pi/2].

Returns:
    CylinderResult: point (on the axis), axis (unit), radius, inliers; status "degenerate"
    when every sample was (a plane: parallel normals).

Raises:
    TypeError: non-float points. ValueError: shapes, settings (named), fewer than 2 finite points.)");
  m.def(
      "fit_cylinder",
      [](const py::object& points, const Eigen::Vector3d& point, const Eigen::Vector3d& axis, double radius,
         int max_iterations) {
        if (!point.allFinite() || !axis.allFinite() || !(axis.norm() > 0) || !(radius > 0) || !std::isfinite(radius))
          throw py::value_error("fit_cylinder: the start needs a finite point, a non-zero axis and a radius > 0 (m)");
        if (max_iterations < 1) throw py::value_error("fit_cylinder: max_iterations must be at least 1");
        return withCloud(points, "points", [&](auto view) {
          std::vector<std::uint32_t> rows;
          for (std::size_t i = 0; i < view.size; ++i)
            if (view.isFinite(i)) rows.push_back(static_cast<std::uint32_t>(i));
          CylinderResult r;
          r.hypothesis = CylinderModel{point, axis.normalized(), radius};
          r.model = r.hypothesis;
          {
            py::gil_scoped_release release;
            r.refined = fitCylinderLeastSquares(view, rows, r.model, max_iterations);
          }
          r.status = rows.size() < 5 ? RansacStatus::kTooFewPoints : RansacStatus::kSuccess;
          r.inliers = rows;
          return r;
        });
      },
      py::arg("points"), py::arg("point"), py::arg("axis"), py::arg("radius"), py::kw_only(),
      py::arg("max_iterations") = 50,
      R"(Least-squares cylinder: minimise sum (|(p - point) x axis| - radius)^2 (metres) by
Levenberg-Marquardt over the axis (2 degrees of freedom), its position (2) and the radius,
from the start (point, axis, radius). Every finite row takes part (select inliers first).

Returns:
    CylinderResult: the fit (point: the foot of the points' centroid on the axis), refined
    False (and the start returned) when it did not lower the cost, status "too_few_points"
    for fewer than 5 finite points; inliers are the finite rows, hypothesis_* the start.)");
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
        if (!viewpoint.is_none()) s.viewpoint = vec3(viewpoint, "viewpoint");
        if (!up.is_none()) s.up = vec3(up, "up");
        s.cluster_tolerance = cluster_tolerance;
        if (min_cluster_size < 1 || (max_cluster_size && *max_cluster_size < min_cluster_size))
          throw py::value_error("need 1 <= min_cluster_size <= max_cluster_size");
        s.min_cluster_size = static_cast<std::size_t>(min_cluster_size);
        if (max_cluster_size) s.max_cluster_size = static_cast<std::size_t>(*max_cluster_size);
        validate(s);
        TableSegmentationResult result = withCloud(points, "points", [&](auto view) {
          requireFinitePoints(view, 3, "segment_table");
          py::gil_scoped_release release;
          return segmentTable(view, s);
        });
        warnPython(result.warning);
        return result;
      },
      py::arg("points"), py::kw_only(), py::arg("threshold") = dt.plane.threshold, py::arg("crop_min") = py::none(),
      py::arg("crop_max") = py::none(), py::arg("viewpoint") = py::none(),
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
    viewpoint: the sensor's centre in the cloud's frame, metres; None: the origin, the camera
        centre of a cloud in its camera frame. The table normal faces it (unless up is given):
        the table is seen from above, and points on the other side are removed.
    up: optional "up" direction (any length) to orient the normal instead, for a cloud in a
        world frame. An up that puts the viewpoint below the table contradicts it: the result's
        warning says so and a UserWarning is raised (omit up for a camera-frame cloud).
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
