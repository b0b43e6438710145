// Bindings of scanalign/grasp: grasps on a CAD part, the part's symmetry, the gripper, the
// planner settings and planGrasp, with the C++ structs bound directly (their doc comments are
// the docstrings). Every argument is checked in C++ (std::invalid_argument -> ValueError naming
// the field); python/scanalign/grasp.py re-exports these classes and reads grasp files.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <string>
#include <vector>

#include "pickle.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/grasp/grasp_planner.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {
using namespace scanalign;
using Matrix4 = Eigen::Matrix4d;

std::string shapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// `x` as a finite rows x cols (cols 0: a vector of `rows`) float64 matrix; TypeError naming
/// `name` unless it holds real numbers, ValueError for another shape or a non-finite value.
Eigen::MatrixXd realArray(const py::object& x, const std::string& name, int rows, int cols) {
  const py::array a = py::array::ensure(x);
  const char kind = a ? a.dtype().kind() : 'O';
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(name + ": expected real numbers, got " +
                         (a ? "dtype " + std::string(py::str(a.dtype())) : std::string(py::str(py::type::of(x)))));
  const auto f = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  const bool fits = cols == 0 ? f.ndim() == 1 && f.shape(0) == rows
                              : f.ndim() == 2 && f.shape(0) == rows && f.shape(1) == cols;
  if (!fits)
    throw py::value_error(name + ": expected shape (" + std::to_string(rows) +
                          (cols ? ", " + std::to_string(cols) + ")" : ",)") + ", got " + shapeText(f));
  Eigen::MatrixXd M(rows, std::max(cols, 1));
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < std::max(cols, 1); ++j) M(i, j) = f.data()[i * std::max(cols, 1) + j];
  if (!M.allFinite()) throw py::value_error(name + ": non-finite values");
  return M;
}

Eigen::Vector3d vec3(const py::object& x, const std::string& name) { return realArray(x, name, 3, 0); }

Eigen::Isometry3d rigid(const py::object& x, const std::string& name) {
  Eigen::Isometry3d T;
  T.matrix() = realArray(x, name, 4, 4);
  requireRigid(T.matrix(), name);
  return T;
}


GripperShape shapeOf(const std::string& s) {
  if (s == "box") return GripperShape::Box;
  if (s == "capsule") return GripperShape::Capsule;
  throw std::invalid_argument("gripper.shape must be 'box' or 'capsule', got '" + s + "'");
}

/// A setter that validates the whole object after the change and keeps the old value on error.
template <typename C, typename V, typename Set>
auto checked(Set set) {
  return [set](C& obj, const V& v) {
    C copy = obj;
    set(copy, v);
    copy.validate();
    obj = copy;
  };
}

void bindSymmetry(py::module_& m) {
  using S = PartSymmetry;
  py::class_<S>(m, "PartSymmetry",
                "A part's rotational symmetry in its model frame: it looks the same after a rotation by 2*pi/order "
                "about the axis through point (order 1: none; 0: any rotation, a body of revolution)")
      .def(py::init([](const py::object& axis, const py::object& point, int order) {
             S s{vec3(axis, "axis"), vec3(point, "point"), order};
             s.validate();
             return s;
           }),
           py::arg("axis") = std::vector<double>{0, 0, 1}, py::arg("point") = std::vector<double>{0, 0, 0},
           py::arg("order") = 1)
      .def_property("axis", [](const S& s) { return s.axis; },
                    checked<S, py::object>([](S& s, const py::object& v) { s.axis = vec3(v, "PartSymmetry.axis"); }),
                    "(3,) symmetry axis direction, model frame (normalised on use)")
      .def_property("point", [](const S& s) { return s.point; },
                    checked<S, py::object>([](S& s, const py::object& v) { s.point = vec3(v, "PartSymmetry.point"); }),
                    "(3,) a point on the axis, model frame, m")
      .def_property("order", [](const S& s) { return s.order; }, checked<S, int>([](S& s, int v) { s.order = v; }),
                    "1: no symmetry; n >= 2: 2*pi/n rotations; 0: continuous")
      .def(
          "transforms",
          [](const S& s, int continuous_steps) {
            if (continuous_steps < 1 || continuous_steps > 3600)
              throw std::invalid_argument("continuous_steps must be in 1..3600");
            std::vector<Matrix4> out;
            for (const auto& T : s.transforms(continuous_steps)) out.push_back(T.matrix());
            return out;
          },
          py::arg("continuous_steps") = 72,
          "The transforms S_k (model -> model, 4x4) that map the part onto itself, S_0 = identity; for a continuous "
          "symmetry continuous_steps evenly spaced angles")
      .def("__repr__", [](const S& s) {
        return "PartSymmetry(axis=" + std::string(py::repr(py::cast(s.axis).attr("tolist")())) +
               ", point=" + std::string(py::repr(py::cast(s.point).attr("tolist")())) +
               ", order=" + std::to_string(s.order) + ")";
      });
}

