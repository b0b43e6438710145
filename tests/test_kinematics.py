"""scanalign.kinematics: forward kinematics and analytic CGA inverse kinematics of the KUKA
KR6 R900 sixx and the UR arms (Kleppe, PhD thesis, NTNU 2018, Ch. 5.3 and Paper 1 §4-5).

Independent truth: the thesis authors' DH table typed in here and a numpy DH chain written here;
`eaik` (general analytic 6R IK) and `ur_analytic_ik` (Universal Robots' published DH
tables); a numeric IK (scipy least squares from many seeds); the thesis's CGA construction
written literally with `clifford` (g3c); plain geometry for labels and singularities.
"""

from __future__ import annotations

import numpy as np
import pytest
import ur_analytic_ik
from eaik.IK_DH import DhRobot
from numpy import pi
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from scanalign import kinematics as kin
from scanalign.kinematics import Robot

TWO_PI = 2 * pi
UR_MODELS = ("ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e")
# The DH table of the thesis authors' code (Paper 1 Table 1 is garbled in print; this one
# closes the loop and gives KUKA's home pose): rows [a (m), alpha, d (m), theta offset].
KUKA_AUTHORS_DH = np.array([[0.025, -pi / 2, 0.400, 0], [0.455, 0, 0, 0], [0.035, -pi / 2, 0, -pi / 2],
                         [0, pi / 2, 0.420, 0], [0, -pi / 2, 0, 0], [0, 0, 0.080, 0]])


# ----------------------------------------------------------------------------- helpers

def wrap(x):
    """Angles to [-pi, pi)."""
    return (np.asarray(x) + pi) % TWO_PI - pi


def same_angles(a, b, tol):
    return np.max(np.abs(wrap(np.asarray(a) - np.asarray(b)))) <= tol


def among(rows, q, tol):
    """q equals one of rows modulo 2 pi (joint-wise) within tol."""
    rows = np.asarray(rows).reshape(-1, 6)
    return rows.shape[0] > 0 and bool(np.any(np.max(np.abs(wrap(rows - q)), axis=1) <= tol))


def dh_frames(dh, q):
    """Independent numpy DH chain: (N, 7, 4, 4) T_0i for q (N, 6), standard DH (P1 (1))."""
    q = np.atleast_2d(np.asarray(q, float))
    n = len(q)
    F = np.tile(np.eye(4), (n, 7, 1, 1))
    for i in range(6):
        a, al, d, off = dh[i]
        th = q[:, i] + off
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        A = np.zeros((n, 4, 4))
        A[:, 0] = np.stack([ct, -st * ca, st * sa, a * ct], 1)
        A[:, 1] = np.stack([st, ct * ca, -ct * sa, a * st], 1)
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3], A[:, 3, 3] = sa, ca, d, 1
        F[:, i + 1] = F[:, i] @ A
    return F


def dh_fk(robot, q):
    """T_base_tool by the numpy chain: (N, 4, 4)."""
    return robot.T_base_dh0 @ dh_frames(robot.dh, q)[:, 6] @ robot.T_flange_tool


def random_q(robot, rng, n, inside=True):
    """Uniform joints inside the limits (at most one turn per joint), or in [-pi, pi)."""
    if not inside:
        return rng.uniform(-pi, pi, (n, 6))
    lim = np.clip(robot.limits, -pi, pi)
    return rng.uniform(lim[:, 0], lim[:, 1], (n, 6))


def pose(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def pose_from_flange_point(robot, R, p_wrist):
    """Tool pose (tool = flange) whose wrist point p_e - d6 a_e is p_wrist (DH frame 0 = base)."""
    return pose(R, np.asarray(p_wrist) + robot.d[5] * R[:, 2])


def fk_error(robot, qs, T):
    """Max |FK(q) - T| entries over rows qs (position in metres, rotation entries)."""
    if len(qs) == 0:
        return 0.0
    return float(np.max(np.abs(robot.fk(np.asarray(qs)) - T)))


def theta(robot, q):
    return np.asarray(q) + robot.theta_offset


def distinct_count(qs, ok, tol=1e-9):
    """Vectorised: number of ok rows per pose that differ from every earlier ok row."""
    d = np.max(np.abs(wrap(qs[:, :, None, :] - qs[:, None, :, :])), axis=-1)   # (N, 8, 8)
    same = (d <= tol) & ok[:, :, None] & ok[:, None, :]
    earlier = np.tril(np.ones((8, 8), bool), -1)
    dup = np.any(same & earlier[None], axis=2)
    return np.count_nonzero(ok & ~dup, axis=1)


@pytest.fixture(scope="module")
def kuka():
    return kin.kuka_kr6_r900_sixx()


@pytest.fixture(scope="module")
def ur5():
    return kin.ur5()


ROBOTS = ("kr6_r900_sixx", "ur5")


# ----------------------------------------------------------------------------- robots and FK

def test_builtin_robots_and_geometry():
    for name in kin.BUILTIN_ROBOTS:
        r = Robot.by_name(name)
        assert r.dh.shape == (6, 4) and r.limits.shape == (6, 2)
        assert r.geometry == ("spherical_wrist" if name in ("kr6_r900_sixx", "agilus") else "universal_robots")
        np.testing.assert_array_equal(r.T_base_dh0, np.eye(4))
        np.testing.assert_array_equal(r.T_flange_tool, np.eye(4))
        assert name.replace("agilus", "kr6_r900_sixx") == r.name and r.name in repr(r)
    for fn, name in ((kin.kuka_kr6_r900_sixx, "kr6_r900_sixx"), (kin.ur3, "ur3"), (kin.ur5, "ur5"),
                     (kin.ur10, "ur10"), (kin.ur3e, "ur3e"), (kin.ur5e, "ur5e"), (kin.ur10e, "ur10e"),
                     (kin.ur5_thesis, "ur5_thesis")):
        np.testing.assert_array_equal(fn().dh, Robot.by_name(name).dh)
    r = kin.ur5()
    np.testing.assert_array_equal(np.c_[r.a, r.alpha, r.d, r.theta_offset], r.dh)
    with pytest.raises(ValueError):
        r.dh[0, 0] = 1.0                      # read-only views
    with pytest.raises(ValueError, match="unknown robot"):
        Robot.by_name("ur42")


def test_kuka_dh_table_is_the_authors_table(kuka):
    np.testing.assert_allclose(kuka.dh, KUKA_AUTHORS_DH, atol=1e-15)
    # KUKA data sheet limits (degrees): A1 +-170, A2 -190..45, A3 -120..156, A4 +-185, A5 +-120, A6 +-350
    np.testing.assert_allclose(np.rad2deg(kuka.limits),
                               [[-170, 170], [-190, 45], [-120, 156], [-185, 185], [-120, 120], [-350, 350]])


def test_agilus_home_pose(kuka):  # Paper 1 Fig. 2b
    T = kuka.fk([0, -pi / 2, pi / 2, 0, 0, 0])
    np.testing.assert_allclose(T[:3, 3], [0.525, 0, 0.890], atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-12)                 # approach a_e = +x
    np.testing.assert_allclose(T[:3, :3], [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-12)


def test_ur5_thesis_zero_pose():  # thesis numbers of Paper 1 Table 2
    T = kin.ur5_thesis().fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [-0.81743, -0.19145, -0.00545], atol=1e-12)


@pytest.mark.parametrize("model", UR_MODELS)
def test_ur_tables_match_published_tables(model):
    """ur_analytic_ik carries Universal Robots' published DH tables: same FK to 1e-12."""
    robot, ref = Robot.by_name(model), getattr(ur_analytic_ik, model)
    q = random_q(robot, np.random.default_rng(1), 50)
    ours = robot.fk(q)
    for i in range(len(q)):
        np.testing.assert_allclose(ours[i], ref.forward_kinematics(*q[i]), atol=1e-12, rtol=0)


def test_kuka_fk_matches_eaik(kuka):
    # eaik built from the table typed in above (not ours); it takes DH theta = q + offsets
    ref = DhRobot(KUKA_AUTHORS_DH[:, 1], KUKA_AUTHORS_DH[:, 0], KUKA_AUTHORS_DH[:, 2])
    q = random_q(kuka, np.random.default_rng(2), 100)
    ours = kuka.fk(q)
    for i in range(len(q)):
        np.testing.assert_allclose(ours[i], ref.fwdKin(q[i] + KUKA_AUTHORS_DH[:, 3]), atol=1e-12, rtol=0)


@pytest.mark.parametrize("name", kin.BUILTIN_ROBOTS)
def test_fk_single_batch_frames_and_numpy_chain_agree(name):
    robot = Robot.by_name(name)
    q = random_q(robot, np.random.default_rng(3), 300)
    batch = robot.fk(q)
    assert batch.shape == (300, 4, 4)
    np.testing.assert_allclose(batch, dh_fk(robot, q), atol=1e-13, rtol=0)
    np.testing.assert_array_equal(batch, robot.fk(q, num_threads=1))
    for i in range(0, 300, 37):
        np.testing.assert_allclose(robot.fk(q[i]), batch[i], atol=1e-15, rtol=0)
        F = robot.joint_frames(q[i])
        assert F.shape == (7, 4, 4)
        np.testing.assert_allclose(F, dh_frames(robot.dh, q[i])[0], atol=1e-13, rtol=0)
        np.testing.assert_allclose(robot.fk_flange(q[i]), F[6], atol=1e-15)
    assert robot.fk(np.zeros((0, 6))).shape == (0, 4, 4)


def test_base_and_tool_transforms_compose():
    rng = np.random.default_rng(4)
    for name in ROBOTS:
        robot = Robot.by_name(name)
        Tb = pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
        Tt = pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-0.1, 0.1, 3))
        moved = robot.with_base(Tb).with_tool(Tt)
        assert robot.T_flange_tool[0, 3] == 0 and "T_flange_tool" in repr(moved)   # copies
        q = random_q(robot, rng, 20)
        np.testing.assert_allclose(moved.fk(q), Tb @ robot.fk(q) @ Tt, atol=1e-13)
        # IK with base and tool: the solutions of the bare robot for the flange pose in DH frame 0
        for qi in q[:5]:
            T = moved.fk(qi)
            sol, bare = moved.ik(T), robot.ik(np.linalg.inv(Tb) @ T @ np.linalg.inv(Tt))
            assert sol.status == bare.status
            np.testing.assert_allclose(sol.valid_q(), bare.valid_q(), atol=1e-9)
            assert fk_error(moved, sol.valid_q(), T) < 1e-10 and among(sol.valid_q(), qi, 1e-8)


