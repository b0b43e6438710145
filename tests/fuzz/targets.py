"""Fuzz targets: every public entry point of every module, with the inputs it may be given.

Each target is a hypothesis strategy of printable recipes (see ``inputs``) and a function
that builds the inputs, calls the entry point through ``contract.call`` and checks what a
success must satisfy. Targets are grouped by module; ``run.py`` runs one group in a child
process so a crash or a hang fails that group's test, not the whole run.
"""

from __future__ import annotations

import functools
import re
from typing import Callable, Dict, List, Tuple

import numpy as np
from hypothesis import strategies as st

from contract import STATS, ContractError, call, check_result, finite
from inputs import (INF, NAN, Param, build, cases, choice, clouds, counts, good_clouds, numbers,
                    rigid_from, transforms)

TARGETS: Dict[str, List[Tuple[str, st.SearchStrategy, Callable]]] = {}


def target(module: str, weight: float = 1.0, **strategies: st.SearchStrategy):
    """Registers a fuzz target; ``weight`` scales its share of the example budget (slow
    pipelines get fewer examples)."""
    def register(fn):
        fn.weight = weight
        TARGETS.setdefault(module, []).append((fn.__name__, cases(**strategies), fn))
        return fn
    return register


def clean(recipe, kinds=None, min_size=0) -> bool:
    """Whether a cloud recipe builds a finite (N, 3) float cloud of the given kinds, so the
    answer is known (a truth check applies)."""
    _, kind, n, _, scale, corrupt, dtype, shape, _ = recipe
    known = (corrupt == "none" and dtype in ("f8", "f4", ">f8") and shape == "n3" and n >= min_size
             and (kinds is None or kind in kinds) and 1e-6 <= scale <= 1e6)
    STATS["truth_checks"] += known
    return known


def rotation_error(T_est, T_true) -> tuple:
    """(radians, metres) between two rigid transforms."""
    E = np.linalg.inv(T_true) @ np.asarray(T_est)
    return float(np.arccos(np.clip((np.trace(E[:3, :3]) - 1) / 2, -1, 1))), float(np.linalg.norm(E[:3, 3]))


UNDETERMINED = ("identical", "line", "two_points")  # a rigid motion is not fixed by these


def iterations(typical):
    """Iteration counts without the legitimately long ones (those are the interrupt test's)."""
    return Param(st.sampled_from([typical, 0, -1, 1, 1.5, NAN, "3", None, 2**70]), st.just(typical))


def _pair(max_size=None):
    """A source cloud, its target (the source moved by a known small rigid motion, or an
    unrelated bad cloud) and target normals."""
    c = clouds(max_size)
    seeds = st.integers(0, 2**16)
    return Param(st.tuples(c.wild, c.wild, seeds, st.booleans()), st.tuples(c.typical, c.typical, seeds, st.just(True)))


def _make_pair(pair):
    src_r, tgt_r, seed, related = pair
    source = build(src_r)
    if related and isinstance(source, np.ndarray) and source.ndim == 2 and source.shape[-1] == 3 \
            and source.dtype.kind == "f":
        T = rigid_from(np.random.default_rng(seed), 0.03, 0.01)
        target = source @ T[:3, :3].T + T[:3, 3]
        return source, np.ascontiguousarray(target, dtype=np.float64), T
    return source, build(tgt_r), None


# -- registration ------------------------------------------------------------------------
@target("registration", pair=_pair(1500), normals=choice(["unit", "zero", "nan", "short", "estimated"]),
        init=transforms(), distance=numbers([0.05, 0.2]), estimator=choice(["point_to_plane", "point_to_point", "dual_quaternion", "nope"]),
        iters=iterations(30), eps=numbers(1e-6), box=choice([None, None, (-1, 1, -1, 1, 0, 9), (1, -1, 0, 0, 0, 0), (NAN,) * 6, (0,) * 5]),
        backend=choice(["cpu", "cpu", "cuda", "gpu"]))
def icp(case):
    from scanalign import features, registration
    source, target_pts, T = _make_pair(case["pair"])
    normals = _normals_for(target_pts, case["normals"])
    init = build(case["init"])
    r = call(registration.icp, source, target_pts, normals, init, max_correspondence_distance=case["distance"],
             box=case["box"], estimator=case["estimator"], max_iterations=case["iters"],
             transformation_epsilon=case["eps"], backend=case["backend"])
    if r is None or not r.converged:
        return
    finite(r.T_target_source, "T_target_source")
    src_r = case["pair"][0]
    if T is not None and clean(src_r, UNDETERMINED, 3) and case["box"] is None and not r.degenerate:
        raise ContractError(f"icp converged, not degenerate, on a {src_r[1]} source (a rigid motion is not determined)")
    point_to_point = case["estimator"] in ("point_to_point", "dual_quaternion")
    if T is not None and clean(src_r, ("corner", "box") if point_to_point else ("corner",), 300) and case["init"][1] == "identity" \
            and case["box"] is None and case["distance"] in (0.05, 0.2) and (point_to_point or case["normals"] == "estimated"):
        angle, shift = rotation_error(r.T_target_source, T)
        if angle > 1e-3 or shift > 1e-3 * src_r[4] * 10:
            raise ContractError(f"icp converged {angle:.2g} rad / {shift * 1e3:.2g} mm from the true motion")


def _normals_for(target_pts, how):
    from scanalign import features
    n = len(target_pts) if isinstance(target_pts, np.ndarray) and target_pts.ndim >= 1 else 3
    if how == "estimated":
        try:
            return features.estimate_normals(target_pts, radius=0.3)
        except (ValueError, TypeError):
            return None
    unit = np.tile((0.0, 0.0, 1.0), (n, 1))
    return {"unit": unit, "zero": np.zeros((n, 3)), "nan": np.full((n, 3), NAN), "short": unit[:-1]}[how]


@target("registration", pair=_pair(300), normals=choice(["unit", "zero", "nan", "short", "estimated"]),
        init=transforms(), variant=choice(["point_to_plane_lls", "point_to_plane", "point_to_point", "gicp", "bad"]),
        distance=numbers(0.2), iters=iterations(20))
def pcl_icp(case):
    from scanalign import registration
    source, target_pts, _ = _make_pair(case["pair"])
    call(registration.pcl_icp, source, target_pts, _normals_for(target_pts, case["normals"]), build(case["init"]),
         variant=case["variant"], max_correspondence_distance=case["distance"], max_iterations=case["iters"])


@target("registration", pair=_pair(300), normals=choice(["unit", "zero", "nan", "short"]),
        thr=numbers(1e-10), pcl=st.booleans())
def point_to_plane_lls(case):
    from scanalign import registration
    source, target_pts, _ = _make_pair(case["pair"])
    n = _normals_for(target_pts, case["normals"])
    if case["pcl"]:
        r = call(registration.pcl_point_to_plane_lls, source, target_pts, n)
    else:
        r = call(registration.point_to_plane_lls, source, target_pts, n, case["thr"])


@target("registration", points=clouds(1500), queries=clouds(300), k=counts(1))
def kdtree(case):
    from scanalign import registration
    tree = call(registration.KdTree, build(case["points"]))
    if tree is not None:
        call(tree.nearest, build(case["queries"]))


@target("registration", points=clouds(300), idx=choice(["int_idx", "weights"]),
        box=choice([(-1, 1, -1, 1, 0, 9), (1, -1, 0, 0, 0, 0), (NAN,) * 6, (0,) * 5, "free_hand", None]))
def box_rejector(case):
    from scanalign import registration
    points = build(case["points"])
    idx = build(("like", case["points"], case["idx"], 1))
    call(registration.box_rejector_keep, points, idx, case["box"])


# -- features ------------------------------------------------------------------------------
@target("features", points=clouds(1500), radius=numbers([0.05, 0.3]), vp=choice([(0, 0, 0), (NAN, 0, 0), (1e300,) * 3, (0, 0)]),
        min_nb=counts(3), curvature=st.booleans(), threads=counts(0, 5000))
def estimate_normals(case):
    from scanalign import features
    r = call(features.estimate_normals, build(case["points"]), case["radius"], case["vp"],
             min_neighbors=case["min_nb"], return_curvature=case["curvature"], num_threads=case["threads"])
    if r is not None and clean(case["points"], ("plane",), 50):
        n = np.asarray(r[0] if case["curvature"] else r, dtype=float)
        n = n[np.isfinite(n).all(axis=1)]
        cos = np.abs(n @ (np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)))
        if n.size and cos.min() < 1 - 1e-6:
            raise ContractError(f"estimate_normals on an exact plane: a normal {np.degrees(np.arccos(cos.min())):.2g} deg off")


@target("features", ev=clouds(300))
def shape_factors(case):
    from scanalign import features
    ev = build(case["ev"])
    r = call(features.shape_factors, np.abs(ev) if isinstance(ev, np.ndarray) and ev.dtype.kind == "f" else ev)
    if r is not None:
        finite(r, "shape factors")


# -- reconstruction ----------------------------------------------------------------------
@target("reconstruction", points=clouds(1500), leaf=numbers([0.01, 0.2], 1e-12), extras=choice(["none", "unit", "colors_u8", "colors_f", "colors_c", "strings", "short", "nan"]),
        min_pts=counts(1))
def voxel_grid(case):
    from scanalign.reconstruction import voxel_grid as vg
    extra = build(("like", case["points"], case["extras"], 3)) if case["extras"] != "none" else None
    normals = extra if case["extras"] in ("unit", "short", "nan", "strings") else None
    colors = extra if case["extras"].startswith("colors") else None
    r = call(vg, build(case["points"]), case["leaf"], normals=normals, colors=colors, min_points_per_voxel=case["min_pts"])
    if r is not None:
        finite(r.points, "voxel centroids")


def _depth(kind: str, seed: int):
    rng = np.random.default_rng(seed)
    d = (rng.uniform(300, 1500, (24, 32))).astype(np.uint16)
    return {"u16": d, "f32": d.astype(np.float32) / 1000, "nan": np.where(d > 900, np.nan, d / 1000.0),
            "empty": np.zeros((0, 0), np.uint16), "zeros": np.zeros_like(d), "3d": d[:, :, None].repeat(3, 2),
            "wrong_size": d[:10], "neg": -d.astype(np.float32), "c": d.astype(complex), "str": "depth"}[kind]


_DEPTHS = ["u16"] * 4 + ["f32", "nan", "empty", "zeros", "3d", "wrong_size", "neg", "c", "str"]


def _intrinsics(kind: str):
    from scanalign.reconstruction.camera import Intrinsics
    base = dict(width=32, height=24, fx=30.0, fy=30.0, cx=16.0, cy=12.0)
    base.update({"ok": {}, "fx0": {"fx": 0.0}, "nan": {"cx": NAN}, "neg": {"fy": -30.0}, "huge": {"fx": 1e300},
                 "size0": {"width": 0}}[kind])
    try:
        return Intrinsics(**base)
    except (ValueError, TypeError):
        return None


@target("reconstruction", depth=choice(_DEPTHS), seed=st.integers(0, 99),
        intr=choice(["ok"] * 4 + ["fx0", "nan", "neg", "huge", "size0"]), scale=numbers([0.001], 1e300),
        dmin=numbers(0.1), dmax=numbers(2.0), stride=counts(1))
def depth_to_cloud(case):
    from scanalign.reconstruction import depth_to_cloud as d2c
    r = call(d2c, _depth(case["depth"], case["seed"]), _intrinsics(case["intr"]), depth_scale=case["scale"],
             min_depth=case["dmin"], max_depth=case["dmax"], stride=case["stride"])
    if r is not None:
        finite(r[0], "back-projected points")
        z = np.asarray(r[0])[:, 2]
        if z.size and isinstance(case["dmin"], float) and isinstance(case["dmax"], float) and \
                (z.min() < case["dmin"] - 1e-6 or z.max() > case["dmax"] + 1e-6):
            raise ContractError(f"depth_to_cloud: depths {z.min()}..{z.max()} outside [{case['dmin']}, {case['dmax']}]")


@target("reconstruction", depth=choice(_DEPTHS), seed=st.integers(0, 99), radius=counts(2, 10**6),
        sigma_s=numbers(1.5), sigma_d=numbers(0.003), scale=numbers(0.001), threads=counts(0, 5000))
def bilateral_filter_depth(case):
    from scanalign import reconstruction
    f = call(reconstruction.BilateralFilterSettings, radius=case["radius"], sigma_space=case["sigma_s"], sigma_depth=case["sigma_d"])
    if f is not None:
        r = call(reconstruction.bilateral_filter_depth, _depth(case["depth"], case["seed"]), f,
                 depth_scale=case["scale"], num_threads=case["threads"])


@target("reconstruction", frames=st.lists(st.tuples(st.one_of(clouds(1500).typical, clouds(1500).wild), st.one_of(transforms().typical, transforms().wild)),
                        min_size=1, max_size=4),
        voxel=numbers(0.01), distance=numbers(0.05))
