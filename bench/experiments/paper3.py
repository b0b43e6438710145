"""Thesis Paper 3 (A. L. Kleppe, A. Bjørkedal, K. Larsen, O. Egeland, "Automated assembly using 3D and 2D cameras",
Robotics 6 (2017) 14, in Kleppe, PhD thesis, NTNU 2018): its three experiments on scanalign's synthetic two-robot cell
(scanalign.synthetic.assembly_cell: a Kinect One-like time-of-flight camera behind the table, a gripper arm and a
camera arm with a webcam, both KR6 R900 sixx).

* Experiment 1 (Tables 1-4): the 3D step's accuracy at 16 grid positions, 10 runs each, for two objects.
* Experiment 2 (Tables 5-6): the 2D step's orientation stability at 0 and 90 degrees: the spread (max - min) of 25
  data points, each the mean of 10 measurements, SIFT against the paper's SIFT/SURF hybrid (here AKAZE and ORB, the
  free substitutes: SURF is patented and not in OpenCV's default build).
* Experiment 3: full assemblies of part A onto part B (the paper: 10 runs, 7 within 1 mm and 1 degree).

    python bench/reproduce.py [--quick] --only paper3
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np

from scanalign import pose
from scanalign.grasp import camera_above
from scanalign.grasp.parts import load_part
from scanalign.pipelines.assemble import AssemblySettings, assemble_cell, plan_pick_and_place
from scanalign.pipelines.pick import upper_views
from scanalign.pose.image_matching import refine_planar_pose
from scanalign.reconstruction.camera import INTRINSICS_PRESETS
from scanalign.synthetic.assembly_cell import (T_BASE_FIXED_CAMERA, assembly_cell, placement_error,
                                               score_assembly)
from scanalign.synthetic.hand_camera import WEBCAM, render_labels
from scanalign.synthetic.scan import render_scan
from scanalign.synthetic.scene import Scene

from . import Check, Log, Section, Timer

# Paper 3 Tables 1 and 3: actual (X, Y) cm -> the 3D step's measured (X, Y) cm, the mean of 10 runs (thesis.md §5;
# the "-5.17" of object A at (-5, 20) is printed so, its |dX| 1.28 implies -6.28).
PAPER_GRID = {
    "A": {(-5, 5): (-6.18, 5.4), (-5, 10): (-6.25, 10.55), (-5, 15): (-6.28, 16.11), (-5, 20): (-6.28, 21.56),
          (-10, 5): (-11.12, 5.08), (-10, 10): (-10.83, 10.43), (-10, 15): (-10.98, 15.92), (-10, 20): (-11.46, 20.85),
          (-15, 5): (-15.89, 5.2), (-15, 10): (-15.81, 10.56), (-15, 15): (-15.97, 15.77), (-15, 20): (-16.18, 21.01),
          (-20, 5): (-20.43, 5.4), (-20, 10): (-20.68, 10.72), (-20, 15): (-20.72, 16.27), (-20, 20): (-21.18, 21.38)},
    "B": {(-5, 5): (-5.76, 5.16), (-5, 10): (-6.12, 10.8), (-5, 15): (-5.98, 15.94), (-5, 20): (-6.17, 20.88),
          (-10, 5): (-10.65, 5.47), (-10, 10): (-10.62, 10.21), (-10, 15): (-10.73, 15.81), (-10, 20): (-10.91, 20.79),
          (-15, 5): (-15.22, 5.46), (-15, 10): (-15.46, 10.62), (-15, 15): (-15.71, 16.2), (-15, 20): (-15.85, 21.14),
          (-20, 5): (-20.1, 5.43), (-20, 10): (-20.73, 10.06), (-20, 15): (-20.26, 16.35), (-20, 20): (-21.43, 21.96)},
}
# Paper 3 Tables 5 and 6: spread (max - min, degrees) of 25 means of 10 orientation measurements.
PAPER_SPREAD = {("A", 0): (1.7469, 5.4994), ("A", 90): (1.1102, 7.9095),
                ("B", 0): (0.07888, 0.2041), ("B", 90): (0.1721, 0.1379)}
PAPER_ASSEMBLIES = (7, 10)
# Our stand-ins: object A of experiments 1 and 3 is the standoff (placed on the bracket, B); experiment 2's weakly
# textured object (the paper's A) is the block with its faint label, its textured one (the paper's B) the bracket.
GRID_OBJECTS = {"A": "standoff", "B": "bracket"}
STABILITY_OBJECTS = {"A": "block", "B": "bracket"}
DETECTORS = ("sift", "akaze", "orb")


def _command(quick: bool) -> str:
    return f"`python bench/reproduce.py{' --quick' if quick else ''} --only paper3`"


def _to_base(X: float, Y: float) -> Tuple[float, float]:
    """The paper's grid (cm, X -20..-5, Y 5..20) centred on our table (base frame, m)."""
    return 0.5 + (X + 12.5) / 100.0, (Y - 12.5) / 100.0