def test_from_dh_reproduces_builtin_and_within_limits():
    ur = kin.ur5()
    r = Robot.from_dh(ur.a, ur.alpha, ur.d, limits=ur.limits, name="my_ur5")
    assert r.name == "my_ur5" and r.geometry == "universal_robots"
    q = random_q(ur, np.random.default_rng(5), 10)
    np.testing.assert_array_equal(r.fk(q), ur.fk(q))
    np.testing.assert_array_equal(r.ik(ur.fk(q[0])).q, ur.ik(ur.fk(q[0])).q)
    default = Robot.from_dh(ur.a, ur.alpha, ur.d)
    np.testing.assert_array_equal(default.limits, np.tile([-pi, pi], (6, 1)))
    np.testing.assert_array_equal(default.theta_offset, np.zeros(6))
    kuka = kin.kuka_kr6_r900_sixx()
    assert kuka.within_limits([0, -pi / 2, pi / 2, 0, 0, 0])
    assert not kuka.within_limits([0, 1.0, 0, 0, 0, 0])                     # A2 max is 45 deg
    np.testing.assert_array_equal(kuka.within_limits([[0, 0, 0, 0, 0, 0], [3.0, 0, 0, 0, 0, 0]]), [True, False])
    assert kuka.within_limits([0, np.deg2rad(45) + 1e-7, 0, 0, 0, 0], tol=1e-6)


# ----------------------------------------------------------------------------- IK: FK(IK(T)) = T

def _roundtrip(robot, q, tol_fk=1e-10, tol_q=1e-7, respect_limits=True):
    """ik_batch of FK(q): every ok solution reproduces the pose, the generating q is found.
    Returns the batch."""
    T = robot.fk(q)
    res = robot.ik_batch(T, respect_limits=respect_limits)
    assert res.q.shape == (len(q), 8, 6) and res.status.shape == (len(q), 8)
    idx = np.nonzero(res.ok)
    assert len(idx[0]) > 0
    err = np.abs(robot.fk(res.q[idx]) - T[idx[0]])
    worst = float(err.max())
    assert worst < tol_fk, f"FK(IK(T)) off by {worst:.3g}"
    assert np.all(np.isnan(res.q[~res.ok & (res.status == 2)]))
    # the generating q is among the ok solutions (modulo 2 pi)
    d = np.max(np.abs(wrap(res.q - q[:, None, :])), axis=2)
    d[~res.ok] = np.inf
    found = d.min(axis=1) <= tol_q
    assert found.all(), f"generating q not found for {np.count_nonzero(~found)} poses, e.g. {q[~found][0]}"
    return res


@pytest.mark.parametrize("name", ROBOTS)
def test_fk_ik_roundtrip_random_poses(name):  # Paper 1 §4-5: FK(IK(T)) = T
    robot = Robot.by_name(name)
    q = random_q(robot, np.random.default_rng(6), 4000)
    res = _roundtrip(robot, q)
    # respect_limits: ok solutions are inside the limits, others outside_limits
    okq = res.q[res.ok]
    assert np.all(robot.within_limits(okq, tol=1e-12))
    assert np.all((res.status == 0) | (res.status == 1) | (res.status == 2))
    assert np.all(res.singular[res.ok] == 0)                                   # generic poses


@pytest.mark.parametrize("model", ["ur3", "ur10", "ur3e", "ur5e", "ur10e", "ur5_thesis"])
def test_fk_ik_roundtrip_other_ur_models(model):
    robot = Robot.by_name(model)
    _roundtrip(robot, random_q(robot, np.random.default_rng(7), 500))


def _stretched_q(robot, rng, n, delta):
    """Random q with the elbow delta rad from stretched (P1, P2, wrist point collinear)."""
    q = random_q(robot, rng, n)
    if robot.geometry == "spherical_wrist":
        # in frame 2 the wrist centre is Rot_z(theta3) (a3, d4, 0): along +x2 when stretched
        th3 = -np.arctan2(robot.d[3], robot.a[2])
    else:
        th3 = 0.0                                                              # a2, a3 in line
    q[:, 2] = th3 - robot.theta_offset[2] + delta
    return q


@pytest.mark.parametrize("name", ROBOTS)
def test_roundtrip_near_workspace_boundary(name):
    robot, rng = Robot.by_name(name), np.random.default_rng(8)
    for delta in (1e-3, -1e-4, 1e-5):
        q = _stretched_q(robot, rng, 200, delta)
        res = _roundtrip(robot, q, tol_q=1e-6, respect_limits=False)
        assert np.all(res.singular[res.ok] & 2 == 0)                           # not tangent yet


