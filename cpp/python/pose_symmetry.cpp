// Bindings of scanalign/pose/part_symmetry.hpp in _core.pose: a part's rotational symmetry
// (PartSymmetry, through its field table, fields.hpp) and the pose error up to it
// (symmetric_pose_error), the one convention of find_parts, the pick scores and the batch
// records. python/scanalign/grasp.py re-exports both.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "field_access.hpp"
#include "fields.hpp"
#include "pose.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/pose/part_symmetry.hpp"

namespace scanalign::python {

namespace {

/// A rigid 4x4 transform; TypeError / ValueError naming `name`.
Eigen::Isometry3d rigid(py::handle x, const std::string& name) {
  Eigen::Isometry3d T;
  T.matrix() = fields::Conv<Eigen::Matrix4d>::set(x, name);
  requireRigid(T.matrix(), name);
  return T;
}

}  // namespace

void bindPoseSymmetry(py::module_& m) {
  using S = PartSymmetry;
  fieldsOf(py::class_<S>(m, "PartSymmetry",
                         "A part's rotational symmetry in its model frame: it looks the same after a rotation by "
                         "2*pi/order about the axis through point (order 1: none; 0: any rotation, a body of "
                         "revolution). Every field is checked with the others (ValueError naming it, the old value "
                         "kept).")
               .def(py::init([](const py::object& axis, const py::object& point, int order) {
                      S s{fields::Conv<Eigen::Vector3d>::set(axis, "axis"),
                          fields::Conv<Eigen::Vector3d>::set(point, "point"), order};
                      s.validate();
                      return s;
                    }),
                    py::arg("axis") = std::vector<double>{0, 0, 1}, py::arg("point") = std::vector<double>{0, 0, 0},
                    py::arg("order") = 1)
               .def(
                   "transforms",
                   [](const S& s, int continuous_steps) {
                     if (continuous_steps < 1 || continuous_steps > 3600)
                       throw std::invalid_argument("continuous_steps must be in 1..3600");
                     std::vector<Eigen::Matrix4d> out;
                     for (const auto& T : s.transforms(continuous_steps)) out.push_back(T.matrix());
                     return out;
                   },
                   py::arg("continuous_steps") = 72,
                   "The transforms S_k (model -> model, 4x4) that map the part onto itself, S_0 = identity; for a "
                   "continuous symmetry continuous_steps evenly spaced angles")
               .def("__repr__",
                    [](const S& s) {
                      return "PartSymmetry(axis=" + std::string(py::repr(py::cast(s.axis).attr("tolist")())) +
                             ", point=" + std::string(py::repr(py::cast(s.point).attr("tolist")())) +
                             ", order=" + std::to_string(s.order) + ")";
                    }))
      .field("axis", member(&S::axis), validating(&S::axis), "",
             "(3,) symmetry axis direction, model frame (normalised on use)")
      .field("point", member(&S::point), validating(&S::point), "m", "(3,) a point on the axis, model frame")
      .field("order", member(&S::order), validating(&S::order), "",
             "1: no symmetry; n >= 2: 2*pi/n rotations; 0: continuous")
      .result();
  m.def(
      "symmetric_pose_error",
      [](const py::object& T_a, const py::object& T_b, const S& symmetry) {
        symmetry.validate();
        const auto [angle, distance] = symmetricPoseError(rigid(T_a, "T_a"), rigid(T_b, "T_b"), symmetry);
        return py::make_tuple(angle, distance);
      },
      py::arg("T_a"), py::arg("T_b"), py::arg("symmetry"),
      "(rotation angle rad, translation m) between two poses T_a, T_b (4x4 rigid, model -> scene) of a part with "
      "this symmetry, the smallest over its symmetry rotations: the rotation of inv(R_a) R_b S_k, the translation "
      "measured at the symmetry point, which every symmetry rotation keeps fixed (for a continuous symmetry only the "
      "tilt of the axis counts, in closed form)");
}

}  // namespace scanalign::python
