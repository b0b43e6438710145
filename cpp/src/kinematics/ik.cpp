// Analytic inverse kinematics with CGA (Kleppe, PhD thesis, NTNU 2018, Paper 1 §4-5 and §5.3).
// See ik.hpp for the construction, the configuration labels and the singularity choices.
#include "scanalign/kinematics/ik.hpp"
#include "scanalign/common/threads.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <omp.h>
#include <Eigen/Geometry>  // cross()

#include "scanalign/cga/vector5.hpp"
#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

constexpr double kPi = M_PI;
constexpr double kTwoPi = 2 * M_PI;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Largest |h^2/r^2| of an imaginary elbow pair that is still tried as tangent (then polished
/// and verified by forward kinematics): 1e-6 is ~2e-7 m of reach on a 0.4 m link; near the
/// wrist singularity it grows as 1e-14 / sin(theta5), the error of the wrist point P4.
constexpr double kNearTangent = 1e-6;

using Vector3d = Eigen::Vector3d;
using Matrix3d = Eigen::Matrix3d;
/// Conformal vectors on (e1, e2, e3, e∞, e0) with the metric of (5.32): scanalign/cga/vector5.hpp.
using Vector5d = cga5::Vec5;
using cga5::dualPlane;
using cga5::dualSphere;

// ---------------------------------------------------------------------------
// CGA in 5-vector coordinates (thesis (4.54)-(4.69); the metric of (5.32))
// ---------------------------------------------------------------------------

/// The point pair Q = (A* ∧ B* ∧ C*)* of three dual spheres / planes (thesis (4.70)-(4.73)), returned
/// as its two points. The null vectors X = up(x) with X·A* = X·B* = X·C* = 0 are the
/// points of Q; X·V* = v·x − v∞ − ½v0|x|² for V* = [v; v∞; v0]. Eliminating |x|² with the
/// sphere of largest |v0| leaves one sphere |x − c|² = r² and two planes, i.e. a line
/// m + t u; the points are m ± h u with h² = r² − |c − m|². Q² is a positive multiple of h²,
/// so the reality test of thesis (4.70)-(4.73) (Q² > 0 real, = 0 tangent, < 0 imaginary) is the sign of
/// the normalised discriminant h²/r².
struct PointPair {
  Vector3d a = Vector3d::Constant(kNaN), b = Vector3d::Constant(kNaN);
  double discriminant = kNaN;  ///< h²/r² (< 0: imaginary)
  bool degenerate = true;      ///< not a point pair (parallel planes, no sphere, r² <= 0)
};

PointPair meet3(const Vector5d& A, const Vector5d& B, const Vector5d& C) {
  PointPair out;
  const Vector5d* v[3] = {&A, &B, &C};
  int s = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs((*v[i])[4]) > std::abs((*v[s])[4])) s = i;
  const double w = (*v[s])[4];
  if (w == 0) return out;  // three planes: a line or a flat point, not a point pair
  const Vector5d S = *v[s] * (1.0 / w);  // e0-normalised sphere
  const Vector3d c = S.head<3>();
  const double r2 = c.squaredNorm() - 2 * S[3];
  // the other two, minus their sphere part: planes n·x = δ
  Vector3d n[2];
  double delta[2];
  for (int i = 0, k = 0; i < 3; ++i) {
    if (i == s) continue;
    const Vector5d P = *v[i] - (*v[i])[4] * S;
    n[k] = P.head<3>();
    delta[k] = P[3];
    ++k;
  }
  const Vector3d u = n[0].cross(n[1]);
  const double uu = u.squaredNorm();
  const double scale = n[0].squaredNorm() * n[1].squaredNorm();
  if (!(uu > 1e-24 * scale) || !(r2 > 0)) return out;
  // point of the line: x0 = (δ0 (n1×u) + δ1 (u×n0)) / |u|²
  const Vector3d x0 = (delta[0] * n[1].cross(u) + delta[1] * u.cross(n[0])) * (1.0 / uu);
  const Vector3d un = u * (1.0 / std::sqrt(uu));
  const Vector3d m = x0 + (c - x0).dot(un) * un;
  const double h2 = r2 - (c - m).squaredNorm();
  out.degenerate = false;
  out.discriminant = h2 / r2;
  const double h = h2 > 0 ? std::sqrt(h2) : 0.0;
  out.a = m + h * un;
  out.b = m - h * un;
  return out;
}

/// Reality test with tolerance (IKSettings::reach_tolerance): -1 imaginary, 0 tangent, 1 real.
inline int reality(const PointPair& q, double tol) {
  if (q.degenerate || !(q.discriminant >= -tol)) return -1;
  return q.discriminant <= tol ? 0 : 1;
}

inline double sgn(double x) { return x < 0 ? -1.0 : 1.0; }

// ---------------------------------------------------------------------------
// Recursive DH angle extraction (applies Paper 1's rule N* = z_{i-1}, eq. (22))
// ---------------------------------------------------------------------------

/// A DH joint with its twist's cosine and sine evaluated once per solve.
struct Link {
  double a, d, ca, sa;
  double inv_a, inv_sa;  ///< 1/a and 1/sin(alpha) (infinite when zero: never used then)
};

/// An angle with its cosine, sine and value (rad). The extraction yields (cos, sin)
/// directly, so stepping into the next frame needs no further trigonometry, and each
/// angle's atan2 is evaluated once even when several solutions share it.
struct Angle {
  double c, s, t;
  static Angle of(double theta) { return {std::cos(theta), std::sin(theta), theta}; }
  static Angle fromXY(double x, double y) {
    const double n = std::sqrt(x * x + y * y);
    if (!(n > 0)) return Angle{1.0, 0.0, 0.0};
    const double in = 1.0 / n;
    return Angle{x * in, y * in, std::atan2(y, x)};
  }
  Angle plusPi() const { return {-c, -s, t + kPi}; }
  Angle negated() const { return {c, -s, -t}; }
};

