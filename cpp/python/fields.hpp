// One field table per bound struct. Each entry names a member once, with its unit and doc,
// and the table gives the class everything a field needs on the Python side:
//
//   - a property (checked setter: a wrong type is a TypeError naming Class.field, never a
//     silent conversion of a string or a bool), its doc "[unit] doc (default: value)";
//   - pickling: the state is {field: value} (numbers, str, NumPy arrays, nested structs), so
//     settings and results cross process boundaries (multiprocessing, Ray) and a state from
//     another version is refused by name (a missing or unknown key);
//   - `__fields__`: ((name, unit, doc, writable), ...), which the Python settings schema
//     (scanalign.common.settings) turns into dicts, YAML, --set paths and dump-config;
//   - `==` over the stored fields, a repr, and for settings `Class(**fields)` / `Class(other)`.
//
//   Fields<IcpSettings>(cls)
//       .field("max_correspondence_distance", &IcpSettings::max_correspondence_distance, "m", "pairs ...")
//       .name("estimator", &IcpSettings::estimator, 2, "", "'point_to_plane' or 'point_to_point'")
//       .settings();   // or .result() for outputs
//
// Member kinds: numbers, bool, str, enums bound with py::enum_ (a member or its name), enums
// shown by name (name(): toString, `count` enumerators), fixed-size Eigen matrices,
// Eigen::Isometry3d (a 4x4), std::optional<X>, std::vector of numbers or fixed-size matrices
// (a NumPy array), nested bound structs (the property returns the nested object itself, so
// `settings.pose.icp_distance = 0.02` changes `settings`), and anything else pybind11 casts.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "arrays.hpp"

