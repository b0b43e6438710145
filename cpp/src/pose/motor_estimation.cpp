// Valkenburg–Dorst motor estimation and Kabsch/SVD (paper 5 §III-E; thesis (2.1)-(2.15)). See motor_estimation.hpp.
//
// Forming Q. Q_ij = Σ_k w_k ⟨c̃_i Y_k c_j X_k⟩ is bilinear in the conformal points, so with
// X_k = Σ_b [X_k]_b E_b and Y_k = Σ_a [Y_k]_a E_a on the vector basis E = (e1, e2, e3, e∞, e0)
// (4.55) it is Q_ij = Σ_ab S_ab B_ijab, where S = Σ_k w_k [Y_k][X_k]ᵀ is a 5x5 moment matrix and
// B_ijab = ⟨c̃_i E_a c_j E_b⟩ are 8·8·5·5 constants of the algebra. B is computed once with
// the full geometric product (cga/multivector.hpp), so the data pass is 25 multiply-adds per
// pair and the algebra stays the thesis's, not a hand-expanded formula.
#include "scanalign/pose/motor_estimation.hpp"

#include "scanalign/common/rigid.hpp"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/Dense>

#include "scanalign/cga/objects.hpp"

namespace scanalign {

namespace {

using Matrix8d = Eigen::Matrix<double, 8, 8>;
using Vector8d = Eigen::Matrix<double, 8, 1>;
using cga::Multivector;

const std::array<const char*, 8> kMotorBasis = {"e23", "e31", "e12", "e1inf", "e2inf", "e3inf", "e123inf", ""};

/// The 8 motor basis blades c_i (paper 5 order: 1, e23, e31, e12, e1∞, e2∞, e3∞, e123∞).
std::array<Multivector, 8> motorBasis() {
  std::array<Multivector, 8> c;
  c[0] = Multivector(1.0);
  for (int i = 1; i < 8; ++i) c[i] = Multivector::named(kMotorBasis[i - 1]);
  return c;
}

/// B[i][j] is the 5x5 matrix B_ijab = ⟨c̃_i E_a c_j E_b⟩ (see the file comment).
const std::array<std::array<Eigen::Matrix<double, 5, 5>, 8>, 8>& constantsB() {
  static const auto B = [] {
    std::array<std::array<Eigen::Matrix<double, 5, 5>, 8>, 8> out;
    const auto c = motorBasis();
    const std::array<Multivector, 5> E = {Multivector::e1(), Multivector::e2(), Multivector::e3(), Multivector::eInf(),
                                          Multivector::e0()};
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j)
        for (int a = 0; a < 5; ++a) {
          const Multivector left = c[i].reverse() * E[a] * c[j];
          for (int b = 0; b < 5; ++b) out[i][j](a, b) = (left * E[b]).scalar();
        }
    return out;
  }();
  return B;
}

struct Prepared {
  Eigen::Vector3d cx = Eigen::Vector3d::Zero(), cy = Eigen::Vector3d::Zero();
  double scale = 1.0;
  double wsum = 0.0;
  std::size_t count = 0;
};

void checkInputs(const CloudView<double>& source, const CloudView<double>& target, const double* weights,
                 const char* who) {
  if (source.size != target.size)
    throw std::invalid_argument(std::string(who) + ": source and target must have the same number of points (pairs)");
  for (std::size_t i = 0; i < source.size; ++i) {
    if (weights && (!std::isfinite(weights[i]) || weights[i] < 0))
      throw std::invalid_argument(std::string(who) + ": weight " + std::to_string(i) + " is negative or not finite");
    if (weights && weights[i] == 0) continue;
    if (!source.isFinite(i) || !target.isFinite(i))
      throw std::invalid_argument(std::string(who) + ": pair " + std::to_string(i) + " has NaN or infinite coordinates");
  }
}

/// Weighted centroids, RMS spread and a degeneracy check (fewer than 3 pairs, or all source or
/// target points on one line: the rotation about that line is undetermined).
Prepared prepare(const CloudView<double>& source, const CloudView<double>& target, const double* weights,
                 std::string& message) {
  Prepared p;
  for (std::size_t i = 0; i < source.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    p.cx += w * source[i];
    p.cy += w * target[i];
    p.wsum += w;
    ++p.count;
  }
  if (p.count < 3) {
    message = "need at least 3 pairs with positive weight, got " + std::to_string(p.count);
    return p;
  }
  p.cx /= p.wsum;
  p.cy /= p.wsum;
  Eigen::Matrix3d sx = Eigen::Matrix3d::Zero(), sy = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < source.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    const Eigen::Vector3d dx = source[i] - p.cx, dy = target[i] - p.cy;
    sx += w * dx * dx.transpose();
    sy += w * dy * dy.transpose();
  }
  const Eigen::Vector3d ex = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sx, Eigen::EigenvaluesOnly).eigenvalues();
  const Eigen::Vector3d ey = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sy, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(ex(2) > 0) || ex(1) <= 1e-12 * ex(2) || !(ey(2) > 0) || ey(1) <= 1e-12 * ey(2)) {
    message = "degenerate pairs: the points are coincident or collinear, the rotation is undetermined";
    p.count = 0;
    return p;
  }
  p.scale = std::sqrt(0.5 * (ex.sum() + ey.sum()) / p.wsum);
  return p;
}

