// Accessor pairs for field tables (fields.hpp) whose values need more than the member itself:
//
//   .field("T_flange_camera", frozen(&R::T_flange_camera), thawed(&R::T_flange_camera), "m", "...", false)
//       a result's array shown read-only (results are values: a caller cannot change one that
//       others hold), assigned (unpickling) through the member's checked conversion;
//   .field("axis", member(&S::axis), validating(&S::axis), "", "...")
//       a member of a struct with validate(): the struct is validated with the new value, and a
//       refused value (ValueError naming the field) leaves it as it was.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <type_traits>

#include "fields.hpp"

namespace scanalign::python {

/// `a` with NumPy's writeable flag cleared (any array type), returned.
template <typename A>
A readonly(A a) {
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

/// A value shown to Python as a read-only array (see fields::Conv<Frozen<M>>).
template <typename M>
struct Frozen {
  M value;
};

namespace fields {
/// A getter that builds its Python value itself (a dict, a tuple, a read-only array): the
/// value as it is. (fields.hpp's general Conv casts, which pybind11 refuses for Python objects.)
template <typename M>
struct Conv<M, std::enable_if_t<std::is_base_of_v<py::object, M>>> {
  static py::object get(const M& v) { return v; }
  static M set(py::handle h, const std::string& where) {
    if (!py::isinstance<M>(h)) wrongType(where, "a " + std::string(py::type_id<M>()), h);
    return py::reinterpret_borrow<M>(h);
  }
};

template <typename M>
struct Conv<Frozen<M>, void> {
  static py::object get(const Frozen<M>& v) { return readonly(py::array(Conv<M>::get(v.value))); }
  static Frozen<M> set(py::handle h, const std::string& where) { return {Conv<M>::set(h, where)}; }
};
}  // namespace fields

/// Getter of a member shown as a read-only array.
template <typename T, typename M>
auto frozen(M T::*m) {
  return [m](const T& t) { return Frozen<M>{t.*m}; };
}

/// The setter that goes with frozen(m).
template <typename T, typename M>
auto thawed(M T::*m) {
  return [m](T& t, const Frozen<M>& v) { t.*m = v.value; };
}

/// Getter of a member, as it is.
template <typename T, typename M>
auto member(M T::*m) {
  return [m](const T& t) { return t.*m; };
}

/// Setter of a member of a struct with validate(): a copy is changed and validated first.
template <typename T, typename M>
auto validating(M T::*m) {
  return [m](T& t, const M& v) {
    T copy = t;
    copy.*m = v;
    copy.validate();
    t = copy;
  };
}

}  // namespace scanalign::python
