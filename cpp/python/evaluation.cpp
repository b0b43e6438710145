// _core.evaluation: the exact point-to-mesh distance index (evaluation/mesh_distance.hpp),
// bound directly with its Python docs, and the error summaries through their field tables
// (fields.hpp); python/scanalign/evaluation.py re-exports them.
// Inputs are checked here (TypeError for dtypes, ValueError for shapes and values).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/LU>  // Matrix3d::determinant

#include "arrays.hpp"
#include "fields.hpp"
#include "pickle.hpp"  // refusePickle
#include "scanalign/common/rigid.hpp"  // kRigidTolerance
#include "scanalign/evaluation/associate.hpp"
#include "scanalign/evaluation/associate_nearest.hpp"
#include "scanalign/evaluation/error_stats.hpp"
#include "scanalign/evaluation/mesh_distance.hpp"
#include "scanalign/evaluation/pose_interpolation.hpp"
#include "scanalign/evaluation/rpe_pairs.hpp"

namespace scanalign::python {

using namespace pybind11::literals;

namespace {

using Rows = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::string shapeOf(const py::array& a) { return std::string(py::str(a.attr("shape"))); }

/// Any array-like as a NumPy array (lists are accepted like numpy.asarray accepts them).
py::array asArray(const py::object& o, const char* what) {
  py::array a = py::array::ensure(o);
  if (!a) throw py::type_error(std::string(what) + ": expected an array");
  return a;
}

/// (N, 3) float32 / float64 array as a C-contiguous float64 copy or view.
Rows float64Rows(const py::object& o, const char* what, const char* shape) {
  const py::array a = checkedArray(o, what);
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + ": expected shape " + shape + ", got " +
                          shapeOf(a));
  return Rows::ensure(a);
}

std::unique_ptr<MeshDistanceIndex> makeIndex(const py::object& vertices, const py::object& faces_like, int leaf_size) {
  const Rows v = float64Rows(vertices, "vertices", "(V, 3)");
  const py::array faces = asArray(faces_like, "faces");
  const char kind = faces.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw py::type_error("faces: expected an integer array, got dtype " + std::string(py::str(faces.dtype())));
  if (faces.ndim() != 2 || faces.shape(1) != 3)
    throw py::value_error("faces: expected shape (F, 3), got " +
                          shapeOf(faces));
  const auto f = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
  const CloudView<double> view(v.data(), static_cast<std::size_t>(v.shape(0)));
  py::gil_scoped_release release;
  return std::make_unique<MeshDistanceIndex>(view, f.data(), static_cast<std::size_t>(f.shape(0)), leaf_size);
}

py::array_t<double> distance(const MeshDistanceIndex& index, const py::object& points, int num_threads) {
  const Rows p = float64Rows(points, "points", "(N, 3)");
  py::array_t<double> out(p.shape(0));
  const CloudView<double> view(p.data(), static_cast<std::size_t>(p.shape(0)));
  double* d = out.mutable_data();
  py::gil_scoped_release release;
  index.distances(view, d, num_threads);
  return out;
}

std::tuple<py::array_t<double>, py::array_t<double>, py::array_t<std::int64_t>> closestPoints(
    const MeshDistanceIndex& index, const py::object& points, int num_threads) {
  const Rows p = float64Rows(points, "points", "(N, 3)");
  const py::ssize_t n = p.shape(0);
  py::array_t<double> d(n), q({n, py::ssize_t{3}});
  py::array_t<std::int64_t> tri(n);
  const CloudView<double> view(p.data(), static_cast<std::size_t>(n));
  double *dp = d.mutable_data(), *qp = q.mutable_data();
  std::int64_t* tp = tri.mutable_data();
  {
    py::gil_scoped_release release;
    index.closestPoints(view, dp, tp, qp, num_threads);
  }
  return {d, q, tri};
}

using Stack = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// A C-contiguous float64 stack of shape (N, rows[, cols]).
Stack stackOf(const py::array& a, const char* what, py::ssize_t rows, py::ssize_t cols) {
  const Stack s = Stack::ensure(a);
  if (!s || s.ndim() != (cols ? 3 : 2) || s.shape(1) != rows || (cols && s.shape(2) != cols))
    throw py::value_error(std::string(what) + ": expected shape (N, " + std::to_string(rows) +
                          (cols ? ", " + std::to_string(cols) : std::string()) + "), got " + shapeOf(a));
  return s;
}

/// A C-contiguous float64 stack of shape (..., rows, cols) (cols 0: (..., rows)) and its
/// leading shape, so that one call maps any batch of matrices or quaternions.
std::pair<Stack, std::vector<py::ssize_t>> batchOf(const py::object& o, const char* what, py::ssize_t rows,
                                                   py::ssize_t cols) {
  const py::array a = asArray(o, what);
  const Stack s = Stack::ensure(a);
  const py::ssize_t dims = cols ? 2 : 1;
  if (!s || s.ndim() < dims || s.shape(s.ndim() - dims) != rows || (cols && s.shape(s.ndim() - 1) != cols))
    throw py::value_error(std::string(what) + ": expected shape (..., " + std::to_string(rows) +
                          (cols ? ", " + std::to_string(cols) : std::string()) + "), got " + shapeOf(a));
  return {s, std::vector<py::ssize_t>(s.shape(), s.shape() + s.ndim() - dims)};
}

py::array_t<double> quaternionsFromRotations(const py::object& rotations) {
  auto [R, shape] = batchOf(rotations, "rotations", 3, 3);
  shape.push_back(4);
  py::array_t<double> out(shape);
  const py::ssize_t n = R.size() / 9;
  for (py::ssize_t i = 0; i < n; ++i) {
    const Eigen::Matrix3d Ri = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.data() + 9 * i);
    // A rotation, or a positive multiple of one (the rotation block of a similarity, as a
    // scale-aligned trajectory has); a zero, NaN or sheared matrix used to come back as some
    // unit quaternion (the zero matrix as (1, 0, 0, 0)).
    const Eigen::Matrix3d RtR = Ri.transpose() * Ri;
    const double c = RtR.trace() / 3.0;
    if (!Ri.allFinite() || !(c > 0) || !std::isfinite(c) ||
        (RtR / c - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kRigidTolerance || !(Ri.determinant() > 0))
      throw std::invalid_argument("rotations[" + std::to_string(i) +
                                  "] (flattened batch index) is not a rotation matrix or a positive multiple "
                                  "of one (non-finite, not orthogonal to 1e-5, or a reflection)");
    Eigen::Map<Eigen::Vector4d>(out.mutable_data() + 4 * i) = quaternionFromRotation(Ri / std::sqrt(c));
  }
  return out;
}

py::array_t<double> rotationsFromQuaternions(const py::object& quaternions) {
  auto [q, shape] = batchOf(quaternions, "quaternions", 4, 0);
  shape.insert(shape.end(), {3, 3});
  py::array_t<double> out(shape);
  const py::ssize_t n = q.size() / 4;
  for (py::ssize_t i = 0; i < n; ++i) {
    // Divided by its largest component first: normalising (1e300, 1e300, 0, 1) directly
    // overflows the squared norm, and the rotation came back as the identity.
    Eigen::Vector4d v = Eigen::Map<const Eigen::Vector4d>(q.data() + 4 * i);
    if (const double s = v.cwiseAbs().maxCoeff(); s > 0 && std::isfinite(s)) v /= s;
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(out.mutable_data() + 9 * i) = rotationFromQuaternion(v);
  }
  return out;
}

py::array_t<double> interpolatePoses(const py::array& from, const py::array& to, const py::array& fraction) {
  const Stack T0 = stackOf(from, "start", 4, 4), T1 = stackOf(to, "end", 4, 4);
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(fraction);
  if (T1.shape(0) != T0.shape(0) || !a || a.ndim() != 1 || a.shape(0) != T0.shape(0))
    throw py::value_error("interpolate_poses: start, end and fraction must hold the same number of poses");
  using M4 = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;
  py::array_t<double> out({T0.shape(0), py::ssize_t{4}, py::ssize_t{4}});
  for (py::ssize_t i = 0; i < T0.shape(0); ++i)
    Eigen::Map<M4>(out.mutable_data(i, 0, 0)) =
        interpolatePose(Eigen::Map<const M4>(T0.data(i, 0, 0)), Eigen::Map<const M4>(T1.data(i, 0, 0)), a.at(i));
  return out;
}

MeshDistanceStats distanceStats(const MeshDistanceIndex& index, const py::object& points, int num_threads) {
  const py::array_t<double> d = distance(index, points, num_threads);
  return summarizeDistances(d.data(), static_cast<std::size_t>(d.size()));
}

py::array_t<std::int64_t> pairArray(const std::vector<std::pair<std::int64_t, std::int64_t>>& pairs) {
  py::array_t<std::int64_t> out({static_cast<py::ssize_t>(pairs.size()), py::ssize_t{2}});
  for (std::size_t k = 0; k < pairs.size(); ++k)
    *out.mutable_data(k, 0) = pairs[k].first, *out.mutable_data(k, 1) = pairs[k].second;
  return out;
}

std::vector<double> values(const Stack& a) { return std::vector<double>(a.data(), a.data() + a.size()); }

/// The stored fields (their pickled state) as plain Python values, for JSON.
py::dict fieldsDict(const py::object& self) {
  py::dict d = self.attr("__getstate__")();
  for (const auto& item : d)
    if (py::isinstance<py::array>(item.second)) d[item.first] = item.second.attr("tolist")();
  return d;
}

void defineStats(py::module_& m) {
  using E = ErrorStats;
  fieldsOf(py::class_<E>(m, "ErrorStats", R"doc(
Summary of per-pose (or per-pair) errors, as the TUM benchmark tools and ``evo`` report them.

Units are those of ``errors`` (metres for translations, degrees for rotations). ``std`` is
the population standard deviation (ddof = 0, like ``numpy.std``, ``evo`` and the TUM
scripts); ``sse`` the sum of squares; ``rmse = sqrt(sse / count)``; ``median`` as
``numpy.median``.
)doc")
               .def_static(
                   "from_errors",
                   [](const py::array_t<double, py::array::c_style | py::array::forcecast>& errors) {
                     return summarizeErrors(std::vector<double>(errors.data(), errors.data() + errors.size()));
                   },
                   py::arg("errors"), "The statistics of an array of errors (flattened); ValueError when it is empty.")
               .def("__repr__", [](const E& s) {
                 return "ErrorStats(rmse=" + std::to_string(s.rmse) + ", mean=" + std::to_string(s.mean) +
                        ", max=" + std::to_string(s.max) + ", count=" + std::to_string(s.count) + ")";
               }))
      .output("rmse", &E::rmse, "", "root mean square error")
      .output("mean", &E::mean, "", "mean error")
      .output("median", &E::median, "", "median error")
      .output("std", &E::std, "", "population standard deviation (ddof = 0)")
      .output("min", &E::min, "", "smallest error")
      .output("max", &E::max, "", "largest error")
      .output("sse", &E::sse, "", "sum of squared errors")
      .output("count", &E::count, "", "number of errors")
      .output("errors", &E::errors, "", "(count,) float64 copy of the errors")
      .result()
      .def(
          "as_dict",
          [](const py::object& self, bool include_errors) {
            py::dict d = fieldsDict(self);
            if (!include_errors) PyDict_DelItemString(d.ptr(), "errors");
            return d;
          },
          py::arg("include_errors") = false, "Plain floats (JSON-serialisable); the per-pose errors only on request.");

  using D = MeshDistanceStats;
  fieldsOf(py::class_<D>(m, "MeshDistanceStats",
                         "Cloud-to-mesh distance summary (m) over the finite points; ``count`` points were measured, "
                         "``dropped`` rows had NaN/Inf coordinates and were left out.")
               .def("__repr__", [](const D& s) {
                 return "MeshDistanceStats(mean=" + std::to_string(s.mean) + ", p95=" + std::to_string(s.p95) +
                        ", max=" + std::to_string(s.max) + ", count=" + std::to_string(s.count) + ")";
               }))
      .output("mean", &D::mean, "m", "mean distance")
      .output("median", &D::median, "m", "median distance")
      .output("p95", &D::p95, "m", "95th percentile, linear interpolation as numpy.percentile")
      .output("max", &D::max, "m", "largest distance")
      .output("rmse", &D::rmse, "m", "root mean square distance")
      .output("count", &D::count, "", "points measured")
      .output("dropped", &D::dropped, "", "rows left out for NaN/Inf coordinates")
      .result()
      .def("as_dict", &fieldsDict, "The fields as a JSON-serialisable dict");
}

}  // namespace

