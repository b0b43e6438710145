"""`scanalign ik`: the command prints every solution, and each printed q reaches the pose."""

from __future__ import annotations

import re

import numpy as np

from scanalign import cli
from scanalign import kinematics as kin


def _rows(out: str):
    rows = []
    for line in out.splitlines():
        m = re.match(r"\s+(\d)\s+([+-]1)\s+([+-]1)\s+([+-]1)\s+(\w+)\s*(.*)", line)
        if m:
            q = [float(x) for x in m.group(6).split()[:6]] if m.group(5) in ("ok", "outside_limits") else None
            rows.append((int(m.group(1)), m.group(5), q))
    return rows


def test_ik_command_from_joints(capsys, tmp_path):
    q = np.array([0.3, -1.2, 1.1, -1.4, -1.2, 0.5])
    png = tmp_path / "ik.png"
    rc = cli.main(["ik", "--robot", "ur5", "--joints", *map(str, q), "--closest", *map(str, q), "--plot", str(png)])
    out = capsys.readouterr().out
    assert rc == 0 and png.stat().st_size > 10_000
    rows = _rows(out)
    assert [k for k, _, _ in rows] == list(range(8))
    robot = kin.ur5()
    T = robot.fk(q)
    ok = [r for r in rows if r[1] == "ok"]
    assert len(ok) == len(robot.ik(T)) >= 2
    for _, _, qk in ok:  # printed with 4 decimals: the pose to ~1e-4 rad x 1 m
        assert np.abs(robot.fk(np.array(qk)) - T).max() < 5e-4
    assert any(np.abs(np.array(qk) - q).max() < 1e-4 for _, _, qk in ok)  # the generating joints
    assert "closest to" in out and " ".join(f"{x:+.4f}" for x in q) in out


def test_ik_command_pose_and_unreachable(capsys):
    # rotation vector (pi, 0, 0): tool z pointing down, as the UR teach pendant writes it
    rc = cli.main(["ik", "--robot", "ur5", "--pose", "0.4", "-0.2", "0.3", "3.141592653589793", "0", "0"])
    out = capsys.readouterr().out
    assert rc == 0 and sum(1 for r in _rows(out) if r[1] == "ok") == 8
    rc = cli.main(["ik", "--robot", "kr6_r900_sixx", "--pose", "3", "0", "0", "0", "0", "0"])
    out = capsys.readouterr().out
    assert rc == 1 and all(r[1] == "unreachable" for r in _rows(out)) and "imaginary" in out
    assert cli.main(["ik", "--robot", "ur5"]) == 2  # neither --pose nor --joints
    assert "exactly one of" in capsys.readouterr().err
