// Pickle support for the bound C++ structs (issue 18: settings, results and models cross
// process boundaries: multiprocessing, Ray). One rule for every class: the state is a dict
// {Python attribute name: value}, values plain Python scalars / str / NumPy arrays / nested
// picklable objects, so the state is readable, stable across builds and diffable; a large
// std::vector is stored as a NumPy array (pickle protocol 5 ships it as one buffer instead
// of a list of Python floats).
//
//   pickleFields(cls, field("radius", &T::radius), field("part", &T::part), ...);
//
// `__setstate__` default-constructs T and assigns each member; a missing or unknown key is
// a ValueError and a value of the wrong type a TypeError, both naming the class and key.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scanalign::python {

namespace py = pybind11;

namespace pickling {

template <typename T>
struct IsStdVector : std::false_type {};
template <typename V, typename A>
struct IsStdVector<std::vector<V, A>> : std::true_type {};

/// Fixed-size Eigen matrix (Vector3d, Matrix4d, ...): element of an (N, rows[, cols]) array.
template <typename T>
struct IsFixedEigen : std::false_type {};
template <typename S, int R, int C, int O, int MR, int MC>
struct IsFixedEigen<Eigen::Matrix<S, R, C, O, MR, MC>> : std::bool_constant<(R > 0 && C > 0)> {};

/// A vector member stored as one NumPy array: numbers, bools, fixed-size Eigen matrices.
template <typename M>
constexpr bool isArrayVector() {
  if constexpr (IsStdVector<M>::value) {
    using V = typename M::value_type;
    return std::is_arithmetic_v<V> || IsFixedEigen<V>::value;
  } else {
    return false;
  }
}

template <typename V>
struct ElementOf {
  using type = V;
  static constexpr int rows = 1, cols = 1;
};
template <typename S, int R, int C, int O, int MR, int MC>
struct ElementOf<Eigen::Matrix<S, R, C, O, MR, MC>> {
  using type = S;
  static constexpr int rows = R, cols = C;
};

/// std::vector of numbers or fixed-size matrices -> (N,), (N, rows) or (N, rows, cols) array.
template <typename M>
py::object vectorToArray(const M& v) {
  using V = typename M::value_type;
  using E = ElementOf<V>;
  using S = typename E::type;
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(v.size())};
  if (E::rows > 1 || E::cols > 1) shape.push_back(E::rows);
  if (E::cols > 1) shape.push_back(E::cols);
  py::array_t<S> a(shape);
  S* out = a.mutable_data();
  for (const V& x : v) {
    if constexpr (IsFixedEigen<V>::value) {
      // Row-major in the array whatever the Eigen storage order.
      for (int r = 0; r < E::rows; ++r)
        for (int c = 0; c < E::cols; ++c) *out++ = x(r, c);
    } else {
      *out++ = static_cast<S>(x);  // std::vector<bool> yields proxies
    }
  }
  return std::move(a);
}

template <typename M>
M arrayToVector(py::handle h, const std::string& what) {
  using V = typename M::value_type;
  using E = ElementOf<V>;
  using S = typename E::type;
  const std::string dtype = py::str(py::dtype::of<S>());
  if (!py::isinstance<py::array>(h) || !py::isinstance<py::array_t<S>>(h))
    throw py::type_error(what + ": expected a NumPy array of dtype " + dtype + ", got " +
                         std::string(py::str(py::type::of(h))) +
                         (py::isinstance<py::array>(h) ? " of dtype " + std::string(py::str(h.attr("dtype"))) : ""));
  const auto a = py::array_t<S, py::array::c_style | py::array::forcecast>::ensure(h);
  const py::ssize_t ndim = 1 + (E::rows > 1 || E::cols > 1) + (E::cols > 1);
  if (a.ndim() != ndim || (ndim > 1 && a.shape(1) != E::rows) || (ndim > 2 && a.shape(2) != E::cols))
    throw py::value_error(what + ": array of the wrong shape");
  M v;
  v.reserve(static_cast<std::size_t>(a.shape(0)));
  const S* in = a.data();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    if constexpr (IsFixedEigen<V>::value) {
      V x;
      for (int r = 0; r < E::rows; ++r)
        for (int c = 0; c < E::cols; ++c) x(r, c) = *in++;
      v.push_back(x);
    } else {
      v.push_back(static_cast<V>(*in++));
    }
  }
  return v;
}

}  // namespace pickling

