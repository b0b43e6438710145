"""CGA core G(4,1) against the `clifford` package (g3c) as an independent oracle.

clifford's g3c uses the orthonormal e1..e5 with e4^2 = +1, e5^2 = -1, i.e. e4 = e+ and
e5 = e-. Then einf = e4 + e5 and e0 = (e5 - e4)/2 (thesis (4.44)); our orthonormal blade
with bits b (bit 0 = e1, 1 = e2, 2 = e3, 3 = e+, 4 = e-) is clifford's blade of the same
vectors in ascending order, so coefficients map by a permutation.
"""

import numpy as np
import pytest

clifford = pytest.importorskip("clifford")
from clifford import g3c  # noqa: E402

from scanalign import cga  # noqa: E402

L = g3c.layout
B = g3c.blades
C_EINF = B["e4"] + B["e5"]
C_E0 = 0.5 * (B["e5"] - B["e4"])
C_IC = C_E0 ^ B["e1"] ^ B["e2"] ^ B["e3"] ^ C_EINF
_PERM = np.array([L.bladeTupList.index(tuple(i + 1 for i in range(5) if bits >> i & 1)) for bits in range(32)])


def to_cl(m: cga.Multivector):
    v = np.zeros(32)
    v[_PERM] = m.orthonormal_coefficients()
    return L.MultiVector(v)


def from_cl(x) -> cga.Multivector:
    return cga.Multivector.from_orthonormal(np.asarray(x.value)[_PERM])


def cl_up(x):
    x = np.asarray(x, float)
    v = x[0] * B["e1"] + x[1] * B["e2"] + x[2] * B["e3"]
    return v + 0.5 * float(x @ x) * C_EINF + C_E0


def cl_down(P):
    P = P / float(-(C_EINF | P)[()])
    return np.array([float(P[(1,)]), float(P[(2,)]), float(P[(3,)])])


def assert_mv(a: cga.Multivector, b, tol=1e-10):
    np.testing.assert_allclose(to_cl(a).value, b.value, atol=tol, rtol=0)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def random_pair(rng):
    a = rng.standard_normal(32)
    b = rng.standard_normal(32)
    return cga.Multivector.from_orthonormal(a), cga.Multivector.from_orthonormal(b)


def quat_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# ----------------------------------------------------------------------------- algebra

def test_basis_matches_clifford():
    assert_mv(cga.einf, C_EINF, 0)
    assert_mv(cga.e0, C_E0, 0)
    assert_mv(cga.Ic, C_IC, 1e-15)                       # (4.48)
    assert float((cga.e0 | cga.einf).scalar()) == -1.0   # (4.45)
    assert_mv(cga.Ic * cga.Ic, -1 + 0 * C_IC, 1e-15)     # (4.49)


def test_products_against_clifford(rng):
    for _ in range(25):
        a, b = random_pair(rng)
        ca, cb = to_cl(a), to_cl(b)
        assert_mv(a * b, ca * cb)
        assert_mv(a ^ b, ca ^ cb)
        assert_mv(a | b, ca | cb)
        assert_mv(~a, ~ca)
        assert_mv(a.dual(), ca * C_IC.inv())             # (4.50)
        assert_mv(a.undual(), ca * C_IC)                 # (4.51)
        assert_mv(a.dual().dual(), -ca)
        for k in range(6):
            assert_mv(a.grade(k), ca(k))
        assert_mv(a * 2.5 - b, 2.5 * ca - cb)


def test_inverse_against_clifford(rng):
    for _ in range(10):
        a, _b = random_pair(rng)
        assert_mv(a.inverse(), to_cl(a).inv(), 1e-8)
    v = cga.up([1.0, 2.0, 3.0])   # null vector: not invertible
    with pytest.raises(ValueError):
        v.inverse()