@pytest.mark.parametrize("name", ROBOTS)
def test_roundtrip_near_wrist_singularity(name):
    robot, rng = Robot.by_name(name), np.random.default_rng(9)
    # theta5 = +-1e-6, and +-1e-10 (just above singular_tolerance): still solved as regular
    # and exact in the pose; near the singularity theta4 and theta6 (UR: theta2..theta4 and
    # theta6) are ill-conditioned one by one, so the generating q is matched loosely there
    for theta5, tol_q in ((1e-6, 1e-6), (1e-10, 1e-2)):
        q = random_q(robot, rng, 300)
        q[:, 4] = -robot.theta_offset[4] + rng.choice([-theta5, theta5], 300)
        res = _roundtrip(robot, q, tol_q=tol_q)
        assert np.all(res.singular[res.ok] & 4 == 0)
        d = np.abs(wrap(res.q[:, :, 0] - q[:, None, 0]))                       # theta1 is not
        assert np.all(np.min(np.where(res.ok, d, np.inf), axis=1) < 1e-9)


def test_roundtrip_kuka_wrist_centre_near_first_axis(kuka):
    rng = np.random.default_rng(10)
    T = []
    for k in range(100):
        phi = rng.uniform(-pi, pi)
        pw = [1e-6 * np.cos(phi), 1e-6 * np.sin(phi), rng.uniform(0.8, 1.2)]
        T.append(pose_from_flange_point(kuka, Rotation.random(random_state=rng).as_matrix(), pw))
    T = np.array(T)
    res = kuka.ik_batch(T, respect_limits=False)
    assert np.all(res.count_ok == 8) and np.all(res.singular == 0)
    assert fk_error(kuka, res.q.reshape(-1, 6), np.repeat(T, 8, axis=0)) < 1e-10
    # front and back differ in q1 by pi (Paper 1 §4, eq. (26)) even this close to the axis
    for s in range(2):
        np.testing.assert_allclose(np.abs(wrap(res.q[:, s, 0] - res.q[:, 4 + s, 0])), pi, atol=1e-8)


def test_roundtrip_ur_wrist_point_near_horizon(ur5):
    """UR: P5 just outside d4 of the first axis: two nearly coincident shoulder solutions."""
    rng = np.random.default_rng(11)
    T = []
    for k in range(100):
        R = Rotation.random(random_state=rng).as_matrix()
        phi = rng.uniform(-pi, pi)
        rho = ur5.d[3] * (1 + 1e-6)
        T.append(pose_from_flange_point(ur5, R, [rho * np.cos(phi), rho * np.sin(phi), rng.uniform(-0.2, 0.4)]))
    T = np.array(T)
    res = ur5.ik_batch(T, respect_limits=False)
    assert np.all(res.count_ok >= 2)
    assert fk_error(ur5, res.q[res.ok], T[np.nonzero(res.ok)[0]]) < 1e-9


# ----------------------------------------------------------------------------- number of solutions

@pytest.mark.parametrize("name,band,reference", [("kr6_r900_sixx", (0.84, 0.95), 0.899), ("ur5", (0.70, 0.86), 0.779)])
def test_number_of_distinct_solutions(name, band, reference):
    robot = Robot.by_name(name)
    rng = np.random.default_rng(12)
    q = random_q(robot, rng, 1000, inside=False)                  # uniform joints, limits ignored
    res = robot.ik_batch(robot.fk(q), respect_limits=False)
    n = distinct_count(res.q, res.ok)
    assert np.all(n == res.count_ok)                              # generic: no duplicates
    assert np.all(n % 2 == 0) and np.all(n <= 8) and np.all(n >= 2)
    frac8 = np.mean(n == 8)
    assert band[0] <= frac8 <= band[1], f"{frac8} poses with 8 solutions (independent re-implementation: {reference})"
    if name == "kr6_r900_sixx":
        assert set(np.unique(n)) <= {4, 8}                        # otherwise 4
    else:
        assert set(np.unique(n)) <= {2, 4, 6, 8} and len(set(np.unique(n))) >= 3
    # IKResult.distinct agrees
    for i in range(0, 1000, 97):
        sol = res.solutions(i)
        assert len(sol.distinct()) == n[i] == len(sol)


# ----------------------------------------------------------------------------- oracles

def test_solution_sets_equal_eaik():
    """eaik (general analytic 6R IK) on our DH tables: the same solution sets."""
    rng = np.random.default_rng(13)
    for name in ROBOTS:
        robot = Robot.by_name(name)
        ref = DhRobot(robot.alpha, robot.a, robot.d)
        q = random_q(robot, rng, 250, inside=False)
        T = robot.fk(q)
        res = robot.ik_batch(T, respect_limits=False)
        compared = 0
        for i in range(len(q)):
            s = ref.IK(T[i])
            theirs = [qe - robot.theta_offset for qe, ls in zip(s.Q, s.is_LS) if not ls]
            ours = res.q[i][res.ok[i]]
            for qe in theirs:
                assert among(ours, qe, 1e-7), (name, i, qe)
            for qo in ours:
                assert among(theirs, qo, 1e-7), (name, i, qo)
            compared += len(theirs)
        assert compared > 5 * len(q)


@pytest.mark.parametrize("model", UR_MODELS)
def test_solution_sets_equal_ur_analytic_ik(model):
    robot, ref = Robot.by_name(model), getattr(ur_analytic_ik, model)
    rng = np.random.default_rng(14)
    q = random_q(robot, rng, 150, inside=False)
    T = robot.fk(q)
    res = robot.ik_batch(T, respect_limits=False)
    for i in range(len(q)):
        theirs = [x for x in ref.inverse_kinematics(T[i]) if np.all(np.isfinite(x))]
        ours = res.q[i][res.ok[i]]
        assert len(theirs) == len(ours), (model, i)
        for qe in theirs:
            assert among(ours, qe, 1e-7), (model, i, qe)
        for qo in ours:
            assert among(theirs, qo, 1e-7), (model, i, qo)


