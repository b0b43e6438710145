// Hand-eye calibration: Daniilidis' dual-quaternion closed form, then Levenberg-Marquardt
// on SE(3) x SE(3). See the header for the equations and frames.
#include "scanalign/calibration/hand_eye.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

using Mat4 = Eigen::Matrix4d;
using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;

Mat3 skew(const Vec3& v) {
  Mat3 S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Mat3 rot(const Mat4& T) { return T.topLeftCorner<3, 3>(); }
Vec3 trans(const Mat4& T) { return T.topRightCorner<3, 1>(); }

Mat4 compose(const Mat3& R, const Vec3& t) {
  Mat4 T = Mat4::Identity();
  T.topLeftCorner<3, 3>() = R;
  T.topRightCorner<3, 1>() = t;
  return T;
}

/// Rotation vector (axis times angle, rad) of R.
Vec3 logSO3(const Mat3& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

Mat3 expSO3(const Vec3& phi) {
  const double angle = phi.norm();
  return angle < 1e-300 ? Mat3::Identity() : Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
}

/// Inverse of the right Jacobian of SO(3) at phi (Barfoot, "State Estimation for Robotics",
/// 2017, eq. (7.77b) with right Jacobians): d log(R Exp(dphi)) / d dphi at dphi = 0.
Mat3 rightJacobianInverse(const Vec3& phi) {
  const double theta = phi.norm();
  const Mat3 S = skew(phi);
  if (theta < 1e-6) return Mat3::Identity() + 0.5 * S + S * S / 12.0;
  const double c = 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Mat3::Identity() + 0.5 * S + c * S * S;
}

/// Adjoint of T acting on twists ordered (rho, phi): Ad_T xi = (T xi^ T^-1)^v.
Mat6 adjoint(const Mat4& T) {
  Mat6 A = Mat6::Zero();
  A.topLeftCorner<3, 3>() = rot(T);
  A.topRightCorner<3, 3>() = skew(trans(T)) * rot(T);
  A.bottomRightCorner<3, 3>() = rot(T);
  return A;
}

/// T exp(delta) to first order: [Exp(phi), rho] applied on the right. Its derivative at 0 is
/// that of the exponential map, which is all Levenberg-Marquardt needs of a retraction.
Mat4 retract(const Mat4& T, const Vec6& delta) {
  return T * compose(expSO3(delta.tail<3>()), delta.head<3>());
}

/// Unit dual quaternion (rotor r, dual part d = t r / 2) of a rigid motion; the rotor's
/// scalar part is made >= 0 so that the two motions of a pair have the same sign
/// (Daniilidis 1999, §4: their scalar parts are equal, the screw congruence theorem).
struct DualQuaternion {
  Eigen::Quaterniond r, d;
};

DualQuaternion dualQuaternion(const Mat4& T) {
  DualQuaternion q;
  q.r = Eigen::Quaterniond(rot(T)).normalized();
  if (q.r.w() < 0) q.r.coeffs() = -q.r.coeffs();
  const Vec3 t = trans(T);
  q.d = Eigen::Quaterniond(0.0, t.x(), t.y(), t.z()) * q.r;
  q.d.coeffs() *= 0.5;
  return q;
}

/// The 6 equations of one motion pair a x = x b in x = (q, q') (Daniilidis 1999, eq. (31)):
/// [a - b, [a + b]x, 0, 0; a' - b', [a' + b']x, a - b, [a + b]x] (q0, q, q'0, q') = 0, vector
/// parts of the rotors a, b and of the dual parts a', b'.
Eigen::Matrix<double, 6, 8> motionEquations(const DualQuaternion& a, const DualQuaternion& b) {
  Eigen::Matrix<double, 6, 8> S = Eigen::Matrix<double, 6, 8>::Zero();
  const Vec3 ar = a.r.vec(), br = b.r.vec(), ad = a.d.vec(), bd = b.d.vec();
  S.block<3, 1>(0, 0) = ar - br;
  S.block<3, 3>(0, 1) = skew(ar + br);
  S.block<3, 1>(3, 0) = ad - bd;
  S.block<3, 3>(3, 1) = skew(ad + bd);
  S.block<3, 1>(3, 4) = ar - br;
  S.block<3, 3>(3, 5) = skew(ar + br);
  return S;
}

/// The unit dual quaternion in the null space of the stacked system spanned by v7, v8:
/// x = l1 v7 + l2 v8 with |q| = 1 and q . q' = 0 (Daniilidis 1999, eqs. (34)-(35)). The
/// quadratic constraint is l^T M l = 0 for the symmetric 2x2 M of the q . q' products;
/// written in M's eigenbasis its two roots are explicit, and the one with the larger |q| is
/// the paper's choice. Noise can make M definite; its least-|eigenvalue| direction is then
/// the nearest to a root.
Mat4 nullSpaceMotion(const Eigen::Matrix<double, 8, 1>& v7, const Eigen::Matrix<double, 8, 1>& v8) {
  const Eigen::Vector4d u1 = v7.head<4>(), w1 = v7.tail<4>(), u2 = v8.head<4>(), w2 = v8.tail<4>();
  Eigen::Matrix2d M;
  M << u1.dot(w1), 0.5 * (u1.dot(w2) + u2.dot(w1)), 0.5 * (u1.dot(w2) + u2.dot(w1)), u2.dot(w2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(M);
  const double e0 = eig.eigenvalues()(0), e1 = eig.eigenvalues()(1);
  const Eigen::Vector2d b0 = eig.eigenvectors().col(0), b1 = eig.eigenvectors().col(1);
  Eigen::Vector2d candidates[2];
  int count = 0;
  if (e0 <= 0.0 && e1 >= 0.0 && e1 - e0 > 0.0) {
    const double c0 = std::sqrt(e1 / (e1 - e0)), c1 = std::sqrt(-e0 / (e1 - e0));
    candidates[count++] = c0 * b0 + c1 * b1;
    candidates[count++] = c0 * b0 - c1 * b1;
  } else {
    candidates[count++] = std::abs(e0) <= std::abs(e1) ? b0 : b1;
  }
  Eigen::Vector4d q = Eigen::Vector4d::Zero(), qd = Eigen::Vector4d::Zero();
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector4d qk = candidates[k](0) * u1 + candidates[k](1) * u2;
    if (qk.norm() > q.norm()) q = qk, qd = candidates[k](0) * w1 + candidates[k](1) * w2;
  }
  qd /= q.norm();
  q /= q.norm();
  const Eigen::Quaterniond r(q(0), q(1), q(2), q(3)), d(qd(0), qd(1), qd(2), qd(3));
  const Vec3 t = 2.0 * (d * r.conjugate()).vec();  // d = t r / 2
  return compose(r.toRotationMatrix(), t);
}

/// Z = T_base_world from X: the chordal mean (Umeyama 1991's SVD projection of the summed
/// rotations) and the mean translation of A_i X inv(B_i).
Mat4 meanWorld(const std::vector<Mat4>& A, const std::vector<Mat4>& B, const Mat4& X) {
  Mat3 H = Mat3::Zero();
  Vec3 t = Vec3::Zero();
  for (std::size_t i = 0; i < A.size(); ++i) {
    const Mat4 Zi = A[i] * X * rigidInverse(B[i]);
    H += rot(Zi);
    t += trans(Zi);
  }
  return compose(rotationFromCrossCovariance(H).R, t / double(A.size()));
}

/// Residual of pose i at (X, Z): E = B inv(X) inv(A) Z, r = (t_E, w log R_E).
struct PoseResidual {
  Vec6 r;
  Mat4 E, C;  // C = inv(X) inv(A) Z, the predicted T_camera_world
};

PoseResidual poseResidual(const Mat4& A, const Mat4& B, const Mat4& Xinv, const Mat4& Z, double w) {
  PoseResidual p;
  p.C = Xinv * rigidInverse(A) * Z;
  p.E = B * p.C;
  p.r << trans(p.E), w * logSO3(rot(p.E));
  return p;
}

/// Per-pose robust weight (iteratively reweighted least squares for the Huber loss) and cost.
double huberWeight(double s, double delta) { return delta > 0 && s > delta ? delta / s : 1.0; }
double huberCost(double s, double delta) { return delta > 0 && s > delta ? delta * (s - 0.5 * delta) : 0.5 * s * s; }

double totalCost(const std::vector<Mat4>& A, const std::vector<Mat4>& B, const Mat4& X, const Mat4& Z,
                 const HandEyeSettings& s) {
  const Mat4 Xinv = rigidInverse(X);
  double cost = 0.0;
  for (std::size_t i = 0; i < A.size(); ++i)
    cost += huberCost(poseResidual(A[i], B[i], Xinv, Z, s.rotation_weight).r.norm(), s.huber_delta);
  return cost;
}

/// Levenberg-Marquardt over (xi_x, xi_z) with X <- X exp(xi_x), Z <- Z exp(xi_z). E(xi) =
/// E0 exp(xi_z - Ad(inv C) xi_x) to first order, so with d r / d delta = [R_E, 0; 0,
/// w Jr^-1(log R_E)] the Jacobian is exact at the current estimate.
void refine(const std::vector<Mat4>& A, const std::vector<Mat4>& B, const HandEyeSettings& s, HandEyeResult& out) {
  Mat4 X = out.T_flange_camera, Z = out.T_base_world;
  double cost = totalCost(A, B, X, Z, s);
  double lambda = 1e-4;
  out.converged = false;
  for (int it = 0; it < s.max_iterations; ++it) {
    Mat12 H = Mat12::Zero();
    Vec12 g = Vec12::Zero();
    const Mat4 Xinv = rigidInverse(X);
    for (std::size_t i = 0; i < A.size(); ++i) {
      const PoseResidual p = poseResidual(A[i], B[i], Xinv, Z, s.rotation_weight);
      Mat6 dr = Mat6::Zero();
      dr.topLeftCorner<3, 3>() = rot(p.E);
      dr.bottomRightCorner<3, 3>() = s.rotation_weight * rightJacobianInverse(p.r.tail<3>() / s.rotation_weight);
      Eigen::Matrix<double, 6, 12> J;
      J.leftCols<6>() = -dr * adjoint(rigidInverse(p.C));
      J.rightCols<6>() = dr;
      const double weight = huberWeight(p.r.norm(), s.huber_delta);
      H.noalias() += weight * J.transpose() * J;
      g.noalias() += weight * J.transpose() * p.r;
    }
    bool accepted = false;
    Vec12 step = Vec12::Zero();
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Mat12 Ha = H;
      Ha.diagonal() += lambda * H.diagonal() + Vec12::Constant(1e-30);
      step = -Ha.ldlt().solve(g);
      if (!step.allFinite()) break;
      const Mat4 X1 = retract(X, step.head<6>()), Z1 = retract(Z, step.tail<6>());
      const double cost1 = totalCost(A, B, X1, Z1, s);
      if (cost1 <= cost) {
        X = X1, Z = Z1, cost = cost1, accepted = true;
        lambda = std::max(lambda / 10.0, 1e-12);
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted) {  // no step lowers the cost: at the minimum to rounding
      out.converged = true;
      break;
    }
    out.iterations = it + 1;
    if (step.cwiseAbs().maxCoeff() <= s.step_tolerance) {
      out.converged = true;
      break;
    }
  }
  out.T_flange_camera = X;
  out.T_base_world = Z;
}

void fillResiduals(const std::vector<Mat4>& A, const std::vector<Mat4>& B, HandEyeResult& out) {
  const std::size_t n = A.size();
  out.residual_rotation.resize(static_cast<Eigen::Index>(n));
  out.residual_translation.resize(static_cast<Eigen::Index>(n));
  const Mat4 Xinv = rigidInverse(out.T_flange_camera);
  for (std::size_t i = 0; i < n; ++i) {
    const PoseResidual p = poseResidual(A[i], B[i], Xinv, out.T_base_world, 1.0);
    out.residual_translation(static_cast<Eigen::Index>(i)) = p.r.head<3>().norm();
    out.residual_rotation(static_cast<Eigen::Index>(i)) = p.r.tail<3>().norm();
  }
  out.rms_rotation = std::sqrt(out.residual_rotation.squaredNorm() / double(n));
  out.rms_translation = std::sqrt(out.residual_translation.squaredNorm() / double(n));
}

HandEyeResult failure(HandEyeStatus status, std::string message) {
  HandEyeResult r;
  r.status = status;
  r.message = std::move(message);
  return r;
}

std::string degrees(double rad) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g deg", rad * kDeg);
  return buf;
}

/// Calls f(i, j) for the pose pairs of the closed form: all pairs i < j up to kAllPairsUpTo
/// poses; beyond, the pairs j - i = 1, 2, 4, 8, ... (consecutive and spread motions, about
/// N log2 N of them), so that memory and time stay near linear in N.
constexpr std::size_t kAllPairsUpTo = 64;

template <typename F>
void forEachPair(std::size_t n, F&& f) {
  if (n <= kAllPairsUpTo) {
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) f(i, j);
    return;
  }
  for (std::size_t step = 1; step < n; step *= 2)
    for (std::size_t i = 0; i + step < n; ++i) f(i, i + step);
}

