// Timing of the CGA inverse kinematics in C++ (scanalign/kinematics/ik.hpp), issue target:
// all solutions of one pose in under 2 µs on one thread.
//
// For the KUKA KR6 R900 sixx and the UR5: n random joint vectors (uniform inside the joint
// limits, limits wider than ±π clamped to ±π, fixed seed), their FK poses (reachable by
// construction), then, each timed as the best of `repeats` passes over all poses:
//   forward    Robot::forward per configuration, one thread
//   ik         all (up to 8) solutions per pose, one thread
//   ikBatch    the same through ikBatch with all threads (OpenMP)
//   ikClosest  the solution closest to the generating joints plus 0.05 rad noise, one thread
// Every pass accumulates a checksum of its results that is printed, so the optimiser cannot
// drop the work. Correctness is checked on the side (not timed): the largest FK residual of
// any returned solution, and how often the generating joints are among the Ok solutions.
//
//   build/py/cpp/tests/bench_ik [--n 200000] [--repeats 5] [--threads 0]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "scanalign/kinematics/ik.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace {

using namespace scanalign;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

double poseError(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  // translation in metres + rotation matrix entries (dimensionless), max norm
  return (A.matrix() - B.matrix()).cwiseAbs().maxCoeff();
}

double wrapPi(double x) { return std::remainder(x, 2 * M_PI); }

struct Row {
  std::string what;
  double seconds_per_item;
  double checksum;
};

void printRow(const std::string& robot, const Row& r) {
  std::printf("| %-14s | %-11s | %9.3f | %12.0f | %+.6e |\n", robot.c_str(), r.what.c_str(),
              r.seconds_per_item * 1e6, 1.0 / r.seconds_per_item, r.checksum);
}

template <class F>
double best(int repeats, F&& pass) {
  double t = 1e300;
  for (int k = 0; k < repeats; ++k) {
    const auto a = Clock::now();
    pass();
    t = std::min(t, seconds(a, Clock::now()));
  }
  return t;
}