def _to_paper(x: float, y: float) -> Tuple[float, float]:
    return (x - 0.5) * 100.0 - 12.5, y * 100.0 + 12.5


# --- Experiment 1 -------------------------------------------------------------------------------------------------

def _detect_alone(name: str, xy: Tuple[float, float], seed: int, models: List[Any], names: List[str],
                  settings: Any) -> Tuple[bool, Tuple[float, float]]:
    """One run: the object alone on the table, the fixed camera's frame, find_parts among both objects. Returns
    (identified correctly, its measured (x, y) in m; NaN when not found)."""
    part = load_part(name)
    scene = Scene(table_size=(0.6, 0.6))
    scene.add_object(part.mesh, position=xy, yaw=0.0, name=name)
    scan = render_scan(scene, T_BASE_FIXED_CAMERA[None], INTRINSICS_PRESETS["kinect_one"], noise="kinect_one",
                       seed=seed, num_threads=1)
    d = pose.find_parts(models, scan.points(0, in_base=True), settings.find_parts,
                        symmetries=[load_part(n).symmetry for n in names], views=upper_views())
    # The 3D step's own verdict: a run counts when find_parts reports the right part as found; a not_found or
    # ambiguous detection is the step saying it failed (the assembly pipeline then lets the 2D step verify).
    for det in d.detections:
        if det.part >= 0 and names[det.part] == name and det.status.name == "found":
            T = np.asarray(det.pose.T_scene_model)
            return True, (float(T[0, 3]), float(T[1, 3]))
    return False, (math.nan, math.nan)