def reconstructor(case):
    """Frames of every kind into one model: a rejected or failed frame leaves the model
    bit-identical (issue: no lost data under faults)."""
    from scanalign.reconstruction import Reconstructor
    rec = call(Reconstructor, model_voxel_size=case["voxel"], frame_voxel_size=case["voxel"], normal_radius=case["distance"])
    if rec is None:
        return
    for cloud_r, guess_r in case["frames"]:
        before = _model_arrays(rec)
        report = call(rec.integrate_points, build(cloud_r), guess=build(guess_r))
        if report is None or not report.merged:
            after = _model_arrays(rec)
            if not all(np.array_equal(a, b, equal_nan=True) for a, b in zip(before, after)):
                raise ContractError("a frame that was not merged changed the model")
        else:
            finite(report.T_model_camera, "T_model_camera")


def _model_arrays(rec):
    m = rec.model
    return [np.array(getattr(m, name), copy=True) for name in ("points", "normals") if hasattr(m, name)]


# -- fitting and segmentation ------------------------------------------------------------
@target("fitting", points=clouds(300), weights=choice(["none", "weights", "neg_weights", "short", "nan"]), tol=numbers(1e-6))
def fit_sphere(case):
    from scanalign import fitting
    w = None if case["weights"] == "none" else build(("like", case["points"], case["weights"], 2))
    if isinstance(w, np.ndarray) and w.ndim == 2:
        w = w[:, 0]
    r = call(fitting.fit_sphere, build(case["points"]), w, plane_tolerance=case["tol"])
    if r is None or r.is_plane or r.imaginary:
        return
    finite([r.radius, *r.center], "sphere")
    recipe = case["points"]
    if clean(recipe) and recipe[2] < 4:
        raise ContractError(f"fit_sphere returned a sphere from {recipe[2]} points (4 are needed)")
    if clean(recipe, ("sphere",), 4) and case["weights"] in ("none", "weights"):
        s_ = recipe[4]
        err = max(abs(r.radius - s_), np.abs(np.asarray(r.center) - (0, 0, 4 * s_)).max()) / s_
        if err > 1e-6:
            raise ContractError(f"fit_sphere on exact sphere points: relative error {err:.2g}")


@target("fitting", points=clouds(1500), offsets=choice([[0], [0, 5], [5, 0], [0, 10**9], [-1], []]), threads=counts(0, 5000))
def fit_spheres(case):
    from scanalign import fitting
    pts = build(case["points"])
    offs = np.asarray(case["offsets"] + ([len(pts)] if isinstance(pts, np.ndarray) and pts.ndim >= 1 else [3]), dtype=np.int64)
    call(fitting.fit_spheres, pts, offs, num_threads=case["threads"])


@target("fitting", points=clouds(300))
def fit_circle_2d(case):
    from scanalign import fitting
    p = build(case["points"])
    r = call(fitting.fit_circle_2d, p[:, :2] if isinstance(p, np.ndarray) and p.ndim == 2 else p)


@target("segmentation", points=clouds(1500), thr=numbers(0.01), iters=iterations(200), conf=numbers(0.99, 1.5),
        rmin=numbers(0.0), rmax=numbers(INF), threads=counts(0, 5000), sphere=st.booleans())
def ransac(case):
    from scanalign import segmentation
    pts = build(case["points"])
    if case["sphere"]:
        r = call(segmentation.ransac_sphere, pts, case["thr"], min_radius=case["rmin"], max_radius=case["rmax"],
                 max_iterations=case["iters"], confidence=case["conf"], num_threads=case["threads"])
    else:
        r = call(segmentation.ransac_plane, pts, case["thr"], max_iterations=case["iters"], confidence=case["conf"],
                 num_threads=case["threads"])
    if r is None or not r.success:
        return
    recipe, scale = case["points"], case["points"][4]
    if case["sphere"] and clean(recipe, ("sphere",), 12) and case["thr"] == 0.01 and scale == 0.1:
        if abs(r.radius - scale) > 0.01 or np.linalg.norm(np.asarray(r.center) - (0, 0, 4 * scale)) > 0.01:
            raise ContractError(f"ransac_sphere succeeded with r={r.radius}, c={r.center} on a sphere r=0.1, c=(0,0,0.4)")
    if not case["sphere"] and clean(recipe, ("plane",), 12) and case["thr"] == 0.01:
        cos = abs(np.dot(r.normal, np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)))
        if cos < 1 - 1e-6 or len(r.inliers) != recipe[2]:
            raise ContractError(f"ransac_plane on an exact plane: normal {r.normal}, {len(r.inliers)}/{recipe[2]} inliers")


@target("segmentation", points=clouds(1500), thr=numbers(0.01), tol=numbers([0.05, 0.5], 1e6), min_size=counts(10),
        up=choice([None, (0, 0, 1), (0, 0, -1), (0, 0, 0), (NAN, 0, 0), (1, 2)]),
        viewpoint=choice([None, (0, 0, 5), (0, 0, -5), (INF, 0, 0), "abc"]))
def segment_table(case):
    import warnings

    from scanalign import segmentation
    with warnings.catch_warnings(record=True) as caught:  # an up against the viewpoint: a warning, never a crash
        warnings.simplefilter("always")
        r = call(segmentation.segment_table_full, build(case["points"]), threshold=case["thr"],
                 cluster_tolerance=case["tol"], min_cluster_size=case["min_size"], up=case["up"],
                 viewpoint=case["viewpoint"])
    if r is not None and bool(r.warning) != any("below the table" in str(w.message) for w in caught):
        raise ContractError(f"the result's warning {r.warning!r} and the UserWarning raised disagree")


@target("segmentation", points=clouds(1500), thr=numbers(0.005), rmax=numbers(0.2), angle=numbers(0.35, 2.0),
        nrad=numbers(0.05), iters=iterations(100), normals=choice(["none", "given", "short", "nan", "int"]))
def ransac_cylinder(case):
    from scanalign import segmentation
    pts = build(case["points"])
    n = len(pts) if isinstance(pts, np.ndarray) and pts.ndim == 2 else 3
    rng = np.random.default_rng(n)
    normals = {"none": None, "given": rng.normal(size=(n, 3)), "short": np.ones((max(n - 1, 0), 3)),
               "nan": np.full((n, 3), NAN), "int": np.ones((n, 3), dtype=np.int64)}[case["normals"]]
    r = call(segmentation.ransac_cylinder, pts, case["thr"], normals=normals, max_radius=case["rmax"],
             max_normal_angle=case["angle"], normal_radius=case["nrad"], max_iterations=case["iters"])
    if r is None or not r.success:
        return
    if not (np.all(np.isfinite(r.axis)) and abs(np.linalg.norm(r.axis) - 1) < 1e-9 and 0 < r.radius <= case["rmax"]):
        raise ContractError(f"ransac_cylinder succeeded with axis {r.axis}, radius {r.radius} (max {case['rmax']})")
    inl = np.asarray(r.inliers)
    if len(inl) and (inl.min() < 0 or inl.max() >= n):
        raise ContractError("ransac_cylinder: an inlier index outside the input")
    f = call(segmentation.fit_cylinder, pts, r.point, r.axis, r.radius)
    if f is not None and f.refined and not (np.isfinite(f.radius) and f.radius > 0):
        raise ContractError(f"fit_cylinder refined to radius {f.radius}")


@target("segmentation", pts=st.lists(st.sampled_from([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (NAN, 0, 0), (1e300, 0, 0), (2, 0, 0), (0, 0)]), min_size=4, max_size=4))
def model_from_points(case):
    from scanalign import segmentation
    p = [np.asarray(x, dtype=float) for x in case["pts"]]
    call(segmentation.plane_from_points, *p[:3])
    call(segmentation.sphere_from_points, *p)


# -- cga -----------------------------------------------------------------------------------
_VEC = [(0.1, 0.2, 0.3)] * 4 + [(0, 0, 0), (NAN, 0, 0), (INF, 0, 0), (1e300, 0, 0), (1e-300, 0, 0), (1, 2), (1, 2, 3, 4),
                                 (1j, 0, 0), ("a", 0, 0), None]
_SCALAR = [0.2] * 4 + [0.0, -0.2, NAN, INF, 1e300, 1e-300, 1j, "r", None]


@target("cga", x=choice(_VEC), y=choice(_VEC), r=choice(_SCALAR), angle=choice(_SCALAR))
def cga_objects(case):
    from scanalign import cga
    x, y, r = case["x"], case["y"], case["r"]
    arr = lambda v: np.asarray(v) if v is not None else None  # noqa: E731 - arrays of any dtype, as users pass them
    P = call(cga.up, arr(x))
    if P is not None:
        finite(np.asarray(P), "up(x)")
        d = call(cga.down, P)
        if d is not None:
            finite(d, "down(up(x))")
            if not np.allclose(d, np.asarray(x, dtype=float), rtol=1e-12, atol=1e-300):
                raise ContractError(f"down(up(x)) = {d} != x = {x}")
    S = call(cga.Sphere, x, r)
    if S is not None:
        finite([S.radius if hasattr(S, "radius") else 0.0], "sphere radius")
    call(cga.Plane, x, r)
    call(cga.Line, x, y)
    call(cga.point_pair, x, y)
    call(cga.rotor, x, case["angle"])
    call(cga.translator, x)
    M = call(cga.Motor.from_matrix, build(("transform", "small", 1)))
    if M is not None:
        call(M.apply_points, arr(x) if arr(x) is None or arr(x).ndim != 1 else arr(x)[None])


@target("cga", a=clouds(12), b=clouds(12))
def cga_products(case):
    from scanalign import cga
    a, b = build(case["a"]), build(case["b"])
    # (N, 32) multivector coefficient arrays from the clouds' numbers
    lift = lambda c: np.resize(c, (max(len(c), 1), 32)) if isinstance(c, np.ndarray) and c.ndim == 2 else c  # noqa: E731
    r = call(cga.geometric_product_many, lift(a), lift(b))


# -- kinematics --------------------------------------------------------------------------
_ROBOTS = ["ur5", "kuka_kr6_r900_sixx", "ur10e"]
_QS = ["random"] * 5 + ["stretched", "wrist_singular", "nan", "inf", "huge", "five", "seven", "complex", "str", "batch", "batch_bad"]


def _q(kind, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, 6)
    if kind == "stretched":
        q[2] = rng.normal(0, 1e-3)
    elif kind == "wrist_singular":
        q[4] = rng.normal(0, 1e-7)
    return {"random": q, "stretched": q, "wrist_singular": q, "nan": np.r_[q[:5], NAN], "inf": np.r_[q[:5], INF],
            "huge": q * 1e300, "five": q[:5], "seven": np.r_[q, 0], "complex": q.astype(complex), "str": "home",
            "batch": rng.uniform(-3, 3, (7, 6)), "batch_bad": rng.uniform(-3, 3, (7, 5))}.get(kind, q)


@target("kinematics", robot=choice(_ROBOTS), q=choice(_QS), seed=st.integers(0, 2**16),
        pose=choice(["fk"] * 6 + ["transform"] * 3), T=transforms(), threads=counts(0, 5000))
def ik_round_trip(case):
    """Every solution flagged ok reaches the pose (FK within 1e-6 m / rad), and a pose made
    by FK of joint values within the limits is reachable (truth: those joint values)."""
    from scanalign import kinematics
    robot = getattr(kinematics, case["robot"])()
    q = _q(case["q"], case["seed"])
    T_fk = call(robot.fk, q, num_threads=case["threads"])
    T = T_fk if case["pose"] == "fk" and T_fk is not None and np.shape(T_fk) == (4, 4) else build(case["T"])
    sols = call(robot.ik, T)
    if sols is None:
        return
    for qi, ok in zip(np.asarray(sols.q), np.asarray(sols.ok)):
        if ok:
            err = np.abs(robot.fk(qi) - T).max()
            if not err < 1e-6:
                raise ContractError(f"an ok IK solution misses the pose by {err}")
    if case["pose"] == "fk" and np.shape(T_fk) == (4, 4) and case["q"] in ("random", "stretched", "wrist_singular"):
        lo, hi = np.asarray(robot.limits).reshape(2, 6) if np.size(robot.limits) == 12 else (None, None)
        if lo is not None and np.all((q >= lo) & (q <= hi)) and not np.any(sols.ok):
            raise ContractError(f"a pose made by FK of joints within the limits came back unreachable: q={q.tolist()}")
    call(robot.ik_closest, T, q)
    call(robot.ik_batch, np.asarray(T)[None] if np.ndim(T) == 2 else T, num_threads=case["threads"])


# -- CAD views, pose and CBD ---------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def _part():
    from scanalign.data import parts
    return parts.builtin_mesh(24)


@functools.lru_cache(maxsize=1)
def _part_cloud():
    from scanalign.data import parts
    return parts.sample_mesh(_part(), 1500, seed=1)[0]


_MESHES = ["part"] * 3 + ["nan_vertex", "bad_index", "neg_index", "no_faces", "degenerate", "float_faces", "2d"]


def _mesh(kind):
    m = _part()
    v, f = np.array(m.vertices, dtype=float), np.array(m.faces)
    if kind == "nan_vertex":
        v[0] = NAN
    elif kind == "bad_index":
        f[0, 0] = len(v) + 5
    elif kind == "neg_index":
        f[0, 0] = -1
    elif kind == "no_faces":
        f = f[:0]
    elif kind == "degenerate":
        f[:] = f[:, :1]
    elif kind == "float_faces":
        f = f.astype(float) + 0.5
    elif kind == "2d":
        v = v[:, :2]
    return v, f


