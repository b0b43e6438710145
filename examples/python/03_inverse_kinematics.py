"""03: forward and inverse kinematics of a UR5 and a KUKA KR6 R900 sixx (thesis Paper 1).

Every pose has up to 8 joint solutions, one per configuration (shoulder, elbow, wrist);
the solver builds the arm's joint points as CGA sphere / plane intersections and reports
"unreachable" instead of wrong angles. Units: metres and radians.

Run after the README's set-up:  .venv/bin/python examples/python/03_inverse_kinematics.py
"""

import numpy as np

from scanalign import kinematics as kin

np.set_printoptions(precision=4, suppress=True)
LABELS = {(1, 0): "front", (-1, 0): "back", (1, 1): "up", (-1, 1): "down", (1, 2): "no flip", (-1, 2): "flip"}


def show(robot: kin.Robot, q: np.ndarray) -> None:
    print(f"\n=== {robot!r}")
    T_base_tool = robot.fk(q)                                   # tool -> robot base
    print("q =", q, "rad\nT_base_tool =\n", T_base_tool)

    sol = robot.ik(T_base_tool)                                 # all 8 configurations
    print(f"{len(sol)} solutions inside the joint limits:")
    for k in range(8):
        labels = "/".join(LABELS[(int(v), i)] for i, v in enumerate(sol.config[k]))
        extra = f"  singular: {sol.singular[k]}" if sol.singular[k] else ""
        q_text = np.array2string(sol.q[k], precision=4, suppress_small=True)
        print(f"  [{k}] {labels:18s} {sol.status[k]:14s} {q_text}{extra}")
        if sol.ok[k]:
            assert np.allclose(robot.fk(sol.q[k]), T_base_tool, atol=1e-10)

    # the solution nearest the current joints (e.g. to move without a configuration change)
    q_current = q + 0.05
    best = robot.ik_closest(T_base_tool, q_current)
    print("closest to q + 0.05:", best.q, best.status, "config", tuple(int(v) for v in best.config))
    assert best.ok and np.allclose(best.q, q, atol=1e-9)

    # a 10 cm straight line in the base frame, orientation fixed: one continuous branch
    path = np.repeat(T_base_tool[None], 11, axis=0)
    path[:, :3, 3] += np.linspace(0, 1, 11)[:, None] * [0.0, 0.10, 0.0]
    traj = robot.ik_trajectory(path, q)
    step = np.max(np.abs(np.diff(traj.q, axis=0)))
    print(f"trajectory: {int(traj.ok.sum())}/{len(traj)} ok, largest joint step {step:.4f} rad")
    assert traj.ok.all() and np.allclose(robot.fk(traj.q), path, atol=1e-10)

    far = T_base_tool.copy()
    far[:3, 3] = [3.0, 0.0, 0.5]                                 # out of reach
    print("3 m away:", set(robot.ik(far).status), set(robot.ik(far).unreachable_step))


show(kin.ur5(), np.array([0.3, -1.2, 1.4, -1.0, 1.2, 0.3]))
show(kin.kuka_kr6_r900_sixx(), np.array([0.3, -1.2, 1.4, 0.4, 0.9, -0.3]))

# KUKA home pose (thesis Table 1): flange at (0.525, 0, 0.890) m pointing along +x
home = kin.kuka_kr6_r900_sixx().fk([0, -np.pi / 2, np.pi / 2, 0, 0, 0])
print("\nKUKA home: p =", home[:3, 3], " a_e =", home[:3, 2])