def _grid(quick: bool, log: Log, out: Path) -> Section:
    timer = Timer().__enter__()
    settings = AssemblySettings()
    names = [GRID_OBJECTS["A"], GRID_OBJECTS["B"]]
    models = [load_part(n).mesh for n in names]
    positions = [(-5, 5), (-20, 20)] if quick else list(PAPER_GRID["A"])
    runs = 2 if quick else 10
    ours: Dict[str, Dict[Tuple[int, int], Dict[str, Any]]] = {}
    for label, name in GRID_OBJECTS.items():
        ours[label] = {}
        for X, Y in positions:
            xy = _to_base(X, Y)
            found = [_detect_alone(name, xy, 100 * (X + 100) + Y * 7 + r, models, names, settings) for r in range(runs)]
            m = np.array([p for ok, p in found if ok])
            mean = m.mean(axis=0) if len(m) else np.full(2, math.nan)
            worst = np.abs(m - xy).max(axis=0) * 100 if len(m) else np.full(2, math.nan)
            off = int((np.linalg.norm(m - xy, axis=1) > 0.01).sum()) if len(m) else 0
            ours[label][X, Y] = {"identified": sum(ok for ok, _ in found), "runs": runs, "off_1cm": off,
                                 "measured": _to_paper(*mean), "worst_cm": worst}
        log(f"paper3 exp 1: object {label} ({name}) done")
    rows = ["| object | actual (X, Y) cm | paper: measured | paper: \\|ΔX\\|, \\|ΔY\\| | ours: measured (mean) | "
            "ours: \\|ΔX\\|, \\|ΔY\\| (mean) | ours: worst run | identified |", "|---|---|---|---|---|---|---|---|"]
    summary, checks, worst_all = [], [], 0.0
    for label in GRID_OBJECTS:
        dx_p = [abs(PAPER_GRID[label][k][0] - k[0]) for k in positions]
        dy_p = [abs(PAPER_GRID[label][k][1] - k[1]) for k in positions]
        dx_o, dy_o = [], []
        for k in positions:
            o, p = ours[label][k], PAPER_GRID[label][k]
            dx, dy = abs(o["measured"][0] - k[0]), abs(o["measured"][1] - k[1])
            dx_o.append(dx)
            dy_o.append(dy)
            worst_all = max(worst_all, float(np.nanmax(o["worst_cm"])) if np.isfinite(o["worst_cm"]).any() else 0.0)
            rows.append(f"| {label} ({GRID_OBJECTS[label]}) | ({k[0]}, {k[1]}) | ({p[0]:.2f}, {p[1]:.2f}) | "
                        f"{abs(p[0] - k[0]):.2f}, {abs(p[1] - k[1]):.2f} | ({o['measured'][0]:.2f}, "
                        f"{o['measured'][1]:.2f}) | {dx:.3f}, {dy:.3f} | {o['worst_cm'][0]:.3f}, {o['worst_cm'][1]:.3f} "
                        f"| {o['identified']}/{o['runs']} |")
        summary.append(f"| {label} | {max(dx_p):.2f} / {max(dy_p):.2f} | {min(dx_p):.2f} / {min(dy_p):.2f} | "
                       f"{np.nanmax(dx_o):.3f} / {np.nanmax(dy_o):.3f} | {np.nanmin(dx_o):.3f} / {np.nanmin(dy_o):.3f} |")
    identified = sum(o["identified"] for lab in ours.values() for o in lab.values())
    total = sum(o["runs"] for lab in ours.values() for o in lab.values())
    every = all(o["identified"] > 0 for lab in ours.values() for o in lab.values())
    worst_mean = max(max(abs(o["measured"][0] - k[0]), abs(o["measured"][1] - k[1]))
                     for lab in ours.values() for k, o in lab.items())
    off = sum(o["off_1cm"] for lab in ours.values() for o in lab.values())
    checks.append(Check("Paper 3, Exp. 1: the 3D step is within 2 cm at every grid position (the mean of its runs, as "
                        "the paper's tables)", worst_mean < 2.0 and every,
                        f"worst position {worst_mean:.3f} cm; {identified} of {total} runs found the object, {off} "
                        f"of them more than 1 cm off, the worst single run {worst_all:.3f} cm"))
    fig = out / "paper3_grid.png"
    _plot_grid(ours, positions, fig)
    timer.__exit__()
    md = [f"Made by {_command(quick)}.", "",
          f"Set-up: the paper's 16 positions (a 15 x 15 cm grid, 5 cm apart) centred on our table, {runs} runs each "
          "(the sensor noise redrawn), each object alone, yaw 0; the fixed camera's one depth frame (Kinect One-like: "
          "1 mm noise at 0.75 m, flying pixels at the edges), scanalign.pose.find_parts among both objects with "
          "AssemblySettings.find_parts (CBD, views from above, ICP); a run counts when find_parts reports the right "
          "part with status found (a not_found or ambiguous detection is the step saying it failed). Object A is the standoff (30 mm across flats), "
          "B the bracket (70 x 40 mm); the paper's objects are its own 3D-printed parts."
          + (f" Quick: {len(positions)} opposite corners, {runs} runs." if quick else ""), "",
          "**Tables 1-4** (cm; the paper's measured column is the mean of its 10 runs, as is ours):", "", *rows, "",
          "Max / min of \\|ΔX\\| / \\|ΔY\\| over the positions (cm):", "",
          "| object | paper max | paper min | ours max | ours min |", "|---|---|---|---|---|", *summary, "",
          f"Found in {identified} of {total} runs; {off} found runs lie more than 1 cm off (the worst "
          f"{worst_all:.2f} cm). The misses are spread over the grid, find_parts declining to choose rather than "
          "choosing wrong: on the standoff's 200 noisy points two of its own poses, a few degrees apart in tilt and "
          "under a millimetre apart in position, often score alike (ambiguous); the bracket, seen from behind its "
          "upright plate, is not_found when its well-scoring poses dip into the table or leave a third of the "
          "cluster off its surface. The assembly pipeline takes the best-scoring pose in such cases and lets the 2D "
          "step verify it.", "",
          "What differs: the paper's errors (0.1-2 cm) are mostly a bias of 0.4-1.5 cm in X and Y that grows with "
          "the distance from the camera: its Kinect's depth bias and extrinsic calibration. Our cell's camera pose "
          "is exact and its noise unbiased, so only the registration's error is left: a few millimetres in most "
          "runs. Both meet the paper's conclusion (under 2 cm at every position) "
          "and its point: the 3D step alone is far from the 1 mm an assembly needs."]
    return Section("Thesis Paper 3, Experiment 1 (Tables 1-4): the 3D step's accuracy on a 16-position grid",
                   "\n".join(md), [fig], checks, timer.seconds)