/// A direction given in DH frame i-1, expressed in frame i: R_{i-1,i}ᵀ v with
/// R_{i-1,i} = Rot_z(θ) Rot_x(α) (P1 (1)).
inline Vector3d toChild(const Vector3d& v, const Angle& th, const Link& j) {
  const double x = th.c * v.x() + th.s * v.y();
  const double y = -th.s * v.x() + th.c * v.y();
  return {x, j.ca * y + j.sa * v.z(), -j.sa * y + j.ca * v.z()};
}
/// A point given relative to the origin of frame i-1 (in frame i-1 axes), expressed
/// relative to the origin of frame i in frame i axes (O_i = O_{i-1} + R (a cosθ, a sinθ, d)).
inline Vector3d pointToChild(const Vector3d& p, const Angle& th, const Link& j) {
  return toChild(p - Vector3d(j.a * th.c, j.a * th.s, j.d), th, j);
}
// With the frames of the angles found so far,
//   a_i != 0: v = R_{0,i-1}ᵀ (O_i − O_{i−1}) = (a cosθ, a sinθ, d), θ = atan2(v_y/a, v_x/a);
//   a_i == 0: z = R_{0,i-1}ᵀ z_i = (sinθ sinα, −cosθ sinα, cosα), θ = atan2(z_x/sinα, −z_y/sinα).
inline Angle angleFromOrigin(const Vector3d& v, const Link& j) {
  return Angle::fromXY(v.x() * j.inv_a, v.y() * j.inv_a);
}
inline Angle angleFromAxis(const Vector3d& z, const Link& j) {
  return Angle::fromXY(-z.y() * j.inv_sa, z.x() * j.inv_sa);
}

/// Wraps q into (-π, π]; then, with limits, to the 2π multiple inside [lo, hi] nearest 0.
inline bool wrapJoint(double& q, const DHJoint& j, bool respect_limits) {
  // q = atan2(...) - offset: one or two steps of 2π bring it into (-π, π]
  if (!(std::abs(q) <= 4 * kPi)) q = std::remainder(q, kTwoPi);
  while (q > kPi) q -= kTwoPi;
  while (q <= -kPi) q += kTwoPi;
  if (!respect_limits) return true;
  constexpr double tol = 1e-12;
  if (q >= j.q_min - tol && q <= j.q_max + tol) return true;
  double best = kNaN;
  for (int k = -3; k <= 3; ++k) {
    const double c = q + k * kTwoPi;
    if (c >= j.q_min - tol && c <= j.q_max + tol && !(std::abs(c) >= std::abs(best))) best = c;
  }
  if (std::isnan(best)) return false;
  q = best;
  return true;
}

// ---------------------------------------------------------------------------
// The solver
// ---------------------------------------------------------------------------

/// Records the construction of one configuration for ikConstruction(). The named points
/// have fixed slots (NaN until reached), so an unreachable configuration still shows the
/// points found before the imaginary point pair, and its discriminant.
struct Recorder {
  IKConfig config;
  IKConstruction* out = nullptr;
  void init(const char* const* names, int n) {
    out->num_points = n;
    for (int i = 0; i < n; ++i) {
      out->names[static_cast<std::size_t>(i)] = names[i];
      out->points[static_cast<std::size_t>(i)] = Vector3d::Constant(kNaN);
    }
  }
  bool matches(int s, int e, int w) const {
    return out && config.shoulder == s && config.elbow == e && config.wrist == w;
  }
  void set(int slot, const Vector3d& p) { out->points[static_cast<std::size_t>(slot)] = p; }
};
// slots: KUKA p_e, P_w, P1, P2, P_wx; UR p_e, P5, P_c, P4, P3, P2, P1
constexpr const char* kSphericalWristPoints[] = {"p_e", "P_w", "P1", "P2", "P_wx"};
constexpr const char* kURPoints[] = {"p_e", "P5", "P_c", "P4", "P3", "P2", "P1"};

struct Target {
  Matrix3d R;  ///< flange orientation in DH frame 0: columns n_e, s_e, a_e (P1 (2))
  Vector3d p;  ///< flange position p_e in DH frame 0, m
};

/// Stores the joint angles (DH thetas) of one configuration, applying offsets and limits.
void finish(const Robot& robot, const Angle theta[6], const IKConfig& cfg, std::uint8_t singular,
            const IKSettings& o, IKResult& res) {
  IKSolution& s = res.solutions[static_cast<std::size_t>(configIndex(cfg))];
  s.config = cfg;
  s.singular = singular;
  s.unreachable_step = IKStep::None;
  bool inside = true;
  for (int i = 0; i < 6; ++i) {
    const DHJoint& j = robot.joints[static_cast<std::size_t>(i)];
    double q = theta[i].t - j.theta_offset;
    inside = wrapJoint(q, j, o.respect_limits) && inside;
    s.q[i] = q;
  }
  s.status = inside ? IKStatus::Ok : IKStatus::OutsideLimits;
}

void markUnreachable(IKResult& res, int shoulder, int elbow, IKStep step) {
  for (int w = 1; w >= -1; w -= 2) {
    const IKConfig c{static_cast<std::int8_t>(shoulder), static_cast<std::int8_t>(elbow), static_cast<std::int8_t>(w)};
    IKSolution& s = res.solutions[static_cast<std::size_t>(configIndex(c))];
    s = IKSolution{};
    s.config = c;
    s.status = IKStatus::Unreachable;
    s.unreachable_step = step;
  }
}

