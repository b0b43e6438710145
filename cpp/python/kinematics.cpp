// Bindings of scanalign/kinematics: the Robot (DH table, joint limits, base and tool
// transforms), forward kinematics and the CGA inverse kinematics, with the C++ result structs
// bound directly. Every argument is checked here, once, and a bad one raises TypeError /
// ValueError naming it; python/scanalign/kinematics.py re-exports these classes.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "pickle.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/kinematics/ik.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {
using namespace scanalign;
using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using RowMatrix4d = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;

constexpr const char* kStepNames[] = {"", "shoulder", "elbow", "fk_check"};
constexpr const char* kSingularNames[] = {"shoulder", "elbow", "wrist"};

// ----------------------------------------------------------------------------- arguments

/// Results are values: their arrays are read-only, so a caller cannot corrupt a shared one.
template <typename A>
A readonly(A a) {
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

std::string shapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// `x` as a C-contiguous float64 array; TypeError naming `name` unless it holds real numbers
/// (bool, complex, strings and objects are refused rather than cast).
F64 realArray(py::handle x, const std::string& name) {
  if (py::isinstance<F64>(x)) return py::reinterpret_borrow<F64>(x);  // the hot path: no copy
  const py::array a = py::array::ensure(x);
  const char kind = a ? a.dtype().kind() : 'O';
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(name + ": expected real numbers (a float or integer array), got " +
                         (a ? "dtype " + std::string(py::str(a.dtype())) : std::string(py::str(py::type::of(x)))));
  return F64::ensure(a);
}

Vector6d vector6(py::handle x, const std::string& name, bool nonnegative = false) {
  const F64 a = realArray(x, name);
  if (a.ndim() != 1 || a.shape(0) != 6) throw py::value_error(name + ": expected shape (6,), got " + shapeText(a));
  const Vector6d v = Eigen::Map<const Vector6d>(a.data());
  if (!v.allFinite()) throw py::value_error(name + ": non-finite values");
  if (nonnegative && (v.array() < 0).any()) throw py::value_error(name + ": values must be >= 0");
  return v;
}

Vector6d vector6Or(const py::object& x, const char* name, const Vector6d& otherwise, bool nonnegative = false) {
  return x.is_none() ? otherwise : vector6(x, name, nonnegative);
}

/// (6,) or (N, 6) finite joint values, rad.
F64 joints(py::handle x, const char* name = "q") {
  F64 a = realArray(x, name);
  if ((a.ndim() != 1 && a.ndim() != 2) || a.shape(a.ndim() - 1) != 6)
    throw py::value_error(std::string(name) + ": expected shape (6,) or (N, 6), got " + shapeText(a));
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a.data()[i])) throw py::value_error(std::string(name) + ": non-finite joint values");
    // beyond any joint's travel; cos/sin of such a value have lost every digit of the angle
    if (std::abs(a.data()[i]) > 1e6) throw py::value_error(std::string(name) + ": joint values must lie within +-1e6 rad");
  }
  return a;
}

/// One rigid 4x4 transform (scanalign::requireRigid names the failed property).
Eigen::Isometry3d rigid(py::handle x, const std::string& name) {
  const F64 a = realArray(x, name);
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(name + ": expected a 4x4 homogeneous transform, got shape " + shapeText(a));
  Eigen::Isometry3d T;
  T.matrix() = Eigen::Map<const RowMatrix4d>(a.data());
  requireRigid(T.matrix(), name);
  return T;
}

/// (N, 4, 4) poses; with `each_rigid` every pose must be rigid (the error names its index),
/// else a bad pose is left to the solver, which gives it IKStatus::InvalidInput.
F64 poses(py::handle x, const char* name, bool each_rigid) {
  F64 a = realArray(x, name);
  if (a.ndim() != 3 || a.shape(1) != 4 || a.shape(2) != 4)
    throw py::value_error(std::string(name) + ": expected an (N, 4, 4) array of poses, got shape " + shapeText(a));
  for (py::ssize_t i = 0; each_rigid && i < a.shape(0); ++i)
    requireRigid(Eigen::Map<const RowMatrix4d>(a.data() + 16 * i), std::string(name) + "[" + std::to_string(i) + "]");
  return a;
}

double tolerance(double v, const char* name) {
  if (!std::isfinite(v) || v < 0) throw py::value_error(std::string(name) + ": expected a finite value >= 0");
  return v;
}

int threadCount(int num_threads) {
  if (num_threads < 0)
    throw py::value_error("num_threads: expected >= 0 (0 = all cores), got " + std::to_string(num_threads));
  return num_threads;
}

void requireIk(const Robot& r) {
  if (r.geometry() == ArmGeometry::Unsupported)
    throw py::value_error(
        "robot '" + r.name +
        "': analytic IK covers two DH layouts only: 'spherical_wrist' (KUKA type: alpha = (-pi/2, 0, -pi/2, pi/2, "
        "-pi/2, 0), d2 = d3 = d5 = 0, a4 = a5 = a6 = 0, a2 > 0, d4 > 0) and 'universal_robots' (alpha = (pi/2, 0, 0, "
        "pi/2, -pi/2, 0), a1 = a4 = a5 = a6 = 0, d2 = d3 = 0, a2, a3 != 0, d4, d5 > 0); this DH table is neither "
        "(forward kinematics still works)");
}

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

