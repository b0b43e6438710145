// Bindings of scanalign/kinematics/ik.hpp: the CGA inverse kinematics on Robot (ik, ik_closest,
// ik_batch, ik_trajectory, ik_construction) and its results, each through its field table
// (fields.hpp). Results are values with read-only arrays.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "fields.hpp"
#include "kinematics.hpp"
#include "scanalign/kinematics/ik.hpp"

namespace scanalign::python::kin {

namespace {

constexpr const char* kSingularNames[] = {"shoulder", "elbow", "wrist"};
constexpr int kStatusCount = 4;  // ok, outside_limits, unreachable, invalid_input
constexpr int kStepCount = 4;    // none, shoulder, elbow, fk_check

/// Inverse kinematics of N poses as arrays (Robot.ik_batch), filled once from the C++ results.
struct IKBatchResult {
  py::array_t<double> q;
  py::array_t<std::uint8_t> status, singular, unreachable_step;
  py::ssize_t size() const { return q.ndim() == 3 ? q.shape(0) : 0; }
};

/// Joint values along a pose sequence (Robot.ik_trajectory).
struct JointTrajectoryResult {
  py::array_t<double> q;
  std::vector<IKStatus> status;
};

// ----------------------------------------------------------------------------- arguments

std::int8_t label(int v, const char* name) {
  if (v != 1 && v != -1) throw py::value_error(std::string(name) + ": expected +1 or -1, got " + std::to_string(v));
  return static_cast<std::int8_t>(v);
}

IKConfig config(int shoulder, int elbow, int wrist) {
  return {label(shoulder, "shoulder"), label(elbow, "elbow"), label(wrist, "wrist")};
}

int configIndexChecked(int shoulder, int elbow, int wrist) { return configIndex(config(shoulder, elbow, wrist)); }

IKSettings options(const Robot& r, const Vector6d& q_free, double reach_tolerance, double singular_tolerance,
                   bool respect_limits) {
  requireIk(r);
  IKSettings o;
  o.q_free = q_free;
  o.reach_tolerance = tolerance(reach_tolerance, "reach_tolerance");
  o.singular_tolerance = tolerance(singular_tolerance, "singular_tolerance");
  o.respect_limits = respect_limits;
  return o;
}

// ----------------------------------------------------------------------------- values as Python shows them

py::tuple singularNames(std::uint8_t bits) {
  py::list out;
  for (int i = 0; i < 3; ++i)
    if (bits >> i & 1) out.append(kSingularNames[i]);
  return py::tuple(out);
}

/// The bits of a sequence of singularity names; ValueError naming `where` otherwise.
std::uint8_t singularBits(py::handle names, const std::string& where) {
  if (!py::isinstance<py::sequence>(names) || py::isinstance<py::str>(names))
    throw py::type_error(where + ": expected a tuple of singularity names");
  std::uint8_t bits = 0;
  for (const py::handle n : names) {
    const auto* it = py::isinstance<py::str>(n) ? std::find(std::begin(kSingularNames), std::end(kSingularNames),
                                                            n.cast<std::string>())
                                                : std::end(kSingularNames);
    if (it == std::end(kSingularNames))
      throw py::value_error(where + ": unknown singularity " + std::string(py::repr(n)) +
                            "; expected 'shoulder', 'elbow' or 'wrist'");
    bits |= static_cast<std::uint8_t>(1u << (it - std::begin(kSingularNames)));
  }
  return bits;
}

/// A status by name; ValueError naming `where` otherwise.
IKStatus statusNamed(py::handle name, const std::string& where) {
  for (int s = 0; s < kStatusCount; ++s)
    if (py::isinstance<py::str>(name) && name.cast<std::string>() == toString(static_cast<IKStatus>(s)))
      return static_cast<IKStatus>(s);
  throw py::value_error(where + ": unknown status " + std::string(py::repr(name)));
}

/// (n, 3) int8 labels (shoulder, elbow, wrist) of configuration(k), k < n; read-only.
template <typename F>
py::array_t<std::int8_t> configRows(py::ssize_t n, F&& configuration) {
  py::array_t<std::int8_t> a({n, py::ssize_t{3}});
  std::int8_t* out = a.mutable_data();
  for (py::ssize_t k = 0; k < n; ++k) {
    const IKConfig c = configuration(k);
    out[3 * k] = c.shoulder, out[3 * k + 1] = c.elbow, out[3 * k + 2] = c.wrist;
  }
  return readonly(a);
}

py::array_t<std::int8_t> configArray(const IKConfig& c) {
  const std::int8_t v[3] = {c.shoulder, c.elbow, c.wrist};
  return readonly(py::array_t<std::int8_t>(3, v));
}

/// Three labels, each +1 or -1.
IKConfig configFrom(py::handle h, const std::string& where) {
  std::vector<long long> v;
  try {
    v = py::module_::import("numpy").attr("asarray")(h).attr("tolist")().cast<std::vector<long long>>();
  } catch (const py::error_already_set&) {
    throw py::type_error(where + ": expected 3 integer labels");
  } catch (const py::cast_error&) {
    throw py::type_error(where + ": expected 3 integer labels");
  }
  if (v.size() != 3 || std::any_of(v.begin(), v.end(), [](long long x) { return x != 1 && x != -1; }))
    throw py::value_error(where + ": expected 3 labels, each +1 or -1");
  return {static_cast<std::int8_t>(v[0]), static_cast<std::int8_t>(v[1]), static_cast<std::int8_t>(v[2])};
}

template <typename F>
py::tuple perSolution(const IKResult& r, F&& f) {
  py::tuple t(8);
  for (std::size_t k = 0; k < 8; ++k) t[k] = f(r.solutions[k]);
  return t;
}

/// (K, 6) rows of q.
py::array_t<double> rowsOf(const std::vector<Vector6d>& q) {
  py::array_t<double> a({static_cast<py::ssize_t>(q.size()), py::ssize_t{6}});
  for (std::size_t i = 0; i < q.size(); ++i) std::copy(q[i].data(), q[i].data() + 6, a.mutable_data() + 6 * i);
  return a;
}

/// An (N, ...) array of A's dtype from a pickled state, with the shape the accessors index
/// (they do not check bounds); n < 0: any N. A read-only copy.
template <typename A>
A shapedArray(py::handle h, std::vector<py::ssize_t> tail, py::ssize_t n, const std::string& what) {
  if (!py::isinstance<A>(h)) throw py::type_error(what + ": pickled array of the wrong dtype");
  const py::array a = py::reinterpret_borrow<py::array>(h);
  bool ok = a.ndim() == static_cast<py::ssize_t>(tail.size()) + 1 && (n < 0 || a.shape(0) == n);
  for (std::size_t i = 0; ok && i < tail.size(); ++i) ok = a.shape(static_cast<py::ssize_t>(i) + 1) == tail[i];
  if (!ok) throw py::value_error(what + ": pickled array of the wrong shape " + shapeText(a));
  return readonly(A::ensure(a.attr("copy")()));
}

IKBatchResult batchArrays(const std::vector<IKResult>& res) {
  const auto n = static_cast<py::ssize_t>(res.size());
  IKBatchResult b{py::array_t<double>({n, py::ssize_t{8}, py::ssize_t{6}}),
                  py::array_t<std::uint8_t>({n, py::ssize_t{8}}), py::array_t<std::uint8_t>({n, py::ssize_t{8}}),
                  py::array_t<std::uint8_t>({n, py::ssize_t{8}})};
  for (std::size_t i = 0; i < res.size(); ++i)
    for (std::size_t k = 0; k < 8; ++k) {
      const IKSolution& s = res[i].solutions[k];
      std::copy(s.q.data(), s.q.data() + 6, b.q.mutable_data() + 48 * i + 6 * k);
      b.status.mutable_data()[8 * i + k] = static_cast<std::uint8_t>(s.status);
      b.singular.mutable_data()[8 * i + k] = s.singular;
      b.unreachable_step.mutable_data()[8 * i + k] = static_cast<std::uint8_t>(s.unreachable_step);
    }
  readonly(b.q), readonly(b.status), readonly(b.singular), readonly(b.unreachable_step);
  return b;
}

IKResult batchEntry(const IKBatchResult& b, py::ssize_t i) {
  if (i < 0) i += b.size();
  if (i < 0 || i >= b.size()) throw py::index_error("i: pose index out of range");
  IKResult r;
  for (std::size_t k = 0; k < 8; ++k) {
    IKSolution& s = r.solutions[k];
    s.q = Eigen::Map<const Vector6d>(b.q.data() + 48 * i + 6 * k);
    s.config = configFromIndex(static_cast<int>(k));
    s.status = static_cast<IKStatus>(b.status.data()[8 * i + k]);
    s.singular = b.singular.data()[8 * i + k];
    s.unreachable_step = static_cast<IKStep>(b.unreachable_step.data()[8 * i + k]);
    if (s.status < r.status) r.status = s.status;
  }
  return r;
}

std::string solutionRepr(const IKSolution& s) {
  std::string q;
  for (int j = 0; j < 6; ++j) q += (j ? ", " : "") + std::string(py::str(py::float_(s.q[j])));
  return std::string("IKSolution(status='") + toString(s.status) + "', config=(" + std::to_string(s.config.shoulder) +
         ", " + std::to_string(s.config.elbow) + ", " + std::to_string(s.config.wrist) + "), q=[" + q + "])";
}

constexpr const char* kStatusDoc = "'ok', or why no solution exists: 'outside_limits', 'unreachable', 'invalid_input'";
constexpr const char* kStepDoc =
    "'', or the construction step whose point pair is imaginary: 'shoulder' (UR horizon: the wrist point within d4 of "
    "the first axis), 'elbow' (the wrist too far from or too close to the shoulder) or 'fk_check' (the angles' "
    "forward kinematics missed the target by more than 1e-6 m / 1e-6: never reported 'ok')";
constexpr const char* kSingularDoc =
    "the singularities that applied ('shoulder', 'elbow', 'wrist'); empty when regular";

// ----------------------------------------------------------------------------- results

void bindSolution(py::module_& m) {
  using S = IKSolution;
  fieldsOf(py::class_<S>(m, "IKSolution", "One inverse-kinematics solution (Robot.ik_closest)")
               .def("__repr__", &solutionRepr))
      .field("q", frozen(&S::q), thawed(&S::q), "rad",
             "(6,) joint values (NaN unless a solution with status 'ok' exists)", false)
      .field(
          "config", [](const S& s) { return configArray(s.config); },
          [](S& s, py::handle h) { s.config = configFrom(h, "IKSolution.config"); }, "",
          "(3,) int8 labels (shoulder, elbow, wrist), each +1 or -1", false)
      .name("status", &S::status, kStatusCount, "", kStatusDoc, false)
      .field(
          "singular", [](const S& s) { return singularNames(s.singular); },
          [](S& s, py::handle h) { s.singular = singularBits(h, "IKSolution.singular"); }, "",
          "tuple of the singularities that applied ('shoulder', 'elbow', 'wrist'); empty when regular", false)
      .name("unreachable_step", &S::unreachable_step, kStepCount, "", kStepDoc, false)
      .derived("ok", [](const S& s) { return s.ok(); }, "", "status == 'ok'")
      .result();
}

void bindResult(py::module_& m) {
  using R = IKResult;
  fieldsOf(py::class_<R>(m, "IKResult",
                         "All inverse-kinematics solutions of one pose (Robot.ik). Row k holds the configuration "
                         "CONFIGS[k], k = 4*(shoulder<0) + 2*(elbow<0) + (wrist<0), whatever the pose. len() is the "
                         "number of 'ok' rows, so a result without one is falsy.")
               .def("__repr__", [](const R& r) {
                 std::string s = "IKResult(" + std::to_string(r.count()) + " ok;";
                 for (std::size_t k = 0; k < 8; ++k) {
                   const IKConfig& c = r.solutions[k].config;
                   s += std::string(k ? "," : "") + " (" + std::to_string(c.shoulder) + ", " +
                        std::to_string(c.elbow) + ", " + std::to_string(c.wrist) + "): " +
                        toString(r.solutions[k].status);
                 }
                 return s + ")";
               }))
      .field(
          "solutions", [](const R& r) { return r.solutions; },
          [](R& r, py::handle h) {
            std::array<IKSolution, 8> s;
            try {
              s = h.cast<std::array<IKSolution, 8>>();
            } catch (const py::cast_error&) {
              throw py::type_error("IKResult.solutions: expected 8 IKSolution");
            }
            for (std::size_t k = 0; k < 8; ++k)
              if (configIndex(s[k].config) != static_cast<int>(k))
                throw py::value_error("IKResult.solutions: row " + std::to_string(k) +
                                      " is not in configuration CONFIGS[" + std::to_string(k) + "]");
            r.solutions = s;
          },
          "", "the 8 IKSolution, row k in configuration CONFIGS[k]", false)
      .name("overall_status", &R::status, kStatusCount, "",
            "'ok' when some row is 'ok', else 'outside_limits' when some row is, else 'unreachable' ('invalid_input' "
            "for a non-finite or non-rigid pose)",
            false)
      .derived(
          "q",
          [](const R& r) {
            py::array_t<double> q({py::ssize_t{8}, py::ssize_t{6}});
            for (std::size_t k = 0; k < 8; ++k)
              std::copy(r.solutions[k].q.data(), r.solutions[k].q.data() + 6, q.mutable_data() + 6 * k);
            return readonly(q);
          },
          "rad",
          "(8, 6) joint values: each joint the 2*pi multiple inside its limits nearest 0 (respect_limits) or wrapped "
          "to (-pi, pi]; NaN rows where the configuration is unreachable")
      .derived(
          "status", [](const R& r) { return perSolution(r, [](const IKSolution& s) { return toString(s.status); }); },
          "", "tuple of 8 statuses: 'ok', 'outside_limits', 'unreachable', 'invalid_input'")
      .derived(
          "ok",
          [](const R& r) {
            py::array_t<bool> a(8);
            for (std::size_t k = 0; k < 8; ++k) a.mutable_data()[k] = r.solutions[k].ok();
            return a;
          },
          "", "(8,) bool: rows with status 'ok'")
      .derived(
          "config",
          [](const R& r) {
            return configRows(8, [&](py::ssize_t k) { return r.solutions[static_cast<std::size_t>(k)].config; });
          },
          "", "(8, 3) int8 labels (shoulder, elbow, wrist) of each row, each +1 or -1 (= CONFIGS)")
      .derived(
          "singular",
          [](const R& r) { return perSolution(r, [](const IKSolution& s) { return singularNames(s.singular); }); },
          "", "tuple of 8 tuples of the singularities that applied ('shoulder', 'elbow', 'wrist'); empty when regular")
      .derived(
          "unreachable_step",
          [](const R& r) {
            return perSolution(r, [](const IKSolution& s) { return toString(s.unreachable_step); });
          },
          "", "tuple of 8: see IKSolution.unreachable_step")
      .result()
      .def("__len__", [](const R& r) { return r.count(); })
      .def(
          "valid_q",
          [](const R& r) {
            std::vector<Vector6d> q;
            for (const IKSolution& s : r.solutions)
              if (s.ok()) q.push_back(s.q);
            return rowsOf(q);
          },
          "(K, 6) joint values of the 'ok' rows, in index order, rad")
      .def(
          "distinct", [](const R& r, double tol) { return rowsOf(distinctSolutions(r, tolerance(tol, "tol"))); },
          py::arg("tol") = 1e-9,
          "(M, 6) 'ok' rows without duplicates: two rows are equal when every joint differs by a multiple of 2*pi "
          "within tol rad (e.g. both elbow labels at the elbow singularity); the first of each group is kept")
      .def_static("index", &configIndexChecked, py::arg("shoulder"), py::arg("elbow"), py::arg("wrist"),
                  "Row of the configuration (shoulder, elbow, wrist), each +1 or -1: see config_index");
}

void bindBatch(py::module_& m) {
  using B = IKBatchResult;
  // The arrays are held as built (read-only); their shapes are checked on load because the
  // accessors index them without bounds checks.
  fieldsOf(py::class_<B>(m, "IKBatchResult", "Inverse kinematics of N poses (Robot.ik_batch), as read-only arrays"))
      .field(
          "q", [](const B& b) { return b.q; },
          [](B& b, py::handle h) { b.q = shapedArray<py::array_t<double>>(h, {8, 6}, -1, "IKBatchResult.q"); }, "rad",
          "(N, 8, 6) joint values; q[i, k] has configuration CONFIGS[k]; NaN where not reached", false)
      .field(
          "status", [](const B& b) { return b.status; },
          [](B& b, py::handle h) {
            b.status = shapedArray<py::array_t<std::uint8_t>>(h, {8}, b.size(), "IKBatchResult.status");
          },
          "",
          "(N, 8) uint8 status codes, indices into STATUS_NAMES (0 ok, 1 outside_limits, 2 unreachable, 3 "
          "invalid_input: a non-finite or non-rigid pose)",
          false)
      .field(
          "singular", [](const B& b) { return b.singular; },
          [](B& b, py::handle h) {
            b.singular = shapedArray<py::array_t<std::uint8_t>>(h, {8}, b.size(), "IKBatchResult.singular");
          },
          "", "(N, 8) uint8 singularity bits (1 shoulder, 2 elbow, 4 wrist)", false)
      .field(
          "unreachable_step", [](const B& b) { return b.unreachable_step; },
          [](B& b, py::handle h) {
            b.unreachable_step =
                shapedArray<py::array_t<std::uint8_t>>(h, {8}, b.size(), "IKBatchResult.unreachable_step");
          },
          "",
          "(N, 8) uint8 failed construction step (0 none, 1 shoulder, 2 elbow, 3 fk_check: the forward kinematics "
          "of the angles missed the target)",
          false)
      .derived(
          "ok", [](const B& b) { return py::array(b.status.attr("__eq__")(0)); }, "", "(N, 8) bool: status 'ok'")
      .derived(
          "count_ok",
          [](const B& b) {
            py::array_t<std::int64_t> c(b.size());
            for (py::ssize_t i = 0; i < b.size(); ++i) {
              c.mutable_data()[i] = 0;
              for (int k = 0; k < 8; ++k) c.mutable_data()[i] += b.status.data()[8 * i + k] == 0;
            }
            return c;
          },
          "", "(N,) number of 'ok' solutions per pose")
      .result()
      .def(
          "status_names",
          [](const B& b) {
            py::list names;
            for (int s = 0; s < kStatusCount; ++s) names.append(toString(static_cast<IKStatus>(s)));
            return py::array(py::module_::import("numpy").attr("asarray")(names)[b.status]);
          },
          "(N, 8) array of status names (str)")
      .def("__len__", &B::size)
      .def("solutions", &batchEntry, py::arg("i"), "The solutions of pose i as an IKResult");
}

void bindTrajectory(py::module_& m) {
  using T = JointTrajectoryResult;
  fieldsOf(py::class_<T>(m, "JointTrajectoryResult", "Joint values along a pose sequence (Robot.ik_trajectory)"))
      .field(
          "q", [](const T& t) { return t.q; },
          [](T& t, py::handle h) { t.q = shapedArray<py::array_t<double>>(h, {6}, -1, "JointTrajectoryResult.q"); },
          "rad", "(N, 6) joint values; NaN rows where no 'ok' solution exists", false)
      .field(
          "status",
          [](const T& t) {
            py::tuple out(t.status.size());
            for (std::size_t i = 0; i < t.status.size(); ++i) out[i] = toString(t.status[i]);
            return out;
          },
          [](T& t, py::handle h) {
            const std::string where = "JointTrajectoryResult.status";
            if (!py::isinstance<py::sequence>(h) || py::isinstance<py::str>(h))
              throw py::type_error(where + ": expected a tuple of status names");
            std::vector<IKStatus> s;
            for (const py::handle x : h) s.push_back(statusNamed(x, where));
            if (static_cast<py::ssize_t>(s.size()) != t.q.shape(0))
              throw py::value_error(where + ": expected one status per row of q");
            t.status = std::move(s);
          },
          "", "tuple of N statuses ('ok', 'outside_limits', 'unreachable')", false)
      .derived(
          "ok",
          [](const T& t) {
            py::array_t<bool> a(static_cast<py::ssize_t>(t.status.size()));
            for (std::size_t i = 0; i < t.status.size(); ++i) a.mutable_data()[i] = t.status[i] == IKStatus::Ok;
            return a;
          },
          "", "(N,) bool: steps with status 'ok'")
      .result()
      .def("__len__", [](const T& t) { return t.status.size(); });
}

void bindConstruction(py::module_& m) {
  using K = IKConstruction;
  fieldsOf(py::class_<K>(m, "IKConstruction",
                         "The intermediate CGA construction of one configuration (Robot.ik_construction), in DH frame "
                         "0, metres"))
      .name("geometry", &K::geometry, 3, "", "the layout solved: 'spherical_wrist' or 'universal_robots'", false)
      .output("solution", &K::solution, "", "the IKSolution of this configuration, limits respected")
      .field(
          "points",
          [](const K& k) {
            py::dict d;
            for (int i = 0; i < k.num_points; ++i)
              d[py::str(k.names[static_cast<std::size_t>(i)])] = Eigen::Vector3d(k.points[static_cast<std::size_t>(i)]);
            return d;
          },
          [](K& k, py::handle h) {
            const std::string where = "IKConstruction.points";
            if (!py::isinstance<py::dict>(h)) throw py::type_error(where + ": expected a dict name -> (3,) point");
            const py::dict d = py::reinterpret_borrow<py::dict>(h);
            if (d.size() > k.points.size()) throw py::value_error(where + ": at most 8 points");
            K c = k;
            c.num_points = 0;
            for (const auto& item : d) {
              const auto i = static_cast<std::size_t>(c.num_points++);
              c.names[i] = fields::Conv<std::string>::set(item.first, where);
              c.points[i] = fields::Conv<Eigen::Vector3d>::set(item.second, where + "['" + c.names[i] + "']");
            }
            k = c;
          },
          "m",
          "dict name -> (3,) point (KUKA: p_e, P_w, P1, P2, P_wx; UR: p_e, P5, P_c, P4, P3, P2, P1); NaN when not "
          "reached",
          false)
      .output("shoulder_discriminant", &K::shoulder_discriminant, "",
              "normalised h^2/r^2 of the UR horizon point pair (negative: imaginary, Q^2 < 0; NaN when not computed)")
      .output("elbow_discriminant", &K::elbow_discriminant, "",
              "normalised h^2/r^2 of the elbow point pair (negative: imaginary, Q^2 < 0; NaN when not computed)")
      .derived(
          "config",
          [](const K& k) {
            const IKConfig& c = k.solution.config;
            return py::make_tuple(int(c.shoulder), int(c.elbow), int(c.wrist));
          },
          "", "(shoulder, elbow, wrist)")
      .result();
}

// ----------------------------------------------------------------------------- Robot methods

IKResult ikOne(const Robot& r, const py::object& T, const py::object& q_free, bool respect_limits,
               double reach_tolerance, double singular_tolerance) {
  const IKSettings o = options(r, vector6Or(q_free, "q_free", Vector6d::Zero()), reach_tolerance, singular_tolerance,
                               respect_limits);
  return ik(r, rigid(T, "T_base_tool"), o);
}

IKSolution ikClosestOne(const Robot& r, const py::object& T, const py::object& q_current, const py::object& weights,
                        bool respect_limits, double reach_tolerance, double singular_tolerance) {
  const Vector6d qc = vector6(q_current, "q_current");
  const IKSettings o = options(r, qc, reach_tolerance, singular_tolerance, respect_limits);
  ClosestSettings c;
  c.weights = vector6Or(weights, "weights", Vector6d::Ones(), true);
  return ikClosest(r, rigid(T, "T_base_tool"), qc, o, c);
}

IKBatchResult ikBatchMany(const Robot& r, const py::object& T, const py::object& q_free, bool respect_limits,
                          int num_threads, double reach_tolerance, double singular_tolerance) {
  const IKSettings o = options(r, vector6Or(q_free, "q_free", Vector6d::Zero()), reach_tolerance, singular_tolerance,
                               respect_limits);
  const F64 p = poses(T, "T_base_tool", false);
  threadCount(num_threads);
  std::vector<IKResult> res(static_cast<std::size_t>(p.shape(0)));
  {
    py::gil_scoped_release release;
    ikBatch(r, p.data(), res.size(), res.data(), o, num_threads);
  }
  return batchArrays(res);
}

JointTrajectoryResult ikTrajectoryMany(const Robot& r, const py::object& T, const py::object& q_start,
                                       const py::object& weights, bool respect_limits, double reach_tolerance,
                                       double singular_tolerance) {
  const Vector6d qs = vector6(q_start, "q_start");
  const IKSettings o = options(r, qs, reach_tolerance, singular_tolerance, respect_limits);
  ClosestSettings c;
  c.weights = vector6Or(weights, "weights", Vector6d::Ones(), true);
  const F64 p = poses(T, "T_base_tool", true);
  const py::ssize_t n = p.shape(0);
  JointTrajectoryResult t{py::array_t<double>({n, py::ssize_t{6}}), std::vector<IKStatus>(static_cast<std::size_t>(n))};
  double* q = t.q.mutable_data();
  {
    py::gil_scoped_release release;
    ikTrajectory(r, p.data(), static_cast<std::size_t>(n), qs, q, t.status.data(), o, c);
  }
  readonly(t.q);
  return t;
}

IKConstruction construction(const Robot& r, const py::object& T, int shoulder, int elbow, int wrist,
                            const py::object& q_free) {
  const IKConfig c = config(shoulder, elbow, wrist);
  const IKSettings o = options(r, vector6Or(q_free, "q_free", Vector6d::Zero()), IKSettings{}.reach_tolerance,
                               IKSettings{}.singular_tolerance, true);
  return ikConstruction(r, rigid(T, "T_base_tool"), c, o);
}

constexpr const char* kIkDoc =
    "All (up to 8) inverse-kinematics solutions of a tool pose, as an IKResult.\n\n"
    "T_base_tool: 4x4 rigid transform, tool -> robot base (metres).\n"
    "q_free: (6,) free angles used at singularities, rad (q_free[0] KUKA shoulder, q_free[3] KUKA wrist, q_free[5] "
    "UR wrist); default zeros.\n"
    "respect_limits: report solutions with no 2*pi multiple inside the limits as 'outside_limits' (True), or ignore "
    "the limits and wrap to (-pi, pi].\n"
    "reach_tolerance: a point pair whose normalised discriminant h^2/r^2 is >= -reach_tolerance counts as real "
    "(<= reach_tolerance: tangent).\n"
    "singular_tolerance: sine of the axis angle below which a wrist / KUKA shoulder counts as singular.\n"
    "Raises TypeError / ValueError for bad arguments (shape, dtype, non-finite, non-rigid pose) and ValueError for a "
    "robot whose geometry is 'unsupported'.";

}  // namespace

void bindIkResults(py::module_& m) {
  // The C++ defaults and names, so that the Python layer has one source of truth.
  m.attr("DEFAULT_REACH_TOLERANCE") = IKSettings{}.reach_tolerance;
  m.attr("DEFAULT_SINGULAR_TOLERANCE") = IKSettings{}.singular_tolerance;
  py::list status, steps;
  for (int s = 0; s < kStatusCount; ++s) status.append(toString(static_cast<IKStatus>(s)));
  for (int s = 0; s < kStepCount; ++s) steps.append(toString(static_cast<IKStep>(s)));
  m.attr("STATUS_NAMES") = py::tuple(status);
  m.attr("SINGULAR_NAMES") = py::make_tuple(kSingularNames[0], kSingularNames[1], kSingularNames[2]);
  m.attr("STEP_NAMES") = py::tuple(steps);
  m.attr("CONFIGS") = configRows(8, [](py::ssize_t k) { return configFromIndex(static_cast<int>(k)); });
  m.def("config_index", &configIndexChecked, py::arg("shoulder"), py::arg("elbow"), py::arg("wrist"),
        "The fixed solution index 4*(shoulder<0) + 2*(elbow<0) + (wrist<0) of a configuration (each label +1 or -1)");
  bindSolution(m);
  bindResult(m);
  bindBatch(m);
  bindTrajectory(m);
  bindConstruction(m);
}

void defInverse(RobotClass& c) {
  const IKSettings defaults;
  c.def("ik", &ikOne, py::arg("T_base_tool"), py::arg("q_free") = py::none(), py::arg("respect_limits") = true,
        py::kw_only(), py::arg("reach_tolerance") = defaults.reach_tolerance,
        py::arg("singular_tolerance") = defaults.singular_tolerance, kIkDoc)
      .def("ik_closest", &ikClosestOne, py::arg("T_base_tool"), py::arg("q_current"), py::arg("weights") = py::none(),
           py::arg("respect_limits") = true, py::kw_only(), py::arg("reach_tolerance") = defaults.reach_tolerance,
           py::arg("singular_tolerance") = defaults.singular_tolerance,
           "The IKSolution nearest to q_current ((6,) rad) in sum_i w_i (q_i - q_current_i)^2, over every 'ok' "
           "solution and every 2*pi multiple of each joint inside the limits (a joint with +-2*pi limits stays near "
           "q_current instead of being wrapped). Singular free angles are taken from q_current. weights: (6,) >= 0, "
           "default ones. Without an 'ok' solution its status says why and q is NaN. Other arguments as in ik.")
      .def("ik_batch", &ikBatchMany, py::arg("T_base_tool"), py::arg("q_free") = py::none(),
           py::arg("respect_limits") = true, py::arg("num_threads") = 0, py::kw_only(),
           py::arg("reach_tolerance") = defaults.reach_tolerance,
           py::arg("singular_tolerance") = defaults.singular_tolerance,
           "ik for N poses T_base_tool (N, 4, 4) in one C++ call, parallel over poses (num_threads, 0 = all cores, "
           "1 = serial), as an IKBatchResult. A non-finite or non-rigid pose does not raise: its 8 solutions get "
           "status 'invalid_input'.")
      .def("ik_trajectory", &ikTrajectoryMany, py::arg("T_base_tool"), py::arg("q_start"),
           py::arg("weights") = py::none(), py::arg("respect_limits") = true, py::kw_only(),
           py::arg("reach_tolerance") = defaults.reach_tolerance,
           py::arg("singular_tolerance") = defaults.singular_tolerance,
           "Joint values along rigid poses T_base_tool (N, 4, 4), as a JointTrajectoryResult: each step takes the "
           "solution closest (ik_closest) to the previous step's joints, the first to q_start ((6,) rad). A step "
           "without an 'ok' solution gets a NaN row and its status; the next starts again from the last good joints.")
      .def("ik_construction", &construction, py::arg("T_base_tool"), py::arg("shoulder") = 1, py::arg("elbow") = 1,
           py::arg("wrist") = 1, py::arg("q_free") = py::none(),
           "The intermediate CGA construction (IKConstruction) of one configuration, each label +1 or -1: for "
           "inspection, plots and tests against an independent CGA implementation");
}

}  // namespace scanalign::python::kin