def test_named_blades_against_clifford(rng):
    cl_vec = {"0": C_E0, "1": B["e1"], "2": B["e2"], "3": B["e3"], "inf": C_EINF}
    names = cga.blade_names()
    assert names[0] == "1" and names[31] == "e0123inf"
    for i in range(1, 32):
        toks = [t for t, bit in zip(["0", "1", "2", "3", "inf"], range(5)) if i >> bit & 1]
        x = cl_vec[toks[0]]
        for t in toks[1:]:
            x = x ^ cl_vec[t]
        assert_mv(cga.Multivector.blade(names[i]), x, 1e-15)
    # coefficients read back by name
    a, _ = random_pair(rng)
    c = a.null_coefficients()
    for i in (1, 5, 17, 18, 31):
        assert a[names[i]] == pytest.approx(c[i])
    assert a["einf1"] == pytest.approx(-a["e1inf"])
    with pytest.raises(ValueError):
        a["e5"]
    rebuilt = sum((cga.Multivector.blade(n, v) for n, v in zip(names, c)), cga.Multivector())
    assert_mv(rebuilt, to_cl(a), 1e-10)


# ----------------------------------------------------------------------------- points

def test_up_down_single_and_vectorised(rng):
    x = rng.uniform(-2, 2, (50, 3))
    for p in x[:10]:
        assert_mv(cga.up(p), cl_up(p), 1e-12)
        np.testing.assert_allclose(cga.down(cga.up(p) * 3.0), p, atol=1e-14)
    V = cga.up(x)
    assert V.shape == (50, 5)
    np.testing.assert_allclose(cga.down(V), x, atol=1e-14)
    np.testing.assert_allclose(cga.down(V * -2.0), x, atol=1e-14)
    np.testing.assert_allclose(cga.down(cga.up(x.astype(np.float32))), x.astype(np.float32), atol=1e-6)
    # matrix form (5.32): X.Y = X^T M Y equals -1/2 |a-b|^2 (4.56)
    M = cga.inner_product_matrix()
    d = np.einsum("ij,jk,ik->i", V[:-1], M, V[1:])
    np.testing.assert_allclose(d, -0.5 * np.sum((x[:-1] - x[1:]) ** 2, axis=1), atol=1e-12)
    for i in range(5):
        np.testing.assert_allclose(cga.to_vector5(cga.up(x[i])), V[i], atol=1e-14)
        assert float((cga.up(x[i]) | cga.up(x[i + 1])).scalar()) == pytest.approx(
            float((cl_up(x[i]) | cl_up(x[i + 1]))[()]), abs=1e-12)
        assert cga.point_distance(x[i], x[i + 1]) == pytest.approx(np.linalg.norm(x[i] - x[i + 1]), abs=1e-12)


def test_bad_point_input():
    with pytest.raises(ValueError):
        cga.up([np.nan, 0, 0])
    with pytest.raises(ValueError):
        cga.up(np.array([[0, 0, np.inf]]))
    with pytest.raises(ValueError):
        cga.up(np.zeros((4, 2)))
    with pytest.raises(ValueError):
        cga.up([1.0, 2.0])
    with pytest.raises(TypeError):
        cga.geometric_product_many(np.zeros((2, 32), dtype=np.int32), np.zeros((2, 32)))
    with pytest.raises(ValueError):
        cga.geometric_product_many(np.zeros((2, 32)), np.zeros((3, 32)))
    with pytest.raises(TypeError):
        cga.up(np.zeros((4, 3), dtype=np.int64))
    with pytest.raises(ValueError):
        cga.down(cga.einf)                      # point at infinity
    with pytest.raises(ValueError):
        cga.down(np.array([[1.0, 2, 3, 4, 0]]))
    with pytest.raises(ValueError):
        cga.Plane([0, 0, 0], 1.0)               # zero normal
    with pytest.raises(ValueError):
        cga.Line([0, 0, 0], [0, 0, 0])          # zero direction
    with pytest.raises(ValueError):
        cga.Sphere([0, 0, np.nan], 1.0)
    with pytest.raises(ValueError):
        cga.Sphere([0, 0, 0], -1.0)
    with pytest.raises(ValueError):
        cga.Sphere.from_dual(cga.Plane([0, 0, 1], 1.0).dual())   # a plane is not a sphere
    with pytest.raises(ValueError):
        cga.Plane.from_dual(cga.up([1.0, 2, 3]))                 # a point is not a plane
    with pytest.raises(ValueError):
        cga.Motor.from_matrix(np.diag([2.0, 1, 1, 1]))
    with pytest.raises(ValueError):
        cga.Motor.from_multivector(cga.Multivector(2.0))
    with pytest.raises(ValueError):
        cga.rotor([0, 0, 0], 0.3)


