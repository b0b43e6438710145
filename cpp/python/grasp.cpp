// Bindings of scanalign/grasp: grasps on a CAD part, the gripper, the planner settings and
// planGrasp, each struct through its field table (fields.hpp). Every argument is checked in C++
// (std::invalid_argument -> ValueError naming the field); python/scanalign/grasp.py re-exports
// these classes (and PartSymmetry, bound in _core.pose) and reads grasp files.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <string>
#include <vector>

#include "field_access.hpp"
#include "fields.hpp"
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
  const auto f = checkedAs<double>(x, name, kReals);
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

// ok, unreachable, outside_limits, near_singularity, below_table, approach_branch_change
constexpr int kReasonCount = 6;

void bindGrasp(py::module_& m) {
  using G = Grasp;
  fieldsOf(py::class_<G>(m, "Grasp",
                         "A grasp on a CAD part: T_model_grasp (TCP pose at the grasp, model frame, m), the approach "
                         "direction (unit, grasp/TCP frame: where the TCP moves to reach the grasp) and the pre-grasp "
                         "distance (m): the pre-grasp is the grasp moved back by that distance against the approach. "
                         "Every field is checked with the others (ValueError naming it, the old value kept).")
               .def(py::init([](const std::string& name, const py::object& T_model_grasp, const py::object& approach,
                                double pre_grasp_distance) {
                      G g{name, Eigen::Isometry3d::Identity(), Eigen::Vector3d::UnitZ(), pre_grasp_distance};
                      if (!T_model_grasp.is_none()) g.T_model_grasp = rigid(T_model_grasp, "T_model_grasp");
                      if (!approach.is_none()) g.approach = vec3(approach, "approach");
                      g.validate("grasp '" + name + "'");
                      return g;
                    }),
                    py::arg("name") = "", py::arg("T_model_grasp") = py::none(), py::arg("approach") = py::none(),
                    py::arg("pre_grasp_distance") = 0.08,
                    "T_model_grasp (4, 4), default identity; approach (3,), default (0, 0, 1)")
               .def(
                   "pre_grasp", [](const G& g) { return Matrix4(g.preGrasp().matrix()); },
                   "T_model_pregrasp (4, 4): the grasp pose moved back by pre_grasp_distance against the approach, m")
               .def("__repr__", [](const G& g) {
                 return "Grasp(name='" + g.name + "', pre_grasp_distance=" +
                        std::string(py::repr(py::float_(g.pre_grasp_distance))) + ")";
               }))
      .field("name", &G::name, "", "name, for messages and files")
      .field("T_model_grasp", member(&G::T_model_grasp), validating(&G::T_model_grasp), "m",
             "(4, 4) TCP pose at the grasp in the model frame")
      .field("approach", member(&G::approach), validating(&G::approach), "",
             "(3,) unit approach direction in the grasp (TCP) frame; +z is the tool axis")
      .field("pre_grasp_distance", member(&G::pre_grasp_distance), validating(&G::pre_grasp_distance), "m",
             "from the pre-grasp to the grasp along the approach (>= 0)")
      .result();
}