def test_numeric_ik_finds_only_our_solutions():
    """scipy least squares on the numpy DH chain from 24 random seeds per pose: every
    converged solution is one of ours, and it finds several of them."""
    rng = np.random.default_rng(15)
    for name in ROBOTS:
        robot = Robot.by_name(name)
        for qg in random_q(robot, rng, 4, inside=False):
            T = dh_fk(robot, qg)[0]
            ours = robot.ik(T, respect_limits=False).valid_q()

            def residual(x):
                F = dh_fk(robot, x)[0]
                return np.r_[F[:3, 3] - T[:3, 3], 0.5 * (F[:3, :3] - T[:3, :3]).ravel()]

            found = []
            for x0 in rng.uniform(-pi, pi, (24, 6)):
                r = least_squares(residual, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
                if np.max(np.abs(r.fun)) < 1e-11:
                    assert among(ours, r.x, 1e-6), (name, qg, wrap(r.x))
                    if not among(found, r.x, 1e-6):
                        found.append(r.x)
            assert len(found) >= 2, (name, qg, len(found))


# ----------------------------------------------------------------------------- CGA oracle (clifford)

class _CGA:
    """The thesis construction written literally in clifford's G(4,1) (Paper 1 §4 and §5)."""

    def __init__(self):
        from clifford.g3c import e1, e2, e3, einf, eo

        self.e1, self.e2, self.e3, self.einf, self.eo = e1, e2, e3, einf, eo
        self.Ic = eo ^ e1 ^ e2 ^ e3 ^ einf                     # (4.48)

    def dual(self, X):
        return X * (-self.Ic)                                  # X Ic^-1, Ic^2 = -1 (4.50)

    def up(self, x):
        x = np.asarray(x, float)
        return float(x[0]) * self.e1 + float(x[1]) * self.e2 + float(x[2]) * self.e3 \
            + 0.5 * float(x @ x) * self.einf + self.eo        # (4.54)

    def down(self, P):
        P = P / float((-(self.einf | P))[()])
        return np.array([float(P[(1,)]), float(P[(2,)]), float(P[(3,)])])

    def sphere(self, P, r2):
        return P - 0.5 * r2 * self.einf                        # (4.59)

    def pair(self, Q):
        """((P+, P-) or None, Q^2): P+- = (Q +- sqrt(Q^2)) / (-einf . Q) (4.63)."""
        q2 = float((Q * Q)[()])
        if q2 < 0:
            return None, q2
        den = -(self.einf | Q)
        s = np.sqrt(q2)
        return (self.down((Q + s) / den), self.down((Q - s) / den)), q2

    def scalar(self, X):
        return float(X[()])


def _match(points, x, tol=1e-9):
    return points is not None and min(np.linalg.norm(p - x) for p in points) <= tol


def test_construction_points_are_the_clifford_point_pairs():
    """For each configuration our construction's points are points of the thesis's point
    pairs computed with clifford; both points of each pair are used by some configuration
    (sets, not labels: their signs depend on blade orientation, Paper 1 eqs. (26)-(28), (40)-(42)); Q^2 < 0 exactly when our discriminant is negative."""
    c = _CGA()
    e3, einf, eo = c.e3, c.einf, c.eo
    rng = np.random.default_rng(16)
    checked = {"kuka": 0, "ur": 0, "unreachable": 0}
    kuka = kin.kuka_kr6_r900_sixx()
    d1, a1, a2, a3, d4, d6 = kuka.d[0], kuka.a[0], kuka.a[1], kuka.a[2], kuka.d[3], kuka.d[5]
    for k in range(24):
        if k < 18:
            T = kuka.fk(random_q(kuka, rng, 1, inside=False)[0])
        else:                                                  # some poses out of reach
            T = pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1.2, 1.2, 3))
        Pw = c.up(T[:3, 3] - d6 * T[:3, 2])                     # (23)-(24)
        Pi_c = eo ^ e3 ^ Pw ^ einf                              # (25)
        P1s, _ = c.pair((c.sphere(eo, d1 * d1 + a1 * a1) ^ (e3 + d1 * einf)) | Pi_c)   # (29)
        used = {"P1": [], "P2": {}, "P_wx": {}}
        for idx in range(8):
            s, e, w = (int(v) for v in kin.CONFIGS[idx])
            con = kuka.ik_construction(T, s, e, w)
            pts = con.points
            # ik.hpp: points not reached are NaN, the discriminant gives the sign of Q^2
            assert {"p_e", "P_w", "P1", "P2", "P_wx"} <= set(pts), (k, idx, con)
            assert _match(P1s, pts["P1"])
            np.testing.assert_allclose(pts["P_w"], c.down(Pw), atol=1e-12)
            used["P1"].append(pts["P1"])
            P1 = c.up(pts["P1"])
            P2s, q2 = c.pair((c.sphere(P1, a2 * a2) ^ c.sphere(Pw, d4 * d4 + a3 * a3)) | Pi_c)   # (32)-(34)
            disc = con.elbow_discriminant
            assert np.isfinite(disc) and (q2 < 0) == (disc < 0), (k, idx, q2, disc)
            if q2 < 0:
                assert con.solution.status == "unreachable"
                assert np.all(np.isnan(pts["P2"])) and np.all(np.isnan(pts["P_wx"]))
                checked["unreachable"] += 1
                continue
            assert _match(P2s, pts["P2"])
            used["P2"].setdefault(s, (P2s, []))[1].append(pts["P2"])
            S2 = c.sphere(c.up(pts["P2"]), a3 * a3)
            K = Pw + c.scalar(Pw | S2) * einf                  # (35) with the corrected sign
            Pwxs, _ = c.pair((K ^ S2) | Pi_c)                  # (36)-(37)
            assert _match(Pwxs, pts["P_wx"])
            checked["kuka"] += 1
        # sets: both points of Q1 are used (front and back) ...
        assert all(_match(used["P1"], p) for p in P1s)
        # ... and both points of each real Q2 (elbow up and down)
        for P2s, ours in used["P2"].values():
            assert all(_match(ours, p) for p in P2s)

    ur = kin.ur5()
    d1, a2, a3, d4, d5, d6 = ur.d[0], ur.a[1], ur.a[2], ur.d[3], ur.d[4], ur.d[5]
    for k in range(24):
        if k < 16:
            T = ur.fk(random_q(ur, rng, 1, inside=False)[0])
        elif k < 20:                                           # P5 within d4 of the first axis
            T = pose_from_flange_point(ur, Rotation.random(random_state=rng).as_matrix(),
                                       [0.03, -0.05, rng.uniform(-0.3, 0.5)])
        else:                                                  # far out of reach
            T = pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3) * [2, 2, 1])
        pe, ae = T[:3, 3], T[:3, 2]
        P5, Pe = c.up(pe - d6 * ae), c.up(pe)                  # (39)
        Sc = c.sphere(P5, d4 * d4)
        K0 = eo + c.scalar(eo | Sc) * einf                     # (43) with the corrected sign
        Pcs, qc = c.pair((Sc ^ K0) | (P5 ^ c.e1 ^ c.e2 ^ einf))   # (44)-(45)
        P1 = c.up([0, 0, d1])
        used_c = []
        for idx in range(8):
            s, e, w = (int(v) for v in kin.CONFIGS[idx])
            con = ur.ik_construction(T, s, e, w)
            pts = con.points
            assert {"p_e", "P5", "P_c", "P4", "P3", "P2", "P1"} <= set(pts), (k, idx, con)
            disc_c = con.shoulder_discriminant
            assert np.isfinite(disc_c) and (qc < 0) == (disc_c < 0), (k, idx, qc, disc_c)
            if qc < 0:
                assert con.solution.status == "unreachable"
                assert con.solution.unreachable_step == "shoulder" and np.all(np.isnan(pts["P_c"]))
                checked["unreachable"] += 1
                continue
            assert _match(Pcs, pts["P_c"])
            used_c.append(pts["P_c"])
            Pi_c = eo ^ e3 ^ c.up(pts["P_c"]) ^ einf           # (46)
            Pi_cs = c.dual(Pi_c)
            Pi_par = Pi_cs + c.scalar(P5 | Pi_cs) * einf       # (47)
            Pi_56 = c.dual(P5 ^ Pe) ^ einf                     # (48)
            N = (Pi_56 | eo) | einf
            N = -N / np.sqrt(abs(c.scalar(N * ~N)))
            Pi_perp = P5 ^ N ^ einf
            L45 = Pi_par ^ c.dual(Pi_perp)
            P4s, _ = c.pair(c.dual(L45 ^ c.sphere(P5, d5 * d5)))   # (49)
            assert _match(P4s, pts["P4"])
            P4 = c.up(pts["P4"])
            P3s, _ = c.pair(c.sphere(P4, d4 * d4) | (P4 ^ Pi_cs ^ einf))   # (50)
            assert _match(P3s, pts["P3"])
            np.testing.assert_allclose(pts["P1"], [0, 0, d1], atol=1e-15)   # (51)
            P2s, q2 = c.pair((c.sphere(P1, a2 * a2) ^ c.sphere(c.up(pts["P3"]), a3 * a3)) | Pi_c)  # (52)-(53)
            disc = con.elbow_discriminant
            assert np.isfinite(disc) and (q2 < 0) == (disc < 0), (k, idx, q2, disc)
            if q2 < 0:
                assert con.solution.status == "unreachable" and np.all(np.isnan(pts["P2"]))
                checked["unreachable"] += 1
                continue
            assert _match(P2s, pts["P2"])
            checked["ur"] += 1
        if qc >= 0:
            assert all(_match(used_c, p) for p in Pcs)         # both horizon points are used
    assert checked["kuka"] > 100 and checked["ur"] > 80 and checked["unreachable"] > 30, checked


