"""Thesis Paper 4, Table 1 (A. L. Kleppe, L. Tingelstad, O. Egeland, "Initial alignment of point clouds using motors",
in Kleppe, PhD thesis, NTNU 2018, §4): the flag alignment (centroid + average normal line, Levenberg-Marquardt on the
motor manifold; scanalign.pose.align_flags) of 2 CAD models x 42 viewpoint clouds x 3 sizes = 252 clouds, each
against a copy under a random rigid motion plus noise.

    python bench/reproduce.py [--quick] --only paper4
    PYTHONPATH=python python -m bench.experiments.paper4 [--quick] [--out DIR]   # this module alone
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import spearmanr

from scanalign import pose
from scanalign.data import downloads as datasets
from scanalign.pose import model_views as cad

from . import Check, Log, Section, Timer

MODELS = ("fandisk", "joint")  # CGAL mechanical parts standing in for the thesis's two (unpublished) CAD models
RESOLUTION = 400               # px per view: every view has more than 10000 points
SIZES = (100, 1000, 10000)
SIGMA_MM = 0.1                 # the thesis gives no noise level; 0.1 mm is the Zivid's depth resolution (P5 §IV-A)
SIGMA_EXTRA_MM = 1.0           # a second level, averages only
THESIS_ROWS = {  # cloud -> ((iterations, error m) per size); exponents the OCR lost are None (thesis.md §6)
    1: ((6, "1.840e-3"), (6, "9.4128e-3"), (17, "6.6647e-?")),
    6: ((7, "4.8510e-4"), (16, "1.3453e-?"), (12, "3.5899e-7")),
    7: ((7, "3.1998e-4"), (14, "2.5855e-?"), (12, "2.5160e-?")),
    14: ((7, "1.8475e-4"), (7, "5.7251e-3"), (12, "1.0650e-8")),
    22: ((7, "1.1063e-3"), (6, "1.2058e-2"), (11, "3.9998e-8")),
    31: ((6, "1.7973e-3"), (7, "5.5537e-3"), (7, "1.0105e-2")),
    45: ((7, "1.0676e-3"), (13, "4.3508e-7"), (11, "8.0189e-8")),
    65: ((7, "1.1544e-4"), (13, "2.5538e-7"), (13, "8.5678e-7")),
    73: ((12, "8.7525e-7"), (11, "7.6853e-7"), (10, "4.7666e-7")),
    78: ((11, "1.0848e-8"), (11, "3.4762e-8"), (12, "6.9853e-?")),
}
THESIS_AVG = ("6.8325e-4", "3.323e-? (text: 10^-4 or 10^-7)", "3.7214e-? (text: 10^-5)")


def _command(quick: bool) -> str:
    return f"`python bench/reproduce.py{' --quick' if quick else ''} --only paper4`"


@functools.lru_cache(maxsize=None)
def _views(name: str) -> Tuple[Tuple[np.ndarray, np.ndarray], ...]:
    m = datasets.load_cgal_mesh(name)
    v = m.vertices - m.vertices.mean(axis=0)
    v = v * (0.12 / np.ptp(v, axis=0).max())
    views = cad.render_views((v, np.asarray(m.faces)), resolution=RESOLUTION, num_threads=1)
    return tuple((np.asarray(w.points, np.float64), np.asarray(w.normals, np.float64)) for w in views)


def _align(points: np.ndarray, normals: np.ndarray, n: int, sigma_mm: float, seed: int) -> Dict[str, float]:
    """``n`` points of a view (source Y, CAD normals) against a copy under a random motion with Gaussian noise on
    the points (target X; its normals are the rotated CAD normals). Error: RMS over the known correspondences of
    the estimated against the true motion, sqrt(mean |T y_i - T_est y_i|^2), m."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(points), size=n, replace=n > len(points))
    y, ny = points[idx], normals[idx]
    R = Rotation.random(random_state=rng).as_matrix()
    t = rng.normal(size=3) * 0.1
    x = y @ R.T + t + rng.normal(scale=sigma_mm / 1000, size=y.shape)
    r = pose.align_flags(y, ny, x, ny @ R.T)
    T = np.asarray(r.T_target_source)
    est = y @ T[:3, :3].T + T[:3, 3]
    err = float(np.sqrt(np.mean(np.sum((y @ R.T + t - est) ** 2, axis=1))))
    noisy = float(np.sqrt(np.mean(np.sum((x - est) ** 2, axis=1))))
    f = r.source_flag
    offset = 1000 * float(np.linalg.norm(np.asarray(f.centroid) - np.asarray(f.foot)))
    return dict(valid=bool(r.valid), iterations=int(r.iterations), error=err if r.valid else math.nan,
                error_noisy=noisy if r.valid else math.nan, offset=offset, message=str(r.message))