/// The triangular factor R of a tall matrix given in blocks of rows: R^T R = T^T T, and R has
/// the right singular vectors of T, without storing T (Golub and Van Loan 2013, §5.2:
/// Householder QR of [R; block] for each new block).
class StreamingQr {
 public:
  void add(const Eigen::Matrix<double, 6, 8>& rows) {
    buffer_.middleRows<6>(8 + 6 * pending_) = rows;
    if (++pending_ == kBlocks) flush();
  }
  Eigen::Matrix<double, 8, 8> r() {
    flush();
    return buffer_.topRows<8>();
  }

 private:
  static constexpr int kBlocks = 64;
  void flush() {
    if (pending_ == 0) return;
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(buffer_.topRows(8 + 6 * pending_));
    buffer_.topRows<8>() = qr.matrixQR().topRows<8>().triangularView<Eigen::Upper>();
    pending_ = 0;
  }
  Eigen::MatrixXd buffer_ = Eigen::MatrixXd::Zero(8 + 6 * kBlocks, 8);
  int pending_ = 0;
};

/// Rotation angles and axes of the robot's relative motions: the rotation about an axis is
/// only determined by motions about another axis (Tsai and Lenz 1989, "A new technique for
/// fully autonomous and efficient 3D robotics hand/eye calibration", IEEE T-RA 5(3), §III:
/// two motions with non-parallel axes). Fills the diagnostics; false when degenerate.
bool motionSpread(const std::vector<Mat4>& A, const HandEyeSettings& s, HandEyeResult& out) {
  const auto motion = [&](std::size_t i, std::size_t j) {
    return Eigen::AngleAxisd(Mat3(rot(A[i]).transpose() * rot(A[j])));
  };
  Eigen::AngleAxisd largest(0.0, Vec3::UnitZ());
  int counted = 0;
  forEachPair(A.size(), [&](std::size_t i, std::size_t j) {
    const Eigen::AngleAxisd m = motion(i, j);
    if (m.angle() >= s.min_relative_rotation) ++counted;
    if (m.angle() > largest.angle()) largest = m;
  });
  out.max_relative_rotation = largest.angle();
  if (counted < 2) {
    out.status = HandEyeStatus::DegenerateMotion;
    out.message = "rotations too small: " + std::to_string(counted) + " relative motions rotate by min_relative_rotation (" +
                  degrees(s.min_relative_rotation) + ") or more, 2 are needed (largest: " +
                  degrees(out.max_relative_rotation) + ")";
    return false;
  }
  forEachPair(A.size(), [&](std::size_t i, std::size_t j) {
    const Eigen::AngleAxisd m = motion(i, j);
    if (m.angle() >= s.min_relative_rotation)
      out.axis_spread = std::max(out.axis_spread, std::acos(std::min(1.0, std::abs(m.axis().dot(largest.axis())))));
  });
  if (out.axis_spread < s.min_axis_angle) {
    out.status = HandEyeStatus::DegenerateMotion;
    out.message = "all relative rotation axes are nearly parallel (spread " + degrees(out.axis_spread) +
                  " < min_axis_angle " + degrees(s.min_axis_angle) +
                  "): the rotation about that axis and the offset along it are not determined; rotate the flange "
                  "about at least two different axes";
    return false;
  }
  return true;
}