void makeLinks(const Robot& r, Link L[6]) {
  for (int i = 0; i < 6; ++i) {
    const DHJoint& j = r.joints[static_cast<std::size_t>(i)];
    // The twists of the two families are 0 and ±π/2: use exact cosines and sines.
    double ca, sa;
    if (j.alpha == 0) {
      ca = 1, sa = 0;
    } else if (j.alpha == kPi / 2 || j.alpha == -kPi / 2) {
      ca = 0, sa = j.alpha > 0 ? 1 : -1;
    } else {
      ca = std::cos(j.alpha), sa = std::sin(j.alpha);
    }
    L[i] = Link{j.a, j.d, ca, sa, 1.0 / j.a, 1.0 / sa};
  }
}

double armScale(const Robot& r) {
  double L = 0;
  for (const auto& j : r.joints) L += std::abs(j.a) + std::abs(j.d);
  return L;
}

/// Elbow label (ik.hpp): +1 when P2 is above the line from P1 to the wrist point, seen with
/// the arm reaching forward: sign(shoulder · ((w × e) · (f × e3))), f = sign(a2) x1.
inline int elbowLabel(int shoulder, const Vector3d& f, const Vector3d& P1, const Vector3d& wrist, const Vector3d& P2) {
  const Vector3d fz(f.y(), -f.x(), 0.0);  // f × e3
  const double c = (wrist - P1).cross(P2 - P1).dot(fz);
  return shoulder * c >= 0 ? 1 : -1;
}

