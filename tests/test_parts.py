"""Own parts end to end (docs/parts.md): a part file's mesh oriented into the model frame, its
declared symmetry checked against the mesh, the synthetic cell's truth keyed like the picks, and
the picking robot's FK at the flange versus the gripper's TCP."""

import json
import math

import numpy as np
import pytest

from scanalign import grasp
from scanalign.common import rigid as se3
from scanalign.data.parts import builtin_mesh
from scanalign.grasp.parts import BUILTIN_PART_FILES, load_part
from scanalign.pipelines import pick
from scanalign.synthetic.cell import pick_cell, score_picks

#: mesh -> model of the test's CAD file: the file has the part's up axis along its y and is in mm
T_MODEL_MESH = se3.rigid([1.0, 0.0, 0.0], math.pi / 2, [0.004, -0.002, 0.001])


def write_obj(path, vertices, faces):
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in np.asarray(vertices).tolist())
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    return path


def prism(sides, radius=0.02, height=0.02):
    """A regular prism standing on z = 0, corners at angles k 2 pi / sides: (vertices, faces)."""
    a = np.arange(sides) * 2 * math.pi / sides
    ring = np.c_[radius * np.cos(a), radius * np.sin(a)]
    v = np.r_[np.c_[ring, np.zeros(sides)], np.c_[ring, np.full(sides, height)], [[0, 0, 0], [0, 0, height]]]
    n, f = sides, []
    for i in range(n):  # two side triangles, one bottom and one top fan triangle, wound outwards
        j = (i + 1) % n
        f += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    return v, np.array(f)


def part_file(tmp_path, name, mesh, symmetry=None, **extra):
    data = {"name": name, "mesh": mesh, "grasps": [{"T_model_grasp": np.eye(4).tolist()}], **extra}
    if symmetry is not None:
        data["symmetry"] = symmetry
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("order, ok", [(2, True), (4, True), (8, True), (3, False), (6, False), (0, False)])
def test_a_symmetry_is_checked_against_the_mesh(tmp_path, order, ok):
    """A regular octagonal prism maps onto itself under rotations by multiples of 45 deg only: 2-,
    4- and 8-fold symmetries load, 3- and 6-fold (the issue's 15 deg off the flats) and a continuous
    one are a ValueError naming the file and the symmetry."""
    mesh = write_obj(tmp_path / "octagon.obj", *prism(8))
    path = part_file(tmp_path, "octagon", mesh.name, {"axis": [0, 0, 1], "point": [0, 0, 0], "order": order})
    if ok:
        assert load_part(path).symmetry.order == order
    else:
        with pytest.raises(ValueError, match=rf"octagon\.json: symmetry \(order {order} about axis \[0.0, 0.0, 1.0\]"):
            load_part(path)


def test_a_symmetry_about_the_wrong_axis_or_point_is_refused(tmp_path):
    """The hexagonal standoff is 6-fold about z through its origin, not about x, nor about a
    parallel axis 5 mm aside; a PartGrasps is named by its part name."""
    for axis, point in (([1, 0, 0], [0, 0, 0]), ([0, 0, 1], [0.005, 0, 0])):
        path = part_file(tmp_path, "standoff", "builtin:standoff", {"axis": axis, "point": point, "order": 6})
        with pytest.raises(ValueError, match="standoff.json: symmetry .* does not map the mesh onto itself"):
            load_part(path)
    part = grasp.read_part_grasps(BUILTIN_PART_FILES["standoff"])
    part.symmetry = grasp.PartSymmetry(order=4)
    with pytest.raises(ValueError, match="part 'standoff': symmetry \\(order 4.* turned by 90.0 deg"):
        load_part(part)


def _oriented_bracket(tmp_path):
    """The built-in bracket as a CAD file would hold it: in mm, its up axis along the file's y
    and its origin moved; the part file brings it back with scale and T_model_mesh."""
    mesh = builtin_mesh(name="bracket")
    v = se3.transform_points(se3.inverse(T_MODEL_MESH), mesh.vertices) * 1000.0
    write_obj(tmp_path / "bracket_y_up.obj", v, mesh.faces)
    data = json.loads(BUILTIN_PART_FILES["bracket"].read_text())
    data.update(name="bracket_y_up", mesh="bracket_y_up.obj", scale=0.001, T_model_mesh=T_MODEL_MESH.tolist())
    path = tmp_path / "bracket_y_up.json"
    path.write_text(json.dumps(data))
    return path


