// Bindings of scanalign/kinematics (DH robots, forward kinematics, CGA inverse kinematics).
// The documented API is python/scanalign/kinematics.py, which validates shapes, dtypes and
// finiteness first; the checks here are the last line of defence.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "scanalign/kinematics/ik.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace py = pybind11;

namespace scanalign::python {

namespace {
using namespace scanalign::kinematics;
using RowArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

Eigen::Isometry3d toIsometry(const Eigen::Matrix4d& m) {
  Eigen::Isometry3d T;
  T.matrix() = m;
  return T;
}

IKOptions makeOptions(const Vector6d& q_free, double reach_tolerance, double singular_tolerance, bool respect_limits) {
  IKOptions o;
  o.q_free = q_free;
  o.reach_tolerance = reach_tolerance;
  o.singular_tolerance = singular_tolerance;
  o.respect_limits = respect_limits;
  return o;
}

void checkPoses(const RowArray& poses) {
  if (poses.ndim() != 3 || poses.shape(1) != 4 || poses.shape(2) != 4)
    throw py::value_error("poses: expected an (N, 4, 4) array");
}

py::dict resultToDict(const IKResult& r) {
  py::array_t<double> q({py::ssize_t{8}, py::ssize_t{6}});
  py::array_t<std::uint8_t> status(8), singular(8), step(8);
  py::array_t<std::int8_t> config({py::ssize_t{8}, py::ssize_t{3}});
  auto qa = q.mutable_unchecked<2>();
  auto ca = config.mutable_unchecked<2>();
  for (int k = 0; k < 8; ++k) {
    const IKSolution& s = r.solutions[static_cast<std::size_t>(k)];
    for (int j = 0; j < 6; ++j) qa(k, j) = s.q[j];
    ca(k, 0) = s.config.shoulder, ca(k, 1) = s.config.elbow, ca(k, 2) = s.config.wrist;
    status.mutable_data()[k] = static_cast<std::uint8_t>(s.status);
    singular.mutable_data()[k] = s.singular;
    step.mutable_data()[k] = static_cast<std::uint8_t>(s.unreachable_step);
  }
  py::dict d;
  d["q"] = q, d["status"] = status, d["singular"] = singular, d["config"] = config, d["step"] = step;
  d["overall"] = static_cast<int>(r.status);
  return d;
}

py::dict solutionToDict(const IKSolution& s) {
  py::dict d;
  d["q"] = Vector6d(s.q);
  d["status"] = static_cast<int>(s.status);
  d["singular"] = static_cast<int>(s.singular);
  d["config"] = py::make_tuple(static_cast<int>(s.config.shoulder), static_cast<int>(s.config.elbow),
                               static_cast<int>(s.config.wrist));
  d["step"] = static_cast<int>(s.unreachable_step);
  return d;
}
}  // namespace

void defineKinematics(py::module_& m) {
  // The C++ defaults, so that the Python layer has one source of truth.
  m.attr("DEFAULT_REACH_TOLERANCE") = IKOptions{}.reach_tolerance;
  m.attr("DEFAULT_SINGULAR_TOLERANCE") = IKOptions{}.singular_tolerance;
  py::enum_<ArmGeometry>(m, "ArmGeometry")
      .value("Unsupported", ArmGeometry::Unsupported)
      .value("SphericalWrist", ArmGeometry::SphericalWrist)
      .value("UniversalRobots", ArmGeometry::UniversalRobots);

  py::class_<Robot>(m, "Robot")
      .def(py::init<>())
      .def_readwrite("name", &Robot::name)
      .def_property(
          "dh",
          [](const Robot& r) {
            // (6, 4): a, alpha, d, theta_offset
            Eigen::Matrix<double, 6, 4, Eigen::RowMajor> t;
            for (int i = 0; i < 6; ++i) {
              const DHJoint& j = r.joints[static_cast<std::size_t>(i)];
              t.row(i) << j.a, j.alpha, j.d, j.theta_offset;
            }
            return t;
          },
          [](Robot& r, const Eigen::Matrix<double, 6, 4, Eigen::RowMajor>& t) {
            for (int i = 0; i < 6; ++i) {
              DHJoint& j = r.joints[static_cast<std::size_t>(i)];
              j.a = t(i, 0), j.alpha = t(i, 1), j.d = t(i, 2), j.theta_offset = t(i, 3);
            }
          })
      .def_property(
          "limits",
          [](const Robot& r) {
            Eigen::Matrix<double, 6, 2, Eigen::RowMajor> t;
            for (int i = 0; i < 6; ++i) t.row(i) << r.joints[i].q_min, r.joints[i].q_max;
            return t;
          },
          [](Robot& r, const Eigen::Matrix<double, 6, 2, Eigen::RowMajor>& t) {
            for (int i = 0; i < 6; ++i) r.joints[i].q_min = t(i, 0), r.joints[i].q_max = t(i, 1);
          })
      .def_property(
          "T_base_dh0", [](const Robot& r) { return Eigen::Matrix4d(r.T_base_dh0.matrix()); },
          [](Robot& r, const Eigen::Matrix4d& m) { r.T_base_dh0 = toIsometry(m); })
      .def_property(
          "T_flange_tool", [](const Robot& r) { return Eigen::Matrix4d(r.T_flange_tool.matrix()); },
          [](Robot& r, const Eigen::Matrix4d& m) { r.T_flange_tool = toIsometry(m); })
      .def("geometry", &Robot::geometry)
      .def("forward",
           [](const Robot& r, const Vector6d& q) {
             if (!q.allFinite()) throw py::value_error("q: non-finite joint values");
             return Eigen::Matrix4d(r.forward(q).matrix());
           })
      .def("forward_flange",
           [](const Robot& r, const Vector6d& q) { return Eigen::Matrix4d(r.forwardFlange(q).matrix()); })
      .def("joint_frames",
           [](const Robot& r, const Vector6d& q) {
             const auto F = r.jointFrames(q);
             py::array_t<double> out({py::ssize_t{7}, py::ssize_t{4}, py::ssize_t{4}});
             auto o = out.mutable_unchecked<3>();
             for (int i = 0; i < 7; ++i)
               for (int a = 0; a < 4; ++a)
                 for (int b = 0; b < 4; ++b) o(i, a, b) = F[static_cast<std::size_t>(i)].matrix()(a, b);
             return out;
           })
      .def(
          "forward_batch",
          [](const Robot& r, const RowArray& q, int num_threads) {
            if (q.ndim() != 2 || q.shape(1) != 6) throw py::value_error("q: expected an (N, 6) array");
            const py::ssize_t n = q.shape(0);
            py::array_t<double> out({n, py::ssize_t{4}, py::ssize_t{4}});
            double* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              r.forwardBatch(q.data(), static_cast<std::size_t>(n), o, num_threads);
            }
            return out;
          },
          py::arg("q"), py::arg("num_threads") = 0)
      .def_static("by_name", &Robot::byName);

