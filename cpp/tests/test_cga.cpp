// CGA core G(4,1) (Kleppe, PhD thesis, NTNU 2018, ch. 4: (4.45), (4.49), (4.56), (4.59)-(4.67), (4.62)-(4.63), (4.73);
// Paper 5 eqs. (10), (33)-(35)): algebra identities and typed
// objects against analytic truth.
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Geometry>  // cross()

#include "scanalign/cga/multivector.hpp"
#include "scanalign/cga/objects.hpp"

using namespace scanalign::cga;

namespace {
Multivector randomMv(std::mt19937& g) {
  std::normal_distribution<double> n;
  Multivector::Coeffs c;
  for (int i = 0; i < 32; ++i) c[i] = n(g);
  return Multivector::fromOrthonormal(c);
}
Vector3 randomVec(std::mt19937& g, double s = 1.0) {
  std::uniform_real_distribution<double> u(-s, s);
  return Vector3(u(g), u(g), u(g));
}
void expectMvNear(const Multivector& a, const Multivector& b, double tol) {
  EXPECT_LE((a - b).maxAbs(), tol) << "a=" << a.orthonormal().transpose() << "\nb=" << b.orthonormal().transpose();
}
}  // namespace

TEST(CgaAlgebra, NullBasis) {
  const Multivector e0 = Multivector::e0(), ei = Multivector::eInf();
  EXPECT_DOUBLE_EQ((e0 * e0).maxAbs(), 0.0);                 // (4.45)
  EXPECT_DOUBLE_EQ((ei * ei).maxAbs(), 0.0);
  EXPECT_DOUBLE_EQ(e0.inner(ei).scalar(), -1.0);             // e0 . einf = -1
  const Multivector Ic = e0.outer(Multivector::e1()).outer(Multivector::e2()).outer(Multivector::e3()).outer(ei);
  expectMvNear(Ic, Multivector::pseudoscalar(), 1e-15);    // (4.48)-(4.49)
  expectMvNear(Ic * Ic, Multivector(-1.0), 1e-15);
  expectMvNear(Ic.inverse(), -Ic, 1e-15);
  EXPECT_DOUBLE_EQ(Ic.get("e0123inf"), 1.0);
  EXPECT_DOUBLE_EQ(Ic.get("einf0123"), 1.0);   // 4 swaps
  EXPECT_DOUBLE_EQ(Ic.get("e1023inf"), -1.0);
  EXPECT_THROW(Ic.get("e11"), std::invalid_argument);
  EXPECT_THROW(Ic.get("x1"), std::invalid_argument);
  // Euclidean duals (4.39): e1* = -e23, e12* = e3 with A I3^{-1}.
  const Multivector I3inv = Multivector::pseudoscalar3().inverse();
  expectMvNear(Multivector::e1() * I3inv, -Multivector::named("e23"), 1e-15);
  expectMvNear(Multivector::named("e12") * I3inv, Multivector::e3(), 1e-15);
}

TEST(CgaAlgebra, ProductIdentitiesOnRandomMultivectors) {
  std::mt19937 g(7);
  for (int k = 0; k < 20; ++k) {
    const Multivector A = randomMv(g), B = randomMv(g), C = randomMv(g);
    expectMvNear((A * B) * C, A * (B * C), 1e-11);                 // associativity
    expectMvNear(A.outer(B).outer(C), A.outer(B.outer(C)), 1e-11);
    expectMvNear(A.dual().dual(), -A, 1e-12);                      // (A*)* = -A
    expectMvNear(A.dual().undual(), A, 1e-12);                     // (4.51)
    expectMvNear((A * B).reverse(), B.reverse() * A.reverse(), 1e-11);
    // vectors: a.b = 1/2(ab+ba), a^b = 1/2(ab-ba) (4.21)-(4.22)
    const Multivector a = A.grade(1), b = B.grade(1);
    expectMvNear(a.inner(b), (a * b + b * a) * 0.5, 1e-12);
    expectMvNear(a.outer(b), (a * b - b * a) * 0.5, 1e-12);
    expectMvNear(a * b, a.inner(b) + a.outer(b), 1e-12);           // (4.18)
    // left contraction of a vector on a blade: a _| (b^c) = (a.b) c - (a.c) b
    const Multivector c = C.grade(1);
    expectMvNear(a.leftContraction(b.outer(c)), c * a.inner(b).scalar() - b * a.inner(c).scalar(), 1e-12);
    // null-basis coefficients round trip
    expectMvNear(Multivector::fromNull(A.nullCoefficients()), A, 1e-12);
    // general inverse
    expectMvNear(A * A.inverse(), Multivector(1.0), 1e-9);
  }
}