@target("cad", mesh=choice(_MESHES), res=counts([24, 40], 10**5), angle=numbers(1.0, 3.2), level=counts(0, 9),
        dist=choice([None, 0.5, 0.0, -1.0, NAN, 1e300]))
def render_views(case):
    from scanalign.pose import model_views as cad
    views = call(cad.render_views, _mesh(case["mesh"]), resolution=case["res"], view_angle=case["angle"],
                 level=case["level"], distance=case["dist"])
    for v in views or []:
        finite(v.points, "view points")


@target("cad", points=clouds(1500), normals=choice(["none", "given", "short", "nan", "zero"]), res=counts([24, 40], 10**5),
        level=counts(0, 9), nrad=numbers(0.02, 1e-9), splat=numbers(0.0, 1e3), tol=numbers(0.0))
def cloud_views(case):
    """Views of a model cloud: any cloud and settings give views of finite points facing their camera, or a
    ValueError / TypeError naming the cause."""
    from scanalign.io.interop import Cloud
    from scanalign.pose import model_views as cad
    pts = build(case["points"])
    n = len(pts) if isinstance(pts, np.ndarray) and pts.ndim == 2 else 3
    normals = {"none": None, "given": np.random.default_rng(n).normal(size=(n, 3)), "short": np.ones((max(n - 1, 0), 3)),
               "nan": np.full((n, 3), NAN), "zero": np.zeros((n, 3))}[case["normals"]]
    model = pts if normals is None else Cloud(pts, normals)
    views = call(cad.cloud_views, model, resolution=case["res"], level=case["level"],
                 cloud={"normal_radius": case["nrad"], "splat_radius": case["splat"], "depth_tolerance": case["tol"]})
    for v in views or []:
        finite(v.points, "view points")
        eye = np.asarray(v.T_model_camera)[:3, 3]
        if len(v.points) and np.any(np.einsum("ij,ij->i", v.normals, eye - v.points) < -1e-9):
            raise ContractError("a cloud view's normal faces away from its camera")


@target("cad", points=clouds(600), kind=choice(["pcd", "ply", "xyz", "empty"]))
def read_model(case, tmp=[]):
    """write_pcd / write_ply then read_model: the points come back (float32), or a ValueError names the file."""
    import tempfile
    from pathlib import Path

    from scanalign import io
    from scanalign.pose import model_views as cad
    if not tmp:
        tmp.append(Path(tempfile.mkdtemp(prefix="fuzz_read_model_")))
    path = tmp[0] / f"model.{case['kind'] if case['kind'] != 'empty' else 'pcd'}"
    path.unlink(missing_ok=True)  # never a file from an earlier example
    pts = build(case["points"])
    if case["kind"] == "empty":
        path.write_bytes(b"")
    elif case["kind"] == "xyz":
        path.write_text("0 0 0\n")
    else:
        call((io.write_pcd if case["kind"] == "pcd" else io.write_ply), path, pts)
        if not path.exists():  # refused: nothing written
            return
    model = call(cad.read_model, path)
    if model is not None and case["kind"] in ("pcd", "ply") and isinstance(pts, np.ndarray) and pts.ndim == 2:
        good = np.asarray(pts, dtype=np.float32)
        good = good[np.all(np.isfinite(good), axis=1)]
        if len(model.points) != len(good) or not np.allclose(model.points, good, equal_nan=True):
            raise ContractError(f"read_model gave {len(model.points)} points for {len(good)} finite ones written")


@target("pose", src=clouds(300), tgt=clouds(300), w=choice(["none", "weights", "neg_weights", "short"]), svd=st.booleans())
def estimate_motor(case):
    from scanalign import pose
    src, T = build(case["src"]), rigid_from(np.random.default_rng(3), 1.0, 0.5)
    moved = clean(case["src"]) and case["tgt"][1] == "wavy"  # half the cases: the target is the source moved by T
    tgt = np.asarray(src, dtype=float) @ T[:3, :3].T + T[:3, 3] if moved else build(case["tgt"])
    w = None if case["w"] == "none" else build(("like", case["src"], case["w"], 0))
    w = w[:, 0] if isinstance(w, np.ndarray) and w.ndim == 2 else w
    r = call(pose.estimate_rigid_svd if case["svd"] else pose.estimate_motor, src, tgt, w)
    if r is None or not r.valid or not moved or case["w"] not in ("none", "weights"):
        return
    if case["src"][1] in UNDETERMINED:
        raise ContractError(f"estimate_motor valid on {case['src'][1]} points (the rotation is not determined)")
    angle, shift = rotation_error(r.T_target_source, T)
    if angle > 1e-6 or shift > 1e-6 * max(1.0, case["src"][4] * 10):
        raise ContractError(f"estimate_motor valid but {angle:.2g} rad / {shift:.2g} m from the true motion")


@target("pose", src=clouds(300), nkind=choice(["unit", "zero", "nan", "short", "scaled"]), tgt=clouds(300), moved=st.booleans())
def align_flags(case):
    """Truth: when the target is the source moved by a known motion and the result is
    valid, it is that motion (flags are exact on noise-free data)."""
    from scanalign import pose
    src = build(case["src"])
    n_src = build(("like", case["src"], case["nkind"], 5))
    T = rigid_from(np.random.default_rng(1), 0.5, 0.1)
    if case["moved"] and isinstance(src, np.ndarray) and src.ndim == 2 and src.shape[1:] == (3,) and src.dtype.kind == "f" \
            and isinstance(n_src, np.ndarray) and n_src.shape == src.shape:
        tgt, n_tgt = src @ T[:3, :3].T + T[:3, 3], n_src @ T[:3, :3].T
    else:
        tgt, n_tgt, T = build(case["tgt"]), build(("like", case["tgt"], "unit", 6)), None
    r = call(pose.align_flags, src, n_src, tgt, n_tgt)
    if r is not None and r.valid and T is not None and np.all(np.isfinite(src)):
        err = np.abs(np.asarray(r.T_target_source) - T).max()
        if err > 1e-6 * max(1.0, np.abs(src).max()):
            raise ContractError(f"align_flags valid but {err:.3g} from the true motion")


@functools.lru_cache(maxsize=1)
def _views():
    from scanalign.pose import model_views as cad
    return cad.render_views(_part(), resolution=40)


@target("pose", weight=0.25, scene=clouds(1500), method=choice(["cbd", "flags", "fpfh", "nope"], ["cbd", "flags"]),
        res=counts(40, 10**5, 10**9), moved=choice([True, False], [True, False]), thr=numbers(0.005))
def estimate_pose(case):
    """Truth: the scene is one rendered view of the part moved by a known motion, or a bad
    or unrelated cloud. A found pose must put the scene on the part's surface (exact
    point-to-mesh distance, median under 1 mm: symmetric parts may be found in any of
    their equivalent poses)."""
    from scanalign import evaluation, pose
    T = rigid_from(np.random.default_rng(2), 0.3, 0.05)
    scene = np.asarray(_views()[7].points) @ T[:3, :3].T + T[:3, 3] if case["moved"] else build(case["scene"])
    model = _views() if case["res"] == 40 else _part()
    r = call(pose.estimate_pose, model, scene, method=case["method"], resolution=case["res"],
             inlier_threshold=case["thr"], views=[0, 7])
    if r is not None and r.found and case["moved"]:
        T_model_scene = np.linalg.inv(np.asarray(r.T_scene_model))
        in_model = scene @ T_model_scene[:3, :3].T + T_model_scene[:3, 3]
        gap = np.median(evaluation.point_to_mesh_distance(in_model, _part().vertices, _part().faces))
        if gap > 0.001:
            raise ContractError(f"estimate_pose found a pose that puts the scene {gap * 1e3:.1f} mm off the part")


@target("pose", weight=0.25, scene=clouds(1500), kind=choice(["two_copies", "cloud"]), inst=counts([1, 2, 10], 10**9),
        score=numbers(0.9, 1.5))
def find_parts_instances(case):
    """Two copies of a rendered view side by side on a table plane, or any cloud, with any instance settings: a
    result whose detections index the scene and explain each point at most once, or a ValueError naming the field."""
    from scanalign import pose
    rng = np.random.default_rng(3)
    if case["kind"] == "two_copies":
        view = np.asarray(_views()[7].points)
        view = view - [*view[:, :2].mean(axis=0), view[:, 2].min() - 0.001]
        table = np.c_[rng.uniform(-0.2, 0.2, (3000, 2)), np.zeros(3000)]
        scene = np.vstack([table, view, view + [np.ptp(view[:, 0]) + 0.004, 0, 0]])
    else:
        scene = build(case["scene"])
    r = call(pose.find_parts, [_views()], scene, views=[0, 7], max_instances=case["inst"],
             min_instance_score=case["score"], up=(0, 0, 1), min_cluster_size=20)
    if r is None:
        return
    seen = [np.asarray(d.indices) for d in r.detections if d.status != pose.DetectionStatus.not_found]
    idx = np.concatenate(seen) if seen else np.zeros(0, dtype=np.int64)
    if len(np.unique(idx)) != len(idx) or (len(idx) and (idx.min() < 0 or idx.max() >= len(scene))):
        raise ContractError("find_parts' instances share points or index outside the scene")


@target("pose", src=clouds(1500), tgt=clouds(1500),
        method=choice(["fpfh", "shot", "pfh", "rsd", "gasd", "vfh", "nope"]),
        settings=choice([{}, {"rsd_plane_radius": 0.0}, {"rsd_plane_radius": INF}, {"vfh_min_points": 2},
                         {"vfh_min_points": 10 ** 9}, {"vfh_eps_angle": NAN}, {"vfh_cluster_tolerance": -1.0},
                         {"vfh_curvature_threshold": 0.0}, {"gasd_half_turns": False}, {"gasd_half_turns": "yes"},
                         {"feature_radius": 1e3}]))
def pcl_feature_alignment(case):
    from scanalign import pose
    call(pose.pcl_feature_alignment, build(case["src"]), build(case["tgt"]), method=case["method"], **case["settings"])


@target("cbd", points=clouds(1500), radius=numbers([0.05, 0.3]), kp=counts([50, 200]), min_nb=counts(0))
def cbd_compute(case):
    from scanalign.pose import cbd
    f = call(cbd.compute, build(case["points"]), radius=case["radius"], max_keypoints=case["kp"], min_neighbors=case["min_nb"])
    if f is not None:
        finite(f.descriptors, "CBD descriptors")
        call(cbd.match, f, f)


@target("cbd", points=clouds(1500), radius=numbers(0.3), min_nb=counts(20), k=counts(50))
def cbd_parts(case):
    from scanalign.pose import cbd
    r = call(cbd.neighbourhood_pca, build(case["points"]), case["radius"])
    if r is not None:
        counts_, ev = r
        call(cbd.keypoint_scores, counts_, ev, case["min_nb"])
        call(cbd.select_keypoints, counts_, ev, min_neighbors=case["min_nb"])
        call(cbd.automatic_keypoints, counts_, ev, case["k"], case["min_nb"])


# -- file readers (mutated valid files; the atheris targets in fuzz/ go further) ---------
def _valid_files(tmp):
    from scanalign import io
    rng = np.random.default_rng(0)
    p = rng.uniform(-1, 1, (20, 3))
    files = {}
    for binary in (False, True):
        path = f"{tmp}/cloud_{int(binary)}.ply"
        io.write_ply(path, p, normals=p, binary=binary)
        files[path] = open(path, "rb").read()
    header = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 20\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 20\n"
    files[f"{tmp}/a.pcd"] = (header + "DATA ascii\n" + "\n".join(" ".join(map(str, r)) for r in p) + "\n").encode()
    files[f"{tmp}/b.pcd"] = (header + "DATA binary\n").encode() + p.astype(np.float32).tobytes()
    files[f"{tmp}/m.off"] = b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 2 3\n"
    files[f"{tmp}/m.obj"] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n"
    tri = np.array([[0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0]], np.float32)
    files[f"{tmp}/m.stl"] = b"\0" * 80 + np.uint32(1).tobytes() + tri.tobytes() + b"\0\0"
    files[f"{tmp}/t.txt"] = b"# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n2.0 0.1 0 0 0 0 0 1\n"
    return files


def _mutate(data: bytes, edits) -> bytes:
    b = bytearray(data)
    for op, pos, value in edits:
        if not b:
            break
        i = pos % len(b)
        if op == "flip":
            b[i] = value
        elif op == "cut":
            del b[i:]
        elif op == "insert":
            b[i:i] = bytes([value]) * (1 + value % 7)
        elif op == "digits":  # lie in a header: make a number huge or negative
            b[i:i] = b"-" if value % 2 else b"99999999999"
    return bytes(b)


_EDITS = st.lists(st.tuples(st.sampled_from(["flip", "cut", "insert", "digits"]), st.integers(0, 10**6), st.integers(0, 255)),
                  max_size=4)