void bindGrasp(py::module_& m) {
  py::class_<Grasp>(m, "Grasp",
                    "A grasp on a CAD part: T_model_grasp (TCP pose at the grasp, model frame, m), the approach "
                    "direction (unit, grasp/TCP frame: where the TCP moves to reach the grasp) and the pre-grasp "
                    "distance (m): the pre-grasp is the grasp moved back by that distance against the approach")
      .def(py::init([](const std::string& name, const py::object& T_model_grasp, const py::object& approach,
                       double pre_grasp_distance) {
             Grasp g{name, Eigen::Isometry3d::Identity(), Eigen::Vector3d::UnitZ(), pre_grasp_distance};
             if (!T_model_grasp.is_none()) g.T_model_grasp = rigid(T_model_grasp, "T_model_grasp");
             if (!approach.is_none()) g.approach = vec3(approach, "approach");
             g.validate("grasp '" + name + "'");
             return g;
           }),
           py::arg("name") = "", py::arg("T_model_grasp") = py::none(), py::arg("approach") = py::none(),
           py::arg("pre_grasp_distance") = 0.08,
           "T_model_grasp (4, 4), default identity; approach (3,), default (0, 0, 1)")
      .def_readwrite("name", &Grasp::name, "name, for messages and files")
      .def_property(
          "T_model_grasp", [](const Grasp& g) { return Matrix4(g.T_model_grasp.matrix()); },
          checked<Grasp, py::object>([](Grasp& g, const py::object& M) { g.T_model_grasp = rigid(M, "T_model_grasp"); }),
          "(4, 4) TCP pose at the grasp in the model frame, m")
      .def_property("approach", [](const Grasp& g) { return g.approach; },
                    checked<Grasp, py::object>([](Grasp& g, const py::object& v) { g.approach = vec3(v, "approach"); }),
                    "(3,) unit approach direction in the grasp (TCP) frame; default +z, the tool axis")
      .def_property("pre_grasp_distance", [](const Grasp& g) { return g.pre_grasp_distance; },
                    checked<Grasp, double>([](Grasp& g, double v) { g.pre_grasp_distance = v; }),
                    "m, from the pre-grasp to the grasp along the approach (>= 0)")
      .def(
          "pre_grasp", [](const Grasp& g) { return Matrix4(g.preGrasp().matrix()); },
          "T_model_pregrasp (4, 4): the grasp pose moved back by pre_grasp_distance against the approach, m")
      .def("__repr__", [](const Grasp& g) {
        return "Grasp(name='" + g.name + "', pre_grasp_distance=" + std::string(py::repr(py::float_(g.pre_grasp_distance))) + ")";
      });
}