TEST(CgaObjects, UpDownAndPointDistance) {
  std::mt19937 g(1);
  for (int k = 0; k < 20; ++k) {
    const Vector3 a = randomVec(g, 2), b = randomVec(g, 2);
    const Multivector A = up(a), B = up(b);
    EXPECT_NEAR((A * A).maxAbs(), 0.0, 1e-12);                                      // null (thesis (4.45), (4.49), (4.56))
    EXPECT_LT((down(A * 3.7) - a).norm(), 1e-14);
    EXPECT_NEAR(A.inner(B).scalar(), -0.5 * (a - b).squaredNorm(), 1e-12);         // (4.56)
    EXPECT_NEAR(pointDistance(a, b), (a - b).norm(), 1e-12);
    EXPECT_NEAR(-Multivector::eInf().inner(A).scalar(), 1.0, 1e-15);
    const Vector5 va = toVector5(A), vb = toVector5(B);
    EXPECT_NEAR(va.dot(innerProductMatrix() * vb), A.inner(B).scalar(), 1e-12);    // (5.32)
  }
  EXPECT_THROW(down(Multivector::eInf()), std::domain_error);
  EXPECT_THROW(up(Vector3(NAN, 0, 0)), std::invalid_argument);
}

TEST(CgaObjects, SpheresAndPlanes) {
  std::mt19937 g(2);
  for (int k = 0; k < 10; ++k) {
    const Vector3 c = randomVec(g);
    const double r = 0.3 + 0.1 * k;
    const Sphere s(c, r);
    EXPECT_NEAR((s.dual() * s.dual()).scalar(), r * r, 1e-12);   // (4.61)
    // four points on the sphere -> the same sphere (4.58)
    Vector3 p[4];
    for (auto& q : p) q = c + r * randomVec(g).normalized();
    const Sphere f = Sphere::throughPoints(p[0], p[1], p[2], p[3]);
    EXPECT_LT((f.center - c).norm(), 1e-9);
    EXPECT_NEAR(f.radius(), r, 1e-9);
    const Vector3 x = randomVec(g, 3);
    EXPECT_NEAR(spherePointInner(s, x), 0.5 * (r * r - (x - c).squaredNorm()), 1e-12);   // thesis (4.59)-(4.61), Paper 5 eq. (10)
    EXPECT_NEAR(pointSphereDistance(x, s), (x - c).norm() - r, 1e-9);                    // P5(10)
    const Plane pl(randomVec(g), 0.4);
    EXPECT_NEAR(pointPlaneDistance(x, pl), pl.normal.dot(x) - pl.distance, 1e-12);      // (4.67)
  }
  // with the dual (4.50), the plane through (0,0,1),(1,0,1),(0,1,1) is -(e3 + einf) in this convention.
  const Plane q = Plane::throughPoints({0, 0, 1}, {1, 0, 1}, {0, 1, 1});
  EXPECT_LT((q.normal - Vector3(0, 0, -1)).norm(), 1e-12);
  EXPECT_NEAR(q.distance, -1.0, 1e-12);
  EXPECT_THROW(Sphere::fromDual(Plane(Vector3::UnitZ(), 1).dual()), std::domain_error);
  EXPECT_THROW(Plane(Vector3::Zero(), 1), std::invalid_argument);
  EXPECT_TRUE(!Sphere::fromDual(up(Vector3(1, 2, 3)) + Multivector::eInf() * 0.5).isReal());
}

