// scanalign._core: the compiled core. The public, documented API is the Python package
// python/scanalign, which validates inputs and calls into these submodules.
#include <pybind11/pybind11.h>

#include <chrono>

#include "scanalign/common/build_info.hpp"
#include "scanalign/common/interrupt.hpp"

namespace py = pybind11;

namespace scanalign::python {
void defineCommon(py::module_& m);
void defineRegistration(py::module_& m);
void defineFeatures(py::module_& m);
void defineReconstruction(py::module_& m);
void defineSegmentation(py::module_& m);
void defineFitting(py::module_& m);
void defineSynthetic(py::module_& m);
void defineCga(py::module_& m);
void defineKinematics(py::module_& m);
void definePose(py::module_& m);
void defineEvaluation(py::module_& m);
void defineIo(py::module_& m);
void defineCalibration(py::module_& m);
void defineGrasp(py::module_& m);
}  // namespace scanalign::python

namespace {

/// The exception a Python signal handler raised (KeyboardInterrupt for Ctrl-C) while a C++
/// loop ran: fetched in the hook, so that no Python error is pending while the C++ stack
/// unwinds, and restored by the translator below when the Interrupted it caused arrives.
struct PendingSignalError {
  PyObject* type = nullptr;
  PyObject* value = nullptr;
  PyObject* traceback = nullptr;
};
thread_local PendingSignalError pending_signal_error;

/// scanalign::interrupt_hook for Python: runs the signal handlers (Python only runs them
/// between bytecodes, never while a C++ call is running). Long calls release the GIL
/// (py::gil_scoped_release), so it is taken here; PyGILState_Ensure also works when the
/// thread already holds it. On threads other than the main one PyErr_CheckSignals does
/// nothing and returns 0.
/// At most one check per 20 ms and thread: taking the GIL may wait for another Python
/// thread's switch interval, and a person pressing Ctrl-C does not notice 20 ms.
bool pythonInterruptHook() {
  thread_local std::chrono::steady_clock::time_point last_check{};
  const auto now = std::chrono::steady_clock::now();
  if (now - last_check < std::chrono::milliseconds(20)) return false;
  last_check = now;
  const PyGILState_STATE gil = PyGILState_Ensure();
  bool stop = false;
  if (PyErr_CheckSignals() != 0) {
    PendingSignalError& e = pending_signal_error;
    Py_XDECREF(e.type);
    Py_XDECREF(e.value);
    Py_XDECREF(e.traceback);
    PyErr_Fetch(&e.type, &e.value, &e.traceback);
    stop = true;
  }
  PyGILState_Release(gil);
  return stop;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "scanalign compiled core (use the scanalign package API)";
  m.attr("__version__") = scanalign::version();  // the package's version (one source: CMakeLists.txt)
  m.attr("built_with_pcl") = scanalign::builtWithPcl();
  m.attr("built_with_cuda") = scanalign::builtWithCuda();
  auto common = m.def_submodule("common", "rigid transforms, camera placement, mesh sampling");
  scanalign::python::defineCommon(common);
  auto registration = m.def_submodule("registration", "ICP engine, k-d tree, PCL plug-ins and baselines");
  auto features = m.def_submodule("features", "normal estimation");
  auto reconstruction = m.def_submodule(
      "reconstruction", "intrinsics, depth images, depth renderer, frame-to-model reconstruction, voxel grid");
  scanalign::python::defineRegistration(registration);
  scanalign::python::defineFeatures(features);
  scanalign::python::defineReconstruction(reconstruction);
  auto segmentation = m.def_submodule("segmentation", "RANSAC plane / sphere, table segmentation");
  scanalign::python::defineSegmentation(segmentation);
  auto fitting = m.def_submodule("fitting", "CGA sphere fit, Pratt circle fit");
  scanalign::python::defineFitting(fitting);
  auto synthetic = m.def_submodule("synthetic", "built-in parts, the simulator's scene and camera paths, sensor noise");
  scanalign::python::defineSynthetic(synthetic);
  auto cga = m.def_submodule("cga", "conformal geometric algebra G(4,1)");
  scanalign::python::defineCga(cga);
  auto kinematics = m.def_submodule("kinematics", "DH robots, forward kinematics, CGA inverse kinematics");
  scanalign::python::defineKinematics(kinematics);
  auto pose = m.def_submodule("pose", "CBD descriptor, motor estimation, correspondence RANSAC, flag alignment");
  scanalign::python::definePose(pose);
  auto io = m.def_submodule("io", "PCD reading, LZF decompression");
  scanalign::python::defineIo(io);
  auto evaluation = m.def_submodule("evaluation", "exact point-to-mesh distance");
  scanalign::python::defineEvaluation(evaluation);
  auto calibration = m.def_submodule("calibration", "hand-eye calibration (AX = XB)");
  scanalign::python::defineCalibration(calibration);
  auto grasp = m.def_submodule("grasp", "grasps, gripper, grasp planning with IK");
  scanalign::python::defineGrasp(grasp);
  // Ctrl-C stops long loops: scanalign::Interrupted (common/interrupt.hpp) becomes the
  // exception the signal handler raised, KeyboardInterrupt by default. Registered last so
  // that it is tried first (pybind11 tries translators newest first), before any
  // translator a submodule might add for std::runtime_error, Interrupted's base.
  scanalign::interrupt_hook.store(&pythonInterruptHook);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const scanalign::Interrupted& e) {
      PendingSignalError& pending = pending_signal_error;
      if (pending.type != nullptr) {
        PyErr_Restore(pending.type, pending.value, pending.traceback);  // steals the references
        pending = PendingSignalError{};
      } else {
        PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
      }
    }
  });
  // A wrongly typed argument is named in the TypeError instead of pybind11's dump of every
  // signature (scanalign.common.arrays.explain_bad_arguments wraps each function and method).
  // Skipped only where the module is loaded outside its package (type-stub generation).
  try {
    const py::object explain = py::module_::import("scanalign.common.arrays").attr("explain_bad_arguments");
    for (const auto& item : m.attr("__dict__").cast<py::dict>())
      if (py::isinstance<py::module_>(item.second)) explain(item.second);
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_ImportError)) throw;
  }
}
