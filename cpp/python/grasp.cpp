// placeholder: Python bindings of the grasp area (being written)
#include <pybind11/pybind11.h>
namespace py = pybind11;
namespace scanalign::python {
void defineGrasp(py::module_& m) { (void)m; }
}  // namespace scanalign::python