  m.def(
      "ik",
      [](const Robot& robot, const Eigen::Matrix4d& T, const Vector6d& q_free, double reach_tolerance,
         double singular_tolerance, bool respect_limits) {
        IKResult r;
        {
          py::gil_scoped_release release;
          r = ik(robot, toIsometry(T), makeOptions(q_free, reach_tolerance, singular_tolerance, respect_limits));
        }
        return resultToDict(r);
      },
      py::arg("robot"), py::arg("T"), py::arg("q_free"), py::arg("reach_tolerance"), py::arg("singular_tolerance"),
      py::arg("respect_limits"));

  // Single-pose IK for the Python hot path: a tuple (q (8, 6), codes (8, 3) uint8 with
  // status, singular bits, unreachable step; overall status). The configurations are fixed
  // by index (CONFIGS), so they are not returned.
  m.def(
      "ik_tuple",
      [](const Robot& robot, const Eigen::Matrix4d& T, const Vector6d& q_free, double reach_tolerance,
         double singular_tolerance, bool respect_limits) {
        const IKResult r = ik(robot, toIsometry(T), makeOptions(q_free, reach_tolerance, singular_tolerance, respect_limits));
        py::array_t<double> q({py::ssize_t{8}, py::ssize_t{6}});
        py::array_t<std::uint8_t> codes({py::ssize_t{8}, py::ssize_t{3}});
        double* qa = q.mutable_data();
        std::uint8_t* ca = codes.mutable_data();
        for (int k = 0; k < 8; ++k) {
          const IKSolution& s = r.solutions[static_cast<std::size_t>(k)];
          for (int j = 0; j < 6; ++j) qa[6 * k + j] = s.q[j];
          ca[3 * k] = static_cast<std::uint8_t>(s.status);
          ca[3 * k + 1] = s.singular;
          ca[3 * k + 2] = static_cast<std::uint8_t>(s.unreachable_step);
        }
        return py::make_tuple(q, codes, static_cast<int>(r.status));
      });