namespace scanalign::python {

namespace py = pybind11;

namespace fields {

/// How a value is shown in a message: its repr, or its type for a long one.
inline std::string shown(py::handle v) {
  std::string r = py::repr(v);
  return r.size() <= 60 ? r : "a " + std::string(py::str(py::type::of(v).attr("__name__")));
}

[[noreturn]] inline void wrongType(const std::string& where, const std::string& expected, py::handle v) {
  throw py::type_error(where + ": expected " + expected + ", got " + shown(v));
}

/// The NumPy dtype kind ('b', 'i', 'u', 'f', 'c', ...) of a NumPy scalar, or 0 for anything else.
inline char numpyScalarKind(py::handle v) {
  // Leaked on purpose: a static py::object would be released after the interpreter is gone.
  static const py::handle generic = py::object(py::module_::import("numpy").attr("generic")).release();
  if (!py::isinstance(v, generic)) return 0;
  return std::string(py::str(v.attr("dtype").attr("kind")))[0];
}

inline bool isBool(py::handle v) { return PyBool_Check(v.ptr()) || numpyScalarKind(v) == 'b'; }
inline bool isInteger(py::handle v) {
  return (PyLong_Check(v.ptr()) && !PyBool_Check(v.ptr())) || numpyScalarKind(v) == 'i' || numpyScalarKind(v) == 'u';
}
inline bool isReal(py::handle v) { return isInteger(v) || PyFloat_Check(v.ptr()) || numpyScalarKind(v) == 'f'; }

template <typename T>
struct IsVector : std::false_type {};
template <typename V, typename A>
struct IsVector<std::vector<V, A>> : std::true_type {};
template <typename T>
struct IsOptional : std::false_type {};
template <typename V>
struct IsOptional<std::optional<V>> : std::true_type {};
template <typename T>
struct IsFixedEigen : std::false_type {};
template <typename S, int R, int C, int O, int MR, int MC>
struct IsFixedEigen<Eigen::Matrix<S, R, C, O, MR, MC>> : std::bool_constant<(R > 0 && C > 0)> {
  using Scalar = S;
  static constexpr int rows = R, cols = C;
};

/// A member type shown as a NumPy array: a vector of numbers or of fixed-size matrices.
template <typename M>
constexpr bool isArrayVector() {
  if constexpr (IsVector<M>::value) {
    using V = typename M::value_type;
    return (std::is_arithmetic_v<V> && !std::is_same_v<V, bool>) || IsFixedEigen<V>::value;
  } else {
    return false;
  }
}

/// A member that is itself a bound struct (the property returns it by reference).
template <typename T>
struct IsStdArrayOrPair : std::false_type {};
template <typename V, std::size_t N>
struct IsStdArrayOrPair<std::array<V, N>> : std::true_type {};
template <typename A, typename B>
struct IsStdArrayOrPair<std::pair<A, B>> : std::true_type {};
template <typename M>
constexpr bool isNested() {
  return std::is_class_v<M> && !IsVector<M>::value && !IsOptional<M>::value && !IsStdArrayOrPair<M>::value &&
         !std::is_base_of_v<Eigen::EigenBase<M>, M> && !std::is_same_v<M, std::string> &&
         !std::is_same_v<M, Eigen::Isometry3d> && !std::is_base_of_v<py::object, M>;
}

template <typename M>
std::string expected() {
  if constexpr (std::is_same_v<M, bool>) {
    return "True or False";
  } else if constexpr (std::is_integral_v<M>) {
    return "an integer in [" + std::to_string(std::numeric_limits<M>::lowest()) + ", " +
           std::to_string(std::numeric_limits<M>::max()) + "]";
  } else if constexpr (std::is_floating_point_v<M>) {
    return "a real number";
  } else if constexpr (std::is_same_v<M, std::string>) {
    return "a string";
  } else if constexpr (IsFixedEigen<M>::value) {
    return IsFixedEigen<M>::cols == 1 ? std::to_string(IsFixedEigen<M>::rows) + " real numbers"
                                      : "a " + std::to_string(IsFixedEigen<M>::rows) + "x" +
                                            std::to_string(IsFixedEigen<M>::cols) + " real matrix";
  } else {
    return "a " + std::string(py::type_id<M>());
  }
}

/// Real numbers (float32/float64, integer or bool: arrays.hpp's dtype rule); TypeError naming
/// `where` otherwise.
inline py::array realArray(py::handle h, const std::string& where, const std::string& what) {
  const py::array a = py::array::ensure(h);
  if (!a || !accepts(a.dtype(), kReals | kBools)) wrongType(where, what, h);
  return a;
}

/// C++ <-> Python for one member type, the Python -> C++ side checked.
template <typename M, typename Enable = void>
struct Conv {
  static py::object get(const M& v) { return py::cast(v); }
  static M set(py::handle h, const std::string& where) {
    if constexpr (std::is_enum_v<M>) {
      // A bound enum: its member, or its member's name (as config files write it).
      if (py::isinstance<py::str>(h)) {
        // By typeid: py::type::of<M>() does not compile for enums (pybind11 3 casts them with its own caster).
        const py::dict members = py::handle(py::detail::get_type_handle(typeid(M), true)).attr("__members__");
        if (!members.contains(h))
          throw py::value_error(where + ": unknown value " + shown(h) + "; expected one of " +
                                std::string(py::str(py::list(members.attr("keys")()))));
        return members[h].cast<M>();
      }
    }
    try {
      return h.cast<M>();
    } catch (const py::cast_error&) {
      wrongType(where, expected<M>(), h);
    }
  }
};

template <>
struct Conv<bool> {
  static py::object get(bool v) { return py::bool_(v); }
  static bool set(py::handle h, const std::string& where) {
    if (!isBool(h)) wrongType(where, "True or False", h);
    return PyObject_IsTrue(h.ptr()) == 1;
  }
};

template <typename M>
struct Conv<M, std::enable_if_t<std::is_integral_v<M> && !std::is_same_v<M, bool>>> {
  static py::object get(M v) { return py::int_(v); }
  static M set(py::handle h, const std::string& where) {
    if (!isInteger(h)) wrongType(where, expected<M>(), h);
    const py::int_ i(py::reinterpret_borrow<py::object>(h));
    // Compared as Python ints, so that 2**70 or -1 for an unsigned field cannot wrap.
    if (i < py::int_(std::numeric_limits<M>::lowest()) || i > py::int_(std::numeric_limits<M>::max()))
      throw py::value_error(where + ": " + shown(h) + " is out of range; expected " + expected<M>());
    if constexpr (std::is_signed_v<M>)
      return static_cast<M>(PyLong_AsLongLong(i.ptr()));
    else
      return static_cast<M>(PyLong_AsUnsignedLongLong(i.ptr()));
  }
};

template <typename M>
struct Conv<M, std::enable_if_t<std::is_floating_point_v<M>>> {
  static py::object get(M v) { return py::float_(static_cast<double>(v)); }
  static M set(py::handle h, const std::string& where) {
    if (!isReal(h)) wrongType(where, "a real number", h);
    const double v = PyFloat_AsDouble(h.ptr());
    if (v == -1.0 && PyErr_Occurred()) {  // an int beyond a double's range
      PyErr_Clear();
      throw py::value_error(where + ": " + shown(h) + " is out of range of a double");
    }
    return static_cast<M>(v);
  }
};

template <>
struct Conv<std::string> {
  static py::object get(const std::string& v) { return py::str(v); }
  static std::string set(py::handle h, const std::string& where) {
    if (!py::isinstance<py::str>(h)) wrongType(where, "a string", h);
    return h.cast<std::string>();
  }
};

template <typename M>
struct Conv<M, std::enable_if_t<IsFixedEigen<M>::value>> {
  static py::object get(const M& v) { return py::cast(M(v)); }
  static M set(py::handle h, const std::string& where) {
    const py::array a = realArray(h, where, expected<M>());
    using E = IsFixedEigen<M>;
    const bool vector_shape = E::cols == 1 && a.ndim() == 1 && a.shape(0) == E::rows;
    const bool matrix_shape = a.ndim() == 2 && a.shape(0) == E::rows && a.shape(1) == E::cols;
    if (!vector_shape && !matrix_shape)
      throw py::value_error(where + ": expected " + expected<M>() + ", got shape " +
                            std::string(py::str(a.attr("shape"))));
    return a.attr("astype")("float64").cast<M>();
  }
};

template <>
struct Conv<Eigen::Isometry3d> {
  static py::object get(const Eigen::Isometry3d& v) { return py::cast(Eigen::Matrix4d(v.matrix())); }
  static Eigen::Isometry3d set(py::handle h, const std::string& where) {
    Eigen::Isometry3d T;
    T.matrix() = Conv<Eigen::Matrix4d>::set(h, where);
    return T;
  }
};

template <typename V>
struct Conv<std::optional<V>> {
  static py::object get(const std::optional<V>& v) { return v ? Conv<V>::get(*v) : py::object(py::none()); }
  static std::optional<V> set(py::handle h, const std::string& where) {
    if (h.is_none()) return std::nullopt;
    return Conv<V>::set(h, where);
  }
};

/// A vector of numbers or of fixed-size matrices: an (N,), (N, rows) or (N, rows, cols) array.
template <typename M>
struct Conv<M, std::enable_if_t<isArrayVector<M>()>> {
  using V = typename M::value_type;
  static constexpr int rows() {
    if constexpr (IsFixedEigen<V>::value) return IsFixedEigen<V>::rows;
    return 1;
  }
  static constexpr int cols() {
    if constexpr (IsFixedEigen<V>::value) return IsFixedEigen<V>::cols;
    return 1;
  }
  using S = std::conditional_t<std::is_arithmetic_v<V>, V, double>;

