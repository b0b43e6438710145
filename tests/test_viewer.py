"""The rerun live view (scanalign.viz.viewer): recordings hold the expected entities; the arm's
joint chain matches the robot's forward kinematics; no display is refused before the run and a
lost viewer never hides the caller's exception. Skipped without rerun-sdk."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest

from scanalign import kinematics
from scanalign.data import parts
from scanalign.viz.viewer import Viewer, arm_points


def _contents(path):
    """{entity path: set of its archetype:component columns} of a .rrd file, read back with
    rerun's own reader."""
    from rerun.chunk import RrdReader

    out = {}
    for chunk in RrdReader(str(path)).stream():
        out.setdefault(str(chunk.entity_path), set()).update(
            f.name for f in chunk.to_record_batch().schema if ":" in f.name)
    return out


@pytest.fixture(scope="module")
def small_scan():
    from scanalign.synthetic.config import builtin_scan

    return builtin_scan(n_frames=6, resolution_scale=0.25)


def test_arm_points_follow_forward_kinematics():
    robot = kinematics.ur5().with_tool(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.1], [0, 0, 0, 1.0]]))
    q = np.array([0.3, -1.2, 1.4, -0.6, 1.1, 0.4])
    pts = arm_points(robot, q)
    assert pts.shape == (8, 3)
    np.testing.assert_allclose(pts[0], np.asarray(robot.T_base_dh0)[:3, 3], atol=1e-12)
    np.testing.assert_allclose(pts[6], np.asarray(robot.fk_flange(q))[:3, 3], atol=1e-12)
    np.testing.assert_allclose(pts[7], np.asarray(robot.fk(q))[:3, 3], atol=1e-12)
    T_mount = np.eye(4)
    T_mount[:3, 3] = [0.5, -0.2, 0.1]  # the same arm mounted elsewhere: re-anchored on its logged flange
    moved = arm_points(robot, q, T_mount @ np.asarray(robot.fk_flange(q)))
    np.testing.assert_allclose(moved, pts + T_mount[:3, 3], atol=1e-12)


def test_reconstruction_recording(small_scan, tmp_path):
    pytest.importorskip("rerun")
    from scanalign.pipelines.reconstruct import reconstruct

    path = tmp_path / "scan.rrd"
    with Viewer(save=path, model_every=2) as view:
        result = reconstruct(small_scan.frames, on_frame=view.on_frame, progress=False, filter_depth=False,
                             normal_radius=0.005, icp=dict(box=None))  # the paper's values register this 6-frame loop
        view.log_reconstruction(result)
    assert len(result.estimate) >= 4
    got = _contents(path)
    assert {"Points3D:positions", "Points3D:colors"} <= got["/world/model"]
    assert {"Transform3D:translation", "Pinhole:image_from_camera"} <= got["/world/camera"]
    for strip in ("/world/camera_path", "/world/reference_path", "/world/arm"):
        assert "LineStrips3D:strips" in got[strip], strip


def test_pick_recording(tmp_path):
    """log_pick: the scene, each posed part as its mesh at its pose, the arm at the chosen grasp."""
    pytest.importorskip("rerun")
    from scanalign.pipelines.pick import PartPick, PickResult

    robot = kinematics.ur5()
    q = np.array([0.1, -1.3, 1.5, -1.8, -1.6, 0.2])
    T = np.eye(4)
    T[:3, 3] = [0.4, 0.1, 0.02]
    plan = SimpleNamespace(candidates=[SimpleNamespace(q_grasp=q, T_base_tcp_grasp=robot.fk(q))], chosen=0)
    picks = [PartPick("block", "picked", T_base_model=T, plan=plan, grasp_names=["top"],
                      gripper=SimpleNamespace(T_flange_tcp=np.eye(4))),
             PartPick("standoff", "not_found")]
    mesh = parts.builtin_mesh(segments=24)
    result = PickResult(picks, np.random.default_rng(0).random((500, 3)), None, robot, np.zeros(6),
                        [SimpleNamespace(name="block", mesh=mesh), SimpleNamespace(name="standoff", mesh=mesh)])
    path = tmp_path / "pick.rrd"
    with Viewer(save=path) as view:
        view.log_pick(result)
    got = _contents(path)
    assert "Points3D:positions" in got["/world/scene"]
    part = got["/world/parts/0_block"]
    assert {"Transform3D:translation", "Mesh3D:vertex_positions", "Mesh3D:triangle_indices"} <= part
    assert "LineStrips3D:strips" in got["/world/grasps/0_block/arm"]
    assert "Transform3D:translation" in got["/world/grasps/0_block/tcp"]
    assert not any("standoff" in k for k in got)