# --- Experiment 2 -------------------------------------------------------------------------------------------------

def _stability_point(part: Any, truth: np.ndarray, detector: str, rng: np.random.Generator, n: int,
                     seed: int) -> Tuple[float, int]:
    """One data point: the camera above a rough estimate (truth moved by up to 1 cm, turned by up to 5 deg), ``n``
    images with fresh noise; the mean of the measured yaws (deg) and the number of failed measurements."""
    ref = part.reference_image
    g = ref.geometry()
    r, a = 0.01 * math.sqrt(rng.uniform()), rng.uniform(0, 2 * math.pi)
    rough = truth.copy()
    rough[:2, 3] += [r * math.cos(a), r * math.sin(a)]
    cam = camera_above(rough, g.top_height, AssemblySettings().view.height, float(rng.uniform(-0.09, 0.09)))
    yaws, failed = [], 0
    for k in range(n):
        image = render_labels([(ref.image, g, truth)], cam, WEBCAM, seed=seed * 100 + k, colour=True)
        step = refine_planar_pose(image, ref.image, g, WEBCAM, cam, rough, matching={"detector": detector})
        if not step:
            failed += 1
            continue
        yaws.append(math.degrees(math.atan2(step.T_base_part[1, 0], step.T_base_part[0, 0])))
    return (float(np.mean(yaws)) if yaws else math.nan), failed