  static std::vector<py::ssize_t> shape(std::size_t n) {
    std::vector<py::ssize_t> s{static_cast<py::ssize_t>(n)};
    if (rows() > 1 || cols() > 1) s.push_back(rows());
    if (cols() > 1) s.push_back(cols());
    return s;
  }
  static py::object get(const M& v) {
    py::array_t<S> a(shape(v.size()));
    S* out = a.mutable_data();
    for (const V& x : v) {
      if constexpr (IsFixedEigen<V>::value) {
        for (int r = 0; r < rows(); ++r)
          for (int c = 0; c < cols(); ++c) *out++ = x(r, c);  // row-major whatever Eigen's order
      } else {
        *out++ = x;
      }
    }
    return std::move(a);
  }
  static M set(py::handle h, const std::string& where) {
    const py::array given = realArray(h, where, "an array of real numbers");
    if constexpr (std::is_integral_v<S>) {
      if (given.size() > 0 && given.dtype().kind() == 'f') wrongType(where, "an integer array", h);
    }
    const auto a = py::array_t<S, py::array::c_style | py::array::forcecast>::ensure(given);
    const auto want = shape(static_cast<std::size_t>(a.ndim() ? a.shape(0) : 0));
    bool ok = a.ndim() == static_cast<py::ssize_t>(want.size());
    for (std::size_t k = 1; ok && k < want.size(); ++k) ok = a.shape(static_cast<py::ssize_t>(k)) == want[k];
    if (!ok) throw py::value_error(where + ": an array of the wrong shape " + std::string(py::str(given.attr("shape"))));
    if constexpr (std::is_integral_v<S> && std::is_unsigned_v<S>) {
      if (given.size() > 0 && given.dtype().kind() == 'i' && py::module_::import("numpy").attr("any")(
                                                                   py::reinterpret_borrow<py::object>(given) < py::int_(0))
                                                                   .cast<bool>())
        throw py::value_error(where + ": negative values in an unsigned array");
    }
    M v;
    v.reserve(static_cast<std::size_t>(a.shape(0)));
    const S* in = a.data();
    for (py::ssize_t i = 0; i < a.shape(0); ++i) {
      if constexpr (IsFixedEigen<V>::value) {
        V x;
        for (int r = 0; r < rows(); ++r)
          for (int c = 0; c < cols(); ++c) x(r, c) = *in++;
        v.push_back(x);
      } else {
        v.push_back(*in++);
      }
    }
    return v;
  }
};

/// A nested bound struct: the stored value is a copy, the property the object itself.
template <typename M>
M setNested(py::handle h, const std::string& where) {
  if (!py::isinstance<M>(h)) {
    const std::string name = py::str(py::type::of<M>().attr("__name__"));
    wrongType(where, (std::string("AEIOU").find(name[0]) == std::string::npos ? "a " : "an ") + name, h);
  }
  return h.cast<M>();
}

template <typename T, typename = void>
struct HasValidate : std::false_type {};
template <typename T>
struct HasValidate<T, std::void_t<decltype(std::declval<const T&>().validate())>> : std::true_type {};

}  // namespace fields

/// One entry of a struct's field table.
template <typename T>
struct FieldEntry {
  std::string name, unit, doc;
  bool writable = true;  ///< Python may assign it
  std::function<py::object(const T&)> get;
  std::function<void(T&, py::handle, const std::string&)> set;  ///< null: derived, not part of the state
};

/// The field table of a bound struct T (see the top of this file). Build it with field(),
/// output(), name() and derived(), then call settings() or result() once.
template <typename T, typename... Extra>
class Fields {
 public:
  using Class = py::class_<T, Extra...>;