# ----------------------------------------------------------------------------- unreachable, singular

def test_unreachable_poses_give_no_angles(kuka, ur5):  # Q^2 < 0: thesis (4.70)-(4.73)
    rng = np.random.default_rng(17)
    R = Rotation.random(random_state=rng).as_matrix()
    for robot in (kuka, ur5):
        sol = robot.ik(pose(R, [2.5, -1.0, 0.4]))
        assert sol.status == ("unreachable",) * 8 and sol.unreachable_step == ("elbow",) * 8
        assert np.all(np.isnan(sol.q)) and len(sol) == 0 and not sol
        assert sol.valid_q().shape == (0, 6) and sol.distinct().shape == (0, 6)
        best = robot.ik_closest(pose(R, [2.5, -1.0, 0.4]), np.zeros(6))
        assert best.status == "unreachable" and not best.ok and np.all(np.isnan(best.q))
    # UR: P5 within d4 of the first axis (the horizon has no real point)
    for k in range(10):
        R = Rotation.random(random_state=rng).as_matrix()
        r = ur5.d[3] * rng.uniform(0, 0.99)
        phi = rng.uniform(-pi, pi)
        sol = ur5.ik(pose_from_flange_point(ur5, R, [r * np.cos(phi), r * np.sin(phi), rng.uniform(-0.3, 0.6)]))
        assert sol.status == ("unreachable",) * 8 and sol.unreachable_step == ("shoulder",) * 8
        assert np.all(np.isnan(sol.q))
    # KUKA: wrist centre closer to both shoulder points (d1 e3 +- a1 x1) than
    # a2 - sqrt(a3^2 + d4^2) = 33.5 mm (inside the inner workspace sphere)
    sol = kuka.ik(pose_from_flange_point(kuka, np.eye(3), [1e-3, 0.0, 0.41]), respect_limits=False)
    assert sol.status == ("unreachable",) * 8 and sol.unreachable_step == ("elbow",) * 8


def test_kuka_wrist_singularity_free_angle(kuka):  # Paper 1 §4-5, singular configurations
    rng = np.random.default_rng(18)
    for q in random_q(kuka, rng, 20):
        q[4] = 0.0                                             # theta5 = 0: a_e parallel to z3
        T = kuka.fk(q)
        for q4 in (q[3], 0.7):
            sol = kuka.ik(T, q_free=[0, 0, 0, q4, 0, 0], respect_limits=False)
            assert len(sol) >= 4
            # the branch (shoulder, elbow) of q has z3 = a_e: both its wrist labels are singular
            flagged = [k for k in range(8) if "wrist" in sol.singular[k]]
            assert len(flagged) >= 2 and all(sol.ok[k] for k in flagged)
            for k in flagged:
                assert same_angles(sol.q[k, 3], q4 + (0 if sol.config[k, 2] > 0 else pi), 1e-12)
                assert abs(np.sin(sol.q[k, 4])) < 1e-9
            assert fk_error(kuka, sol.valid_q(), T) < 1e-10
            if q4 == q[3]:
                assert among(sol.valid_q(), q, 1e-8)


def test_kuka_shoulder_singularity_free_angle(kuka):  # Paper 1 §4-5, singular configurations
    rng = np.random.default_rng(19)
    for k in range(20):
        R = Rotation.random(random_state=rng).as_matrix()
        T = pose_from_flange_point(kuka, R, [0.0, 0.0, rng.uniform(0.85, 1.2)])   # P_w on the first axis
        q1 = rng.uniform(-2, 2)
        sol = kuka.ik(T, q_free=[q1, 0, 0, 0, 0, 0], respect_limits=False)
        assert len(sol) >= 4
        for i in np.nonzero(sol.ok)[0]:
            assert "shoulder" in sol.singular[i]
            assert same_angles(sol.q[i, 0], q1 + (0 if sol.config[i, 0] > 0 else pi), 1e-12)
        assert fk_error(kuka, sol.valid_q(), T) < 1e-10


def _ur_elbow_reaches(robot, T, z1, theta6):
    """Independent geometry of the UR wrist singularity: with theta6 fixed, P4 = P5 - d5 z4
    (z4 = R05 (0, sin a5, cos a5), R05 = R Rz(theta6)^T) and P3 = P4 - d4 z1; the elbow
    reaches when ||a2| - |a3|| <= |P3 - P1| <= |a2| + |a3|."""
    R, p = T[:3, :3], T[:3, 3]
    p5 = p - robot.d[5] * R[:, 2]
    c, s_ = np.cos(theta6), np.sin(theta6)
    R05 = R @ np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]]).T
    z4 = R05 @ [0, np.sin(robot.alpha[4]), np.cos(robot.alpha[4])]
    p3 = p5 - robot.d[4] * z4 - robot.d[3] * z1
    dist = np.linalg.norm(p3 - [0, 0, robot.d[0]])
    a2, a3 = abs(robot.a[1]), abs(robot.a[2])
    return abs(a2 - a3) - 1e-12 <= dist <= a2 + a3 + 1e-12


def test_ur_wrist_singularity_free_angle(ur5):  # Paper 1 §4-5, singular configurations
    rng = np.random.default_rng(20)
    moved = 0
    for q in random_q(ur5, rng, 30):
        q[4] = pi if rng.random() < 0.5 else 0.0               # theta5 in {0, pi}: a_e parallel to z1
        T = ur5.fk(q)
        for q6 in (q[5], -1.1, 2.5):
            sol = ur5.ik(T, q_free=[0, 0, 0, 0, 0, q6], respect_limits=False)
            # the shoulder branch of q has z1 parallel to a_e: its solutions are singular
            flagged = [k for k in range(8) if "wrist" in sol.singular[k]]
            assert len(flagged) >= 2 and all(sol.ok[k] for k in flagged), (q, q6, sol)
            assert fk_error(ur5, sol.valid_q(), T) < 1e-10
            for k in flagged:
                assert abs(np.sin(sol.q[k, 4])) < 1e-9
                target = q6 + (0 if sol.config[k, 2] > 0 else pi)      # ik.hpp: flip uses q6 + pi
                if same_angles(sol.q[k, 5], target, 1e-12):
                    continue
                # ik.hpp: otherwise the nearest q6 for which the elbow reaches: the target
                # and every q6 closer to it do not reach, the returned one does
                z1 = ur5.joint_frames(sol.q[k])[1][:3, 2]
                got = sol.q[k, 5]
                delta = abs(wrap(got - target))
                assert _ur_elbow_reaches(ur5, T, z1, got + 1e-9 * np.sign(wrap(got - target)))
                for t in target + np.linspace(-1, 1, 41)[1:-1] * delta:
                    assert not _ur_elbow_reaches(ur5, T, z1, t), (q, q6, k, got, t)
                moved += 1
            if q6 == q[5]:
                assert among(sol.valid_q(), q, 1e-8)
    assert moved > 0


