"""Figures for reports and benchmarks: trajectories, per-frame statistics, curves.  matplotlib is imported on first
use, only through its object-oriented API with the Agg canvas (no pyplot, no display, no global backend switch): these
functions work headless and leave an interactive session alone.  Every function writes a PNG to ``path`` (creating its
folder) and returns that path; ``title`` is the figure's title.  Inputs in metres and seconds.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from scanalign.evaluation import absolute_trajectory_error
from scanalign.evaluation.trajectory import Trajectory
from scanalign.pipelines.pick import placed_parts
from scanalign.pose.image_matching import homography_of_part

__all__ = ["plot_batch", "plot_trajectory_topdown", "plot_frame_stats", "plot_series", "plot_arm_configurations",
           "plot_joint_trajectory", "pose_overlay", "plot_pick", "plot_assembly_views"]

PathLike = Union[str, os.PathLike]


def _figure(figsize: Tuple[float, float]):
    """A matplotlib Figure attached to an Agg canvas (no pyplot state)."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("scanalign.viz.plots needs matplotlib (pip install matplotlib); the rest of scanalign "
                          "works without it") from exc
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: PathLike, dpi: int) -> Path:
    out = Path(path)
    if not out.parent.exists():  # a file in the way is savefig's NotADirectoryError naming the path
        out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi, format="png")
    return out


def _plane_axes(plane: Optional[str], positions: np.ndarray) -> Tuple[int, int]:
    if plane is None:
        ext = np.ptp(positions, axis=0) if positions.shape[0] else np.zeros(3)
        return tuple(sorted(np.argsort(-ext, kind="stable")[:2].tolist()))
    if len(plane) != 2 or not set(plane) <= set("xyz") or plane[0] == plane[1]:
        raise ValueError(f"plane must be two different letters of 'xyz' such as 'xy' or 'xz', got {plane!r}")
    return "xyz".index(plane[0]), "xyz".index(plane[1])


def _cube(pts: np.ndarray) -> Tuple[np.ndarray, float]:
    """Centre and half side of a cube 1.1 times the points' largest extent (at least 1 mm)."""
    return 0.5 * (pts.min(axis=0) + pts.max(axis=0)), 0.55 * max(float(np.ptp(pts, axis=0).max()), 1e-3)


def _set_cube(ax: Any, centre: np.ndarray, half: float) -> None:
    """Equal 3D axes spanning ``centre +- half``."""
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_lim(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))