def _stability(quick: bool, log: Log, out: Path) -> Section:
    timer = Timer().__enter__()
    points, per_point = (4, 2) if quick else (25, 10)
    res: Dict[Tuple[str, int, str], Dict[str, float]] = {}
    for label, name in STABILITY_OBJECTS.items():
        part = load_part(name)
        for angle in (0, 90):
            truth = np.eye(4)
            truth[:2, :2] = [[math.cos(math.radians(angle)), -math.sin(math.radians(angle))],
                             [math.sin(math.radians(angle)), math.cos(math.radians(angle))]]
            truth[:3, 3] = [0.5, 0.0, -float(np.asarray(part.mesh.vertices)[:, 2].min())]
            for det in DETECTORS:
                rng = np.random.default_rng(angle + 7)  # the same camera poses for every detector
                means, failed = zip(*(_stability_point(part, truth, det, rng, per_point, s) for s in range(points)))
                m = np.array(means)
                ok = np.isfinite(m)
                err = np.abs(np.remainder(m[ok] - angle + 180, 360) - 180)
                res[label, angle, det] = {"spread": float(np.ptp(m[ok])) if ok.any() else math.nan,
                                          "mean_error": float(err.mean()) if ok.any() else math.nan,
                                          "failed": int(sum(failed)), "points": int(ok.sum())}
            log(f"paper3 exp 2: {name} at {angle} deg done")
    rows = ["| object | angle | paper: SIFT | paper: SIFT/SURF | ours: " + " | ours: ".join(d.upper() for d in DETECTORS)
            + " |", "|---|---|---|---|" + "---|" * len(DETECTORS)]
    for (label, angle), (p_sift, p_hybrid) in PAPER_SPREAD.items():
        cells = []
        for det in DETECTORS:
            r = res[label, angle, det]
            spread = f"{r['spread']:.3f}" if r["points"] >= 2 else "—"
            cells.append(f"{spread} (mean error {r['mean_error']:.3f}; {r['failed']} of {points * per_point} failed)")
        rows.append(f"| {label} ({STABILITY_OBJECTS[label]}) | {angle}° | {p_sift} | {p_hybrid} | "
                    + " | ".join(cells) + " |")
    sift = [res[k] for k in res if k[2] == "sift"]
    fails = {det: sum(res[k]["failed"] for k in res if k[0] == "A" and k[2] == det) for det in DETECTORS}
    spread_a = {det: max(res["A", a, det]["spread"] for a in (0, 90)) for det in DETECTORS}
    spread_b = {det: max(res["B", a, det]["spread"] for a in (0, 90)) for det in DETECTORS}
    checks = [Check("Paper 3, Exp. 2: SIFT's orientation is stable to under 2 deg with a mean error under 1 deg",
                    all(r["spread"] < 2.0 and r["mean_error"] < 1.0 for r in sift),
                    "SIFT spreads " + ", ".join(f"{r['spread']:.3f}" for r in sift) + " deg, mean errors "
                    + ", ".join(f"{r['mean_error']:.3f}" for r in sift) + " deg")]
    fig = out / "paper3_stability.png"
    _plot_stability(res, fig)
    timer.__exit__()
    md = [f"Made by {_command(quick)}.", "",
          f"Set-up: each object upright at 0° and 90° on the table; {points} data points, each the mean of "
          f"{per_point} measurements (the paper: 25 of 10). A data point: the hand camera 12 cm above a rough estimate "
          "(the truth moved by up to 1 cm and the camera turned by up to 5°, redrawn per point), images with fresh "
          "noise (a colour webcam, 1280 x 720, 0.8 px blur, noise of 2 levels per channel); a measurement is one 2D step "
          "(scanalign.pose.image_matching.refine_planar_pose: keypoints, RANSAC homography, eqs. (5)-(6)). The "
          "weakly textured object (as the paper's A) is the block with its faint label (builtin:sparse-1: twelve "
          "faint shapes, three words), the textured one (as the paper's B) the bracket with its printed label. The "
          "paper's hybrid (SIFT keypoints, SURF descriptors) is replaced by AKAZE and ORB: SURF is patented and not "
          "in OpenCV's default build. A failed measurement (too few inliers, a non-rigid homography) is left out "
          "of its mean and counted.", "",
          "**Tables 5-6**: spread = max − min of the data points' means (degrees):", "", *rows, "",
          "On the weakly textured object, failed measurements: " + ", ".join(
              f"{det.upper()} {fails[det]} of {2 * points * per_point}" for det in DETECTORS)
          + "; largest spread: " + ", ".join(f"{det.upper()} {spread_a[det]:.3f}°" for det in DETECTORS)
          + ". On the textured one: " + ", ".join(f"{det.upper()} {spread_b[det]:.3f}°" for det in DETECTORS) + ".", "",
          "What differs: the paper's weakly textured object A spread 1.1-1.7° with SIFT and 5.5-7.9° with its "
          "hybrid; our faint label spreads far less with every detector, as our images have no lighting changes, "
          "no reflections and exact focus. What holds: on the weak texture SIFT is the one that keeps measuring "
          "(the substitutes' fits from few, clustered keypoints are refused as non-rigid), while a substitute's "
          "spread over the measurements it keeps is not always larger than SIFT's, unlike the paper's hybrid; on "
          "the rich texture every detector is steady, SIFT the steadiest, as with the paper's B."]
    return Section("Thesis Paper 3, Experiment 2 (Tables 5-6): the 2D step's orientation stability",
                   "\n".join(md), [fig], checks, timer.seconds)


# --- Experiment 3 -------------------------------------------------------------------------------------------------

def _stage_placement(cell: Any, result: Any, poses: Dict[str, np.ndarray]) -> Dict[str, Any]:
    """The placement error had the pick and place been planned from ``poses`` (part name -> T_base_model)."""
    a, b = cell.part, cell.onto
    plan = plan_pick_and_place(a, poses[a.name], poses[b.name], cell.gripper_robot,
                               table_plane=np.asarray([0.0, 0.0, 1.0, 0.0]), settings=AssemblySettings().planner)
    if plan.status != "planned":
        return {"translation_m": math.nan, "angle_deg": math.nan, "success": False}
    c, p = plan.pick.candidates[plan.pick.chosen], plan.place.candidates[plan.place.chosen]
    return placement_error(np.asarray(c.T_base_tcp_grasp), np.asarray(p.T_base_tcp_grasp), cell)