void bindGripper(py::module_& m) {
  using G = Gripper;
  const auto vec = [](Eigen::Vector3d G::*field, const char* name) {
    return checked<G, py::object>([field, name](G& g, const py::object& v) { g.*field = vec3(v, name); });
  };
  const auto scalar = [](double G::*field) {
    return checked<G, double>([field](G& g, double v) { g.*field = v; });
  };
  py::class_<G>(m, "Gripper",
                "The tool on the flange: T_flange_tcp and a collision body (a box or a capsule, flange frame, m) "
                "that the planner keeps above the table, plus the flange disc of flange_radius")
      .def(py::init([](const py::object& T_flange_tcp, const std::string& shape, const py::object& box_centre,
                       const py::object& box_half_extents, const py::object& capsule_a, const py::object& capsule_b,
                       double capsule_radius, double flange_radius) {
             G g;
             g.T_flange_tcp = rigid(T_flange_tcp, "gripper.T_flange_tcp");
             g.shape = shapeOf(shape);
             g.box_centre = vec3(box_centre, "gripper.box_centre");
             g.box_half_extents = vec3(box_half_extents, "gripper.box_half_extents");
             g.capsule_a = vec3(capsule_a, "gripper.capsule_a"), g.capsule_b = vec3(capsule_b, "gripper.capsule_b");
             g.capsule_radius = capsule_radius;
             g.flange_radius = flange_radius;
             g.validate();
             return g;
           }),
           py::arg("T_flange_tcp") = std::vector<std::vector<double>>{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}},
           py::arg("shape") = "box", py::arg("box_centre") = std::vector<double>{0, 0, 0},
           py::arg("box_half_extents") = std::vector<double>{0, 0, 0}, py::arg("capsule_a") = std::vector<double>{0, 0, 0},
           py::arg("capsule_b") = std::vector<double>{0, 0, 0},
           py::arg("capsule_radius") = 0.0, py::arg("flange_radius") = 0.0315)
      .def_static("parallel_jaw", &G::parallelJaw,
                  "A parallel-jaw gripper like the Robotiq 2F-85: TCP 0.15 m along the flange z; body a box "
                  "0.08 x 0.14 x 0.15 m from the flange face to the TCP; flange radius 0.0315 m")
      .def_property(
          "T_flange_tcp", [](const G& g) { return Matrix4(g.T_flange_tcp.matrix()); },
          checked<G, py::object>([](G& g, const py::object& M) { g.T_flange_tcp = rigid(M, "gripper.T_flange_tcp"); }),
          "(4, 4) TCP -> flange, m")
      .def_property(
          "shape", [](const G& g) { return std::string(toString(g.shape)); },
          checked<G, std::string>([](G& g, const std::string& s) { g.shape = shapeOf(s); }),
          "'box' or 'capsule': which collision body is used")
      .def_property("box_centre", [](const G& g) { return g.box_centre; }, vec(&G::box_centre, "gripper.box_centre"), "(3,) flange frame, m")
      .def_property("box_half_extents", [](const G& g) { return g.box_half_extents; }, vec(&G::box_half_extents, "gripper.box_half_extents"),
                    "(3,) half extents along flange x, y, z, m (>= 0)")
      .def_property("capsule_a", [](const G& g) { return g.capsule_a; }, vec(&G::capsule_a, "gripper.capsule_a"),
                    "(3,) capsule axis end, flange frame, m")
      .def_property("capsule_b", [](const G& g) { return g.capsule_b; }, vec(&G::capsule_b, "gripper.capsule_b"),
                    "(3,) capsule axis end, flange frame, m")
      .def_property("capsule_radius", [](const G& g) { return g.capsule_radius; }, scalar(&G::capsule_radius),
                    "m (>= 0)")
      .def_property("flange_radius", [](const G& g) { return g.flange_radius; }, scalar(&G::flange_radius),
                    "radius of the flange disc, m (>= 0)")
      .def(
          "lowest_height",
          [](const G& g, const py::object& T_base_flange, const py::object& plane) {
            const Eigen::Isometry3d T = rigid(T_base_flange, "T_base_flange");
            const Eigen::Vector4d table_plane = realArray(plane, "table_plane", 4, 0);
            const Eigen::Vector3d n = table_plane.head<3>();
            if (!table_plane.allFinite() || std::abs(n.norm() - 1) > 1e-6)
              throw std::invalid_argument("table_plane: (n, d) must be finite with a unit normal n");
            return std::min(g.bodyHeight(T, n, table_plane[3]), g.flangeHeight(T, n, table_plane[3]));
          },
          py::arg("T_base_flange"), py::arg("table_plane"),
          "Signed height (m) above the plane n.p + d = 0 (base frame) of the lowest point of the body and the "
          "flange disc with the flange at T_base_flange; negative: below the plane")
      .def("__repr__", [](const G& g) { return std::string("Gripper(shape='") + toString(g.shape) + "')"; });
}

void bindSettings(py::module_& m) {
  using S = GraspPlannerSettings;
  py::class_<S>(m, "GraspPlannerSettings", "Settings of plan_grasp (checked when planning, naming the field)")
      .def(py::init<>())
      .def_readwrite("table_clearance", &S::table_clearance,
                     "m, least height of the gripper body and flange above the table plane (default 0.005)")
      .def_readwrite("check_arm_points", &S::check_arm_points,
                     "also keep the arm's joint points (DH frame origins 2..5) above the table (default True)")
      .def_readwrite("min_wrist_angle", &S::min_wrist_angle,
                     "rad, least distance of the DH wrist angle theta5 from 0 or pi (default 0.05)")
      .def_readwrite("min_shoulder_distance", &S::min_shoulder_distance,
                     "m, least distance of the wrist centre (KUKA P_w, UR P_c) from the first axis (default 0.02)")
      .def_readwrite("min_elbow_angle", &S::min_elbow_angle,
                     "rad, least angle of the elbow away from stretched or folded (default 0.05)")
      .def_readwrite("approach_step", &S::approach_step, "m, spacing of the approach samples (default 0.005, > 0)")
      .def_readwrite("max_joint_step", &S::max_joint_step,
                     "rad, largest joint change between approach samples that counts as continuous (default 0.1)")
      .def_property(
          "joint_weights", [](const S& s) { return s.joint_weights; },
          [](S& s, const py::object& v) { s.joint_weights = realArray(v, "GraspPlannerSettings.joint_weights", 6, 0); }, "(6,) weights of the cost sum w_i |dq_i|, each in [0, 1e6] (default ones)")
      .def_readwrite("respect_limits", &S::respect_limits, "reject solutions outside the joint limits (default True)")
      .def_readwrite("continuous_symmetry_steps", &S::continuous_symmetry_steps,
                     "copies of a grasp on a part with a continuous symmetry (order 0), 1..3600 (default 36)");
}