TEST(CgaObjects, PointPairExtractionAndReality) {
  std::mt19937 g(3);
  for (int k = 0; k < 20; ++k) {
    const Vector3 a = randomVec(g), b = randomVec(g);
    const Multivector Q = pointPair(a, b);
    EXPECT_NEAR((Q * Q).scalar(), std::pow(0.5 * (a - b).squaredNorm(), 2), 1e-10);   // thesis (4.62)-(4.63)
    const auto [pm, pp] = pointPairPoints(Q);
    EXPECT_LT((pm - a).norm(), 1e-9);
    EXPECT_LT((pp - b).norm(), 1e-9);
    EXPECT_LT((roundCenter(Q) - 0.5 * (a + b)).norm(), 1e-9);
    EXPECT_NEAR(roundRadius2(Q), 0.25 * (a - b).squaredNorm(), 1e-9);
    const Vector3 c = b + Vector3(0.1, 0.2, 0.3), d = b + Vector3(-0.3, 0.1, 0.2);
    const double sr2 = Sphere::throughPoints(a, b, c, d).radius2;   // sphere as a round
    EXPECT_NEAR(roundRadius2(up(a).outer(up(b)).outer(up(c)).outer(up(d))), sr2, 1e-8 * std::max(1.0, sr2));
  }
  // sphere meet plane meet plane (thesis (4.70)-(4.73), Paper 1 §3.4): unit sphere, plane z = 0, plane x = h.
  const Sphere s(Vector3::Zero(), 1.0);
  const Plane z(Vector3::UnitZ(), 0.0);
  for (double h : {0.6, 1.0, 1.4}) {
    const Multivector Cs = meetSpherePlane(s, z);
    const Multivector Qs = meetPlaneCircle(Plane(Vector3::UnitX(), h), Cs);
    const Multivector Q = Qs.undual();
    const Reality r = pointPairReality(Q);
    if (h < 1) {
      ASSERT_EQ(r, Reality::Real);
      auto [p1, p2] = pointPairPoints(Q);
      const double y = std::sqrt(1 - h * h);
      EXPECT_NEAR(p1.x(), h, 1e-12);
      EXPECT_NEAR(p2.x(), h, 1e-12);
      EXPECT_NEAR(std::abs(p1.y()), y, 1e-12);
      EXPECT_NEAR(p1.y(), -p2.y(), 1e-12);
      EXPECT_NEAR(p1.z(), 0, 1e-12);
    } else if (h == 1) {
      EXPECT_EQ(r, Reality::Tangent);
    } else {
      EXPECT_EQ(r, Reality::Imaginary);
      EXPECT_THROW(pointPairPoints(Q), std::domain_error);
    }
  }
}

TEST(CgaObjects, LinesCirclesMeets) {
  std::mt19937 g(4);
  for (int k = 0; k < 10; ++k) {
    const Vector3 a = randomVec(g), b = randomVec(g);
    const Line l = Line::throughPoints(a, b);
    const Multivector L = up(a).outer(up(b)).outer(Multivector::eInf());   // (4.68)
    const Line f = Line::fromDirect(L);
    EXPECT_LT((f.direction - (b - a).normalized()).norm(), 1e-9);
    EXPECT_LT((f.point - l.point).norm(), 1e-9);
    EXPECT_LT((Line::fromDual(l.dual()).point - l.point).norm(), 1e-9);
    // line meet plane (4.73): flat point at the Euclidean intersection (thesis (4.73))
    const Plane p(randomVec(g), 0.2);
    const double t = (p.distance - p.normal.dot(a)) / p.normal.dot(b - a);
    EXPECT_LT((flatPointLocation(meetLinePlane(l, p)) - (a + t * (b - a))).norm(), 1e-8);
    // circle through three points: centre and radius
    const Vector3 c = randomVec(g);
    const double r = 0.5;
    const Vector3 u = randomVec(g).normalized(), v = u.cross(randomVec(g)).normalized();
    const Multivector C = circle(c + r * u, c + r * v, c - r * u);
    EXPECT_LT((roundCenter(C) - c).norm(), 1e-9);
    EXPECT_NEAR(roundRadius2(C), r * r, 1e-9);
    // plane meet plane is a dual line along n1 x n2
    const Plane p2(randomVec(g), -0.3);
    const Line m = Line::fromDual(meetPlanes(p, p2));
    EXPECT_NEAR(std::abs(m.direction.dot(p.normal.cross(p2.normal).normalized())), 1.0, 1e-9);
    EXPECT_NEAR(pointPlaneDistance(m.point, p), 0.0, 1e-9);
    EXPECT_NEAR(pointPlaneDistance(m.point, p2), 0.0, 1e-9);
  }
}

