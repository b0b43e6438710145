"""The assembly with the two-step pose (Kleppe et al., Robotics 6 (2017) 14, the thesis's Paper 3; issue 30 §2-3): the
part file's reference image and assembly target, the two-robot cell, and detect -> refine -> pick -> place against
the cell's truth: where the placed part truly ends up is computed here from the true poses, the planned TCP poses and
forward kinematics, not taken from the pipeline's own score."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from scanalign.cli.commands import main  # noqa: E402
from scanalign.data.labels import builtin_label, printed_label  # noqa: E402
from scanalign.grasp import ReferenceImage, read_part_grasps, write_part_grasps  # noqa: E402
from scanalign.grasp.parts import BUILTIN_PART_FILES, load_part  # noqa: E402
from scanalign.pipelines.assemble import (AssemblySettings, assemble, assemble_cell,  # noqa: E402
                                          plan_pick_and_place, upright_on_table)
from scanalign.synthetic.hand_camera import render_labels  # noqa: E402
from scanalign.synthetic.assembly_cell import (ASSEMBLY_MOUNTS, PLACEMENT_REGION, assembly_cell,  # noqa: E402
                                               random_placements, score_assembly)


def yaw_of(T: np.ndarray) -> float:
    return math.atan2(T[1, 0], T[0, 0])


def wrapped_deg(a: float, period_deg: float = 360.0) -> float:
    d = math.degrees(a) % period_deg
    return min(d, period_deg - d)


@pytest.fixture(scope="module")
def runs():
    """Two random cells and their assemblies (about 3 s each)."""
    out = []
    for seed in (0, 4):
        cell = assembly_cell(seed=seed)
        out.append((cell, assemble_cell(cell)))
    return out


def test_part_files_carry_the_reference_image_and_the_assembly_and_round_trip(tmp_path):
    standoff = load_part("standoff")
    ref, target = standoff.reference_image, standoff.assembly
    assert ref.image.shape == (176, 176) and ref.image.dtype == np.uint8  # 22 mm at 8000 px/m
    g = ref.geometry()
    assert (g.width, g.height, g.top_height) == (176, 176, 0.02) and tuple(g.origin_pixel) == (87.5, 87.5)
    assert target.onto == "bracket" and target.tolerance_translation == 0.001
    assert target.T_onto_part[2, 3] == pytest.approx(0.006)  # on the bracket's 6 mm base plate
    bracket = load_part("bracket").reference_image.geometry()
    assert bracket.part_point(0, 0)[0] == pytest.approx(-0.035 + 0.0001)  # the label starts at the plate's -x end
    # Written and read back: the same fields; the image a file beside the part file (read as grey).
    raw = read_part_grasps(BUILTIN_PART_FILES["standoff"])
    png = printed_label(120, 80, seed=5)
    cv2.imwrite(str(tmp_path / "top.png"), cv2.cvtColor(png, cv2.COLOR_GRAY2BGR))
    raw = dataclasses.replace(raw, mesh="builtin:standoff",
                              reference_image=ReferenceImage("top.png", 6000.0, 0.02, origin_pixel=(10.0, 20.0)))
    for name in ("p.json", "p.yaml"):
        write_part_grasps(tmp_path / name, raw)
        back = read_part_grasps(tmp_path / name)
        assert back.reference_image == raw.reference_image
        assert back.assembly.onto == "bracket" and np.array_equal(back.assembly.T_onto_part, target.T_onto_part)
        loaded = load_part(tmp_path / name)
        assert np.array_equal(loaded.reference_image.image, png)
        assert tuple(loaded.reference_image.geometry().origin_pixel) == (10.0, 20.0)


@pytest.mark.parametrize("field,value,match", [
    ("reference_image", {"image": "builtin:label-1", "pixels_per_metre": 5000, "top_height": 0.01}, "size"),
    ("reference_image", {"image": "top.png", "pixels_per_metre": 5000, "top_height": 0.01, "size": [1, 1]}, "size"),
    ("reference_image", {"image": "builtin:label-1", "size": [0.02, 0.02], "pixels_per_metre": -1,
                         "top_height": 0.01}, "pixels_per_metre"),
    ("reference_image", {"image": "builtin:label-1", "size": [0.02, 0.02], "pixels_per_metre": 5000}, "top_height"),
    ("reference_image", {"image": "builtin:label-1", "size": [0.02, 0.02], "pixels_per_metre": 5000,
                         "top_height": 0.01, "colour": 1}, "colour"),
    ("assembly", {"onto": "bracket"}, "T_onto_part"),
    ("assembly", {"onto": "bracket", "T_onto_part": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     "T_onto_part"),
    ("assembly", {"onto": "bracket", "T_onto_part": np.eye(4).tolist(), "tolerance_angle": 0}, "tolerance_angle"),
    ("assembly", {"onto": "", "T_onto_part": np.eye(4).tolist()}, "onto"),
])
def test_malformed_fields_are_refused_naming_the_file_and_field(tmp_path, field, value, match):
    data = json.loads(BUILTIN_PART_FILES["block"].read_text())
    data[field] = value
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=match) as e:
        read_part_grasps(path)
    assert "bad.json" in str(e.value)


def test_a_user_part_file_names_the_other_part_by_its_file(tmp_path):
    (tmp_path / "sub").mkdir()
    b = json.loads(BUILTIN_PART_FILES["bracket"].read_text())
    b["name"] = "plate"
    (tmp_path / "sub" / "plate.json").write_text(json.dumps(b))
    a = json.loads(BUILTIN_PART_FILES["standoff"].read_text())
    a["assembly"].update(onto="plate", onto_file="sub/plate.json")
    (tmp_path / "peg.json").write_text(json.dumps(a))
    cell = assembly_cell(tmp_path / "peg.json", seed=3)
    assert cell.onto.name == "plate" and set(cell.truth) == {"standoff", "plate"}
    part = read_part_grasps(tmp_path / "peg.json")
    write_part_grasps(tmp_path / "copy.json", part)
    assert json.loads((tmp_path / "copy.json").read_text())["assembly"]["onto_file"] == "sub/plate.json"
    a["assembly"]["onto_file"] = "sub/missing.json"
    (tmp_path / "peg.json").write_text(json.dumps(a))
    with pytest.raises(ValueError, match="missing.json"):
        assembly_cell(tmp_path / "peg.json")


def test_a_missing_or_unknown_image_is_refused_when_the_part_is_loaded(tmp_path):
    data = json.loads(BUILTIN_PART_FILES["block"].read_text())
    for image, match in (("nowhere.png", "cannot read the image"), ("builtin:shiny-3", "built-in labels")):
        data["reference_image"] = {"image": image, "pixels_per_metre": 5000, "top_height": 0.015}
        if image.startswith("builtin:"):
            data["reference_image"]["size"] = [0.02, 0.02]
        (tmp_path / "p.json").write_text(json.dumps(data))
        with pytest.raises(ValueError, match=match):
            load_part(tmp_path / "p.json")


def test_the_labels_texture_ranks_as_named():
    """SIFT keypoints (OpenCV, not ours): the printed label has hundreds, the faint one tens, the plain face none."""
    sift = cv2.SIFT_create()
    counts = {name: len(sift.detect(builtin_label(name, 400, 250), None))
              for name in ("builtin:label-3", "builtin:sparse-3", "builtin:plain")}
    assert counts["builtin:label-3"] > 3 * counts["builtin:sparse-3"] > 0 and counts["builtin:plain"] == 0
    assert np.array_equal(builtin_label("builtin:label-3", 400, 250), printed_label(400, 250, seed=3))


def test_the_hand_camera_sees_in_colour_what_the_grey_camera_sees():
    cell = assembly_cell(seed=5)
    T = cell.truth["bracket"].copy()
    T[2, 3] += 0.2
    T[:3, :3] = T[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # looking straight down at the bracket
    rgb = cell.capture(T)
    assert rgb.shape == (720, 1280, 3) and rgb.dtype == np.uint8
    labels = [(p.reference_image.image, p.reference_image.geometry(), cell.truth[p.name]) for p in cell.parts]
    grey = render_labels(labels, T, noise_sigma=0.0, blur_sigma=0.0)
    corner = rgb[:40, :40].reshape(-1, 3).mean(axis=0)  # the table: warm (R > G > B)
    assert corner[0] > corner[1] > corner[2]
    # The red gain is 1 on table and labels: the red plane is the grey image, but for blur and noise.
    assert abs(float(rgb[..., 0].astype(float).mean()) - float(grey.mean())) < 1.0
    centre = (slice(340, 380), slice(620, 660))  # the bracket's label under the optical axis: neutral ink
    assert np.abs(rgb[centre].astype(float).mean(axis=(0, 1)) - grey[centre].mean()).max() < 3.0


def test_upright_on_table_keeps_the_yaw_and_rests_the_lowest_point_on_the_plane():
    mesh = load_part("standoff").mesh  # bottom face at model z = 0
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.array([0.05, -0.04, 1.1]))[0]  # tilted by the 3D step's noise, turned about 63 deg
    T[:3, 3] = (0.5, 0.1, 0.013)
    n = np.array([0.01, 0.0, 1.0])
    n /= np.linalg.norm(n)
    plane = np.append(n, -n @ [0.5, 0.1, 0.004])  # through (0.5, 0.1, 0.004)
    U = upright_on_table(T, mesh, plane)
    assert np.allclose(U[:3, 2], [0, 0, 1]) and U[:3, 3] == pytest.approx([0.5, 0.1, 0.004])
    x = T[:3, 0]
    assert yaw_of(U) == pytest.approx(math.atan2(x[1], x[0]))
    with pytest.raises(ValueError, match="table_plane"):
        upright_on_table(T, mesh, [1.0, 0.0, 0.0, 0.0])


def test_the_cell_places_both_parts_apart_in_reach_and_its_camera_sees_them():
    (x0, x1), (y0, y1) = PLACEMENT_REGION
    for seed in range(20):
        p = random_placements(seed, ["a", "b"])
        assert all(x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1 for _, xy, _ in p)
        assert np.linalg.norm(np.subtract(p[0][1], p[1][1])) >= 0.09
    cell = assembly_cell(seed=2)
    assert {cell.part.name, cell.onto.name} == {"standoff", "bracket"}
    cloud = cell.cloud()
    for name, T in cell.truth.items():
        near = np.linalg.norm(cloud[:, :2] - T[:2, 3], axis=1) < 0.02
        assert (cloud[near, 2] > 0.004).sum() > 30, name  # points on the part, above the table
    assert np.allclose(cell.gripper_robot.T_base_dh0[:3, 3], ASSEMBLY_MOUNTS["gripper"][:3, 3], atol=0.5)
    with pytest.raises(ValueError, match="assembly"):
        assembly_cell("block")
    with pytest.raises(ValueError, match="placements"):
        assembly_cell(placements=[("standoff", (0.5, 0.0), 0.0)])


def test_assemblies_place_the_part_within_its_tolerance_checked_against_the_truth(runs):
    for cell, r in runs:
        assert r.status == "planned", r.reason
        a, b = cell.part, cell.onto
        for name in (a.name, b.name):  # the 2D step: within 1 mm and 0.5 deg of the truth
            T, truth = r.parts[name].T_base_model, cell.truth[name]
            assert np.linalg.norm(T[:2, 3] - truth[:2, 3]) < 0.001
            period = 60.0 if name == "standoff" else 360.0
            assert wrapped_deg(yaw_of(T) - yaw_of(truth), period) < 0.5
            assert abs(T[2, 3] - truth[2, 3]) < 0.001  # upright on the fitted table plane
        # The joint targets reach the planned TCP poses (forward kinematics of the arm, its tool the gripper's).
        arm = cell.gripper_robot.with_tool(np.asarray(a.gripper.T_flange_tcp))
        q = r.q_gripper
        assert np.allclose(arm.fk(q["grasp"]), r.T_base_tcp_grasp, atol=1e-9)
        assert np.allclose(arm.fk(q["place"]), r.T_base_tcp_place, atol=1e-9)
        # Where A truly ends up: held as the gripper truly closed on it, let go at the place.
        placed = r.T_base_tcp_place @ np.linalg.inv(r.T_base_tcp_grasp) @ cell.truth[a.name]
        rel = np.linalg.inv(cell.truth[b.name]) @ placed
        goal = a.assembly.T_onto_part
        assert np.linalg.norm(rel[:3, 3] - goal[:3, 3]) < a.assembly.tolerance_translation
        assert np.allclose(rel[:3, 2], [0, 0, 1], atol=1e-3)
        assert wrapped_deg(yaw_of(rel) - yaw_of(goal), 60.0) < math.degrees(a.assembly.tolerance_angle)
        s = score_assembly(r, cell)["placement"]
        assert s["success"] and s["translation_m"] == pytest.approx(np.linalg.norm(rel[:3, 3] - goal[:3, 3]),
                                                                    abs=1e-6)
        assert len(r.q_camera) == sum(len(p.refine.views) for p in r.parts.values()) >= 4


def test_the_3d_step_alone_misses_the_tolerance_the_2d_step_meets(runs):
    misses = 0
    for cell, r in runs:
        rough = {n: p.T_base_model_rough for n, p in r.parts.items()}
        plan = plan_pick_and_place(cell.part, rough[cell.part.name], rough[cell.onto.name], cell.gripper_robot,
                                   settings=AssemblySettings().planner)
        assert plan.status == "planned"
        c, p = plan.pick.candidates[plan.pick.chosen], plan.place.candidates[plan.place.chosen]
        placed = np.asarray(p.T_base_tcp_grasp) @ np.linalg.inv(c.T_base_tcp_grasp) @ cell.truth[cell.part.name]
        rel = np.linalg.inv(cell.truth[cell.onto.name]) @ placed
        misses += np.linalg.norm(rel[:3, 3] - cell.part.assembly.T_onto_part[:3, 3]) > 0.001 or \
            wrapped_deg(yaw_of(rel), 60.0) > 1.0
    assert misses >= 2
    cell, _ = runs[0]
    with pytest.raises(ValueError, match="no 'assembly'"):
        plan_pick_and_place(cell.onto, np.eye(4), np.eye(4), cell.gripper_robot)
    with pytest.raises(ValueError, match="T_base_onto"):
        plan_pick_and_place(cell.part, np.eye(4), np.eye(3), cell.gripper_robot)


def test_failures_are_statuses_with_reasons_never_a_pose():
    cell = assembly_cell(seed=1)
    # A weakly textured, then a plain label on part B: no pose for it, no plan.
    for image, statuses in (("builtin:plain", {"too_few_features", "too_few_matches", "too_few_inliers"}),):
        plain = dataclasses.replace(cell.onto, reference_image=ReferenceImage(image, 5000, 0.006, size=(0.064, 0.04)))
        plain = load_part(plain)
        r = assemble(cell.cloud(), cell.part, capture=cell.capture, gripper_robot=cell.gripper_robot,
                     camera_robot=cell.camera_robot, T_flange_camera=cell.T_flange_camera, intrinsics=cell.intrinsics,
                     onto=plain)
        assert r.status == "refine_failed" and r.parts["bracket"].status in statuses and "bracket" in r.reason
        assert r.parts["bracket"].T_base_model is None and r.pick is None and not r and r.q_gripper == {}
    # The camera arm 3 m away: no view is reachable.
    far = cell.camera_robot.with_base(np.array([[1, 0, 0, 3.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
                                      @ cell.camera_robot.T_base_dh0)
    r = assemble(cell.cloud(), cell.part, capture=cell.capture, gripper_robot=cell.gripper_robot, camera_robot=far,
                 T_flange_camera=cell.T_flange_camera, intrinsics=cell.intrinsics)
    assert r.status == "refine_failed" and r.parts["standoff"].status == "unreachable"
    # Only the table: nothing to find.
    table = cell.cloud()
    r = assemble(table[table[:, 2] < 0.002], cell.part, capture=cell.capture, gripper_robot=cell.gripper_robot,
                 camera_robot=cell.camera_robot, T_flange_camera=cell.T_flange_camera, intrinsics=cell.intrinsics)
    assert r.status == "not_found" and "standoff" in r.reason and r.parts["standoff"].T_base_model is None


def test_settings_are_one_struct_with_the_tof_defaults():
    s = AssemblySettings()
    assert s.find_parts.table.plane.threshold == 0.0025 and s.view.height == 0.12 and s.refine_2d.max_steps == 4
    s.refine_2d.max_steps = 0
    with pytest.raises(ValueError, match="refine_2d"):
        s.validate()


def test_the_command_writes_both_arms_targets_and_repeats_from_its_config(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["assemble", "--seed", "0", "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "success" in text and "3D step" in text and "converged" in text
    rows = (out / "joints_gripper.csv").read_text().splitlines()
    assert rows[0].startswith("target,q1_rad") and [r.split(",")[0] for r in rows[1:]] == [
        "pre_grasp", "grasp", "pre_place", "place"]
    assert len((out / "joints_camera.csv").read_text().splitlines()) >= 5
    result = json.loads((out / "assembly.json").read_text())
    assert result["status"] == "planned" and (out / "views.png").stat().st_size > 10_000
    again = tmp_path / "again"
    assert main(["assemble", "--seed", "0", "--out", str(again), "--quiet", "--config", str(out / "config.yaml"),
                 "--max-steps", "3", "--no-plots"]) == 0
    config = (again / "config.yaml").read_text()
    assert "max_steps: 3" in config and "threshold: 0.0025" in config and not (again / "views.png").exists()
    assert main(["assemble", "--part", "block", "--out", str(tmp_path / "x")]) == 2
    assert "no 'assembly'" in capsys.readouterr().err
