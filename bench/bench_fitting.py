"""Sphere fits per second for 50-point neighbourhoods: scanalign.fitting.fit_spheres (one C++
call over all neighbourhoods, OpenMP) against a vectorised NumPy implementation of the same
CGA fit (same normalisation, same symmetric eigenproblem, batched numpy.linalg.eigh).

Prints fits per second for both, the ratio, and the largest centre difference.

    python bench/bench_fitting.py [--groups 20000] [--size 50] [--repeats 5] [--threads 0]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from scanalign.fitting import fit_spheres

_M = np.array([[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 0, -1], [0, 0, 0, -1, 0]], float)


def numpy_fit(points: np.ndarray) -> tuple:
    """(G, K, 3) points -> (G, 3) centres, (G,) radii. Thesis 5.31 with the symmetric
    pencil form used in sphere_fit.cpp (D a = lambda M a, largest eigenvalue of L^-1 M L^-T)."""
    m = points.mean(axis=1, keepdims=True)
    s = np.sqrt(((points - m) ** 2).sum(axis=2).mean(axis=1))[:, None, None]
    q = (points - m) / s
    P = np.concatenate([q, 0.5 * (q**2).sum(axis=2, keepdims=True), np.ones(q.shape[:2] + (1,))], axis=2)
    D = np.einsum("gki,gkj->gij", P, P) / points.shape[1]
    ev, V = np.linalg.eigh(D)
    ev = np.maximum(ev, ev[:, -1:] * 1e-30)
    LinvT = V / np.sqrt(ev)[:, None, :]
    C = np.einsum("gji,jk,gkl->gil", LinvT, _M, LinvT)
    _, W = np.linalg.eigh(C)
    a = np.einsum("gij,gj->gi", LinvT, W[:, :, -1])
    sv = a @ _M  # [S*] = M a (M symmetric)
    c = sv[:, :3] / sv[:, 4:5]
    r2 = (c**2).sum(axis=1) - 2 * sv[:, 3] / sv[:, 4]
    return m[:, 0] + s[:, 0] * c, s[:, 0, 0] * np.sqrt(np.abs(r2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--groups", type=int, default=20000)
    ap.add_argument("--size", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=0, help="OpenMP threads for the C++ call (0 = all)")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    G, K = args.groups, args.size
    centres = rng.uniform(-0.5, 0.5, (G, 1, 3)) + [0, 0, 0.8]
    radii = rng.uniform(0.005, 0.05, (G, 1, 1))
    d = rng.normal(size=(G, K, 3))
    d[..., 2] = np.abs(d[..., 2])  # a hemispherical cap, as a surface neighbourhood
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    pts = centres + (radii + rng.normal(0, 2e-4, (G, K, 1))) * d
    flat = np.ascontiguousarray(pts.reshape(-1, 3))
    offsets = np.arange(G + 1, dtype=np.int64) * K

    def timed(fn):
        times, out = [], None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return statistics.median(times), out

    def ours():  # the batch's centre and radius arrays, as the NumPy version returns them
        b = fit_spheres(flat, offsets, num_threads=args.threads)
        return b.center, b.radius

    t_cpp, (c_cpp, r_cpp) = timed(ours)
    t_np, (c_np, r_np) = timed(lambda: numpy_fit(pts))
    print(f"{G} neighbourhoods of {K} points, median of {args.repeats}")
    print(f"scanalign fit_spheres (C++)  {G / t_cpp:12.0f} fits/s  ({t_cpp * 1e3:8.2f} ms)")
    print(f"NumPy, vectorised            {G / t_np:12.0f} fits/s  ({t_np * 1e3:8.2f} ms)")
    print(f"ratio C++ / NumPy            {t_np / t_cpp:12.1f} x")
    print(f"max |centre difference|      {np.abs(c_cpp - c_np).max():.2e} m, "
          f"max |radius difference| {np.abs(r_cpp - r_np).max():.2e} m")


if __name__ == "__main__":
    main()