std::int8_t label(int v, const char* name) {
  if (v != 1 && v != -1) throw py::value_error(std::string(name) + ": expected +1 or -1, got " + std::to_string(v));
  return static_cast<std::int8_t>(v);
}

IKConfig config(int shoulder, int elbow, int wrist) {
  return {label(shoulder, "shoulder"), label(elbow, "elbow"), label(wrist, "wrist")};
}

int configIndexChecked(int shoulder, int elbow, int wrist) { return configIndex(config(shoulder, elbow, wrist)); }

// ----------------------------------------------------------------------------- results

py::tuple singularNames(std::uint8_t bits) {
  py::list out;
  for (int i = 0; i < 3; ++i)
    if (bits >> i & 1) out.append(kSingularNames[i]);
  return py::tuple(out);
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

/// Inverse kinematics of N poses as arrays (Robot.ik_batch), filled once from the C++ results.
struct IKBatch {
  py::array_t<double> q;
  py::array_t<std::uint8_t> status, singular, step;
  py::ssize_t size() const { return q.shape(0); }
};

/// Joint values along a pose sequence (Robot.ik_trajectory).
struct JointTrajectory {
  py::array_t<double> q;
  std::vector<IKStatus> status;
};

IKBatch batchArrays(const std::vector<IKResult>& res) {
  const auto n = static_cast<py::ssize_t>(res.size());
  IKBatch b{py::array_t<double>({n, py::ssize_t{8}, py::ssize_t{6}}), py::array_t<std::uint8_t>({n, py::ssize_t{8}}),
            py::array_t<std::uint8_t>({n, py::ssize_t{8}}), py::array_t<std::uint8_t>({n, py::ssize_t{8}})};
  for (std::size_t i = 0; i < res.size(); ++i)
    for (std::size_t k = 0; k < 8; ++k) {
      const IKSolution& s = res[i].solutions[k];
      std::copy(s.q.data(), s.q.data() + 6, b.q.mutable_data() + 48 * i + 6 * k);
      b.status.mutable_data()[8 * i + k] = static_cast<std::uint8_t>(s.status);
      b.singular.mutable_data()[8 * i + k] = s.singular;
      b.step.mutable_data()[8 * i + k] = static_cast<std::uint8_t>(s.unreachable_step);
    }
  readonly(b.q), readonly(b.status), readonly(b.singular), readonly(b.step);
  return b;
}

IKResult batchEntry(const IKBatch& b, py::ssize_t i) {
  if (i < 0) i += b.size();
  if (i < 0 || i >= b.size()) throw py::index_error("i: pose index out of range");
  IKResult r;
  for (std::size_t k = 0; k < 8; ++k) {
    IKSolution& s = r.solutions[k];
    s.q = Eigen::Map<const Vector6d>(b.q.data() + 48 * i + 6 * k);
    s.config = configFromIndex(static_cast<int>(k));
    s.status = static_cast<IKStatus>(b.status.data()[8 * i + k]);
    s.singular = b.singular.data()[8 * i + k];
    s.unreachable_step = static_cast<IKStep>(b.step.data()[8 * i + k]);
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

void bindSolution(py::module_& m) {
  py::class_<IKSolution>(m, "IKSolution", "One inverse-kinematics solution (Robot.ik_closest)")
      .def_property_readonly(
          "q", [](const IKSolution& s) { return readonly(py::array_t<double>(6, s.q.data())); },
          "(6,) joint values, rad (NaN unless a solution with status 'ok' exists)")
      .def_property_readonly(
          "status", [](const IKSolution& s) { return toString(s.status); },
          "'ok', or why no solution exists: 'outside_limits', 'unreachable', 'invalid_input'")
      .def_property_readonly(
          "config", [](const IKSolution& s) { return configArray(s.config); },
          "(3,) int8 labels (shoulder, elbow, wrist), each +1 or -1")
      .def_property_readonly(
          "singular", [](const IKSolution& s) { return singularNames(s.singular); },
          "tuple of the singularities that applied ('shoulder', 'elbow', 'wrist'); empty when regular")
      .def_property_readonly("ok", &IKSolution::ok, "status == 'ok'")
      .def_property_readonly(
          "unreachable_step", [](const IKSolution& s) { return kStepNames[static_cast<int>(s.unreachable_step)]; },
          "'', or the construction step whose point pair is imaginary: 'shoulder' (UR horizon: the wrist point "
          "within d4 of the first axis), 'elbow' (the wrist too far from or too close to the shoulder) or 'fk_check' "
          "(the angles' forward kinematics missed the target by more than 1e-6 m / 1e-6: never reported 'ok')")
      .def("__repr__", &solutionRepr);
}

void bindSolutions(py::module_& m) {
  py::class_<IKResult>(m, "IKSolutions",
                       "All inverse-kinematics solutions of one pose (Robot.ik). Row k holds the configuration "
                       "CONFIGS[k], k = 4*(shoulder<0) + 2*(elbow<0) + (wrist<0), whatever the pose. len() is "
                       "the number of 'ok' rows, so a result without one is falsy.")
      .def_property_readonly(
          "q",
          [](const IKResult& r) {
            py::array_t<double> q({py::ssize_t{8}, py::ssize_t{6}});
            for (std::size_t k = 0; k < 8; ++k)
              std::copy(r.solutions[k].q.data(), r.solutions[k].q.data() + 6, q.mutable_data() + 6 * k);
            return readonly(q);
          },
          "(8, 6) joint values, rad: each joint the 2*pi multiple inside its limits nearest 0 (respect_limits) or "
          "wrapped to (-pi, pi]; NaN rows where the configuration is unreachable")
      .def_property_readonly(
          "status",
          [](const IKResult& r) { return perSolution(r, [](const IKSolution& s) { return toString(s.status); }); },
          "tuple of 8 statuses: 'ok', 'outside_limits', 'unreachable', 'invalid_input'")
      .def_property_readonly(
          "ok",
          [](const IKResult& r) {
            py::array_t<bool> a(8);
            for (std::size_t k = 0; k < 8; ++k) a.mutable_data()[k] = r.solutions[k].ok();
            return a;
          },
          "(8,) bool: rows with status 'ok'")
      .def_property_readonly(
          "config",
          [](const IKResult& r) {
            return configRows(8, [&](py::ssize_t k) { return r.solutions[static_cast<std::size_t>(k)].config; });
          },
          "(8, 3) int8 labels (shoulder, elbow, wrist) of each row, each +1 or -1 (= CONFIGS)")
      .def_property_readonly(
          "singular",
          [](const IKResult& r) {
            return perSolution(r, [](const IKSolution& s) { return singularNames(s.singular); });
          },
          "tuple of 8 tuples of the singularities that applied ('shoulder', 'elbow', 'wrist'); empty when regular")
      .def_property_readonly(
          "unreachable_step",
          [](const IKResult& r) {
            return perSolution(r, [](const IKSolution& s) { return kStepNames[static_cast<int>(s.unreachable_step)]; });
          },
          "tuple of 8: '', or the construction step whose point pair is imaginary ('shoulder': UR horizon, the "
          "wrist point within d4 of the first axis; 'elbow': the wrist too far from or too close to the shoulder; "
          "'fk_check': the angles' forward kinematics missed the target by more than 1e-6 m / 1e-6)")
      .def("__len__", [](const IKResult& r) { return r.count(); })
      .def(
          "valid_q",
          [](const IKResult& r) {
            std::vector<Vector6d> q;
            for (const IKSolution& s : r.solutions)
              if (s.ok()) q.push_back(s.q);
            return rowsOf(q);
          },
          "(K, 6) joint values of the 'ok' rows, in index order, rad")
      .def(
          "distinct",
          [](const IKResult& r, double tol) { return rowsOf(distinctSolutions(r, tolerance(tol, "tol"))); },
          py::arg("tol") = 1e-9,
          "(M, 6) 'ok' rows without duplicates: two rows are equal when every joint differs by a multiple of 2*pi "
          "within tol rad (e.g. both elbow labels at the elbow singularity); the first of each group is kept")
      .def_static("index", &configIndexChecked, py::arg("shoulder"), py::arg("elbow"), py::arg("wrist"),
                  "Row of the configuration (shoulder, elbow, wrist), each +1 or -1: see config_index")
      .def("__repr__", [](const IKResult& r) {
        std::string s = "IKSolutions(" + std::to_string(r.count()) + " ok;";
        for (std::size_t k = 0; k < 8; ++k) {
          const IKConfig& c = r.solutions[k].config;
          s += std::string(k ? "," : "") + " (" + std::to_string(c.shoulder) + ", " + std::to_string(c.elbow) + ", " +
               std::to_string(c.wrist) + "): " + toString(r.solutions[k].status);
        }
        return s + ")";
      });
}

void bindBatch(py::module_& m) {
  py::class_<IKBatch>(m, "IKBatch", "Inverse kinematics of N poses (Robot.ik_batch), as read-only arrays")
      .def_readonly("q", &IKBatch::q,
                    "(N, 8, 6) joint values, rad; q[i, k] has configuration CONFIGS[k]; NaN where not reached")
      .def_readonly("status", &IKBatch::status,
                    "(N, 8) uint8 status codes, indices into STATUS_NAMES (0 ok, 1 outside_limits, 2 unreachable, "
                    "3 invalid_input: a non-finite or non-rigid pose)")
      .def_readonly("singular", &IKBatch::singular, "(N, 8) uint8 singularity bits (1 shoulder, 2 elbow, 4 wrist)")
      .def_readonly("unreachable_step", &IKBatch::step,
                    "(N, 8) uint8 failed construction step (0 none, 1 shoulder, 2 elbow, 3 fk_check: the forward "
                    "kinematics of the angles missed the target)")
      .def_property_readonly(
          "ok", [](const IKBatch& b) { return py::array(b.status.attr("__eq__")(0)); }, "(N, 8) bool: status 'ok'")
      .def_property_readonly(
          "count_ok",
          [](const IKBatch& b) {
            py::array_t<std::int64_t> c(b.size());
            for (py::ssize_t i = 0; i < b.size(); ++i) {
              c.mutable_data()[i] = 0;
              for (int k = 0; k < 8; ++k) c.mutable_data()[i] += b.status.data()[8 * i + k] == 0;
            }
            return c;
          },
          "(N,) number of 'ok' solutions per pose")
      .def(
          "status_names",
          [](const IKBatch& b) {
            py::list names;
            for (int s = 0; s < 4; ++s) names.append(toString(static_cast<IKStatus>(s)));
            return py::array(py::module_::import("numpy").attr("asarray")(names)[b.status]);
          },
          "(N, 8) array of status names (str)")
      .def("__len__", &IKBatch::size)
      .def("solutions", &batchEntry, py::arg("i"), "The solutions of pose i as an IKSolutions");
}

void bindTrajectory(py::module_& m) {
  py::class_<JointTrajectory>(m, "JointTrajectory", "Joint values along a pose sequence (Robot.ik_trajectory)")
      .def_readonly("q", &JointTrajectory::q, "(N, 6) joint values, rad; NaN rows where no 'ok' solution exists")
      .def_property_readonly(
          "status",
          [](const JointTrajectory& t) {
            py::tuple out(t.status.size());
            for (std::size_t i = 0; i < t.status.size(); ++i) out[i] = toString(t.status[i]);
            return out;
          },
          "tuple of N statuses ('ok', 'outside_limits', 'unreachable')")
      .def_property_readonly(
          "ok",
          [](const JointTrajectory& t) {
            py::array_t<bool> a(static_cast<py::ssize_t>(t.status.size()));
            for (std::size_t i = 0; i < t.status.size(); ++i) a.mutable_data()[i] = t.status[i] == IKStatus::Ok;
            return a;
          },
          "(N,) bool: steps with status 'ok'")
      .def("__len__", [](const JointTrajectory& t) { return t.status.size(); });
}

void bindConstruction(py::module_& m) {
  py::class_<IKConstruction>(m, "IKConstruction",
                             "The intermediate CGA construction of one configuration (Robot.ik_construction), in DH "
                             "frame 0, metres")
      .def_property_readonly(
          "points",
          [](const IKConstruction& k) {
            py::dict d;
            for (int i = 0; i < k.num_points; ++i)
              d[py::str(k.names[static_cast<std::size_t>(i)])] = Eigen::Vector3d(k.points[static_cast<std::size_t>(i)]);
            return d;
          },
          "dict name -> (3,) point, m (KUKA: p_e, P_w, P1, P2, P_wx; UR: p_e, P5, P_c, P4, P3, P2, P1); NaN when not "
          "reached")
      .def_readonly("shoulder_discriminant", &IKConstruction::shoulder_discriminant,
                    "normalised h^2/r^2 of the UR horizon point pair (negative: imaginary, Q^2 < 0; NaN when not "
                    "computed)")
      .def_readonly("elbow_discriminant", &IKConstruction::elbow_discriminant,
                    "normalised h^2/r^2 of the elbow point pair (negative: imaginary, Q^2 < 0; NaN when not computed)")
      .def_readonly("solution", &IKConstruction::solution, "the IKSolution of this configuration, limits respected")
      .def_property_readonly(
          "config",
          [](const IKConstruction& k) {
            const IKConfig& c = k.solution.config;
            return py::make_tuple(int(c.shoulder), int(c.elbow), int(c.wrist));
          },
          "(shoulder, elbow, wrist)");
}

// ----------------------------------------------------------------------------- robot

Eigen::Matrix<double, 6, 4, Eigen::RowMajor> dhTable(const Robot& r) {
  Eigen::Matrix<double, 6, 4, Eigen::RowMajor> t;
  for (std::size_t i = 0; i < 6; ++i) {
    const DHJoint& j = r.joints[i];
    t.row(static_cast<int>(i)) << j.a, j.alpha, j.d, j.theta_offset;
  }
  return t;
}

py::array_t<double> dhColumn(const Robot& r, int c) {
  const Eigen::Matrix<double, 6, 1> v = dhTable(r).col(c);
  return readonly(py::array_t<double>(6, v.data()));
}

template <typename M>
py::array_t<double> readonlyMatrix(const M& m) {
  const Eigen::Matrix<double, M::RowsAtCompileTime, M::ColsAtCompileTime, Eigen::RowMajor> r = m;
  return readonly(py::array_t<double>({py::ssize_t{r.rows()}, py::ssize_t{r.cols()}}, r.data()));
}

Eigen::Matrix<double, 6, 2, Eigen::RowMajor> limitTable(const Robot& r) {
  Eigen::Matrix<double, 6, 2, Eigen::RowMajor> t;
  for (std::size_t i = 0; i < 6; ++i) t.row(static_cast<int>(i)) << r.joints[i].q_min, r.joints[i].q_max;
  return t;
}

Robot fromDh(const py::object& a, const py::object& alpha, const py::object& d, const py::object& theta_offset,
             const py::object& limits, const std::string& name, const py::object& T_base_dh0,
             const py::object& T_flange_tool) {
  Robot r;
  r.name = name;
  const Vector6d va = vector6(a, "a"), val = vector6(alpha, "alpha"), vd = vector6(d, "d"),
                 vo = vector6Or(theta_offset, "theta_offset", Vector6d::Zero());
  // No arm is a thousand kilometres long; beyond that FK products overflow towards inf.
  for (const auto& [v, what] : {std::pair{&va, "a"}, std::pair{&vd, "d"}})
    if (v->cwiseAbs().maxCoeff() > 1e6) throw py::value_error(std::string(what) + ": link lengths must lie within +-1e6 m");
  for (std::size_t i = 0; i < 6; ++i) {
    const int k = static_cast<int>(i);
    r.joints[i].a = va[k], r.joints[i].alpha = val[k], r.joints[i].d = vd[k], r.joints[i].theta_offset = vo[k];
  }
  if (!limits.is_none()) {
    const F64 lim = realArray(limits, "limits");
    if (lim.ndim() != 2 || lim.shape(0) != 6 || lim.shape(1) != 2)
      throw py::value_error("limits: expected shape (6, 2), got " + shapeText(lim));
    for (std::size_t i = 0; i < 6; ++i) {
      const double lo = lim.data()[2 * i], hi = lim.data()[2 * i + 1];
      if (std::isnan(lo) || std::isnan(hi) || lo > hi)
        throw py::value_error("limits: expected [q_min, q_max] rows with q_min <= q_max (no NaN)");
      r.joints[i].q_min = lo, r.joints[i].q_max = hi;
    }
  }
  if (!T_base_dh0.is_none()) r.T_base_dh0 = rigid(T_base_dh0, "T_base_dh0");
  if (!T_flange_tool.is_none()) r.T_flange_tool = rigid(T_flange_tool, "T_flange_tool");
  return r;
}

py::object fk(const Robot& r, const py::object& q, int num_threads) {
  const F64 a = joints(q);
  threadCount(num_threads);
  if (a.ndim() == 1) return py::cast(Eigen::Matrix4d(r.forward(Eigen::Map<const Vector6d>(a.data())).matrix()));
  const py::ssize_t n = a.shape(0);
  py::array_t<double> out({n, py::ssize_t{4}, py::ssize_t{4}});
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    r.forwardBatch(a.data(), static_cast<std::size_t>(n), o, num_threads);
  }
  return std::move(out);
}

py::object withinLimits(const Robot& r, const py::object& q, double tol) {
  const F64 a = joints(q);
  const py::ssize_t n = a.ndim() == 1 ? 1 : a.shape(0);
  py::array_t<bool> inside(n);
  for (py::ssize_t i = 0; i < n; ++i)
    inside.mutable_data()[i] = r.withinLimits(Eigen::Map<const Vector6d>(a.data() + 6 * i), tol);
  if (a.ndim() == 1) return py::bool_(inside.data()[0]);
  return std::move(inside);
}

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

IKBatch ikBatchMany(const Robot& r, const py::object& T, const py::object& q_free, bool respect_limits,
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

JointTrajectory ikTrajectoryMany(const Robot& r, const py::object& T, const py::object& q_start,
                                 const py::object& weights, bool respect_limits, double reach_tolerance,
                                 double singular_tolerance) {
  const Vector6d qs = vector6(q_start, "q_start");
  const IKSettings o = options(r, qs, reach_tolerance, singular_tolerance, respect_limits);
  ClosestSettings c;
  c.weights = vector6Or(weights, "weights", Vector6d::Ones(), true);
  const F64 p = poses(T, "T_base_tool", true);
  const py::ssize_t n = p.shape(0);
  JointTrajectory t{py::array_t<double>({n, py::ssize_t{6}}), std::vector<IKStatus>(static_cast<std::size_t>(n))};
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

std::string robotRepr(const Robot& r) {
  std::string extra;
  if (!r.T_base_dh0.matrix().isIdentity(0)) extra += ", T_base_dh0=<set>";
  if (!r.T_flange_tool.matrix().isIdentity(0)) extra += ", T_flange_tool=<set>";
  return "Robot(name='" + r.name + "', geometry='" + toString(r.geometry()) + "'" + extra + ")";
}

constexpr const char* kRobotDoc =
    "A serial 6R arm: standard DH table (metres, radians), joint limits, base and tool transforms.\n\n"
    "Create one with Robot.from_dh, Robot.by_name or the module functions (kuka_kr6_r900_sixx, ur5, ...); "
    "Robot(other) copies. A value object: with_tool and with_base return modified copies.";

constexpr const char* kIkDoc =
    "All (up to 8) inverse-kinematics solutions of a tool pose, as IKSolutions.\n\n"
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

using RobotClass = py::class_<Robot>;

py::array_t<double> jointFrames(const Robot& r, const py::object& q) {
  const auto F = r.jointFrames(vector6(q, "q"));
  py::array_t<double> out({py::ssize_t{7}, py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t i = 0; i < 7; ++i) Eigen::Map<RowMatrix4d>(out.mutable_data() + 16 * i) = F[i].matrix();
  return out;
}

void defForward(RobotClass& c) {
  c.def("fk", &fk, py::arg("q"), py::kw_only(), py::arg("num_threads") = 0,
        "Forward kinematics T_base_tool(q) (Kleppe, PhD thesis, NTNU 2018, Paper 1 eq. (3)): q (6,) rad -> (4, 4), "
        "or q (N, 6) -> (N, 4, 4) batched in C++ (num_threads, 0 = all cores); tool -> robot base, m. ValueError for "
        "another shape, NaN/Inf or |q| > 1e6 rad, TypeError for non-real input")
      .def(
          "fk_flange",
          [](const Robot& r, const py::object& q) {
            return Eigen::Matrix4d(r.forwardFlange(vector6(q, "q")).matrix());
          },
          py::arg("q"), "T_base_flange(q) (4, 4): like fk without the tool transform; q (6,) rad")
      .def("joint_frames", &jointFrames, py::arg("q"),
           "(7, 4, 4) T_dh0_i for i = 0..6 in DH frame 0 ([0] identity, [6] the flange; without T_base_dh0 and the "
           "tool); q (6,) rad")
      .def("within_limits", &withinLimits, py::arg("q"), py::arg("tol") = 0.0,
           "Whether every joint lies in [q_min - tol, q_max + tol] (rad): a bool for q (6,), an (N,) bool array for "
           "q (N, 6)");
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
           "1 = serial), as an IKBatch. A non-finite or non-rigid pose does not raise: its 8 solutions get status "
           "'invalid_input'.")
      .def("ik_trajectory", &ikTrajectoryMany, py::arg("T_base_tool"), py::arg("q_start"),
           py::arg("weights") = py::none(), py::arg("respect_limits") = true, py::kw_only(),
           py::arg("reach_tolerance") = defaults.reach_tolerance,
           py::arg("singular_tolerance") = defaults.singular_tolerance,
           "Joint values along rigid poses T_base_tool (N, 4, 4), as a JointTrajectory: each step takes the solution "
           "closest (ik_closest) to the previous step's joints, the first to q_start ((6,) rad). A step without an "
           "'ok' solution gets a NaN row and its status; the next starts again from the last good joints.")
      .def("ik_construction", &construction, py::arg("T_base_tool"), py::arg("shoulder") = 1, py::arg("elbow") = 1,
           py::arg("wrist") = 1, py::arg("q_free") = py::none(),
           "The intermediate CGA construction (IKConstruction) of one configuration, each label +1 or -1: for "
           "inspection, plots and tests against an independent CGA implementation");
}

/// A copy of r with one transform replaced (Robot is a value type: with_tool / with_base).
template <Eigen::Isometry3d Robot::*Field>
Robot withTransform(const Robot& r, const py::object& T, const char* name) {
  Robot c = r;
  c.*Field = rigid(T, name);
  return c;
}

/// Pickled as the arguments of Robot.from_dh (the DH columns, limits, name and the two
/// transforms), so loading checks them as from_dh does.
constexpr const char* kRobotKeys[] = {"name", "a", "alpha", "d", "theta_offset", "limits", "T_base_dh0", "T_flange_tool"};

py::dict robotState(const Robot& r) {
  py::dict d;
  d["name"] = r.name;
  for (int c = 0; c < 4; ++c) d[kRobotKeys[1 + c]] = dhColumn(r, c);
  d["limits"] = readonlyMatrix(limitTable(r));
  d["T_base_dh0"] = readonlyMatrix(r.T_base_dh0.matrix());
  d["T_flange_tool"] = readonlyMatrix(r.T_flange_tool.matrix());
  return d;
}

/// From robotState's dict, or the 8-tuple in its key order that pickles of earlier versions hold.
Robot robotFromState(const py::object& state) {
  py::dict d;
  if (py::isinstance<py::tuple>(state) && py::len(state) == 8) {
    for (std::size_t i = 0; i < 8; ++i) d[kRobotKeys[i]] = py::tuple(state)[i];
  } else if (py::isinstance<py::dict>(state)) {
    d = py::reinterpret_borrow<py::dict>(state);
  } else {
    throw py::type_error("Robot: pickled state must be a dict");
  }
  for (const auto& item : d) {
    const std::string key = py::str(item.first);
    if (std::find(std::begin(kRobotKeys), std::end(kRobotKeys), key) == std::end(kRobotKeys))
      throw py::value_error("Robot: pickled state has an unknown key '" + key + "'");
  }
  for (const char* key : kRobotKeys)
    if (!d.contains(key)) throw py::value_error(std::string("Robot: pickled state lacks '") + key + "'");
  if (!py::isinstance<py::str>(d["name"])) throw py::type_error("Robot: pickled state 'name' must be a str");
  const auto at = [&](const char* key) { return py::object(d[key]); };
  return fromDh(at("a"), at("alpha"), at("d"), at("theta_offset"), at("limits"), d["name"].cast<std::string>(),
                at("T_base_dh0"), at("T_flange_tool"));
}


/// The configuration labels as 3 ints (+1 / -1); a pickled state with other values is refused.
std::array<int, 3> configLabels(const IKConfig& c) { return {c.shoulder, c.elbow, c.wrist}; }
IKConfig configFromLabels(const std::array<int, 3>& v) {
  for (int x : v)
    if (x != 1 && x != -1) throw py::value_error("IKSolution: pickled state 'config': labels must be +1 or -1");
  return {static_cast<std::int8_t>(v[0]), static_cast<std::int8_t>(v[1]), static_cast<std::int8_t>(v[2])};
}

/// A status index read from a pickled state, in [0, n).
template <typename E>
E enumIndex(int v, int n, const char* what) {
  if (v < 0 || v >= n) throw py::value_error(std::string(what) + ": pickled value out of range");
  return static_cast<E>(v);
}

/// An (N, ...) array of `dtype` from a pickled state, with the shape the accessors index.
template <typename A>
A shapedArray(const py::array& a, std::vector<py::ssize_t> tail, py::ssize_t n, const char* what) {
  if (!py::isinstance<A>(a)) throw py::type_error(std::string(what) + ": pickled array of the wrong dtype");
  bool ok = a.ndim() == static_cast<py::ssize_t>(tail.size()) + 1 && (n < 0 || a.shape(0) == n);
  for (std::size_t i = 0; ok && i < tail.size(); ++i) ok = a.shape(static_cast<py::ssize_t>(i) + 1) == tail[i];
  if (!ok) throw py::value_error(std::string(what) + ": pickled array of the wrong shape");
  return readonly(A::ensure(a.attr("copy")()));
}

void pickleResults(py::module_& m) {
  pickleFields(m, "IKSolution", field("q", &IKSolution::q),
               field<IKSolution>(
                   "config", [](const IKSolution& s) { return configLabels(s.config); },
                   [](IKSolution& s, const std::array<int, 3>& v) { s.config = configFromLabels(v); }),
               field<IKSolution>(
                   "status", [](const IKSolution& s) { return static_cast<int>(s.status); },
                   [](IKSolution& s, int v) { s.status = enumIndex<IKStatus>(v, 4, "IKSolution.status"); }),
               field("singular", &IKSolution::singular),
               field<IKSolution>(
                   "unreachable_step", [](const IKSolution& s) { return static_cast<int>(s.unreachable_step); },
                   [](IKSolution& s, int v) { s.unreachable_step = enumIndex<IKStep>(v, 4, "IKSolution.unreachable_step"); }));
  pickleFields(m, "IKSolutions", field("solutions", &IKResult::solutions),
               field<IKResult>(
                   "status_overall", [](const IKResult& r) { return static_cast<int>(r.status); },
                   [](IKResult& r, int v) { r.status = enumIndex<IKStatus>(v, 4, "IKSolutions.status"); }));
  // IKBatch and JointTrajectory hold their arrays already; their shapes are checked on load
  // because the accessors index them without bounds checks.
  pickleFields(
      m, "IKBatch",
      field<IKBatch>(
          "q", [](const IKBatch& b) { return py::array(b.q); },
          [](IKBatch& b, const py::array& a) { b.q = shapedArray<py::array_t<double>>(a, {8, 6}, -1, "IKBatch.q"); }),
      field<IKBatch>(
          "status", [](const IKBatch& b) { return py::array(b.status); },
          [](IKBatch& b, const py::array& a) {
            b.status = shapedArray<py::array_t<std::uint8_t>>(a, {8}, b.size(), "IKBatch.status");
          }),
      field<IKBatch>(
          "singular", [](const IKBatch& b) { return py::array(b.singular); },
          [](IKBatch& b, const py::array& a) {
            b.singular = shapedArray<py::array_t<std::uint8_t>>(a, {8}, b.size(), "IKBatch.singular");
          }),
      field<IKBatch>(
          "unreachable_step", [](const IKBatch& b) { return py::array(b.step); },
          [](IKBatch& b, const py::array& a) {
            b.step = shapedArray<py::array_t<std::uint8_t>>(a, {8}, b.size(), "IKBatch.unreachable_step");
          }));
  pickleFields(m, "JointTrajectory",
               field<JointTrajectory>(
                   "q", [](const JointTrajectory& t) { return py::array(t.q); },
                   [](JointTrajectory& t, const py::array& a) {
                     t.q = shapedArray<py::array_t<double>>(a, {6}, -1, "JointTrajectory.q");
                   }),
               field<JointTrajectory>(
                   "status",
                   [](const JointTrajectory& t) {
                     std::vector<std::uint8_t> v;
                     for (IKStatus s : t.status) v.push_back(static_cast<std::uint8_t>(s));
                     return v;
                   },
                   [](JointTrajectory& t, const std::vector<std::uint8_t>& v) {
                     t.status.clear();
                     for (auto s : v) t.status.push_back(enumIndex<IKStatus>(s, 4, "JointTrajectory.status"));
                   }));
  pickleFields(m, "IKConstruction",
               field<IKConstruction>(
                   "geometry", [](const IKConstruction& k) { return static_cast<int>(k.geometry); },
                   [](IKConstruction& k, int v) { k.geometry = static_cast<ArmGeometry>(v); }),
               field("solution", &IKConstruction::solution), field("names", &IKConstruction::names),
               field<IKConstruction>("points",
                     [](const IKConstruction& k) { return std::vector<Eigen::Vector3d>(k.points.begin(), k.points.end()); },
                     [](IKConstruction& k, const std::vector<Eigen::Vector3d>& v) {
                       if (v.size() != k.points.size()) throw py::value_error("IKConstruction.points: expected 8 rows");
                       std::copy(v.begin(), v.end(), k.points.begin());
                     }),
               field<IKConstruction>(
                   "num_points", [](const IKConstruction& k) { return k.num_points; },
                   [](IKConstruction& k, int v) {
                     if (v < 0 || v > 8) throw py::value_error("IKConstruction.num_points: pickled value out of range");
                     k.num_points = v;
                   }),
               field("shoulder_discriminant", &IKConstruction::shoulder_discriminant),
               field("elbow_discriminant", &IKConstruction::elbow_discriminant));
}

void bindRobot(py::module_& m) {
  RobotClass c(m, "Robot", kRobotDoc);
  c.def(py::init<const Robot&>(), py::arg("robot"), "A copy of robot")
      .def_static("from_dh", &fromDh, py::arg("a"), py::arg("alpha"), py::arg("d"),
                  py::arg("theta_offset") = py::none(), py::arg("limits") = py::none(), py::arg("name") = "custom",
                  py::arg("T_base_dh0") = py::none(), py::arg("T_flange_tool") = py::none(),
                  "A robot from its standard DH table: a (6,) link lengths along x_i, m (may be negative, as in UR's "
                  "tables); alpha (6,) link twists about x_i, rad; d (6,) link offsets along z_{i-1}, m; "
                  "theta_offset (6,) theta_i = q_i + theta_offset_i, rad (default zeros); limits (6, 2) "
                  "[q_min, q_max] per joint, rad, +-inf allowed (default [-pi, pi]); T_base_dh0 4x4 rigid, DH frame "
                  "0 -> robot base (default identity); T_flange_tool 4x4 rigid, tool -> flange (default identity). "
                  "ValueError for non-finite values or |a|, |d| beyond 1e6 m")
      .def_static(
          "by_name",
          [](const py::object& name) {
            if (!py::isinstance<py::str>(name))
              throw py::type_error("name: expected a robot name (str), got " +
                                   std::string(py::str(py::type::of(name).attr("__name__"))));
            return Robot::byName(name.cast<std::string>());
          },
          py::arg("name"),
          "A built-in robot: one of BUILTIN_ROBOTS (ValueError naming the known ones otherwise, TypeError for a "
          "name that is not a str)")
      .def(
          "with_tool",
          [](const Robot& r, const py::object& T) {
            return withTransform<&Robot::T_flange_tool>(r, T, "T_flange_tool");
          },
          py::arg("T_flange_tool"), "A copy with the tool centre point at T_flange_tool (4x4 rigid, tool -> flange)")
      .def(
          "with_base",
          [](const Robot& r, const py::object& T) { return withTransform<&Robot::T_base_dh0>(r, T, "T_base_dh0"); },
          py::arg("T_base_dh0"), "A copy with DH frame 0 placed at T_base_dh0 (4x4 rigid, DH frame 0 -> base)")
      .def_readonly("name", &Robot::name, "a label")
      .def_property_readonly(
          "dh", [](const Robot& r) { return readonlyMatrix(dhTable(r)); },
          "(6, 4) DH table, one row per joint: [a (m), alpha (rad), d (m), theta_offset (rad)]")
      .def_property_readonly("a", [](const Robot& r) { return dhColumn(r, 0); }, "(6,) link lengths, m")
      .def_property_readonly("alpha", [](const Robot& r) { return dhColumn(r, 1); }, "(6,) link twists, rad")
      .def_property_readonly("d", [](const Robot& r) { return dhColumn(r, 2); }, "(6,) link offsets, m")
      .def_property_readonly(
          "theta_offset", [](const Robot& r) { return dhColumn(r, 3); },
          "(6,) DH angle offsets, theta = q + theta_offset, rad")
      .def_property_readonly(
          "limits", [](const Robot& r) { return readonlyMatrix(limitTable(r)); },
          "(6, 2) joint limits [q_min, q_max], rad")
      .def_property_readonly(
          "T_base_dh0", [](const Robot& r) { return readonlyMatrix(r.T_base_dh0.matrix()); },
          "4x4: DH frame 0 -> robot base, m")
      .def_property_readonly(
          "T_flange_tool", [](const Robot& r) { return readonlyMatrix(r.T_flange_tool.matrix()); },
          "4x4: tool -> flange (DH frame 6), m")
      .def_property_readonly(
          "geometry", [](const Robot& r) { return toString(r.geometry()); },
          "which analytic solver applies: 'spherical_wrist' (KUKA layout), 'universal_robots' or 'unsupported' "
          "(forward kinematics only)")
      .def("__repr__", &robotRepr)
      .def(py::pickle(&robotState, &robotFromState));
  defForward(c);
  defInverse(c);
}
}  // namespace

void defineKinematics(py::module_& m) {
  // The C++ defaults and names, so that the Python layer has one source of truth.
  m.attr("DEFAULT_REACH_TOLERANCE") = IKSettings{}.reach_tolerance;
  m.attr("DEFAULT_SINGULAR_TOLERANCE") = IKSettings{}.singular_tolerance;
  m.attr("STATUS_NAMES") = py::make_tuple(toString(IKStatus::Ok), toString(IKStatus::OutsideLimits),
                                          toString(IKStatus::Unreachable), toString(IKStatus::InvalidInput));
  m.attr("SINGULAR_NAMES") = py::make_tuple(kSingularNames[0], kSingularNames[1], kSingularNames[2]);
  m.attr("STEP_NAMES") = py::make_tuple(kStepNames[0], kStepNames[1], kStepNames[2], kStepNames[3]);
  m.attr("CONFIGS") = configRows(8, [](py::ssize_t k) { return configFromIndex(static_cast<int>(k)); });
  m.def("config_index", &configIndexChecked, py::arg("shoulder"), py::arg("elbow"), py::arg("wrist"),
        "The fixed solution index 4*(shoulder<0) + 2*(elbow<0) + (wrist<0) of a configuration (each label +1 or -1)");
  bindSolution(m);
  bindSolutions(m);
  bindBatch(m);
  bindTrajectory(m);
  bindConstruction(m);
  bindRobot(m);
  pickleResults(m);
}

}  // namespace scanalign::python