void benchRobot(const Robot& robot, std::size_t n, int repeats, int threads, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Vector6d> q(n), q_near(n);
  std::normal_distribution<double> noise(0.0, 0.05);
  for (std::size_t i = 0; i < n; ++i) {
    for (int j = 0; j < 6; ++j) {
      const auto& J = robot.joints[j];
      const double lo = std::max(J.q_min, -M_PI), hi = std::min(J.q_max, M_PI);
      q[i][j] = std::uniform_real_distribution<double>(lo, hi)(rng);
      q_near[i][j] = q[i][j] + noise(rng);
    }
  }
  std::vector<Eigen::Isometry3d> T(n);
  std::vector<double> poses(16 * n);
  for (std::size_t i = 0; i < n; ++i) {
    T[i] = robot.forward(q[i]);
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(poses.data() + 16 * i) = T[i].matrix();
  }

  std::vector<Row> rows;

  // forward
  {
    double sum = 0;
    const double t = best(repeats, [&] {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Isometry3d X = robot.forward(q[i]);
        s += X(0, 3) + X(1, 3) + X(2, 3) + X(0, 0);
      }
      sum = s;
    });
    rows.push_back({"forward", t / n, sum});
  }
  // ik, all solutions, one thread
  std::vector<IKResult> results(n);
  {
    double sum = 0;
    const double t = best(repeats, [&] {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) {
        results[i] = ik(robot, T[i]);
        const IKResult& r = results[i];
        for (const auto& sol : r.solutions)
          if (sol.status == IKStatus::Ok) s += sol.q.sum();
      }
      sum = s;
    });
    rows.push_back({"ik (8 sol.)", t / n, sum});
  }
  // ikBatch, all threads
  std::vector<IKResult> batch(n);
  {
    double sum = 0;
    // Only the call is timed; the checksum is taken afterwards (ikBatch writes memory the
    // optimiser cannot see through, and the checksum reads it).
    const double t = best(repeats, [&] { ikBatch(robot, poses.data(), n, batch.data(), IKSettings{}, threads); });
    for (std::size_t i = 0; i < n; ++i)
      for (const auto& sol : batch[i].solutions)
        if (sol.status == IKStatus::Ok) sum += sol.q.sum();
    rows.push_back({"ikBatch", t / n, sum});
  }
  // ikClosest
  std::vector<Vector6d> closest(n);
  {
    double sum = 0;
    const double t = best(repeats, [&] {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const IKSolution sol = ikClosest(robot, T[i], q_near[i]);
        closest[i] = sol.q;
        if (sol.ok()) s += sol.q.sum();
      }
      sum = s;
    });
    rows.push_back({"ikClosest", t / n, sum});
  }
  for (const auto& r : rows) printRow(robot.name, r);

  // ---- correctness on the side (not timed) ----
  double max_residual = 0;
  std::size_t n_solutions = 0, found = 0, closest_match = 0, batch_equal = 0, reachable = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const IKResult& r = results[i];
    bool has = false;
    reachable += r.status == IKStatus::Ok;
    for (const auto& sol : r.solutions) {
      if (sol.status != IKStatus::Ok && sol.status != IKStatus::OutsideLimits) continue;
      ++n_solutions;
      max_residual = std::max(max_residual, poseError(robot.forward(sol.q), T[i]));
      double dq = 0;
      for (int j = 0; j < 6; ++j) dq = std::max(dq, std::abs(wrapPi(sol.q[j] - q[i][j])));
      has = has || (sol.status == IKStatus::Ok && dq < 1e-6);
    }
    found += has;
    // ikClosest must return a solution at least as close to q_near as the generating joints
    // (near singular poses another solution can be closer still).
    closest_match += (closest[i] - q_near[i]).norm() <= (q[i] - q_near[i]).norm() + 1e-9;
    bool same = true;
    for (int k = 0; k < 8 && same; ++k) {
      const auto& a = r.solutions[k];
      const auto& b = batch[i].solutions[k];
      same = a.status == b.status &&
             (a.status != IKStatus::Ok || (a.q - b.q).cwiseAbs().maxCoeff() == 0.0);
    }
    batch_equal += same;
  }
  std::printf("|   %s: %zu poses, %.1f solutions/pose (Ok or outside limits), max |FK(q) - T| = %.2e,\n",
              robot.name.c_str(), n, double(n_solutions) / n, max_residual);
  std::printf("|   generating q among the Ok solutions: %.4f %%, ikClosest at least as close as it: %.4f %%, "
              "ikBatch == ik: %.4f %%, poses with an Ok solution: %.4f %%\n",
              100.0 * found / n, 100.0 * closest_match / n, 100.0 * batch_equal / n, 100.0 * reachable / n);
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t n = 200000;
  int repeats = 5, threads = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--n") n = std::strtoull(next(), nullptr, 10);
    else if (a == "--repeats") repeats = std::atoi(next());
    else if (a == "--threads") threads = std::atoi(next());
    else {
      std::printf("usage: bench_ik [--n 200000] [--repeats 5] [--threads 0 (all cores)]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (n == 0 || repeats < 1) return 2;
  std::printf("bench_ik: %zu random reachable poses per robot (FK of random joints, seed 1), best of %d passes\n",
              n, repeats);
  std::printf("ikBatch threads: %d (0 = all; hardware_concurrency %u); other rows one thread\n\n", threads,
              std::thread::hardware_concurrency());
  std::printf("| robot          | call        |  µs/item  |   items/s    | checksum      |\n");
  std::printf("| -------------- | ----------- | --------- | ------------ | ------------- |\n");
  benchRobot(Robot::kukaKR6R900sixx(), n, repeats, threads, 1);
  benchRobot(Robot::ur5(), n, repeats, threads, 1);
  return 0;
}
