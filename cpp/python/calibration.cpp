// placeholder: Python bindings of the calibration area (being written)
#include <pybind11/pybind11.h>
namespace py = pybind11;
namespace scanalign::python {
void defineCalibration(py::module_& m) { (void)m; }
}  // namespace scanalign::python