void defineEvaluation(py::module_& m) {
  defineStats(m);
  py::class_<MeshDistanceIndex>(m, "MeshDistanceIndex", R"doc(
Exact point-to-triangle-mesh distance queries; build once, query many times.

A bounding-volume hierarchy of tight axis-aligned boxes (median splits of the triangle
centroids along the longest axis, ``leaf_size`` triangles per leaf) is searched nearer
child first, skipping boxes farther than the best triangle so far, so the result is the
exact minimum over all triangles (up to rounding). Point-to-triangle distances follow the
Voronoi regions of the triangle (Ericson, Real-Time Collision Detection, 2005, §5.1.5);
zero-area triangles count as their edges. Queries run in parallel (OpenMP).

Args:
    vertices: (V, 3) float32/float64 vertex coordinates (m). Vertices no face uses are
        ignored (and may be non-finite).
    faces: (F, 3) integer vertex indices (any integer dtype), F >= 1.
    leaf_size: triangles per leaf (>= 1).

Raises:
    TypeError: wrong dtypes. ValueError: wrong shapes, no faces, an index out of range,
    a non-finite vertex used by a face, leaf_size < 1.
)doc")
      .def(py::init(&makeIndex), py::arg("vertices"), py::arg("faces"),
           py::arg("leaf_size") = MeshDistanceIndex::kDefaultLeafSize)
      .def_property_readonly("n_faces", &MeshDistanceIndex::numFaces, "number of triangles F")
      .def("distance", &distance, py::arg("points"), py::arg("num_threads") = 0, R"doc(
Exact Euclidean distance (m) from every point to the nearest triangle (unsigned).

Args:
    points: (N, 3) float32/float64, in the mesh's frame. Rows with NaN/Inf are not an
        error: their distance is NaN.
    num_threads: OpenMP threads (0: all).

Returns:
    (N,) float64 distances.
)doc")
      .def("__call__", &distance, py::arg("points"), py::arg("num_threads") = 0, "same as distance()")
      .def("stats", &distanceStats, py::arg("points"), py::arg("num_threads") = 0,
           "MeshDistanceStats of distance(points); rows with NaN/Inf are dropped. Raises ValueError when "
           "no point is finite.")
      .def("closest_points", &closestPoints, py::arg("points"), py::arg("num_threads") = 0, R"doc(
Nearest surface points: ``(distances (N,) float64 m, points (N, 3) float64 in the mesh's
frame, triangles (N,) int64 rows of faces)``. Rows of ``points`` with NaN/Inf give
distance NaN, point NaN and triangle -1.
)doc");

  // The BVH keeps only its triangles (no vertex table, no leaf size to rebuild from).
  refusePickle<MeshDistanceIndex>(m, "MeshDistanceIndex",
                                  "send the mesh (vertices, faces) and build the index in the worker");
  m.def("quaternions_from_rotations", &quaternionsFromRotations, py::arg("rotations"),
        "Unit quaternions (..., 4) as (qx, qy, qz, qw), Hamilton convention, qw >= 0, of rotation "
        "matrices (..., 3, 3) (Eigen's Shepperd method, accurate over the whole rotation group); a positive "
        "multiple of a rotation (a similarity's rotation block) gives that rotation's quaternion. Raises "
        "ValueError for any other matrix (non-finite, zero, not orthogonal to 1e-5, a reflection).");
  m.def("rotations_from_quaternions", &rotationsFromQuaternions, py::arg("quaternions"),
        "Rotation matrices (..., 3, 3) of quaternions (..., 4) given as (qx, qy, qz, qw), normalised "
        "first (divided by its largest component, so any finite magnitude works, 1e-300 or 1e300). "
        "Raises ValueError for a zero or non-finite quaternion.");
  m.def(
      "associate_timestamps",
      [](const Stack& first, const Stack& second, double max_difference) {
        return pairArray(associateTimestamps(values(first), values(second), max_difference));
      },
      py::arg("first"), py::arg("second"), py::arg("max_difference"), R"doc(
Pairs two timestamp streams one-to-one, closest pairs first: the package's one rule.

Every pair ``(i, j)`` with ``|first[i] - second[j]| <= max_difference`` is a candidate;
candidates are taken greedily by increasing ``|dt|`` (ties: smaller ``i``, then smaller
``j``), skipping those whose ``i`` or ``j`` is already taken.  This is the TUM RGB-D
benchmark's ``associate.py`` (Sturm et al., IROS 2012) except for the bound, which is
inclusive as in ``evo``'s ``matching_time_indices``: the two differ only for pairs
exactly at the bound, and ``max_difference=0`` then means "identical timestamps".

Args:
    first, second: timestamps (s), each sorted ascending (repeats allowed).
    max_difference: largest accepted time difference (s), finite and >= 0.

Returns:
    (K, 2) int64 index pairs ``(i, j)``, sorted by ``i``.

Raises:
    ValueError: a negative or non-finite ``max_difference``, unsorted or non-finite
        timestamps.
)doc");
  m.def(
      "associate_nearest",
      [](const Stack& shorter, const Stack& longer, double max_difference) {
        return pairArray(associateNearest(values(shorter), values(longer), max_difference));
      },
      py::arg("shorter"), py::arg("longer"), py::arg("max_difference"),
      "(K, 2) int64 pairs (i, j): for every time shorter[i], the nearest time longer[j] (longer sorted "
      "ascending) within max_difference seconds (inclusive; ties to the earlier one), as evo's "
      "associate_trajectories; a j may repeat. ValueError when longer is not sorted, a timestamp is not "
      "finite, or max_difference is NaN, infinite or negative.");
  m.def(
      "relative_pose_pairs",
      [](const Stack& s, double delta, bool all_pairs, double tol) {
        return pairArray(relativePosePairs(values(s), delta, all_pairs, tol));
      },
      py::arg("s"), py::arg("delta"), py::arg("all_pairs"), py::arg("tol"),
      "(M, 2) int64 pose pairs (i, j) over a non-decreasing sequence s (frame indices, path length "
      "in m or timestamps in s), as evo's RPE: all_pairs false gives the chain 0 = i_0 < i_1 < ..., "
      "each the first index with s[i_{k+1}] - s[i_k] >= delta; all_pairs true, for every i the first "
      "j > i minimising |(s[j] - s[i]) - delta|, kept when that is <= tol.");
  m.def("interpolate_poses", &interpolatePoses, py::arg("start"), py::arg("end"), py::arg("fraction"),
        "(N, 4, 4) poses a fraction (N,) of the way from (N, 4, 4) `start` to `end`: translation "
        "linear, rotation spherical-linear along the shorter arc (metres)");
}

}  // namespace scanalign::python