# ----------------------------------------------------------------------------- objects

def test_sphere_plane_distances(rng):
    for _ in range(10):
        c, r = rng.uniform(-1, 1, 3), rng.uniform(0.1, 1.0)
        s = cga.Sphere(c, r)
        Sc = cl_up(c) - 0.5 * r * r * C_EINF                      # (4.59)
        assert_mv(s.dual(), Sc, 1e-12)
        assert float((Sc * Sc)[()]) == pytest.approx(r * r)        # (4.61)
        # sphere through four points (4.58), via clifford's outer product and dual
        d = rng.standard_normal((4, 3))
        pts = c + r * d / np.linalg.norm(d, axis=1, keepdims=True)
        Scl = (cl_up(pts[0]) ^ cl_up(pts[1]) ^ cl_up(pts[2]) ^ cl_up(pts[3])) * C_IC.inv()
        f = cga.Sphere.from_dual(from_cl(Scl))
        np.testing.assert_allclose(f.center, c, atol=1e-9)
        assert f.radius == pytest.approx(r, abs=1e-9)
        f2 = cga.Sphere.through_points(*pts)
        np.testing.assert_allclose(f2.center, c, atol=1e-9)
        x = rng.uniform(-2, 2, 3)
        assert cga.sphere_point_inner(s, x) == pytest.approx(float((Sc | cl_up(x))[()]), abs=1e-12)
        assert cga.sphere_point_inner(s, x) == pytest.approx(0.5 * (r * r - np.sum((x - c) ** 2)), abs=1e-12)
        assert cga.point_sphere_distance(x, s) == pytest.approx(np.linalg.norm(x - c) - r, abs=1e-9)
        n = rng.standard_normal(3)
        p = cga.Plane(n, 0.3)
        nn = n / np.linalg.norm(n)
        Pcl = nn[0] * B["e1"] + nn[1] * B["e2"] + nn[2] * B["e3"] + 0.3 / np.linalg.norm(n) * C_EINF  # (4.65)
        assert_mv(p.dual(), Pcl, 1e-12)
        assert cga.point_plane_distance(x, p) == pytest.approx(float((cl_up(x) | Pcl)[()]), abs=1e-12)  # (4.67)
        assert cga.point_plane_distance(x, p) == pytest.approx(nn @ x - p.distance, abs=1e-12)
    assert repr(cga.Sphere([0, 0, 1], 0.05)) == "Sphere(center=[0, 0, 1], radius=0.05)"
    assert repr(cga.Plane([0, 0, 2], 1.0)) == "Plane(normal=[0, 0, 1], distance=0.5)"
    imag = cga.Sphere.with_radius2([0, 0, 0], -1.0)
    assert not imag.is_real and "imaginary" in repr(imag)
    with pytest.raises(ValueError):
        imag.radius


def test_point_pair_extraction_against_clifford(rng):
    for _ in range(10):
        a, b = rng.uniform(-1, 1, (2, 3))
        Q = cga.point_pair(a, b)
        Qc = cl_up(a) ^ cl_up(b)
        assert_mv(Q, Qc, 1e-12)
        q2 = float((Qc * Qc)[()])
        assert q2 == pytest.approx((0.5 * np.sum((a - b) ** 2)) ** 2)       # thesis (4.62)-(4.63)
        # (4.63) evaluated in clifford
        denom = -(C_EINF | Qc)
        Pm, Pp = (Qc - np.sqrt(q2)) * denom.inv(), (Qc + np.sqrt(q2)) * denom.inv()
        pm, pp = cga.point_pair_points(Q)
        np.testing.assert_allclose(pm, cl_down(Pm), atol=1e-9)
        np.testing.assert_allclose(pp, cl_down(Pp), atol=1e-9)
        np.testing.assert_allclose(pm, a, atol=1e-9)
        np.testing.assert_allclose(pp, b, atol=1e-9)
        assert cga.point_pair_reality(Q) == cga.Reality.real
        np.testing.assert_allclose(cga.round_center(Q), 0.5 * (a + b), atol=1e-9)
        assert cga.round_radius2(Q) == pytest.approx(0.25 * np.sum((a - b) ** 2))


