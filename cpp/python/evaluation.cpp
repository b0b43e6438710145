// _core.evaluation: the exact point-to-mesh distance index (evaluation/mesh_distance.hpp),
// bound directly with its Python docs; python/scanalign/evaluation.py re-exports it.
// Inputs are checked here (TypeError for dtypes, ValueError for shapes and values).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "arrays.hpp"
#include "scanalign/evaluation/mesh_distance.hpp"
#include "scanalign/evaluation/pose_interpolation.hpp"

namespace scanalign::python {

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
  const py::array a = asArray(o, what);
  const char kind = a.dtype().kind();
  if (kind != 'f' || (a.itemsize() != 4 && a.itemsize() != 8))
    throw py::type_error(std::string(what) + ": expected a float32 or float64 array, got dtype " +
                         std::string(py::str(a.dtype())));
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
  for (py::ssize_t i = 0; i < n; ++i)
    Eigen::Map<Eigen::Vector4d>(out.mutable_data() + 4 * i) =
        quaternionFromRotation(Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.data() + 9 * i));
  return out;
}

py::array_t<double> rotationsFromQuaternions(const py::object& quaternions) {
  auto [q, shape] = batchOf(quaternions, "quaternions", 4, 0);
  shape.insert(shape.end(), {3, 3});
  py::array_t<double> out(shape);
  const py::ssize_t n = q.size() / 4;
  for (py::ssize_t i = 0; i < n; ++i)
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(out.mutable_data() + 9 * i) =
        rotationFromQuaternion(Eigen::Map<const Eigen::Vector4d>(q.data() + 4 * i));
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

}  // namespace

void defineEvaluation(py::module_& m) {
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
      .def("closest_points", &closestPoints, py::arg("points"), py::arg("num_threads") = 0, R"doc(
Nearest surface points: ``(distances (N,) float64 m, points (N, 3) float64 in the mesh's
frame, triangles (N,) int64 rows of faces)``. Rows of ``points`` with NaN/Inf give
distance NaN, point NaN and triangle -1.
)doc");

  m.def("quaternions_from_rotations", &quaternionsFromRotations, py::arg("rotations"),
        "Unit quaternions (..., 4) as (qx, qy, qz, qw), Hamilton convention, qw >= 0, of rotation "
        "matrices (..., 3, 3) (Eigen's Shepperd method, accurate over the whole rotation group).");
  m.def("rotations_from_quaternions", &rotationsFromQuaternions, py::arg("quaternions"),
        "Rotation matrices (..., 3, 3) of quaternions (..., 4) given as (qx, qy, qz, qw), normalised "
        "first. Raises ValueError for a zero or non-finite quaternion.");
  m.def("interpolate_poses", &interpolatePoses, py::arg("start"), py::arg("end"), py::arg("fraction"),
        "(N, 4, 4) poses a fraction (N,) of the way from (N, 4, 4) `start` to `end`: translation "
        "linear, rotation spherical-linear along the shorter arc (metres)");
}

}  // namespace scanalign::python