void bindGripper(py::module_& m) {
  using G = Gripper;
  fieldsOf(py::class_<G>(m, "Gripper",
                         "The tool on the flange: T_flange_tcp and a collision body (a box or a capsule, flange frame, "
                         "m) that the planner keeps above the table, plus the flange disc of flange_radius. Every "
                         "field is checked with the others (ValueError naming it, the old value kept).")
               .def(py::init([](const py::object& T_flange_tcp, const std::string& shape, const py::object& box_centre,
                                const py::object& box_half_extents, const py::object& capsule_a,
                                const py::object& capsule_b, double capsule_radius, double flange_radius) {
                      G g;
                      g.T_flange_tcp = rigid(T_flange_tcp, "gripper.T_flange_tcp");
                      g.shape = shapeOf(shape);
                      g.box_centre = vec3(box_centre, "gripper.box_centre");
                      g.box_half_extents = vec3(box_half_extents, "gripper.box_half_extents");
                      g.capsule_a = vec3(capsule_a, "gripper.capsule_a");
                      g.capsule_b = vec3(capsule_b, "gripper.capsule_b");
                      g.capsule_radius = capsule_radius;
                      g.flange_radius = flange_radius;
                      g.validate();
                      return g;
                    }),
                    py::arg("T_flange_tcp") =
                        std::vector<std::vector<double>>{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}},
                    py::arg("shape") = "box", py::arg("box_centre") = std::vector<double>{0, 0, 0},
                    py::arg("box_half_extents") = std::vector<double>{0, 0, 0},
                    py::arg("capsule_a") = std::vector<double>{0, 0, 0},
                    py::arg("capsule_b") = std::vector<double>{0, 0, 0}, py::arg("capsule_radius") = 0.0,
                    py::arg("flange_radius") = 0.0315)
               .def_static("parallel_jaw", &G::parallelJaw,
                           "A parallel-jaw gripper like the Robotiq 2F-85: TCP 0.15 m along the flange z; body a box "
                           "0.08 x 0.14 x 0.15 m from the flange face to the TCP; flange radius 0.0315 m")
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
                   "Signed height (m) above the plane n.p + d = 0 (base frame) of the lowest point of the body and "
                   "the flange disc with the flange at T_base_flange; negative: below the plane")
               .def("__repr__", [](const G& g) { return std::string("Gripper(shape='") + toString(g.shape) + "')"; }))
      .field("T_flange_tcp", member(&G::T_flange_tcp), validating(&G::T_flange_tcp), "m", "(4, 4) TCP -> flange")
      .name("shape", &G::shape, 2, "", "'box' or 'capsule': which collision body is used")
      .field("capsule_a", member(&G::capsule_a), validating(&G::capsule_a), "m", "(3,) capsule axis end, flange frame")
      .field("capsule_b", member(&G::capsule_b), validating(&G::capsule_b), "m", "(3,) capsule axis end, flange frame")
      .field("capsule_radius", member(&G::capsule_radius), validating(&G::capsule_radius), "m", "capsule radius (>= 0)")
      .field("box_centre", member(&G::box_centre), validating(&G::box_centre), "m", "(3,) box centre, flange frame")
      .field("box_half_extents", member(&G::box_half_extents), validating(&G::box_half_extents), "m",
             "(3,) half extents along flange x, y, z (>= 0)")
      .field("flange_radius", member(&G::flange_radius), validating(&G::flange_radius), "m",
             "radius of the flange disc, kept above the table too (>= 0)")
      .result();
}

void bindSettings(py::module_& m) {
  using S = GraspPlannerSettings;
  fieldsOf(py::class_<S>(m, "GraspPlannerSettings", "Settings of plan_grasp (checked when planning, naming the field)"))
      .field("table_clearance", &S::table_clearance, "m",
             "least height of the gripper body and flange above the table plane")
      .field("check_arm_points", &S::check_arm_points, "",
             "also keep the arm's joint points (DH frame origins 2..5) above the table")
      .field("min_wrist_angle", &S::min_wrist_angle, "rad", "least distance of the DH wrist angle theta5 from 0 or pi")
      .field("min_shoulder_distance", &S::min_shoulder_distance, "m",
             "least distance of the wrist centre (KUKA P_w, UR P_c) from the first axis")
      .field("min_elbow_angle", &S::min_elbow_angle, "rad", "least angle of the elbow away from stretched or folded")
      .field("approach_step", &S::approach_step, "m", "spacing of the approach samples (> 0)")
      .field("max_joint_step", &S::max_joint_step, "rad",
             "largest joint change between approach samples that counts as continuous")
      .field(
          "joint_weights", member(&S::joint_weights),
          [](S& s, py::handle v) {
            s.joint_weights =
                realArray(py::reinterpret_borrow<py::object>(v), "GraspPlannerSettings.joint_weights", 6, 0);
          },
          "", "(6,) weights of the cost sum w_i |dq_i|, each in [0, 1e6]")
      .field("respect_limits", &S::respect_limits, "", "reject solutions outside the joint limits")
      .field("continuous_symmetry_steps", &S::continuous_symmetry_steps, "",
             "copies of a grasp on a part with a continuous symmetry (order 0), 1..3600")
      .settings();
}