def test_meets_against_clifford(rng):
    for _ in range(10):
        c, r = rng.uniform(-0.3, 0.3, 3), rng.uniform(0.5, 1.0)
        s = cga.Sphere(c, r)
        p1 = cga.Plane.through_point(rng.standard_normal(3), c + 0.1 * rng.standard_normal(3))
        p2 = cga.Plane.through_point(rng.standard_normal(3), c + 0.1 * rng.standard_normal(3))
        S, P1, P2 = to_cl(s.dual()), to_cl(p1.dual()), to_cl(p2.dual())
        Cs = cga.meet_sphere_plane(s, p1)
        assert_mv(Cs, P1 ^ S)                                                  # (4.70)
        assert_mv(cga.meet_planes(p1, p2), P1 ^ P2)
        s2 = cga.Sphere(c + rng.uniform(-0.3, 0.3, 3), r)
        assert_mv(cga.meet_spheres(s, s2), S ^ to_cl(s2.dual()))
        Qs = cga.meet_plane_circle(p2, Cs)
        assert_mv(Qs, P2 ^ (P1 ^ S))
        Q = Qs.undual()
        assert cga.point_pair_reality(Q) == cga.Reality.real
        for x in cga.point_pair_points(Q):   # both on the sphere and both planes
            assert cga.sphere_point_inner(s, x) == pytest.approx(0, abs=1e-9)
            assert cga.point_plane_distance(x, p1) == pytest.approx(0, abs=1e-9)
            assert cga.point_plane_distance(x, p2) == pytest.approx(0, abs=1e-9)
        # line meet plane (4.73): flat point Pi* . L at the Euclidean intersection
        a, b = rng.uniform(-1, 1, (2, 3))
        line = cga.Line.through_points(a, b)
        Lc = cl_up(a) ^ cl_up(b) ^ C_EINF
        F = cga.meet_line_plane(line, p1)
        Fc = P1 | Lc
        t = (p1.distance - p1.normal @ a) / (p1.normal @ (b - a))
        np.testing.assert_allclose(cga.flat_point_location(F), a + t * (b - a), atol=1e-8)
        np.testing.assert_allclose(cga.flat_point_location(from_cl(Fc)), a + t * (b - a), atol=1e-8)
        np.testing.assert_allclose(cga.Line.from_direct(from_cl(Lc)).direction, (b - a) / np.linalg.norm(b - a),
                                   atol=1e-9)
    # no intersection: plane far from the circle gives an imaginary pair (thesis (4.70)-(4.73), Paper 1 §3.4)
    s = cga.Sphere([0, 0, 0], 1.0)
    Q = cga.meet_plane_circle(cga.Plane([1, 0, 0], 1.5), cga.meet_sphere_plane(s, cga.Plane([0, 0, 1], 0))).undual()
    assert cga.point_pair_reality(Q) == cga.Reality.imaginary
    with pytest.raises(ValueError):
        cga.point_pair_points(Q)
    Q = cga.meet_plane_circle(cga.Plane([1, 0, 0], 1.0), cga.meet_sphere_plane(s, cga.Plane([0, 0, 1], 0))).undual()
    assert cga.point_pair_reality(Q) == cga.Reality.tangent


# ----------------------------------------------------------------------------- motors