  explicit Fields(Class cls) : cls_(std::move(cls)), cls_name_(py::str(cls_.attr("__name__"))) {
    if constexpr (std::is_default_constructible_v<T>) defaults_.emplace();
  }

  /// A read-write member.
  template <typename M>
  Fields& field(const char* name, M T::*member, const char* unit, const char* doc) {
    return addMember(name, member, unit, doc, true);
  }

  /// A read-only member (a result's figure); part of the state.
  template <typename M>
  Fields& output(const char* name, M T::*member, const char* unit, const char* doc) {
    return addMember(name, member, unit, doc, false);
  }

  /// A value reached through accessors, part of the state: get(const T&) -> V and
  /// set(T&, V) (or set(T&, py::handle) to parse the Python value itself).
  template <typename Get, typename Set>
  Fields& field(const char* name, Get get, Set set, const char* unit, const char* doc, bool writable = true) {
    using V = std::decay_t<std::invoke_result_t<Get, const T&>>;
    FieldEntry<T> e{name, unit, doc, writable, {}, {}};
    e.get = [get](const T& t) { return fields::Conv<V>::get(get(t)); };
    if constexpr (std::is_invocable_v<Set, T&, py::handle>) {
      e.set = [set](T& t, py::handle h, const std::string&) { set(t, h); };
    } else {
      e.set = [set](T& t, py::handle h, const std::string& where) { set(t, fields::Conv<V>::set(h, where)); };
    }
    return add(std::move(e));
  }