def plot_trajectory_topdown(estimate: Trajectory, reference: Optional[Trajectory], path: PathLike,
                            title: Optional[str] = None, aligned: bool = True, plane: Optional[str] = None,
                            units: str = "auto", with_scale: bool = False, associate: bool = False,
                            max_difference: float = 0.02, dpi: int = 150) -> Path:
    """Top-down view of estimated vs reference camera centres, like Fig. 4 of the eye-in-hand
    paper (Comput. Electron. Agric. 180 (2021) 105929): the reference black, the estimate
    coloured, grey segments joining paired poses; circles mark the start, squares the end.

    Args:
        estimate, reference: ``T_world_camera`` trajectories, paired as by
            :func:`scanalign.evaluation.absolute_trajectory_error` (``associate``,
            ``max_difference`` s). Without a reference the estimate alone is drawn, in its frame.
        aligned: align the estimate to the reference first (``with_scale``: a similarity) and
            give the ATE RMSE in the title; otherwise the RMSE of the raw distances.
        plane: two axes of the reference world frame, e.g. ``"xy"`` (x horizontal) or
            ``"xz"``; default: the two axes along which the reference centres extend most.
        units: ``"m"``, ``"mm"`` or ``"auto"`` (mm when the drawn extent is under 0.5 m).
    """
    ate = None if reference is None else absolute_trajectory_error(
        estimate, reference, align=aligned, with_scale=with_scale, associate=associate, max_difference=max_difference)
    est = ate.aligned.positions if ate else estimate.positions
    ref = ate.reference.positions if ate else est[:0]
    i, j = _plane_axes(plane, ref if ate else est)
    both = np.concatenate([est, ref])
    extent = float(np.ptp(both[:, [i, j]], axis=0).max()) if both.shape[0] else 0.0
    if units not in ("auto", "m", "mm"):
        raise ValueError(f"units must be 'auto', 'm' or 'mm', got {units!r}")
    unit = ("mm" if extent < 0.5 else "m") if units == "auto" else units
    k = 1000.0 if unit == "mm" else 1.0
    e2, r2 = est[:, [i, j]] * k, ref[:, [i, j]] * k
    ax = _figure((6.4, 5.6)).add_subplot(1, 1, 1)
    if ate:
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(np.stack([r2, e2], axis=1), colors="0.6", linewidths=0.6, label="error",
                                         zorder=1))
        ax.plot(r2[:, 0], r2[:, 1], "-", color="black", lw=1.4, label="reference", zorder=2)
    ax.plot(e2[:, 0], e2[:, 1], "-", color="tab:blue", lw=1.2,
            label="estimate" + (" (aligned)" if ate and aligned else ""), zorder=3)
    for pts, color in ((r2, "black"), (e2, "tab:blue")) if ate else ((e2, "tab:blue"),):
        ax.plot(pts[0, 0], pts[0, 1], "o", color=color, ms=6, mfc="white", zorder=4)
        ax.plot(pts[-1, 0], pts[-1, 1], "s", color=color, ms=6, zorder=4)
    ax.plot([], [], "o", color="0.3", mfc="white", label="start")
    ax.plot([], [], "s", color="0.3", label="end")
    ax.set(xlabel=f"{'xyz'[i]} ({unit})", ylabel=f"{'xyz'[j]} ({unit})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(True, lw=0.3, alpha=0.5)
    label = "ATE" if aligned else "RMS distance (unaligned)"
    summary = (f"{label} RMSE {ate.translation.rmse * k:.3g} {unit}, max {ate.translation.max * k:.3g} {unit}, "
               f"{ate.translation.count} poses" if ate else
               f"estimated camera path (model frame), {len(estimate)} poses, no reference")
    ax.set_title(f"{title + chr(10) if title else ''}{summary}")
    ax.legend(loc="best", fontsize=8)
    return _save(ax.figure, path, dpi)


_ALIASES = {"time": ("time", "seconds"), "iterations": ("iterations",), "fitness": ("fitness",),
            "model_size": ("model_size", "model_points"), "skipped": ("skipped",)}


def _columns(per_frame: Union[Sequence[Mapping[str, Any]], Mapping[str, Sequence[Any]]]
             ) -> Tuple[int, Dict[str, np.ndarray]]:
    """The number of frames and float columns by canonical name, of rows of dicts or a dict of columns."""
    if isinstance(per_frame, Mapping):
        raw = {k: list(v) for k, v in per_frame.items()}
        n = len(next(iter(raw.values()))) if raw else 0
        if any(len(v) != n for v in raw.values()):
            raise ValueError("per_frame: columns have different lengths")
    else:
        rows = list(per_frame)
        if not all(isinstance(r, Mapping) for r in rows):
            raise TypeError("per_frame: expected a sequence of dicts or a dict of columns")
        raw = {k: [r.get(k) for r in rows] for k in {k for r in rows for k in r}}
        n = len(rows)
    found = {name: next((a for a in aliases if a in raw), None) for name, aliases in _ALIASES.items()}
    return n, {name: np.array([np.nan if x is None else float(x) for x in raw[a]], dtype=np.float64)
               for name, a in found.items() if a is not None}


def plot_frame_stats(per_frame: Union[Sequence[Mapping[str, Any]], Mapping[str, Sequence[Any]]], path: PathLike,
                     title: Optional[str] = None, dpi: int = 150) -> Path:
    """Per-frame registration cost and model growth, two panels sharing the frame axis.  Top: registration time (ms,
    bars) and ICP iterations.  Bottom: model size (points) and ICP fitness.  Skipped frames (``skipped`` true, or a
    missing / NaN time) are shaded red.  ``per_frame``: one dict per frame, or a dict of equal-length columns, with the
    time in seconds (``time`` or ``seconds``, required), ``iterations``, ``fitness``, the model size in points
    (``model_size`` or ``model_points``) and ``skipped``."""
    n, cols = _columns(per_frame)
    if n == 0:
        raise ValueError("per_frame: no frames")
    if "time" not in cols:
        raise ValueError(f"per_frame: no time column (one of {_ALIASES['time']})")
    frames = np.arange(n)
    t_ms = cols["time"] * 1000.0
    skipped = ~np.isfinite(t_ms)
    if "skipped" in cols:
        skipped |= np.nan_to_num(cols["skipped"], nan=0.0) != 0
    fig = _figure((7.5, 5.5))
    ax1 = fig.add_subplot(2, 1, 1)
    ax2 = fig.add_subplot(2, 1, 2, sharex=ax1)
    ok = ~skipped
    ax1.bar(frames[ok], t_ms[ok], width=0.8, color="tab:blue", label="registration time")
    ax1.set_ylabel("time (ms)")
    handles, h2s = ax1.containers[:1], []
    if "model_size" in cols:
        h2s += ax2.plot(frames, cols["model_size"], "-", color="tab:green", lw=1.2, label="model size")
        ax2.set_ylabel("model size (points)")
    else:
        ax2.set_yticks([])
    for ax, hs, key, style, colour, ylabel in ((ax1, handles, "iterations", ".-", "tab:orange", "ICP iterations"),
                                               (ax2, h2s, "fitness", ".", "tab:purple", "fitness")):
        if key in cols:  # on a second y axis of the panel (lw only shows on the iterations' line)
            twin = ax.twinx()
            hs += twin.plot(frames, cols[key], style, color=colour, lw=0.8, ms=3, label=key)
            twin.set_ylabel(ylabel)
    for ax in (ax1, ax2):
        for f in frames[skipped]:
            ax.axvspan(f - 0.5, f + 0.5, color="tab:red", alpha=0.15, lw=0)
        ax.grid(True, lw=0.3, alpha=0.5)
    if np.any(skipped):
        handles += ax1.plot(frames[skipped], np.zeros(int(skipped.sum())), "x", color="tab:red", ms=7,
                            clip_on=False, label="skipped")
    ax2.set_xlabel("frame")
    if handles:
        ax1.legend(handles=handles, loc="upper left", fontsize=8)
    if h2s:
        ax2.legend(handles=h2s, loc="upper left", fontsize=8)
    ax1.set_title(f"{title + chr(10) if title else ''}{n} frames, {int(skipped.sum())} skipped, "
                  f"registration {np.nansum(cols['time']):.3g} s total")
    return _save(fig, path, dpi)


def plot_series(x: Sequence[float], series: Mapping[str, Sequence[float]], path: PathLike, *,
                xlabel: str = "", ylabel: str = "", title: Optional[str] = None, logx: bool = False,
                logy: bool = False, errors: Optional[Mapping[str, Sequence[float]]] = None,
                markers: bool = True, dpi: int = 150) -> Path:
    """Benchmark curves: one line per label over shared x values (eye-in-hand paper Figs. 5, 6, 7, 9:
    time or ATE vs number of images or iteration cap).

    Args:
        x: (M,) x values (e.g. number of images, iteration cap).
        series: label -> (M,) y values; NaN leaves a gap (e.g. a method that failed).
        xlabel, ylabel: axis labels, with units (e.g. ``"total time (s)"``).
        logx, logy: logarithmic axes (non-positive values are not drawn).
        errors: optional label -> (M,) symmetric error bars (e.g. standard deviations).

    ValueError: no series, or a series (or its errors) whose length differs from ``x``.
    """
    xv = np.asarray(x, dtype=np.float64).reshape(-1)
    if not series:
        raise ValueError("plot_series: no series given")
    ax = _figure((6.4, 4.4)).add_subplot(1, 1, 1)
    style = "o-" if markers else "-"
    for label, y in series.items():
        yv = np.asarray(y, dtype=np.float64).reshape(-1)
        if yv.shape != xv.shape:
            raise ValueError(f"plot_series: series {label!r} has {yv.size} values for {xv.size} x values")
        err = None if errors is None or label not in errors else np.asarray(errors[label], dtype=np.float64)
        if err is not None:
            if err.shape != xv.shape:
                raise ValueError(f"plot_series: errors for {label!r} have {err.size} values for {xv.size} x values")
            ax.errorbar(xv, yv, yerr=err, fmt=style, ms=4, lw=1.2, capsize=3, label=str(label))
        else:
            ax.plot(xv, yv, style, ms=4, lw=1.2, label=str(label))
    if logx:
        ax.set_xscale("log")
        finite_x = np.unique(xv[np.isfinite(xv) & (xv > 0)])
        if 0 < finite_x.size <= 12:  # label the measured x values (image counts, caps) plainly
            from matplotlib.ticker import NullFormatter

            ax.set_xticks(finite_x, [f"{v:g}" for v in finite_x])
            ax.xaxis.set_minor_formatter(NullFormatter())
    if logy:
        ax.set_yscale("log")
    ax.set(xlabel=xlabel, ylabel=ylabel, title=title or "")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(loc="best", fontsize=8)
    return _save(ax.figure, path, dpi)


def plot_arm_configurations(robot: Any, q: np.ndarray, path: PathLike, *, labels: Optional[Sequence[str]] = None,
                            T_base_tool: Optional[np.ndarray] = None, title: Optional[str] = None,
                            dpi: int = 110) -> Path:
    """Draws arm configurations (e.g. all IK solutions of one pose) as stick figures, one 3D panel each (metres, equal
    axes).

    Args:
        robot: a :class:`scanalign.kinematics.Robot` (its ``joint_positions(q, tcp=True)``
            gives the origins of DH frames 0..6 and the TCP in the robot base frame).
        q: (K, 6) joint values, radians; rows with NaN are skipped.
        labels: one caption per row (e.g. "shoulder +1 elbow +1 wrist -1").
        T_base_tool: (4, 4) target tool pose (tool -> base), drawn as a small RGB triad.
    """
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    if q.ndim != 2 or q.shape[1] != 6:
        raise ValueError(f"q: expected shape (K, 6), got {q.shape}")
    rows = [k for k in range(q.shape[0]) if np.all(np.isfinite(q[k]))]
    if labels is not None and len(labels) != q.shape[0]:
        raise ValueError("labels: need one label per row of q")
    n = max(len(rows), 1)
    cols, nrows = min(n, 4), -(-n // 4)
    fig = _figure((3.2 * cols, 3.2 * nrows))
    chains = [(k, np.asarray(robot.joint_positions(q[k], tcp=True))) for k in rows]
    T = None if T_base_tool is None else np.asarray(T_base_tool, dtype=np.float64)
    pts = [c for _, c in chains] + ([] if T is None else [T[None, :3, 3]])
    centre, half = _cube(np.vstack(pts) if chains else np.zeros((1, 3)))
    for i, (k, chain) in enumerate(chains):
        ax = fig.add_subplot(nrows, cols, i + 1, projection="3d")
        ax.plot(chain[:, 0], chain[:, 1], chain[:, 2], "-o", color="0.25", lw=2.5, ms=3.5)
        ax.plot([chain[0, 0]], [chain[0, 1]], [chain[0, 2]], "s", color="k", ms=6)
        for a, colour in enumerate(("r", "g", "b") if T is not None else ()):  # the target tool triad
            ax.plot(*np.stack([T[:3, 3], T[:3, 3] + 0.25 * half * T[:3, a]], axis=1), color=colour, lw=1.5)
        _set_cube(ax, centre, half)
        ax.tick_params(labelsize=6)
        ax.set_title(labels[k] if labels is not None else f"solution {k}", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path, dpi)


def plot_joint_trajectory(t: Sequence[float], q: np.ndarray, path: PathLike, *,
                          limits: Optional[np.ndarray] = None, title: Optional[str] = None, dpi: int = 110) -> Path:
    """Joint angles (degrees) over ``t`` ((N,) s), one panel per joint of ``q`` ((N, 6) rad; NaN rows, steps without a
    solution, are gaps), with the ``limits`` ((6, 2) lower / upper, rad) as dashed lines."""
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 6 or t.shape != (q.shape[0],):
        raise ValueError(f"expected t (N,) and q (N, 6), got {t.shape} and {q.shape}")
    fig = _figure((9.0, 5.0))
    axes = fig.subplots(2, 3, sharex=True)
    for j, ax in enumerate(axes.ravel()):
        vals, seen = np.degrees(q[:, j]), np.isfinite(q[:, j]).any()
        ax.plot(t, vals, color="C0", lw=1.4)
        if limits is not None:
            span = np.nanmax(np.abs(vals)) if seen else 180.0
            for v in np.degrees(np.asarray(limits, dtype=np.float64)[j]):
                if abs(v) <= 1.5 * span + 30:
                    ax.axhline(v, color="C3", ls="--", lw=0.8)
        if seen:  # at least 10 degrees of span: a still joint reads as still
            lo, hi = np.nanmin(vals), np.nanmax(vals)
            half = max(0.55 * (hi - lo), 5.0)
            ax.set_ylim(0.5 * (lo + hi) - half, 0.5 * (lo + hi) + half)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_title(f"joint {j + 1}", fontsize=9)
        ax.set_ylabel("deg", fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time [s]", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path, dpi)


def pose_overlay(obj: np.ndarray, placed: np.ndarray, result: Any, path: PathLike, *, dpi: int = 110) -> Path:
    """Three orthographic projections (mm) of an object's scan points (orange) and the model
    placed at ``result.T_scene_model`` (blue), titled with the pose's quality figures."""
    fig = _figure((13, 4.4))
    axes = fig.subplots(1, 3)
    for ax, (i, j, name) in zip(axes, ((0, 1, "x-y"), (0, 2, "x-z"), (1, 2, "y-z"))):
        ax.scatter(1000 * obj[::3, i], 1000 * obj[::3, j], s=0.3, c="tab:orange", label="object (scan)")
        ax.scatter(1000 * placed[::3, i], 1000 * placed[::3, j], s=0.3, c="tab:blue", alpha=0.4,
                   label="model at T_scene_model")
        ax.set_title(f"{name} (mm)")
        ax.set_aspect("equal")
    axes[0].legend(loc="upper right", markerscale=12, fontsize=8)
    fig.suptitle(f"{result.method}: fitness {result.fitness:.3f}, coverage {result.coverage:.3f}, "
                 f"inlier RMSE {1000 * result.inlier_rmse:.3f} mm, {result.seconds:.2f} s")
    return _save(fig, path, dpi)


def plot_pick(result: Any, path: PathLike, *, dpi: int = 110) -> Path:
    """The arm at each chosen grasp over the scene (a :class:`scanalign.pipelines.pick.PickResult`): a 3D view and a
    top view in the base frame (m): scene points grey, placed parts coloured, the arm as a stick figure from its base
    through the joints to the TCP, and the straight approach from the pre-grasp (dashed)."""
    fig = _figure((13, 6))
    ax3, ax2 = fig.add_subplot(1, 2, 1, projection="3d"), fig.add_subplot(1, 2, 2)
    pts = result.points[:: max(1, len(result.points) // 20000)]
    ax3.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.2, c="0.6")
    ax2.scatter(pts[:, 0], pts[:, 1], s=0.2, c="0.7")
    robot, T_dh0 = result.robot, np.asarray(result.robot.T_base_dh0)
    chains = [T_dh0[None, :3, 3]]
    for k, v in placed_parts(result, 1500):  # the parts at their found poses, the pick's colour
        ax3.scatter(v[:, 0], v[:, 1], v[:, 2], s=0.5, c=f"C{k % 10}")
        ax2.scatter(v[:, 0], v[:, 1], s=0.5, c=f"C{k % 10}")
    for k, p in enumerate(result.picks):
        if p.status != "picked":
            continue
        c, colour = p.chosen, f"C{k % 10}"
        chain = np.asarray(result.tcp_robot(p).joint_positions(c.q_grasp, tcp=True))  # ends at the TCP
        chains.append(chain)
        approach = np.array([np.asarray(c.T_base_tcp_pregrasp)[:3, 3], np.asarray(c.T_base_tcp_grasp)[:3, 3]])
        for ax, dims in ((ax3, 3), (ax2, 2)):
            ax.plot(*chain[:, :dims].T, "-o", color=colour, lw=2, ms=3,
                    label=f"{p.part}: {p.grasp_names[c.grasp_index]}")
            ax.plot(*approach[:, :dims].T, "--", color="k", lw=1)
    _set_cube(ax3, *_cube(np.vstack([pts] + chains)))
    ax2.set_aspect("equal")
    ax2.set_title("top view (m, base frame)")
    ax2.legend(loc="best", fontsize=8)
    fig.suptitle(f"{robot.name}: joint targets at the chosen grasps")
    return _save(fig, path, dpi)


def plot_batch(records: Sequence[Mapping[str, Any]], path: PathLike, *, dpi: int = 110) -> Path:
    """Distributions of a batch's results (:func:`scanalign.pipelines.batch.run_batch` records): time per
    job by kind, and the accuracy metrics that the jobs report (ATE RMSE, pose and TCP
    errors, in mm / degrees), one histogram each; failed jobs are counted in the title."""
    panels = [("seconds", "time per job (s)", 1.0), ("ate_rmse_m", "reconstruction ATE RMSE (mm)", 1000.0),
              ("pose_error_max_m", "worst part pose error per job (mm)", 1000.0),
              ("pose_error_max_deg", "worst part pose error per job (deg)", 1.0),
              ("tcp_error_max_m", "worst grasp TCP error per job (mm)", 1000.0)]

    def values(key: str, kind: str) -> np.ndarray:
        v = np.array([r.get(key) for r in records if r.get("kind") == kind and r.get("status") == "ok"], dtype=float)
        return v[np.isfinite(v)]

    kinds = sorted({str(r.get("kind")) for r in records})
    shown = [p for p in panels if any(values(p[0], k).size for k in kinds)] or panels[:1]
    fig = _figure((4.2 * len(shown), 3.6))
    for i, (key, label, scale) in enumerate(shown):
        ax = fig.add_subplot(1, len(shown), i + 1)
        for j, kind in enumerate(kinds):
            v = values(key, kind) * scale
            if v.size:
                ax.hist(v, bins=min(30, max(5, v.size // 2)), alpha=0.6, color=f"C{j}",
                        label=f"{kind} (n={v.size}, median {np.median(v):.3g})")
        ax.set(xlabel=label, ylabel="jobs")
        ax.legend(fontsize=7)
    fig.suptitle(f"batch: {len(records)} jobs, {sum(r.get('status') != 'ok' for r in records)} failed or crashed")
    return _save(fig, path, dpi)


def plot_assembly_views(result: Any, images: Mapping[str, np.ndarray], references: Mapping[str, Any],
                        intrinsics: Any, path: PathLike, *, truth: Optional[Mapping[str, np.ndarray]] = None,
                        dpi: int = 110) -> Path:
    """The hand camera's last image of each part (a :class:`scanalign.pipelines.assemble.AssemblyResult`'s parts;
    ``images``: part name -> that image) with the outline of its reference image (``references``: part name ->
    (image, :class:`ReferenceImageGeometry`)) drawn where the refined pose puts it (green; the 3D step's rough pose
    dashed orange, the truth dotted white when given), and the matched inliers (cyan)."""
    names = [n for n in result.parts if n in images]
    fig = _figure((6.5 * max(1, len(names)), 4.6))
    for k, name in enumerate(names):
        ax, p = fig.add_subplot(1, max(1, len(names)), k + 1), result.parts[name]
        ax.imshow(images[name], cmap="gray", vmin=0, vmax=255)
        image, g = references[name]
        corners = np.array([[0, 0, 1], [g.width - 1, 0, 1], [g.width - 1, g.height - 1, 1], [0, g.height - 1, 1],
                            [0, 0, 1]], float).T
        view = p.refine.views[-1] if p.refine is not None and p.refine.views else None
        poses = [(p.T_base_model_rough, "--", "orange", "rough (3D step)"), (p.T_base_model, "-", "lime", "refined"),
                 (None if truth is None else truth.get(name), ":", "white", "truth")]
        for T, style, colour, label in poses:
            if T is None or view is None:
                continue
            q = homography_of_part(g, intrinsics, np.asarray(view.T_base_camera), np.asarray(T)) @ corners
            ax.plot(q[0] / q[2], q[1] / q[2], style, color=colour, lw=1.5, label=label)
        if view is not None and len(view.step.match.image_points):
            ax.plot(*view.step.match.image_points.T, ".", color="cyan", ms=2, label=f"{view.step.match.inliers} inliers")
        ax.set_title(f"{name}: {p.status}" + ("" if view is None else f", view {len(p.refine.views)}"), fontsize=9)
        ax.legend(loc="lower right", fontsize=7)
        ax.set_axis_off()
    fig.suptitle(f"hand camera: {result.status} ({result.reason[:90]})", fontsize=9)
    return _save(fig, path, dpi)
