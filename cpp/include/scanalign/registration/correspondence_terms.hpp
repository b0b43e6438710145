// The per-correspondence work of one ICP iteration, shared by the CPU engine (icp.cpp) and
// the CUDA kernel (cuda/icp_device.cu): move the source point, reject it by the box, weight
// it, and add its terms to the estimator's sums.
//
// Algorithm 1 of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929): per
// source point a nearest-neighbour search (left_balanced_search.hpp), the box rejection of
// §3.4, the distance rejection, and the point's share of Low's (2004) normal equations
// A^T A x = A^T b (§3.2), which a summing tree then reduces. Plain C++ on raw arrays, so that
// nvcc compiles the same code for the device (common/host_device.hpp).
#pragma once

#include <cstdint>

#include "scanalign/common/host_device.hpp"

namespace scanalign {

/// M-estimator on the point-to-plane residual, solved by iteratively reweighted least
/// squares: each correspondence's row of Low's system is weighted by w(|r|) (Zhang 1997,
/// "Parameter estimation techniques"). Far correspondences then pull less than in plain
/// least squares, which matters when the correspondence distance is large (sparse scans
/// with a large initial motion).
enum class RobustKernel {
  None,    ///< w = 1: Low's plain least squares (eye-in-hand paper §3.2)
  Huber,   ///< w = 1 for |r| <= k, k / |r| beyond
  Cauchy,  ///< w = 1 / (1 + (r / k)^2)
};

/// What one ICP pass applies to every source point: the current estimate and the rejection
/// rules. A plain value, copied to the GPU as a kernel argument.
template <typename Scalar>
struct IcpPassRules {
  Scalar R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< rotation of T_target_source, row-major
  Scalar t[3] = {0, 0, 0};                    ///< translation of T_target_source (m)
  bool has_box = false;                       ///< reject source points outside [box_lo, box_hi]
  double box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};  ///< box in the source camera frame (m), §3.4
  Scalar max_squared_distance = 0;  ///< correspondences at or beyond this are rejected (m^2)
  int stack_depth = 20;             ///< fixed search stack (§3.1)
  bool warm_start = true;           ///< start each search from the point's last neighbour
  RobustKernel kernel = RobustKernel::None;
  double robust_scale = 0.01;       ///< the kernel's k (m)
};

namespace detail {

/// Inside the closed box [lo, hi] (the eye-in-hand paper's box rejector, §3.4).
template <typename Scalar>
SCANALIGN_HOST_DEVICE inline bool insideBox(const double lo[3], const double hi[3], const Scalar* p) {
  return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
}

/// A source point is used when it is finite and, with a box, inside it (in its own frame).
template <typename Scalar>
SCANALIGN_HOST_DEVICE inline bool sourcePointUsed(const IcpPassRules<Scalar>& rules, const Scalar* s) {
  return finite3(s) && (!rules.has_box || insideBox(rules.box_lo, rules.box_hi, s));
}

/// q = R s + t, summed as r0 s0 + (r1 s1 + r2 s2) + t on both sides, so the host and the device
/// round alike (and as Eigen's fixed-size product did in the CPU engine before: the same bits).
template <typename Scalar>
SCANALIGN_HOST_DEVICE inline void transformPoint(const IcpPassRules<Scalar>& rules, const Scalar* s, Scalar* q) {
  for (int r = 0; r < 3; ++r)
    q[r] = rules.R[3 * r] * s[0] + (rules.R[3 * r + 1] * s[1] + rules.R[3 * r + 2] * s[2]) + rules.t[r];
}

/// IRLS weight of a point-to-plane correspondence (RobustKernel): s moved source point,
/// d target point, n its unit normal.
SCANALIGN_HOST_DEVICE inline double robustWeight(RobustKernel kernel, double k, const double s[3], const double d[3],
                                                 const double n[3]) {
  if (kernel == RobustKernel::None) return 1.0;
  double r = n[0] * (d[0] - s[0]) + n[1] * (d[1] - s[1]) + n[2] * (d[2] - s[2]);
  r = r < 0 ? -r : r;
  return kernel == RobustKernel::Huber ? (r <= k ? 1.0 : k / r) : 1.0 / (1.0 + (r / k) * (r / k));
}

/// Adds one correspondence to Low's normal equations: s moved source point, d target point,
/// n target unit normal, w its weight. Row A_i = [(s x n)^T, n^T], b_i = n . (d - s) (Low
/// 2004, eqs. (8)-(10)); ata is the upper triangle of A^T A row-major (21), atb A^T b (6),
/// btb the sum of w b_i^2.
SCANALIGN_HOST_DEVICE inline void addPointToPlaneTerms(double* ata, double* atb, double& btb, const double s[3],
                                                       const double d[3], const double n[3], double w) {
  const double a0 = n[2] * s[1] - n[1] * s[2];
  const double a1 = n[0] * s[2] - n[2] * s[0];
  const double a2 = n[1] * s[0] - n[0] * s[1];
  const double row[6] = {a0, a1, a2, n[0], n[1], n[2]};
  const double b = n[0] * (d[0] - s[0]) + n[1] * (d[1] - s[1]) + n[2] * (d[2] - s[2]);
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    const double wr = w * row[r];
    for (int c = r; c < 6; ++c) ata[k++] += wr * row[c];
    atb[r] += wr * b;
  }
  btb += w * b * b;
}

/// Adds one pair to the point-to-point sums (Horn 1987 / Umeyama 1991 from running sums):
/// sum_s, sum_d (3 each), sum_sd = sum of s d^T row-major (9), sum_ss, sum_dd.
SCANALIGN_HOST_DEVICE inline void addPointPairTerms(double* sum_s, double* sum_d, double* sum_sd, double& sum_ss,
                                                    double& sum_dd, const double s[3], const double d[3]) {
  for (int r = 0; r < 3; ++r) {
    sum_s[r] += s[r];
    sum_d[r] += d[r];
    sum_ss += s[r] * s[r];
    sum_dd += d[r] * d[r];
    for (int c = 0; c < 3; ++c) sum_sd[3 * r + c] += s[r] * d[c];
  }
}

}  // namespace detail

}  // namespace scanalign