def run(out: Path, quick: bool, log: Log) -> List[Section]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    views_per_model = 8 if quick else 42
    results: Dict[Tuple[float, int], Dict[int, Dict[str, float]]] = {}
    with Timer() as timer:
        clouds = []  # (thesis cloud number 1..84, points, normals)
        for mi, name in enumerate(MODELS):
            views = _views(name)
            picks = np.linspace(0, 41, views_per_model, dtype=int) if quick else range(42)
            clouds += [(42 * mi + int(v) + 1, *views[int(v)]) for v in picks]
        smallest = min(len(c[1]) for c in clouds)
        for sigma in (SIGMA_MM, SIGMA_EXTRA_MM):
            for n in SIZES:
                results[sigma, n] = {c: _align(p, nn, n, sigma, 100003 * n + c + int(1000 * sigma))
                                     for c, p, nn in clouds}
            log(f"paper4 sigma {sigma} mm: {len(clouds)} clouds x {len(SIZES)} sizes aligned")
    fig = out / "paper4_table1.png"
    _plot(results, fig)

    def stats(sigma, n):
        e = np.array([r["error"] for r in results[sigma, n].values()])
        ok = np.isfinite(e)
        return dict(mean=float(np.mean(e[ok])) if ok.any() else math.nan,
                    median=float(np.median(e[ok])) if ok.any() else math.nan,
                    p90=float(np.percentile(e[ok], 90)) if ok.any() else math.nan, valid=int(ok.sum()), n=len(e),
                    it=float(np.mean([r["iterations"] for r in results[sigma, n].values()])),
                    noisy=float(np.nanmean([r["error_noisy"] for r in results[sigma, n].values()])))

    st = {(s, n): stats(s, n) for s, n in results}
    rows = ["| cloud | thesis 100 pts: it, ε m | ours 100 | thesis 1000 | ours 1000 | thesis 10000 | ours 10000 |",
            "|---|---|---|---|---|---|---|"]
    for c, th in THESIS_ROWS.items():
        cells = []
        for k, n in enumerate(SIZES):
            r = results[SIGMA_MM, n].get(c)
            ours = "not run (quick)" if r is None else (f"{r['iterations']}, {r['error']:.3e}" if r["valid"]
                                                        else f"refused ({r['iterations']})")
            cells += [f"{th[k][0]}, {th[k][1]}", ours]
        rows.append(f"| {c} | " + " | ".join(cells) + " |")
    rows.append("| average | " + " | ".join(f"{THESIS_AVG[k]} | {st[SIGMA_MM, n]['mean']:.3e}"
                                           for k, n in enumerate(SIZES)) + " |")
    summary = ["| σ mm | points | clouds aligned | mean ε m | median ε m | 90th percentile m | mean iterations | "
               "RMS against the noisy points m |", "|---|---|---|---|---|---|---|---|"]
    for (s, n), x in st.items():
        summary.append(f"| {s:g} | {n} | {x['valid']}/{x['n']} | {x['mean']:.3e} | {x['median']:.3e} | "
                       f"{x['p90']:.3e} | {x['it']:.1f} | {x['noisy']:.3e} |")
    means = [st[SIGMA_MM, n]["mean"] for n in SIZES]
    medians = [st[SIGMA_MM, n]["median"] for n in SIZES]
    dec_mean = all(a > b for a, b in zip(means, means[1:]))
    dec_median = all(a > b for a, b in zip(medians, medians[1:]))
    checks = [Check("the error decreases with more points (P4 §4: 100 < 1000 < 10000 points, median ε)",
                    dec_median, "median ε " + ", ".join(f"{m:.2e} m at {n}" for m, n in zip(medians, SIZES)) +
                    "; mean " + ", ".join(f"{m:.2e}" for m in means))]
    worst = sorted(((r["error"], c, n, r["offset"]) for n in SIZES for c, r in results[SIGMA_MM, n].items()
                    if np.isfinite(r["error"])), reverse=True)[:3]
    # how the error depends on the centroid's distance from the average normal line (the lever of the rotation
    # about that line): rank correlation over all clouds and sizes at the main noise level
    e_all = np.array([r["error"] for n in SIZES for r in results[SIGMA_MM, n].values()])
    o_all = np.array([r["offset"] for n in SIZES for r in results[SIGMA_MM, n].values()])
    ok = np.isfinite(e_all)
    rho = float(spearmanr(e_all[ok], 1 / np.maximum(o_all[ok], 1e-9)).correlation) if ok.sum() > 2 else math.nan
    capped = {n: sum(r["iterations"] >= 100 for r in results[SIGMA_MM, n].values()) for n in SIZES}
    refused: Dict[str, List[str]] = {}
    for (s, n), x in results.items():
        for c, r in x.items():
            if not r["valid"]:
                refused.setdefault(f"cloud {c}: {r['message']}", []).append(f"{n} points at σ {s:g} mm")
    m100 = st[SIGMA_EXTRA_MM, SIZES[0]]["mean"]
    md = [f"Made by {_command(quick)}.", "",
          f"Set-up: {len(clouds)} viewpoint clouds ({MODELS[0]} = clouds 1-42, {MODELS[1]} = 43-84 when all 42 "
          f"views run; CGAL parts scaled to 120 mm, {RESOLUTION} px views with at least {smallest} points) x "
          f"{len(SIZES)} sizes ({', '.join(map(str, SIZES))} points drawn at random from each view) = "
          f"{len(clouds) * len(SIZES)} clouds"
          + (" (quick: 8 views per model; the full run has the thesis's 252)" if quick else " (the thesis's 252)")
          + ". Each is the source Y with the CAD normals of its triangles; the target X is Y under a uniformly random "
          "rotation and a translation ~ N(0, 0.1 m) per axis, with Gaussian noise of σ on every coordinate (the "
          f"thesis gives no level: σ = {SIGMA_MM:g} mm, the Zivid's depth resolution, and {SIGMA_EXTRA_MM:g} mm); "
          "X's normals are Y's rotated (noise-free normals, as from the CAD model). Error: RMS over the known "
          "correspondences, ε = sqrt(mean |T y_i − T_est y_i|²), against the noise-free moved points: against the "
          "noisy ones (the thesis's formula read literally) ε cannot fall below √3 σ "
          f"= {math.sqrt(3) * SIGMA_MM / 1000:.1e} m, yet the thesis reports errors down to 1e-8 m (last column "
          "below).", "",
          f"**Table 1** — iterations, ε (m); σ = {SIGMA_MM:g} mm; the thesis's columns as printed (the OCR lost "
          "several "
          "exponents, marked ?; its averages conflict with its rows, e.g. 1.0105e-2 for cloud 31 at 10000 points):",
          "", *rows, "", "Per size, all clouds:", "", *summary, "",
          "Thesis (P4 §4): average error 6.8325e-4 m at 100 points, 3.323e-? at 1000, 3.7214e-? at 10000; \"the "
          "error decreased as the number of samples increased ... the more the average will cancel out the added "
          "noise\".", "",
          "Ours: " + ("the error decreases with the number of points" if dec_median else
                      "the median error does not decrease monotonically with the number of points") +
          f" (median {medians[0]:.2e} → {medians[1]:.2e} → {medians[2]:.2e} m at σ {SIGMA_MM:g} mm), as the noise "
          "in the centroid and in the average line shrinks like 1/sqrt(n)"
          + ("" if dec_mean else "; the mean does not, being dominated by a few views") +
          ". The largest errors are " + ", ".join(f"cloud {c} at {n} points ({e:.1e} m, centroid {o:.1f} mm from "
                                                  f"the average normal line)" for e, c, n, o in worst) +
          f" (median distance over all clouds {np.median(o_all):.1f} mm); the rank correlation of ε with the inverse "
          f"of that distance (the lever that fixes the rotation about the line) is {rho:.2f}"
          + (", so a short lever explains the worst views" if rho > 0.5 else
             ", so the lever does not single out the worst views: at a given size the error is the noise's") +
          ". Our errors are one to "
          "two orders of magnitude below the thesis's 100-point average: its noise level is unknown and its normals "
          "may have been estimated from the noisy points (ours are exact). Iterations: ours are Levenberg-Marquardt "
          "steps until the relative cost decrease is below 1e-12, at most 100; the cap is reached by " +
          ", ".join(f"{capped[n]} of {len(clouds)} clouds at {n} points" for n in SIZES) +
          " (the thesis: 6-17 iterations)." +
          (" Refused (valid = False, the flag is undefined): " +
           "; ".join(f"{k} ({', '.join(v)})" for k, v in refused.items()) + "." if refused else "") +
          f" At σ = {SIGMA_EXTRA_MM:g} mm our 100-point mean is {m100:.1e} m, the order of the thesis's "
          "6.8325e-4 m: its noise may have been about 1 mm.", ""]
    return [Section("Thesis Paper 4, Table 1: flag alignment, 2 models x 42 views x 3 sizes", "\n".join(md), [fig],
                    checks, timer.seconds)]


def _plot(results, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sigmas = sorted({s for s, _ in results})
    fig, ax = plt.subplots(1, len(sigmas), figsize=(5 * len(sigmas), 4), sharey=True)
    for a, s in zip(np.atleast_1d(ax), sigmas):
        data = [np.log10([r["error"] for r in results[s, n].values() if np.isfinite(r["error"])]) for n in SIZES]
        a.boxplot(data, whis=(5, 95))
        a.set_xticks(range(1, len(SIZES) + 1), [str(n) for n in SIZES])
        a.set(xlabel="points per cloud", title=f"flag alignment, σ = {s:g} mm")
    np.atleast_1d(ax)[0].set_ylabel("log10 ε (m), RMS over the correspondences")
    np.atleast_1d(ax)[0].axhline(math.log10(6.8325e-4), color="red", ls=":", lw=0.8)
    np.atleast_1d(ax)[0].text(1, math.log10(6.8325e-4), " thesis mean, 100 pts", color="red", fontsize=7,
                              va="bottom")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