def test_a_part_file_orients_its_mesh(tmp_path):
    """Loaded, the oriented file's mesh is the built-in bracket in its own model frame (z up)."""
    part = load_part(_oriented_bracket(tmp_path))
    assert np.abs(part.mesh.vertices - builtin_mesh(name="bracket").vertices).max() < 1e-12
    assert part.T_model_mesh is None and part.scale == 1.0
    back = tmp_path / "again.yaml"  # written and read back with the field
    grasp.write_part_grasps(back, grasp.read_part_grasps(_oriented_bracket(tmp_path)))
    assert np.abs(grasp.read_part_grasps(back).T_model_mesh - T_MODEL_MESH).max() < 1e-15
    for bad, message in (("up", "T_model_mesh"), ([[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                                                  "T_model_mesh.*orthonormal")):
        with pytest.raises(ValueError, match=f"bad.json: .*{message}"):
            load_part(part_file(tmp_path, "bad", "builtin:block", T_model_mesh=bad))


@pytest.fixture(scope="module")
def oriented_pick(tmp_path_factory):
    """The oriented bracket alone in the UR5 cell, picked by a robot given with a tool of its own."""
    path = _oriented_bracket(tmp_path_factory.mktemp("parts"))
    cell = pick_cell("ur5", placements=[(str(path), (0.36, -0.07), 0.7)], seed=1)
    robot = cell.robot.with_tool(se3.rigid([0, 0, 1], 0.0, [0.0, 0.0, 0.05]))
    return path, cell, pick.pick(cell.scan, cell.parts, robot, progress=False)


def test_an_oriented_custom_part_is_picked_and_scored_by_name(oriented_pick):
    """The truth is keyed by the part's name, as the picks are: score_picks scores the part, its
    chosen grasp within 1 mm and 0.5 deg of the same grasp on the truly placed part."""
    path, cell, result = oriented_pick
    assert list(cell.truth) == ["bracket_y_up"]
    assert [(p.part, p.status) for p in result.picks] == [("bracket_y_up", "picked")]
    errors = score_picks(result, cell.truth)
    assert list(errors) == ["bracket_y_up"]
    assert errors["bracket_y_up"]["tcp_m"] < 1e-3 and errors["bracket_y_up"]["tcp_deg"] < 0.5, errors
    with pytest.raises(ValueError, match="truth: .*bracket_y_up.json.* name no part of the pick"):
        score_picks(result, {str(path): cell.truth["bracket_y_up"]})  # keyed by file: an error, never {}
    with pytest.raises(ValueError, match="part 'bracket_y_up' was picked but has no true pose"):
        score_picks(result, {})


def test_cell_truth_is_keyed_by_part_name(tmp_path):
    path = part_file(tmp_path, "my_block", "builtin:block")
    cell = pick_cell("ur5", placements=[(str(path), (0.36, -0.07), 0.3)], n_frames=2)
    assert list(cell.truth) == ["my_block"] and [p.name for p in cell.parts] == ["my_block"]
    with pytest.raises(ValueError, match="placements: each part once"):
        pick_cell("ur5", placements=[(str(path), (0.36, -0.07), 0.3), (str(path), (0.6, 0.1), 0.0)])


def test_fk_gives_the_flange_and_tcp_robot_the_tcp(oriented_pick):
    """result.robot's FK at the grasp joints is the commanded flange pose (even for a robot given
    with a tool), tcp_robot's the TCP; they lie the gripper's tool length (0.15 m) apart."""
    _, _, result = oriented_pick
    p = result.picks[0]
    c, q = p.chosen, np.asarray(p.chosen.q_grasp)
    flange, tcp = result.robot.fk(q), result.tcp_robot(p).fk(q)
    assert np.abs(flange - np.asarray(c.T_base_flange_grasp)).max() < 1e-9
    assert np.abs(tcp - np.asarray(c.T_base_tcp_grasp)).max() < 1e-9
    assert np.linalg.norm(tcp[:3, 3] - flange[:3, 3]) == pytest.approx(0.15, abs=1e-9)
    assert np.linalg.norm(np.asarray(p.gripper.T_flange_tcp)[:3, 3]) == pytest.approx(0.15, abs=1e-12)