@pytest.mark.parametrize("name", ROBOTS)
def test_elbow_stretched_sets_elbow_flag(name):  # Paper 1 §4-5, singular configurations
    robot, rng = Robot.by_name(name), np.random.default_rng(21)
    for q in _stretched_q(robot, rng, 20, 0.0):
        T = robot.fk(q)
        sol = robot.ik(T, respect_limits=False)
        assert fk_error(robot, sol.valid_q(), T) < 1e-10
        assert among(sol.valid_q(), q, 1e-6)
        flagged = [k for k in np.nonzero(sol.ok)[0] if "elbow" in sol.singular[k]]
        assert len(flagged) >= 2
        for k in flagged:                                      # both elbow labels: the same angles
            partner = k ^ 2
            assert sol.ok[partner] and "elbow" in sol.singular[partner]
            assert same_angles(sol.q[k], sol.q[partner], 1e-6)
        assert len(sol.distinct(tol=1e-6)) == len(sol) - len(flagged) // 2


def test_ur_shoulder_singularity(ur5):  # Paper 1 §5: P_c on the first axis
    rng = np.random.default_rng(22)
    for k in range(20):
        R = Rotation.random(random_state=rng).as_matrix()
        phi = rng.uniform(-pi, pi)
        p5 = [ur5.d[3] * np.cos(phi), ur5.d[3] * np.sin(phi), rng.uniform(-0.2, 0.5)]
        T = pose_from_flange_point(ur5, R, p5)
        sol = ur5.ik(T, respect_limits=False)
        assert len(sol) >= 2
        assert fk_error(ur5, sol.valid_q(), T) < 1e-9
        for i in np.nonzero(sol.ok)[0]:
            assert "shoulder" in sol.singular[i]
            # ik.hpp: the solutions with shoulder AND elbow labels flipped coincide (the elbow
            # label is measured relative to the shoulder side, which has no meaning here)
            assert sol.ok[i ^ 6] and same_angles(sol.q[i], sol.q[i ^ 6], 1e-6), (k, i)
        assert len(sol.distinct(tol=1e-6)) == len(sol) // 2


# ----------------------------------------------------------------------------- flag pairs, labels

@pytest.mark.parametrize("name", ROBOTS)
def test_wrist_flip_and_label_pairs(name):  # Paper 1 eqs. (26)-(28)
    robot = Robot.by_name(name)
    rng = np.random.default_rng(23)
    q = random_q(robot, rng, 300, inside=False)
    res = robot.ik_batch(robot.fk(q), respect_limits=False)
    th = res.q + robot.theta_offset
    pairs = 0
    for i in range(len(q)):
        for k in range(0, 8, 2):                               # k: wrist +1, k + 1: flip
            if not (res.ok[i, k] and res.ok[i, k + 1]):
                continue
            a, b = th[i, k], th[i, k + 1]
            pairs += 1
            if name == "kr6_r900_sixx":
                expect = np.r_[a[:3], a[3] + pi, -a[4], a[5] + pi]
                assert same_angles(b, expect, 1e-9), (i, k, a, b)
            else:
                assert same_angles(b[0], a[0], 1e-9)
                assert same_angles(b[4], -a[4], 1e-9) and same_angles(b[5], a[5] + pi, 1e-9)
        for k in (0, 1, 4, 5):                                 # elbow pairs share theta1
            if res.ok[i, k] and res.ok[i, k + 2]:
                assert same_angles(th[i, k, 0], th[i, k + 2, 0], 1e-9)
        for k in range(4):                                     # shoulder pairs
            if res.ok[i, k] and res.ok[i, k + 4]:
                d = abs(wrap(th[i, k, 0] - th[i, k + 4, 0]))
                if name == "kr6_r900_sixx":
                    assert abs(d - pi) < 1e-9
                else:
                    # horizon geometry: the tangent points from the axis to the circle of
                    # radius d4 around P5 are pi - 2 asin(d4 / rho) apart in theta1
                    T = robot.fk(q[i])
                    p5 = T[:3, 3] - robot.d[5] * T[:3, 2]
                    beta = np.arcsin(robot.d[3] / np.hypot(p5[0], p5[1]))
                    assert abs(d - (pi - 2 * beta)) < 1e-8, (i, k, d, pi - 2 * beta)
    assert pairs > 800


@pytest.mark.parametrize("name", ROBOTS)
def test_configuration_labels_are_geometric(name):
    """ik.hpp: shoulder = side of the wrist centre w.r.t. f = sign(a2) x1 (the way the
    upper arm points at theta2 = 0), elbow = P2 above the line from P1 to the wrist point
    seen with the arm reaching forward, wrist = sign(sin theta5); on the joint frames."""
    robot = Robot.by_name(name)
    rng = np.random.default_rng(24)
    q = random_q(robot, rng, 200, inside=False)
    res = robot.ik_batch(robot.fk(q), respect_limits=False)
    e3 = np.array([0.0, 0.0, 1.0])
    checked = 0
    bad = {"shoulder": 0, "elbow": 0, "wrist": 0}
    for i, k in zip(*np.nonzero(res.ok)):
        qs = res.q[i, k]
        F = robot.joint_frames(qs)
        x1, z1 = F[1][:3, 0], F[1][:3, 2]
        P1, P2 = F[1][:3, 3], F[2][:3, 3]
        if name == "kr6_r900_sixx":
            centre = wrist_point = F[4][:3, 3]                   # P_w
        else:
            P5 = F[5][:3, 3]
            centre = P5 - (P5 @ z1) * z1                        # P_c: P5 projected on the arm plane
            wrist_point = F[3][:3, 3]                           # P3
        horiz = centre * [1, 1, 0]
        if np.linalg.norm(horiz) < 1e-3:
            continue
        w_hat = horiz / np.linalg.norm(horiz)                  # the arm reaches towards +w_hat
        side = np.sign(robot.a[1]) * x1 @ centre               # on the side f = sign(a2) x1?
        above = np.cross(wrist_point - P1, P2 - P1) @ np.cross(w_hat, e3)
        s5 = np.sin(qs[4] + robot.theta_offset[4])
        if abs(side) < 1e-6 or abs(s5) < 1e-6:
            continue
        bad["shoulder"] += int(kin.CONFIGS[k, 0] != np.sign(side))
        bad["wrist"] += int(kin.CONFIGS[k, 2] != np.sign(s5))
        if (wrist_point - P1) @ w_hat > 1e-3 and abs(above) > 1e-9:   # unambiguous "above"
            bad["elbow"] += int(kin.CONFIGS[k, 1] != np.sign(above))
            checked += 1
    assert bad == {"shoulder": 0, "elbow": 0, "wrist": 0}, (bad, checked)
    assert checked > 500


def test_solution_indexing():
    for k in range(8):
        s, e, w = (int(v) for v in kin.CONFIGS[k])
        assert kin.IKResult.index(s, e, w) == k == kin.config_index(s, e, w)
    with pytest.raises(ValueError):
        kin.config_index(1, 0, 1)
    robot = kin.kuka_kr6_r900_sixx()
    sol = robot.ik(robot.fk([0.3, -1.2, 1.5, 0.4, 0.8, -0.2]))
    np.testing.assert_array_equal(sol.config, kin.CONFIGS)
    assert sol.config.dtype == np.int8 and sol.q.shape == (8, 6)
    assert len(sol.status) == len(sol.singular) == len(sol.unreachable_step) == 8
    assert sol.ok.dtype == bool and len(sol) == np.count_nonzero(sol.ok)
    np.testing.assert_array_equal(sol.valid_q(), sol.q[sol.ok])