  /// An enum member shown to Python by its name (toString, found by ADL; enumerators
  /// 0..count-1): 'point_to_plane', as config files write it.
  template <typename E>
  Fields& name(const char* name, E T::*member, int count, const char* unit, const char* doc, bool writable = true) {
    FieldEntry<T> e{name, unit, doc, writable, {}, {}};
    e.get = [member](const T& t) { return py::object(py::str(toString(t.*member))); };
    e.set = [member, count](T& t, py::handle h, const std::string& where) {
      std::string names;
      for (int i = 0; i < count; ++i) names += std::string(i ? ", '" : "'") + toString(static_cast<E>(i)) + "'";
      if (!py::isinstance<py::str>(h)) fields::wrongType(where, "one of " + names, h);
      const std::string s = h.cast<std::string>();
      for (int i = 0; i < count; ++i)
        if (s == toString(static_cast<E>(i))) {
          t.*member = static_cast<E>(i);
          return;
        }
      throw py::value_error(where + ": unknown value '" + s + "'; expected one of " + names);
    };
    return add(std::move(e));
  }

  /// A read-only value computed from the others (an alias, a view): not part of the state.
  template <typename Get>
  Fields& derived(const char* name, Get get, const char* unit, const char* doc) {
    using V = std::decay_t<std::invoke_result_t<Get, const T&>>;
    FieldEntry<T> e{name, unit, doc, false, {}, {}};
    e.get = [get](const T& t) { return fields::Conv<V>::get(get(t)); };
    return add(std::move(e));
  }

  /// Finishes a settings struct: T(**fields) and T(other), then as result().
  Class settings() {
    if constexpr (std::is_default_constructible_v<T> && std::is_copy_constructible_v<T>) {
      const auto entries = entries_;
      const std::string cls = cls_name_;
      cls_.def(py::init([entries, cls](const py::kwargs& given) {
                 T t{};
                 assign(t, given, entries, cls, "keyword argument");
                 return t;
               }),
               ("A " + cls + " with its defaults, and the fields given by keyword").c_str());
      cls_.def(py::init([](const T& other) { return other; }), py::arg("other"), "A copy of other");
      cls_.def("__copy__", [](const T& t) { return t; });
      cls_.def("__deepcopy__", [](const T& t, const py::dict&) { return t; }, py::arg("memo"));
    }
    return result();
  }