/// Rigid, and within kMaxTranslation of the origin: beyond, squared residuals overflow long
/// before a robot cell's poses could get there.
constexpr double kMaxTranslation = 1e6;  // m

bool checkPoses(const std::vector<Mat4>& T, const char* name, HandEyeResult& out) {
  for (std::size_t i = 0; i < T.size(); ++i) {
    const char* problem = rigidProblem(T[i]);
    if (!problem && !(trans(T[i]).cwiseAbs().maxCoeff() <= kMaxTranslation))
      problem = "its translation is beyond 1e6 m";
    if (problem) {
      out = failure(HandEyeStatus::InvalidInput,
                    std::string(name) + "[" + std::to_string(i) + "] is not a rigid transform: " + problem);
      return false;
    }
  }
  return true;
}

}  // namespace

const char* toString(HandEyeStatus status) {
  switch (status) {
    case HandEyeStatus::Ok: return "ok";
    case HandEyeStatus::TooFewPoses: return "too_few_poses";
    case HandEyeStatus::InvalidInput: return "invalid_input";
    case HandEyeStatus::DegenerateMotion: return "degenerate_motion";
    case HandEyeStatus::InconsistentPoses: return "inconsistent_poses";
  }
  return "invalid_input";
}

void validate(const HandEyeSettings& s) {
  auto angle = [](double v, const char* name) {
    if (!std::isfinite(v) || v < 0 || v > kPi / 2)
      throw std::invalid_argument(std::string("HandEyeSettings.") + name + ": expected an angle in [0, pi/2] rad, got " +
                                  std::to_string(v));
  };
  angle(s.min_relative_rotation, "min_relative_rotation");
  angle(s.min_axis_angle, "min_axis_angle");
  if (!std::isfinite(s.rotation_weight) || !(s.rotation_weight > 0))
    throw std::invalid_argument("HandEyeSettings.rotation_weight: expected a finite value > 0 (m/rad)");
  if (!std::isfinite(s.huber_delta) || s.huber_delta < 0)
    throw std::invalid_argument("HandEyeSettings.huber_delta: expected a finite value >= 0 (m; 0 = least squares)");
  if (!std::isfinite(s.max_rms_translation) || !(s.max_rms_translation > 0))
    throw std::invalid_argument("HandEyeSettings.max_rms_translation: expected a finite value > 0 (m)");
  if (!std::isfinite(s.max_rms_rotation) || !(s.max_rms_rotation > 0))
    throw std::invalid_argument("HandEyeSettings.max_rms_rotation: expected a finite value > 0 (rad)");
  if (s.max_iterations < 1) throw std::invalid_argument("HandEyeSettings.max_iterations: expected >= 1");
  if (!std::isfinite(s.step_tolerance) || s.step_tolerance < 0)
    throw std::invalid_argument("HandEyeSettings.step_tolerance: expected a finite value >= 0");
}

