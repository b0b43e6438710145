"""Cloud-to-mesh distance on a real mesh: scanalign.evaluation.MeshDistanceIndex (C++ bounding-volume
hierarchy, OpenMP) against the NumPy tree it replaced and Open3D's RaycastingScene.

The NumPy implementation is read from the git history (``--numpy-rev``, the last revision
that had it) rather than kept in the package; Open3D is optional.  Query points: samples of
the surface moved along random directions by up to ``--spread`` of the mesh's bounding-box
diagonal (a reconstructed cloud near its ground truth), plus ``--far`` of them anywhere in a
box twice the mesh's size.  Prints build and query times (best of ``--repeats``), points per
second and the largest absolute difference of each peer to the C++ distances.

    python bench/bench_mesh_distance.py [--mesh bunny00] [--points 200000] [--threads 0]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, Tuple

import numpy as np

import scanalign
from scanalign.data import downloads as datasets
from scanalign.data import parts
from scanalign.evaluation import MeshDistanceIndex

_ROOT = Path(__file__).resolve().parents[1]


def load_numpy_index(rev: str):
    """The NumPy MeshDistanceIndex class of python/scanalign/evaluation.py at git revision ``rev``."""
    text = subprocess.run(["git", "-C", str(_ROOT), "show", f"{rev}:python/scanalign/evaluation.py"],
                          check=True, capture_output=True, text=True).stdout
    spec = importlib.util.spec_from_loader("scanalign._evaluation_numpy", loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "scanalign"  # its relative imports resolve in the installed package
    sys.modules[spec.name] = module
    exec(compile(text, f"{rev}:evaluation.py", "exec"), module.__dict__)
    return module.MeshDistanceIndex


def best_of(repeats: int, fn: Callable[[], np.ndarray]) -> Tuple[float, np.ndarray]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def query_points(vertices: np.ndarray, faces: np.ndarray, n: int, spread: float, far: float) -> np.ndarray:
    rng = np.random.default_rng(0)
    diag = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    n_far = int(round(far * n))
    surface, _ = parts.sample_mesh((vertices, faces), n - n_far, seed=1)
    direction = rng.normal(size=surface.shape)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    near = surface + direction * rng.uniform(0, spread * diag, (len(surface), 1))
    centre, half = 0.5 * (vertices.max(0) + vertices.min(0)), vertices.max(0) - vertices.min(0)
    anywhere = centre + rng.uniform(-1, 1, (n_far, 3)) * half
    return np.ascontiguousarray(np.concatenate([near, anywhere]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh", default="bunny00", help="CGAL example mesh (scanalign.data.downloads.load_cgal_mesh)")
    ap.add_argument("--points", type=int, default=200_000)
    ap.add_argument("--spread", type=float, default=0.01, help="offset from the surface, fraction of the diagonal")
    ap.add_argument("--far", type=float, default=0.05, help="fraction of points anywhere in the doubled box")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0, help="OpenMP threads for the C++ index (0 = all)")
    ap.add_argument("--numpy-rev", default="e7fb466", help="git revision holding the NumPy implementation")
    args = ap.parse_args()

    mesh = datasets.load_cgal_mesh(args.mesh)
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    P = query_points(V, F, args.points, args.spread, args.far)
    print(f"mesh {args.mesh}: {len(V)} vertices, {len(F)} triangles; {len(P)} query points "
          f"(scanalign {scanalign.__version__})")

    t_build, index = best_of(args.repeats, lambda: MeshDistanceIndex(V, F))
    t_query, d = best_of(args.repeats, lambda: index.distance(P, num_threads=args.threads))
    print(f"{'scanalign C++ BVH':28s} build {t_build * 1e3:8.1f} ms  query {t_query * 1e3:9.1f} ms  "
          f"{len(P) / t_query:12.0f} points/s")

    peers = []
    try:
        NumpyIndex = load_numpy_index(args.numpy_rev)
        peers.append(("numpy tree (before C++)", lambda: NumpyIndex(V, F), lambda i: i.distance(P)))
    except (subprocess.CalledProcessError, FileNotFoundError, AttributeError) as e:
        print(f"numpy tree: not available at revision {args.numpy_rev} ({e})")
    try:
        import open3d as o3d

        def o3d_build():
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(V.astype(np.float32)), o3d.core.Tensor(F.astype(np.uint32)))
            return scene

        peers.append(("Open3D RaycastingScene f32", o3d_build,
                      lambda s: s.compute_distance(o3d.core.Tensor(P.astype(np.float32))).numpy().astype(np.float64)))
    except ImportError:
        print("Open3D: not installed")
    for name, build, query in peers:
        tb, peer = best_of(args.repeats, build)
        tq, dp = best_of(args.repeats, lambda: query(peer))
        print(f"{name:28s} build {tb * 1e3:8.1f} ms  query {tq * 1e3:9.1f} ms  {len(P) / tq:12.0f} points/s  "
              f"C++ is {tq / t_query:6.1f}x faster; max |difference| {np.max(np.abs(dp - d)):.3g}")


if __name__ == "__main__":
    main()
