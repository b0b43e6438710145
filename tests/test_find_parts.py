"""find_parts on a rendered table scene with the three built-in parts at known poses (a
Zivid-like camera image): the right part and pose per cluster, a ball of no part, two copies
of a model (ambiguous), the standoff's symmetric poses (not ambiguous), and bad input."""

import functools
import math
import types

import numpy as np
import pytest

from scanalign import _core, io, pose
from scanalign.pose import model_views as cad
from scanalign.data import parts
from scanalign import synthetic as syn
from scanalign.reconstruction.camera import intrinsics_preset
from scanalign.reconstruction import depth_to_cloud

NAMES = ("block", "bracket", "standoff")
PLACED = {"block": (0.42, -0.10, 0.4), "bracket": (0.58, 0.08, 2.0), "standoff": (0.40, 0.10, 0.9)}
KW = dict(up=(0, 0, 1), table_threshold=0.002, cluster_tolerance=0.01)  # Zivid noise: a 2 mm table band


def _ball(radius):
    """A sphere (subdivided icosahedron) of `radius` m: no part looks like it."""
    v, f = _core.pose.tessellated_sphere(4)
    return io.Mesh(radius * v, f)


@functools.lru_cache(maxsize=None)
def _models():
    return [cad.render_views(parts.builtin_mesh(name=n), resolution=100) for n in NAMES]


@functools.lru_cache(maxsize=None)
def _scene(distractor: bool = True):
    """One camera image of the table (base frame, z up) and the true T_base_object per part."""
    scene = syn.Scene(table_size=(0.6, 0.6), table_center=(0.5, 0.0))
    truth = {n: scene.add_object(parts.builtin_mesh(name=n), position=PLACED[n][:2], yaw=PLACED[n][2]).T_base_object
             for n in NAMES}
    if distractor:
        scene.add_object(_ball(0.025), position=(0.60, -0.12))
    K = intrinsics_preset("sr300")
    target = np.array([0.5, 0.0, 0.0])
    eye = target + 0.45 * np.array([math.cos(0.3) * math.cos(1.0), math.sin(0.3) * math.cos(1.0), math.sin(1.0)])
    T = syn.look_at(eye, target)
    r = scene.render(T, K)
    z = _core.synthetic.apply_sensor_noise(syn.NOISE_PRESETS["zivid"], r.depth, r.cos_incidence, 1)
    p, _ = depth_to_cloud(z, K, max_depth=1.5)
    return p.astype(np.float64) @ T[:3, :3].T + T[:3, 3], truth


def _symmetric_error(T, T_true, sym):
    """(deg, mm) minimised over the part's rotations about its axis (an independent oracle)."""
    best = (math.inf, math.inf)
    for k in range(sym.order):
        a = 2 * math.pi * k / sym.order
        S = np.eye(4)
        S[:3, :3] = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]  # axis z, origin
        dT = np.linalg.inv(T) @ T_true @ S
        ang = math.degrees(math.acos(np.clip((np.trace(dT[:3, :3]) - 1) / 2, -1, 1)))
        best = min(best, (ang, 1e3 * np.linalg.norm(T[:3, 3] - T_true[:3, 3])))
    return best


def test_each_cluster_gets_its_part_and_pose_and_the_box_is_no_part():
    cloud, truth = _scene()
    syms = [parts.BUILTIN_PARTS[n] for n in NAMES]
    out = pose.find_parts(_models(), cloud, symmetries=syms, **KW)
    assert len(out.detections) == 4
    found = {}
    for d in out.detections:
        centre = cloud[d.indices].mean(axis=0)
        if np.linalg.norm(centre[:2] - [0.60, -0.12]) < 0.03:  # the ball
            assert d.status == pose.DetectionStatus.not_found, d.message
            assert not d.pose.found
            continue
        assert d.status == pose.DetectionStatus.found, d.message
        name = NAMES[d.part]
        assert np.linalg.norm(centre[:2] - truth[name][:2, 3]) < 0.05, f"{name} found elsewhere"
        deg, mm = _symmetric_error(d.pose.T_scene_model, truth[name], parts.BUILTIN_PARTS[name])
        assert deg < 0.5 and mm < 1.0, (name, deg, mm)
        assert len(d.parts) == 3 and d.pose.found and d.score >= 0.9
        found[name] = d
    assert sorted(found) == sorted(NAMES)
    # The size gate: the standoff (35 mm) cannot be the block's or the bracket's cluster.
    for name in ("block", "bracket"):
        assert found[name].parts[2].message.startswith("skipped"), found[name].parts[2].message
    # Without the size gate every part is aligned to the ball, and none fits it.
    ungated = pose.find_parts(_models(), cloud, symmetries=syms, max_size_ratio=0, min_size_ratio=0, **KW)
    ball = next(d for d in ungated.detections if np.linalg.norm(cloud[d.indices].mean(0)[:2] - [0.60, -0.12]) < 0.03)
    assert ball.status == pose.DetectionStatus.not_found, ball.message
    assert not any(p.message.startswith("skipped") for p in ball.parts) and not any(p.found for p in ball.parts)
    # Every candidate keeps its pose; the reported one is among them.
    d = found["block"]
    assert any(np.allclose(c.T_scene_model, d.pose.T_scene_model) for c in d.pose.candidates)