// ----- KUKA KR6 R900 sixx and arms of the same layout (Paper 1 §4) -----
void solveSphericalWrist(const Robot& robot, const Target& T, const IKSettings& o, IKResult& res, Recorder* rec) {
  const auto& J = robot.joints;
  const double d1 = J[0].d, a1 = J[0].a, a2 = J[1].a, a3 = J[2].a, d4 = J[3].d, d6 = J[5].d;
  const Vector3d a_e = T.R.col(2);
  const Vector3d p_e = T.p;
  // (23)-(24): wrist centre P_w = p_e − d6 a_e
  const Vector3d p_w = p_e - d6 * a_e;
  if (rec) {
    rec->init(kSphericalWristPoints, 5);
    rec->set(0, p_e);
    rec->set(1, p_w);
  }
  const double L = armScale(robot);
  const double tol = o.reach_tolerance;
  const Vector3d e3 = Vector3d::UnitZ();
  Link Lk[6];
  makeLinks(robot, Lk);

  // Arm plane Π_c = e0 ∧ e3 ∧ P_w ∧ e∞ (25): the vertical plane through the first axis and
  // P_w. Its horizontal direction towards P_w, ŵ. Shoulder singularity (Paper 1 §4-5, singular configurations): P_w on
  // the axis, Π_c = 0; then θ1 = q_free[0] (+ offset) defines the plane.
  const Vector3d pw_h(p_w.x(), p_w.y(), 0.0);
  const double rho = pw_h.norm();
  std::uint8_t singular0 = 0;
  Vector3d w_hat;
  if (rho <= o.singular_tolerance * L) {
    singular0 |= kSingularShoulder;
    const double th1 = o.q_free[0] + J[0].theta_offset;
    w_hat = Vector3d(std::cos(th1), std::sin(th1), 0.0);
  } else {
    w_hat = pw_h / rho;
  }

  for (int shoulder = 1; shoulder >= -1; shoulder -= 2) {
    // x1 = ±ŵ: front puts the wrist on the +x1 side (sign(a2) = +1 for this layout).
    const Vector3d x1 = shoulder * w_hat;
    const Vector3d z1 = e3.cross(x1);  // normal of Π_c, = DH z1 for alpha1 = -pi/2
    const Vector5d Pi_c = dualPlane(z1, 0.0);
    // (29): P1 from S0* = e0 − ½(d1² + a1²)e∞, Π1* = e3 + d1 e∞, and Π_c. The pair is
    // (d1 e3 ± a1 x1); the front/back choice of (30)-(31) is made with the wrist point
    // (Paper 1 tests with P_e, which mislabels about 6 % of random cases; P_w labels them all
    // right): the candidate on the x1 side.
    const PointPair Q1 = meet3(dualSphere(Vector3d::Zero(), d1 * d1 + a1 * a1), dualPlane(e3, d1), Pi_c);
    if (Q1.degenerate) {
      markUnreachable(res, shoulder, 1, IKStep::Elbow);
      markUnreachable(res, shoulder, -1, IKStep::Elbow);
      continue;
    }
    const Vector3d P1 = (Q1.a - d1 * e3).dot(x1) * a1 >= (Q1.b - d1 * e3).dot(x1) * a1 ? Q1.a : Q1.b;
    if (rec && rec->config.shoulder == shoulder) rec->set(2, P1);
    // θ1 from O1 = P1 (Paper 1 eq. (22)), i.e. from x1 (also when a1 = 0).
    const Angle th1 = Angle::fromXY(x1.x(), x1.y());
    const Vector3d O1(a1 * th1.c, a1 * th1.s, d1);
    // the target's approach and normal directions in frame 1 (shared by both elbows)
    const Vector3d a_1 = toChild(a_e, th1, Lk[0]), n_1 = toChild(T.R.col(0), th1, Lk[0]);

    // (32)-(34): elbow P2 from S1* = P1 − ½a2² e∞, S_w* = P_w − ½(d4² + a3²) e∞, Π_c.
    const PointPair Q2 = meet3(dualSphere(P1, a2 * a2), dualSphere(p_w, d4 * d4 + a3 * a3), Pi_c);
    const int real2 = reality(Q2, tol);
    if (rec && rec->config.shoulder == shoulder) rec->out->elbow_discriminant = Q2.discriminant;
    if (real2 < 0) {
      markUnreachable(res, shoulder, 1, IKStep::Elbow);
      markUnreachable(res, shoulder, -1, IKStep::Elbow);
      continue;
    }
    const Vector3d cand2[2] = {Q2.a, Q2.b};
    int label2[2];
    label2[0] = elbowLabel(shoulder, x1, P1, p_w, cand2[0]);
    label2[1] = -label2[0];  // mirror images across the line P1-P_w (tangent: equal points)
    std::uint8_t singular1 = singular0;
    if (real2 == 0) singular1 |= kSingularElbow;

    for (int k = 0; k < 2; ++k) {
      const int elbow = label2[k];
      const Vector3d& P2 = cand2[k];
      // (35)-(37): P_wx by the horizon of P_w on S2* = P2 − ½a3² e∞:
      // K* = P_w + (P_w·S2*) e∞ (Paper 1 §3.6, eq. (35); the printed "-" gives an imaginary sphere, "+" reproduces FK), the sphere of the points X on S2 with
      // (X − P2) ⊥ (X − P_w); Q_wx = (K* ∧ S2*)·Π_c.
      const Vector5d S2 = dualSphere(P2, a3 * a3);
      const Vector5d Pw = cga5::up(p_w);
      const Vector5d K = Pw + cga5::inner(Pw, S2) * cga5::eInf();
      const PointPair Qwx = meet3(K, S2, Pi_c);
      // The DH chain has P_w − P_wx = d4 z3, P_wx − P2 = a3 x3 and x3 × z3 = z2 = z1 (alpha3
      // = -pi/2): choose the candidate with ((P_wx − P2) × (P_w − P_wx))·z1 of sign a3·d4
      // (the orientation test of (37), Π_2wc).
      Vector3d P_wx;
      if (Qwx.degenerate) {
        P_wx = P2;  // a3 = 0: the horizon collapses onto P2
      } else {
        const double ca = (Qwx.a - P2).cross(p_w - Qwx.a).dot(z1);
        P_wx = (ca * a3 * d4 >= 0) ? Qwx.a : Qwx.b;
      }
      // Angles 1-3 by the recursive DH extraction (Paper 1 eq. (22)).
      Angle th[6];
      th[0] = th1;
      th[1] = angleFromOrigin(toChild(P2 - O1, th1, Lk[0]), Lk[1]);
      if (a3 != 0) {
        th[2] = angleFromOrigin(pointToChild(toChild(P_wx - O1, th1, Lk[0]), th[1], Lk[1]), Lk[2]);
      } else {
        th[2] = angleFromAxis(toChild(toChild((p_w - P2) / d4, th1, Lk[0]), th[1], Lk[1]), Lk[2]);
      }
      const Vector3d a_3 = toChild(toChild(a_1, th[1], Lk[1]), th[2], Lk[2]);
      const Vector3d n_3 = toChild(toChild(n_1, th[1], Lk[1]), th[2], Lk[2]);
      // Wrist: z4 = ±(z3 × a_e)/|z3 × a_e| (Paper 1 eq. (22)); in frame 3, z3 × a = (−a_y, a_x, 0).
      // Singular when a_e ∥ z3 (§4.7).
      const double s34 = std::hypot(a_3.x(), a_3.y());
      const bool wrist_singular = s34 <= o.singular_tolerance;
      // One wrist branch is computed; on this spherical wrist the other one is
      // (θ4 + π, −θ5, θ6 + π) (Paper 1 §4, eq. (28)).
      if (wrist_singular) {
        th[3] = Angle::of(o.q_free[3] + J[3].theta_offset);
      } else {
        th[3] = angleFromAxis(Vector3d(-a_3.y() / s34, a_3.x() / s34, 0.0), Lk[3]);
      }
      th[4] = angleFromAxis(toChild(a_3, th[3], Lk[3]), Lk[4]);
      // θ6 from R56 = R05ᵀ R_target (alpha6 = 0): its first column is n_e in frame 5.
      const Vector3d n_5 = toChild(toChild(n_3, th[3], Lk[3]), th[4], Lk[4]);
      th[5] = Angle::fromXY(n_5.x(), n_5.y());
      for (int b = 0; b < 2; ++b) {
        Angle tb[6] = {th[0], th[1], th[2], th[3], th[4], th[5]};
        if (b) {
          tb[3] = th[3].plusPi();
          tb[4] = th[4].negated();
          tb[5] = th[5].plusPi();
        }
        int wrist;
        if (wrist_singular) {
          wrist = b ? -1 : 1;
        } else {
          wrist = tb[4].s >= 0 ? 1 : -1;
        }
        const IKConfig cfg{static_cast<std::int8_t>(shoulder), static_cast<std::int8_t>(elbow),
                           static_cast<std::int8_t>(wrist)};
        finish(robot, tb, cfg, static_cast<std::uint8_t>(singular1 | (wrist_singular ? kSingularWrist : 0)), o, res);
        if (rec && rec->matches(shoulder, elbow, wrist)) {
          rec->set(3, P2);
          rec->set(4, P_wx);
        }
      }
    }
  }
}