void bindResults(py::module_& m) {
  using C = GraspCandidate;
  fieldsOf(py::class_<C>(m, "GraspCandidate", "One grasp x symmetry copy x IK configuration, with why it was rejected")
               .def("__repr__", [](const C& c) {
                 return "GraspCandidate(grasp_index=" + std::to_string(c.grasp_index) + ", symmetry_index=" +
                        std::to_string(c.symmetry_index) + ", config_index=" + std::to_string(c.config_index) +
                        ", reason='" + toString(c.reason) + "')";
               }))
      .output("grasp_index", &C::grasp_index, "", "index into the grasp list")
      .output("symmetry_index", &C::symmetry_index, "", "symmetry copy k (PartSymmetry.transforms()[k])")
      .output("config_index", &C::config_index, "",
              "IK configuration 4*(shoulder<0) + 2*(elbow<0) + (wrist<0) (scanalign.kinematics)")
      .output("T_base_tcp_pregrasp", &C::T_base_tcp_pregrasp, "m", "(4, 4) the TCP at the pre-grasp")
      .output("T_base_tcp_grasp", &C::T_base_tcp_grasp, "m", "(4, 4) T_base_model T_model_grasp'")
      .output("T_base_flange_pregrasp", &C::T_base_flange_pregrasp, "m", "(4, 4) the flange at the pre-grasp")
      .output("T_base_flange_grasp", &C::T_base_flange_grasp, "m", "(4, 4) T_base_tcp_grasp inv(T_flange_tcp)")
      .output("q_pregrasp", &C::q_pregrasp, "rad", "(6,) joints at the pre-grasp (NaN if not reached)")
      .output("q_grasp", &C::q_grasp, "rad", "(6,) joints at the grasp (NaN unless the approach was followed)")
      .name("reason", &C::reason, kReasonCount, "",
            "'ok', 'unreachable', 'outside_limits', 'near_singularity', 'below_table' or 'approach_branch_change'",
            false)
      .output("detail", &C::detail, "", "the reason in words, with the measured value")
      .output("cost", &C::cost, "rad", "weighted joint motion (inf unless 'ok')")
      .result();
  using P = GraspPlanResult;
  // chosen after candidates: loading checks it against them (the best property indexes them).
  fieldsOf(py::class_<P>(m, "GraspPlanResult", "The result of plan_grasp: the chosen candidate and every other one")
               .def("__bool__", [](const P& p) { return p.found; })
               .def("__repr__", [](const P& p) {
                 return std::string("GraspPlanResult(found=") + (p.found ? "True" : "False") + ", message='" +
                        p.message + "')";
               }))
      .output("found", &P::found, "", "True when some candidate is 'ok'")
      .output("message", &P::message, "", "the choice, or why nothing was found")
      .output("candidates", &P::candidates, "", "list of GraspCandidate")
      .output("approach_q", &P::approach_q, "rad",
              "(K, 6) joints at every approach sample of the chosen candidate, pre-grasp first")
      .field(
          "chosen", member(&P::chosen),
          [](P& p, int v) {
            if (v < -1 || v >= static_cast<int>(p.candidates.size()) || (p.found && v < 0))
              throw py::value_error("GraspPlanResult: pickled state 'chosen' is not an index into candidates");
            p.chosen = v;
          },
          "", "index into candidates, -1 when none", false)
      .derived(
          "best",
          [](const P& p) -> py::object {
            return p.found ? py::cast(p.candidates[static_cast<std::size_t>(p.chosen)]) : py::none();
          },
          "", "the chosen GraspCandidate, or None")
      .result();
}

}  // namespace

void bindPickSettings(py::module_& m);  // grasp_pick_settings.cpp
void bindViewPlanner(py::module_& m);   // grasp_view_planner.cpp
void bindAssemblySettings(py::module_& m);  // grasp_assembly_settings.cpp

void defineGrasp(py::module_& m) {
  bindGrasp(m);
  bindGripper(m);
  bindSettings(m);
  bindResults(m);
  bindPickSettings(m);
  bindViewPlanner(m);
  bindAssemblySettings(m);
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
