// A suspect result's warning text, raised as a Python UserWarning (the C++ result keeps it
// too: `TableSegmentationResult::warning`). Needs the GIL; under `-W error` the warning
// propagates as the exception Python made of it.
#pragma once

#include <pybind11/pybind11.h>

#include <string>

namespace scanalign::python {

inline void warnPython(const std::string& message) {
  if (message.empty()) return;
  if (PyErr_WarnEx(PyExc_UserWarning, message.c_str(), 1) < 0) throw pybind11::error_already_set();
}

}  // namespace scanalign::python
