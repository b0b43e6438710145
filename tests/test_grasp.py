"""scanalign.grasp: the planner on UR5 and KR6 cells (checked by forward kinematics and the
frame composition written out here), the grasp-file reader/writer and every bad-input error."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from scanalign import grasp as G
from scanalign import kinematics
from scanalign.synthetic.trajectories import robot_mount

TOP = np.diag([1.0, -1.0, -1.0, 1.0])  # tool z down
TOP[2, 3] = 0.03


def _pose(x, y, z=0.0, yaw=0.0):
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = [x, y, z]
    return T


CELLS = {  # robot placed in the cell, the part's pose, the current joints
    "ur5_hanging": (kinematics.ur5().with_base(robot_mount()), _pose(0.75, 0.15, yaw=0.3),
                    [0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0]),
    "kr6_upright": (kinematics.kuka_kr6_r900_sixx(), _pose(0.55, 0.1, yaw=1.0), [0, -math.pi / 2, math.pi / 2, 0, 1, 0]),
}


@pytest.mark.parametrize("cell", sorted(CELLS))
def test_planner_reaches_the_grasp_exactly(cell):
    robot, T_base_model, q0 = CELLS[cell]
    grasps = [G.Grasp("top", TOP), G.Grasp("turned", TOP @ _pose(0, 0, 0, 0.5), pre_grasp_distance=0.05)]
    sym = G.PartSymmetry(order=4)
    gripper = G.Gripper.parallel_jaw()
    plan = G.plan_grasp(robot, T_base_model, grasps, symmetry=sym, gripper=gripper, q_current=q0)
    assert plan and plan.found, plan.message
    assert len(plan.candidates) == 2 * 4 * 8
    ok = [c for c in plan.candidates if c.reason == "ok"]
    assert plan.best.cost == min(c.cost for c in ok)  # brute force over the candidates
    S = sym.transforms()
    for c in ok:
        tcp = T_base_model @ S[c.symmetry_index] @ grasps[c.grasp_index].T_model_grasp
        assert np.abs(robot.fk_flange(c.q_grasp) @ gripper.T_flange_tcp - tcp).max() < 1e-9
        assert np.abs(robot.fk_flange(c.q_grasp) - c.T_base_flange_grasp).max() < 1e-9
        assert np.abs(robot.fk_flange(c.q_pregrasp) - c.T_base_flange_pregrasp).max() < 1e-9
    best = plan.best
    # The approach path: straight down onto the grasp in 5 mm steps.
    assert plan.approach_q.shape[1] == 6
    assert np.array_equal(plan.approach_q[0], best.q_pregrasp) and np.array_equal(plan.approach_q[-1], best.q_grasp)
    tips = np.array([(robot.fk_flange(q) @ gripper.T_flange_tcp)[:3, 3] for q in plan.approach_q])
    assert np.allclose(tips[:, :2], best.T_base_tcp_grasp[:2, 3], atol=1e-9)
    assert np.allclose(np.diff(tips[:, 2]), -0.005, atol=1e-9)  # both pre-grasp distances are multiples of 5 mm
    # Rejected candidates say why.
    assert all(c.detail for c in plan.candidates if c.reason != "ok")
    assert all(math.isinf(c.cost) for c in plan.candidates if c.reason != "ok")


def test_out_of_reach_and_below_table_are_reported():
    robot, _, q0 = CELLS["ur5_hanging"]
    far = G.plan_grasp(robot, _pose(4, 0), [G.Grasp("top", TOP)], q_current=q0)
    assert not far.found and far.best is None and far.message.startswith("out of reach")
    assert {c.reason for c in far.candidates} == {"unreachable"}
    below = np.eye(4)
    below[2, 3] = 0.03  # tool z up: from under the table (here raised 0.4 m so the hanging arm reaches)
    plan = G.plan_grasp(robot, _pose(0.75, 0.15, 0.4), [G.Grasp("below", below)], table_plane=(0, 0, 1, -0.4),
                        q_current=q0, respect_limits=False)
    assert not plan.found and "below the table" in plan.message
    assert {c.reason for c in plan.candidates} <= {"below_table", "unreachable"}
    assert any("below_table" == c.reason and "above the table" in c.detail for c in plan.candidates)


def test_settings_by_name_and_bad_arguments():
    robot, T, q0 = CELLS["kr6_upright"]
    g = [G.Grasp("top", TOP)]
    strict = G.plan_grasp(robot, T, g, q_current=q0, min_wrist_angle=1.5)  # 86 degrees: nothing passes
    assert not strict.found and "near a singularity" in strict.message
    with pytest.raises(TypeError, match="clearance: unknown plan_grasp setting; did you mean table_clearance"):
        G.plan_grasp(robot, T, g, clearance=0.1)
    with pytest.raises(TypeError, match="approach_step"):
        G.plan_grasp(robot, T, g, approach_step="fine")
    with pytest.raises(ValueError, match="settings.approach_step"):
        G.plan_grasp(robot, T, g, approach_step=0.0)
    with pytest.raises(ValueError, match="T_base_model"):
        G.plan_grasp(robot, 2 * T, g)
    with pytest.raises(ValueError, match="grasps: the grasp list is empty"):
        G.plan_grasp(robot, T, [])
    with pytest.raises(TypeError, match="grasps"):
        G.plan_grasp(robot, T, g[0])
    with pytest.raises(ValueError, match="table_plane"):
        G.plan_grasp(robot, T, g, table_plane=(0, 0, float("nan"), 0))
    with pytest.raises(ValueError, match="q_current"):
        G.plan_grasp(robot, T, g, q_current=[0, 0, float("inf"), 0, 0, 0])
    with pytest.raises(ValueError, match="unknown robot"):
        G.plan_grasp("ur99", T, g)
    for kwargs, error, match in [
        (dict(T_base_model=np.eye(3)), ValueError, r"T_base_model: expected shape \(4, 4\), got \(3, 3\)"),
        (dict(T_base_model="abc"), TypeError, "T_base_model: expected real numbers"),
        (dict(table_plane=(0, 0, 1)), ValueError, r"table_plane: expected shape \(4,\)"),
        (dict(q_current=[0] * 5), ValueError, r"q_current: expected shape \(6,\)"),
        (dict(q_current=np.zeros(6, complex)), TypeError, "q_current: expected real numbers"),
        (dict(symmetry=3), TypeError, "symmetry: expected PartSymmetry"),
        (dict(gripper="big"), TypeError, "gripper: expected Gripper"),
        (dict(robot=5), TypeError, "robot: expected Robot"),
        (dict(joint_weights=[1] * 5), ValueError, r"joint_weights: expected shape \(6,\)"),
        (dict(joint_weights=[1, 1, 1, 1e7, 1, 1]), ValueError, r"joint_weights must be 6 values in \[0, 1e6\]"),
    ]:
        args = {"robot": robot, "T_base_model": T, "grasps": g, **kwargs}
        with pytest.raises(error, match=match):
            G.plan_grasp(args.pop("robot"), args.pop("T_base_model"), args.pop("grasps"), **args)
    with pytest.raises(ValueError, match=r"approach: expected shape \(3,\)"):
        G.Grasp("x", TOP, approach=(0, 0))
    with pytest.raises(ValueError, match=r"gripper.capsule_a: expected shape \(3,\)"):
        G.Gripper(capsule_a=[1, 2])
    with pytest.raises(ValueError, match="approach"):
        G.Grasp("x", TOP, approach=(0, 0, 2))
    with pytest.raises(ValueError, match="pre_grasp_distance"):
        G.Grasp("x", TOP, pre_grasp_distance=-1)
    with pytest.raises(ValueError, match="T_model_grasp is not a rigid transform"):
        G.Grasp("x", 2 * TOP)
    with pytest.raises(ValueError, match="symmetry order"):
        G.PartSymmetry(order=-2)
    with pytest.raises(ValueError, match="gripper.shape"):
        G.Gripper(shape="sphere")
    grip = G.Gripper.parallel_jaw()
    with pytest.raises(ValueError, match="capsule_radius"):
        grip.capsule_radius = -0.01
    assert grip.capsule_radius == 0.04  # unchanged by the refused value
    assert len(G.PartSymmetry(order=0).transforms(10)) == 10
    assert np.allclose(G.Grasp("x", TOP).pre_grasp()[:3, 3], [0, 0, 0.11])


def _part():
    return G.PartGrasps(name="standoff", mesh="builtin:standoff", scale=0.001,
                        symmetry=G.PartSymmetry((0, 0, 1), (0, 0, 0.01), 6), gripper=G.Gripper.parallel_jaw(),
                        grasps=[G.Grasp("top", TOP), G.Grasp("side", TOP @ _pose(0, 0, 0, 0.7), (1, 0, 0), 0.05)])


@pytest.mark.parametrize("suffix", [".json", ".yaml", ".yml"])
def test_grasp_file_round_trip(tmp_path, suffix):
    path = tmp_path / f"part{suffix}"
    part = _part()
    G.write_part_grasps(path, part)
    back = G.read_part_grasps(path)
    assert (back.name, back.mesh, back.scale) == ("standoff", "builtin:standoff", 0.001)
    assert back.symmetry.order == 6 and np.array_equal(back.symmetry.point, [0, 0, 0.01])
    assert back.gripper.shape == "box" and np.array_equal(back.gripper.T_flange_tcp, part.gripper.T_flange_tcp)
    assert np.array_equal(back.gripper.box_half_extents, part.gripper.box_half_extents)
    for a, b in zip(back.grasps, part.grasps):
        assert a.name == b.name and a.pre_grasp_distance == b.pre_grasp_distance
        assert np.array_equal(a.T_model_grasp, b.T_model_grasp) and np.array_equal(a.approach, b.approach)


def test_minimal_yaml_file_defaults(tmp_path):
    path = tmp_path / "bolt.yaml"
    path.write_text("grasps:\n  - T_model_grasp: [[1,0,0,0],[0,-1,0,0],[0,0,-1,0.03],[0,0,0,1]]\n")
    part = G.read_part_grasps(path)
    assert part.name == "bolt" and part.symmetry is None and part.gripper is None and part.scale == 1.0
    assert part.grasps[0].pre_grasp_distance == 0.08 and np.array_equal(part.grasps[0].approach, [0, 0, 1])


def _bad(tmp_path, data, match):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    with pytest.raises(ValueError, match=match) as e:
        G.read_part_grasps(path)
    assert "bad.json" in str(e.value)


def test_grasp_file_errors_name_file_grasp_and_field(tmp_path):
    good = {"name": "g", "T_model_grasp": TOP.tolist()}
    scaled = (2 * TOP).tolist()
    _bad(tmp_path, "{not json", "not valid JSON")
    _bad(tmp_path, [1, 2], "mapping at the top level")
    _bad(tmp_path, {"name": "p"}, "'grasps' must be a non-empty list")
    _bad(tmp_path, {"grasps": []}, "'grasps' must be a non-empty list")
    _bad(tmp_path, {"grasps": [good, {"name": "g2"}]}, r"grasps\[1\] \('g2'\): missing field 'T_model_grasp'")
    _bad(tmp_path, {"grasps": [{"name": "s", "T_model_grasp": scaled}]}, r"grasps\[0\] \('s'\).*T_model_grasp.*rigid")
    _bad(tmp_path, {"grasps": [{"name": "s", "T_model_grasp": [[1, 0], [0, 1]]}]}, r"grasps\[0\] \('s'\)")
    _bad(tmp_path, {"grasps": [{**good, "approach": "down"}]}, r"grasps\[0\] \('g'\)")
    _bad(tmp_path, {"grasps": [{**good, "approach": ["0", "0", "1"]}]}, r"grasps\[0\] \('g'\): approach: expected real")
    _bad(tmp_path, {"grasps": [{**good, "T_model_grasp": [[1, 0], [0, 1, 0]]}]}, r"\('g'\): field 'T_model_grasp'")
    _bad(tmp_path, {"grasps": [{**good, "approach": [0, 0, 0]}]}, r"grasps\[0\] \('g'\).*approach")
    _bad(tmp_path, {"grasps": [{**good, "pre_grasp_distance": -1}]}, "pre_grasp_distance")
    _bad(tmp_path, {"grasps": [{**good, "aproach": [0, 0, 1]}]}, "unknown field 'aproach'")
    _bad(tmp_path, {"grasps": [good], "scale": -1}, "'scale' must be a positive number")
    _bad(tmp_path, {"grasps": [good], "mesh": 3}, "'mesh' must be a string")
    _bad(tmp_path, {"grasps": [good], "symmetry": {"order": -1}}, "symmetry: symmetry order")
    _bad(tmp_path, {"grasps": [good], "symmetry": {"order": 2.5}}, "symmetry")
    _bad(tmp_path, {"grasps": [good], "gripper": {"shape": "ball"}}, "gripper: gripper.shape")
    _bad(tmp_path, {"grasps": [good], "gripper": {"T_flange_tcp": scaled}}, "gripper.*T_flange_tcp")
    _bad(tmp_path, {"grasps": [good], "colour": "red"}, "unknown field")
    path = tmp_path / "bad.yaml"
    path.write_text("grasps: [\n")
    with pytest.raises(ValueError, match="bad.yaml: not valid YAML"):
        G.read_part_grasps(path)
    with pytest.raises(ValueError, match="path"):
        G.write_part_grasps(tmp_path / "part.txt", _part())
    in_memory = _part()
    in_memory.mesh = object()
    with pytest.raises(ValueError, match="part.mesh"):
        G.write_part_grasps(tmp_path / "part.json", in_memory)