def test_motor_against_clifford_and_matrix(rng):
    for _ in range(10):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        t = rng.uniform(-1, 1, 3)
        T = np.eye(4)
        T[:3, :3] = quat_matrix(q)
        T[:3, 3] = t
        M = cga.Motor.from_matrix(T)
        np.testing.assert_allclose(M.matrix(), T, atol=1e-12)
        np.testing.assert_allclose(cga.Motor.from_quaternion(q, t).matrix(), T, atol=1e-12)
        # clifford motor: T = 1 - 1/2 t einf, R = w - (x e23 + y e31 + z e12)  (Paper 4 §3.5)
        tv = t[0] * B["e1"] + t[1] * B["e2"] + t[2] * B["e3"]
        Rc = q[0] - (q[1] * B["e23"] - q[2] * B["e13"] + q[3] * B["e12"])
        Mc = (1 - 0.5 * tv * C_EINF) * Rc
        assert np.allclose(to_cl(M.multivector).value, Mc.value, atol=1e-12) or \
            np.allclose(to_cl(M.multivector).value, -Mc.value, atol=1e-12)   # q and -q
        x = rng.uniform(-2, 2, (20, 3))
        want = x @ T[:3, :3].T + t
        np.testing.assert_allclose(M.apply_points(x), want, atol=1e-12)
        for i in range(3):
            np.testing.assert_allclose(cl_down(Mc * cl_up(x[i]) * ~Mc), want[i], atol=1e-12)
            np.testing.assert_allclose(M.apply_point(x[i]), want[i], atol=1e-12)
            assert_mv(M.apply_multivector(cga.up(x[i])), Mc * cl_up(x[i]) * ~Mc, 1e-11)
        p = cga.Plane.through_point(rng.standard_normal(3), x[0])
        pm = M.apply_plane(p)
        np.testing.assert_allclose(pm.normal, T[:3, :3] @ p.normal, atol=1e-12)
        assert cga.point_plane_distance(want[0], pm) == pytest.approx(0, abs=1e-12)
        sm = M.apply_sphere(cga.Sphere(x[1], 0.2))
        np.testing.assert_allclose(sm.center, want[1], atol=1e-12)
        lm = M.apply_line(cga.Line.through_points(x[0], x[1]))
        np.testing.assert_allclose(lm.direction, (want[1] - want[0]) / np.linalg.norm(want[1] - want[0]), atol=1e-12)
        M2 = cga.Motor.from_quaternion(rng.standard_normal(4), rng.uniform(-1, 1, 3))
        np.testing.assert_allclose((M * M2).matrix(), T @ M2.matrix(), atol=1e-12)
        np.testing.assert_allclose(M.inverse().matrix(), np.linalg.inv(T), atol=1e-12)
        mid = cga.Motor.interpolate(M, M2, 0.5)
        np.testing.assert_allclose(mid.translation(), 0.5 * (t + M2.translation()), atol=1e-12)
    assert repr(cga.Motor()).startswith("Motor(quaternion_wxyz=[1, 0, 0, 0], translation=[0, 0, 0]")


def test_typed_point_and_repr():
    p = cga.Point([1.0, 2.0, 3.0])
    assert (p | cga.Point([1.0, 2.0, 4.0])).scalar() == pytest.approx(-0.5)
    assert repr(p) == "Point([1, 2, 3])"
    # a Point is accepted wherever a Multivector is, as its conformal point up(x)
    assert_mv(p ^ cga.einf, cl_up([1.0, 2.0, 3.0]) ^ C_EINF, 1e-12)
    assert_mv(cga.einf ^ p, C_EINF ^ cl_up([1.0, 2.0, 3.0]), 1e-12)
    np.testing.assert_allclose(cga.down(p), [1.0, 2.0, 3.0], atol=1e-15)
    np.testing.assert_allclose(cga.Point.from_multivector(cga.up([1.0, 2, 3]) * -4.0).position, [1, 2, 3], atol=1e-14)
    with pytest.raises(ValueError):
        cga.Point([0, np.inf, 0])
    assert repr(cga.einf) == "Multivector(1*einf)"
    assert repr(cga.Multivector(2.0) - cga.e1) == "Multivector(2 - 1*e1)"


def test_geometric_product_many(rng):
    a = rng.standard_normal((7, 32))
    b = rng.standard_normal((7, 32))
    out = cga.geometric_product_many(a, b)
    for i in range(7):
        np.testing.assert_allclose(
            out[i], (cga.Multivector.from_orthonormal(a[i]) * cga.Multivector.from_orthonormal(b[i])).orthonormal_coefficients(),
            atol=1e-12)