/// UR wrist singularity (a_e ∥ z1): the DH θ6 nearest `desired` for which the elbow point
/// pair of P2 is real. With z4(θ6) = sinα5 (sinθ6 n_e + cosθ6 s_e) + cosα5 a_e and
/// P3 = P5 − d5 z4 − d4 z1, |P3 − P1|² = K + R cos(θ6 − ψ); the elbow reaches while it lies in
/// [(|a2| − |a3|)², (|a2| + |a3|)²]. Returns `desired` when it is feasible or nothing is.
double feasibleWristAngle(double desired, const Target& T, const Vector3d& p5, const Vector3d& z1, const Vector3d& P1,
                          const Link& l5, double d4, double d5, double a2, double a3) {
  const Vector3d C = p5 - d5 * l5.ca * T.R.col(2) - d4 * z1 - P1;
  const double w = -d5 * l5.sa;
  const double cn = C.dot(T.R.col(0)), cs = C.dot(T.R.col(1));
  const double K = C.squaredNorm() + w * w;
  const double R = 2 * std::abs(w) * std::sqrt(cn * cn + cs * cs);
  if (!(R > 1e-15)) return desired;  // |P3 − P1| does not depend on θ6
  const double psi = std::atan2(w * cn, w * cs);
  const double lo = std::abs(std::abs(a2) - std::abs(a3)), hi = std::abs(a2) + std::abs(a3);
  const double cmin = std::max((lo * lo - K) / R, -1.0), cmax = std::min((hi * hi - K) / R, 1.0);
  if (cmin > cmax) return desired;  // no θ6 works: truly unreachable
  const double A = std::acos(cmax), B = std::acos(cmin);  // feasible |θ6 − ψ| in [A, B]
  const double delta = std::remainder(desired - psi, kTwoPi);
  const double mag = std::abs(delta);
  if (mag >= A && mag <= B) return desired;
  return psi + (delta >= 0 ? 1.0 : -1.0) * std::clamp(mag, A, B);
}

