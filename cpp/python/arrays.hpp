// NumPy <-> CloudView without copies. The Python layer (python/scanalign) validates
// dtypes and shapes first and makes arrays contiguous only when their layout demands it;
// these checks are the last line of defence and raise TypeError / ValueError.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include <Eigen/Core>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign::python {

namespace py = pybind11;

// ---- The one dtype rule of the bindings (README "Conventions") ---------------------------
// Number arrays are float32 or float64 (either byte order; copied to native order when
// needed). Where a function documents them, any integer dtype (and, for real-valued
// attributes, bool) too. Everything else -- float16, long double (float96/float128),
// complex, strings, objects, datetimes, and values that are no array -- is a TypeError
// naming the argument and the dtype. Every entry point that takes points or other number
// arrays converts them with checkedArray / checkedAs (or withCloud / asCloudArray below).

/// Which dtypes an argument accepts (a bit set).
enum Dtypes : unsigned { kFloats = 1u, kIntegers = 2u, kBools = 4u, kReals = kFloats | kIntegers };

/// Whether `d` is float32 or float64 (any byte order).
inline bool isFloat32Or64(const py::dtype& d) { return d.kind() == 'f' && (d.itemsize() == 4 || d.itemsize() == 8); }

/// Whether `d` is one of the dtypes `accept` names.
inline bool accepts(const py::dtype& d, unsigned accept) {
  const char k = d.kind();
  return ((accept & kFloats) && isFloat32Or64(d)) || ((accept & kIntegers) && (k == 'i' || k == 'u')) ||
         ((accept & kBools) && k == 'b');
}

/// The words for what `accept` names: "a float32 or float64 array", or "real numbers (a
/// float32, float64 or integer array)".
inline std::string acceptedWords(unsigned accept) {
  if (!(accept & (kIntegers | kBools))) return "a float32 or float64 array";
  std::string s = "real numbers (a float32, float64";
  if (accept & kIntegers) s += (accept & kBools) ? ", integer" : " or integer";
  if (accept & kBools) s += " or bool";
  return s + " array)";
}

/// `o` (an array or any array-like: a list of rows, a tuple ...) as a NumPy array of a dtype
/// `accept` names; TypeError naming `what` and the dtype (or the value) otherwise.
inline py::array checkedArray(py::handle o, const std::string& what, unsigned accept = kFloats) {
  const py::array a = py::array::ensure(o);
  const bool an_array = py::isinstance<py::array>(o);
  if (a && accepts(a.dtype(), accept)) return a;
  std::string got;
  if (a && (an_array || a.dtype().kind() != 'O')) {
    got = "dtype " + std::string(py::str(a.dtype()));
  } else {
    const std::string r = py::repr(o);
    got = r.size() <= 60 ? r : "a " + std::string(py::str(py::type::of(o).attr("__name__")));
  }
  throw py::type_error(what + ": expected " + acceptedWords(accept) + ", got " + got);
}

/// checkedArray as a C-contiguous, native-order Scalar array (no copy when it already is one).
template <typename Scalar>
py::array_t<Scalar, py::array::c_style | py::array::forcecast> checkedAs(py::handle o, const std::string& what,
                                                                          unsigned accept = kFloats) {
  return py::array_t<Scalar, py::array::c_style | py::array::forcecast>::ensure(checkedArray(o, what, accept));
}

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

/// `o` as an array cloudView<Scalar> can view: `o` itself when it already is one (no copy),
/// else a C-contiguous Scalar copy. TypeError naming `what` unless it is float32/float64.
template <typename Scalar>
py::array asCloudArray(const py::object& o, const char* what) {
  const py::array a = checkedArray(o, what);
  const auto item = static_cast<py::ssize_t>(sizeof(Scalar));
  const bool viewable = holds<Scalar>(a) && a.ndim() == 2 && a.strides(1) == item &&
                        (a.shape(0) <= 1 || (a.strides(0) >= 3 * item && a.strides(0) % item == 0));
  return viewable ? a : py::array_t<Scalar, py::array::c_style | py::array::forcecast>::ensure(a);
}

/// Calls f(CloudView<float>) or f(CloudView<double>) in the precision of `o` (any float32 /
/// float64 array-like; copied only when its layout demands it). TypeError naming `what` for
/// another dtype, ValueError for a shape other than (N, 3).
template <typename F>
auto withCloud(const py::object& o, const char* what, F&& f) {
  const py::array a = checkedArray(o, what);
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

/// ValueError naming `what` when `bytes` exceed half of this machine's memory or the
/// process's address-space limit (checked before allocating: a huge size is a clear error,
/// not an unbounded allocation).
inline void requireMemory(double bytes, const std::string& what) {
  double limit = 0.5 * static_cast<double>(sysconf(_SC_PAGE_SIZE)) * static_cast<double>(sysconf(_SC_PHYS_PAGES));
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY)
    limit = std::min(limit, 0.5 * static_cast<double>(as.rlim_cur));
  if (!(bytes <= limit)) {
    char text[96];
    std::snprintf(text, sizeof text, " need %.1f GiB, over the memory available (%.1f GiB)", bytes / 1073741824.0,
                  limit / 1073741824.0);
    throw py::value_error(what + text);
  }
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