def test_circle_from_sphere_plane_meet(rng):
    for _ in range(10):
        c, r = rng.uniform(-1, 1, 3), rng.uniform(0.5, 1.0)
        p = cga.Plane.through_point(rng.standard_normal(3), c + 0.3 * rng.standard_normal(3) * 0.5)
        h = cga.point_plane_distance(c, p)
        if abs(h) >= r:
            continue
        circ = cga.Circle.from_dual(cga.meet_sphere_plane(cga.Sphere(c, r), p))
        np.testing.assert_allclose(circ.center, c - h * p.normal, atol=1e-9)      # foot of the centre
        assert circ.radius == pytest.approx(np.sqrt(r * r - h * h), abs=1e-9)
        assert abs(circ.normal @ p.normal) == pytest.approx(1.0, abs=1e-9)
        again = cga.Circle.from_direct(circ.direct())
        np.testing.assert_allclose(again.center, circ.center, atol=1e-9)
        assert again.radius == pytest.approx(circ.radius, abs=1e-9)
        # the same circle built in clifford from three of its points
        a, b, d = (cl_up(x) for x in (c - h * p.normal + circ.radius * u for u in _orthonormal_in_plane(circ.normal)))
        np.testing.assert_allclose(cga.round_center(from_cl(a ^ b ^ d)), circ.center, atol=1e-9)
    with pytest.raises(ValueError):
        cga.Circle.from_dual(cga.meet_sphere_plane(cga.Sphere([0, 0, 0], 1.0), cga.Plane([0, 0, 1], 2.0)))
    assert repr(cga.Circle([0, 0, 0], [0, 0, 2], 0.5)) == "Circle(center=[0, 0, 0], normal=[0, 0, 1], radius=0.5)"
    # through three points: the circumcircle (centre equidistant from them, in their plane)
    a, b, d = rng.uniform(-1, 1, (3, 3))
    circ = cga.Circle.through_points(a, b, d)
    np.testing.assert_allclose([np.linalg.norm(x - circ.center) for x in (a, b, d)], circ.radius, atol=1e-9)
    n = np.cross(b - a, d - a)
    assert abs(circ.normal @ n) == pytest.approx(np.linalg.norm(n), rel=1e-9)
    assert circ.normal @ (circ.center - a) == pytest.approx(0, abs=1e-9)
    for bad in (([0, 0, 0], [0, 0, 0], 1.0), ([0, 0, 0], [0, 0, 1], -1.0), ([0, 0, np.nan], [0, 0, 1], 1.0)):
        with pytest.raises(ValueError):
            cga.Circle(*bad)
    with pytest.raises(ValueError):                # collinear points: a line, not a circle
        cga.Circle.through_points([0, 0, 0], [1, 0, 0], [2, 0, 0])