// ----- Universal Robots (Paper 1 §5) -----
void solveUniversalRobots(const Robot& robot, const Target& T, const IKSettings& o, IKResult& res, Recorder* rec) {
  const auto& J = robot.joints;
  const double d1 = J[0].d, a2 = J[1].a, a3 = J[2].a, d4 = J[3].d, d5 = J[4].d, d6 = J[5].d;
  const Vector3d a_e = T.R.col(2);
  const Vector3d p_e = T.p;
  const double tol = o.reach_tolerance;
  const Vector3d e3 = Vector3d::UnitZ();
  Link Lk[6];
  makeLinks(robot, Lk);
  // (39): P5 = p_e − d6 a_e
  const Vector3d p5 = p_e - d6 * a_e;
  const Vector3d P1 = d1 * e3;  // (51)
  if (rec) {
    rec->init(kURPoints, 7);
    rec->set(0, p_e);
    rec->set(1, p5);
    rec->set(6, P1);
  }
  // (43)-(45): P_c by the horizon of the origin on S_c* = P5 − ½d4² e∞:
  // K0* = e0 + (e0·S_c*) e∞ (Paper 1 eq. (43) prints "-"; only "+" reproduces FK), in the horizontal plane through P5.
  const Vector5d Sc = dualSphere(p5, d4 * d4);
  const Vector5d K0 = cga5::e0() + cga5::inner(cga5::e0(), Sc) * cga5::eInf();
  const PointPair Qc = meet3(Sc, K0, dualPlane(e3, p5.z()));
  const int realc = reality(Qc, tol);
  if (rec) rec->out->shoulder_discriminant = Qc.discriminant;
  if (realc < 0) {
    for (int s = 1; s >= -1; s -= 2)
      for (int e = 1; e >= -1; e -= 2) markUnreachable(res, s, e, IKStep::Shoulder);
    return;
  }
  std::uint8_t singular0 = realc == 0 ? kSingularShoulder : 0;
  const Vector3d candC[2] = {Qc.a, Qc.b};
  int shoulderLabel[2];
  Vector3d z1s[2];
  Angle th1s[2];
  for (int c = 0; c < 2; ++c) {
    // z1 = (P5 − P_c)/d4 (the arm plane's normal, = DH z1); θ1 from z1 (a1 = 0, §4.5).
    z1s[c] = (p5 - candC[c]) / d4;
    z1s[c].z() = 0;  // P_c and P5 share z exactly; remove rounding
    z1s[c].normalize();
    th1s[c] = Angle::fromXY(-z1s[c].y() / Lk[0].sa, z1s[c].x() / Lk[0].sa);
    const Vector3d x1(th1s[c].c, th1s[c].s, 0.0);
    shoulderLabel[c] = a2 * candC[c].dot(x1) >= 0 ? 1 : -1;
  }
  if (realc == 0 || shoulderLabel[0] == shoulderLabel[1]) shoulderLabel[1] = -shoulderLabel[0];

  for (int c = 0; c < 2; ++c) {
    const int shoulder = shoulderLabel[c];
    const Vector3d& P_c = candC[c];
    const Vector3d z1 = z1s[c];
    const Angle th1 = th1s[c];
    const Vector3d x1(th1.c, th1.s, 0.0);
    // (46): Π_c through the first axis with normal z1 (built from P5 − P_c rather than from
    // P3: Paper 1 §5 builds it from P3, whose side of the axis varies; P_c is always
    // consistent, also when P_c is on the axis).
    const Vector5d Pi_c = dualPlane(z1, 0.0);
    const Vector3d O1(Lk[0].a * th1.c, Lk[0].a * th1.s, d1);
    const Vector3d a_1 = toChild(a_e, th1, Lk[0]), n_1 = toChild(T.R.col(0), th1, Lk[0]);
    // (47)-(48): Π_c∥ (parallel to Π_c through P5) and Π_c⊥ (through P5, normal a_e);
    // L45* = Π_c∥* ∧ Π_c⊥*. Wrist singularity (§4.7): a_e ∥ z1, L45 undefined.
    const Vector3d c15 = z1.cross(a_e);
    const bool wrist_singular = c15.norm() <= o.singular_tolerance;
    // (49): P4 from L45* ∧ S5*, S5* = P5 − ½d5² e∞ (one point pair for both wrist labels).
    const PointPair Q4 = wrist_singular ? PointPair{}
                                        : meet3(dualPlane(z1, z1.dot(p5)), dualPlane(a_e, a_e.dot(p5)), dualSphere(p5, d5 * d5));
    for (int b = 0; b < 2; ++b) {
      Vector3d P4;
      double th6_free = kNaN;
      if (wrist_singular) {
        // Free angle θ6 = q_free[5]: R05 = R_target Rz(θ6)ᵀ, z4 = R05 (0, sinα5, cosα5),
        // P4 = P5 − d5 z4. The "flip" partner uses θ6 + π. θ6 moves P3 = P4 − d4 z1 on a
        // circle, so the elbow may be out of reach for the requested θ6 but not for others:
        // then the nearest θ6 that keeps it in reach is used (Paper 1 §3.4: "unreachable"
        // only when no angles exist).
        th6_free = feasibleWristAngle(o.q_free[5] + J[5].theta_offset + (b ? kPi : 0.0), T, p5, z1, P1, Lk[4], d4,
                                      d5, a2, a3);
        const Matrix3d R05 = T.R * Eigen::AngleAxisd(th6_free, e3).toRotationMatrix().transpose();
        const Vector3d z4 = R05 * Vector3d(0.0, Lk[4].sa, Lk[4].ca);
        P4 = p5 - d5 * z4;
      } else {
        P4 = b ? Q4.b : Q4.a;
      }
      // (50): P3 on the line L34 = P4 ∧ Π_c* ∧ e∞ (through P4 along z1) at distance d4, the
      // candidate lying in Π_c (Paper 1 §5, robust alternative).
      const Vector3d y1 = z1.cross(e3);
      const PointPair Q3 = meet3(dualPlane(e3, P4.z()), dualPlane(y1, y1.dot(P4)), dualSphere(P4, d4 * d4));
      const Vector3d P3 = std::abs(Q3.a.dot(z1)) <= std::abs(Q3.b.dot(z1)) ? Q3.a : Q3.b;
      // (52)-(53): P2 from (P1 − ½a2² e∞) ∧ (P3 − ½a3² e∞) ∧ Π_c.
      const PointPair Q2 = meet3(dualSphere(P1, a2 * a2), dualSphere(P3, a3 * a3), Pi_c);
      int real2 = reality(Q2, tol);
      // A stretched (or folded) arm with a nearly singular wrist: P4 comes from two nearly
      // parallel planes (z1 x a_e ~ sin theta5) and carries an error ~1e-16 / sin(theta5) m, enough
      // to push a tangent elbow pair to a slightly negative discriminant (about 12 % of such
      // reachable UR5 poses were reported unreachable). Solve it as tangent; the forward
      // kinematics check in solve() keeps the solution only if it really reaches the pose.
      const double near_tangent = wrist_singular ? kNearTangent : std::min(1e-3, kNearTangent + 1e-14 / c15.norm());
      if (real2 < 0 && !Q2.degenerate && Q2.discriminant >= -near_tangent) real2 = 0;
      if (real2 < 0) {
        // both elbows of this shoulder / wrist branch
        for (int e = 1; e >= -1; e -= 2) {
          const int wl = wrist_singular ? (b ? -1 : 1) : 0;
          const int wlabel = wl != 0 ? wl : ((p5 - P4).dot(z1.cross(a_e)) >= 0 ? 1 : -1);
          if (rec && rec->matches(shoulder, e, wlabel)) {
            rec->out->elbow_discriminant = Q2.discriminant;
            rec->set(2, P_c);
            rec->set(3, P4);
            rec->set(4, P3);
          }
          if (wl != 0) {
            const IKConfig cfg{static_cast<std::int8_t>(shoulder), static_cast<std::int8_t>(e),
                               static_cast<std::int8_t>(wl)};
            IKSolution& s = res.solutions[static_cast<std::size_t>(configIndex(cfg))];
            s = IKSolution{};
            s.config = cfg;
            s.status = IKStatus::Unreachable;
            s.unreachable_step = IKStep::Elbow;
          } else {
            // No angles exist, but the wrist label is still geometric: with x4 = z3 × z4
            // (alpha4 = pi/2, z3 = z1) and alpha5 = -pi/2, sin θ5 has the sign of
            // z4·(z1 × a_e), z4 = (P5 − P4)/d5.
            const Vector3d z4 = (p5 - P4) / d5;
            const double s5 = z4.dot(z1.cross(a_e));
            const IKConfig cfg{static_cast<std::int8_t>(shoulder), static_cast<std::int8_t>(e),
                               static_cast<std::int8_t>(s5 >= 0 ? 1 : -1)};
            IKSolution& s = res.solutions[static_cast<std::size_t>(configIndex(cfg))];
            s = IKSolution{};
            s.config = cfg;
            s.status = IKStatus::Unreachable;
            s.unreachable_step = IKStep::Elbow;
          }
        }
        continue;
      }
      std::uint8_t singular1 = singular0;
      if (real2 == 0) singular1 |= kSingularElbow;
      if (wrist_singular) singular1 |= kSingularWrist;
      const Vector3d f = (a2 >= 0 ? 1.0 : -1.0) * x1;
      const Vector3d cand2[2] = {Q2.a, Q2.b};
      const int l0 = elbowLabel(shoulder, f, P1, P3, cand2[0]);
      // Axes 2, 3 and 4 are parallel (alpha2 = alpha3 = 0): R_14 = Rot_z(φ) Rot_x(alpha4) with
      // φ = θ2 + θ3 + θ4, so z4 = (P5 − P4)/d5 gives φ (§4.5, a4 = 0), and θ5, θ6 follow from
      // φ alone: they are shared by both elbows.
      const Angle phi = angleFromAxis(toChild((p5 - P4) / d5, th1, Lk[0]), Lk[3]);
      Angle th[6];
      th[0] = th1;
      th[4] = angleFromAxis(toChild(a_1, phi, Lk[3]), Lk[4]);
      const Vector3d n_5 = toChild(toChild(n_1, phi, Lk[3]), th[4], Lk[4]);
      th[5] = Angle::fromXY(n_5.x(), n_5.y());
      const Vector3d P3_1 = toChild(P3 - O1, th1, Lk[0]);
      for (int k = 0; k < 2; ++k) {
        const Vector3d& P2 = cand2[k];
        const int elbow = k == 0 ? l0 : -l0;
        th[1] = angleFromOrigin(toChild(P2 - O1, th1, Lk[0]), Lk[1]);
        th[2] = angleFromOrigin(pointToChild(P3_1, th[1], Lk[1]), Lk[2]);
        th[3] = Angle{0.0, 0.0, phi.t - th[1].t - th[2].t};  // only its value is used
        const int wrist = wrist_singular ? (b ? -1 : 1) : (th[4].s >= 0 ? 1 : -1);
        const IKConfig cfg{static_cast<std::int8_t>(shoulder), static_cast<std::int8_t>(elbow),
                           static_cast<std::int8_t>(wrist)};
        finish(robot, th, cfg, singular1, o, res);
        if (rec && rec->matches(shoulder, elbow, wrist)) {
          rec->out->elbow_discriminant = Q2.discriminant;
          rec->set(2, P_c);
          rec->set(3, P4);
          rec->set(4, P3);
          rec->set(5, P2);
        }
      }
    }
  }
}

