// NumPy <-> CloudView without copies. The Python layer (python/scanalign) validates
// dtypes and shapes first and makes arrays contiguous only when their layout demands it;
// these checks are the last line of defence and raise TypeError / ValueError.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign::python {

namespace py = pybind11;

/// True when `a` holds native-order Scalar values. Compares the element type, not the dtype
/// object's identity: an array that went through pickle (multiprocessing, joblib, Ray)
/// carries an equal but distinct dtype object.
template <typename Scalar>
bool holds(const py::array& a) {
  return py::isinstance<py::array_t<Scalar>>(a);
}

/// View of an (N,3) array of Scalar whose rows may be strided (e.g. a[:, :3] of an (N,8)
/// PCL-layout array) but whose 3 coordinates are contiguous.
template <typename Scalar>
CloudView<Scalar> cloudView(const py::array& a, const char* what) {
  if (!holds<Scalar>(a))
    throw py::type_error(std::string(what) + ": expected dtype " + std::string(py::str(py::dtype::of<Scalar>())) +
                         ", got " + std::string(py::str(a.dtype())));
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + ": expected an (N, 3) array");
  if (a.shape(0) == 0) return {};  // empty arrays may carry zero strides
  const auto item = static_cast<py::ssize_t>(sizeof(Scalar));
  if (a.shape(0) > 1 && (a.strides(0) <= 0 || a.strides(0) % item != 0 || a.strides(0) < 3 * item))
    throw py::value_error(std::string(what) + ": unsupported row stride (make the array C-contiguous)");
  if (a.strides(1) != item) throw py::value_error(std::string(what) + ": coordinates must be contiguous in each row");
  const std::size_t stride = a.shape(0) > 1 ? static_cast<std::size_t>(a.strides(0) / item) : 3;
  return CloudView<Scalar>(static_cast<const Scalar*>(a.data()), static_cast<std::size_t>(a.shape(0)), stride);
}

/// `a` as an array cloudView<Scalar> can view: `a` itself when it already is one (no copy),
/// else a C-contiguous Scalar copy. TypeError naming `what` unless `a` holds floats.
template <typename Scalar>
py::array asCloudArray(const py::array& a, const char* what) {
  if (a.dtype().kind() != 'f')
    throw py::type_error(std::string(what) + ": expected a float32 or float64 array, got dtype " +
                         std::string(py::str(a.dtype())));
  const auto item = static_cast<py::ssize_t>(sizeof(Scalar));
  const bool viewable = holds<Scalar>(a) && a.ndim() == 2 && a.strides(1) == item &&
                        (a.shape(0) <= 1 || (a.strides(0) >= 3 * item && a.strides(0) % item == 0));
  return viewable ? a : py::array_t<Scalar, py::array::c_style | py::array::forcecast>::ensure(a);
}

/// Calls f(CloudView<float>) or f(CloudView<double>) in the precision of `o` (any float
/// array-like; copied only when its layout demands it). TypeError naming `what` for a
/// non-float array, ValueError for a shape other than (N, 3).
template <typename F>
auto withCloud(const py::object& o, const char* what, F&& f) {
  const py::array a = py::array::ensure(o);
  if (!a || a.dtype().kind() != 'f')
    throw py::type_error(std::string(what) + ": expected a float32 or float64 array" +
                         (a ? ", got dtype " + std::string(py::str(a.dtype())) : std::string()));
  if (holds<float>(a)) return f(cloudView<float>(asCloudArray<float>(a, what), what));
  return f(cloudView<double>(asCloudArray<double>(a, what), what));
}

/// An empty view for None.
template <typename Scalar>
CloudView<Scalar> optionalCloudView(const py::object& o, const char* what) {
  if (o.is_none()) return {};
  return cloudView<Scalar>(py::cast<py::array>(o), what);
}

/// An integer argument in [lo, hi]: a Python or NumPy integer (not a bool); TypeError or
/// ValueError naming `what` otherwise, instead of pybind11's signature dump for 2**40.
inline long long intArg(const py::object& o, const char* what, long long lo, long long hi) {
  if (py::isinstance<py::bool_>(o) || !py::hasattr(o, "__index__"))
    throw py::type_error(std::string(what) + ": expected an integer, got " + std::string(py::repr(o)));
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(py::int_(o).ptr(), &overflow);
  if (overflow != 0 || v < lo || v > hi)
    throw py::value_error(std::string(what) + " must be an integer in [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "], got " + std::string(py::repr(o)));
  return v;
}

/// A random seed: a Python or NumPy integer in [0, 2^64); TypeError or ValueError naming
/// `what` otherwise (NumPy's default_rng refuses negative seeds too).
inline std::uint64_t seedArg(const py::object& o, const char* what) {
  if (py::isinstance<py::bool_>(o) || !py::hasattr(o, "__index__"))
    throw py::type_error(std::string(what) + ": expected a non-negative integer, got " + std::string(py::repr(o)));
  const py::int_ i(o);
  const unsigned long long v = PyLong_AsUnsignedLongLong(i.ptr());
  if (v == static_cast<unsigned long long>(-1) && PyErr_Occurred()) {
    PyErr_Clear();
    throw py::value_error(std::string(what) + " must be an integer in [0, 2^64), got " + std::string(py::repr(o)));
  }
  return v;
}

/// intArg for a C++ int in [lo, 2^31 - 1].
inline int boundedInt(const py::object& v, const char* what, int lo) {
  return static_cast<int>(intArg(v, what, lo, std::numeric_limits<int>::max()));
}


/// A vector of numbers as an (N,) array, or as an (N / cols, cols) array.
template <typename T>
py::array_t<T> vectorArray(const std::vector<T>& v, py::ssize_t cols = 0) {
  py::array_t<T> a = cols > 0 ? py::array_t<T>({static_cast<py::ssize_t>(v.size()) / cols, cols})
                              : py::array_t<T>(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// Fixed-size vectors (Eigen::Vector3d, ...) as an (N, rows) array.
template <typename S, int R>
py::array_t<S> rowsArray(const std::vector<Eigen::Matrix<S, R, 1>>& v) {
  py::array_t<S> a({static_cast<py::ssize_t>(v.size()), static_cast<py::ssize_t>(R)});
  S* out = a.mutable_data();
  for (const auto& x : v)
    for (int r = 0; r < R; ++r) *out++ = x[r];
  return a;
}

/// An (M, cols) array of integers of any integer dtype (an empty array of any shape with
/// at most 2 dimensions: no rows) as int64, row-major; TypeError or ValueError naming `what`.
inline std::vector<std::int64_t> indexRows(const py::object& o, const char* what, py::ssize_t cols) {
  const py::array a = py::array::ensure(o);
  if (!a) throw py::type_error(std::string(what) + ": expected an integer array");
  if (a.size() == 0 && a.ndim() <= 2) return {};
  if (a.dtype().kind() != 'i' && a.dtype().kind() != 'u')
    throw py::type_error(std::string(what) + ": expected an integer array, got dtype " + std::string(py::str(a.dtype())));
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw py::value_error(std::string(what) + ": expected shape (M, " + std::to_string(cols) + "), got " +
                          std::string(py::str(a.attr("shape"))));
  if (a.dtype().kind() == 'u' && a.itemsize() == 8) {  // uint64 beyond int64 must not wrap
    const auto u = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    constexpr auto top = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
    if (u.size() && *std::max_element(u.data(), u.data() + u.size()) > top)
      throw py::value_error(std::string(what) + ": index beyond int64");
  }
  const auto f = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
  return std::vector<std::int64_t>(f.data(), f.data() + f.size());
}

}  // namespace scanalign::python