def _orthonormal_in_plane(n):
    u = np.cross(n, [1.0, 0, 0])
    if np.linalg.norm(u) < 0.5:
        u = np.cross(n, [0, 1.0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return (u, v, -u)


# --- Paper 1 §3.7: signed angle (17), rotation planes (20), (21) -------------------------------


def _cl_vec(x):
    return x[0] * B["e1"] + x[1] * B["e2"] + x[2] * B["e3"]


def test_signed_angle_eq17_numpy_and_clifford():
    rng = np.random.default_rng(91)
    I3c = B["e1"] ^ B["e2"] ^ B["e3"]
    for _ in range(100):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        a, b = rng.normal(size=3) * 2, rng.normal(size=3) * 2
        a -= n * (n @ a)
        b -= n * (n @ b)
        N = cga.rotation_plane_from_axis(n)
        # clifford: N = n I3, unit, and its Euclidean dual is n
        Nc = _cl_vec(n) * I3c
        np.testing.assert_allclose(to_cl(N).value, Nc.value, atol=1e-12)
        np.testing.assert_allclose(cga.rotation_axis(N), n, atol=1e-12)
        # (a^b) N^{-1} and a.b from clifford, then (17)
        s_cl = float(((_cl_vec(a) ^ _cl_vec(b)) * Nc.inv())[()])
        c_cl = float((_cl_vec(a) | _cl_vec(b))[()])
        truth = np.arctan2(np.cross(a, b) @ n, a @ b)  # numpy oracle (Paper 1 eq. (17))
        th = cga.signed_angle(a, b, N)
        assert th == pytest.approx(truth, abs=1e-10)
        assert np.arctan2(s_cl, c_cl) == pytest.approx(truth, abs=1e-10)
        assert cga.signed_angle(a, b, -2.0 * N) == pytest.approx(-truth, abs=1e-10)
        assert cga.signed_angle(cga.Multivector.vector(a), b, N) == pytest.approx(truth, abs=1e-10)
    assert cga.signed_angle([1, 0, 0], [0, 1, 0], cga.e1 ^ cga.e2) == pytest.approx(np.pi / 2)
    with pytest.raises(ValueError):
        cga.signed_angle([1, 0, 0], [0, 1, 0], cga.Multivector())
    with pytest.raises(ValueError, match="b"):
        cga.signed_angle([1, 0, 0], [0, 1], cga.e1 ^ cga.e2)
    with pytest.raises(ValueError):
        cga.rotation_plane_from_axis([0, 0, 0])


def test_rotation_planes_line_and_plane_vs_clifford():
    rng = np.random.default_rng(92)
    for _ in range(30):
        a, b = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3)
        L = cga.up(a) ^ cga.up(b) ^ cga.einf
        N = cga.rotation_plane_perpendicular_to_line(L.dual())
        # (20) in clifford: (L* ^ einf) . e0, normalised
        Lc = cl_up(a) ^ cl_up(b) ^ C_EINF
        Nc = (Lc * C_IC.inv()) ^ C_EINF
        Nc = Nc | C_E0
        Nc = Nc / np.sqrt(abs(float((Nc * ~Nc)[()])))
        np.testing.assert_allclose(to_cl(N).value, Nc.value, atol=1e-10)
        np.testing.assert_allclose(cga.rotation_axis(N), (b - a) / np.linalg.norm(b - a), atol=1e-9)
        line = cga.Line(a, b - a)
        np.testing.assert_allclose(
            cga.rotation_axis(cga.rotation_plane_perpendicular_to_line(line)), (b - a) / np.linalg.norm(b - a), atol=1e-9
        )
        # (21): (Pi . e0) . einf, normalised, with Pi = PA^PB^PC^einf (4.64)
        p, q, r = rng.uniform(-2, 2, (3, 3))
        Pi = cga.up(p) ^ cga.up(q) ^ cga.up(r) ^ cga.einf
        N2 = cga.rotation_plane_parallel_to_plane(Pi)
        Pic = cl_up(p) ^ cl_up(q) ^ cl_up(r) ^ C_EINF
        N2c = (Pic | C_E0) | C_EINF
        N2c = N2c / np.sqrt(abs(float((N2c * ~N2c)[()])))
        np.testing.assert_allclose(to_cl(N2).value, N2c.value, atol=1e-10)
        normal = np.cross(q - p, r - p)
        normal /= np.linalg.norm(normal)
        np.testing.assert_allclose(cga.rotation_axis(N2), normal, atol=1e-9)  # right-hand normal
        # the typed Plane is oriented explicitly: axis = its normal
        pl = cga.Plane(-normal, float(-normal @ p))
        np.testing.assert_allclose(cga.rotation_axis(cga.rotation_plane_parallel_to_plane(pl)), -normal, atol=1e-9)


# --- typed PointPair / FlatPoint (thesis (4.62)-(4.63), (4.69)) -----------------------------------


def test_point_pair_eq4_63_vs_clifford():
    rng = np.random.default_rng(93)
    for _ in range(30):
        a, b = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        Q = cga.PointPair.from_points(a, b)
        Qc = cl_up(a) ^ cl_up(b)
        np.testing.assert_allclose(to_cl(Q.direct).value, Qc.value, atol=1e-12)
        h = 0.5 * float((a - b) @ (a - b))
        q2_cl = float((Qc * Qc)[()])
        assert Q.square() == pytest.approx(h * h, rel=1e-10)
        assert q2_cl == pytest.approx(h * h, rel=1e-10)
        assert Q.reality() == cga.Reality.real
        # (4.63) in clifford: (Q +- sqrt(Q^2)) / (-einf . Q) -> up(b), up(a), normalised
        d = -(C_EINF | Qc)
        Pp = (Qc + np.sqrt(q2_cl)) * d.inv()
        Pm = (Qc - np.sqrt(q2_cl)) * d.inv()
        np.testing.assert_allclose(Pp.value, cl_up(b).value, atol=1e-9)
        np.testing.assert_allclose(Pm.value, cl_up(a).value, atol=1e-9)
        pm, pp = Q.points()
        np.testing.assert_allclose(pm, a, atol=1e-9)
        np.testing.assert_allclose(pp, b, atol=1e-9)
        # free functions still agree
        pm2, pp2 = cga.point_pair_points(cga.point_pair(a, b))
        np.testing.assert_allclose(pm2, a, atol=1e-9)
        assert "PointPair(real" in repr(Q)
        np.testing.assert_allclose(to_cl(cga.PointPair.from_dual(Q.dual()).direct).value, Qc.value, atol=1e-12)
    with pytest.raises(ValueError):
        cga.PointPair.from_direct(cga.e1)


def test_point_pair_from_meet_real_tangent_imaginary():
    C = cga.meet_sphere_plane(cga.Sphere([0, 0, 0], 1.0), cga.Plane([0, 0, 1], 0.0))  # unit circle
    Q = cga.meet_plane_circle_pair(cga.Plane([1, 0, 0], 0.6), C)
    assert Q.reality() == cga.Reality.real
    pts = sorted(Q.points(), key=lambda p: p[1])
    np.testing.assert_allclose(pts[0], [0.6, -0.8, 0], atol=1e-9)
    np.testing.assert_allclose(pts[1], [0.6, 0.8, 0], atol=1e-9)
    # same pair built from the dual meet by hand
    Q2 = cga.PointPair.from_dual(cga.meet_plane_circle(cga.Plane([1, 0, 0], 0.6), C))
    np.testing.assert_allclose(Q2.direct.orthonormal_coefficients(), Q.direct.orthonormal_coefficients())
    T = cga.meet_plane_circle_pair(cga.Plane([1, 0, 0], 1.0), C)
    assert T.reality() == cga.Reality.tangent
    for p in T.points():
        np.testing.assert_allclose(p, [1, 0, 0], atol=1e-6)
    assert "tangent" in repr(T)
    Im = cga.meet_plane_circle_pair(cga.Plane([1, 0, 0], 1.5), C)
    assert Im.reality() == cga.Reality.imaginary
    assert Im.square() < 0
    assert "imaginary" in repr(Im)
    with pytest.raises(ValueError):
        Im.points()


def test_flat_point_location_and_meet():
    rng = np.random.default_rng(94)
    for _ in range(20):
        p = rng.uniform(-3, 3, 3)
        np.testing.assert_allclose(cga.FlatPoint.at(p).location(), p, atol=1e-12)
        F = cga.FlatPoint.from_multivector(cga.flat_point(p) * -4.0)
        np.testing.assert_allclose(F.location(), p, atol=1e-12)
        np.testing.assert_allclose(cga.flat_point_location(F.direct), p, atol=1e-12)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        n = d + 0.3 * rng.normal(size=3)
        f = cga.meet_line_plane_flat(cga.Line(p - 2 * d, d), cga.Plane(n, float(n @ p)))
        np.testing.assert_allclose(f.location(), p, atol=1e-9)
    assert repr(cga.FlatPoint.at([1, 2, 3])) == "FlatPoint([1, 2, 3])"
    with pytest.raises(ValueError):
        cga.FlatPoint.from_multivector(cga.e1 ^ cga.e2)