def test_command_line_view_save(tmp_path):
    pytest.importorskip("rerun")
    from scanalign.cli import main

    path = tmp_path / "cli.rrd"
    assert main(["reconstruct", "builtin", "--frames", "4", "--pixel-stride", "4", "--out", str(tmp_path / "out"),
                 "--quiet", "--no-plots", "--view-save", str(path), "--set", "min_merged_fraction=0"]) == 0
    got = _contents(path)
    assert {"/world/model", "/world/camera", "/world/camera_path", "/world/arm"} <= set(got)


def test_missing_rerun_is_named(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "rerun", None)
    with pytest.raises(ImportError, match="pip install rerun-sdk"):
        Viewer()
    from scanalign.cli import main

    assert main(["reconstruct", "builtin", "--frames", "2", "--out", str(tmp_path), "--quiet",
                 "--view-save", str(tmp_path / "x.rrd")]) == 2
    assert "pip install rerun-sdk" in capsys.readouterr().err


def _run(args, tmp_path, **env):
    """``python args`` in a subprocess with this sys.path and ``env`` over os.environ (None: unset),
    the interpreter's folder (rerun-sdk's ``rerun`` viewer) first on PATH; a hang fails the test."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path),
           "PATH": os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")]), **env}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=tmp_path, timeout=180,
                          env={k: v for k, v in env.items() if v is not None})


def test_view_without_a_display_is_refused_before_the_run(tmp_path):
    """``--view`` where no window can open: a clear error naming the fix, before anything runs
    (was: a viewer that dies at once, the run going on, a gRPC error at the end)."""
    pytest.importorskip("rerun")
    if not sys.platform.startswith("linux"):
        pytest.skip("DISPLAY / WAYLAND_DISPLAY decide only on Linux")
    with socket.socket() as s:
        if s.connect_ex(("127.0.0.1", 9876)) == 0:
            pytest.skip("a rerun viewer is listening on port 9876")
    r = _run(["-m", "scanalign.cli", "reconstruct", "builtin", "--frames", "2", "--pixel-stride", "4", "--out", "out",
              "--quiet", "--no-plots", "--view"], tmp_path, DISPLAY=None, WAYLAND_DISPLAY=None, WAYLAND_SOCKET=None)
    assert r.returncode == 2, r.stderr
    assert "no display (DISPLAY and WAYLAND_DISPLAY are unset)" in r.stderr and "--view-save scan.rrd" in r.stderr
    assert not (tmp_path / "out").exists()  # refused before the run


def test_a_lost_viewer_never_hides_the_callers_exception(tmp_path):
    """A viewer that is gone (nothing listens on its port): the body's exception propagates
    unchanged, the .rrd file still gets everything, and a good run ends with a warning only."""
    pytest.importorskip("rerun")
    script = textwrap.dedent("""
        import socket, warnings
        from scanalign.viz.viewer import Viewer
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            url = f"rerun+http://127.0.0.1:{s.getsockname()[1]}/proxy"  # closed again: nobody listens
        mine = KeyError("mine")
        try:
            with Viewer(connect=url, save="lost.rrd") as view:
                view.log_points("world/p", [[0.0, 0.0, 0.0]])
                raise mine
        except KeyError as e:
            print("body exception propagated:", e is mine)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with Viewer(connect=url) as view:
                view.log_points("world/p", [[0.0, 0.0, 0.0]])
        print("warned:", [str(w.message) for w in caught])
    """)
    r = _run(["-c", script], tmp_path)
    assert r.returncode == 0, r.stderr
    assert "body exception propagated: True" in r.stdout, r.stdout
    assert "warned: ['the rerun viewer did not receive the whole recording (" in r.stdout, r.stdout
    assert "Points3D:positions" in _contents(tmp_path / "lost.rrd")["/world/p"]
