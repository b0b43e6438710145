// Bindings of scanalign/calibration: hand-eye calibration (AX = ZB). The C++ settings and
// result structs are bound through their field tables (fields.hpp). Pose
// arrays are checked here (shape, rigidity naming the index) and raise ValueError / TypeError;
// python/scanalign/calibration.py re-exports these and picks the camera-pose source.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "field_access.hpp"
#include "fields.hpp"
#include "scanalign/calibration/hand_eye.hpp"
#include "scanalign/common/rigid.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {
constexpr int kHandEyeStatusCount = 5;  // ok, too_few_poses, invalid_input, degenerate_motion, inconsistent_poses
using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using RowMatrix4d = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;

std::string shapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// (N, 4, 4) real array -> N rigid transforms; TypeError / ValueError naming `name` (and the
/// index of a pose that is not rigid).
std::vector<Eigen::Matrix4d> poses(py::handle x, const std::string& name) {
  const F64 f = checkedAs<double>(x, name, kReals);
  if (f.ndim() != 3 || f.shape(1) != 4 || f.shape(2) != 4)
    throw py::value_error(name + ": expected an (N, 4, 4) array of poses, got shape " + shapeText(f));
  std::vector<Eigen::Matrix4d> out(static_cast<std::size_t>(f.shape(0)));
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = Eigen::Map<const RowMatrix4d>(f.data() + 16 * i);
    requireRigid(out[i], name + "[" + std::to_string(i) + "]");
    if (!(out[i].topRightCorner<3, 1>().cwiseAbs().maxCoeff() <= 1e6))
      throw py::value_error(name + "[" + std::to_string(i) + "]: its translation is beyond 1e6 m");
  }
  return out;
}

void checkCount(const std::vector<Eigen::Matrix4d>& A, const std::vector<Eigen::Matrix4d>& B, const char* name) {
  if (A.size() != B.size())
    throw py::value_error(std::string("T_base_flange and ") + name + " must hold as many poses, got " +
                          std::to_string(A.size()) + " and " + std::to_string(B.size()));
}

void bindSettings(py::module_& m) {
  using S = HandEyeSettings;
  fieldsOf(py::class_<S>(m, "HandEyeSettings", "Settings of calibrate_hand_eye (units beside each field)"))
      .field("min_relative_rotation", &S::min_relative_rotation, "rad",
             "relative motions rotating less do not count for the degeneracy check; fewer than 2 above it: "
             "'degenerate_motion'")
      .field("min_axis_angle", &S::min_axis_angle, "rad",
             "least spread of the relative rotation axes (the largest angle between the axis of the largest relative "
             "rotation and any other counted one, axes as lines); below it: 'degenerate_motion'")
      .field("refine", &S::refine, "", "Levenberg-Marquardt refinement of the closed form")
      .field("rotation_weight", &S::rotation_weight, "m/rad",
             "a rotation error of 1 rad costs as much as this many metres; the maximum-likelihood choice is "
             "sigma_translation / sigma_rotation of the camera poses")
      .field("huber_delta", &S::huber_delta, "m",
             "Huber threshold on the weighted 6-vector residual of a pose (0: least squares)")
      .field("max_rms_translation", &S::max_rms_translation, "m",
             "largest RMS translation residual of an answer; above it: 'inconsistent_poses'")
      .field("max_rms_rotation", &S::max_rms_rotation, "rad",
             "largest RMS rotation residual of an answer; above it: 'inconsistent_poses'")
      .field("max_iterations", &S::max_iterations, "", "Levenberg-Marquardt iterations, >= 1")
      .field("step_tolerance", &S::step_tolerance, "m, rad", "stop when the step's largest component is below this")
      .settings()
      .def("validate", [](const S& s) { validate(s); }, "ValueError naming a bad field");
}