@target("io", which=st.integers(0, 8), edits=_EDITS)
def readers(case):
    import tempfile

    from scanalign import io
    from scanalign.evaluation import trajectory
    with tempfile.TemporaryDirectory() as tmp:
        files = _valid_files(tmp)
        path, data = sorted(files.items())[case["which"] % len(files)]
        with open(path, "wb") as fh:
            fh.write(_mutate(data, case["edits"]))
        if path.endswith(".pcd"):
            r = call(io.read_pcd, path)
            call(io.read_pcd_points, path)
        elif path.endswith(".ply"):
            call(io.read_ply_points, path)
            call(io.read_mesh, path)
        elif path.endswith(".txt"):
            t = call(trajectory.read_tum_trajectory, path)
            if t is not None:
                finite(t.timestamps, "timestamps")
                finite(t.poses, "poses")
        else:
            m = call(io.read_mesh, path)
            if m is not None and len(m.faces):
                f = np.asarray(m.faces)
                if f.min() < 0 or f.max() >= len(m.vertices):
                    raise ContractError("a mesh read with face indices out of range")


_LZF_OK = b"\x03abcd\x20\x03"  # a literal run "abcd", then a back-reference copying 3 bytes: "abcdbcd"


@target("io", data=st.one_of(st.just(_LZF_OK), st.binary(max_size=64).map(lambda b: _LZF_OK + b)), size=counts([7, 16], 2**40))
def lzf(case):
    from scanalign import io
    out = call(io.lzf_decompress, case["data"], case["size"])
    if out is not None and len(out) != case["size"]:
        raise ContractError("lzf_decompress returned a length other than expected_size")


@target("io", points=clouds(300), extras=choice(["none", "unit", "colors_u8", "colors_f", "colors_c", "strings", "short", "nan"]), binary=st.booleans())
def write_ply(case):
    import tempfile

    from scanalign import io
    extra = build(("like", case["points"], case["extras"], 3)) if case["extras"] != "none" else None
    normals = extra if case["extras"] in ("unit", "short", "nan", "strings") else None
    colors = extra if case["extras"].startswith("colors") else None
    with tempfile.TemporaryDirectory() as tmp:
        call(io.write_ply, f"{tmp}/out.ply", build(case["points"]), normals=normals, colors=colors, binary=case["binary"])


# -- trajectories and evaluation ---------------------------------------------------------
def _trajectory(kind, seed, n=12):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1 + 1.0
    poses = np.stack([rigid_from(rng, 0.3, 1.0) for _ in range(n)])
    if kind == "static":
        poses[:] = np.eye(4)
    elif kind == "nan_time":
        t[3] = NAN
    elif kind == "nan_pose":
        poses[2, 0, 3] = NAN
    elif kind == "unsorted":
        t = t[::-1].copy()
    elif kind == "duplicate_time":
        t[4] = t[3]
    elif kind == "scaled":
        poses[:, :3, :3] *= 2
    elif kind in ("one", "empty"):
        t, poses = t[: int(kind == "one")], poses[: int(kind == "one")]
    return t, poses


_TRAJ = ["ok"] * 4 + ["static", "nan_time", "nan_pose", "unsorted", "duplicate_time", "scaled", "one", "empty"]


@target("evaluation", est=choice(_TRAJ), ref=choice(_TRAJ), seed=st.integers(0, 99), align=st.booleans(),
        delta=numbers(1), assoc=st.booleans(), maxdiff=numbers(0.02))
def trajectory_errors(case):
    from scanalign import evaluation
    from scanalign.evaluation import trajectory
    est = call(trajectory.Trajectory, *_trajectory(case["est"], case["seed"]))
    ref = call(trajectory.Trajectory, *_trajectory(case["ref"], case["seed"] + 1))
    if est is None or ref is None:
        return
    a = call(evaluation.absolute_trajectory_error, est, ref, align=case["align"], associate=case["assoc"], max_difference=case["maxdiff"])
    if a is not None:
        finite(a.rmse if hasattr(a, "rmse") else 0.0, "ATE")
    call(evaluation.relative_pose_error, est, ref, delta=case["delta"], associate=case["assoc"])
    call(trajectory.associate_timestamps, est.timestamps, ref.timestamps, case["maxdiff"])


@target("evaluation", src=clouds(300), tgt=clouds(300), scale=st.booleans())
def umeyama(case):
    from scanalign import evaluation
    src, T = build(case["src"]), rigid_from(np.random.default_rng(4), 1.0, 0.5)
    moved = clean(case["src"]) and case["tgt"][1] == "wavy"
    tgt = np.asarray(src, dtype=float) @ T[:3, :3].T + T[:3, 3] if moved else build(case["tgt"])
    r = call(evaluation.umeyama_alignment, src, tgt, case["scale"])
    if r is not None and moved:
        if case["src"][1] in UNDETERMINED:
            raise ContractError(f"umeyama_alignment answered for {case['src'][1]} points (the rotation is not determined)")
        R, t, c = r
        if np.abs(np.asarray(R) - T[:3, :3]).max() > 1e-6 or abs(c - 1) > 1e-6:
            raise ContractError("umeyama_alignment: wrong rotation or scale for an exact rigid motion")


@target("evaluation", points=clouds(1500), mesh=choice(_MESHES))
def mesh_distance(case):
    from scanalign import evaluation
    v, f = _mesh(case["mesh"])
    points = build(case["points"])
    d = call(evaluation.point_to_mesh_distance, points, v, f)
    if d is not None and clean(case["points"]) and case["mesh"] == "part":
        finite(d, "distances of finite points")  # a NaN point's distance is NaN, honestly
    call(evaluation.mesh_distance_stats, build(case["points"]), v, f)


@target("se3", T=transforms(), T2=transforms(), axis=choice(_VEC), angle=choice(_SCALAR))
def se3_functions(case):
    from scanalign.common import rigid as se3
    T, T2 = build(case["T"]), build(case["T2"])
    call(se3.inverse, T)
    call(se3.pose_error, T, T2)
    call(se3.require_rigid, T, "T")
    call(se3.rotation_angle, T[:3, :3] if isinstance(T, np.ndarray) and T.ndim == 2 and T.shape[0] >= 3 else T)
    r = call(se3.rigid, case["axis"], case["angle"], (0.0, 0.0, 0.0))
    if r is not None:
        finite(r, "rigid")


# -- meshes, rendering and the synthetic scanner -------------------------------------------
@target("rendering", mesh=choice(_MESHES), intr=choice(["ok"] * 4 + ["fx0", "nan", "neg", "huge", "size0"]),
        T=transforms(), near=numbers(0.01), far=numbers(INF), n=counts(100, 10**12))
def render_and_sample(case):
    from scanalign.data import parts
    from scanalign.reconstruction import rendering
    v, f = _mesh(case["mesh"])
    T = build(case["T"])
    if isinstance(T, np.ndarray) and T.shape == (4, 4) and T.dtype.kind == "f":
        T = T.copy()
        T[2, 3] += 2.0  # put the part in front of the camera
    r = call(rendering.render_depth, v, f, _intrinsics(case["intr"]), T, near=case["near"], far=case["far"])
    s = call(parts.sample_mesh, (v, f), case["n"])
    if s is not None:
        finite(s[0], "samples")


@target("synthetic", frames=counts(2, 10**9), noise=choice(["sr300", "zivid", "kinect_one", "none", "nope", None]),
        traj=choice(["loop", "hemisphere", "nope"]), scale=numbers(0.1, 1e6), robot=choice(["ur5", "kr6", "nope"]))
def builtin_scan(case):
    from scanalign import synthetic
    scan = call(synthetic.builtin_scan, case["frames"], case["noise"], trajectory=case["traj"],
                resolution_scale=case["scale"], robot=case["robot"])
    for frame in getattr(scan, "frames", [])[:2] if scan is not None else []:
        finite(frame.T_base_camera, "frame pose")


# -- the command line (in process: a crash in C++ still kills the fuzz process) -------------
_NUM = ["0.4", "0", "-1", "nan", "inf", "1e300", "x", ""]


@target("cli", weight=0.5, robot=choice(["ur5", "kr6_r900_sixx", "ur10e", "nope"]),
        pose=Param(st.lists(st.sampled_from(_NUM), min_size=6, max_size=6), st.just(["0.4", "0.1", "0.3", "3.1", "0", "0"])), joints=choice([None, "0 -1 1 0 1 0", "nan 0 0 0 0 0", "1 2"]),
        plot=choice([None, "ik.png", "/proc/version/ik.png"]), reg=choice([None, "ply", "pcd", "missing", "mutated"]),
        opts=st.lists(st.sampled_from(["--max-distance", "--max-iterations", "--normal-radius"]), max_size=2),
        value=choice(["0.05", "0", "-1", "nan", "1e300", "x"]))
def cli_commands(case):
    """Every command ends with an exit status (0, 1 or 2) and a message: never a traceback
    (an exception out of main) or a crash."""
    import contextlib
    import io as _io
    import os
    import tempfile

    from scanalign import cli, io
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(_io.StringIO()), \
            contextlib.redirect_stderr(_io.StringIO()):
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            if case["reg"] is None:
                argv = ["ik", "--robot", case["robot"], "--pose", *case["pose"]]
                if case["joints"]:
                    argv = ["ik", "--robot", case["robot"], "--joints", *case["joints"].split()]
                if case["plot"]:
                    argv += ["--plot", case["plot"]]
            else:
                p = np.random.default_rng(0).uniform(-0.1, 0.1, (200, 3)) + (0, 0, 0.5)
                io.write_ply("a.ply", p)
                io.write_ply("b.ply", p + 0.002)
                files = _valid_files(tmp)
                src = {"ply": "a.ply", "pcd": f"{tmp}/b.pcd", "missing": "none.ply"}.get(case["reg"], "a.ply")
                if case["reg"] == "mutated":
                    with open("a.ply", "r+b") as fh:
                        fh.seek(200)
                        fh.write(b"\xff" * 8)
                argv = ["register", src, "b.ply"] + [x for o in case["opts"] for x in (o, case["value"])]
            try:
                status = cli.main(argv)
            except SystemExit as exc:  # argparse: usage error, status 2
                status = exc.code
            STATS["returned" if status == 0 else "refused"] += 1
            if status not in (0, 1, 2):
                raise ContractError(f"scanalign {' '.join(argv)} exited with status {status!r}")
            if case["plot"] == "/proc/version/ik.png" and status == 0:
                raise ContractError("scanalign ik reported success but could not write its plot")
        finally:
            os.chdir(cwd)