double rmseOf(const CloudView<double>& source, const CloudView<double>& target, const double* weights,
              const Eigen::Matrix4d& T) {
  double acc = 0, wsum = 0;
  for (std::size_t i = 0; i < source.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    acc += w * (target[i] - (T.topLeftCorner<3, 3>() * source[i] + T.topRightCorner<3, 1>())).squaredNorm();
    wsum += w;
  }
  return wsum > 0 ? std::sqrt(acc / wsum) : 0.0;
}

Vector8d motorCoefficients(const Multivector& M) {
  Vector8d m;
  m(0) = M.scalar();
  for (int i = 1; i < 8; ++i) m(i) = M.get(kMotorBasis[i - 1]);
  return m;
}

/// Q of (36-38) for the pairs mapped by x -> (x - ox)/s, y -> (y - oy)/s.
Matrix8d costMatrix(const CloudView<double>& source, const CloudView<double>& target, const double* weights,
                    const Eigen::Vector3d& ox, const Eigen::Vector3d& oy, double s) {
  Eigen::Matrix<double, 5, 5> S = Eigen::Matrix<double, 5, 5>::Zero();
  for (std::size_t k = 0; k < source.size; ++k) {
    const double w = weights ? weights[k] : 1.0;
    if (w == 0) continue;
    const Eigen::Vector3d x = (source[k] - ox) / s, y = (target[k] - oy) / s;
    Eigen::Matrix<double, 5, 1> X, Y;
    X << x, 0.5 * x.squaredNorm(), 1.0;  // [up(x)] on (e1, e2, e3, e∞, e0) (4.55)
    Y << y, 0.5 * y.squaredNorm(), 1.0;
    S.noalias() += w * Y * X.transpose();
  }
  const auto& B = constantsB();
  Matrix8d Q;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) Q(i, j) = B[i][j].cwiseProduct(S).sum();
  return 0.5 * (Q + Q.transpose());  // only the symmetric part enters mᵀQm
}

}  // namespace

Eigen::Matrix4d motorToMatrix(const Vector8d& motor) {
  if (!motor.allFinite()) throw std::invalid_argument("motorToMatrix: motor is not finite");
  const double rn = motor.head<4>().norm();
  if (!(rn > 0)) throw std::invalid_argument("motorToMatrix: the rotor part is zero");
  const Eigen::Vector4d r = motor.head<4>() / rn;
  Multivector R(r(0));
  for (int i = 1; i < 4; ++i) R = R + Multivector::named(kMotorBasis[i - 1], r(i));
  Multivector M(motor(0) / rn);
  for (int i = 1; i < 8; ++i) M = M + Multivector::named(kMotorBasis[i - 1], motor(i) / rn);
  // T = M R̃ = 1 − ½ t e∞ (thesis ch. 4, motors): read t off the e_i∞ coefficients and rebuild a proper
  // motor, which projects away any e123∞ part inconsistent with M M̃ = 1.
  const Multivector T = M * R.reverse();
  const Eigen::Vector3d t(-2 * T.get("e1inf"), -2 * T.get("e2inf"), -2 * T.get("e3inf"));
  return cga::Motor::fromMultivector(cga::translator(t) * R, 1e-6).matrix();
}

