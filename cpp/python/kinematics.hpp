// Shared by the bindings of scanalign/kinematics: kinematics_robot.cpp (the Robot, forward
// kinematics, robots from DH tables and joint chains) and kinematics_ik.cpp (inverse
// kinematics and its results). Every argument is checked here, once, and a bad one raises
// TypeError / ValueError naming it.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "field_access.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace scanalign::python::kin {

namespace py = pybind11;
using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using RowMatrix4d = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;
using RobotClass = py::class_<Robot>;

/// "(6,)", "(N, 4, 4)": a shape as Python writes it.
std::string shapeText(const py::array& a);

/// `x` as a C-contiguous float64 array; TypeError naming `name` unless it holds real numbers
/// (bool, complex, strings and objects are refused rather than cast).
F64 realArray(py::handle x, const std::string& name);

/// (6,) finite values (>= 0 with nonnegative).
Vector6d vector6(py::handle x, const std::string& name, bool nonnegative = false);
Vector6d vector6Or(const py::object& x, const char* name, const Vector6d& otherwise, bool nonnegative = false);

/// (6,) or (N, 6) finite joint values within +-1e6 rad.
F64 joints(py::handle x, const char* name = "q");

/// One rigid 4x4 transform (scanalign::requireRigid names the failed property).
Eigen::Isometry3d rigid(py::handle x, const std::string& name);

/// (N, 4, 4) poses; with `each_rigid` every pose must be rigid (the error names its index),
/// else a bad pose is left to the solver, which gives it IKStatus::InvalidInput.
F64 poses(py::handle x, const char* name, bool each_rigid);

/// A finite value >= 0.
double tolerance(double v, const char* name);

/// num_threads >= 0 (0 = all cores).
int threadCount(int num_threads);

/// ValueError unless the analytic IK covers r's DH table.
void requireIk(const Robot& r);

/// A fixed-size matrix as a read-only row-major array.
template <typename M>
py::array_t<double> readonlyMatrix(const M& m) {
  const Eigen::Matrix<double, M::RowsAtCompileTime, M::ColsAtCompileTime, Eigen::RowMajor> r = m;
  return readonly(py::array_t<double>({py::ssize_t{r.rows()}, py::ssize_t{r.cols()}}, r.data()));
}

/// Binds the IK result classes and the module's IK constants (kinematics_ik.cpp).
void bindIkResults(py::module_& m);
/// Adds ik, ik_closest, ik_batch, ik_trajectory and ik_construction to Robot (kinematics_ik.cpp).
void defInverse(RobotClass& c);

}  // namespace scanalign::python::kin