TEST(CgaMotor, AppliesRigidTransform) {
  std::mt19937 g(5);
  for (int k = 0; k < 20; ++k) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(3.0 * (k + 1) / 21, randomVec(g).normalized()));
    const Vector3 t = randomVec(g);
    const Motor M = Motor::fromQuaternion(q, t);
    expectMvNear(M.multivector() * M.multivector().reverse(), Multivector(1.0), 1e-12);   // M ~M = 1, Paper 5 eq. (35)
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Vector3 x = randomVec(g, 2);
    EXPECT_LT((M.apply(x) - (R * x + t)).norm(), 1e-12);
    EXPECT_LT((M.matrix().topLeftCorner<3, 3>() - R).norm(), 1e-12);
    EXPECT_LT((M.translation() - t).norm(), 1e-12);
    const Motor M2 = Motor::fromMatrix(M.matrix());
    EXPECT_LT((M2.apply(x) - M.apply(x)).norm(), 1e-12);
    // planes, spheres and lines move with the motion
    const Plane p = Plane::throughPoint(randomVec(g), x);
    const Plane pm = M.apply(p);
    EXPECT_LT((pm.normal - R * p.normal).norm(), 1e-12);
    EXPECT_NEAR(pointPlaneDistance(R * x + t, pm), 0.0, 1e-12);
    const Sphere sm = M.apply(Sphere(x, 0.3));
    EXPECT_LT((sm.center - (R * x + t)).norm(), 1e-12);
    EXPECT_NEAR(sm.radius(), 0.3, 1e-12);
    const Line lm = M.apply(Line(x, Vector3::UnitX()));
    EXPECT_LT((lm.direction - R.col(0)).norm(), 1e-12);
    // composition and inverse
    const Motor N = Motor::fromQuaternion(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vector3::UnitZ())), randomVec(g));
    EXPECT_LT(((M * N).matrix() - M.matrix() * N.matrix()).norm(), 1e-12);
    EXPECT_LT((M.inverse().apply(M.apply(x)) - x).norm(), 1e-12);
    EXPECT_LT((Motor::interpolate(M, N, 0.0).matrix() - M.matrix()).norm(), 1e-12);
    EXPECT_LT((Motor::interpolate(M, N, 1.0).matrix() - N.matrix()).norm(), 1e-12);
    EXPECT_NO_THROW(Motor::fromMultivector(M.multivector()));
  }
  Eigen::Matrix4d bad = Eigen::Matrix4d::Identity();
  bad(0, 0) = 2;
  EXPECT_THROW(Motor::fromMatrix(bad), std::invalid_argument);
  EXPECT_THROW(Motor::fromMultivector(Multivector(2.0)), std::invalid_argument);
}

