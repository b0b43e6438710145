// Bindings of the common area: rigid transforms, camera placement and mesh sampling
// (scanalign._core.common).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/common/look_at.hpp"
#include "scanalign/common/mesh_sampling.hpp"
#include "scanalign/common/rigid.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {

template <typename Scalar>
py::array_t<Scalar> transformed(const Eigen::Matrix4d& T, const CloudView<Scalar>& points) {
  py::array_t<Scalar> out({static_cast<py::ssize_t>(points.size), py::ssize_t{3}});
  Scalar* o = out.mutable_data();
  py::gil_scoped_release release;
  transformPoints(T, points, o);
  return out;
}

}  // namespace

void defineCommon(py::module_& m) {
  m.attr("RIGID_TOLERANCE") = kRigidTolerance;
  m.attr("RIGID_ROW_TOLERANCE") = kRigidRowTolerance;
  m.def(
      "rigid_problem",
      [](const py::object& T) -> py::object {
        const char* problem = rigidProblem(fields::Conv<Eigen::Matrix4d>::set(T, "T"));
        return problem ? py::object(py::str(problem)) : py::object(py::none());
      },
      py::arg("T"), "Why a 4x4 matrix is not a rigid transform (common/rigid.hpp), or None when it is.");
  // Eigen arguments through the field conversion: pybind11's own would parse strings and
  // drop imaginary parts.
  m.def(
      "look_at",
      [](const py::object& eye, const py::object& target, const py::object& up) {
        using V = fields::Conv<Eigen::Vector3d>;
        return lookAt(V::set(eye, "eye"), V::set(target, "target"), V::set(up, "up"));
      },
      py::arg("eye"), py::arg("target"), py::arg("up") = Eigen::Vector3d::UnitZ(),
        "T_world_camera (4x4) of a camera at eye (m) whose optical axis (z) points at target, image up (-y) near up");
  m.def(
      "transform_points",
      [](const py::object& T_in, const py::object& points) -> py::object {
        const Eigen::Matrix4d T = fields::Conv<Eigen::Matrix4d>::set(T_in, "T");
        return withCloud(points, "points", [&](auto view) -> py::object { return transformed(T, view); });
      },
      py::arg("T"), py::arg("points"),
      "T applied to (N, 3) float32/float64 points (any row stride): A p + t with [A | t] the top rows of the 4x4 T, "
      "in double, returned as a new (N, 3) array of the points' dtype. T need not be rigid (a scale is applied as "
      "given) but must be finite with the bottom row 0 0 0 1 (ValueError naming T); non-finite points give "
      "non-finite rows. TypeError for other dtypes, ValueError for other shapes.");
  m.def(
      "sample_mesh",
      [](const py::object& vertices, const py::object& faces, const py::object& n_points, const py::object& seed) {
        const auto v = checkedAs<double>(vertices, "vertices", kReals);
        if (v.ndim() != 2 || v.shape(1) != 3)
          throw py::value_error("vertices: expected a (V, 3) array of real numbers, metres");
        const std::vector<std::int64_t> f = indexRows(faces, "faces", 3);
        const auto n = static_cast<std::size_t>(intArg(n_points, "n_points", 0, std::int64_t{1} << 40));
        requireMemory(160.0 * static_cast<double>(n), "n_points = " + std::to_string(n));  // points, normals, draws
        const std::uint64_t seed_value = seedArg(seed, "seed");
        MeshSamples s;
        {
          py::gil_scoped_release release;
          s = sampleMesh(CloudView<double>(v.data(), static_cast<std::size_t>(v.shape(0))), f.data(), f.size() / 3,
                         n, seed_value);
        }
        return py::make_tuple(rowsArray(s.points), rowsArray(s.normals), vectorArray(s.faces));
      },
      py::arg("vertices"), py::arg("faces"), py::arg("n_points"), py::arg("seed") = 0,
      "(points (n, 3) float64, normals (n, 3) float64 unit face normals, faces (n,) int64) sampled uniformly per unit "
      "area on a triangle mesh ((V, 3) vertices, (F, 3) integer faces): a face drawn by area (zero-area faces never), "
      "a point uniform in it, relative to its first corner (points on axis-aligned faces keep the exact coordinate). "
      "The random numbers are numpy.random.default_rng(seed)'s, drawn as Generator.choice(p=areas) and "
      "Generator.random draw them (seed in [0, 2^64)). ValueError for a face index out of range, a non-finite "
      "vertex in use or zero total area.");
}

}  // namespace scanalign::python