HandEyeResult calibrateHandEye(const std::vector<Mat4>& A, const std::vector<Mat4>& B, const HandEyeSettings& s) {
  validate(s);
  if (A.size() != B.size())
    return failure(HandEyeStatus::InvalidInput, "T_base_flange and the camera poses differ in number: " +
                                                    std::to_string(A.size()) + " and " + std::to_string(B.size()));
  if (A.size() < 3)
    return failure(HandEyeStatus::TooFewPoses,
                   "hand-eye calibration needs at least 3 poses (2 relative motions), got " + std::to_string(A.size()));
  HandEyeResult out;
  if (!checkPoses(A, "T_base_flange", out) || !checkPoses(B, "T_world_camera", out)) return out;
  if (!motionSpread(A, s, out)) return out;

  // Closed form over the pairs (forEachPair). A pair whose rotation is near 180 deg has a
  // rotor scalar part near 0, where the sign that makes a and b congruent is not known: such
  // pairs are left out.
  StreamingQr qr;
  forEachPair(A.size(), [&](std::size_t i, std::size_t j) {
    const DualQuaternion a = dualQuaternion(rigidInverse(A[i]) * A[j]);
    const DualQuaternion b = dualQuaternion(rigidInverse(B[i]) * B[j]);
    if (a.r.w() < 0.05 || b.r.w() < 0.05) return;
    qr.add(motionEquations(a, b));
    ++out.pairs;
  });
  if (out.pairs < 2)
    return failure(HandEyeStatus::DegenerateMotion, "fewer than 2 relative motions below 174 deg of rotation");
  const Eigen::JacobiSVD<Eigen::Matrix<double, 8, 8>> svd(qr.r(), Eigen::ComputeFullV);
  out.T_flange_camera_closed_form = nullSpaceMotion(svd.matrixV().col(6), svd.matrixV().col(7));
  out.T_base_world_closed_form = meanWorld(A, B, out.T_flange_camera_closed_form);
  out.T_flange_camera = out.T_flange_camera_closed_form;
  out.T_base_world = out.T_base_world_closed_form;
  fillResiduals(A, B, out);
  out.rms_rotation_closed_form = out.rms_rotation;
  out.rms_translation_closed_form = out.rms_translation;
  out.converged = true;
  if (s.refine) {
    refine(A, B, s, out);
    fillResiduals(A, B, out);
  }
  if (!(out.rms_translation <= s.max_rms_translation) || !(out.rms_rotation <= s.max_rms_rotation)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "%.3g m and %.3g deg", out.rms_translation, out.rms_rotation * kDeg);
    out.status = HandEyeStatus::InconsistentPoses;
    out.message = std::string("the poses do not fit one T_flange_camera and T_base_world: RMS residual ") + buf +
                  " (max_rms_translation " + std::to_string(s.max_rms_translation) + " m, max_rms_rotation " +
                  degrees(s.max_rms_rotation) + "); are robot and camera poses paired by time, is a view wrong?";
    return out;
  }
  out.status = HandEyeStatus::Ok;
  return out;
}

HandEyeResult calibrateHandEyeFromTarget(const std::vector<Mat4>& A, const std::vector<Mat4>& T_camera_target,
                                         const HandEyeSettings& s) {
  validate(s);
  HandEyeResult out;
  if (!checkPoses(T_camera_target, "T_camera_target", out)) return out;
  std::vector<Mat4> B;
  B.reserve(T_camera_target.size());
  for (const Mat4& T : T_camera_target) B.push_back(rigidInverse(T));
  return calibrateHandEye(A, B, s);
}

}  // namespace scanalign