/// A member (or property) as a pickled value: numbers, bool, str, Eigen arrays, bound structs
/// and std::optional through the bindings' casters; vectors of numbers or fixed-size Eigen
/// matrices as one NumPy array; an Eigen::Isometry3d as its 4x4 matrix; an enum bound with
/// py::enum_ as its member (an unbound one needs namedEnum).
template <typename M>
py::object toState(const M& v) {
  if constexpr (pickling::isArrayVector<M>()) {
    return pickling::vectorToArray(v);
  } else if constexpr (std::is_enum_v<M>) {
    // An unbound enum has no checked Python form here: bind it with namedEnum (its name) or
    // an accessor field with a range check, never a raw int nobody validates on load.
    if (!py::detail::get_type_info(typeid(M)))
      throw py::type_error("pickling an unbound enum as a plain field: use namedEnum (pickle.hpp)");
    return py::cast(v);
  } else if constexpr (py::detail::is_pyobject<M>::value) {
    return py::reinterpret_borrow<py::object>(v);
  } else if constexpr (std::is_same_v<M, Eigen::Isometry3d>) {
    return py::cast(Eigen::Matrix4d(v.matrix()));  // as the 4x4 the bindings show
  } else {
    return py::cast(v);
  }
}

/// The inverse of toState; TypeError / ValueError naming `what` for a value it cannot be.
template <typename M>
M fromState(py::handle h, const std::string& what) {
  if constexpr (pickling::isArrayVector<M>()) {
    return pickling::arrayToVector<M>(h, what);
  } else if constexpr (std::is_same_v<M, Eigen::Isometry3d>) {
    Eigen::Isometry3d T;
    T.matrix() = h.cast<Eigen::Matrix4d>();
    return T;
  } else if constexpr (std::is_same_v<M, bool>) {
    // pybind11 would accept numpy.bool_ too; a float or int here means a mangled state.
    if (!py::isinstance<py::bool_>(h) && !py::isinstance(h, py::module_::import("numpy").attr("bool_")))
      throw py::type_error(what + ": expected a bool, got " + std::string(py::str(py::type::of(h))));
    return h.cast<bool>();
  } else {
    return h.cast<M>();
  }
}

/// One pickled attribute of T: the Python name and how to read / write it.
template <typename T>
struct PickleField {
  std::string name;
  std::function<py::object(const T&)> get;
  std::function<void(T&, py::handle, const std::string&)> set;
};

/// A data member pickled under `name` (the Python attribute name).
template <typename T, typename M>
PickleField<T> field(const char* name, M T::*member) {
  return {name, [member](const T& t) { return toState(t.*member); },
          [member](T& t, py::handle h, const std::string& what) { t.*member = fromState<M>(h, what); }};
}

/// A value reached through accessors (a private member, a derived layout): get(const T&) -> V
/// and set(T&, V).
template <typename T, typename Get, typename Set>
PickleField<T> field(const char* name, Get get, Set set) {
  using V = std::decay_t<std::invoke_result_t<Get, const T&>>;
  return {name, [get](const T& t) { return toState<V>(get(t)); },
          [set](T& t, py::handle h, const std::string& what) { set(t, fromState<V>(h, what)); }};
}

/// An enum member that Python sees as a string (IcpSettings.estimator = 'point_to_plane'):
/// pickled as that string, toString(E) found by ADL; `count` enumerators 0..count-1. An
/// unknown name is a ValueError, so a state from another version cannot load a wrong value.
template <typename T, typename E>
PickleField<T> namedEnum(const char* name, E T::*member, int count) {
  return {name, [member](const T& t) { return py::object(py::str(toString(t.*member))); },
          [member, count](T& t, py::handle h, const std::string& what) {
            if (!py::isinstance<py::str>(h))
              throw py::type_error(what + ": expected a str, got " + std::string(py::str(py::type::of(h))));
            const std::string s = h.cast<std::string>();
            for (int i = 0; i < count; ++i)
              if (s == toString(static_cast<E>(i))) {
                t.*member = static_cast<E>(i);
                return;
              }
            throw py::value_error(what + ": unknown value '" + s + "'");
          }};
}