# ----------------------------------------------------------------------------- closest, trajectory

def _closest_oracle(robot, T, qc, w):
    """Brute force over every ok solution and 2 pi multiple inside the limits."""
    sol = robot.ik(T)
    best, best_cost = None, np.inf
    lim = robot.limits
    for q in sol.valid_q():
        cand = q[None, :] + TWO_PI * np.arange(-3, 4)[:, None]          # (7, 6)
        inside = (cand >= lim[:, 0] - 1e-12) & (cand <= lim[:, 1] + 1e-12)
        cost = np.where(inside, w * (cand - qc) ** 2, np.inf)
        pick = cand[np.argmin(cost, axis=0), np.arange(6)]
        c = float(np.sum(w * (pick - qc) ** 2))
        if c < best_cost:
            best, best_cost = pick, c
    return best, best_cost


@pytest.mark.parametrize("name", ROBOTS)
def test_ik_closest_matches_brute_force(name):
    robot = Robot.by_name(name)
    rng = np.random.default_rng(25)
    differs = 0
    for q in random_q(robot, rng, 60):
        T = robot.fk(q)
        near = robot.ik_closest(T, q + rng.normal(0, 0.01, 6))
        assert near.ok and near.status == "ok" and near.singular == ()
        np.testing.assert_allclose(near.q, q, atol=1e-9)              # the generating q itself
        qc = random_q(robot, rng, 1)[0]
        w = rng.uniform(0.01, 10, 6)
        got = robot.ik_closest(T, qc, weights=w)
        ref, cost = _closest_oracle(robot, T, qc, w)
        np.testing.assert_allclose(got.q, ref, atol=1e-9)
        assert abs(np.sum(w * (got.q - qc) ** 2) - cost) < 1e-9
        unweighted = robot.ik_closest(T, qc)
        differs += not np.allclose(unweighted.q, got.q)
        cfg = got.config
        assert kin.IKResult.index(*(int(v) for v in cfg)) in np.nonzero(robot.ik(T).ok)[0]
    assert differs > 0                                                  # weights matter


def test_ik_closest_keeps_two_pi_multiples_inside_limits(ur5, kuka):
    q = np.array([6.0, -1.0, 1.2, -0.5, 1.0, -5.9])                    # UR limits are +-2 pi
    T = ur5.fk(q)
    got = ur5.ik_closest(T, q + 0.01)
    np.testing.assert_allclose(got.q, q, atol=1e-9)                     # not wrapped to -0.28
    sol = ur5.ik(T)                                                     # ik: the multiple nearest 0
    k = np.argmin(np.max(np.abs(wrap(sol.q - q)), axis=1))
    np.testing.assert_allclose(sol.q[k], wrap(q), atol=1e-9)
    q = np.array([0.2, -1.3, 1.4, 0.3, 0.9, 5.5])                       # KUKA A6 +-350 deg
    got = kuka.ik_closest(kuka.fk(q), q - 0.02)
    np.testing.assert_allclose(got.q, q, atol=1e-9)


def test_limits_give_outside_limits():
    kuka = kin.kuka_kr6_r900_sixx()
    q0 = np.array([0.2, -1.3, 1.4, 0.3, 0.9, 0.5])
    narrow = Robot.from_dh(kuka.a, kuka.alpha, kuka.d, kuka.theta_offset,
                           limits=np.c_[q0 - 0.2, q0 + 0.2], name="narrow")
    assert narrow.geometry == "spherical_wrist"
    inside = narrow.ik(narrow.fk(q0))
    assert len(inside) == 1 and among(inside.valid_q(), q0, 1e-9)
    q = q0 + [1.0, 0, 0, 0, 0, 0]
    T = narrow.fk(q)
    sol = narrow.ik(T)
    assert len(sol) == 0 and "outside_limits" in sol.status
    assert set(sol.status) <= {"outside_limits", "unreachable"}
    out = [k for k in range(8) if sol.status[k] == "outside_limits"]
    assert fk_error(narrow, sol.q[out], T) < 1e-10                      # angles are still given
    free = narrow.ik(T, respect_limits=False)
    assert among(free.valid_q(), q, 1e-9)
    best = narrow.ik_closest(T, q0)
    assert best.status == "outside_limits" and not best.ok and np.all(np.isnan(best.q))
    assert narrow.ik_closest(T, q0, respect_limits=False).ok
    b = narrow.ik_batch(T[None])
    assert b.status_names()[0].tolist() == list(sol.status)


@pytest.mark.parametrize("name", ROBOTS)
def test_ik_trajectory_follows_a_smooth_path(name):
    robot = Robot.by_name(name)
    q0 = np.array([0.3, -1.2, 1.4, 0.4, 0.9, -0.3]) if name != "ur5" else np.array([0.3, -1.2, 1.4, -1.0, 1.2, 0.3])
    T0 = robot.fk(q0)
    n = 60
    path = np.repeat(T0[None], n, axis=0)
    s = np.linspace(0, 1, n)
    path[:, :3, 3] += s[:, None] * [0.08, -0.06, 0.05]
    for i in range(n):
        path[i, :3, :3] = Rotation.from_rotvec([0, 0.3 * s[i], 0.4 * s[i]]).as_matrix() @ T0[:3, :3]
    traj = robot.ik_trajectory(path, q0)
    assert traj.ok.all() and traj.q.shape == (n, 6) and len(traj) == n
    np.testing.assert_allclose(traj.q[0], q0, atol=1e-9)
    assert np.max(np.abs(np.diff(traj.q, axis=0))) < 0.05              # continuous, one branch
    assert fk_error(robot, traj.q, path) < 1e-10
    # = chaining ik_closest by hand
    q = q0
    for i in range(n):
        q = robot.ik_closest(path[i], q).q
        np.testing.assert_allclose(traj.q[i], q, atol=1e-12)
    # a pose out of reach in the middle: NaN row, then continue from the last good joints
    bad = path.copy()
    bad[30, :3, 3] = [3.0, 0, 0]
    t2 = robot.ik_trajectory(bad, q0)
    assert t2.status[30] == "unreachable" and np.all(np.isnan(t2.q[30]))
    assert t2.ok.sum() == n - 1
    np.testing.assert_allclose(t2.q[31], traj.q[31], atol=1e-9)


def test_ik_construction_reports_points(kuka, ur5):
    q = np.array([0.3, -1.2, 1.4, 0.4, 0.9, -0.3])
    con = kuka.ik_construction(kuka.fk(q), 1, 1, 1)
    assert set(con.points) == {"p_e", "P_w", "P1", "P2", "P_wx"} and con.config == (1, 1, 1)
    assert con.solution.status in ("ok", "outside_limits") and con.elbow_discriminant > 0
    sol = kuka.ik(kuka.fk(q))
    np.testing.assert_allclose(con.solution.q, sol.q[0], atol=1e-12)
    F = kuka.joint_frames(con.solution.q)                            # points = joint origins
    for name, i in (("P1", 1), ("P2", 2), ("P_wx", 3), ("P_w", 4)):
        np.testing.assert_allclose(con.points[name], F[i][:3, 3], atol=1e-10)
    con = ur5.ik_construction(ur5.fk(q), -1, 1, -1)
    assert set(con.points) == {"p_e", "P5", "P_c", "P4", "P3", "P2", "P1"}
    F = ur5.joint_frames(con.solution.q)
    for name, i in (("P1", 1), ("P2", 2), ("P3", 3), ("P4", 4), ("P5", 5)):
        np.testing.assert_allclose(con.points[name], F[i][:3, 3], atol=1e-10)
    with pytest.raises(ValueError):
        ur5.ik_construction(ur5.fk(q), 2, 1, 1)