TEST(CgaObjects, DirectionFormulasAndHorizon) {
  std::mt19937 g(6);
  const Multivector e0 = Multivector::e0(), ei = Multivector::eInf();
  for (int k = 0; k < 10; ++k) {
    const Vector3 a = randomVec(g), b = randomVec(g);
    // P1 (18): (L.e0).einf = a - b for L = A^B^einf.
    const Multivector L = up(a).outer(up(b)).outer(ei);
    expectMvNear(L.inner(e0).inner(ei), Multivector::vector(a - b), 1e-12);
    // P1 (19): -(Pi*^einf).e0 = n for Pi* = n + delta einf.
    const Plane p(randomVec(g), 0.7);
    expectMvNear(-(p.dual().outer(ei)).inner(e0), Multivector::vector(p.normal), 1e-12);
    // thesis (4.59)-(4.61), Paper 5 eq. (10): S*.up(x) > 0 inside, < 0 outside
    const Sphere s(a, 0.5);
    EXPECT_GT(spherePointInner(s, a + Vector3(0.3, 0, 0)), 0);
    EXPECT_LT(spherePointInner(s, a + Vector3(0.6, 0, 0)), 0);
    // Horizon (Paper 1 §3.6, with the sign of K* corrected): S* = P1 - 1/2 d^2 einf, K* = P2 + (P2.S*) einf.
    const Vector3 p1 = a, p2 = a + 2.0 * randomVec(g).normalized();
    const double d = 0.8;
    const Multivector S = up(p1) - ei * (0.5 * d * d);
    const Multivector K = up(p2) + ei * up(p2).inner(S).scalar();
    EXPECT_NEAR(Sphere::fromDual(K).radius2, (p2 - p1).squaredNorm() - d * d, 1e-12);
    const Plane pl = Plane::throughPoints(p1, p2, p1 + randomVec(g));
    const Multivector Q = pl.dual().outer(K.outer(S)).undual();
    ASSERT_EQ(pointPairReality(Q), Reality::Real);
    const auto [x1, x2] = pointPairPoints(Q);
    for (const Vector3& x : {x1, x2}) {
      EXPECT_NEAR((x - p1).dot(x - p2), 0.0, 1e-9);
      EXPECT_NEAR((x - p1).norm(), d, 1e-9);
      EXPECT_NEAR(pointPlaneDistance(x, pl), 0.0, 1e-9);
    }
  }
}

// ---------------------------------------------------------------------------
// Paper 1 §3.7: signed angle (17), rotation planes (20), (21)
// ---------------------------------------------------------------------------

TEST(CgaAngle, SignedAngleMatchesCrossProductOracle) {
  std::mt19937 g(91);
  for (int i = 0; i < 200; ++i) {
    const Vector3 n = randomVec(g).normalized();
    // a, b perpendicular to N* = n, random lengths
    Vector3 a = randomVec(g, 2.0), b = randomVec(g, 2.0);
    a -= n * n.dot(a);
    b -= n * n.dot(b);
    const Multivector N = rotationPlaneFromAxis(n);
    EXPECT_NEAR(rotationAxis(N).dot(n), 1.0, 1e-12);          // N* = N I3^{-1} = n
    const double truth = std::atan2(a.cross(b).dot(n), a.dot(b));  // independent oracle
    EXPECT_NEAR(signedAngle(a, b, N), truth, 1e-10);
    EXPECT_NEAR(signedAngle(a, b, N * 3.5), truth, 1e-10);     // N normalised (Paper 1 §3.7)
    EXPECT_NEAR(signedAngle(a, b, -N), -truth, 1e-10);          // opposite plane orientation
    // rotating a by theta about n (rotor, Paper 4 §3.5) lands on b's direction
    const Motor M = Motor::fromQuaternion(Eigen::Quaterniond(Eigen::AngleAxisd(truth, n)), Vector3::Zero());
    EXPECT_LE((M.apply(a).normalized() - b.normalized()).norm(), 1e-9);
  }
  const Multivector e12 = Multivector::e1().outer(Multivector::e2());
  expectMvNear(rotationPlaneFromAxis(Vector3::UnitZ()), e12, 1e-15);  // e3 I3 = e12
  EXPECT_NEAR(signedAngle(Vector3::UnitX(), Vector3::UnitY(), e12), EIGEN_PI / 2, 1e-15);
  EXPECT_NEAR(std::abs(signedAngle(Vector3::UnitX(), -Vector3::UnitX(), e12)), EIGEN_PI, 1e-15);
  EXPECT_THROW(rotationPlaneFromAxis(Vector3::Zero()), std::invalid_argument);
  EXPECT_THROW(signedAngle(Vector3::UnitX(), Vector3::UnitY(), Multivector()), std::domain_error);
  EXPECT_THROW(rotationAxis(Multivector::e1()), std::domain_error);
  EXPECT_THROW(rotationAxis(e12 + Multivector::e1()), std::invalid_argument);
}

