// scanalign._core: the compiled core. The public, documented API is the Python package
// python/scanalign, which validates inputs and calls into these submodules.
#include <pybind11/pybind11.h>

namespace py = pybind11;

namespace scanalign::python {
void defineRegistration(py::module_& m);
void defineFeatures(py::module_& m);
void defineReconstruction(py::module_& m);
void defineSegmentation(py::module_& m);
void defineFitting(py::module_& m);
void bindSynthetic(py::module_& m);  // adds the submodule `synthetic`
void defineCga(py::module_& m);
void defineKinematics(py::module_& m);
void definePose(py::module_& m);
void definePclFeatures(py::module_& m);
void defineEvaluation(py::module_& m);
void defineIo(py::module_& m);
}  // namespace scanalign::python

PYBIND11_MODULE(_core, m) {
  m.doc() = "scanalign compiled core (use the scanalign package API)";
  auto registration = m.def_submodule("registration", "ICP engine, k-d tree, PCL plug-ins and baselines");
  auto features = m.def_submodule("features", "normal estimation");
  auto reconstruction = m.def_submodule("reconstruction", "voxel grid");
  scanalign::python::defineRegistration(registration);
  scanalign::python::defineFeatures(features);
  scanalign::python::defineReconstruction(reconstruction);
  auto segmentation = m.def_submodule("segmentation", "RANSAC plane / sphere, table segmentation");
  scanalign::python::defineSegmentation(segmentation);
  auto fitting = m.def_submodule("fitting", "CGA sphere fit, Pratt circle fit");
  scanalign::python::defineFitting(fitting);
  scanalign::python::bindSynthetic(m);
  auto cga = m.def_submodule("cga", "conformal geometric algebra G(4,1)");
  scanalign::python::defineCga(cga);
  auto kinematics = m.def_submodule("kinematics", "DH robots, forward kinematics, CGA inverse kinematics");
  scanalign::python::defineKinematics(kinematics);
  auto pose = m.def_submodule("pose", "CBD descriptor, motor estimation, correspondence RANSAC, flag alignment");
  scanalign::python::definePose(pose);
  scanalign::python::definePclFeatures(pose);
  auto io = m.def_submodule("io", "PCD reading, LZF decompression");
  scanalign::python::defineIo(io);
  auto evaluation = m.def_submodule("evaluation", "exact point-to-mesh distance");
  scanalign::python::defineEvaluation(evaluation);
}