/// The pickled state of `obj`: {name: value} over `fields`.
template <typename T>
py::dict stateOf(const T& obj, const std::vector<PickleField<T>>& fields) {
  py::dict d;
  for (const auto& f : fields) d[py::str(f.name)] = f.get(obj);
  return d;
}

/// Assigns `state` to `obj` field by field: ValueError for a missing or unknown key (a state
/// from another version of the class), TypeError naming the key for a value of the wrong type.
template <typename T>
void assignState(T& obj, const py::dict& state, const std::vector<PickleField<T>>& fields, const std::string& cls) {
  for (const auto& item : state) {
    const std::string key = py::str(item.first);
    bool known = false;
    for (const auto& f : fields) known = known || f.name == key;
    if (!known) throw py::value_error(cls + ": pickled state has an unknown key '" + key + "'");
  }
  for (const auto& f : fields) {
    if (!state.contains(f.name)) throw py::value_error(cls + ": pickled state lacks '" + f.name + "'");
    const std::string what = cls + ": pickled state '" + f.name + "'";
    try {
      f.set(obj, state[py::str(f.name)], what);
    } catch (const py::cast_error& e) {
      throw py::type_error(what + " has the wrong type (" + std::string(py::str(py::type::of(state[py::str(f.name)]))) +
                           "): " + e.what());
    }
  }
}

template <typename T, typename = void>
struct HasValidate : std::false_type {};
template <typename T>
struct HasValidate<T, std::void_t<decltype(std::declval<const T&>().validate())>> : std::true_type {};

/// Adds __getstate__ / __setstate__ (py::pickle) to `cls` from `fields`; T is default-
/// constructed and then assigned, so a field left out keeps its default (and the round-trip
/// test, which sets every field to a non-default value, catches it). A T with a validate()
/// member (SensorNoise, PinholeIntrinsics, Gripper, PartSymmetry, Grasp,
/// GraspPlannerSettings) is validated after loading, as its constructor does: a mangled
/// state is a ValueError, not an object no constructor makes.
template <typename T, typename... Extra>
void pickleFields(py::class_<T, Extra...>& cls, std::vector<PickleField<T>> fields) {
  const std::string name = py::str(cls.attr("__name__"));
  cls.def(py::pickle([fields](const T& obj) { return stateOf(obj, fields); },
                     [fields, name](const py::dict& state) {
                       T obj{};
                       assignState(obj, state, fields, name);
                       if constexpr (HasValidate<T>::value) obj.validate();
                       return obj;
                     }));
}

/// pickleFields for a class_ built inline: cls.def(...) chains return class_&.
template <typename T, typename... Extra, typename... Fields>
void pickleFields(py::class_<T, Extra...>& cls, PickleField<T> first, Fields... rest) {
  pickleFields(cls, std::vector<PickleField<T>>{std::move(first), std::move(rest)...});
}

/// pickleFields for the class bound as `name` in `m` (after a chain of .def calls).
template <typename T, typename... Fields>
void pickleFields(py::module_& m, const char* name, PickleField<T> first, Fields... rest) {
  auto cls = py::reinterpret_borrow<py::class_<T>>(m.attr(name));
  pickleFields(cls, std::vector<PickleField<T>>{std::move(first), std::move(rest)...});
}

/// For engines whose state is not worth shipping: pickling raises TypeError saying what to
/// send instead (docs/api/pickle.md lists them).
template <typename T, typename... Extra>
void refusePickle(py::class_<T, Extra...>& cls, const std::string& instead) {
  const std::string message = std::string(py::str(cls.attr("__name__"))) + " cannot be pickled: " + instead;
  cls.def("__reduce_ex__", [message](const T&, py::handle) -> py::object { throw py::type_error(message); },
          py::arg("protocol"), ("Raises TypeError: " + message).c_str());
}

/// refusePickle for the class bound as `name` in `m`.
template <typename T>
void refusePickle(py::module_& m, const char* name, const std::string& instead) {
  auto cls = py::reinterpret_borrow<py::class_<T>>(m.attr(name));
  refusePickle(cls, instead);
}

}  // namespace scanalign::python
