// 03: analytic inverse kinematics from a robot controller, with the PCL-free core only.
//
// For a UR5 and a KUKA KR6 R900 sixx: all IK solutions of a target tool pose with their
// configuration labels, then a straight-line Cartesian move turned into a joint trajectory
// (each step takes the solution closest to the previous one), checked by forward
// kinematics. Exits non-zero when any returned solution misses its pose by more than 1e-9.
#include <cmath>
#include <cstdio>
#include <vector>

#include <Eigen/Geometry>

#include <scanalign/kinematics/ik.hpp>
#include <scanalign/kinematics/robot.hpp>

using namespace scanalign;

namespace {

double poseError(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  return (A.matrix() - B.matrix()).cwiseAbs().maxCoeff();
}

int run(const Robot& robot, const Vector6d& q_home) {
  int failures = 0;
  // Target: the home pose moved 5 cm along the base x axis (metres, tool -> base).
  Eigen::Isometry3d T_base_tool = robot.forward(q_home);
  T_base_tool.translation().x() += 0.05;

  const IKResult all = ik(robot, T_base_tool);
  std::printf("%s (%s): %d solutions inside the joint limits\n", robot.name.c_str(), toString(robot.geometry()),
              all.count());
  for (const IKSolution& s : all.solutions) {
    std::printf("  shoulder %+d elbow %+d wrist %+d  %-14s", s.config.shoulder, s.config.elbow, s.config.wrist,
                toString(s.status));
    if (s.ok()) {
      const double err = poseError(robot.forward(s.q), T_base_tool);
      failures += err > 1e-9;
      std::printf(" q = [%7.3f %7.3f %7.3f %7.3f %7.3f %7.3f] rad, |FK(q) - T| = %.1e", s.q[0], s.q[1], s.q[2],
                  s.q[3], s.q[4], s.q[5], err);
    }
    std::printf("\n");
  }

  // A 20 cm straight line in 41 steps: poses in, joints out.
  const int n = 41;
  std::vector<double> poses(16 * n), q(6 * n);
  std::vector<IKStatus> status(n);
  for (int i = 0; i < n; ++i) {
    Eigen::Isometry3d T = robot.forward(q_home);
    T.translation() += Eigen::Vector3d(0.0, 0.2 * i / (n - 1) - 0.1, 0.0);
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(poses.data() + 16 * i) = T.matrix();
  }
  const std::size_t good = ikTrajectory(robot, poses.data(), n, q_home, q.data(), status.data());
  double max_step = 0, max_err = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Map<const Vector6d> qi(q.data() + 6 * i);
    if (status[i] != IKStatus::Ok) continue;
    Eigen::Isometry3d T;
    T.matrix() = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(poses.data() + 16 * i);
    max_err = std::max(max_err, poseError(robot.forward(qi), T));
    if (i > 0) max_step = std::max(max_step, (qi - Eigen::Map<const Vector6d>(q.data() + 6 * (i - 1))).cwiseAbs().maxCoeff());
  }
  std::printf("  line of %d poses: %zu solved, largest joint step %.4f rad, largest |FK(q) - T| %.1e\n\n", n, good,
              max_step, max_err);
  failures += good != static_cast<std::size_t>(n) || max_err > 1e-9 || max_step > 0.1;
  return failures;
}

}  // namespace

int main() {
  int failures = 0;
  failures += run(Robot::ur5(), (Vector6d() << 0.0, -1.9, 1.9, -1.57, -1.57, 0.0).finished());
  failures += run(Robot::kukaKR6R900sixx(), (Vector6d() << 0.0, -1.57, 1.57, 0.0, 0.6, 0.0).finished());
  if (failures) std::printf("FAILED: %d checks\n", failures);
  return failures ? 1 : 0;
}