TEST(CgaAngle, RotationPlanesOfLinesAndPlanes) {
  std::mt19937 g(92);
  for (int i = 0; i < 50; ++i) {
    const Vector3 a = randomVec(g, 3.0), b = randomVec(g, 3.0);
    // (20) with L = up(a)^up(b)^einf: N* = (b - a)/|b - a| (Paper 1 §3.7)
    const Multivector L = up(a).outer(up(b)).outer(Multivector::eInf());
    const Multivector N = rotationPlanePerpendicularToLine(L.dual());
    EXPECT_NEAR(N.scalarProduct(N.reverse()), 1.0, 1e-12);
    EXPECT_LE((rotationAxis(N) - (b - a).normalized()).norm(), 1e-9);
    // the typed Line (direct (p + e0)^d^einf) gives N* = d
    const Line l = Line::throughPoints(a, b);
    EXPECT_LE((rotationAxis(rotationPlanePerpendicularToLine(l)) - l.direction).norm(), 1e-9);
    // (21): typed plane oriented so that N* = normal; the raw formula on the direct plane
    // gives -n of the dual, i.e. the right-hand normal of PA^PB^PC^einf
    const Plane p(randomVec(g), randomVec(g)[0]);
    EXPECT_LE((rotationAxis(rotationPlaneParallelToPlane(p)) - p.normal).norm(), 1e-12);
    EXPECT_LE((rotationAxis(rotationPlaneParallelToPlane(p.direct() * 2.0)) + p.normal).norm(), 1e-12);
    const Vector3 c = randomVec(g, 3.0);
    const Multivector Pi = up(a).outer(up(b)).outer(up(c)).outer(Multivector::eInf());
    EXPECT_LE((rotationAxis(rotationPlaneParallelToPlane(Pi)) - (b - a).cross(c - a).normalized()).norm(), 1e-9);
  }
}

// ---------------------------------------------------------------------------
// Typed PointPair / FlatPoint (thesis (4.62)-(4.63), (4.69))
// ---------------------------------------------------------------------------

TEST(CgaPointPair, RealPairSquareAndPoints) {
  std::mt19937 g(93);
  for (int i = 0; i < 50; ++i) {
    const Vector3 a = randomVec(g, 2.0), b = randomVec(g, 2.0);
    const PointPair Q = PointPair::fromPoints(a, b);
    const double h = 0.5 * (a - b).squaredNorm();
    EXPECT_NEAR(Q.square(), h * h, 1e-10 * std::max(1.0, h * h));  // thesis (4.62)-(4.63)
    EXPECT_EQ(Q.reality(), Reality::Real);
    const auto [pm, pp] = Q.points();
    EXPECT_LE((pm - a).norm(), 1e-9);   // "-" -> A
    EXPECT_LE((pp - b).norm(), 1e-9);   // "+" -> B
    const auto [qm, qp] = PointPair::fromDirect(Q.direct * -2.0).points();  // negative scale swaps
    EXPECT_LE((qm - b).norm(), 1e-9);
    EXPECT_LE((qp - a).norm(), 1e-9);
    // dual round trip
    expectMvNear(PointPair::fromDual(Q.dual()).direct, Q.direct, 1e-12);
  }
  EXPECT_THROW(PointPair::fromDirect(Multivector::e1()), std::invalid_argument);
  EXPECT_THROW(PointPair::fromDirect(Multivector()), std::invalid_argument);
}