def _assemblies(quick: bool, log: Log, out: Path) -> Section:
    timer = Timer().__enter__()
    seeds = range(1 if quick else 10)
    runs = []
    for seed in seeds:
        cell = assembly_cell(seed=seed)
        result = assemble_cell(cell)
        score = score_assembly(result, cell)
        stages = {"3d": None, "one_step": None}
        if all(p.T_base_model_rough is not None for p in result.parts.values()):
            stages["3d"] = _stage_placement(cell, result, {n: p.T_base_model_rough for n, p in result.parts.items()})
        if all(p.refine is not None and p.refine.views and p.refine.views[0].step for p in result.parts.values()):
            stages["one_step"] = _stage_placement(
                cell, result, {n: np.asarray(p.refine.views[0].step.T_base_part) for n, p in result.parts.items()})
        runs.append({"seed": seed, "status": result.status, "score": score, "stages": stages,
                     "views": sum(len(p.refine.views) for p in result.parts.values() if p.refine is not None),
                     "seconds": sum(result.seconds.values())})
        log(f"paper3 exp 3: seed {seed}: {result.status}")
    a, b = GRID_OBJECTS["A"], GRID_OBJECTS["B"]

    def cell_text(e: Any) -> str:
        return "—" if e is None or not np.isfinite(e["translation_m"]) else (
            f"{1000 * e['translation_m']:.2f} mm / {e['angle_deg']:.2f}° {'✓' if e['success'] else '✗'}")

    rows = ["| seed | A, B 3D error (mm / °) | A, B after convergence (mm / °) | placed from the 3D step | "
            "after one 2D step | after convergence | views | s |", "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        p = r["score"]["parts"]
        err = lambda s: " · ".join(f"{1000 * p[n][s]['xy_m']:.2f} / {p[n][s]['angle_deg']:.2f}" for n in (a, b))  # noqa: E731
        rows.append(f"| {r['seed']} | {err('3d')} | {err('refined')} | {cell_text(r['stages']['3d'])} | "
                    f"{cell_text(r['stages']['one_step'])} | {cell_text(r['score']['placement'])} | {r['views']} | "
                    f"{r['seconds']:.1f} |")
    count = lambda key: sum(bool(r["stages"][key] and r["stages"][key]["success"]) for r in runs)  # noqa: E731
    final = sum(bool(r["score"]["placement"] and r["score"]["placement"]["success"]) for r in runs)
    need = math.ceil(0.9 * len(runs))
    checks = [Check("Paper 3, Exp. 3: full assemblies succeed within 1 mm and 1 deg (the paper: 7 of 10; the issue: "
                    "at least 9 of 10)", final >= need, f"{final} of {len(runs)} after convergence, "
                    f"{count('one_step')} after one 2D step, {count('3d')} from the 3D step alone")]
    fig = out / "paper3_assembly.png"
    _plot_assembly(runs, fig)
    timer.__exit__()
    tol = load_part(a).assembly
    md = [f"Made by {_command(quick)}.", "",
          f"Set-up: {len(runs)} random cells (scanalign.synthetic.assembly_cell, seeds {seeds.start}-{seeds.stop - 1}):"
          f" part A ({a}) and part B ({b}) anywhere in the reach of both arms, any yaw; "
          "scanalign.pipelines.assemble.assemble_cell with its defaults: find_parts on the fixed camera's frame, "
          "each part refined by the camera arm (SIFT, 12 cm above its label) until a step moves it by less than "
          "0.3 mm and 0.003 rad, then the gripper arm's pick of A and place onto B. Success: A within "
          f"{1000 * tol.tolerance_translation:.0f} mm and {math.degrees(tol.tolerance_angle):.0f}° of the relative pose "
          "of its part file, A held as the gripper truly grasped it (no slip). The columns 'placed from the 3D step' "
          "and 'after one 2D step' plan the same pick and place from those poses instead.", "",
          "**Experiment 3**:", "", *rows, "",
          f"Success: **{final} of {len(runs)}** after convergence, {count('one_step')} after one 2D step, "
          f"{count('3d')} from the 3D step alone; the paper: {PAPER_ASSEMBLIES[0]} of {PAPER_ASSEMBLIES[1]} "
          "(its three failures: A's orientation, from the 2D step's accuracy and the gripper displacing the part).",
          "", "What differs: our gripper never displaces the part and our 2D images are ideal (no lighting, no lens "
          "distortion left, exact hand-eye): the 2D step lands within about 0.1 mm and 0.05°, so every converged "
          "assembly succeeds. The 3D step alone misses the 1 mm tolerance in most runs, as the paper found (its 5.2 "
          "mm correction in Fig. 13)."]
    return Section("Thesis Paper 3, Experiment 3: full assemblies in the two-robot cell", "\n".join(md), [fig],
                   checks, timer.seconds)


# --- Figures ------------------------------------------------------------------------------------------------------

def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plot_grid(ours: Dict[str, Any], positions: List[Tuple[int, int]], path: Path) -> None:
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    for ax, label in zip(axes, GRID_OBJECTS):
        for k in positions:
            p, o = PAPER_GRID[label][k], ours[label][k]["measured"]
            ax.plot(*k, "ks", ms=5)
            ax.annotate("", p, k, arrowprops=dict(arrowstyle="->", color="tab:red"))
            ax.plot(*o, "o", color="tab:blue", ms=4)
        ax.plot([], [], "ks", label="actual")
        ax.plot([], [], "-", color="tab:red", label="paper: measured (mean of 10)")
        ax.plot([], [], "o", color="tab:blue", label="ours: measured (mean)")
        ax.set(xlabel="X (cm)", ylabel="Y (cm)", title=f"object {label} ({GRID_OBJECTS[label]})", aspect="equal")
        ax.legend(fontsize=7, loc="lower left")
    fig.suptitle("Paper 3, Exp. 1: the 3D step on the 16-position grid")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_stability(res: Dict[Tuple[str, int, str], Dict[str, float]], path: Path) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10, 4.5))
    keys = list(PAPER_SPREAD)
    width = 0.15
    x = np.arange(len(keys))
    ax.bar(x - 2 * width, [PAPER_SPREAD[k][0] for k in keys], width, label="paper: SIFT", color="tab:red")
    ax.bar(x - width, [PAPER_SPREAD[k][1] for k in keys], width, label="paper: SIFT/SURF", color="salmon")
    for i, det in enumerate(DETECTORS):
        ax.bar(x + i * width, [res[k[0], k[1], det]["spread"] for k in keys], width, label=f"ours: {det.upper()}",
               color=f"C{i}")
    ax.set_yscale("log")
    ax.set_xticks(x, [f"{k[0]} ({STABILITY_OBJECTS[k[0]]}) {k[1]}°" for k in keys])
    ax.set_ylabel("spread of the means (deg)")
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Paper 3, Exp. 2: orientation stability")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_assembly(runs: List[Dict[str, Any]], path: Path) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    stages = [("3D step alone", lambda r: r["stages"]["3d"]), ("one 2D step", lambda r: r["stages"]["one_step"]),
              ("converged", lambda r: r["score"]["placement"])]
    for i, (label, get) in enumerate(stages):
        v = [1000 * get(r)["translation_m"] if get(r) else np.nan for r in runs]
        ax.plot([r["seed"] for r in runs], v, "o-", color=f"C{i}", label=label)
    ax.axhline(1.0, color="k", ls=":", lw=1)
    ax.text(0, 1.05, " tolerance 1 mm", fontsize=7)
    ax.set(yscale="log", xlabel="cell seed", ylabel="placed part A: translation error (mm)",
           title="Paper 3, Exp. 3: assemblies (the paper: 7 of 10 within 1 mm, 1°)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(out: Path, quick: bool, log: Log) -> List[Section]:
    out.mkdir(parents=True, exist_ok=True)
    return [_grid(quick, log, out), _stability(quick, log, out), _assemblies(quick, log, out)]