void bindResult(py::module_& m) {
  using R = HandEyeResult;
  fieldsOf(py::class_<R>(m, "HandEyeResult",
                         "Outcome of calibrate_hand_eye: T_base_flange[i] @ T_flange_camera = T_base_world @ "
                         "T_world_camera[i]. Transforms are 4x4 read-only arrays, metres. Falsy unless status is 'ok'.")
               .def("__bool__", &R::ok)
               .def("__repr__", [](const R& r) {
                 return std::string("HandEyeResult(status='") + toString(r.status) + "', rms_rotation=" +
                        std::to_string(r.rms_rotation) + " rad, rms_translation=" + std::to_string(r.rms_translation) +
                        " m, iterations=" + std::to_string(r.iterations) +
                        (r.message.empty() ? "" : ", message=" + r.message) + ")";
               }))
      .name("status", &R::status, kHandEyeStatusCount, "",
            "'ok', 'too_few_poses' (< 3), 'invalid_input', 'degenerate_motion' (rotations too small, or all relative "
            "rotation axes nearly parallel) or 'inconsistent_poses' (RMS residual above max_rms_*: the transforms are "
            "filled in, to look at)",
            false)
      .output("message", &R::message, "", "empty when ok, else why")
      .field("T_flange_camera", frozen(&R::T_flange_camera), thawed(&R::T_flange_camera), "m",
             "(4, 4) camera -> flange: refined, or the closed form when settings.refine is False", false)
      .field("T_base_world", frozen(&R::T_base_world), thawed(&R::T_base_world), "m",
             "(4, 4) world -> robot base: the target's pose (T_base_target) or the scan's model frame in the base",
             false)
      .field("T_flange_camera_closed_form", frozen(&R::T_flange_camera_closed_form),
             thawed(&R::T_flange_camera_closed_form), "m", "(4, 4) the dual-quaternion closed form (Daniilidis 1999)",
             false)
      .field("T_base_world_closed_form", frozen(&R::T_base_world_closed_form), thawed(&R::T_base_world_closed_form),
             "m", "(4, 4) chordal mean of T_base_flange[i] @ X @ inv(T_world_camera[i]) at the closed-form X", false)
      .field("residual_rotation", frozen(&R::residual_rotation), thawed(&R::residual_rotation), "rad",
             "(N,) per pose: rotation angle of inv(T_base_world @ T_world_camera[i]) @ T_base_flange[i] @ "
             "T_flange_camera",
             false)
      .field("residual_translation", frozen(&R::residual_translation), thawed(&R::residual_translation), "m",
             "(N,) per pose: the camera's position error between the two sides", false)
      .output("rms_rotation", &R::rms_rotation, "rad", "RMS over poses at the answer")
      .output("rms_translation", &R::rms_translation, "m", "RMS over poses at the answer")
      .output("rms_rotation_closed_form", &R::rms_rotation_closed_form, "rad", "RMS at the closed form")
      .output("rms_translation_closed_form", &R::rms_translation_closed_form, "m", "RMS at the closed form")
      .output("iterations", &R::iterations, "", "Levenberg-Marquardt iterations (0: no refinement)")
      .output("converged", &R::converged, "", "the refinement met step_tolerance (True without refinement)")
      .output("pairs", &R::pairs, "", "relative motions (pose pairs i < j) in the closed form")
      .output("axis_spread", &R::axis_spread, "rad", "see HandEyeSettings.min_axis_angle")
      .output("max_relative_rotation", &R::max_relative_rotation, "rad", "largest relative rotation of the flange")
      .derived("ok", [](const R& r) { return r.ok(); }, "", "status == 'ok'")
      .result();
}
}  // namespace

void defineCalibration(py::module_& m) {
  m.doc() = "Hand-eye calibration of an eye-in-hand camera (AX = ZB)";
  bindSettings(m);
  bindResult(m);
  m.def(
      "calibrate_hand_eye",
      [](const py::object& T_base_flange, const py::object& T_world_camera, const HandEyeSettings& settings) {
        const auto A = poses(T_base_flange, "T_base_flange"), B = poses(T_world_camera, "T_world_camera");
        checkCount(A, B, "T_world_camera");
        py::gil_scoped_release release;
        return calibrateHandEye(A, B, settings);
      },
      py::arg("T_base_flange"), py::arg("T_world_camera"), py::arg("settings") = HandEyeSettings{},
      "Solves T_base_flange[i] @ X = Z @ T_world_camera[i] for X = T_flange_camera and Z = T_base_world: "
      "Daniilidis' dual-quaternion closed form over all pose pairs, then Levenberg-Marquardt on SE(3). "
      "(N, 4, 4) poses, metres. ValueError for a bad shape, differing N, a non-rigid pose (named by index) "
      "or invalid settings.");
  m.def(
      "calibrate_hand_eye_from_target",
      [](const py::object& T_base_flange, const py::object& T_camera_target, const HandEyeSettings& settings) {
        const auto A = poses(T_base_flange, "T_base_flange"), B = poses(T_camera_target, "T_camera_target");
        checkCount(A, B, "T_camera_target");
        py::gil_scoped_release release;
        return calibrateHandEyeFromTarget(A, B, settings);
      },
      py::arg("T_base_flange"), py::arg("T_camera_target"), py::arg("settings") = HandEyeSettings{},
      "calibrate_hand_eye from views of a fixed target: T_camera_target[i] (target -> camera i) = "
      "inv(T_world_camera[i]); the result's T_base_world is T_base_target.");
}

}  // namespace scanalign::python