  m.def(
      "ik_batch",
      [](const Robot& robot, const RowArray& poses, const Vector6d& q_free, double reach_tolerance,
         double singular_tolerance, bool respect_limits, int num_threads) {
        checkPoses(poses);
        const py::ssize_t n = poses.shape(0);
        std::vector<IKResult> res(static_cast<std::size_t>(n));
        {
          py::gil_scoped_release release;
          ikBatch(robot, poses.data(), static_cast<std::size_t>(n), res.data(),
                  makeOptions(q_free, reach_tolerance, singular_tolerance, respect_limits), num_threads);
        }
        py::array_t<double> q({n, py::ssize_t{8}, py::ssize_t{6}});
        py::array_t<std::uint8_t> status({n, py::ssize_t{8}}), singular({n, py::ssize_t{8}}), step({n, py::ssize_t{8}});
        auto qa = q.mutable_unchecked<3>();
        auto sa = status.mutable_unchecked<2>();
        auto ga = singular.mutable_unchecked<2>();
        auto pa = step.mutable_unchecked<2>();
        for (py::ssize_t i = 0; i < n; ++i)
          for (int k = 0; k < 8; ++k) {
            const IKSolution& s = res[static_cast<std::size_t>(i)].solutions[static_cast<std::size_t>(k)];
            for (int j = 0; j < 6; ++j) qa(i, k, j) = s.q[j];
            sa(i, k) = static_cast<std::uint8_t>(s.status);
            ga(i, k) = s.singular;
            pa(i, k) = static_cast<std::uint8_t>(s.unreachable_step);
          }
        py::dict d;
        d["q"] = q, d["status"] = status, d["singular"] = singular, d["step"] = step;
        return d;
      },
      py::arg("robot"), py::arg("poses"), py::arg("q_free"), py::arg("reach_tolerance"),
      py::arg("singular_tolerance"), py::arg("respect_limits"), py::arg("num_threads"));

  m.def(
      "ik_closest",
      [](const Robot& robot, const Eigen::Matrix4d& T, const Vector6d& q_current, const Vector6d& weights,
         double reach_tolerance, double singular_tolerance, bool respect_limits) {
        ClosestOptions c;
        c.weights = weights;
        IKSolution s;
        {
          py::gil_scoped_release release;
          s = ikClosest(robot, toIsometry(T), q_current,
                        makeOptions(q_current, reach_tolerance, singular_tolerance, respect_limits), c);
        }
        return solutionToDict(s);
      },
      py::arg("robot"), py::arg("T"), py::arg("q_current"), py::arg("weights"), py::arg("reach_tolerance"),
      py::arg("singular_tolerance"), py::arg("respect_limits"));

  m.def(
      "ik_trajectory",
      [](const Robot& robot, const RowArray& poses, const Vector6d& q_start, const Vector6d& weights,
         double reach_tolerance, double singular_tolerance, bool respect_limits) {
        checkPoses(poses);
        const py::ssize_t n = poses.shape(0);
        py::array_t<double> q({n, py::ssize_t{6}});
        std::vector<IKStatus> st(static_cast<std::size_t>(n));
        ClosestOptions c;
        c.weights = weights;
        {
          py::gil_scoped_release release;
          ikTrajectory(robot, poses.data(), static_cast<std::size_t>(n), q_start, q.mutable_data(), st.data(),
                       makeOptions(q_start, reach_tolerance, singular_tolerance, respect_limits), c);
        }
        py::array_t<std::uint8_t> status(n);
        for (py::ssize_t i = 0; i < n; ++i) status.mutable_data()[i] = static_cast<std::uint8_t>(st[static_cast<std::size_t>(i)]);
        py::dict d;
        d["q"] = q, d["status"] = status;
        return d;
      },
      py::arg("robot"), py::arg("poses"), py::arg("q_start"), py::arg("weights"), py::arg("reach_tolerance"),
      py::arg("singular_tolerance"), py::arg("respect_limits"));

  m.def(
      "ik_construction",
      [](const Robot& robot, const Eigen::Matrix4d& T, int shoulder, int elbow, int wrist, const Vector6d& q_free,
         double reach_tolerance, double singular_tolerance) {
        IKConfig c{static_cast<std::int8_t>(shoulder < 0 ? -1 : 1), static_cast<std::int8_t>(elbow < 0 ? -1 : 1),
                   static_cast<std::int8_t>(wrist < 0 ? -1 : 1)};
        const IKConstruction k =
            ikConstruction(robot, toIsometry(T), c, makeOptions(q_free, reach_tolerance, singular_tolerance, true));
        py::dict pts;
        for (int i = 0; i < k.num_points; ++i)
          pts[py::str(k.names[static_cast<std::size_t>(i)])] = Eigen::Vector3d(k.points[static_cast<std::size_t>(i)]);
        py::dict d;
        d["points"] = pts;
        d["shoulder_discriminant"] = k.shoulder_discriminant;
        d["elbow_discriminant"] = k.elbow_discriminant;
        d["solution"] = solutionToDict(k.solution);
        return d;
      },
      py::arg("robot"), py::arg("T"), py::arg("shoulder"), py::arg("elbow"), py::arg("wrist"), py::arg("q_free"),
      py::arg("reach_tolerance"), py::arg("singular_tolerance"));
}

}  // namespace scanalign::python