bool validPose(const Eigen::Isometry3d& T) { return isRigid(T.matrix()); }

/// Pose error of F against T: (position difference, m; rotation vector of R_T R_F^T, rad,
/// first order).
Eigen::Matrix<double, 6, 1> poseError(const Eigen::Isometry3d& F, const Eigen::Isometry3d& T) {
  const Matrix3d E = T.linear() * F.linear().transpose();
  Eigen::Matrix<double, 6, 1> r;
  r << T.translation() - F.translation(), 0.5 * Vector3d(E(2, 1) - E(1, 2), E(0, 2) - E(2, 0), E(1, 0) - E(0, 1));
  return r;
}

Eigen::Matrix<double, 6, 1> poseError(const Robot& robot, const Vector6d& q, const Eigen::Isometry3d& T) {
  return poseError(robot.forward(q), T);
}

/// A few damped Gauss-Newton steps on the joints (Levenberg 1944; Marquardt 1963) from an
/// analytic solution that misses the pose by rounding: near the wrist singularity the wrist point
/// P4 comes from two nearly parallel planes and carries an error ~1e-16 / sin(theta5) m, and with a
/// stretched elbow that error reaches the angles undamped. The damping keeps the step bounded in
/// the singular directions, where the pose does not depend on the joints.
void polish(const Robot& robot, const Eigen::Isometry3d& T, Vector6d& q) {
  Eigen::Matrix<double, 6, 1> r = poseError(robot, q, T);
  for (int it = 0; it < 8 && r.cwiseAbs().maxCoeff() > 1e-14; ++it) {
    Eigen::Matrix<double, 6, 6> J;
    for (int k = 0; k < 6; ++k) {
      Vector6d h = Vector6d::Zero();
      h[k] = 1e-6;
      J.col(k) = (poseError(robot, q - h, T) - poseError(robot, q + h, T)) / 2e-6;  // d(FK)/dq
    }
    Eigen::Matrix<double, 6, 6> A = J.transpose() * J;
    A.diagonal().array() += 1e-12 * (1.0 + A.diagonal().maxCoeff());
    const Vector6d dq = A.ldlt().solve(J.transpose() * r);
    const Vector6d qn = q + dq;
    const Eigen::Matrix<double, 6, 1> rn = poseError(robot, qn, T);
    if (!(rn.squaredNorm() < r.squaredNorm())) break;
    q = qn;
    r = rn;
  }
}

