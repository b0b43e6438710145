"""The synthetic eye-in-hand scanner with a robot arm (issue 5): planned camera poses ->
flange poses in the robot base frame -> joints by analytic IK (closest to the previous
step) -> reference poses by forward kinematics. Checked here: FK of the joints (computed
independently from UR's published DH table) equals the reference flange poses, the
reference camera poses equal the planned ones (the IK is exact), no branch jumps, joint
limits, clear errors for unreachable placements, the config fields and the command line's
joints.csv."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from scanalign import cli
from scanalign import kinematics as kin
from scanalign import synthetic as syn

# Universal Robots' published DH table of the UR5 (CB series), metres / radians; all
# theta offsets are 0. Written out here so that the check does not use scanalign's FK.
UR5_D = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
UR5_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
UR5_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)


def ur5_fk(q: np.ndarray) -> np.ndarray:
    """T_robot_flange of joints q (6,), standard DH: Rz(q) Tz(d) Tx(a) Rx(alpha) per joint."""
    T = np.eye(4)
    for qi, d, a, al in zip(q, UR5_D, UR5_A, UR5_ALPHA):
        ct, st, ca, sa = math.cos(qi), math.sin(qi), math.cos(al), math.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    return T


def planned_and_driven(**fields):
    """The planned path (no robot) and the same path driven by the robot, same config."""
    cfg = syn.SyntheticConfig(**fields)
    scene = cfg.build_scene()
    planned = syn.SyntheticConfig(**{**cfg.to_dict(), "robot": "none"}).build_trajectory(scene)
    return cfg, planned, cfg.build_trajectory(scene)


PATHS = {
    "loop": dict(),
    "loop_72": dict(n_frames=72),
    "hemisphere": dict(trajectory="hemisphere"),
    "hemisphere_60": dict(trajectory="hemisphere", n_frames=60, rings=4),
    "loop_low_wide": dict(height=0.30, radius=0.25, start_angle=1.0),
}


@pytest.mark.parametrize("name", sorted(PATHS))
def test_robot_follows_the_planned_path_exactly(name: str):
    cfg, planned, traj = planned_and_driven(**PATHS[name])
    n = len(planned)
    assert traj.joints.shape == (n, 6) and traj.robot is not None and traj.robot.name == "ur5"
    assert planned.joints is None and planned.robot is None and planned.T_base_robot is None
    Tbr = traj.T_base_robot
    np.testing.assert_allclose(Tbr, cfg.T_base_robot(), atol=0)
    # Forward kinematics of the joints (independent DH code) is the reference flange pose.
    fk = np.array([Tbr @ ur5_fk(q) for q in traj.joints])
    assert np.abs(fk - traj.T_base_flange).max() < 1e-10
    assert np.abs(traj.robot.fk(traj.joints) - traj.T_base_flange).max() < 1e-12
    # ... and the reference camera poses are the planned ones: the IK is exact.
    assert np.abs(traj.T_base_camera - planned.T_base_camera).max() < 1e-9
    assert np.abs(traj.T_base_flange - planned.T_base_flange).max() < 1e-9
    np.testing.assert_array_equal(traj.timestamps, planned.timestamps)
    np.testing.assert_array_equal(traj.T_flange_camera, planned.T_flange_camera)
    # No branch jumps: the configuration (shoulder, elbow, wrist labels) never changes ...
    robot = kin.ur5()
    T_robot_flange = np.linalg.inv(Tbr) @ traj.T_base_flange
    labels = []
    for q, T in zip(traj.joints, T_robot_flange):
        sols = robot.ik(T)
        d = np.abs((sols.q - q + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        assert np.nanmin(d) < 1e-9
        labels.append(int(np.nanargmin(d)))
    assert len(set(labels)) == 1, labels
    # ... and no joint turns more in one frame than the camera turns about the object (the
    # robot's first axis passes through it: on a loop only q1 moves, by exactly that step).
    steps = np.abs(np.diff(traj.joints, axis=0))
    rel = planned.T_base_camera[:, :3, 3] - cfg.build_scene().center
    azimuth_step = np.abs(np.diff(np.unwrap(np.arctan2(rel[:, 1], rel[:, 0])))).max()
    assert steps.max() <= 1.1 * azimuth_step, (steps.max(), azimuth_step)
    # Inside the UR5's limits (+-360 deg on every joint).
    lim = traj.robot.limits
    np.testing.assert_allclose(lim, np.tile([-2 * math.pi, 2 * math.pi], (6, 1)))
    assert np.all(traj.joints >= lim[:, 0]) and np.all(traj.joints <= lim[:, 1])
    # The start is elbow up: the base hangs (z down), so the elbow lies above the line
    # from the shoulder to the wrist in the scene, i.e. away from the table.
    frames = traj.robot.joint_frames(traj.joints[0])  # DH frame 0
    P = (Tbr @ frames[:, :, 3].T).T[:, :3]  # joint origins in the scene
    shoulder, elbow, wrist = P[1], P[2], P[3]
    t = np.clip((elbow - shoulder) @ (wrist - shoulder) / np.sum((wrist - shoulder) ** 2), 0, 1)
    assert elbow[2] > (shoulder + t * (wrist - shoulder))[2]
    # Every step is the solution closest to the previous one among the 8 (2 pi multiples
    # of the joints being the same configuration).
    for k in range(1, n, max(1, n // 8)):
        sols = robot.ik(T_robot_flange[k])
        d_all = np.linalg.norm((sols.q[sols.ok] - traj.joints[k - 1] + np.pi) % (2 * np.pi) - np.pi, axis=1)
        d_taken = np.linalg.norm(traj.joints[k] - traj.joints[k - 1])
        assert d_taken <= d_all.min() + 1e-9


def test_scan_frames_carry_the_joints_and_the_fk_poses():
    scan = syn.SyntheticConfig(n_frames=6, noise="none", resolution_scale=0.25).build()
    assert scan.joints.shape == (6, 6) and scan.robot.name == "ur5"
    for k, frame in enumerate(scan.frames):
        np.testing.assert_array_equal(frame.meta["joints"], scan.joints[k])
        assert frame.meta["robot"] == "ur5"
        T = scan.T_base_robot @ ur5_fk(scan.joints[k]) @ scan.T_flange_camera
        assert np.abs(frame.T_base_camera - T).max() < 1e-10
        np.testing.assert_array_equal(frame.meta["T_base_flange"] @ scan.T_flange_camera, frame.T_base_camera)
    # Without a robot nothing changes: the poses are the planned ones bit for bit.
    plain = syn.SyntheticConfig(n_frames=6, noise="none", resolution_scale=0.25, robot="none").build()
    assert plain.joints is None and plain.robot is None and "joints" not in plain.frames[0].meta
    planned = syn.loop_trajectory(6, center=plain.scene.center)
    np.testing.assert_array_equal(plain.reference.poses, planned.T_base_camera)


def test_trajectory_functions_take_a_robot():
    center = (0.45, 0.05, 0.0)
    plain = syn.loop_trajectory(24, center=center)
    driven = syn.loop_trajectory(24, center=center, robot="ur5")
    assert plain.joints is None
    assert np.abs(driven.T_base_camera - plain.T_base_camera).max() < 1e-9
    # Default mount: hanging DEFAULT_ROBOT_HEIGHT above the centre, first axis down.
    np.testing.assert_allclose(driven.T_base_robot[:3, 3], [0.45, 0.05, syn.DEFAULT_ROBOT_HEIGHT])
    np.testing.assert_allclose(driven.T_base_robot[:3, 2], [0, 0, -1], atol=1e-15)
    # attach_robot on an existing path, with an explicit start: the first step is the
    # solution closest to it.
    again = syn.attach_robot(plain, kin.ur5(), T_base_robot=driven.T_base_robot, q_start=driven.joints[0] + 0.01)
    np.testing.assert_allclose(again.joints, driven.joints, atol=1e-12)
    # elbow="down" gives the other elbow: the same poses with different joints.
    down = syn.attach_robot(plain, "ur5", T_base_robot=driven.T_base_robot, elbow="down")
    assert np.abs(down.T_base_camera - plain.T_base_camera).max() < 1e-9
    assert np.abs(down.joints[0] - driven.joints[0]).max() > 0.1
    with pytest.raises(ValueError, match="elbow"):
        syn.attach_robot(plain, "ur5", elbow="sideways")
    with pytest.raises(ValueError, match="q_start"):
        syn.attach_robot(plain, "ur5", T_base_robot=driven.T_base_robot, q_start=[0.0] * 5)
    with pytest.raises(ValueError, match="unknown robot"):
        syn.attach_robot(plain, "ur7")
    with pytest.raises(TypeError):
        syn.attach_robot(plain, 5)
    with pytest.raises(ValueError, match="need a robot"):
        syn.loop_trajectory(4, T_base_robot=np.eye(4))


def test_unreachable_placement_raises_a_clear_error(tmp_path: Path, capsys):
    # Too far away for every frame: the first frame is named, with its IK status.
    with pytest.raises(ValueError, match=r"cannot reach frame 0 \(t = 0\.000 s.*'unreachable'"):
        syn.SyntheticConfig(robot_x=2.5, robot_z=0.5, robot_roll=0.0).build_trajectory(syn.Scene())
    # Standing upright 0.8 m from the object at table height: the near side of the loop is
    # in reach, the far side (1 m away) is not. The message names the first frame out of
    # reach and the status, never skips it.
    cfg = syn.SyntheticConfig(robot_x=1.3, robot_y=0.0, robot_z=0.0, robot_roll=0.0)
    scene = cfg.build_scene()
    with pytest.raises(ValueError) as err:
        cfg.build_trajectory(scene)
    msg = str(err.value)
    k = int(msg.split("frame ")[1].split(" ")[0])
    assert 0 < k < cfg.n_frames and "'unreachable'" in msg and "ur5" in msg and f"t = {k / 10:.3f} s" in msg
    # That frame really is out of reach, and the frames before it are not.
    Tr = np.linalg.inv(cfg.T_base_robot()) @ syn.SyntheticConfig(**{**cfg.to_dict(), "robot": "none"}) \
        .build_trajectory(scene).T_base_flange
    assert len(kin.ur5().ik(Tr[k])) == 0 and all(len(kin.ur5().ik(T)) > 0 for T in Tr[:k])
    # Hanging above the object, the arm cannot look straight down at it: a ring at 86 deg
    # elevation passes within d4 of the first axis (the UR's shoulder point pair is imaginary).
    cfg = syn.SyntheticConfig(trajectory="hemisphere", min_elevation=0.3, max_elevation=1.5, n_frames=48)
    with pytest.raises(ValueError, match=r"frame 4\d \(t = 4\.\d+ s.*'unreachable' \(45 of 48 frames reachable\)"):
        cfg.build_trajectory(cfg.build_scene())
    # The command line reports it as an error, not a traceback.
    assert cli.main(["demo", "--robot-base", "1.3", "0", "0", "0", "0", "0", "--quiet", "--out", str(tmp_path)]) == 2
    assert "unreachable" in capsys.readouterr().err


def test_config_round_trip_with_the_robot_fields(tmp_path: Path):
    cfg = syn.SyntheticConfig(n_frames=12, robot="ur5", robot_x=0.48, robot_y=0.03, robot_z=0.95,
                              robot_roll=math.pi, robot_pitch=0.05, robot_yaw=0.4, robot_elbow="up")
    cfg.to_json(tmp_path / "scan.json")
    back = syn.SyntheticConfig.from_file(tmp_path / "scan.json")
    assert back == cfg
    d = json.loads((tmp_path / "scan.json").read_text())
    assert d["robot"] == "ur5" and d["robot_yaw"] == 0.4 and d["robot_elbow"] == "up"
    T = back.T_base_robot()
    np.testing.assert_allclose(T[:3, 3], [0.48, 0.03, 0.95])
    traj = back.build_trajectory(back.build_scene())
    np.testing.assert_array_equal(traj.T_base_robot, T)
    # Defaults survive a round trip too (robot_x / robot_y null = above the object).
    default = syn.SyntheticConfig()
    default.to_json(tmp_path / "default.json")
    assert syn.SyntheticConfig.from_file(tmp_path / "default.json") == default
    assert default.robot == "ur5" and default.robot_x is None
    np.testing.assert_allclose(default.T_base_robot()[:3, 3], [default.object_x, default.object_y, 0.9])
    # Flat YAML: no robot, and a mount written field by field.
    (tmp_path / "a.yaml").write_text("n_frames: 8\nrobot: none\n")
    a = syn.SyntheticConfig.from_file(tmp_path / "a.yaml")
    assert a.robot == "none" and a.T_base_robot() is None and a.build_trajectory(a.build_scene()).joints is None
    (tmp_path / "b.yaml").write_text("robot: ur5\nrobot_x: null\nrobot_y: 0.0\nrobot_z: 0.85\nrobot_roll: 3.14159\n")
    b = syn.SyntheticConfig.from_file(tmp_path / "b.yaml")
    assert b.robot_x is None and b.robot_z == 0.85 and b.robot_y == 0.0
    for bad in (dict(robot="ur7"), dict(robot_z=float("nan")), dict(robot_elbow="left"), dict(robot=None),
                dict(robot_yaw="a")):
        with pytest.raises(ValueError):
            syn.SyntheticConfig(**bad)


def read_joints_csv(path: Path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["index", "timestamp", "q1", "q2", "q3", "q4", "q5", "q6"]
    body = np.array([[float(x) for x in r] for r in rows[1:]])
    return body[:, 0].astype(int), body[:, 1], body[:, 2:]


def test_command_line_writes_the_joint_trajectory(tmp_path: Path):
    fields = dict(n_frames=8, noise="none", resolution_scale=0.25)
    cfg = syn.SyntheticConfig(**fields)
    cfg.to_json(tmp_path / "scan.json")
    expected = cfg.build_trajectory(cfg.build_scene())
    out = tmp_path / "out"
    io_only = ["--set", "min_merged_fraction=0"]  # 8 frames, 45 deg apart: the joint log is checked, not the registration
    assert cli.main(["reconstruct", str(tmp_path / "scan.json"), "--out", str(out), "--quiet", "--no-plots", *io_only]) == 0
    idx, t, q = read_joints_csv(out / "joints.csv")
    np.testing.assert_array_equal(idx, np.arange(8))
    np.testing.assert_allclose(t, np.arange(8) / 10.0, atol=1e-15)
    np.testing.assert_array_equal(q, expected.joints)  # 17 significant digits: exact
    report = json.loads((out / "report.json").read_text())
    assert report["summary"]["robot"] == "ur5"
    # --robot none: planned poses, no joints file.
    out2 = tmp_path / "none"
    assert cli.main(["reconstruct", str(tmp_path / "scan.json"), "--robot", "none", "--out", str(out2), "--quiet",
                     "--no-plots", *io_only]) == 0
    assert not (out2 / "joints.csv").exists() and (out2 / "reference.txt").exists()
    # `synth` puts the joints next to the TUM folder's ground truth.
    folder = tmp_path / "tum"
    assert cli.main(["synth", str(tmp_path / "scan.json"), str(folder)]) == 0
    _, _, q2 = read_joints_csv(folder / "joints.csv")
    np.testing.assert_array_equal(q2, expected.joints)
    # --robot-base moves the mount (metres, radians), and the reference follows it exactly.
    folder2 = tmp_path / "tum2"
    assert cli.main(["synth", "builtin", str(folder2), "--frames", "6", "--noise", "none", "--robot-base", "0.52",
                     "0.02", "0.95", str(math.pi), "0", "0.3"]) == 0
    _, _, q3 = read_joints_csv(folder2 / "joints.csv")
    T_base_robot = syn.robot_mount(0.52, 0.02, 0.95, math.pi, 0.0, 0.3)
    gt = np.loadtxt(folder2 / "groundtruth.txt")
    pos = np.array([(T_base_robot @ ur5_fk(qk) @ syn.DEFAULT_T_FLANGE_CAMERA)[:3, 3] for qk in q3])
    assert np.abs(pos - gt[:, 1:4]).max() < 1e-6  # groundtruth.txt is written to 1e-6 m or better
    with pytest.raises(SystemExit):
        cli.main(["demo", "--robot-base", "0", "0"])


def test_kuka_can_drive_part_of_a_loop():
    # The KR6 R900 standing on a 20 cm pedestal beside the table (0.2 m from its edge) sweeps
    # 270 deg of the loop around the part. (Its first axis turns +-170 deg only, so it could
    # not hang above the part and circle it like the UR5.)
    center = (0.5, 0.0, 0.0)
    kw = dict(center=center, start_angle=math.pi / 4, sweep=1.5 * math.pi)
    planned = syn.loop_trajectory(24, **kw)
    traj = syn.loop_trajectory(24, **kw, robot=kin.kuka_kr6_r900_sixx(),
                               T_base_robot=syn.robot_mount(0.0, 0.0, 0.2, 0.0, 0.0, 0.0))
    assert traj.robot.name == "kr6_r900_sixx"
    assert np.abs(traj.T_base_camera - planned.T_base_camera).max() < 1e-9
    assert np.abs(traj.robot.fk(traj.joints) - traj.T_base_flange).max() < 1e-12
    assert traj.robot.within_limits(traj.joints).all()
    assert np.abs(np.diff(traj.joints, axis=0)).max() < 0.6
    # The default hemisphere is out of its reach from there (0.9 m to the far side, 0.086 m
    # above the pedestal): a clear error naming frame 0.
    with pytest.raises(ValueError, match=r"kr6_r900_sixx .*cannot reach frame 0 \(t = 0\.000 s.*'unreachable'"):
        syn.hemisphere_trajectory(36, center=center, distance=math.hypot(0.4, 0.2), robot="kr6_r900_sixx",
                                  T_base_robot=syn.robot_mount(0, 0, 0.2, 0, 0, 0),
                                  elevations=np.radians([35.0, 55.0, 75.0]))