def test_a_looser_fitting_runner_up_is_no_ambiguity():
    """The bracket slid 8 mm along its plates is a distinct, wrong ICP minimum that, with three
    RANSAC hypotheses per view, scores within the ambiguity margin (the score saturates at the
    5 mm inlier threshold); its inlier RMSE is three times the true pose's, which is what
    ambiguity_rmse_ratio reads."""
    cloud, truth = _scene()
    syms = [parts.BUILTIN_PARTS[n] for n in NAMES]

    def bracket(**kw):
        out = pose.find_parts(_models(), cloud, symmetries=syms, hypotheses=3, **KW, **kw)
        return next(d for d in out.detections if np.linalg.norm(cloud[d.indices].mean(0)[:2] - truth["bracket"][:2, 3]) < 0.05)

    loose = bracket(ambiguity_rmse_ratio=0)
    assert loose.status == pose.DetectionStatus.ambiguous and loose.runner_up_part == NAMES.index("bracket")
    assert loose.runner_up_distance > 0.005 and loose.runner_up_score >= 0.98 * loose.score
    d = bracket()
    assert d.status == pose.DetectionStatus.found, d.message
    deg, mm = _symmetric_error(d.pose.T_scene_model, truth["bracket"], parts.BUILTIN_PARTS["bracket"])
    assert deg < 0.5 and mm < 1.0, (deg, mm)
    with pytest.raises(ValueError, match="ambiguity_rmse_ratio"):
        pose.find_parts(_models(), cloud, ambiguity_rmse_ratio=0.5, **KW)


def test_two_copies_of_a_model_are_ambiguous_and_the_standoff_symmetry_is_not():
    cloud, truth = _scene(False)
    block, _, standoff = _models()
    out = pose.find_parts([block, block], cloud, **KW)
    d = next(d for d in out.detections if d.part is not None and d.pose.found
             and np.linalg.norm(cloud[d.indices].mean(0)[:2] - truth["block"][:2, 3]) < 0.05)
    assert d.status == pose.DetectionStatus.ambiguous, d.message
    assert d.runner_up_part == 1 - d.part and d.runner_up_score >= 0.95 * d.score
    assert d.runner_up_angle < math.radians(5) and d.runner_up_distance < 0.005  # the same pose, another part

    def standoff_detection(symmetries):
        out = pose.find_parts([standoff], cloud, symmetries=symmetries, max_size_ratio=0, min_size_ratio=0, **KW)
        return next(d for d in out.detections
                    if np.linalg.norm(cloud[d.indices].mean(0)[:2] - truth["standoff"][:2, 3]) < 0.03)

    d = standoff_detection([parts.BUILTIN_PARTS["standoff"]])
    assert d.status == pose.DetectionStatus.found, d.message
    deg, mm = _symmetric_error(d.pose.T_scene_model, truth["standoff"], parts.BUILTIN_PARTS["standoff"])
    assert deg < 0.5 and mm < 1.0
    # Without its symmetry, the views that landed on another of the six poses compete.
    d1 = standoff_detection(None)
    assert d1.status == pose.DetectionStatus.ambiguous, d1.message
    assert d1.runner_up_angle > math.radians(50)


def test_find_parts_refuses_bad_input():
    cloud, _ = _scene(False)
    block = _models()[0]
    with pytest.raises(ValueError, match="models"):
        pose.find_parts([], cloud)
    with pytest.raises(ValueError, match="symmetries"):
        pose.find_parts([block], cloud, symmetries=[None, None], **KW)
    with pytest.raises(TypeError, match="symmetries"):
        pose.find_parts([block], cloud, symmetries=[object()], **KW)
    with pytest.raises(ValueError, match="symmetries\\[0\\]"):
        pose.find_parts([block], cloud, symmetries=[types.SimpleNamespace(axis=np.zeros(3), point=np.zeros(3), order=2)], **KW)
    with pytest.raises(ValueError, match="ambiguity_margin"):
        pose.find_parts([block], cloud, ambiguity_margin=1.5, **KW)
    with pytest.raises(ValueError, match="voxel_size"):
        pose.find_parts([block], cloud, voxel_size=-1, **KW)
    with pytest.raises(ValueError, match="views"):
        pose.find_parts([block], cloud, views=[99], **KW)
