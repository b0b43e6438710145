// Bindings of scanalign/kinematics/robot.hpp and joint_chain.hpp: the Robot (DH table, joint
// limits, base and tool transforms) through its field table (fields.hpp), robots from DH
// tables, built-in names and joint chains (a URDF's joints), and forward kinematics. The
// inverse kinematics methods are added by kinematics_ik.cpp; python/scanalign/kinematics.py
// re-exports these classes.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <string>

#include "fields.hpp"
#include "kinematics.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/kinematics/joint_chain.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace scanalign::python {

namespace kin {

// ----------------------------------------------------------------------------- arguments

std::string shapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

F64 realArray(py::handle x, const std::string& name) {
  if (py::isinstance<F64>(x)) return py::reinterpret_borrow<F64>(x);  // the hot path: no copy
  return checkedAs<double>(x, name, kReals);
}

Vector6d vector6(py::handle x, const std::string& name, bool nonnegative) {
  const F64 a = realArray(x, name);
  if (a.ndim() != 1 || a.shape(0) != 6) throw py::value_error(name + ": expected shape (6,), got " + shapeText(a));
  const Vector6d v = Eigen::Map<const Vector6d>(a.data());
  if (!v.allFinite()) throw py::value_error(name + ": non-finite values");
  if (nonnegative && (v.array() < 0).any()) throw py::value_error(name + ": values must be >= 0");
  return v;
}

Vector6d vector6Or(const py::object& x, const char* name, const Vector6d& otherwise, bool nonnegative) {
  return x.is_none() ? otherwise : vector6(x, name, nonnegative);
}

F64 joints(py::handle x, const char* name) {
  F64 a = realArray(x, name);
  if ((a.ndim() != 1 && a.ndim() != 2) || a.shape(a.ndim() - 1) != 6)
    throw py::value_error(std::string(name) + ": expected shape (6,) or (N, 6), got " + shapeText(a));
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a.data()[i])) throw py::value_error(std::string(name) + ": non-finite joint values");
    // beyond any joint's travel; cos/sin of such a value have lost every digit of the angle
    if (std::abs(a.data()[i]) > 1e6)
      throw py::value_error(std::string(name) + ": joint values must lie within +-1e6 rad");
  }
  return a;
}

Eigen::Isometry3d rigid(py::handle x, const std::string& name) {
  const F64 a = realArray(x, name);
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(name + ": expected a 4x4 homogeneous transform, got shape " + shapeText(a));
  Eigen::Isometry3d T;
  T.matrix() = Eigen::Map<const RowMatrix4d>(a.data());
  requireRigid(T.matrix(), name);
  return T;
}

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
    throw py::value_error("robot '" + r.name + "': analytic IK covers two DH layouts only: " + analyticLayoutsText() +
                          "; this DH table is neither (forward kinematics still works)");
}