void bindResults(py::module_& m) {
  using C = GraspCandidate;
  const auto mat = [](Eigen::Isometry3d C::*f) { return [f](const C& c) { return Matrix4((c.*f).matrix()); }; };
  py::class_<C>(m, "GraspCandidate", "One grasp x symmetry copy x IK configuration, with why it was rejected")
      .def_readonly("grasp_index", &C::grasp_index, "index into the grasp list")
      .def_readonly("symmetry_index", &C::symmetry_index, "symmetry copy k (PartSymmetry.transforms()[k])")
      .def_readonly("config_index", &C::config_index,
                    "IK configuration 4*(shoulder<0) + 2*(elbow<0) + (wrist<0) (scanalign.kinematics)")
      .def_property_readonly("T_base_tcp_pregrasp", mat(&C::T_base_tcp_pregrasp), "(4, 4) m")
      .def_property_readonly("T_base_tcp_grasp", mat(&C::T_base_tcp_grasp), "(4, 4) T_base_model T_model_grasp', m")
      .def_property_readonly("T_base_flange_pregrasp", mat(&C::T_base_flange_pregrasp), "(4, 4) m")
      .def_property_readonly("T_base_flange_grasp", mat(&C::T_base_flange_grasp),
                             "(4, 4) T_base_tcp_grasp inv(T_flange_tcp), m")
      .def_readonly("q_pregrasp", &C::q_pregrasp, "(6,) joints at the pre-grasp, rad (NaN if not reached)")
      .def_readonly("q_grasp", &C::q_grasp, "(6,) joints at the grasp, rad (NaN unless the approach was followed)")
      .def_property_readonly(
          "reason", [](const C& c) { return toString(c.reason); },
          "'ok', 'unreachable', 'outside_limits', 'near_singularity', 'below_table' or 'approach_branch_change'")
      .def_readonly("detail", &C::detail, "the reason in words, with the measured value")
      .def_readonly("cost", &C::cost, "weighted joint motion, rad (inf unless 'ok')")
      .def("__repr__", [](const C& c) {
        return "GraspCandidate(grasp_index=" + std::to_string(c.grasp_index) + ", symmetry_index=" +
               std::to_string(c.symmetry_index) + ", config_index=" + std::to_string(c.config_index) + ", reason='" +
               toString(c.reason) + "')";
      });
  py::class_<GraspPlan>(m, "GraspPlan", "The result of plan_grasp: the chosen candidate and every other one")
      .def_readonly("found", &GraspPlan::found, "True when some candidate is 'ok'")
      .def_readonly("message", &GraspPlan::message, "the choice, or why nothing was found")
      .def_readonly("chosen", &GraspPlan::chosen, "index into candidates, -1 when none")
      .def_readonly("candidates", &GraspPlan::candidates, "list of GraspCandidate")
      .def_property_readonly(
          "approach_q",
          [](const GraspPlan& p) {
            py::array_t<double> a({static_cast<py::ssize_t>(p.approach_q.size()), py::ssize_t{6}});
            for (std::size_t i = 0; i < p.approach_q.size(); ++i)
              std::copy(p.approach_q[i].data(), p.approach_q[i].data() + 6, a.mutable_data() + 6 * i);
            return a;
          },
          "(K, 6) joints at every approach sample of the chosen candidate, pre-grasp first, rad")
      .def_property_readonly(
          "best",
          [](const GraspPlan& p) -> py::object {
            return p.found ? py::cast(p.candidates[static_cast<std::size_t>(p.chosen)]) : py::none();
          },
          "the chosen GraspCandidate, or None")
      .def("__bool__", [](const GraspPlan& p) { return p.found; })
      .def("__repr__", [](const GraspPlan& p) {
        return std::string("GraspPlan(found=") + (p.found ? "True" : "False") + ", message='" + p.message + "')";
      });
}