TEST(CgaPointPair, MeetRealTangentImaginary) {
  // Unit sphere at the origin met with the plane z = 0 gives the unit circle; a plane x = d
  // cuts it at (d, +-sqrt(1 - d^2), 0): real for |d| < 1, tangent at 1, imaginary beyond.
  const Multivector C = meetSpherePlane(Sphere(Vector3::Zero(), 1.0), Plane(Vector3::UnitZ(), 0.0));
  {
    const PointPair Q = meetPlaneCirclePair(Plane(Vector3::UnitX(), 0.6), C);
    ASSERT_EQ(Q.reality(), Reality::Real);
    auto [p, q] = Q.points();
    if (p.y() > q.y()) std::swap(p, q);
    EXPECT_LE((p - Vector3(0.6, -0.8, 0)).norm(), 1e-9);
    EXPECT_LE((q - Vector3(0.6, 0.8, 0)).norm(), 1e-9);
  }
  {
    const PointPair Q = meetPlaneCirclePair(Plane(Vector3::UnitX(), 1.0), C);
    EXPECT_EQ(Q.reality(), Reality::Tangent);
    const auto [p, q] = Q.points();
    EXPECT_LE((p - Vector3(1, 0, 0)).norm(), 1e-6);
    EXPECT_LE((q - Vector3(1, 0, 0)).norm(), 1e-6);
  }
  {
    const PointPair Q = meetPlaneCirclePair(Plane(Vector3::UnitX(), 1.5), C);
    EXPECT_EQ(Q.reality(), Reality::Imaginary);
    EXPECT_LT(Q.square(), 0);
    EXPECT_THROW(Q.points(), std::domain_error);
  }
}

TEST(CgaFlatPoint, LocationAndLinePlaneMeet) {
  std::mt19937 g(94);
  for (int i = 0; i < 20; ++i) {
    const Vector3 p = randomVec(g, 3.0);
    EXPECT_LE((FlatPoint::at(p).location() - p).norm(), 1e-12);
    EXPECT_LE((FlatPoint::fromMultivector(flatPoint(p) * -4.0).location() - p).norm(), 1e-12);
    // line through p along d meets the plane through p with normal n at p (4.73)
    const Vector3 d = randomVec(g).normalized(), n = (d + 0.3 * randomVec(g)).normalized();
    const FlatPoint f = meetLinePlaneFlat(Line(p - 2.0 * d, d), Plane::throughPoint(n, p));
    EXPECT_LE((f.location() - p).norm(), 1e-9);
  }
  EXPECT_THROW(FlatPoint::fromMultivector(Multivector::e1()), std::invalid_argument);
  EXPECT_THROW(FlatPoint::fromMultivector(Multivector::e1().outer(Multivector::e2())), std::domain_error);
}

// Coordinates whose squares overflow are refused ("overflow"), never turned into objects with
// inf / NaN coefficients; a 1e300 normal keeps its direction.
TEST(CgaObjects, OverflowIsRefusedAndHugeNormalsKeepTheirDirection) {
  EXPECT_THROW(up(Vector3(1e300, 0, 0)), std::invalid_argument);
  EXPECT_THROW(Sphere(Vector3::Zero(), 1e300), std::invalid_argument);
  EXPECT_THROW(translator(Vector3(0, 1e200, 0)), std::invalid_argument);
  EXPECT_TRUE(up(Vector3(1e150, -1e150, 1e150)).allFinite());
  const Plane p(Vector3(1e300, 1e300, 0), 2.0);
  EXPECT_NEAR(p.normal.x(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(p.normal.y(), std::sqrt(0.5), 1e-15);
}

// Far from the origin the null vectors hold 1/2 |x|^2 in e+ and e-, and the inner products
// cancelled them (1 m came out as 8192 m at 1e6 m); the distances move their first argument to
// the origin first (the inner product is translation-invariant).
TEST(CgaObjects, DistancesFarFromTheOriginAreExact) {
  for (double s : {1e3, 1e6, 1e9}) {
    const Vector3 a(s, -s, 0.5 * s), b = a + Vector3(0.6, 0.8, 0.0);
    const double d = (b - a).norm();
    EXPECT_NEAR(pointDistance(a, b), d, 1e-12);
    EXPECT_NEAR(spherePointInner(Sphere(a, 2.0), b), 0.5 * (4.0 - d * d), 1e-12);
    EXPECT_NEAR(pointSphereDistance(b, Sphere(a, 2.0)), d - 2.0, 1e-12);
    EXPECT_NEAR(pointPlaneDistance(b, Plane::throughPoint(Vector3::UnitZ(), a)), 0.0, 1e-9);
  }
}