namespace {

constexpr const char* kColumns[] = {"a", "alpha", "d", "theta_offset"};

/// DH column c of r (a, alpha, d, theta_offset), read-only.
py::array_t<double> dhColumn(const Robot& r, int c) {
  Vector6d v;
  for (std::size_t i = 0; i < 6; ++i) {
    const DHJoint& j = r.joints[i];
    const double row[4] = {j.a, j.alpha, j.d, j.theta_offset};
    v[static_cast<int>(i)] = row[c];
  }
  return readonly(py::array_t<double>(6, v.data()));
}

/// Sets DH column c of r from (6,) finite values (`name` in messages); no arm is a thousand
/// kilometres long: beyond 1e6 m FK products overflow towards inf.
void setDhColumn(Robot& r, int c, py::handle x, const std::string& name) {
  const Vector6d v = vector6(x, name);
  if ((c == 0 || c == 2) && v.cwiseAbs().maxCoeff() > 1e6)
    throw py::value_error(name + ": link lengths must lie within +-1e6 m");
  for (std::size_t i = 0; i < 6; ++i) {
    DHJoint& j = r.joints[i];
    double* row[4] = {&j.a, &j.alpha, &j.d, &j.theta_offset};
    *row[c] = v[static_cast<int>(i)];
  }
}

Eigen::Matrix<double, 6, 2, Eigen::RowMajor> limitTable(const Robot& r) {
  Eigen::Matrix<double, 6, 2, Eigen::RowMajor> t;
  for (std::size_t i = 0; i < 6; ++i) t.row(static_cast<int>(i)) << r.joints[i].q_min, r.joints[i].q_max;
  return t;
}

/// (6, 2) rows [q_min, q_max], rad, +-inf allowed.
std::array<Eigen::Vector2d, 6> limitsArg(py::handle x, const std::string& name) {
  const F64 lim = realArray(x, name);
  if (lim.ndim() != 2 || lim.shape(0) != 6 || lim.shape(1) != 2)
    throw py::value_error(name + ": expected shape (6, 2), got " + shapeText(lim));
  std::array<Eigen::Vector2d, 6> out;
  for (std::size_t i = 0; i < 6; ++i) {
    const double lo = lim.data()[2 * i], hi = lim.data()[2 * i + 1];
    if (std::isnan(lo) || std::isnan(hi) || lo > hi)
      throw py::value_error(name + ": expected [q_min, q_max] rows with q_min <= q_max (no NaN)");
    out[i] = Eigen::Vector2d(lo, hi);
  }
  return out;
}

void setLimits(Robot& r, const std::array<Eigen::Vector2d, 6>& lim) {
  for (std::size_t i = 0; i < 6; ++i) r.joints[i].q_min = lim[i][0], r.joints[i].q_max = lim[i][1];
}

Robot fromDh(const py::object& a, const py::object& alpha, const py::object& d, const py::object& theta_offset,
             const py::object& limits, const std::string& name, const py::object& T_base_dh0,
             const py::object& T_flange_tool) {
  Robot r;
  r.name = name;
  const py::object zeros = py::cast(Vector6d::Zero().eval());
  const py::object columns[4] = {a, alpha, d, theta_offset.is_none() ? zeros : theta_offset};
  for (int c = 0; c < 4; ++c) setDhColumn(r, c, columns[c], kColumns[c]);
  if (!limits.is_none()) setLimits(r, limitsArg(limits, "limits"));
  if (!T_base_dh0.is_none()) r.T_base_dh0 = rigid(T_base_dh0, "T_base_dh0");
  if (!T_flange_tool.is_none()) r.T_flange_tool = rigid(T_flange_tool, "T_flange_tool");
  return r;
}

Robot fromJointChain(const py::object& origins, const py::object& axes, const py::object& limits,
                     const py::object& T_joint6_tip, const std::string& name, const py::object& joint_signs,
                     bool fk_only, double tol, const std::string& what) {
  JointChain chain;
  const F64 o = poses(origins, "origins", true);
  if (o.shape(0) != 6) throw py::value_error("origins: expected 6 joint origins, got " + std::to_string(o.shape(0)));
  const F64 u = realArray(axes, "axes");
  if (u.ndim() != 2 || u.shape(0) != 6 || u.shape(1) != 3)
    throw py::value_error("axes: expected shape (6, 3), got " + shapeText(u));
  for (std::size_t i = 0; i < 6; ++i) {
    chain.origins[i].matrix() = Eigen::Map<const RowMatrix4d>(o.data() + 16 * i);
    chain.axes[i] = Eigen::Map<const Eigen::Vector3d>(u.data() + 3 * i);
  }
  if (!limits.is_none()) chain.limits = limitsArg(limits, "limits");
  if (!T_joint6_tip.is_none()) chain.T_joint6_tip = rigid(T_joint6_tip, "T_joint6_tip");
  JointChainSettings s;
  s.name = name;
  if (!joint_signs.is_none()) s.joint_signs = vector6(joint_signs, "joint_signs");
  s.fk_only = fk_only;
  s.tolerance = tol;
  s.what = what;
  py::gil_scoped_release release;
  return Robot::fromJointChain(chain, s);
}

/// A copy of r with one transform replaced (Robot is a value type: with_tool / with_base).
template <Eigen::Isometry3d Robot::*Field>
Robot withTransform(const Robot& r, const py::object& T, const char* name) {
  Robot c = r;
  c.*Field = rigid(T, name);
  return c;
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

py::array_t<double> jointPositions(const Robot& r, const py::object& q, bool tcp, int num_threads) {
  const F64 a = joints(q);
  threadCount(num_threads);
  const py::ssize_t n = a.ndim() == 1 ? 1 : a.shape(0), rows = tcp ? 8 : 7;
  py::array_t<double> out = a.ndim() == 1 ? py::array_t<double>({rows, py::ssize_t{3}})
                                          : py::array_t<double>({n, rows, py::ssize_t{3}});
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    r.jointPositionsBatch(a.data(), static_cast<std::size_t>(n), o, tcp, num_threads);
  }
  return out;
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

py::array_t<double> jointFrames(const Robot& r, const py::object& q) {
  const auto F = r.jointFrames(vector6(q, "q"));
  py::array_t<double> out({py::ssize_t{7}, py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t i = 0; i < 7; ++i) Eigen::Map<RowMatrix4d>(out.mutable_data() + 16 * i) = F[i].matrix();
  return out;
}

std::string robotRepr(const Robot& r) {
  std::string extra;
  if (!r.T_base_dh0.matrix().isIdentity(0)) extra += ", T_base_dh0=<set>";
  if (!r.T_flange_tool.matrix().isIdentity(0)) extra += ", T_flange_tool=<set>";
  return "Robot(name='" + r.name + "', geometry='" + toString(r.geometry()) + "'" + extra + ")";
}

constexpr const char* kRobotDoc =
    "A serial 6R arm: standard DH table (metres, radians), joint limits, base and tool transforms.\n\n"
    "Create one with Robot.from_dh, Robot.by_name, Robot.from_joint_chain or the module functions "
    "(kuka_kr6_r900_sixx, ur5, ...); Robot(other) copies. A value object: with_tool and with_base return modified "
    "copies.";

/// The DH column c as a field: read-only, set (unpickling) with from_dh's checks.
auto columnGet(int c) {
  return [c](const Robot& r) { return dhColumn(r, c); };
}
auto columnSet(int c) {
  return [c](Robot& r, py::handle h) { setDhColumn(r, c, h, std::string("Robot.") + kColumns[c]); };
}

/// Robot pickles of earlier versions hold the 8-tuple of the state's values in this order.
constexpr const char* kTupleStateKeys[] = {"name", "a", "alpha", "d", "theta_offset", "limits", "T_base_dh0",
                                           "T_flange_tool"};

RobotClass bindRobotFields(py::module_& m) {
  return fieldsOf(RobotClass(m, "Robot", kRobotDoc).def("__repr__", &robotRepr))
      .output("name", &Robot::name, "", "a label")
      .field("a", columnGet(0), columnSet(0), "m", "(6,) link lengths along x_i (may be negative, as in UR's tables)",
             false)
      .field("alpha", columnGet(1), columnSet(1), "rad", "(6,) link twists about x_i", false)
      .field("d", columnGet(2), columnSet(2), "m", "(6,) link offsets along z_{i-1}", false)
      .field("theta_offset", columnGet(3), columnSet(3), "rad", "(6,) DH angle offsets, theta_i = q_i + theta_offset_i",
             false)
      .field(
          "limits", [](const Robot& r) { return readonlyMatrix(limitTable(r)); },
          [](Robot& r, py::handle h) { setLimits(r, limitsArg(h, "Robot.limits")); }, "rad",
          "(6, 2) joint limits [q_min, q_max], +-inf allowed", false)
      .field(
          "T_base_dh0", [](const Robot& r) { return readonlyMatrix(r.T_base_dh0.matrix()); },
          [](Robot& r, py::handle h) { r.T_base_dh0 = rigid(h, "Robot.T_base_dh0"); }, "m",
          "4x4: DH frame 0 -> robot base", false)
      .field(
          "T_flange_tool", [](const Robot& r) { return readonlyMatrix(r.T_flange_tool.matrix()); },
          [](Robot& r, py::handle h) { r.T_flange_tool = rigid(h, "Robot.T_flange_tool"); }, "m",
          "4x4: tool -> flange (DH frame 6)", false)
      .derived(
          "dh",
          [](const Robot& r) {
            Eigen::Matrix<double, 6, 4, Eigen::RowMajor> t;
            for (std::size_t i = 0; i < 6; ++i) {
              const DHJoint& j = r.joints[i];
              t.row(static_cast<int>(i)) << j.a, j.alpha, j.d, j.theta_offset;
            }
            return readonlyMatrix(t);
          },
          "", "(6, 4) DH table, one row per joint: [a (m), alpha (rad), d (m), theta_offset (rad)]")
      .derived(
          "geometry", [](const Robot& r) { return std::string(toString(r.geometry())); }, "",
          "which analytic solver applies: 'spherical_wrist' (KUKA layout), 'universal_robots' or 'unsupported' "
          "(forward kinematics only)")
      .result();
}

void bindRobot(py::module_& m) {
  RobotClass c = bindRobotFields(m);
  // Pickles of earlier versions hold the state's values as a tuple: loaded through the dict
  // state, so with the same checks.
  c.def(py::pickle([](const Robot& r) { return py::cast(r).attr("__getstate__")(); },
                   [](const py::tuple& values) {
                     if (values.size() != std::size(kTupleStateKeys))
                       throw py::value_error("Robot: pickled tuple state must hold 8 values");
                     py::dict d;
                     for (std::size_t i = 0; i < values.size(); ++i) d[kTupleStateKeys[i]] = values[i];
                     const py::object cls = py::type::of<Robot>();
                     py::object r = cls.attr("__new__")(cls);
                     r.attr("__setstate__")(d);
                     return r.cast<Robot>();
                   }));
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
      .def_static("from_joint_chain", &fromJointChain, py::arg("origins"), py::arg("axes"),
                  py::arg("limits") = py::none(), py::arg("T_joint6_tip") = py::none(), py::kw_only(),
                  py::arg("name") = JointChainSettings{}.name, py::arg("joint_signs") = py::none(),
                  py::arg("fk_only") = false, py::arg("tolerance") = JointChainSettings{}.tolerance,
                  py::arg("what") = JointChainSettings{}.what,
                  "The robot of a serial chain of 6 revolute joints, as a URDF gives it (C++ Robot::fromJointChain, "
                  "scanalign/kinematics/joint_chain.hpp): origins (6, 4, 4) rigid, joint i's frame at q = 0 in joint "
                  "i-1's (the first in the base), m, fixed joints folded in; axes (6, 3) each joint's rotation axis "
                  "in its own frame; limits (6, 2) [q_min, q_max], rad, +-inf allowed (default [-pi, pi]); "
                  "T_joint6_tip 4x4 rigid, the tip in joint 6's frame, m. The DH table, T_base_dh0 and "
                  "T_flange_tool follow from the joint lines, in an analytic IK layout where one fits (of the free "
                  "DH x-axis signs, the one with the smallest theta offsets), so that fk(q) is the chain's tip pose "
                  "for chain joint values joint_signs * q. joint_signs: (6,) of +1 / -1 (default all +1; the error "
                  "for a chain no layout fits then names signs that make it one). fk_only: return a robot whose "
                  "geometry is 'unsupported' instead of raising. tolerance (rad, m): axes within this angle are "
                  "parallel, DH values within it of 0 or a multiple of pi/2 are set to them. what: how messages "
                  "name the chain. ValueError for a bad chain or argument, or a chain no analytic layout fits; "
                  "RuntimeError if the DH model departs from the chain")
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
      .def("fk", &fk, py::arg("q"), py::kw_only(), py::arg("num_threads") = 0,
           "Forward kinematics T_base_tool(q) (Kleppe, PhD thesis, NTNU 2018, Paper 1 eq. (3)): q (6,) rad -> (4, "
           "4), or q (N, 6) -> (N, 4, 4) batched in C++ (num_threads, 0 = all cores); tool -> robot base, m. "
           "ValueError for another shape, NaN/Inf or |q| > 1e6 rad, TypeError for non-real input")
      .def(
          "fk_flange",
          [](const Robot& r, const py::object& q) {
            return Eigen::Matrix4d(r.forwardFlange(vector6(q, "q")).matrix());
          },
          py::arg("q"), "T_base_flange(q) (4, 4): like fk without the tool transform; q (6,) rad")
      .def("joint_frames", &jointFrames, py::arg("q"),
           "(7, 4, 4) T_dh0_i for i = 0..6 in DH frame 0 ([0] identity, [6] the flange; without T_base_dh0 and the "
           "tool); q (6,) rad")
      .def("joint_positions", &jointPositions, py::arg("q"), py::kw_only(), py::arg("tcp") = false,
           py::arg("num_threads") = 0,
           "The arm's joint points in the robot base frame, m: the origins of DH frames 0..6 (base to flange), and "
           "with tcp the tool centre point (fk(q)'s origin) after them. q (6,) rad -> (7, 3) ((8, 3) with tcp), or "
           "q (N, 6) -> (N, 7, 3) batched in C++ (num_threads, 0 = all cores)")
      .def("within_limits", &withinLimits, py::arg("q"), py::arg("tol") = 0.0,
           "Whether every joint lies in [q_min - tol, q_max + tol] (rad): a bool for q (6,), an (N,) bool array for "
           "q (N, 6)");
  defInverse(c);
}

}  // namespace

}  // namespace kin

void defineKinematics(py::module_& m) {
  kin::bindIkResults(m);
  kin::bindRobot(m);
}

}  // namespace scanalign::python
