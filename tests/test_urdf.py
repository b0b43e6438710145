"""Robot.from_urdf (scanalign.kinematics.urdf): DH robots from URDF chains.

Independent truth: Pinocchio's forward kinematics (`pin`) of the same URDF files, the
URDFs that `example-robot-data` ships (UR3, UR5, UR10, Kinova Jaco 2, Unitree Z1, Franka
Panda), and the built-in DH tables (`Robot.by_name`), from which a KR6 R900 sixx URDF with a
deliberately non-DH link layout (turned joint frames, -z and oblique axes, fixed joints
between links) is written here.
"""

from __future__ import annotations

import builtins
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import numpy as np
import pytest
from numpy import pi

from scanalign import kinematics as kin
from scanalign.kinematics import Robot

yourdfpy = pytest.importorskip("yourdfpy")

UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint")


def _robots_dir() -> Path:
    """example-robot-data installs its URDFs as package data under cmeel.prefix (no Python module)."""
    try:
        d = Path(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    except PackageNotFoundError:
        pytest.skip("example-robot-data is not installed")
    if not d.is_dir():
        pytest.skip(f"example-robot-data has no robots folder at {d}")
    return d


def wrap(x):
    return (np.asarray(x) + pi) % (2 * pi) - pi


def random_q(robot, rng, n):
    lim = np.clip(robot.limits, -pi, pi)
    return rng.uniform(lim[:, 0], lim[:, 1], (n, 6))


def pin_fk(path, joints, base, tip, q):
    """T_base_tip (N, 4, 4) by Pinocchio for joint values q (N, len(joints)); other joints at 0."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fb, ft = model.getFrameId(base), model.getFrameId(tip)
    out = []
    for row in np.atleast_2d(q):
        qv = pin.neutral(model)
        for name, v in zip(joints, row):
            j = model.joints[model.getJointId(name)]
            if j.nq == 2:  # continuous joints are (cos, sin) in Pinocchio
                qv[j.idx_q:j.idx_q + 2] = np.cos(v), np.sin(v)
            else:
                qv[j.idx_q] = v
        pin.framesForwardKinematics(model, data, qv)
        out.append(np.linalg.inv(data.oMf[fb].homogeneous) @ data.oMf[ft].homogeneous)
    return np.array(out)


def roundtrip(robot, q, tol_fk=1e-10, tol_q=1e-7):
    """As tests/test_kinematics.py: every ok solution of FK(q) reproduces the pose and the
    generating q is among them (modulo 2 pi)."""
    T = robot.fk(q)
    res = robot.ik_batch(T)
    idx = np.nonzero(res.ok)
    assert len(idx[0]) > 0
    worst = float(np.abs(robot.fk(res.q[idx]) - T[idx[0]]).max())
    assert worst < tol_fk, f"FK(IK(T)) off by {worst:.3g}"
    d = np.max(np.abs(wrap(res.q - q[:, None, :])), axis=2)
    d[~res.ok] = np.inf
    found = d.min(axis=1) <= tol_q
    assert found.all(), f"generating q not found for {np.count_nonzero(~found)} poses"
    assert np.all(robot.within_limits(res.q[res.ok], tol=1e-12))


# ----------------------------------------------------------------------------- example-robot-data

@pytest.mark.parametrize("model", ["ur5", "ur3", "ur10"])
def test_ur_urdf_matches_pinocchio_and_builtin_table(model):
    path = _robots_dir() / "ur_description" / "urdf" / f"{model}_robot.urdf"
    robot = Robot.from_urdf(path, "base_link", "tool0")
    assert robot.geometry == "universal_robots" and robot.name == model
    q = random_q(robot, np.random.default_rng(1), 300)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, UR_JOINTS, "base_link", "tool0", q), rtol=0, atol=1e-12)
    # The DH table is UR's published one (x signs chosen for zero theta offsets, a2, a3 < 0); the
    # URDF's pi/2 = 1.57079632679 leaves theta offsets of 5e-12.
    builtin = Robot.by_name(model)
    np.testing.assert_allclose(robot.dh, builtin.dh, rtol=0, atol=1e-11)
    # DH frame 0 is UR's "base" frame, turned by pi about z from ROS's base_link; tool0 is the flange.
    np.testing.assert_allclose(robot.T_base_dh0, np.diag([-1.0, -1, 1, 1]), atol=1e-15)
    np.testing.assert_allclose(robot.T_flange_tool, np.eye(4), atol=1e-11)
    np.testing.assert_allclose(robot.fk(q), builtin.with_base(robot.T_base_dh0).fk(q), rtol=0, atol=1e-10)
    # limits: the URDF's (+-2 pi, elbow +-pi in these files)
    np.testing.assert_allclose(robot.limits, [[-6.28318530718, 6.28318530718]] * 2 + [[-3.14159265359, 3.14159265359]]
                               + [[-6.28318530718, 6.28318530718]] * 3)
    roundtrip(robot, random_q(robot, np.random.default_rng(2), 1000))


def test_ur5_ik_solutions_equal_the_builtin_robot():
    robot = Robot.from_urdf(_robots_dir() / "ur_description/urdf/ur5_robot.urdf", "base_link", "tool0")
    builtin = kin.ur5().with_base(robot.T_base_dh0)
    T = robot.fk(random_q(robot, np.random.default_rng(3), 200))
    a, b = robot.ik_batch(T, respect_limits=False), builtin.ik_batch(T, respect_limits=False)
    np.testing.assert_array_equal(a.status, b.status)
    # the tables differ by the URDF's 5e-12 rad theta offsets, which near-singular poses amplify
    np.testing.assert_allclose(wrap(a.q[a.ok] - b.q[b.ok]), 0, atol=1e-7)
    q0 = np.array([0.1, -1.2, 1.0, -0.5, 1.1, 0.3])
    np.testing.assert_allclose(robot.ik_closest(robot.fk(q0), q0 + 0.01).q, q0, atol=1e-9)


def test_ur5_tip_and_base_choice():
    path = _robots_dir() / "ur_description/urdf/ur5_robot.urdf"
    # ee_link (a fixed joint past wrist_3, turned by pi/2) and the world link above base_link
    robot = Robot.from_urdf(path, "world", "ee_link", name="my ur5")
    assert robot.name == "my ur5" and robot.geometry == "universal_robots"
    q = random_q(robot, np.random.default_rng(4), 100)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, UR_JOINTS, "world", "ee_link", q), rtol=0, atol=1e-12)
    roundtrip(robot, q)


@pytest.mark.parametrize("urdf, base, tip, joints", [
    ("kinova_description/robots/kinova.urdf", "j2s6s200_link_base", "j2s6s200_end_effector",
     [f"j2s6s200_joint_{i}" for i in range(1, 7)]),                     # Jaco 2: e2 offset, continuous joints
    ("z1_description/urdf/z1.urdf", "link00", "link06", [f"joint{i}" for i in range(1, 7)]),   # offset wrist
    ("panda_description/urdf/panda.urdf", "panda_link1", "panda_hand_tcp",
     [f"panda_joint{i}" for i in range(2, 8)]),                          # 6 of the Panda's 7 joints
])
def test_non_analytic_chain_raises_but_fk_only_matches_pinocchio(urdf, base, tip, joints):
    path = _robots_dir() / urdf
    with pytest.raises(ValueError, match=r"kinova.urdf|z1.urdf|panda.urdf") as e:
        Robot.from_urdf(path, base, tip)
    msg = str(e.value)
    assert f"{base} -> {tip}" in msg and "spherical_wrist" in msg and "universal_robots" in msg
    assert "fk_only=True" in msg and joints[0] in msg
    robot = Robot.from_urdf(path, base, tip, fk_only=True)
    assert robot.geometry == "unsupported"
    q = random_q(robot, np.random.default_rng(5), 200)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, joints, base, tip, q), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="spherical_wrist.*universal_robots"):
        robot.ik(robot.fk(q[0]))


@pytest.mark.parametrize("seed", range(5))
def test_random_6r_chain_fk_matches_pinocchio(tmp_path, seed):
    """Skew joint axes, random origins, fixed joints and a continuous joint: FK only, exact."""
    rng = np.random.default_rng(100 + seed)
    f = lambda v: " ".join(repr(float(x)) for x in v)  # noqa: E731
    body = '<link name="l0"/>'
    parent = "l0"
    for i in range(1, 7):
        kind = "continuous" if i == 4 else "revolute"
        body += (f'<link name="m{i}"/><link name="l{i}"/>'
                 f'<joint name="f{i}" type="fixed"><parent link="{parent}"/><child link="m{i}"/>'
                 f'<origin xyz="{f(rng.uniform(-0.2, 0.2, 3))}" rpy="{f(rng.uniform(-pi, pi, 3))}"/></joint>'
                 f'<joint name="j{i}" type="{kind}"><parent link="m{i}"/><child link="l{i}"/>'
                 f'<origin xyz="{f(rng.uniform(-0.2, 0.2, 3))}" rpy="{f(rng.uniform(-pi, pi, 3))}"/>'
                 f'<axis xyz="{f(rng.normal(size=3))}"/><limit lower="-2" upper="2.5" effort="1" velocity="1"/></joint>')
        parent = f"l{i}"
    body += ('<link name="tip"/><joint name="ft" type="fixed"><parent link="l6"/><child link="tip"/>'
             f'<origin xyz="{f(rng.uniform(-0.2, 0.2, 3))}" rpy="{f(rng.uniform(-pi, pi, 3))}"/></joint>')
    path = tmp_path / "random.urdf"
    path.write_text(f'<?xml version="1.0"?><robot name="random">{body}</robot>')
    robot = Robot.from_urdf(path, "l0", "tip", fk_only=True)
    assert robot.geometry == "unsupported"
    np.testing.assert_array_equal(robot.limits[3], [-np.inf, np.inf])
    np.testing.assert_array_equal(robot.limits[[0, 1, 2, 4, 5]], [[-2, 2.5]] * 5)
    q = random_q(robot, rng, 200)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, [f"j{i}" for i in range(1, 7)], "l0", "tip", q),
                               rtol=0, atol=1e-12)


def test_kinova_continuous_joints_are_unlimited():
    robot = Robot.from_urdf(_robots_dir() / "kinova_description/robots/kinova.urdf", "j2s6s200_link_base",
                            "j2s6s200_end_effector", fk_only=True)
    assert np.all(np.isinf(robot.limits[[0, 3, 5]])) and np.all(np.isfinite(robot.limits[[1, 2, 4]]))
    np.testing.assert_allclose(robot.limits[1], [0.820304748437, 5.46288055874])


def test_panda_seven_joints_and_prismatic_fingers_raise():
    path = _robots_dir() / "panda_description/urdf/panda.urdf"
    with pytest.raises(ValueError, match=r"panda\.urdf.*panda_link0 -> panda_hand has 7 revolute.*panda_joint7"):
        Robot.from_urdf(path, "panda_link0", "panda_hand")
    with pytest.raises(ValueError, match=r"panda\.urdf.*'panda_finger_joint1'.*prismatic"):
        Robot.from_urdf(path, "panda_link0", "panda_leftfinger")
    with pytest.raises(ValueError, match=r"panda\.urdf.*has 3 revolute"):
        Robot.from_urdf(path, "panda_link0", "panda_link3")


# ----------------------------------------------------------------------------- a KR6 R900 sixx URDF

def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _random_rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def _origin(T):
    """URDF <origin> of a 4x4 (rpy: R = Rz(yaw) Ry(pitch) Rx(roll)), written to full precision."""
    R = T[:3, :3]
    pitch = np.arcsin(-np.clip(R[2, 0], -1, 1))
    roll, yaw = np.arctan2(R[2, 1], R[2, 2]), np.arctan2(R[1, 0], R[0, 0])
    f = lambda v: " ".join(repr(float(x)) for x in v)  # noqa: E731
    return f'<origin xyz="{f(T[:3, 3])}" rpy="{f((roll, pitch, yaw))}"/>'


def _hom(R=np.eye(3), p=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def write_kuka_urdf(path, T_flange_tool, reversed_joints=(), seed=0):
    """The built-in KR6 R900 sixx as a URDF whose links are not DH frames: every joint frame is
    the DH frame shifted along its axis and turned (the axis becomes -z, x, an oblique vector...),
    with a fixed joint and an extra link before every revolute joint. reversed_joints (0-based)
    turn the other way (axis reversed, limits mirrored), as in KUKA's own descriptions."""
    rng = np.random.default_rng(seed)
    kuka = kin.kuka_kr6_r900_sixx()
    F = kuka.joint_frames(np.zeros(6))                       # DH frames at q = 0 in the base
    local_axes = [(0, 0, -1), (1, 0, 0), None, (0, -1, 0), None, (0, 0, 1)]   # None: oblique
    lines = ['<?xml version="1.0"?>', '<robot name="kr6_test">', '<link name="base"/>']
    parent, T_parent = "base", np.eye(4)
    for i in range(6):
        sign = -1.0 if i in reversed_joints else 1.0
        w = sign * F[i][:3, 2]                                 # the joint axis in the base, URDF sense
        a = np.array(local_axes[i] if local_axes[i] is not None else rng.normal(size=3), float)
        a /= np.linalg.norm(a)
        # a joint frame R with R @ a = w: any rotation taking a to w, then a turn about w
        v, c = np.cross(a, w), np.dot(a, w)
        R_aw = _rot(v, np.arctan2(np.linalg.norm(v), c)) if np.linalg.norm(v) > 1e-12 else \
            (np.eye(3) if c > 0 else _rot(np.cross(a, [0.3, 0.5, 0.7]), pi))
        J = _hom(_rot(w, rng.uniform(-pi, pi)) @ R_aw, F[i][:3, 3] + rng.uniform(-0.2, 0.2) * w)
        M = _hom(_random_rotation(rng), rng.uniform(-0.3, 0.3, 3))   # an intermediate link anywhere
        lo, hi = kuka.limits[i] if sign > 0 else -kuka.limits[i][::-1]
        lines += [f'<link name="mount{i + 1}"/>', f'<link name="link{i + 1}"/>',
                  f'<joint name="fix{i + 1}" type="fixed"><parent link="{parent}"/><child link="mount{i + 1}"/>'
                  f'{_origin(np.linalg.inv(T_parent) @ M)}</joint>',
                  f'<joint name="a{i + 1}" type="revolute"><parent link="mount{i + 1}"/>'
                  f'<child link="link{i + 1}"/>{_origin(np.linalg.inv(M) @ J)}'
                  f'<axis xyz="{" ".join(repr(float(x)) for x in a)}"/>'
                  f'<limit lower="{float(lo)!r}" upper="{float(hi)!r}" effort="1" velocity="1"/></joint>']
        parent, T_parent = f"link{i + 1}", J
    # the flange (DH frame 6) and a tool on it, both by fixed joints
    lines += ['<link name="flange"/>', '<link name="tool0"/>',
              f'<joint name="flange_joint" type="fixed"><parent link="link6"/><child link="flange"/>'
              f'{_origin(np.linalg.inv(T_parent) @ F[6])}</joint>',
              f'<joint name="tool_joint" type="fixed"><parent link="flange"/><child link="tool0"/>'
              f'{_origin(T_flange_tool)}</joint>', '</robot>']
    Path(path).write_text("\n".join(lines))
    return path


@pytest.fixture(scope="module")
def tool():
    return _hom(_rot([1, 2, 3], 0.7), [0.01, -0.02, 0.15])


def test_kuka_urdf_gives_the_builtin_table(tmp_path, tool):
    path = write_kuka_urdf(tmp_path / "kr6.urdf", tool)
    kuka = kin.kuka_kr6_r900_sixx()
    joints = [f"a{i}" for i in range(1, 7)]
    q = random_q(kuka, np.random.default_rng(7), 500)
    # the flange link as the tip: the built-in robot exactly
    flange = Robot.from_urdf(path, "base", "flange")
    assert flange.geometry == "spherical_wrist" and flange.name == "kr6_test"
    np.testing.assert_allclose(flange.dh, kuka.dh, rtol=0, atol=1e-12)
    np.testing.assert_allclose(flange.limits, kuka.limits, rtol=0, atol=1e-15)
    np.testing.assert_allclose(flange.T_base_dh0, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(flange.T_flange_tool, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(flange.fk(q), kuka.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(flange.fk(q), pin_fk(path, joints, "base", "flange", q), rtol=0, atol=1e-12)
    # a tool link past the flange: DH frame 6 moves along axis 6 to the foot of the tool point
    robot = Robot.from_urdf(path, "base", "tool0")
    assert robot.geometry == "spherical_wrist"
    np.testing.assert_allclose(robot.dh[:5], kuka.dh[:5], rtol=0, atol=1e-12)
    assert robot.d[5] == pytest.approx(kuka.d[5] + tool[2, 3], abs=1e-12)
    np.testing.assert_allclose(robot.fk(q), kuka.with_tool(tool).fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, joints, "base", "tool0", q), rtol=0, atol=1e-12)
    roundtrip(robot, q)
    roundtrip(flange, q)


def test_reversed_joint_axes_need_joint_signs(tmp_path, tool):
    # KUKA's own descriptions turn A1, A4 and A6 about -z / -x: with q mapped 1:1 the DH table has
    # d4 < 0, which no analytic layout has; the error names signs that make it analytic.
    path = write_kuka_urdf(tmp_path / "kr6_rev.urdf", tool, reversed_joints=(0, 3, 5), seed=1)
    with pytest.raises(ValueError, match=r"kr6_rev\.urdf.*base -> tool0.*joint_signs=\(1, 1, 1, -1, 1, 1\)"):
        Robot.from_urdf(path, "base", "tool0")
    signs = np.array([-1, 1, 1, -1, 1, -1])
    robot = Robot.from_urdf(path, "base", "tool0", joint_signs=signs)
    kuka = kin.kuka_kr6_r900_sixx()
    assert robot.geometry == "spherical_wrist"
    flange = Robot.from_urdf(path, "base", "flange", joint_signs=signs)   # the built-in table again
    np.testing.assert_allclose(flange.dh, kuka.dh, rtol=0, atol=1e-12)
    np.testing.assert_allclose(flange.limits, kuka.limits, rtol=0, atol=1e-15)
    q = random_q(robot, np.random.default_rng(8), 300)
    q_urdf = signs * q
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, [f"a{i}" for i in range(1, 7)], "base", "tool0", q_urdf),
                               rtol=0, atol=1e-12)
    roundtrip(robot, q)
    # the sign the error suggested works too (another, equally valid, DH table)
    one = Robot.from_urdf(path, "base", "tool0", joint_signs=[1, 1, 1, -1, 1, 1])
    assert one.geometry == "spherical_wrist"
    q1 = q_urdf * np.array([1, 1, 1, -1, 1, 1])
    np.testing.assert_allclose(one.fk(q1), robot.fk(q), rtol=0, atol=1e-12)
    roundtrip(one, np.clip(q1, one.limits[:, 0], one.limits[:, 1]))
    fk_only = Robot.from_urdf(path, "base", "tool0", fk_only=True)     # 1:1, FK only
    np.testing.assert_allclose(fk_only.fk(q_urdf), robot.fk(q), rtol=0, atol=1e-12)


def test_ros_industrial_style_kuka_description(tmp_path):
    # The layout of ROS-Industrial's KUKA descriptions: un-turned link frames, joints placed by
    # KUKA's published link dimensions, A1 about -z, A4 and A6 about -x, tool0 turned by 90 deg
    # about y from link_6.
    dims = [(0, 0, 0.400), (0.025, 0, 0), (0.455, 0, 0), (0, 0, 0.035), (0.420, 0, 0), (0.080, 0, 0)]
    axes = [(0, 0, -1), (0, 1, 0), (0, 1, 0), (-1, 0, 0), (0, 1, 0), (-1, 0, 0)]
    kuka = kin.kuka_kr6_r900_sixx()
    body, parent = '<link name="base_link"/>', "base_link"
    for i, (xyz, ax) in enumerate(zip(dims, axes)):
        lo, hi = np.rad2deg(kuka.limits[i]) if i not in (0, 3, 5) else -np.rad2deg(kuka.limits[i][::-1])
        body += (f'<link name="link_{i + 1}"/><joint name="joint_a{i + 1}" type="revolute">'
                 f'<origin xyz="{" ".join(map(str, xyz))}" rpy="0 0 0"/><parent link="{parent}"/>'
                 f'<child link="link_{i + 1}"/><axis xyz="{" ".join(map(str, ax))}"/>'
                 f'<limit lower="{float(np.deg2rad(lo))!r}" upper="{float(np.deg2rad(hi))!r}" effort="0" velocity="1"/></joint>')
        parent = f"link_{i + 1}"
    body += (f'<link name="tool0"/><joint name="joint_a6-tool0" type="fixed"><parent link="link_6"/>'
             f'<child link="tool0"/><origin xyz="0 0 0" rpy="0 {pi / 2!r} 0"/></joint>')
    path = tmp_path / "kr6r900sixx.urdf"
    path.write_text(f'<?xml version="1.0"?><robot name="kuka_kr6r900sixx">{body}</robot>')
    with pytest.raises(ValueError, match=r"joint_signs=\(1, 1, 1, -1, 1, 1\)"):
        Robot.from_urdf(path, "base_link", "tool0")
    signs = np.array([-1, 1, 1, -1, 1, -1])
    robot = Robot.from_urdf(path, "base_link", "tool0", joint_signs=signs)
    np.testing.assert_allclose(robot.dh, kuka.dh, rtol=0, atol=1e-12)     # the built-in table
    np.testing.assert_allclose(robot.limits, kuka.limits, rtol=0, atol=1e-12)
    np.testing.assert_allclose(robot.T_base_dh0, np.eye(4), atol=1e-12)
    home = np.array([0, -pi / 2, pi / 2, 0, 0, 0])                        # KUKA's home: flange at (525, 0, 890) mm
    np.testing.assert_allclose(robot.fk(home)[:3, 3], [0.525, 0, 0.890], atol=1e-12)
    np.testing.assert_allclose(robot.fk(home)[:3, 2], [1, 0, 0], atol=1e-12)   # tool0's z: the flange normal
    q = random_q(robot, np.random.default_rng(9), 300)
    np.testing.assert_allclose(robot.fk(q), pin_fk(path, [f"joint_a{i}" for i in range(1, 7)], "base_link", "tool0",
                                                   signs * q), rtol=0, atol=1e-12)
    roundtrip(robot, q)


def test_robot_from_urdf_pickles_and_is_a_robot(tmp_path, tool):
    import pickle
    robot = Robot.from_urdf(write_kuka_urdf(tmp_path / "k.urdf", tool), "base", "tool0")
    assert isinstance(robot, Robot) and kin.robot_from_urdf is Robot.from_urdf
    back = pickle.loads(pickle.dumps(robot))
    q = np.array([0.1, -1.0, 1.2, 0.3, 0.4, 0.5])
    np.testing.assert_array_equal(back.fk(q), robot.fk(q))


# ----------------------------------------------------------------------------- bad files and arguments

URDF_HEAD = '<?xml version="1.0"?>\n<robot name="bad">\n'


def _arm(joint2_type="revolute", extra=""):
    """A 2-link chain written by hand (for error tests)."""
    return (URDF_HEAD + '<link name="l0"/><link name="l1"/><link name="l2"/>'
            '<joint name="j1" type="revolute"><parent link="l0"/><child link="l1"/><axis xyz="0 0 1"/>'
            '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
            f'<joint name="j2" type="{joint2_type}"><parent link="l1"/><child link="l2"/><axis xyz="0 1 0"/>'
            f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>{extra}</robot>')


def test_bad_files_raise_naming_the_file(tmp_path):
    bad = tmp_path / "broken.urdf"
    bad.write_text(URDF_HEAD + '<link name="a"/><joint name="j" type="revolute"><parent link="a"/>')
    with pytest.raises(ValueError, match=r"broken\.urdf: not a well-formed URDF"):
        Robot.from_urdf(bad, "a", "b")
    nojoint = tmp_path / "nochild.urdf"
    nojoint.write_text(URDF_HEAD + '<link name="a"/><joint name="j" type="revolute"><parent link="a"/></joint></robot>')
    with pytest.raises(ValueError, match=r"nochild\.urdf: not a valid URDF"):
        Robot.from_urdf(nojoint, "a", "b")
    with pytest.raises(FileNotFoundError, match="missing.urdf"):
        Robot.from_urdf(tmp_path / "missing.urdf", "a", "b")
    arm = tmp_path / "arm.urdf"
    arm.write_text(_arm())
    with pytest.raises(ValueError, match=r"arm\.urdf: base_link 'base' is not a link of robot 'bad' \(links: l0, l1, l2\)"):
        Robot.from_urdf(arm, "base", "l2")
    with pytest.raises(ValueError, match=r"arm\.urdf: tip_link 'tool0' is not a link"):
        Robot.from_urdf(arm, "l0", "tool0")
    with pytest.raises(ValueError, match=r"arm\.urdf: tip_link 'l0' is not below base_link 'l2'"):
        Robot.from_urdf(arm, "l2", "l0")
    with pytest.raises(ValueError, match=r"arm\.urdf: the chain l0 -> l2 has 2 revolute/continuous joints \(j1, j2\)"):
        Robot.from_urdf(arm, "l0", "l2")
    prismatic = tmp_path / "prismatic.urdf"
    prismatic.write_text(_arm("prismatic"))
    with pytest.raises(ValueError, match=r"prismatic\.urdf: joint 'j2' of the chain l0 -> l2 is prismatic"):
        Robot.from_urdf(prismatic, "l0", "l2")
    limits = tmp_path / "limits.urdf"
    limits.write_text(_arm().replace('lower="-1" upper="1"', 'lower="1" upper="-1"', 1))
    with pytest.raises(ValueError, match=r"limits\.urdf: joint 'j1' has the limits lower 1.0 > upper -1.0"):
        Robot.from_urdf(limits, "l0", "l2")
    nan = tmp_path / "nan.urdf"
    nan.write_text(_arm().replace('<axis xyz="0 0 1"/>', '<origin xyz="nan 0 0"/><axis xyz="0 0 1"/>'))
    with pytest.raises(ValueError, match=r"nan\.urdf: joint 'j1' has a non-finite <origin>"):
        Robot.from_urdf(nan, "l0", "l2")
    mimic = tmp_path / "mimic.urdf"
    mimic.write_text(_arm().replace('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="j1"/>'))
    with pytest.raises(ValueError, match=r"mimic\.urdf: joint 'j2' .* mimics 'j1'"):
        Robot.from_urdf(mimic, "l0", "l2")


def test_bad_arguments(tmp_path, tool):
    path = write_kuka_urdf(tmp_path / "k.urdf", tool)
    with pytest.raises(ValueError, match="joint_signs"):
        Robot.from_urdf(path, "base", "tool0", joint_signs=[1, 1, 1])
    with pytest.raises(ValueError, match="joint_signs"):
        Robot.from_urdf(path, "base", "tool0", joint_signs=[1, 1, 1, 0, 1, 1])
    with pytest.raises(ValueError, match="tolerance"):
        Robot.from_urdf(path, "base", "tool0", tolerance=-1)


def test_missing_yourdfpy_names_the_extra(monkeypatch, tmp_path):
    real_import = builtins.__import__

    def no_yourdfpy(name, *args, **kwargs):
        if name == "yourdfpy":
            raise ImportError("No module named 'yourdfpy'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_yourdfpy)
    with pytest.raises(ImportError, match=r"pip install 'scanalign\[urdf\]'"):
        Robot.from_urdf(tmp_path / "any.urdf", "a", "b")