# -- hand-eye calibration ----------------------------------------------------------------
def _hand_eye_data(n: int, motion: str, seed: int):
    """Exact data from a known X = T_flange_camera and Z = T_base_world: robot poses A[i]
    (general, tiny, parallel-axis or translation-only motions) and the camera poses they
    imply, T_world_camera[i] = inv(Z) A[i] X (world = the target, so T_camera_target[i] is
    its inverse)."""
    rng = np.random.default_rng(seed)
    X, Z = rigid_from(rng, rng.uniform(0.2, 3.0), 0.1), rigid_from(rng, rng.uniform(0, np.pi), 1.0)
    A0 = rigid_from(rng, 1.0, 0.5)
    A = []
    for _ in range(n):
        if motion == "general":
            A.append(rigid_from(rng, rng.uniform(0.3, np.pi), 0.8))
        elif motion == "tiny":  # rotations of 1e-4 rad: below min_relative_rotation
            A.append(A0 @ rigid_from(rng, 1e-4, 0.2))
        else:  # parallel: every rotation about one axis (X's shift along it is not determined); translation: none
            T = np.eye(4)
            if motion == "parallel":
                angle = rng.uniform(-3, 3)
                T[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
            T[:3, 3] = rng.uniform(-0.5, 0.5, 3)
            A.append(A0 @ T)
    A = np.array(A).reshape(n, 4, 4)
    W = np.einsum("ij,njk,kl->nil", np.linalg.inv(Z), A, X)
    return A, W, X


_HE_ARGS = ["ok"] * 4 + ["mismatch", "3x4", "flat", "none", "str", "list", "int", "f4", "fortran", "strided", "object",
                         "nan_robot"]


def _he_arg(A, kind):
    if kind == "mismatch":
        return A[:-1] if len(A) else A[:, :0]
    return {"ok": lambda: A, "3x4": lambda: A[:, :3], "flat": lambda: A.reshape(len(A), 16), "none": lambda: None,
            "str": lambda: "poses", "list": lambda: A.tolist(), "int": lambda: A.astype(int), "f4": lambda: A.astype("f4"),
            "fortran": lambda: np.asfortranarray(A), "strided": lambda: np.repeat(A, 2, axis=0)[::2],
            "object": lambda: A.astype(object), "nan_robot": lambda: np.where(np.arange(4)[:, None] == 0, NAN, A)}[kind]()


@target("calibration", n=Param(st.sampled_from([0, 1, 2, 3, 4, 6, 12, 40]), st.sampled_from([3, 4, 6, 12, 40])),
        motion=choice(["general", "tiny", "parallel", "translation"], ["general"] * 3 + ["tiny", "parallel", "translation"]),
        seed=st.integers(0, 2**16), target_views=st.booleans(), error=transforms("identity"), arg=choice(_HE_ARGS),
        rotation_weight=numbers(0.3, 1e-12), huber_delta=numbers([0.0, 0.002], 1e-12), max_iterations=iterations(50),
        refine=choice([True, False], [True, False]), min_relative_rotation=numbers(0.0872664626), step_tolerance=numbers(1e-12))
def calibrate_hand_eye(case):
    """Truth: camera poses made from a known X. "ok" means a finite rigid X, equal to the
    truth to 1e-6 on exact data; fewer than 3 poses or a degenerate motion is never "ok"
    (a parallel-axis motion leaves X's shift along the axis free)."""
    from scanalign import calibration
    A, W, X = _hand_eye_data(case["n"], case["motion"], case["seed"])
    error = build(case["error"])  # one camera pose corrupted (NaN, scaled, sheared, far, ...) or the argument replaced
    exact = case["error"][1] in ("identity", "int")
    if isinstance(error, np.ndarray) and error.shape == (4, 4) and len(W):
        with np.errstate(all="ignore"):
            W = W.astype(np.result_type(W, error))
            W[0] = W[0] @ error
    elif not isinstance(error, np.ndarray) or error.shape != (4, 4):
        W = error
    cams = np.linalg.inv(W) if case["target_views"] and isinstance(W, np.ndarray) and W.dtype.kind == "f" and W.ndim == 3 \
        and W.shape[1:] == (4, 4) and np.all(np.isfinite(W)) else W
    robot = _he_arg(A, case["arg"])
    settings = {k: case[k] for k in ("rotation_weight", "huber_delta", "max_iterations", "refine", "min_relative_rotation",
                                     "step_tolerance")}
    r = call(calibration.calibrate_hand_eye, robot, cams if case["target_views"] else None,
             T_world_camera=None if case["target_views"] else cams, **settings)
    if r is None or r.status != "ok":
        return
    Xe = np.asarray(r.T_flange_camera, dtype=float)
    finite(Xe, "T_flange_camera")
    if np.abs(Xe[:3, :3].T @ Xe[:3, :3] - np.eye(3)).max() > 1e-9 or np.abs(Xe[3] - (0, 0, 0, 1)).max() > 0 \
            or np.linalg.det(Xe[:3, :3]) < 0:
        raise ContractError(f"calibrate_hand_eye ok with a non-rigid T_flange_camera {Xe.tolist()}")
    if case["n"] < 3 or len(A) < 3:
        raise ContractError(f"calibrate_hand_eye ok from {case['n']} poses (3 are needed)")
    typical = case["arg"] in ("ok", "list", "fortran", "strided", "object") and exact
    degenerate = case["motion"] in ("tiny", "parallel", "translation") and case["min_relative_rotation"] == 0.0872664626
    if typical and (case["motion"] == "general" or degenerate):
        STATS["truth_checks"] += 1
        err = np.abs(Xe - X).max()
        if not err <= 1e-6:
            raise ContractError(f"calibrate_hand_eye ok on exact {case['motion']} data but {err:.3g} from the true X")


# -- grasp planning --------------------------------------------------------------------------
_TOP = np.diag([1.0, -1.0, -1.0, 1.0])  # tool z down onto the part, 3 cm above its origin
_TOP[2, 3] = 0.03
_APPROACH = [(0.0, 0.0, 1.0)] * 3 + [(0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (NAN, 0.0, 0.0), (1e300, 0.0, 0.0),
                                     (1e-300, 0.0, 0.0), (0.0, 0.0, 7.0), (1.0, 2.0), "z", None]


def _grasp_list(wild: bool):
    pre = st.sampled_from([0.08, 0.05, 0.0] + ([-0.05, 1e300, NAN, INF, 1e-300, "0.08"] if wild else []))
    approach = st.sampled_from(_APPROACH if wild else _APPROACH[:3])
    yaw = st.sampled_from([0.0, 0.5, 2.0])
    return st.lists(st.tuples(yaw, approach, pre), min_size=1, max_size=3)


def _grasps(recipe):
    from scanalign import grasp
    out = []
    for yaw, approach, pre in recipe:
        T = _TOP @ se3_about_z(yaw)
        g = call(grasp.Grasp, f"g{len(out)}", T, None if approach is None else np.asarray(approach)
                 if not isinstance(approach, str) else approach, pre)
        if g is None:
            return None
        out.append(g)
    return out


def se3_about_z(angle):
    T = np.eye(4)
    T[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
    return T


_PLANES = [(0.0, 0.0, 1.0, 0.0)] * 4 + [(0.0, 0.0, 1.0, -0.4), (0.0, 0.0, 1.0, 5.0), (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 2.0, 0.0),
                                        (NAN, 0.0, 1.0, 0.0), (0.0, 0.0, 1.0, INF), (0.0, 0.0, 1.0), "table", None]
_QCUR = ["zeros", "home", "none"] + ["nan", "inf", "huge", "five", "seven", "complex", "str"]


def _q_current(kind):
    home = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])
    return {"zeros": np.zeros(6), "home": home, "none": None, "nan": np.r_[home[:5], NAN], "inf": np.r_[INF, home[1:]],
            "huge": home * 1e300, "five": home[:5], "seven": np.r_[home, 0.0], "complex": home.astype(complex),
            "str": "home"}[kind]


@target("grasp", robot=choice(["ur5", "kr6_r900_sixx", "ur99"], ["ur5", "kr6_r900_sixx"]),
        T=transforms("identity"), place=st.sampled_from([(0.45, 0.1), (0.3, -0.35), (0.55, 0.2), (3.0, 0.0)]),
        grasps=Param(_grasp_list(True), _grasp_list(False)), order=choice([1, 2, 6, 0, -1, 10**6, 2.5, "2"], [1, 2, 6]),
        plane=choice(_PLANES), q=choice(_QCUR, ["zeros", "home", "none"]),
        approach_step=numbers([0.005, 0.001, 0.02], 1e-9, 1e9), max_joint_step=numbers(0.1, 1e-9, 10.0),
        clearance=numbers([0.005, 0.0], -0.5), limits=choice([True, False], [True, False]))
def plan_grasp(case):
    """Truth: the frames compose as documented. Every "ok" candidate's joints reach its
    flange poses by FK (1e-9), its TCP pose is T_base_model S T_model_grasp (for a
    finite symmetry), and the plan is found iff some candidate is ok (and its best is one)."""
    from scanalign import grasp, kinematics
    T = build(case["T"])
    T_base_model = np.eye(4)
    T_base_model[:2, 3] = case["place"]
    if isinstance(T, np.ndarray) and T.shape == (4, 4):
        with np.errstate(all="ignore"):
            T_base_model = T_base_model @ T  # the part moved (or corrupted: NaN, scaled, sheared, complex)
    else:
        T_base_model = T
    grasps = _grasps(case["grasps"])
    sym = call(grasp.PartSymmetry, order=case["order"])
    if grasps is None or sym is None:
        return
    plan = call(grasp.plan_grasp, case["robot"], T_base_model, grasps, symmetry=sym, table_plane=case["plane"],
                q_current=_q_current(case["q"]), approach_step=case["approach_step"],
                max_joint_step=case["max_joint_step"], table_clearance=case["clearance"], respect_limits=case["limits"])
    if plan is None:
        return
    robot = kinematics.Robot.by_name(case["robot"])
    T_flange_tcp = np.asarray(grasp.Gripper.parallel_jaw().T_flange_tcp)
    S = sym.transforms() if sym.order >= 1 else None
    ok = [c for c in plan.candidates if c.reason == "ok"]
    if plan.found != bool(ok) or (plan.found and plan.best.reason != "ok"):
        raise ContractError(f"plan_grasp found={plan.found} with {len(ok)} ok candidates: {plan.message}")
    for c in ok:
        STATS["truth_checks"] += 1
        for q, T_flange in ((c.q_grasp, c.T_base_flange_grasp), (c.q_pregrasp, c.T_base_flange_pregrasp)):
            err = np.abs(robot.fk_flange(np.asarray(q)) - np.asarray(T_flange)).max()
            if not err < 1e-9:
                raise ContractError(f"an ok grasp candidate's joints miss its flange pose by {err:.3g}")
        tcp = np.asarray(T_base_model) @ (S[c.symmetry_index] if S is not None else np.eye(4)) \
            @ np.asarray(grasps[c.grasp_index].T_model_grasp)
        err = np.abs(robot.fk_flange(np.asarray(c.q_grasp)) @ T_flange_tcp - (tcp if S is not None else c.T_base_tcp_grasp)).max()
        if not err < 1e-9:
            raise ContractError(f"an ok grasp candidate's TCP is {err:.3g} from T_base_model S T_model_grasp")


_GRASP_TEXT_EDITS = [("", "")] * 4 + [("1.0", "2.0"), ("0.0", "NaN"), ("0.0", "1e400"), ("0.08", "-1"), ("\"order\"", "\"ordre\""),
                     ("order: 6", "order: 1000000"), ("grasps", "grasp"), ("[", ""), ("0.03", "\"x\""), ("6", "2.5"),
                     ("name", "T_model_grasp"), ("1.0", "true"), ("0.0", "null")]


@target("grasp", which=st.sampled_from(["part.json", "part.yaml", "missing.json", "part.txt"]),
        text=st.sampled_from(_GRASP_TEXT_EDITS), edits=st.one_of(st.just([]), _EDITS))
def read_part_grasps(case):
    """Mutated grasp files: a result, a ValueError naming the file, or OSError only; a grasp
    read holds a finite rigid T_model_grasp and a finite approach."""
    import tempfile

    from scanalign import grasp
    part = grasp.PartGrasps("standoff", [grasp.Grasp("top", _TOP, pre_grasp_distance=0.08),
                                         grasp.Grasp("side", _TOP @ se3_about_z(0.5), approach=np.array([0.0, 0.0, 1.0]))],
                            symmetry=grasp.PartSymmetry(order=6), gripper=grasp.Gripper.parallel_jaw(), mesh="builtin:standoff")
    with tempfile.TemporaryDirectory() as tmp:
        src = f"{tmp}/{case['which'].replace('missing', 'part').replace('.txt', '.json')}"
        grasp.write_part_grasps(src, part)
        data = open(src, "rb").read().replace(*(s.encode() for s in case["text"]), 1)  # the first occurrence
        path = f"{tmp}/{case['which']}"
        if case["which"] != "missing.json":
            with open(path, "wb") as fh:
                fh.write(_mutate(data, case["edits"]))
        try:
            r = grasp.read_part_grasps(path)
        except (ValueError, OSError) as exc:
            STATS["refused"] += 1
            if isinstance(exc, ValueError) and path not in str(exc):
                raise ContractError(f"read_part_grasps: a ValueError that does not name the file: {exc}") from exc
            return
        except Exception as exc:  # noqa: BLE001 - anything else from a file reader is a finding
            raise ContractError(f"read_part_grasps raised {type(exc).__name__}: {exc}") from exc
    STATS["returned"] += 1
    STATS["truth_checks"] += 1
    for g in r.grasps:
        T, a = np.asarray(g.T_model_grasp), np.asarray(g.approach)
        finite(T, "T_model_grasp")
        finite(a, "approach")
        if np.abs(T[:3, :3].T @ T[:3, :3] - np.eye(3)).max() > 1e-6 or np.abs(T[3] - (0, 0, 0, 1)).max() > 1e-6:
            raise ContractError(f"read_part_grasps accepted a non-rigid T_model_grasp {T.tolist()}")


# -- the argument rule at the binding boundary (issue 26, item 6) -------------------------
# Each target below keeps one held-out finding fixed: valid input returns, the bad input
# named here raises a TypeError / ValueError naming the argument (and, for a dtype, the dtype).
def refused(fn, *args, names=(), exc=(TypeError, ValueError), **kwargs) -> None:
    """fn(*args, **kwargs) must raise one of `exc` whose message names each of `names`."""
    try:
        result = fn(*args, **kwargs)
    except exc as e:
        if re.match(r"[\w.]*\(\): incompatible function arguments", str(e)):
            raise ContractError(f"a signature dump instead of a message naming the argument: {e}") from e
        missing = [n for n in names if n not in str(e)]
        if missing:
            raise ContractError(f"{type(e).__name__} does not name {missing}: {e}") from e
        STATS["refused"] += 1
        return
    raise ContractError(f"accepted (expected {'/'.join(x.__name__ for x in exc)} naming {list(names)}): "
                        f"returned {type(result).__name__}")


def accepted(fn, *args, **kwargs):
    """fn(*args, **kwargs) must return (valid input refused is a finding)."""
    try:
        result = fn(*args, **kwargs)
    except Exception as e:  # noqa: BLE001 - any refusal of valid input is the finding
        raise ContractError(f"valid input refused: {type(e).__name__}: {e}") from e
    STATS["returned"] += 1
    check_result(result)
    return result


def _cloud(n=60, seed=0):
    return build(("cloud", "corner", n, seed, 0.1, "none", "f8", "n3", "C"))


def _points_entries():
    """(label, argument name, call(points)) for entry points that take an (N, 3) cloud."""
    from scanalign import _core, cga, evaluation, features, fitting, pose, reconstruction, registration, segmentation
    v, f = _mesh("part")
    tgt = _cloud(80, 1)
    return [
        ("fit_sphere", "points", lambda p: fitting.fit_sphere(p)),
        ("ransac_plane", "points", lambda p: segmentation.ransac_plane(p, 0.01)),
        ("ransac_sphere", "points", lambda p: segmentation.ransac_sphere(p, 0.01)),
        ("ransac_cylinder", "points", lambda p: segmentation.ransac_cylinder(p, 0.01)),
        ("fit_cylinder", "points", lambda p: segmentation.fit_cylinder(p, (0, 0, 0), (0, 0, 1), 0.1)),
        ("cga.up", "points", lambda p: cga.up(p)),
        ("estimate_normals", "points", lambda p: features.estimate_normals(p, 0.05)),
        ("voxel_grid", "points", lambda p: reconstruction.voxel_grid(p, 0.01)),
        ("icp source", "source", lambda p: registration.icp(p, tgt, estimator="point_to_point")),
        ("Icp target", "target", lambda p: registration.Icp(p, estimator="point_to_point")),
        ("transform_points", "points", lambda p: _core.common.transform_points(np.eye(4), p)),
        ("point_to_mesh_distance", "points", lambda p: evaluation.point_to_mesh_distance(p, v, f)),
        ("alignment_fitness", "source", lambda p: pose.alignment_fitness(p, tgt, np.eye(4), 0.01)),
        ("sample_mesh", "vertices", lambda p: _core.common.sample_mesh(p, np.array([[0, 1, 2]]), 10, 0)),
    ]


_RULE_DTYPES = ["f8", "f4", ">f8", "<f4", "f2", "g", "c16", "?", "U4", "O", "i8"]


@target("arguments", which=st.integers(0, 13), dtype=st.sampled_from(_RULE_DTYPES))
def dtype_rule(case):
    """float32 / float64 (either byte order) points are accepted; float16, long double,
    complex, bool, strings and objects are a TypeError naming the argument and the dtype
    (README: other dtypes raise TypeError). Integer points too, except where integers are
    documented (mesh vertices)."""
    label, name, fn = _points_entries()[case["which"]]
    dtype = np.dtype(case["dtype"])
    with np.errstate(all="ignore"):
        # millimetres for integers, so integer mesh vertices still span a surface
        p = (_cloud() * (1000 if dtype.kind == "i" else 1)).astype(dtype) if dtype.kind != "U" else _cloud().astype("U4")
    if dtype.kind == "f" and dtype.itemsize in (4, 8) or (dtype.kind == "i" and label == "sample_mesh"):
        accepted(fn, p)
    else:
        refused(fn, p, names=(name, str(dtype)), exc=(TypeError,))


def _numeric_entries():
    """(label, argument name, call(value), a valid value) for scalar number arguments."""
    from scanalign import _core, features, reconstruction, registration, segmentation
    from scanalign.reconstruction import camera
    from scanalign.pose import model_views as cad
    from scanalign.data import parts
    p, tgt = _cloud(), _cloud(60, 1)
    intr = dict(width=32, height=24, fx=30.0, fy=30.0, cx=16.0, cy=12.0)
    return [
        ("voxel_grid", "leaf_size", lambda x: reconstruction.voxel_grid(p, leaf_size=x), 0.01),
        ("voxel_grid", "min_points_per_voxel", lambda x: reconstruction.voxel_grid(p, 0.01, min_points_per_voxel=x), 1),
        ("estimate_normals", "radius", lambda x: features.estimate_normals(p, radius=x), 0.05),
        ("estimate_normals", "min_neighbors", lambda x: features.estimate_normals(p, 0.05, min_neighbors=x), 3),
        ("point_to_plane_lls", "degeneracy_threshold",
         lambda x: registration.point_to_plane_lls(p, tgt, np.tile((0.0, 0.0, 1.0), (len(p), 1)), x), 1e-10),
        ("alignment_fitness", "threshold", lambda x: _core.registration.alignment_fitness(p, tgt, np.eye(4), x), 0.01),
        ("sample_mesh", "n_points", lambda x: parts.sample_mesh(_part(), x), 10),
        ("Intrinsics", "width", lambda x: camera.Intrinsics(**{**intr, "width": x}), 32),
        ("intrinsics_from_dict", "width", lambda x: camera.intrinsics_from_dict({**intr, "width": x}), 32),
        ("intrinsics_from_dict", "fx", lambda x: camera.intrinsics_from_dict({**intr, "fx": x}), 30.0),
        ("camera_from_dict", "height", lambda x: camera.camera_from_dict({**intr, "height": x}), 24),
        ("view_intrinsics", "resolution", lambda x: cad.view_intrinsics(x), 40),
        ("ransac_cylinder", "threshold", lambda x: segmentation.ransac_cylinder(p, x), 0.01),
        ("ransac_cylinder", "max_iterations", lambda x: segmentation.ransac_cylinder(p, 0.01, max_iterations=x), 50),
    ]


#: Arguments whose None means "the settings struct's default" (estimate_normals: NormalEstimationSettings.radius).
_NONE_IS_THE_DEFAULT = {("estimate_normals", "radius")}


@target("arguments", which=st.integers(0, 13),
        value=st.sampled_from(["valid", "valid", "0.01", "3", "", b"1", INF, -INF, NAN, 2**70, [1.0], None]))
def numbers_not_strings(case):
    """A number argument given a string is a TypeError naming it (never parsed, as float()
    would), an infinite or huge one a ValueError or TypeError naming it (never OverflowError)."""
    label, name, fn, valid = _numeric_entries()[case["which"]]
    value = case["value"]
    if isinstance(value, str) and value == "valid":
        accepted(fn, valid)
    elif isinstance(value, (str, bytes)):
        refused(fn, value, names=(name,), exc=(TypeError,))
    elif isinstance(valid, float) and isinstance(value, (int, float)):
        call(fn, value)  # a huge or non-finite length: refused or a (useless) result, never a crash or OverflowError
    elif value is None and (label, name) in _NONE_IS_THE_DEFAULT:
        accepted(fn, value)  # documented: None takes the settings struct's default
    else:
        refused(fn, value, names=(name,))  # a count: inf, NaN, 2**70, a list or None is refused, naming it


@target("arguments", scale=st.sampled_from([0.1, 1.0, 1e30, 1e-30, 1e18]),
        variant=st.sampled_from(["svd", "dual_quaternion", "point_to_plane_lls", "scanalign_point_to_plane_lls"]),
        corrupt=st.sampled_from(["none", "none", "nan_half", "huge_one"]), seed=st.integers(0, 99))
def pcl_baselines_converge_honestly(case):
    """A PCL baseline is never 'converged' without a correspondence at its final transform
    (1e30 m input: fitness 0) or with a non-finite transform."""
    from scanalign import registration
    rng = np.random.default_rng(case["seed"])
    with np.errstate(all="ignore"):
        src = _cloud(200, case["seed"]) / 0.1 * case["scale"]
        src = np.asarray(build(("cloud", "corner", 200, case["seed"], case["scale"], case["corrupt"], "f8", "n3", "C")))
        T = rigid_from(rng, 0.03, 0.01 * case["scale"])
        tgt = src @ T[:3, :3].T + T[:3, 3]
    normals = np.tile((0.0, 0.0, 1.0), (len(tgt), 1))
    r = call(registration.pcl_icp, src, np.nan_to_num(tgt, nan=np.nan, posinf=np.nan, neginf=np.nan), normals,
             variant=case["variant"], max_correspondence_distance=0.2 * min(case["scale"] * 10, 1.0))
    if r is not None and r.converged:
        if r.correspondence_count == 0 or not r.fitness > 0:
            raise ContractError(f"pcl_icp {case['variant']} converged with {r.correspondence_count} correspondences, "
                                f"fitness {r.fitness}")
        finite(r.T_target_source, "T_target_source")


@target("arguments", n=st.sampled_from([0, 1, 2, 6, 50]), corrupt=st.sampled_from(["none", "nan_all", "nan_half", "inf_one"]),
        normals=st.sampled_from(["unit", "zero", "nan"]))
def pcl_lls_inputs(case):
    """pcl_point_to_plane_lls: empty or all-non-finite input (no usable pair) is a ValueError,
    as icp refuses an empty cloud; otherwise a transform (finite when 6 or more usable pairs
    constrain it)."""
    from scanalign import registration
    n = case["n"]
    src = np.asarray(build(("cloud", "corner", n, 5, 0.1, case["corrupt"], "f8", "n3", "C"))).reshape(-1, 3)
    tgt = src + 0.001
    nrm = {"unit": np.tile((0.0, 0.0, 1.0), (n, 1)), "zero": np.zeros((n, 3)), "nan": np.full((n, 3), NAN)}[case["normals"]]
    usable = np.isfinite(src).all(axis=1) & np.isfinite(nrm).all(axis=1) & (np.abs(nrm).sum(axis=1) > 0)
    if not usable.any():
        refused(registration.pcl_point_to_plane_lls, src, tgt, nrm, names=("point-to-plane LLS",), exc=(ValueError,))
        refused(registration.icp, src, tgt, nrm, exc=(ValueError,)) if n == 0 else None
    else:
        accepted(registration.pcl_point_to_plane_lls, src, tgt, nrm)


@target("arguments", bad=st.sampled_from(["x", None, 3, {"max_iterations": 3}, "ok", "ok"]),
        field=st.sampled_from([("max_iterations", "x"), ("max_iterations", 2**70), ("max_correspondence_distance", "0.1"),
                               ("estimator", "nope"), ("max_iterations", 5)]))
def icp_settings_mutation(case):
    """Icp.settings given something else than an IcpSettings, or an IcpSettings field given a
    value of the wrong type: a TypeError / ValueError naming it, never AttributeError or a dump."""
    from scanalign import registration
    icp = registration.Icp(_cloud(), estimator="point_to_point")
    if case["bad"] == "ok":
        s = icp.settings
        name, value = case["field"]
        if value == 5:
            s.max_iterations = 5
            icp.settings = s
            accepted(icp.align, _cloud(60, 2))
        else:
            refused(setattr, s, name, value, names=(name,))
    else:
        refused(setattr, icp, "settings", case["bad"], names=("Icp.settings",), exc=(TypeError,))


@target("arguments", kind=st.sampled_from(["list", "tuple_rows", "array", "list", "ragged", "strings"]))
def icp_array_likes(case):
    """Icp accepts any (N, 3) array-like (a list of rows) like the other entry points; a
    ragged list or strings are a TypeError / ValueError naming the argument."""
    from scanalign import registration
    p = _cloud()
    value = {"list": p.tolist(), "tuple_rows": tuple(map(tuple, p.tolist())), "array": p,
             "ragged": [[0.0, 0.0, 0.0], [1.0, 2.0]], "strings": [["0", "0", "0"]] * 4}[case["kind"]]
    if case["kind"] in ("ragged", "strings"):
        refused(registration.Icp, value, estimator="point_to_point", names=("target",))
        return
    icp = accepted(registration.Icp, value, estimator="point_to_point")
    accepted(icp.align, value)
    accepted(registration.icp, value, value, estimator="point_to_point")


def _frame():
    from scanalign.reconstruction.camera import Frame, Intrinsics
    d = np.full((24, 32), 0.5, np.float32)
    d += np.linspace(0, 0.05, 32, dtype=np.float32)[None]
    return Frame(depth=d, intrinsics=Intrinsics(32, 24, 30.0, 30.0, 16.0, 12.0), depth_scale=1.0)


@target("arguments", weight=0.1, item=st.sampled_from(["frame", "frame", "points", "none", "str", "dict"]))
def reconstruct_non_frames(case):
    """reconstruct() given an iterable yielding something other than a Frame: a TypeError
    naming frames (never AttributeError)."""
    from scanalign.pipelines import reconstruct as pipeline
    item = {"frame": None, "points": _cloud(), "none": None, "str": "frame.png", "dict": {"depth": None}}[case["item"]]
    frames = [_frame(), _frame()] if case["item"] == "frame" else [_frame(), item]
    if case["item"] == "frame":
        accepted(pipeline.reconstruct, frames, progress=False, evaluate=False)
    else:
        refused(pipeline.reconstruct, frames, progress=False, evaluate=False, names=("frames",), exc=(TypeError,))


# -- the entry points added last (issue 26): bad shapes, dtypes, NaN/inf, huge sizes -------
_MATS = ["identity", "small", "small", "nan", "inf", "scaled", "3x4", "flat16", "complex", "list", "none", "str",
         "int", "f2", "strings"]


def _mat(kind, seed=0):
    if kind == "f2":
        return np.eye(4, dtype=np.float16)
    if kind == "strings":
        return np.eye(4).astype("U4")
    return build(("transform", kind, seed))


@target("new_entry_points", T=st.sampled_from(_MATS), points=clouds(300).wild)
def transform_and_rigid(case):
    from scanalign import _core
    T = _mat(case["T"])
    r = call(_core.common.transform_points, T, build(case["points"]))
    if r is not None and case["T"] in ("f2", "strings", "complex"):
        raise ContractError(f"transform_points accepted a {case['T']} T")
    call(_core.common.rigid_problem, T)


_VEC3 = [(1.0, 0.0, 0.5)] * 3 + [(0.0, 0.0, 0.0), (NAN, 0, 0), (INF, 0, 0), (1e300, 0, 0), (1, 2), ("1", "2", "3"),
                                  (1j, 0, 0), None, "xyz"]


@target("new_entry_points", eye=st.sampled_from(_VEC3), tgt=st.sampled_from([(0.0, 0.0, 0.0)] * 3 + _VEC3),
        up=st.sampled_from([(0.0, 0.0, 1.0)] * 3 + _VEC3))
def look_at(case):
    from scanalign import _core
    r = call(_core.common.look_at, case["eye"], case["tgt"], case["up"])
    if r is not None:
        finite(r, "look_at")
        if any(isinstance(v, tuple) and any(isinstance(x, (str, complex)) for x in v) for v in case.values()):
            raise ContractError(f"look_at accepted strings or complex numbers: {case}")


@target("new_entry_points", vert=choice(["ok", "ok", "nan", "f2", "2d", "int", "strings", "empty"]),
        faces=choice(["ok", "ok", "bad_index", "neg_index", "float", "empty"]),
        n=counts(50, 10**12, 2**40, 2**41), seed=counts(0, -1, 2**64))
def sample_mesh(case):
    from scanalign import _core
    v, f = _mesh("part")
    v = {"ok": v, "nan": np.where(np.arange(len(v))[:, None] == 0, NAN, v), "f2": v.astype(np.float16), "2d": v[:, :2],
         "int": np.rint(v * 100).astype(np.int64), "strings": v.astype("U6"), "empty": v[:0]}[case["vert"]]
    f = {"ok": f, "bad_index": np.where(f == 0, 10**6, f), "neg_index": f - 1, "float": f.astype(float) + 0.5,
         "empty": f[:0]}[case["faces"]]
    r = call(_core.common.sample_mesh, v, f, case["n"], case["seed"])
    if r is not None:
        finite(r[0], "samples")
        if case["vert"] in ("f2", "strings"):
            raise ContractError(f"sample_mesh accepted {case['vert']} vertices")
    s = call(_core.synthetic.sample_builtin_block, case["n"], case["seed"])
    if s is not None:
        finite(s[0], "block samples")


@target("new_entry_points", src=clouds(300), tgt=clouds(300), T=st.sampled_from(_MATS), thr=numbers(0.01), threads=counts(0, 5000))
def alignment_fitness(case):
    from scanalign import _core
    r = call(_core.registration.alignment_fitness, build(case["src"]), build(case["tgt"]), _mat(case["T"]), case["thr"],
             case["threads"])
    if r is not None:
        finite(r[0], "fitness")


@target("new_entry_points", T=st.sampled_from(_MATS), T2=st.sampled_from(_MATS),
        order=st.sampled_from([1, 2, 6, 0, -1, 2**40]), axis=st.sampled_from(_VEC3))
def symmetric_pose_error(case):
    from scanalign import _core, grasp
    sym = call(grasp.PartSymmetry, axis=case["axis"], order=case["order"])
    if sym is not None:
        r = call(_core.pose.symmetric_pose_error, _mat(case["T"]), _mat(case["T2"], 1), sym)
        if r is not None:
            finite(r, "symmetric pose error")


_SCENE = ["ok"] * 3 + ["nan_vertex", "f2_vertex", "bad_T", "complex_T", "no_tuple", "bad_albedo", "strings_faces", "empty"]


@target("new_entry_points", obj=choice(_SCENE), table=choice([None, (0.6, 0.4), (NAN, 1), (1e300, 1), "big", (1,)]),
        light=st.sampled_from([(0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (NAN, 0, 0), (1j, 0, 0), ("1", "0", "0")]),
        ambient=numbers(0.2), depth=choice(["ok", "ok", "f2", "wrong", "nan"]), T=st.sampled_from(_MATS))
def scene(case):
    """compose_scene -> scene_colors -> shade_scene (the synthetic scene of a scan)."""
    from scanalign import _core
    from scanalign.reconstruction.camera import Intrinsics
    v, f = _mesh("part")
    T = np.eye(4)
    T[2, 3] = 0.5
    obj = {"ok": (v, f, T, (0.5, 0.5, 0.5)), "nan_vertex": (np.where(np.arange(len(v))[:, None] == 0, NAN, v), f, T, (0.5,) * 3),
           "f2_vertex": (v.astype(np.float16), f, T, (0.5,) * 3), "bad_T": (v, f, T * 2, (0.5,) * 3),
           "complex_T": (v, f, T + 1j, (0.5,) * 3), "no_tuple": [v, f, T, (0.5,) * 3], "bad_albedo": (v, f, T, (NAN, 0, 0)),
           "strings_faces": (v, f.astype("U4"), T, (0.5,) * 3), "empty": (v[:0], f[:0], T, (0.5,) * 3)}[case["obj"]]
    table = case["table"]
    d = call(_core.synthetic.compose_scene, [obj], table, (0.0, 0.0), 0.0, (0.8, 0.8, 0.8))
    if d is None:
        return
    if case["obj"] in ("f2_vertex", "complex_T", "strings_faces"):
        raise ContractError(f"compose_scene accepted {case['obj']}")
    c = call(_core.synthetic.scene_colors, d["normals"], d["albedo"], d["owner"], d["n_object_faces"], case["light"],
             case["ambient"], (0.2, 0.2, 0.2))
    if c is None:
        return
    K = Intrinsics(32, 24, 30.0, 30.0, 16.0, 12.0)
    fid = np.zeros((24, 32), np.int32)
    z = {"ok": np.full((24, 32), 0.5, np.float32), "f2": np.full((24, 32), 0.5, np.float16), "wrong": np.zeros((3, 3), np.float32),
         "nan": np.full((24, 32), NAN, np.float32)}[case["depth"]]
    call(_core.synthetic.shade_scene, c[0], c[1], d["n_object_faces"], fid, z, K, _mat(case["T"]), (0.0, 0.0), 0.05)


@target("new_entry_points", vert=choice(["ok", "ok", "f4", "nan", "f2", "int", "2d"]), T=st.sampled_from(_MATS),
        size=st.sampled_from([(32, 24), (32, 24), (1, 1), (40000, 10), (2**31 - 1, 2)]),
        near=numbers(0.01), far=numbers(INF))
def render_depth(case):
    from scanalign import _core
    from scanalign.reconstruction.camera import Intrinsics
    v, f = _mesh("part")
    v = {"ok": v, "f4": v.astype(np.float32), "nan": np.where(np.arange(len(v))[:, None] == 0, NAN, v),
         "f2": v.astype(np.float16), "int": v.astype(np.int64), "2d": v[:, :2]}[case["vert"]]
    K = call(Intrinsics, case["size"][0], case["size"][1], 30.0, 30.0, 16.0, 12.0)
    s = call(_core.reconstruction.DepthRenderSettings, near_clip=case["near"], far_clip=case["far"])
    if K is None or s is None:
        return
    T = _mat(case["T"])
    if isinstance(T, np.ndarray) and T.shape == (4, 4) and T.dtype.kind == "f":
        T = T.copy()
        T[2, 3] += 0.5
    r = call(_core.reconstruction.render_depth, v, f, K, T, s)
    if r is not None and case["T"] in ("f2", "strings", "complex"):
        raise ContractError(f"render_depth accepted a {case['T']} T_camera_world")


_CHAINS = ["ok"] * 4 + ["nan", "f2", "5", "strings", "axes_zero", "axes_bad", "limits_bad", "tip_bad", "huge"]


@target("new_entry_points", chain=choice(_CHAINS), q=choice(["ok", "ok", "batch", "nan", "five", "f2", "str", "huge_batch"]),
        tcp=st.booleans(), threads=counts(0, 5000))
def joint_chain_robot(case):
    from scanalign import kinematics
    ur5 = kinematics.ur5()
    origins, axes = np.tile(np.eye(4), (6, 1, 1)), np.tile((0.0, 0.0, 1.0), (6, 1))
    origins[1:, 2, 3] = 0.1
    origins[2:, 0, 3] = 0.2
    axes[1:3] = (0.0, 1.0, 0.0)
    args = dict(origins=origins, axes=axes)
    kind = case["chain"]
    if kind == "nan":
        args["origins"] = np.where(np.arange(4)[:, None] == 0, NAN, origins)
    elif kind == "f2":
        args["origins"] = origins.astype(np.float16)
    elif kind == "5":
        args = dict(origins=origins[:5], axes=axes[:5])
    elif kind == "strings":
        args["axes"] = axes.astype("U4")
    elif kind == "axes_zero":
        args["axes"] = np.zeros((6, 3))
    elif kind == "axes_bad":
        args["axes"] = axes[:, :2]
    elif kind == "limits_bad":
        args["limits"] = np.tile((1.0, -1.0), (6, 1))
    elif kind == "tip_bad":
        args["T_joint6_tip"] = np.eye(4) * 2
    elif kind == "huge":
        args["origins"] = origins * 1e300
    robot = call(kinematics.Robot.from_joint_chain, **args)
    if robot is not None and kind in ("f2", "strings"):
        raise ContractError(f"from_joint_chain accepted {kind}")
    robot = robot or ur5
    q = {"ok": np.zeros(6), "batch": np.zeros((5, 6)), "nan": np.full(6, NAN), "five": np.zeros(5), "f2": np.zeros(6, np.float16),
         "str": "home", "huge_batch": np.broadcast_to(np.zeros(6), (10**5, 6))}[case["q"]]
    r = call(robot.joint_positions, q, tcp=case["tcp"], num_threads=case["threads"])
    if r is not None and case["q"] in ("f2", "str"):
        raise ContractError(f"joint_positions accepted a {case['q']} q")


# -- own parts and sample recordings (issue 27) -------------------------------------------------


@target("own_parts", T=st.sampled_from(_MATS), scale=numbers([1.0, 0.001]), order=choice([6, 1, 2, 4, 5, 0, -1, 2.5]),
        axis=st.sampled_from([(0.0, 0.0, 1.0)] * 3 + _VEC3), point=st.sampled_from([(0.0, 0.0, 0.0)] * 3 + _VEC3))
def load_part_file(case):
    """A part file with any T_model_mesh, scale and symmetry: a part, or a ValueError / TypeError;
    a loaded part's mesh is the built-in standoff scaled then moved by T_model_mesh (1e-9), and its
    symmetry maps that mesh onto itself (the standoff is a hexagonal prism about its z axis)."""
    import json
    import tempfile

    from scanalign.common.rigid import transform_points
    from scanalign.data.parts import builtin_mesh
    from scanalign.grasp.parts import load_part
    T = _mat(case["T"])
    T_json = T.tolist() if isinstance(T, np.ndarray) and T.dtype.kind in "fiu" else T
    data = {"name": "p", "mesh": "builtin:standoff", "scale": case["scale"],
            "symmetry": {"order": case["order"], **{k: list(v) if isinstance(v, tuple) else v
                                                     for k, v in (("axis", case["axis"]), ("point", case["point"]))}},
            "grasps": [{"name": "top", "T_model_grasp": np.eye(4).tolist()}]}
    if T_json is not None:
        data["T_model_mesh"] = T_json
    with tempfile.TemporaryDirectory() as tmp:
        path = f"{tmp}/p.json"
        try:
            with open(path, "w") as f:
                json.dump(data, f)
        except (TypeError, ValueError):
            return  # not JSON (a complex matrix): nothing to read
        part = call(load_part, path)
    if part is None:
        return
    expected = np.asarray(builtin_mesh(name="standoff").vertices) * float(case["scale"])
    if isinstance(T, np.ndarray) and T.shape == (4, 4):
        expected = transform_points(np.asarray(T, dtype=np.float64), expected)
    STATS["truth_checks"] += 1
    if not np.allclose(part.mesh.vertices, expected, rtol=0, atol=1e-9 * max(1.0, float(np.abs(expected).max()))):
        raise ContractError("load_part: the mesh is not the built-in standoff scaled and moved by T_model_mesh")


@target("own_parts", weight=0.3, n=st.sampled_from([3, 3, 0, 1]), fmt=st.sampled_from(["ros1", "ros2", "png", "png"]),
        depth_scale=numbers([None, 0.001, 0.000125]), exists=st.booleans())
def write_recording(case):
    """write_bag / write_image_folder: a recording that open_source reads back with the same
    frames, poses (1e-6 m) and depth (half a depth unit), or a ValueError / OSError / TypeError."""
    import os
    import tempfile

    from scanalign.datasets import open_source, sources
    frames = _recording_frames()[:case["n"]]
    with tempfile.TemporaryDirectory() as tmp:
        path = f"{tmp}/rec.bag" if case["fmt"] == "ros1" else f"{tmp}/rec"
        if case["exists"]:
            os.makedirs(path) if case["fmt"] != "ros1" else open(path, "w").close()
        if case["fmt"] == "png":
            out = call(sources.write_image_folder, path, frames, depth_scale=case["depth_scale"])
        else:
            out = call(sources.write_bag, path, frames) if case["depth_scale"] is None else None
        if out is None:
            return
        back = call(open_source, path)
        if back is None:
            return
        STATS["truth_checks"] += 1
        if len(back) != len(frames):
            raise ContractError(f"{case['fmt']}: {len(frames)} frames written, {len(back)} read back")
        for a, b in zip(frames, back):
            unit = float(b.depth_scale)
            if a.T_base_camera is not None and b.T_base_camera is not None and \
                    np.abs(np.asarray(a.T_base_camera) - np.asarray(b.T_base_camera)).max() > 1e-6:
                raise ContractError(f"{case['fmt']}: a pose changed on the way through the file")
            ok = np.isfinite(a.depth) & (a.depth > 0)
            got = np.asarray(b.depth, dtype=np.float64) * unit
            want = np.asarray(a.depth, dtype=np.float64) * float(a.depth_scale)
            if np.abs(got[ok] - want[ok]).max() > 0.5 * unit + 1e-12:
                raise ContractError(f"{case['fmt']}: depth differs by more than half a unit")


@functools.lru_cache(maxsize=1)
def _recording_frames():
    from scanalign import synthetic
    return synthetic.SyntheticConfig(n_frames=3, resolution_scale=0.25, noise="none").build().frames


# -- the two-step pose's 2D step (Kleppe et al. 2017, Paper 3) ----------------------------------------------------
_HOMOGRAPHIES = ["exact", "exact", "scaled", "random", "zero", "nan", "inf", "huge", "3x4", "strings", "none"]


def _homography(kind, seed, geometry, camera, part):
    from scanalign.pose.image_matching import homography_of_part
    from scanalign.synthetic.hand_camera import WEBCAM
    rng = np.random.default_rng(seed)
    H = homography_of_part(geometry, WEBCAM, camera, part)
    with np.errstate(invalid="ignore", over="ignore"):
        return {"exact": H, "scaled": -3.0 * H, "random": rng.normal(size=(3, 3)), "zero": np.zeros((3, 3)),
                "nan": np.where(rng.random((3, 3)) < 0.2, NAN, H), "inf": H * INF, "huge": H * 1e300,
                "3x4": H[:, :2], "strings": H.astype("U5"), "none": None}[kind]


@target("two_step", H=choice(_HOMOGRAPHIES), seed=st.integers(0, 2**16), rough=transforms(),
        scale=numbers(5000.0), top=numbers(0.025), width=counts(300), max_scale=numbers(0.15))
def planar_pose_from_homography(case):
    from scanalign.grasp import camera_above
    from scanalign.pose.image_matching import HomographyPoseSettings, ReferenceImageGeometry
    from scanalign.pose.image_matching import planar_pose_from_homography as pose_of
    from scanalign.synthetic.hand_camera import WEBCAM
    part = np.eye(4)
    part[:3, 3] = (0.45, 0.1, 0.0)
    camera = camera_above(part, 0.025, 0.18, 0.3)
    good = ReferenceImageGeometry(width=300, height=200, pixels_per_metre=5000.0, origin_pixel=(149.5, 99.5),
                                  top_height=0.025)
    H = _homography(case["H"], case["seed"], good, camera, part)
    g = call(ReferenceImageGeometry, width=case["width"], height=200, pixels_per_metre=case["scale"],
             origin_pixel=(149.5, 99.5), top_height=case["top"])
    s = call(HomographyPoseSettings, max_scale_error=case["max_scale"])
    if g is None or s is None:
        return
    rough = build(case["rough"])
    if isinstance(rough, np.ndarray) and rough.shape == (4, 4) and rough.dtype.kind == "f":  # moved to the part
        rough = rough.copy()
        rough[:3, 3] += part[:3, 3]
    r = call(pose_of, H, g, WEBCAM, camera, rough, s)
    if r is None or r.status != "ok":
        return
    finite(r.T_base_part, "T_base_part")
    if not (0 <= r.p0[0] < WEBCAM.width and 0 <= r.p0[1] < WEBCAM.height):
        raise ContractError(f"status ok with the part origin at pixel {r.p0}, outside the image")
    moved_part = isinstance(rough, np.ndarray) and rough.shape == (4, 4) and rough.dtype.kind == "f"
    if case["H"] in ("exact", "scaled") and g.pixels_per_metre == 5000.0 and g.width == 300 and g.top_height == 0.025 \
            and moved_part and np.allclose(rough[2, 3], 0.0):
        if np.abs(r.T_base_part[:2, 3] - part[:2, 3]).max() > 1e-9:
            raise ContractError(f"the exact homography gave {r.T_base_part[:2, 3]}, not {part[:2, 3]}")


_IMAGES = ["label", "label", "noise", "flat", "tiny", "empty", "nan", "rgb", "rgba", "int16", "strings", "3d", "none"]


def _image(kind, seed):
    from scanalign.synthetic.hand_camera import top_label
    rng = np.random.default_rng(seed)
    img = top_label(seed=seed % 7).image
    return {"label": img, "noise": rng.integers(0, 255, (120, 160)).astype(np.uint8), "flat": np.full((64, 64), 128),
            "tiny": img[:5, :5], "empty": img[:0], "nan": np.where(rng.random(img.shape) < 0.01, NAN, img * 1.0),
            "rgb": np.repeat(img[..., None], 3, axis=2), "rgba": np.repeat(img[..., None], 4, axis=2),
            "int16": img.astype(np.int16) - 300, "strings": img.astype("U3"), "3d": img[None], "none": None}[kind]


@target("two_step", weight=0.5, ref=choice(_IMAGES), img=choice(_IMAGES), seed=st.integers(0, 2**16),
        detector=choice(["sift", "orb", "akaze", "surf", ""]), ratio=numbers(0.75, 1.5),
        threshold=numbers(2.0), inliers=counts(10, 3, 4))
def match_reference(case):
    from scanalign.pose.image_matching import match_reference as match
    r = call(match, _image(case["ref"], case["seed"]), _image(case["img"], case["seed"] + 1),
             detector=case["detector"], ratio=case["ratio"], ransac_threshold=case["threshold"],
             min_inliers=case["inliers"])
    if r is None or r.status != "ok":
        return
    finite(r.H_image_reference, "H_image_reference")
    if r.inliers < case["inliers"]:
        raise ContractError(f"status ok with {r.inliers} inliers, below min_inliers {case['inliers']}")


@target("two_step", weight=0.5, part=transforms(), top=numbers(0.025), height=numbers(0.18),
        steps=counts(4, 361), q=choice(["home", "home", "nan", "short", "huge"]))
def plan_camera_view(case):
    from scanalign.grasp import hand_camera_mount, plan_camera_view as plan
    part = build(case["part"])
    if isinstance(part, np.ndarray) and part.shape == (4, 4) and part.dtype.kind == "f":  # in front of the robot
        part = part.copy()
        part[:3, 3] += (0.45, 0.1, 0.0)
    q = {"home": [0.0, -1.57, 1.57, -1.57, -1.57, 0.0], "nan": [NAN] * 6, "short": [0.0] * 5,
         "huge": [1e300] * 6}[case["q"]]
    r = call(plan, "ur5", part, case["top"], camera_mount=hand_camera_mount(np.eye(4)), q_current=q,
             height=case["height"], yaw_steps=case["steps"])
    if r is None or not r.found:
        return
    finite(r.q, "q")
    if abs(r.T_base_camera[2, 2] + 1.0) > 1e-9:
        raise ContractError("a planned view does not look straight down")


@target("synthetic", exponent=numbers(1.5, 4.5), flying=numbers(0.5, 1.0, 1.5), width=counts(1, 10**9),
        image=choice(["step", "step", "void", "nan", "tiny", "empty"]), seed=counts(0, 2**64))
def tof_sensor_noise(case):
    """The time-of-flight fields (axial_exponent, flying_pixels) on a step, a silhouette, NaN depth and odd sizes:
    a noisy depth image of the same shape, finite or NaN, or a ValueError naming the field."""
    from scanalign import _core
    noise = call(_core.synthetic.SensorNoise, axial_sigma_ref=0.0015, axial_exponent=case["exponent"],
                 flying_pixels=case["flying"], edge_threshold=0.03, edge_width=case["width"])
    if noise is None:
        return
    z = np.full((40, 60), 1.0, np.float32)
    z[:, 30:] = {"step": 1.5, "void": NAN, "nan": NAN, "tiny": 1.5, "empty": 1.5}[case["image"]]
    if case["image"] == "nan":
        z[::7, ::5] = NAN
    z = {"tiny": z[:1, :2], "empty": z[:0]}.get(case["image"], z)
    out = call(_core.synthetic.apply_sensor_noise, noise, z, np.ones_like(z), case["seed"])
    if out is None:
        return
    if out.shape != z.shape or np.isinf(out).any() or (np.isfinite(out) & (out <= 0)).any():
        raise ContractError(f"apply_sensor_noise gave shape {out.shape}, an infinite or a non-positive depth")


# -- the assembly (Paper 3): part-file fields, the upright pose, the pipeline on odd clouds -------------------------
_FIELD_VALUES = [1.0, 5000, 0.02, -1, 0, NAN, INF, "x", None, [0.02, 0.02], [0.02], [[1, 2]], True, {"a": 1}, ""]


@target("two_step", weight=0.5, image=choice(["builtin:label-3", "builtin:sparse-1", "builtin:plain", "builtin:x",
                                             "missing.png", 7, None]),
        ppm=choice([5000] + _FIELD_VALUES), top=choice([0.02] + _FIELD_VALUES),
        size=choice([[0.02, 0.03]] + _FIELD_VALUES), origin=choice([None] + _FIELD_VALUES),
        onto=choice(["bracket", "", 3, None]), T=choice(["eye", "scaled", "nan", "short", "strings"]),
        tol=choice([0.001] + _FIELD_VALUES),
        extra=choice([None, "colour"]))
def part_file_fields(case):
    """A part file with odd reference_image / assembly fields: read and loaded, or a ValueError naming the field; a
    loaded image has the size the fields give."""
    import json
    import tempfile
    from pathlib import Path

    from scanalign.grasp import read_part_grasps
    from scanalign.grasp.parts import BUILTIN_PART_FILES, load_part
    data = json.loads(BUILTIN_PART_FILES["standoff"].read_text())
    ref = {"image": case["image"], "pixels_per_metre": case["ppm"], "top_height": case["top"], "size": case["size"]}
    if case["origin"] is not None:
        ref["origin_pixel"] = case["origin"]
    if case["extra"]:
        ref[case["extra"]] = 1
    T = {"eye": np.eye(4).tolist(), "scaled": (2 * np.eye(4)).tolist(), "nan": np.full((4, 4), NAN).tolist(),
         "short": [[1, 0, 0]], "strings": "eye"}[case["T"]]
    data["reference_image"] = ref
    data["assembly"] = {"onto": case["onto"], "T_onto_part": T, "tolerance_translation": case["tol"]}
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "p.json"
        try:
            path.write_text(json.dumps(data))
        except ValueError:  # NaN is valid JSON for Python; nothing else fails here
            return
        part = call(read_part_grasps, path)
        if part is None:
            return
        loaded = call(load_part, path)
        if loaded is None:
            return
        r = loaded.reference_image
        h, w = r.image.shape
        if (w, h) != tuple(int(round(v * r.pixels_per_metre)) for v in r.size):
            raise ContractError(f"a {w}x{h} px label for {r.size} m at {r.pixels_per_metre} px/m")


@target("two_step", weight=0.5, T=transforms(), plane=choice(["up", "tilted", "wall", "nan", "short", "strings"]))
def upright_on_table(case):
    from scanalign.grasp.parts import load_part
    from scanalign.pipelines.assemble import upright_on_table as upright
    plane = {"up": [0.0, 0.0, 1.0, -0.01], "tilted": [0.05, 0.0, 0.9987492, 0.0], "wall": [1.0, 0.0, 0.0, 0.0],
             "nan": [NAN, 0.0, 1.0, 0.0], "short": [0.0, 1.0], "strings": "up"}[case["plane"]]
    mesh = load_part("standoff").mesh
    U = call(upright, build(case["T"]), mesh, plane)
    if U is None or not np.isfinite(U).all():
        return
    if not np.allclose(U[:3, 2], [0, 0, 1]) or abs(np.linalg.det(U[:3, :3]) - 1) > 1e-9:
        raise ContractError(f"not upright: {U}")


@target("two_step", weight=0.1, cloud=clouds(max_size=5000), part=choice(["standoff", "block", "nowhere", None]),
        steps=counts(4), height=numbers(0.12))
def assemble(case):
    """The assembly pipeline on any cloud: a status (not_found, refine_failed, ...) or a ValueError, never a crash; a
    plan only with both parts refined."""
    from scanalign.pipelines.assemble import assemble as run
    from scanalign.synthetic.assembly_cell import assembly_cell
    cell = _ASSEMBLY_CELL.get("cell") or _ASSEMBLY_CELL.setdefault("cell", assembly_cell(seed=0))
    r = call(run, build(case["cloud"]), case["part"], capture=cell.capture, gripper_robot=cell.gripper_robot,
             camera_robot=cell.camera_robot, T_flange_camera=cell.T_flange_camera, intrinsics=cell.intrinsics,
             refine_2d={"max_steps": case["steps"]}, view={"height": case["height"]})
    if r is None:
        return
    if r.status == "planned" and any(p.status != "refined" for p in r.parts.values()):
        raise ContractError(f"planned with parts {[(n, p.status) for n, p in r.parts.items()]}")


_ASSEMBLY_CELL: dict = {}
