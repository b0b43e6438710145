// Bindings of the common area: rigid transforms and camera placement (scanalign._core.common).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include "scanalign/common/look_at.hpp"
#include "scanalign/common/rigid.hpp"

namespace py = pybind11;

namespace scanalign::python {

void defineCommon(py::module_& m) {
  m.attr("RIGID_TOLERANCE") = kRigidTolerance;
  m.attr("RIGID_ROW_TOLERANCE") = kRigidRowTolerance;
  m.def(
      "rigid_problem",
      [](const Eigen::Matrix4d& T) -> py::object {
        const char* problem = rigidProblem(T);
        return problem ? py::object(py::str(problem)) : py::object(py::none());
      },
      py::arg("T"), "Why a 4x4 matrix is not a rigid transform (common/rigid.hpp), or None when it is.");
  m.def("look_at", &lookAt, py::arg("eye"), py::arg("target"), py::arg("up") = Eigen::Vector3d::UnitZ(),
        "T_world_camera (4x4) of a camera at eye (m) whose optical axis (z) points at target, image up (-y) near up");
}

}  // namespace scanalign::python