# ----------------------------------------------------------------------------- bad input

def test_bad_input_raises(kuka):
    T = kuka.fk([0.1, -1.0, 1.0, 0.2, 0.5, 0.1])
    with pytest.raises(ValueError, match="q"):
        kuka.fk(np.zeros(5))
    with pytest.raises(ValueError, match="q"):
        kuka.fk(np.zeros((3, 7)))
    with pytest.raises(ValueError, match="non-finite"):
        kuka.fk([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(TypeError, match="q"):
        kuka.fk(np.zeros(6, dtype=complex))
    with pytest.raises(TypeError):
        kuka.fk(["a"] * 6)
    with pytest.raises(TypeError):
        kuka.fk(np.zeros(6, dtype=bool))
    np.testing.assert_array_equal(kuka.fk([0, 0, 0, 0, 0, 0]), kuka.fk(np.zeros(6)))   # integers are fine
    with pytest.raises(ValueError, match="T_base_tool"):
        kuka.ik(T[:3])
    with pytest.raises(TypeError, match="T_base_tool"):
        kuka.ik(T.astype(object))
    bad = T.copy()
    bad[0, 3] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        kuka.ik(bad)
    bad = T.copy()
    bad[:3, :3] *= 1.01
    with pytest.raises(ValueError, match="orthonormal"):
        kuka.ik(bad)
    bad = T.copy()
    bad[3, 0] = 0.5
    with pytest.raises(ValueError, match="last row"):
        kuka.ik(bad)
    bad = T.copy()
    bad[:3, 0] *= -1
    with pytest.raises(ValueError, match="reflection"):
        kuka.ik(bad)
    for fn in (lambda: kuka.ik_closest(bad, np.zeros(6)), lambda: kuka.ik_construction(bad)):
        with pytest.raises(ValueError):
            fn()
    with pytest.raises(ValueError, match="q_free"):
        kuka.ik(T, q_free=np.zeros(5))
    with pytest.raises(ValueError, match="q_current"):
        kuka.ik_closest(T, [0, 0, np.nan, 0, 0, 0])
    with pytest.raises(ValueError, match="weights"):
        kuka.ik_closest(T, np.zeros(6), weights=[1, 1, -1, 1, 1, 1])
    with pytest.raises(ValueError, match="T_base_tool"):
        kuka.ik_batch(T)                                                 # (4, 4), not (N, 4, 4)
    with pytest.raises(ValueError, match=r"T_base_tool\[1\]"):
        kuka.ik_trajectory(np.stack([T, bad]), np.zeros(6))
    with pytest.raises(ValueError, match="q_start"):
        kuka.ik_trajectory(T[None], np.zeros(7))
    with pytest.raises(ValueError, match="limits"):
        Robot.from_dh(kuka.a, kuka.alpha, kuka.d, limits=[[1, -1]] * 6)
    with pytest.raises(ValueError, match="alpha"):
        Robot.from_dh(kuka.a, kuka.alpha[:5], kuka.d)
    with pytest.raises(ValueError, match="T_flange_tool"):
        kuka.with_tool(np.diag([2.0, 1, 1, 1]))
    with pytest.raises(TypeError):
        Robot(object())


def test_results_and_robots_are_values(ur5):
    """Bound C++ structs: read-only results, robots that copy and pickle exactly."""
    import pickle

    q = np.array([0.3, -1.2, 1.4, -1.0, 1.2, 0.3])
    T = ur5.fk(q)
    sol, near = ur5.ik(T), ur5.ik_closest(T, q)
    batch, traj = ur5.ik_batch(np.stack([T, T])), ur5.ik_trajectory(T[None], q)
    for a in (sol.q, sol.config, near.q, batch.q, batch.status, traj.q, kin.CONFIGS, ur5.limits):
        with pytest.raises(ValueError):
            a[0] = 1
    assert bool(sol) and len(sol) == 8 and sol.status == ("ok",) * 8 and traj.status == ("ok",)
    np.testing.assert_array_equal(batch.solutions(-1).q, batch.solutions(1).q)
    with pytest.raises(IndexError):
        batch.solutions(2)
    Tt = np.eye(4)
    Tt[:3, 3] = [0.01, 0.02, 0.15]
    moved = ur5.with_tool(Tt).with_base(T)
    for copy in (Robot(moved), pickle.loads(pickle.dumps(moved))):
        assert copy.name == moved.name and repr(copy) == repr(moved)
        for field in ("dh", "limits", "T_base_dh0", "T_flange_tool"):
            np.testing.assert_array_equal(getattr(copy, field), getattr(moved, field))
        np.testing.assert_array_equal(copy.fk(q), moved.fk(q))
    with pytest.raises(ValueError, match="reach_tolerance"):
        ur5.ik(T, reach_tolerance=-1.0)
    with pytest.raises(ValueError, match="tol"):
        sol.distinct(tol=np.nan)
    for call in (lambda: ur5.fk(np.zeros((2, 6)), num_threads=-1), lambda: ur5.ik_batch(T[None], num_threads=-1)):
        with pytest.raises(ValueError, match="num_threads"):
            call()


def test_unsupported_geometry():
    a = [0.1, 0.3, 0.25, 0.0, 0.0, 0.0]
    alpha = [pi / 2, 0.1, -pi / 2, pi / 2, -pi / 2, 0]                  # a twisted upper arm
    d = [0.3, 0.0, 0.0, 0.3, 0.0, 0.1]
    r = Robot.from_dh(a, alpha, d)
    assert r.geometry == "unsupported"
    q = random_q(r, np.random.default_rng(26), 5)
    np.testing.assert_allclose(r.fk(q), dh_fk(r, q), atol=1e-13)      # FK still works
    T = r.fk(q[0])
    for call in (lambda: r.ik(T), lambda: r.ik_batch(T[None]), lambda: r.ik_closest(T, q[0]),
                 lambda: r.ik_trajectory(T[None], q[0]), lambda: r.ik_construction(T)):
        with pytest.raises(ValueError, match="spherical_wrist.*universal_robots"):
            call()


def test_batch_bad_pose_is_invalid_input_for_that_pose_only(ur5):
    rng = np.random.default_rng(27)
    q = random_q(ur5, rng, 6)
    T = ur5.fk(q)
    T[2, 1, 3] = np.nan
    T[4, :3, :3] *= 1.5                                                 # not rigid
    res = ur5.ik_batch(T)
    for i in range(6):
        if i in (2, 4):
            assert np.all(res.status[i] == 3) and np.all(np.isnan(res.q[i]))
            assert res.status_names()[i].tolist() == ["invalid_input"] * 8
            assert res.count_ok[i] == 0
        else:
            single = ur5.ik(T[i])
            np.testing.assert_array_equal(res.q[i], single.q)
            assert res.status_names()[i].tolist() == list(single.status)
            assert among(single.valid_q(), q[i], 1e-8)
    assert len(res) == 6 and res.ok.shape == (6, 8)
    empty = ur5.ik_batch(np.zeros((0, 4, 4)))
    assert empty.q.shape == (0, 8, 6) and empty.count_ok.shape == (0,)