void pickleGrasp(py::module_& m) {
  pickleFields(m, "PartSymmetry", field("axis", &PartSymmetry::axis), field("point", &PartSymmetry::point),
               field("order", &PartSymmetry::order));
  pickleFields(m, "Grasp", field("name", &Grasp::name), field("T_model_grasp", &Grasp::T_model_grasp),
               field("approach", &Grasp::approach), field("pre_grasp_distance", &Grasp::pre_grasp_distance));
  using G = Gripper;
  pickleFields(m, "Gripper", field("T_flange_tcp", &G::T_flange_tcp), namedEnum("shape", &G::shape, 2),
               field("capsule_a", &G::capsule_a), field("capsule_b", &G::capsule_b),
               field("capsule_radius", &G::capsule_radius), field("box_centre", &G::box_centre),
               field("box_half_extents", &G::box_half_extents), field("flange_radius", &G::flange_radius));
  using S = GraspPlannerSettings;
  pickleFields(m, "GraspPlannerSettings", field("table_clearance", &S::table_clearance),
               field("check_arm_points", &S::check_arm_points), field("min_wrist_angle", &S::min_wrist_angle),
               field("min_shoulder_distance", &S::min_shoulder_distance),
               field("min_elbow_angle", &S::min_elbow_angle), field("approach_step", &S::approach_step),
               field("max_joint_step", &S::max_joint_step), field("joint_weights", &S::joint_weights),
               field("respect_limits", &S::respect_limits),
               field("continuous_symmetry_steps", &S::continuous_symmetry_steps));
  using C = GraspCandidate;
  pickleFields(m, "GraspCandidate", field("grasp_index", &C::grasp_index),
               field("symmetry_index", &C::symmetry_index), field("config_index", &C::config_index),
               field("T_base_tcp_pregrasp", &C::T_base_tcp_pregrasp), field("T_base_tcp_grasp", &C::T_base_tcp_grasp),
               field("T_base_flange_pregrasp", &C::T_base_flange_pregrasp),
               field("T_base_flange_grasp", &C::T_base_flange_grasp), field("q_pregrasp", &C::q_pregrasp),
               field("q_grasp", &C::q_grasp), namedEnum("reason", &C::reason, 6), field("detail", &C::detail),
               field("cost", &C::cost));
  // chosen after candidates: the chosen-candidate property indexes them unchecked.
  pickleFields(m, "GraspPlan", field("found", &GraspPlan::found), field("message", &GraspPlan::message),
               field("candidates", &GraspPlan::candidates), field("approach_q", &GraspPlan::approach_q),
               field<GraspPlan>(
                   "chosen", [](const GraspPlan& p) { return p.chosen; },
                   [](GraspPlan& p, int v) {
                     if (v < -1 || v >= static_cast<int>(p.candidates.size()) || (p.found && v < 0))
                       throw py::value_error("GraspPlan: pickled state 'chosen' is not an index into candidates");
                     p.chosen = v;
                   }));
}

}  // namespace

void defineGrasp(py::module_& m) {
  bindSymmetry(m);
  bindGrasp(m);
  bindGripper(m);
  bindSettings(m);
  bindResults(m);
  pickleGrasp(m);
  m.def(
      "plan_grasp",
      [](const Robot& robot, const py::object& T_base_model, const std::vector<Grasp>& grasps,
         const PartSymmetry& symmetry, const Gripper& gripper, const py::object& plane, const py::object& q,
         const GraspPlannerSettings& settings) {
        const Eigen::Isometry3d T = rigid(T_base_model, "T_base_model");
        const Eigen::Vector4d table_plane = realArray(plane, "table_plane", 4, 0);
        const Vector6d q_current = realArray(q, "q_current", 6, 0);
        py::gil_scoped_release release;
        return planGrasp(robot, T, grasps, symmetry, gripper, table_plane, q_current, settings);
      },
      py::arg("robot"), py::arg("T_base_model"), py::arg("grasps"), py::arg("symmetry"), py::arg("gripper"),
      py::arg("table_plane"), py::arg("q_current"), py::arg("settings"),
      "Joint targets to pick a part (see docs/api/grasp.md): every grasp x symmetry copy x IK configuration is "
      "solved at the pre-grasp and checked (joint limits, singularity margins, table, a straight approach without "
      "a branch change); the least weighted joint motion from q_current (rad) wins. T_base_model (4, 4, m): the "
      "part in the cell; table_plane (4,): unit normal n (up) and d, n.p + d = 0 in the base frame. The robot's "
      "tool is replaced by gripper.T_flange_tcp. ValueError naming the argument for bad input.");
}

}  // namespace scanalign::python