  /// Finishes the class: __fields__, pickling, ==, and a repr unless it has one.
  Class result() {
    py::list schema;
    for (const auto& e : entries_)
      if (e.set) schema.append(py::make_tuple(e.name, e.unit, e.doc, e.writable));
    cls_.attr("__fields__") = py::tuple(schema);
    const auto entries = entries_;
    const std::string cls = cls_name_;
    if constexpr (std::is_default_constructible_v<T>) {
      cls_.def(py::pickle([entries](const T& t) { return state(t, entries); },
                          [entries, cls](const py::dict& d) {
                            T t{};
                            for (const auto& e : entries)
                              if (e.set && !d.contains(e.name))
                                throw py::value_error(cls + ": pickled state lacks '" + e.name + "'");
                            assign(t, d, entries, cls, "pickled state");
                            if constexpr (fields::HasValidate<T>::value) t.validate();
                            return t;
                          }));
    }
    cls_.def(
        "__eq__",
        [entries](const T& a, const py::object& b) -> py::object {
          if (!py::isinstance<T>(b)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
          return py::bool_(equal(a, b.cast<const T&>(), entries));
        },
        py::is_operator());
    cls_.attr("__hash__") = py::none();
    if (!py::hasattr(cls_, "__dict__") || !py::dict(cls_.attr("__dict__")).contains("__repr__")) {
      cls_.def("__repr__", [entries, cls](const T& t) {
        std::string out = cls + "(";
        bool first = true;
        for (const auto& e : entries) {
          if (!e.set) continue;
          out += (first ? "" : ", ") + e.name + "=" + std::string(py::repr(e.get(t)));
          first = false;
        }
        return out + ")";
      });
    }
    return cls_;
  }

 private:
  template <typename M>
  Fields& addMember(const char* name, M T::*member, const char* unit, const char* doc, bool writable) {
    FieldEntry<T> e{name, unit, doc, writable, {}, {}};
    if constexpr (fields::isNested<M>()) {
      e.get = [member](const T& t) { return py::cast(t.*member); };
      e.set = [member](T& t, py::handle h, const std::string& where) { t.*member = fields::setNested<M>(h, where); };
      // The property returns the nested struct itself, so that in-place changes stick.
      const std::string where = cls_name_ + "." + name;
      auto getter = py::cpp_function([member](T& t) -> M& { return t.*member; }, py::is_method(cls_),
                                     py::return_value_policy::reference_internal);
      if (writable) {
        auto setter = py::cpp_function(
            [member, where](T& t, py::handle h) { t.*member = fields::setNested<M>(h, where); }, py::is_method(cls_));
        cls_.def_property(name, getter, setter, docOf(e, e.get).c_str());
      } else {
        cls_.def_property_readonly(name, getter, docOf(e, e.get).c_str());
      }
      entries_.push_back(std::move(e));
      return *this;
    } else {
      e.get = [member](const T& t) { return fields::Conv<M>::get(t.*member); };
      e.set = [member](T& t, py::handle h, const std::string& where) { t.*member = fields::Conv<M>::set(h, where); };
      return add(std::move(e));
    }
  }

  Fields& add(FieldEntry<T> e) {
    const std::string where = cls_name_ + "." + e.name;
    const auto get = e.get;
    const auto set = e.set;
    const std::string doc = docOf(e, get);
    if (e.writable && set)
      cls_.def_property(
          e.name.c_str(), [get](const T& t) { return get(t); },
          [set, where](T& t, py::handle h) { set(t, h, where); }, doc.c_str());
    else
      cls_.def_property_readonly(e.name.c_str(), [get](const T& t) { return get(t); }, doc.c_str());
    entries_.push_back(std::move(e));
    return *this;
  }

  /// "[unit] doc (default: value)"; the default shown for writable fields of settings.
  std::string docOf(const FieldEntry<T>& e, const std::function<py::object(const T&)>& get) const {
    std::string d = e.unit.empty() ? e.doc : "[" + e.unit + "] " + e.doc;
    if (e.writable && e.set && defaults_) {
      const py::object v = get(*defaults_);
      if (!py::hasattr(v, "__fields__")) d += " (default: " + std::string(py::repr(v)) + ")";
    }
    return d;
  }

  static py::dict state(const T& t, const std::vector<FieldEntry<T>>& entries) {
    py::dict d;
    for (const auto& e : entries)
      if (e.set) d[py::str(e.name)] = e.get(t);
    return d;
  }

  /// Sets the fields named in `given`; TypeError (keywords) or ValueError (a state) for an
  /// unknown name, the setter's error for a bad value.
  static void assign(T& t, const py::dict& given, const std::vector<FieldEntry<T>>& entries, const std::string& cls,
                     const char* what) {
    for (const auto& item : given) {
      const std::string key = py::str(item.first);
      const FieldEntry<T>* e = nullptr;
      for (const auto& x : entries)
        if (x.name == key && x.set) e = &x;
      if (!e) {
        std::string known;
        for (const auto& x : entries)
          if (x.set) known += (known.empty() ? "" : ", ") + x.name;
        if (std::string(what) == "pickled state")
          throw py::value_error(cls + ": pickled state has an unknown key '" + key + "'");
        throw py::type_error(cls + ": unknown " + what + " '" + key + "'; fields: " + known);
      }
      e->set(t, item.second, cls + "." + key);
    }
  }

  static bool equal(const T& a, const T& b, const std::vector<FieldEntry<T>>& entries) {
    static const py::handle array_equal = py::object(py::module_::import("numpy").attr("array_equal")).release();
    for (const auto& e : entries) {
      if (!e.set) continue;
      const py::object x = e.get(a), y = e.get(b);
      const bool arrays = py::isinstance<py::array>(x) || py::isinstance<py::array>(y);
      const py::object same = arrays ? array_equal(x, y) : py::object(py::bool_(x.equal(y)));
      if (PyObject_IsTrue(same.ptr()) != 1) return false;
    }
    return true;
  }

  Class cls_;
  std::string cls_name_;
  std::optional<T> defaults_;
  std::vector<FieldEntry<T>> entries_;
};

/// Fields(cls) without spelling the class's template arguments.
template <typename T, typename... Extra>
Fields<T, Extra...> fieldsOf(const py::class_<T, Extra...>& cls) {
  return Fields<T, Extra...>(cls);
}

/// The field table of the class bound as `name` in `m` (after its other .def calls).
template <typename T>
Fields<T> fieldsOf(py::module_& m, const char* name) {
  return Fields<T>(py::reinterpret_borrow<py::class_<T>>(m.attr(name)));
}

}  // namespace scanalign::python
