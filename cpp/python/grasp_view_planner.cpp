// Bindings of the hand camera's view planner (scanalign._core.grasp): the view step of the
// two-step pose (Kleppe et al., Robotics 6 (2017) 14, §3.3), planned as a grasp with the
// camera as its tool.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "fields.hpp"
#include "scanalign/grasp/view_planner.hpp"

namespace scanalign::python {

namespace py = pybind11;

void bindViewPlanner(py::module_& m) {
  using S = ViewPlannerSettings;
  fieldsOf(py::class_<S>(m, "ViewPlannerSettings", "Where the hand camera looks at a part from (plan_camera_view)"))
      .field("height", &S::height, "m", "from the part's top face up to the camera centre")
      .field("yaw_steps", &S::yaw_steps, "", "camera turns about the vertical tried, 2 pi / yaw_steps apart (1..360)")
      .field("planner", &S::planner, "", "GraspPlannerSettings judging each IK configuration (no approach)")
      .settings()
      .def("validate", &S::validate);
  using V = ViewPlan;
  fieldsOf(py::class_<V>(m, "ViewPlan", "The hand camera's view above a part: its pose and joints")
               .def("__bool__", [](const V& v) { return v.found; })
               .def("__repr__", [](const V& v) {
                 return std::string("ViewPlan(found=") + (v.found ? "True" : "False") + ", message='" + v.message +
                        "')";
               }))
      .output("found", &V::found, "", "some view is reachable")
      .output("message", &V::message, "", "the choice, or why no view was reachable")
      .output("T_base_camera", &V::T_base_camera, "m", "(4, 4) the chosen camera pose, optical axis down")
      .output("q", &V::q, "rad", "(6,) its joints (NaN when not found)")
      .output("plan", &V::plan, "", "GraspPlanResult: every view x IK configuration with its reason")
      .result();
  m.def(
      "camera_above",
      [](const py::object& T_base_part, double top_height, double height, double yaw) {
        return Eigen::Matrix4d(
            cameraAbove(fields::Conv<Eigen::Isometry3d>::set(T_base_part, "T_base_part"), top_height, height, yaw)
                .matrix());
      },
      py::arg("T_base_part"), py::arg("top_height"), py::arg("height"), py::arg("yaw") = 0.0,
      "(4, 4) T_base_camera looking straight down at the part from `height` (m) above its top face (top_height m "
      "above its origin), turned by `yaw` (rad) about the vertical");
  m.def(
      "plan_camera_view",
      [](const Robot& robot, const py::object& T_base_part, double top_height, const Gripper& camera_mount,
         const py::object& plane, const py::object& q, const ViewPlannerSettings& settings) {
        const Eigen::Isometry3d T = fields::Conv<Eigen::Isometry3d>::set(T_base_part, "T_base_part");
        const Eigen::Vector4d table_plane = fields::Conv<Eigen::Vector4d>::set(plane, "table_plane");
        const Vector6d q_current = fields::Conv<Vector6d>::set(q, "q_current");
        py::gil_scoped_release release;
        return planCameraView(robot, T, top_height, camera_mount, table_plane, q_current, settings);
      },
      py::arg("robot"), py::arg("T_base_part"), py::arg("top_height"), py::arg("camera_mount"), py::arg("table_plane"),
      py::arg("q_current"), py::arg("settings"),
      "The hand camera's view above a part (ViewPlan): camera poses looking straight down from settings.height above "
      "the top face at settings.yaw_steps turns, every IK configuration judged as plan_grasp judges a grasp; "
      "camera_mount.T_flange_tcp is the hand-eye T_flange_camera. ValueError naming the argument for bad input.");
}

}  // namespace scanalign::python