MotorEstimationResult estimateMotor(const CloudView<double>& source, const CloudView<double>& target,
                                    const double* weights, bool normalize) {
  checkInputs(source, target, weights, "estimateMotor");
  MotorEstimationResult out;
  const Prepared p = prepare(source, target, weights, out.message);
  out.count = p.count;
  if (p.count < 3) return out;
  const Eigen::Vector3d ox = normalize ? p.cx : Eigen::Vector3d::Zero();
  const Eigen::Vector3d oy = normalize ? p.cy : Eigen::Vector3d::Zero();
  const double s = normalize ? p.scale : 1.0;
  const Matrix8d Q = costMatrix(source, target, weights, ox, oy, s);
  const Eigen::Matrix4d Qrr = Q.topLeftCorner<4, 4>(), Qrt = Q.topRightCorner<4, 4>();
  const Eigen::Matrix4d Qtr = Q.bottomLeftCorner<4, 4>(), Qtt = Q.bottomRightCorner<4, 4>();
  // Q_tt is singular (the e123∞ coefficient does not enter the cost on its own): pseudo-inverse.
  const Eigen::Matrix4d Qtt_pinv = Qtt.completeOrthogonalDecomposition().pseudoInverse();
  Eigen::Matrix4d Lp = Qrr - Qrt * Qtt_pinv * Qtr;  // (43)
  Lp = 0.5 * (Lp + Lp.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(Lp);
  const Eigen::Vector4d r = eig.eigenvectors().col(3);  // largest eigenvalue: the cost is maximised
  const Eigen::Vector4d t = -Qtt_pinv * Qtr * r;        // (44)
  Vector8d m;
  m << r, t;
  // Undo the normalisation: the motor found maps x' = (x − ox)/s to y' = (y − oy)/s, i.e.
  // y = R x + (oy + s t' − R ox).
  const Eigen::Matrix4d Tn = motorToMatrix(m);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Tn.topLeftCorner<3, 3>();
  T.topRightCorner<3, 1>() = oy + s * Tn.topRightCorner<3, 1>() - Tn.topLeftCorner<3, 3>() * ox;
  out.T_target_source = T;
  out.motor = motorCoefficients(cga::Motor::fromMatrix(T).multivector());
  out.rmse = rmseOf(source, target, weights, T);
  out.valid = true;
  return out;
}

MotorEstimationResult estimateRigidSvd(const CloudView<double>& source, const CloudView<double>& target,
                                       const double* weights) {
  checkInputs(source, target, weights, "estimateRigidSvd");
  MotorEstimationResult out;
  const Prepared p = prepare(source, target, weights, out.message);
  out.count = p.count;
  if (p.count < 3) return out;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // Σ w (y − ȳ)(x − x̄)ᵀ
  for (std::size_t i = 0; i < source.size; ++i) {
    const double w = weights ? weights[i] : 1.0;
    if (w == 0) continue;
    H += w * (target[i] - p.cy) * (source[i] - p.cx).transpose();
  }
  const Eigen::Matrix3d R = rotationFromCrossCovariance(H).R;  // never a reflection
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R;
  T.topRightCorner<3, 1>() = p.cy - R * p.cx;  // t = ȳ − R x̄ (the printed (2.15) has it wrong)
  out.T_target_source = T;
  out.motor = motorCoefficients(cga::Motor::fromMatrix(T).multivector());
  out.rmse = rmseOf(source, target, weights, T);
  out.valid = true;
  return out;
}

}  // namespace scanalign