/// Demotes every solution whose forward kinematics misses the target (ik.hpp, IKStep::FkCheck),
/// after polishing the ones that miss by rounding: no solution is reported Ok unless FK(q) is
/// the pose it was asked for.
void verifyByForwardKinematics(const Robot& robot, const Eigen::Isometry3d& T, IKResult& res) {
  const Matrix3d R = T.linear();
  const double e = (R.transpose() * R - Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double pos_tol = kIKPositionTolerance + e * armScale(robot);
  const double rot_tol = kIKRotationTolerance + 2 * e;
  for (IKSolution& s : res.solutions) {
    if (s.status != IKStatus::Ok && s.status != IKStatus::OutsideLimits) continue;
    Eigen::Isometry3d F = robot.forward(s.q);  // one FK per solution unless it needs polishing
    if (e < 1e-12 && poseError(F, T).cwiseAbs().maxCoeff() > 1e-12) {
      polish(robot, T, s.q);
      F = robot.forward(s.q);
    }
    const double dp = (F.translation() - T.translation()).cwiseAbs().maxCoeff();
    const double dr = (F.linear() - R).cwiseAbs().maxCoeff();
    if (dp <= pos_tol && dr <= rot_tol) continue;
    const IKConfig c = s.config;
    s = IKSolution{};
    s.config = c;
    s.status = IKStatus::Unreachable;
    s.unreachable_step = IKStep::FkCheck;
  }
}

IKResult solve(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const IKSettings& o, Recorder* rec) {
  IKResult res;
  for (int k = 0; k < 8; ++k) res.solutions[static_cast<std::size_t>(k)].config = configFromIndex(k);
  const ArmGeometry g = robot.geometry();
  if (g == ArmGeometry::Unsupported || !validPose(T_base_tool) || !o.q_free.allFinite()) {
    for (auto& s : res.solutions) s.status = IKStatus::InvalidInput;
    res.status = IKStatus::InvalidInput;
    return res;
  }
  // Flange pose in DH frame 0: T_dh0_flange = T_base_dh0⁻¹ T_base_tool T_flange_tool⁻¹.
  const Eigen::Isometry3d Tf = robot.T_base_dh0.inverse(Eigen::Isometry) * T_base_tool *
                               robot.T_flange_tool.inverse(Eigen::Isometry);
  Target t{Tf.linear(), Tf.translation()};
  if (g == ArmGeometry::SphericalWrist)
    solveSphericalWrist(robot, t, o, res, rec);
  else
    solveUniversalRobots(robot, t, o, res, rec);
  verifyByForwardKinematics(robot, T_base_tool, res);
  res.status = IKStatus::Unreachable;
  for (const auto& s : res.solutions) {
    if (s.status == IKStatus::Ok) {
      res.status = IKStatus::Ok;
      break;
    }
    if (s.status == IKStatus::OutsideLimits) res.status = IKStatus::OutsideLimits;
  }
  return res;
}

Eigen::Isometry3d poseAt(const double* poses, std::size_t i) {
  Eigen::Isometry3d T;
  T.matrix() = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(poses + 16 * i);
  return T;
}

}  // namespace

const char* toString(IKStatus s) {
  switch (s) {
    case IKStatus::Ok: return "ok";
    case IKStatus::OutsideLimits: return "outside_limits";
    case IKStatus::Unreachable: return "unreachable";
    default: return "invalid_input";
  }
}

const char* toString(IKStep s) {
  switch (s) {
    case IKStep::Shoulder: return "shoulder";
    case IKStep::Elbow: return "elbow";
    case IKStep::FkCheck: return "fk_check";
    default: return "";
  }
}

IKResult ik(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const IKSettings& options) {
  return solve(robot, T_base_tool, options, nullptr);
}

IKConstruction ikConstruction(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const IKConfig& config,
                              const IKSettings& options) {
  IKConstruction out;
  out.geometry = robot.geometry();
  Recorder rec;
  rec.config = config;
  rec.out = &out;
  const IKResult r = solve(robot, T_base_tool, options, &rec);
  out.solution = r.solutions[static_cast<std::size_t>(configIndex(config))];
  return out;
}

IKSolution ikClosest(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const Vector6d& q_current,
                     const IKSettings& options, const ClosestSettings& closest) {
  // Joint values beyond any real joint's travel (here |q| > 1e6 rad) are not a configuration:
  // wrapping them loses every digit, and the "closest" solution would be arbitrary.
  if (q_current.allFinite() && q_current.cwiseAbs().maxCoeff() > 1e6)
    throw std::invalid_argument("q_current: joint values must lie within +-1e6 rad");
  IKSettings o = options;
  if (q_current.allFinite()) o.q_free = q_current;
  const IKResult r = solve(robot, T_base_tool, o, nullptr);
  IKSolution best;
  best.status = r.status;
  if (!q_current.allFinite()) {
    best.status = IKStatus::InvalidInput;
    return best;
  }
  double best_cost = std::numeric_limits<double>::infinity();
  for (const IKSolution& s : r.solutions) {
    if (s.status != IKStatus::Ok) continue;
    IKSolution c = s;
    double cost = 0;
    for (int i = 0; i < 6; ++i) {
      const DHJoint& j = robot.joints[static_cast<std::size_t>(i)];
      // the 2π multiple of q_i nearest q_current_i (inside the limits when respected)
      const double k0 = std::round((q_current[i] - s.q[i]) / kTwoPi);
      double bq = s.q[i];
      double bd = std::numeric_limits<double>::infinity();
      for (int dk = -1; dk <= 1; ++dk) {
        const double v = s.q[i] + (k0 + dk) * kTwoPi;
        if (o.respect_limits && !(v >= j.q_min - 1e-12 && v <= j.q_max + 1e-12)) continue;
        const double dist = std::abs(v - q_current[i]);
        if (dist < bd) bd = dist, bq = v;
      }
      c.q[i] = bq;
      const double dq = bq - q_current[i];
      cost += closest.weights[i] * dq * dq;
    }
    if (cost < best_cost) best_cost = cost, best = c;
  }
  return best;
}

void ikBatch(const Robot& robot, const double* poses, std::size_t n, IKResult* out, const IKSettings& options,
             int num_threads) {
  const long long N = static_cast<long long>(n);
#pragma omp parallel for schedule(static) num_threads(resolveThreads(num_threads)) if (num_threads != 1 && N > 64)
  for (long long i = 0; i < N; ++i) out[i] = solve(robot, poseAt(poses, static_cast<std::size_t>(i)), options, nullptr);
}

std::size_t ikTrajectory(const Robot& robot, const double* poses, std::size_t n, const Vector6d& q_start,
                         double* out_q, IKStatus* out_status, const IKSettings& options, const ClosestSettings& closest) {
  Vector6d q = q_start;
  std::size_t good = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const IKSolution s = ikClosest(robot, poseAt(poses, i), q, options, closest);
    out_status[i] = s.status;
    Eigen::Map<Vector6d> row(out_q + 6 * i);
    if (s.status == IKStatus::Ok) {
      row = s.q;
      q = s.q;
      ++good;
    } else {
      row.setConstant(kNaN);
    }
  }
  return good;
}

}  // namespace scanalign
