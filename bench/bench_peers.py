"""scanalign against small_gicp, Open3D and PCL: speed *and* accuracy, in one command.

    pip install .[bench]            # or: .venv/bin/python -m pip install open3d small-gicp scipy
    python bench/bench_peers.py     # all sections, 9 interleaved repeats, 1 and 2 threads
    python bench/bench_peers.py --quick                       # smoke run, < 2 minutes
    python bench/bench_peers.py --sections dense lidar --repeats 5 --threads 1 2 4

Writes ``<out>/peers.json`` (every timing, every setting) and ``<out>/*.png`` (default
``bench/results/peers``) and prints markdown tables. A speed figure counts only at equal or
better accuracy, so every row carries its pose error against the reference (translation
mm, rotation deg) and its iteration count. ``ratio`` is always *method time / scanalign
float32 time* of the same case and thread count: above 1 the method is slower than
scanalign, below 1 it is faster.

Sections
--------
dense    Frame-to-model registration on the demo scan (``synthetic.builtin_scan(36)``,
         SR300 noise). Frames 0-9 build a model with the demo settings (crop 20 x 20 cm,
         10 mm normals, bilateral depth filter, 1 mm grid) in the robot base frame; frame 10
         is prepared exactly as the pipeline does (bilateral filter -> depth_to_cloud ->
         the reconstructor core's prepare: crop, 1 mm grid, normals): ~40k source points
         against a ~120k-point model with its normals; max distance 0.02 m. Two cases:
         ``dense/reconstructed``: the model the reconstructor built, init = its last pose
         (frame 9's estimate). The model itself has drifted from the robot's poses by
         frame 9 (reported as ``model_drift``), so every method's error against frame 10's
         reference includes that drift: compare rows with each other, not with zero.
         ``dense/reference-model``: the same frames merged at their reference poses (the
         same prepare and merge, no registration), init = frame 9's reference pose: the
         error is the registration's own.
lidar    Sparse outdoor LiDAR with a large motion: small_gicp's example pair with its
         reference (``datasets.small_gicp_lidar_pair()``), 0.25 m voxel grid
         (``reconstruction.voxel_grid``), 20-NN PCA target normals computed once here
         (scipy cKDTree + numpy, oriented towards the sensor at the origin), identity init,
         max distance 1.0 m. Extra rows run scanalign with a Huber kernel at 0.1 m
         (``robust_kernel="huber"``), the answer to small_gicp's better pose here, with
         our criteria and with small_gicp's default ones (1e-3 m, 0.1 deg).
Both registration sections also run scanalign coarse-to-fine (``coarse_stride=4``:
every 4th source point until converged, then all points until converged; its
iterations column shows coarse + full).
loop     The whole demo loop, raw depth + colour in -> model merged, 640x480, 36 frames:
         scanalign's ``Reconstructor`` with the demo settings (``scanalign demo``: each
         frame's ICP starts from the constant-velocity prediction, the last inter-frame
         motion applied again); the same with eye-in-hand paper's initial guess (Comput. Electron. Agric. 180 (2021) 105929) (the previous
         pose); the same loop built from Open3D parts and scanalign's loop with PCL's ICP,
         both from the same constant-velocity prediction. Per-frame wall time of the whole
         step (median over registered frames, also as Hz), the prepare / register /
         merge medians, and ATE against the robot's poses (``pipeline.trajectory_metrics``,
         as ``scanalign demo`` reports it). The loops advance frame by frame in lockstep
         (interleaved); ``--loop-repeats`` whole passes.
scaling  scanalign ICP time against source points (model fixed) and against model points
         (source fixed), on a CGAL mesh (bunny00, 15 cm, 0.5 m away) sampled with exact
         normals, a 1 degree / 5.8 mm motion and 0.5 mm noise; small_gicp and Open3D at the
         same sizes until one call exceeds ``--scaling-budget`` seconds. Tree build and
         alignment are timed apart (Open3D's build is timed by building a KDTreeFlann of the
         same target); log-log slopes are fitted per curve: the source sweep should be
         linear (slope ~1); the model sweep's alignment logarithmic (slope ~0), its build
         n log n.
memory   Peak resident memory per million model points of building ``registration.Icp``
         (float32 and float64), small_gicp's PointCloud + KdTree and Open3D's PointCloud
         + KDTreeFlann, each in a fresh child process (``python -c``): the peak (VmHWM,
         reset after the inputs exist) minus the resident size with the inputs in memory.
         And no growth over a long run: a ``Reconstructor`` (demo settings) fed 500 frames,
         twice round the demo loop at half resolution (250 frames per loop, the second
         loop with other sensor noise, so the model saturates and every frame registers),
         VmRSS and model size sampled every 25 frames; the second loop's slopes are fitted.

How each peer's settings map to ours
------------------------------------
All methods get the same arrays (float32 values; float64 copies of those values where a
peer takes only doubles), the same target normals, the same initial pose and the same
max correspondence distance. ICP semantics (PCL's, eye-in-hand paper §3.3): scanalign stops at 50
iterations or when the last increment moves < 1e-4 m (squared translation <= 1e-8) and
turns < 1.41e-4 rad (cos >= 1 - 1e-8), or when the correspondence MSE changes by a
relative 1e-8.

* scanalign ``registration.icp`` (float32 and float64 rows): the defaults above,
  point-to-plane LLS, ``num_threads`` = the thread count. Timed call: k-d tree build +
  ICP (numpy arrays are used without a copy).
* small_gicp ``align(target, source, target_tree, registration_type="PLANE_ICP")``, two
  rows: *ours* = ``max_iterations=50, translation_epsilon=1e-4, rotation_epsilon=1.41e-4``
  (our transformation epsilon written in its terms; small_gicp has no MSE criterion);
  *defaults* = its own 20 iterations, 1e-3 m, 0.1 deg. ``num_threads`` = the thread count
  for the tree and the reduction. Timed call: source ``PointCloud`` + ``KdTree`` of the
  target + align. Caveats: (1) small_gicp 1.0.1's Python ``PointCloud`` takes points only
  (its ``normals()`` returns a copy), so it cannot use our normals: its target normals
  are estimated once, untimed, by ``small_gicp.estimate_normals`` with k = the median
  number of target neighbours inside the radius our normals were fitted over (dense: the
  10 mm normal radius; lidar: k = 20, the same neighbourhoods as ours; scaling: 20); the
  median angle between its normals and ours is reported per case. (2) Its PLANE_ICP
  residual is the component-wise product ``n * (q - T p)`` (a 4-vector, squared norm), not
  the dot product ``n . (q - T p)`` of classic point-to-plane, and it solves with
  Levenberg-Marquardt: a different cost, so a different minimum. (3) Its ``iterations``
  is the 0-based index of the last iteration; the tables show that + 1 (correspondence
  searches).
* Open3D ``registration_icp(..., TransformationEstimationPointToPlane())``, two rows:
  *our iterations* = ``ICPConvergenceCriteria(relative_fitness=0, relative_rmse=0,
  max_iteration=<scanalign float32's iteration count on this case>)``: exactly as many
  iterations as we ran; *defaults* = ``ICPConvergenceCriteria()`` (1e-6, 1e-6, 30; Open3D
  has no transformation-change criterion). Threads: OpenMP, set by ``OMP_NUM_THREADS`` in
  the child process. Timed call: source ``PointCloud`` conversion + ``registration_icp``,
  which builds its KDTreeFlann of the target inside every call; the target ``PointCloud``
  with its normals is converted once, untimed. Open3D does not report iterations; they
  are counted from its debug log in the untimed warm-up call.
* PCL 1.13 ``IterativeClosestPointWithNormals`` (point-to-plane LLS) through
  ``registration.pcl_icp(variant="point_to_plane_lls")``: our criteria (the same
  ``IcpSettings``), single-threaded (PCL's ICP has no threads). Timed call: conversion to
  float32 PCL clouds + its FLANN k-d tree + ICP.

Every timed call therefore includes that method's own target index build. Each case runs
one untimed warm-up call per method, then ``--repeats`` rounds, each round calling every
method once (interleaved), and reports medians. Thread counts cannot be changed reliably
inside one process (Open3D's OpenMP pool), so each thread count runs in a child process
of this script (``OMP_NUM_THREADS=t``, ``num_threads=t``) with all peers; the parent
prepares the dense and lidar inputs once (so every child gets identical arrays), collects
the children's JSON, prints and plots. Missing peers are skipped with a note.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT / "python") not in sys.path and not any(Path(p).joinpath("scanalign").is_dir() for p in sys.path if p):
    sys.path.insert(0, str(ROOT / "python"))

sys.path.insert(0, str(ROOT / "tests"))
from helpers import rigid  # noqa: E402  (the tests' rigid-transform helper)
from scanalign.pipelines.reconstruct import _jsonable  # noqa: E402  (the report writer's JSON conversion)

SECTIONS = ("dense", "lidar", "loop", "scaling", "memory")
DEMO_CROP = (-0.1, 0.1, -0.1, 0.1, 0.1, 1.0)
DEMO_NORMAL_RADIUS = 0.01
DENSE_DISTANCE = 0.02
LIDAR_DISTANCE = 1.0
LIDAR_VOXEL = 0.25
LIDAR_K = 20
# The Huber scale of the robust rows on the LiDAR pair (m): about the residual noise
# after convergence on a 0.25 m grid.
LIDAR_ROBUST_SCALE = 0.1
# The known-motion LiDAR case: sensor noise (m) and its seed.
LIDAR_KNOWN_NOISE = 0.01
LIDAR_KNOWN_SEED = 11
# Our transformation epsilon (1e-8, PCL semantics) in small_gicp's terms: translation
# increment norm <= sqrt(1e-8) m, rotation increment angle <= acos(1 - 1e-8) rad.
SG_TRANSLATION_EPS = math.sqrt(1e-8)
SG_ROTATION_EPS = math.acos(1.0 - 1e-8)
# small_gicp's default criteria (translation 1e-3 m, rotation 0.1 deg) in ours: the
# squared translation (transformation_epsilon) and the cosine (transformation_rotation_epsilon).
SG_DEFAULT_TRANSLATION_EPS = 1e-3
SG_DEFAULT_ROTATION_EPS = math.radians(0.1)
SCANALIGN_F32 = "scanalign f32"
# The coarse-to-fine row: every 4th source point until converged, then all (IcpSettings.coarse_stride).
COARSE_STRIDE = 4
SCANALIGN_COARSE = f"scanalign f32 coarse-to-fine (stride {COARSE_STRIDE})"
# The demo's motion model (scanalign demo's --initial-guess default), applied to every loop.
DEMO_MOTION_MODEL = "constant_velocity"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- helpers


def pose_error(T_est: np.ndarray, T_ref: np.ndarray) -> Tuple[float, float]:
    """(translation error mm, rotation error deg) of T_est relative to T_ref."""
    from scanalign.common import rigid as se3

    rot, trans = se3.pose_error(T_est, T_ref)
    return trans * 1e3, math.degrees(rot)


def pca_normals(points: np.ndarray, k: int, viewpoint=(0.0, 0.0, 0.0)) -> np.ndarray:
    """k-NN PCA normals (the point itself included), oriented towards ``viewpoint``."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64)
    _, idx = cKDTree(p).query(p, k)
    nb = p[idx]
    c = nb - nb.mean(axis=1, keepdims=True)
    _, v = np.linalg.eigh(np.einsum("nki,nkj->nij", c, c))
    n = v[:, :, 0]
    n[np.einsum("ij,ij->i", n, np.asarray(viewpoint) - p) < 0] *= -1.0
    return n


def median_neighbours(points: np.ndarray, radius: float, samples: int = 2000) -> int:
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64)
    step = max(1, len(p) // samples)
    return int(np.median(cKDTree(p).query_ball_point(p[::step], radius, return_length=True)))


def normal_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Median angle between two normal fields, ignoring orientation."""
    cos = np.abs(np.einsum("ij,ij->i", a[:, :3], b[:, :3]))
    return float(np.degrees(np.median(np.arccos(np.clip(cos, 0.0, 1.0)))))


def rss_kb(field: str = "VmRSS") -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return -1


def child_env(threads: int) -> Dict[str, str]:
    """Environment of a child process: the thread count, and this scanalign importable."""
    import scanalign

    paths = [str(Path(scanalign.__file__).resolve().parent.parent)]
    if os.environ.get("PYTHONPATH"):
        paths.append(os.environ["PYTHONPATH"])
    return dict(os.environ, OMP_NUM_THREADS=str(threads), PYTHONPATH=os.pathsep.join(paths))


def load_peers() -> Dict[str, Any]:
    """Import the optional peers; missing ones map to a reason string."""
    peers: Dict[str, Any] = {}
    for name, module in (("open3d", "open3d"), ("small_gicp", "small_gicp")):
        try:
            peers[name] = __import__(module)
        except Exception as exc:  # ImportError, or a broken wheel
            peers[name] = f"{module} unavailable ({type(exc).__name__}: {exc}); pip install .[bench]"
    if not isinstance(peers["open3d"], str):
        peers["open3d"].utility.set_verbosity_level(peers["open3d"].utility.VerbosityLevel.Warning)
    return peers


def peer(peers: Dict[str, Any], name: str) -> Optional[Any]:
    return None if isinstance(peers.get(name), str) else peers.get(name)


def versions(peers: Dict[str, Any]) -> Dict[str, str]:
    out = {"python": platform.python_version(), "numpy": np.__version__}
    try:
        from importlib.metadata import version

        for dist in ("scanalign", "open3d", "small_gicp", "scipy"):
            try:
                out[dist] = version(dist)
            except Exception:
                pass
    except ImportError:  # pragma: no cover
        pass
    if peer(peers, "open3d") is not None:
        out["open3d"] = peers["open3d"].__version__
    return out


class StdoutCapture:
    """Capture what C/C++ code writes to file descriptor 1 (Open3D's debug log)."""

    def __enter__(self) -> "StdoutCapture":
        sys.stdout.flush()
        self._saved = os.dup(1)
        self._file = tempfile.TemporaryFile(mode="w+b")
        os.dup2(self._file.fileno(), 1)
        return self

    def __exit__(self, *exc: Any) -> None:
        sys.stdout.flush()
        os.dup2(self._saved, 1)
        os.close(self._saved)
        self._file.seek(0)
        self.text = self._file.read().decode(errors="replace")
        self._file.close()


# ----------------------------------------------------------------------------- registration methods


class Method:
    """One row: ``run()`` returns ``(T_target_source, iterations or None, extra dict)``."""

    def __init__(self, label: str, run: Callable[[], Tuple[np.ndarray, Optional[int], Dict[str, Any]]],
                 settings: str, warmup: Optional[Callable[[], Tuple[np.ndarray, Optional[int], Dict[str, Any]]]] = None):
        self.label, self.run, self.settings = label, run, settings
        self.warmup = warmup or run


def registration_methods(case: Dict[str, np.ndarray], threads: int, peers: Dict[str, Any], *,
                         normal_k: int, notes: List[str]) -> List[Method]:
    """The rows of a registration case; Open3D's 'our iterations' row is bound later."""
    from scanalign import registration

    src32 = np.ascontiguousarray(case["source"], dtype=np.float32)
    tgt32 = np.ascontiguousarray(case["target"], dtype=np.float32)
    nrm32 = np.ascontiguousarray(case["normals"], dtype=np.float32)
    src64, tgt64, nrm64 = (a.astype(np.float64) for a in (src32, tgt32, nrm32))
    init = np.asarray(case["init"], dtype=np.float64)
    dist = float(case["distance"])
    methods: List[Method] = []

    def sa(s, t, n, **extra):
        def run():
            r = registration.icp(s, t, n, init, max_correspondence_distance=dist, num_threads=threads, **extra)
            return r.T_target_source, int(r.iterations), {"status": r.status, "fitness": r.fitness,
                                                          "exact_search": bool(r.exact_search),
                                                          "coarse_iterations": int(r.coarse_iterations)}
        return run

    methods.append(Method(SCANALIGN_F32, sa(src32, tgt32, nrm32), "registration.icp float32, defaults (50 it, 1e-8, 1e-8)"))
    methods.append(Method("scanalign f64", sa(src64, tgt64, nrm64), "registration.icp float64, defaults"))
    methods.append(Method(SCANALIGN_COARSE, sa(src32, tgt32, nrm32, coarse_stride=COARSE_STRIDE),
                          f"registration.icp float32, defaults + coarse_stride={COARSE_STRIDE} "
                          "(iterations: coarse + full)"))
    if "robust_scale" in case:
        k = float(case["robust_scale"])
        methods.append(Method(f"scanalign f32 Huber {k:g} m", sa(src32, tgt32, nrm32, robust_kernel="huber", robust_scale=k),
                              f"registration.icp float32, defaults + robust_kernel='huber', robust_scale={k:g}"))
        methods.append(Method(f"scanalign f32 Huber {k:g} m (small_gicp's criteria)",
                              sa(src32, tgt32, nrm32, robust_kernel="huber", robust_scale=k,
                                 transformation_epsilon=SG_DEFAULT_TRANSLATION_EPS ** 2,
                                 transformation_rotation_epsilon=math.cos(SG_DEFAULT_ROTATION_EPS)),
                              f"as above, stopping as small_gicp's defaults: transformation_epsilon="
                              f"{SG_DEFAULT_TRANSLATION_EPS:g}^2 m^2, transformation_rotation_epsilon="
                              f"cos({SG_DEFAULT_ROTATION_EPS:.4g} rad)"))

    sg = peer(peers, "small_gicp")
    if sg is None:
        notes.append(f"small_gicp rows skipped: {peers['small_gicp']}")
    else:
        sg_target = sg.PointCloud(tgt64)
        t0 = time.perf_counter()
        sg.estimate_normals(sg_target, sg.KdTree(sg_target, threads), num_neighbors=normal_k, num_threads=threads)
        seconds = time.perf_counter() - t0
        angle = normal_angle_deg(sg_target.normals(), nrm64)
        notes.append(f"small_gicp target normals: its own estimate_normals(k={normal_k}) (untimed), "
                     f"median {angle:.2f} deg from the normals every other method uses")
        case.setdefault("small_gicp_normals", {"k": normal_k, "median_angle_deg": angle, "seconds": seconds})

        def sgrun(**crit):
            def run():
                tree = sg.KdTree(sg_target, threads)
                r = sg.align(sg_target, sg.PointCloud(src64), tree, init_T_target_source=init, registration_type="PLANE_ICP",
                             max_correspondence_distance=dist, num_threads=threads, **crit)
                return np.asarray(r.T_target_source), int(r.iterations) + 1, {"converged": bool(r.converged),
                                                                               "inliers": int(r.num_inliers)}
            return run

        methods.append(Method("small_gicp PLANE_ICP (our criteria)",
                              sgrun(max_iterations=50, translation_epsilon=SG_TRANSLATION_EPS,
                                    rotation_epsilon=SG_ROTATION_EPS),
                              f"max_iterations=50, translation_epsilon={SG_TRANSLATION_EPS:.3g}, "
                              f"rotation_epsilon={SG_ROTATION_EPS:.3g}, own normals k={normal_k}"))
        methods.append(Method("small_gicp PLANE_ICP (defaults)", sgrun(),
                              f"max_iterations=20, translation_epsilon=1e-3, rotation_epsilon=0.1 deg, own normals k={normal_k}"))

    o3d = peer(peers, "open3d")
    if o3d is None:
        notes.append(f"Open3D rows skipped: {peers['open3d']}")
    else:
        reg = o3d.pipelines.registration
        o3_target = o3d.geometry.PointCloud()
        o3_target.points = o3d.utility.Vector3dVector(tgt64)
        o3_target.normals = o3d.utility.Vector3dVector(nrm64)

        def o3run(criteria_fn):
            def call():
                source = o3d.geometry.PointCloud()
                source.points = o3d.utility.Vector3dVector(src64)
                return reg.registration_icp(source, o3_target, dist, init, reg.TransformationEstimationPointToPlane(),
                                            criteria_fn())

            def run():
                r = call()
                return np.asarray(r.transformation), None, {"fitness": r.fitness}

            def warmup():
                o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Debug)
                try:
                    with StdoutCapture() as cap:
                        r = call()
                finally:
                    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Warning)
                return np.asarray(r.transformation), cap.text.count("ICP Iteration #"), {"fitness": r.fitness}
            return run, warmup

        holder: Dict[str, int] = {}
        run, warm = o3run(lambda: reg.ICPConvergenceCriteria(relative_fitness=0.0, relative_rmse=0.0,
                                                             max_iteration=holder["iterations"]))
        m = Method("Open3D point-to-plane (our iterations)", run, "ICPConvergenceCriteria(0, 0, max_iteration=N)", warm)
        m.bind = holder  # type: ignore[attr-defined]
        methods.append(m)
        run, warm = o3run(lambda: reg.ICPConvergenceCriteria())
        methods.append(Method("Open3D point-to-plane (defaults)", run, "ICPConvergenceCriteria() = (1e-6, 1e-6, 30)",
                              warm))

    def pcl():
        r = registration.pcl_icp(src32, tgt32, nrm32, init, variant="point_to_plane_lls", max_correspondence_distance=dist)
        return r.T_target_source, int(r.iterations), {"status": r.status, "fitness": r.fitness}

    methods.append(Method("PCL ICPWithNormals (LLS)", pcl, "pcl_icp point_to_plane_lls, our IcpSettings, 1 thread"))
    return methods


def run_registration_case(name: str, case: Dict[str, Any], threads: int, repeats: int, peers: Dict[str, Any],
                          normal_k: int) -> Dict[str, Any]:
    notes: List[str] = []
    methods = registration_methods(case, threads, peers, normal_k=normal_k, notes=notes)
    ref = np.asarray(case["reference"], dtype=np.float64)
    warm: Dict[str, Tuple] = {}
    live: List[Method] = []
    for m in methods:  # warm-up: untimed, gives Open3D's iteration count, finds broken methods
        if m.label.startswith("Open3D") and hasattr(m, "bind"):
            if SCANALIGN_F32 not in warm:
                continue
            m.bind["iterations"] = max(1, int(warm[SCANALIGN_F32][1]))  # type: ignore[attr-defined]
        try:
            warm[m.label] = m.warmup()
            live.append(m)
        except Exception as exc:  # a peer failing on this input: report, keep going
            notes.append(f"{m.label} skipped: {type(exc).__name__}: {exc}")
    times: Dict[str, List[float]] = {m.label: [] for m in live}
    last: Dict[str, Tuple] = dict(warm)
    bar = _bar(repeats * len(live), f"t={threads} {name}")
    for _ in range(repeats):
        for m in live:
            t0 = time.perf_counter()
            out = m.run()
            times[m.label].append(time.perf_counter() - t0)
            last[m.label] = out
            bar.update(1)
    bar.close()
    rows = []
    for m in live:
        T, iterations, extra = last[m.label]
        if iterations is None:
            iterations = warm[m.label][1]
        e_mm, e_deg = pose_error(T, ref)
        rows.append(dict(case=name, method=m.label, threads=threads, settings=m.settings,
                         median_ms=statistics.median(times[m.label]) * 1e3,
                         min_ms=min(times[m.label]) * 1e3, times_ms=[t * 1e3 for t in times[m.label]],
                         iterations=iterations, error_mm=e_mm, error_deg=e_deg, T_target_source=np.asarray(T).tolist(),
                         **{k: v for k, v in extra.items()}))
    info = {k: v for k, v in case.items() if k in ("description", "model_drift", "small_gicp_normals", "init_error")}
    info.update(source_points=int(len(case["source"])), target_points=int(len(case["target"])),
                distance_m=float(case["distance"]))
    return dict(case=name, threads=threads, rows=rows, notes=notes, info=info)


class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _bar(total: int, desc: str):
    try:
        from tqdm import tqdm

        return tqdm(total=total, desc=desc, file=sys.stderr, leave=False, dynamic_ncols=True, mininterval=1.0)
    except ImportError:  # pragma: no cover
        log(desc)
        return _NoBar()


# ----------------------------------------------------------------------------- inputs (parent)


def demo_frames(n_frames: int = 36, resolution_scale: float = 1.0, seed: int = 0):
    from scanalign import synthetic

    return synthetic.builtin_scan(n_frames=n_frames, resolution_scale=resolution_scale, seed=seed).frames


def demo_reconstructor(frames, threads: int = 0, registration: str = "scanalign", motion_model: str = "previous"):
    from scanalign.reconstruction import BilateralFilterSettings, Reconstructor

    return Reconstructor(T_model_camera0=frames[0].T_base_camera, crop_box=list(DEMO_CROP),
                         normal_radius=DEMO_NORMAL_RADIUS, depth_filter=BilateralFilterSettings(), registration=registration,
                         num_threads=threads, icp=dict(num_threads=threads), motion_model=motion_model)


def prepare_like_pipeline(rec, frame):
    """A frame prepared exactly as ``Reconstructor.integrate`` does before registering."""
    from scanalign.reconstruction import bilateral_filter_depth, depth_to_cloud

    depth = frame.depth
    if rec.depth_filter is not None:
        depth = bilateral_filter_depth(depth, rec.depth_filter, depth_scale=frame.depth_scale,
                                       num_threads=rec.settings.num_threads)
    points, colors = depth_to_cloud(depth, frame.intrinsics, rgb=frame.rgb, depth_scale=frame.depth_scale,
                                    min_depth=rec.min_depth, max_depth=rec.max_depth, stride=rec.pixel_stride)
    return rec._core.prepare(points, colors)


def build_dense_inputs(path: Path) -> None:
    frames = demo_frames(36)
    src_frame = frames[10]
    out: Dict[str, Any] = {}
    # Case 1: the model the reconstructor builds (demo settings), init = its last pose.
    rec = demo_reconstructor(frames)
    for f in frames[:10]:
        r = rec.integrate(f)
        if not r.merged:
            raise RuntimeError(f"dense inputs: demo frame {f.index} was not merged ({r.status})")
    prepared = prepare_like_pipeline(rec, src_frame)
    model, normals = rec._core.model_points(), rec._core.model_normals()
    keep = np.isfinite(normals).all(axis=1)  # opposite normals cancelled in a voxel: no normal
    drift = pose_error(rec.last_pose, frames[9].T_base_camera)
    out["reconstructed"] = dict(source=prepared.points, target=model[keep], normals=normals[keep], init=rec.last_pose,
                                reference=src_frame.T_base_camera, distance=DENSE_DISTANCE,
                                model_drift=np.array(drift))
    # Case 2: the same frames merged at their reference poses (no registration).
    ref = demo_reconstructor(frames)
    for f in frames[:10]:
        ref._core.merge(prepare_like_pipeline(ref, f), f.T_base_camera)
    prepared = prepare_like_pipeline(ref, src_frame)
    model, normals = ref._core.model_points(), ref._core.model_normals()
    keep = np.isfinite(normals).all(axis=1)
    out["reference-model"] = dict(source=prepared.points, target=model[keep], normals=normals[keep],
                                  init=frames[9].T_base_camera, reference=src_frame.T_base_camera,
                                  distance=DENSE_DISTANCE, model_drift=np.zeros(2))
    np.savez(path, **{f"{case}:{k}": np.asarray(v) for case, d in out.items() for k, v in d.items()})


def build_lidar_inputs(path: Path) -> None:
    from scanalign.data import downloads as datasets
    from scanalign.reconstruction import voxel_grid

    raw_source, raw_target, T_ref = datasets.small_gicp_lidar_pair()
    source = voxel_grid(raw_source, LIDAR_VOXEL).points
    target = voxel_grid(raw_target, LIDAR_VOXEL).points
    normals = pca_normals(target, LIDAR_K)  # sensor at the target scan's origin
    common = {"init": np.eye(4), "distance": np.array(LIDAR_DISTANCE), "robust_scale": np.array(LIDAR_ROBUST_SCALE)}
    cases = {"lidar": dict(source=source, target=target, normals=normals, reference=T_ref, **common)}
    # The same regime with exact truth: the target scan moved by the pair's own motion,
    # sampled on a voxel grid shifted by half a voxel (other points than the target's)
    # with 1 cm noise. The error is then the method's own, not the reference's.
    rng = np.random.default_rng(LIDAR_KNOWN_SEED)
    moved = (raw_target - T_ref[:3, 3]) @ T_ref[:3, :3]  # T_ref^-1 applied: source frame
    shift = LIDAR_VOXEL / 2
    known = voxel_grid(moved + shift, LIDAR_VOXEL).points - shift
    known = known + rng.normal(0.0, LIDAR_KNOWN_NOISE, known.shape)
    cases["lidar-known-motion"] = dict(source=known, target=target, normals=normals, reference=T_ref, **common)
    np.savez(path, **{f"{case}:{k}": np.asarray(v) for case, d in cases.items() for k, v in d.items()})


def load_cases(path: Path) -> Dict[str, Dict[str, Any]]:
    cases: Dict[str, Dict[str, Any]] = {}
    with np.load(path) as z:
        for key in z.files:
            case, field = key.split(":", 1)
            cases.setdefault(case, {})[field] = z[key]
    return cases


# ----------------------------------------------------------------------------- sections (child)


def section_dense(args, threads: int, peers) -> Dict[str, Any]:
    out = {}
    for name, case in load_cases(Path(args.inputs) / "dense.npz").items():
        d = case.pop("model_drift")
        case["model_drift"] = {"translation_mm": float(d[0]), "rotation_deg": float(d[1])}
        case["init_error"] = dict(zip(("translation_mm", "rotation_deg"), pose_error(case["init"], case["reference"])))
        case["description"] = ("model built by the reconstructor (demo settings), init = its last pose"
                               if name == "reconstructed" else
                               "frames 0-9 merged at their reference poses, init = frame 9's reference pose")
        k = median_neighbours(case["target"], DEMO_NORMAL_RADIUS)
        if args.quick:  # estimate_normals with k ~ 600 takes ~10 s per case on 2 cores
            k = min(k, 100)
        out[f"dense/{name}"] = run_registration_case(f"dense/{name}", case, threads, args.repeats, peers, k)
    return out


def section_lidar(args, threads: int, peers) -> Dict[str, Any]:
    out = {}
    for name, case in load_cases(Path(args.inputs) / "lidar.npz").items():
        case["description"] = (
            f"small_gicp's outdoor LiDAR pair, {LIDAR_VOXEL} m voxel grid, {LIDAR_K}-NN PCA normals, identity init; "
            "the reference is small_gicp's (its own tests accept 2.5 deg / 0.2 m)" if name == "lidar" else
            f"the pair's target scan moved by the pair's reference motion (exact truth), resampled on a {LIDAR_VOXEL} m "
            f"grid shifted by half a voxel, {LIDAR_KNOWN_NOISE * 1e3:.0f} mm noise; the same target and normals, "
            "identity init")
        case["init_error"] = dict(zip(("translation_mm", "rotation_deg"), pose_error(case["init"], case["reference"])))
        out[name] = run_registration_case(name, case, threads, args.repeats, peers, LIDAR_K)
    return out


class Open3DLoop:
    """The demo loop from Open3D parts (see the module docstring of section ``loop``)."""

    def __init__(self, o3d, T0: np.ndarray, intrinsics, motion_model: str = DEMO_MOTION_MODEL) -> None:
        self.o3d, self.T0 = o3d, np.asarray(T0, dtype=np.float64)
        self.motion_model = motion_model
        self.K = o3d.camera.PinholeCameraIntrinsic(intrinsics.width, intrinsics.height, intrinsics.fx, intrinsics.fy,
                                                   intrinsics.cx, intrinsics.cy)
        self.box = o3d.geometry.AxisAlignedBoundingBox(np.array(DEMO_CROP[0::2]), np.array(DEMO_CROP[1::2]))
        self.model = None
        self.last_pose = self.T0.copy()
        self.previous_pose: Optional[np.ndarray] = None  # the merged pose before last_pose
        self.records: List[Dict[str, Any]] = []

    def integrate(self, frame) -> Dict[str, Any]:
        from scanalign.reconstruction import BilateralFilterSettings, bilateral_filter_depth

        o3d = self.o3d
        reg = o3d.pipelines.registration
        t0 = time.perf_counter()
        # Same input as scanalign's loop: the raw depth through scanalign's bilateral filter
        # (Open3D's legacy pipeline has no depth filter that skips invalid pixels).
        depth = bilateral_filter_depth(frame.depth, BilateralFilterSettings(), depth_scale=frame.depth_scale)
        depth = np.nan_to_num(depth, nan=0.0)
        t_filter = time.perf_counter() - t0
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(np.ascontiguousarray(frame.rgb)), o3d.geometry.Image(depth), depth_scale=1.0,
            depth_trunc=2.0, convert_rgb_to_intensity=False)
        pcd = o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, self.K)
        pcd = pcd.crop(self.box).voxel_down_sample(0.001)
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamRadius(DEMO_NORMAL_RADIUS))
        pcd.orient_normals_towards_camera_location(np.zeros(3))
        t1 = time.perf_counter()
        rec = dict(index=frame.index, timestamp=frame.timestamp, status="registered", merged=False,
                   frame_points=len(pcd.points), iterations=None, register_seconds=0.0, merge_seconds=0.0,
                   filter_seconds=t_filter)
        guess = self.last_pose
        if self.motion_model == "constant_velocity" and self.previous_pose is not None:
            # The same prediction as scanalign's tracker: the last motion applied again.
            guess = self.last_pose @ np.linalg.inv(self.previous_pose) @ self.last_pose
        T = guess
        if self.model is None:
            rec["status"] = "initialized"
        elif len(pcd.points) < 200:
            rec["status"] = "skipped_too_few_points"
        else:
            r = reg.registration_icp(pcd, self.model, DENSE_DISTANCE, guess, reg.TransformationEstimationPointToPlane(),
                                     reg.ICPConvergenceCriteria())
            T = np.asarray(r.transformation)
            rec["register_seconds"] = time.perf_counter() - t1
            rec["fitness"] = r.fitness
            delta = np.linalg.inv(guess) @ T
            angle = math.acos(max(-1.0, min(1.0, (np.trace(delta[:3, :3]) - 1) / 2)))
            if r.fitness < 0.3:
                rec["status"] = "skipped_low_fitness"
            elif np.linalg.norm(delta[:3, 3]) > 0.10 or angle > 0.5:
                rec["status"] = "skipped_motion"
        if rec["status"] in ("initialized", "registered"):
            t2 = time.perf_counter()
            pcd.transform(T)
            self.model = pcd if self.model is None else (self.model + pcd).voxel_down_sample(0.001)
            self.previous_pose = None if rec["status"] == "initialized" else self.last_pose
            self.last_pose = T
            rec["merge_seconds"] = time.perf_counter() - t2
            rec["merged"] = True
        rec["total_seconds"] = time.perf_counter() - t0
        rec["prepare_seconds"] = t1 - t0
        rec["T_model_camera"] = T
        rec["model_points"] = 0 if self.model is None else len(self.model.points)
        self.records.append(rec)
        return rec


class ScanalignLoop:
    """scanalign's Reconstructor (its engine or PCL's ICP), timed around the whole step."""

    def __init__(self, frames, threads: int, registration: str, motion_model: str = DEMO_MOTION_MODEL) -> None:
        self.rec = demo_reconstructor(frames, threads, registration, motion_model)
        self.records: List[Dict[str, Any]] = []

    def integrate(self, frame) -> Dict[str, Any]:
        t0 = time.perf_counter()
        r = self.rec.integrate(frame)
        wall = time.perf_counter() - t0
        # Wall time of the whole step: integrate()'s own total_seconds starts after the
        # bilateral filter and back-projection; those count as preparation here.
        rec = dict(index=frame.index, timestamp=frame.timestamp, status=r.status, merged=r.merged,
                   frame_points=r.frame_points, iterations=r.iterations, register_seconds=r.register_seconds,
                   merge_seconds=r.merge_seconds, total_seconds=wall,
                   prepare_seconds=wall - r.register_seconds - r.merge_seconds, fitness=r.fitness,
                   T_model_camera=np.asarray(r.T_model_camera), model_points=r.model_points)
        self.records.append(rec)
        return rec


def loop_summary(label: str, records: List[Dict[str, Any]], frames, threads: int, settings: str) -> Dict[str, Any]:
    from scanalign.pipelines.reconstruct import trajectory_metrics
    from scanalign.evaluation.trajectory import Trajectory

    reg = [r for r in records if r["status"] == "registered"]
    merged = [r for r in records if r["merged"]]
    ref_of = {f.index: np.asarray(f.T_base_camera) for f in frames}
    med = lambda key: statistics.median(r[key] for r in reg) * 1e3 if reg else None  # noqa: E731
    out: Dict[str, Any] = dict(method=label, threads=threads, settings=settings, frames=len(records),
                               registered=len(reg), merged=len(merged),
                               skipped=sorted({r["status"] for r in records if not r["merged"]}),
                               median_ms=med("total_seconds"), prepare_ms=med("prepare_seconds"),
                               register_ms=med("register_seconds"), merge_ms=med("merge_seconds"),
                               iterations=(statistics.median(r["iterations"] for r in reg)
                                           if reg and reg[0]["iterations"] is not None else None),
                               filter_ms=(med("filter_seconds") if reg and "filter_seconds" in reg[0] else None),
                               model_points=records[-1]["model_points"] if records else 0,
                               per_frame_ms=[r["total_seconds"] * 1e3 for r in records])
    out["hz"] = 1e3 / out["median_ms"] if out["median_ms"] else None
    if len(merged) >= 3:
        ts = np.array([r["timestamp"] for r in merged])
        est = Trajectory(ts, np.array([r["T_model_camera"] for r in merged]))
        ref = Trajectory(ts, np.array([ref_of[r["index"]] for r in merged]))
        m = trajectory_metrics(est, ref)
        out["ate_rmse_mm"] = m["ate_m"]["rmse"] * 1e3
        out["ate_max_mm"] = m["ate_m"]["max"] * 1e3
        out["rpe_rmse_mm"] = m["rpe_translation_m"]["rmse"] * 1e3
    return out


def section_loop(args, threads: int, peers) -> Dict[str, Any]:
    frames = demo_frames(36)
    if args.quick:
        frames = frames[: args.loop_frames or 6]
    elif args.loop_frames:
        frames = frames[: args.loop_frames]
    o3d = peer(peers, "open3d")
    notes = [] if o3d is not None else [f"Open3D loop skipped: {peers['open3d']}"]
    settings = {
        "scanalign": "Reconstructor, demo settings (crop, bilateral filter, 1 mm grid, 10 mm normals, ICP 0.02 m "
                     "from the constant-velocity prediction, 50 it / 1e-8 / 1e-8, fitness >= 0.3, converged)",
        "seed": "as scanalign, ICP from the previous pose (the eye-in-hand paper's initial guess, motion_model='previous')",
        "Open3D": "scanalign's bilateral filter -> RGBDImage.create_from_color_and_depth -> "
                  "PointCloud.create_from_rgbd_image -> crop -> voxel_down_sample(0.001) -> "
                  "estimate_normals(KDTreeSearchParamRadius(0.01)) oriented to the camera -> registration_icp "
                  "point-to-plane 0.02 m from the same constant-velocity prediction, ICPConvergenceCriteria() -> "
                  "fitness >= 0.3 and "
                  "motion checks -> transform, merge, voxel_down_sample(0.001)",
        "PCL": "scanalign's Reconstructor (its preparation, prediction and merge) with PCL "
               "IterativeClosestPointWithNormals (registration='pcl_point_to_plane_lls')",
    }
    passes: Dict[str, List[Dict[str, Any]]] = {}
    for p in range(args.loop_repeats):
        loops: List[Tuple[str, Any, str]] = [
            ("scanalign", ScanalignLoop(frames, threads, "scanalign"), settings["scanalign"]),
            ("scanalign, previous pose (seed)", ScanalignLoop(frames, threads, "scanalign", "previous"), settings["seed"])]
        if o3d is not None:
            loops.append(("Open3D loop", Open3DLoop(o3d, frames[0].T_base_camera, frames[0].intrinsics),
                          settings["Open3D"]))
        loops.append(("scanalign + PCL ICP", ScanalignLoop(frames, threads, "pcl_point_to_plane_lls"), settings["PCL"]))
        bar = _bar(len(frames) * len(loops), f"t={threads} loop pass {p + 1}/{args.loop_repeats}")
        for frame in frames:  # interleaved: every loop takes the same frame in turn
            for _, loop, _ in loops:
                loop.integrate(frame)
                bar.update(1)
        bar.close()
        for label, loop, s in loops:
            passes.setdefault(label, []).append(loop_summary(label, loop.records, frames, threads, s))
    rows = []
    for label, summaries in passes.items():
        row = dict(summaries[0])
        if len(summaries) > 1:  # medians over passes of each pass's median
            for key in ("median_ms", "prepare_ms", "register_ms", "merge_ms", "ate_rmse_mm", "ate_max_mm"):
                vals = [s[key] for s in summaries if s.get(key) is not None]
                row[key] = statistics.median(vals) if vals else None
            row["hz"] = 1e3 / row["median_ms"] if row["median_ms"] else None
            row["passes"] = summaries
        rows.append(row)
    return {"loop": dict(case="loop", threads=threads, rows=rows, notes=notes, info=dict(frames=len(frames)))}


def scaling_surface(n: int, seed: int):
    from scanalign.data import downloads as datasets
    from scanalign.data import parts

    mesh = datasets.load_cgal_mesh("bunny00")
    v = mesh.vertices - mesh.vertices.mean(axis=0)
    v = v * (0.15 / np.ptp(v, axis=0).max()) + [0.0, 0.0, 0.5]
    return parts.sample_mesh((v, mesh.faces), n, seed=seed)


SCALING_MOTION = rigid((0.3, 1.0, -0.4), math.radians(1.0), (0.004, -0.003, 0.003))


def section_scaling(args, threads: int, peers) -> Dict[str, Any]:
    from scanalign import registration

    if args.quick:
        src_sizes, src_fixed_model = [5_000, 20_000, 50_000], 50_000
        mdl_sizes, mdl_fixed_source = [20_000, 50_000, 200_000], 10_000
        repeats, budget = 1, min(args.scaling_budget, 5.0)
    else:
        src_sizes, src_fixed_model = [10_000, 50_000, 200_000, 1_000_000], 500_000
        mdl_sizes, mdl_fixed_source = [100_000, 500_000, 1_000_000, 2_000_000, 5_000_000], 50_000
        repeats, budget = args.scaling_repeats, args.scaling_budget
    sg, o3d = peer(peers, "small_gicp"), peer(peers, "open3d")
    notes = []
    if sg is None:
        notes.append(f"small_gicp skipped: {peers['small_gicp']}")
    if o3d is None:
        notes.append(f"Open3D skipped: {peers['open3d']}")
    rng = np.random.default_rng(3)
    src_all, _ = scaling_surface(max(src_sizes + [mdl_fixed_source]), seed=2)
    src_all = (src_all - SCALING_MOTION[:3, 3]) @ SCALING_MOTION[:3, :3]  # T^-1 p: the source's own frame
    src_all = (src_all + rng.normal(0.0, 0.0005, src_all.shape)).astype(np.float32)
    over_budget: Dict[str, bool] = {}
    rows: List[Dict[str, Any]] = []
    bar = _bar(len(src_sizes) + len(mdl_sizes), f"t={threads} scaling")

    def measure(sweep: str, n_src: int, n_tgt: int, tgt32: np.ndarray, nrm32: np.ndarray, sg_target) -> None:
        src32 = np.ascontiguousarray(src_all[:n_src])
        src64, tgt64, nrm64 = src32.astype(np.float64), tgt32.astype(np.float64), nrm32.astype(np.float64)
        calls: Dict[str, Callable[[], Tuple[float, float, np.ndarray, Optional[int]]]] = {}
        state: Dict[str, int] = {}

        def sa():
            t0 = time.perf_counter()
            eng = registration.Icp(tgt32, nrm32, max_correspondence_distance=DENSE_DISTANCE, num_threads=threads)
            t1 = time.perf_counter()
            r = eng.align(src32)
            t2 = time.perf_counter()
            state["iterations"] = int(r.iterations)
            state["exact_search"] = bool(r.exact_search)
            return t1 - t0, t2 - t1, r.T_target_source, int(r.iterations)
        calls[SCANALIGN_F32] = sa
        if sg is not None and not over_budget.get("small_gicp"):
            def sgc():
                t0 = time.perf_counter()
                tree = sg.KdTree(sg_target, threads)
                t1 = time.perf_counter()
                r = sg.align(sg_target, sg.PointCloud(src64), tree, registration_type="PLANE_ICP",
                             max_correspondence_distance=DENSE_DISTANCE, num_threads=threads, max_iterations=50,
                             translation_epsilon=SG_TRANSLATION_EPS, rotation_epsilon=SG_ROTATION_EPS)
                t2 = time.perf_counter()
                return t1 - t0, t2 - t1, np.asarray(r.T_target_source), int(r.iterations) + 1
            calls["small_gicp PLANE_ICP (our criteria)"] = sgc
        if o3d is not None and not over_budget.get("open3d"):
            reg = o3d.pipelines.registration
            o3_target = o3d.geometry.PointCloud()
            o3_target.points = o3d.utility.Vector3dVector(tgt64)
            o3_target.normals = o3d.utility.Vector3dVector(nrm64)

            def o3c():
                t0 = time.perf_counter()
                o3d.geometry.KDTreeFlann(o3_target)  # the same build registration_icp does inside
                t1 = time.perf_counter()
                source = o3d.geometry.PointCloud()
                source.points = o3d.utility.Vector3dVector(src64)
                r = reg.registration_icp(source, o3_target, DENSE_DISTANCE, np.eye(4),
                                         reg.TransformationEstimationPointToPlane(),
                                         reg.ICPConvergenceCriteria(0.0, 0.0, max(1, state.get("iterations", 30))))
                t2 = time.perf_counter()
                build = t1 - t0
                return build, (t2 - t1) - build, np.asarray(r.transformation), max(1, state.get("iterations", 30))
            calls["Open3D point-to-plane (our iterations)"] = o3c
        samples: Dict[str, List[Tuple[float, float]]] = {k: [] for k in calls}
        result: Dict[str, Tuple[np.ndarray, Optional[int]]] = {}
        for _ in range(repeats):
            for label, call in calls.items():
                build, align, T, it = call()
                samples[label].append((build, align))
                result[label] = (T, it)
        for label, s in samples.items():
            build = statistics.median(b for b, _ in s)
            align = statistics.median(a for _, a in s)
            total = statistics.median(b + a for b, a in s)
            e_mm, e_deg = pose_error(result[label][0], SCALING_MOTION)
            it = result[label][1]
            rows.append(dict(sweep=sweep, method=label, threads=threads, source_points=n_src, model_points=n_tgt,
                             total_ms=total * 1e3, build_ms=build * 1e3, align_ms=align * 1e3, iterations=it,
                             align_ms_per_iteration=align * 1e3 / it if it else None, error_mm=e_mm, error_deg=e_deg,
                             exact_search=state.get("exact_search") if label == SCANALIGN_F32 else None))
            if label == SCANALIGN_F32 and state.get("exact_search") is False:
                notes.append(f"scanalign: inexact k-d tree search at {n_tgt} model points (IcpResult.exact_search "
                             "False: the fixed search stack is exact up to 2**21 - 1 target points)")
            key = "small_gicp" if label.startswith("small_gicp") else "open3d" if label.startswith("Open3D") else None
            if key and total > budget:
                over_budget[key] = True
                notes.append(f"{label}: {total:.1f} s at {n_src} source / {n_tgt} model points > budget "
                             f"{budget:.0f} s; larger sizes skipped")
        bar.update(1)

    def make_target(n: int):
        tgt, nrm = scaling_surface(n, seed=1)
        tgt32, nrm32 = tgt.astype(np.float32), nrm.astype(np.float32)
        sg_target = None
        if sg is not None and not over_budget.get("small_gicp"):
            sg_target = sg.PointCloud(tgt32.astype(np.float64))
            sg.estimate_normals(sg_target, sg.KdTree(sg_target, threads), num_neighbors=20, num_threads=threads)
        return tgt32, nrm32, sg_target

    tgt32, nrm32, sg_target = make_target(src_fixed_model)
    for n in src_sizes:
        measure("source", n, src_fixed_model, tgt32, nrm32, sg_target)
    over_budget.clear()
    for n in mdl_sizes:
        tgt32, nrm32, sg_target = make_target(n)
        measure("model", mdl_fixed_source, n, tgt32, nrm32, sg_target)
    bar.close()
    fits = {}
    for sweep, size_key in (("source", "source_points"), ("model", "model_points")):
        for label in sorted({r["method"] for r in rows if r["sweep"] == sweep}):
            pts = [r for r in rows if r["sweep"] == sweep and r["method"] == label]
            if len(pts) >= 2:
                x = np.log([r[size_key] for r in pts])
                fits[f"{sweep}|{label}"] = {
                    key: float(np.polyfit(x, np.log([max(r[key], 1e-6) for r in pts]), 1)[0])
                    for key in ("total_ms", "align_ms", "build_ms", "align_ms_per_iteration")
                    if all(r[key] for r in pts)}
    return {"scaling": dict(case="scaling", threads=threads, rows=rows, fits=fits, notes=notes,
                            info=dict(mesh="bunny00 (CGAL), 15 cm, 0.5 m from the camera", noise_m=0.0005,
                                      motion="1 deg about (0.3, 1, -0.4), (4, -3, 3) mm", repeats=repeats,
                                      budget_s=budget, distance_m=DENSE_DISTANCE))}


# ----------------------------------------------------------------------------- memory (children of the parent)

MEMORY_CHILD = r"""
import json, sys, numpy as np
def st(f):
    for line in open('/proc/self/status'):
        if line.startswith(f + ':'):
            return int(line.split()[1])
kind, n = sys.argv[1], int(sys.argv[2])
if kind.startswith('scanalign'):
    from scanalign import registration
elif kind == 'small_gicp':
    import small_gicp
else:
    import open3d as o3d
base = st('VmRSS')
dtype = np.float64 if kind in ('scanalign_f64', 'small_gicp', 'open3d') else np.float32
pts = np.random.default_rng(0).random((n, 3), dtype=dtype)
nrm = np.zeros((n, 3), dtype=dtype); nrm[:, 2] = 1.0
inputs = st('VmRSS')
try:
    open('/proc/self/clear_refs', 'w').write('5')  # reset VmHWM: peak of what follows
    reset = True
except OSError:
    reset = False
if kind.startswith('scanalign'):
    keep = registration.Icp(pts, nrm, max_correspondence_distance=0.02)
elif kind == 'small_gicp':
    pc = small_gicp.PointCloud(pts); tree = small_gicp.KdTree(pc, 1)
    small_gicp.estimate_normals(pc, tree, num_neighbors=5)  # PLANE_ICP needs target normals
    keep = (pc, tree)
else:
    pc = o3d.geometry.PointCloud(); pc.points = o3d.utility.Vector3dVector(pts)
    pc.normals = o3d.utility.Vector3dVector(nrm); keep = (pc, o3d.geometry.KDTreeFlann(pc))
print(json.dumps(dict(kind=kind, n=n, base_kb=base, inputs_kb=inputs, peak_kb=st('VmHWM'), after_kb=st('VmRSS'),
                      hwm_reset=reset)))
"""


def memory_per_point(args, peers) -> Dict[str, Any]:
    sizes = [200_000, 500_000] if args.quick else [1_000_000, 2_000_000, 5_000_000]
    kinds = ["scanalign_f32", "scanalign_f64"]
    notes = []
    for name in ("small_gicp", "open3d"):
        if peer(peers, name) is None:
            notes.append(f"{name} skipped: {peers[name]}")
        else:
            kinds.append(name)
    env = child_env(1)
    rows = []
    for kind in kinds:
        for n in sizes:
            p = subprocess.run([sys.executable, "-c", MEMORY_CHILD, kind, str(n)], capture_output=True, text=True,
                               env=env)
            if p.returncode != 0:
                notes.append(f"{kind} {n}: child failed: {p.stderr.strip().splitlines()[-1:]}")
                continue
            r = json.loads(p.stdout.strip().splitlines()[-1])
            r["peak_mb"] = (r["peak_kb"] - r["inputs_kb"]) / 1024
            r["resident_mb"] = (r["after_kb"] - r["inputs_kb"]) / 1024
            r["peak_mb_per_million"] = r["peak_mb"] / (n / 1e6)
            r["resident_mb_per_million"] = r["resident_mb"] / (n / 1e6)
            r["bytes_per_point"] = r["peak_mb"] * 1024 * 1024 / n
            rows.append(r)
            log(f"  memory {kind:14s} {n:>9d} points: peak +{r['peak_mb']:.1f} MB "
                f"({r['peak_mb_per_million']:.1f} MB per million)")
    return dict(rows=rows, notes=notes,
                info="peak = VmHWM after building (reset once the inputs exist) - VmRSS with the inputs; inputs: "
                     "float32 for scanalign_f32, float64 otherwise; scanalign: Icp (k-d tree + normals kept); "
                     "small_gicp: PointCloud (Vector4d points) + KdTree + its normals (estimate_normals, k=5: PLANE_ICP needs them); "
                     "Open3D: PointCloud with normals + KDTreeFlann")


def memory_sequence_child(args) -> Dict[str, Any]:
    """Runs in a child: a Reconstructor fed a long synthetic loop, VmRSS every N frames."""
    n_frames = args.seq_frames or (60 if args.quick else 500)
    every = 10 if args.quick else 25
    t0 = time.perf_counter()
    # Twice round the demo loop (n/2 frames each, the second with other sensor noise): the
    # first loop grows the model, the second revisits every view, so the model saturates
    # and resident memory must stay flat.
    half = n_frames // 2
    frames = demo_frames(half, resolution_scale=0.5, seed=0) + demo_frames(half, resolution_scale=0.5, seed=1)
    render = time.perf_counter() - t0
    rec = demo_reconstructor(frames, threads=args.child_threads)
    samples = [dict(frame=0, rss_mb=rss_kb() / 1024, model_points=0)]
    statuses: Dict[str, int] = {}
    bar = _bar(len(frames), "memory sequence")
    for i, f in enumerate(frames, start=1):
        r = rec.integrate(f)
        statuses[r.status] = statuses.get(r.status, 0) + 1
        if i % every == 0 or i == len(frames):
            samples.append(dict(frame=i, rss_mb=rss_kb() / 1024, model_points=r.model_points))
        bar.update(1)
    bar.close()
    second = [s for s in samples if s["frame"] >= half]

    def slope(key: str) -> Optional[float]:
        if len(second) < 2:
            return None
        return float(np.polyfit([s["frame"] for s in second], [s[key] for s in second], 1)[0] * 100)

    rss_slope, model_slope = slope("rss_mb"), slope("model_points")
    per_point = (rss_slope * 1024 * 1024 / model_slope) if (rss_slope is not None and model_slope) else None
    return dict(frames=len(frames), every=every, render_seconds=render, statuses=statuses, samples=samples,
                rss_growth_mb_per_100_frames_second_loop=rss_slope,
                model_growth_points_per_100_frames_second_loop=model_slope,
                rss_bytes_per_added_model_point_second_loop=per_point,
                peak_rss_mb=rss_kb("VmHWM") / 1024,
                scan=f"twice round the demo loop, {half} frames each (noise seeds 0 and 1), 320x240 "
                     f"(builtin_scan resolution_scale 0.5), demo settings")


# ----------------------------------------------------------------------------- parent: orchestration


def run_child(args, threads: int, sections: List[str], inputs: Path) -> Dict[str, Any]:
    out = inputs / f"child_t{threads}.json"
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--child-threads", str(threads),
           "--inputs", str(inputs), "--child-json", str(out), "--repeats", str(args.repeats),
           "--scaling-repeats", str(args.scaling_repeats), "--scaling-budget", str(args.scaling_budget),
           "--loop-repeats", str(args.loop_repeats), "--sections", *sections]
    if args.quick:
        cmd.append("--quick")
    if args.loop_frames:
        cmd += ["--loop-frames", str(args.loop_frames)]
    if args.seq_frames:
        cmd += ["--seq-frames", str(args.seq_frames)]
    env = child_env(threads)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env)
    if p.returncode != 0:
        raise SystemExit(f"child process for {threads} thread(s) failed (exit {p.returncode})")
    log(f"[bench_peers] {threads} thread(s) done in {time.perf_counter() - t0:.0f} s")
    return json.loads(out.read_text())


def child_main(args) -> int:
    peers = load_peers()
    t = args.child_threads
    results: Dict[str, Any] = {}
    if "memory-sequence" in args.sections:
        results["memory_sequence"] = memory_sequence_child(args)
    for section, fn in (("dense", section_dense), ("lidar", section_lidar), ("loop", section_loop),
                        ("scaling", section_scaling)):
        if section in args.sections:
            log(f"[bench_peers] threads={t}: {section}")
            t0 = time.perf_counter()
            results.update(fn(args, t, peers))
            log(f"[bench_peers] threads={t}: {section} done in {time.perf_counter() - t0:.0f} s")
    Path(args.child_json).write_text(json.dumps(_jsonable(results)))
    return 0


# ----------------------------------------------------------------------------- tables


def fmt(v: Any, spec: str = ".2f") -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float) and not math.isfinite(v):
        return "n/a"
    return format(v, spec) if isinstance(v, (int, float)) else str(v)


RATIO_HEADER = "ratio (method ms / scanalign f32 ms; >1 = slower than scanalign)"


def add_ratios(rows: List[Dict[str, Any]], time_key: str, base_label: str, group_keys: Tuple[str, ...]) -> None:
    base = {tuple(r[k] for k in group_keys): r[time_key] for r in rows if r["method"] == base_label}
    for r in rows:
        b = base.get(tuple(r[k] for k in group_keys))
        r["ratio"] = (r[time_key] / b) if (b and r.get(time_key) is not None) else None


def registration_table(case: str, blocks: List[Dict[str, Any]]) -> str:
    rows = [r for b in blocks for r in b["rows"]]
    add_ratios(rows, "median_ms", SCANALIGN_F32, ("case", "threads"))
    info = blocks[0]["info"]
    lines = [f"### {case}", ""]
    desc = info.get("description", "")
    lines.append(f"{desc}; {info['source_points']} source points, {info['target_points']} target points, "
                 f"max distance {info['distance_m']} m.")
    if info.get("init_error"):
        lines.append(f"Initial pose error: {info['init_error']['translation_mm']:.2f} mm, "
                     f"{info['init_error']['rotation_deg']:.3f} deg.")
    drift = info.get("model_drift")
    if drift and drift.get("translation_mm"):
        lines.append(f"The model's own drift (frame 9's estimate vs its reference): {drift['translation_mm']:.2f} mm, "
                     f"{drift['rotation_deg']:.3f} deg; every row's error includes it.")
    lines += ["", f"| method | threads | median ms | iterations | {RATIO_HEADER} | error mm | error deg |",
              "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        its = fmt(r['iterations'], 'd')
        if r.get("coarse_iterations"):
            its = f"{r['coarse_iterations']}+{its}"
        lines.append(f"| {r['method']} | {r['threads']} | {fmt(r['median_ms'])} | {its} | "
                     f"{fmt(r['ratio'])} | {fmt(r['error_mm'], '.3f')} | {fmt(r['error_deg'], '.4f')} |")
    return with_notes(lines, blocks)


def with_notes(lines: List[str], blocks: List[Dict[str, Any]]) -> str:
    """The table's lines, then every block's notes once, as markdown."""
    notes = sorted({n for b in blocks for n in b["notes"]})
    if notes:
        lines = lines + [""] + [f"- {n}" for n in notes]
    return "\n".join(lines)


def loop_table(blocks: List[Dict[str, Any]]) -> str:
    rows = [r for b in blocks for r in b["rows"]]
    add_ratios(rows, "median_ms", "scanalign", ("threads",))
    lines = ["### loop", "", f"The demo loop over {blocks[0]['info']['frames']} frames (640x480, raw depth + colour "
             "in -> model merged); per-frame wall time over registered frames.", "",
             "| method | threads | median Hz | median ms | prepare ms | register ms | merge ms | iterations | "
             "ratio (method ms / scanalign ms; >1 = slower) | merged / frames | ATE rmse mm | ATE max mm |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['threads']} | {fmt(r['hz'], '.2f')} | {fmt(r['median_ms'], '.1f')} | "
                     f"{fmt(r['prepare_ms'], '.1f')} | {fmt(r['register_ms'], '.1f')} | {fmt(r['merge_ms'], '.1f')} | "
                     f"{fmt(r['iterations'], '.0f')} | {fmt(r['ratio'])} | {r['merged']} / {r['frames']} | "
                     f"{fmt(r.get('ate_rmse_mm'))} | {fmt(r.get('ate_max_mm'))} |")
    return with_notes(lines, blocks)


def scaling_table(blocks: List[Dict[str, Any]]) -> str:
    rows = [r for b in blocks for r in b["rows"]]
    add_ratios(rows, "total_ms", SCANALIGN_F32, ("sweep", "threads", "source_points", "model_points"))
    info = blocks[0]["info"]
    lines = ["### scaling", "", f"{info['mesh']}, noise {info['noise_m'] * 1e3:.1f} mm, motion {info['motion']}, "
             f"{info['repeats']} repeat(s); total = tree build + align.", "",
             f"| sweep | method | threads | source pts | model pts | total ms | build ms | align ms | iterations | "
             f"align ms / it | {RATIO_HEADER} | error mm | error deg |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['sweep']} | {r['method']} | {r['threads']} | {r['source_points']} | {r['model_points']} | "
                     f"{fmt(r['total_ms'], '.1f')} | {fmt(r['build_ms'], '.1f')} | {fmt(r['align_ms'], '.1f')} | "
                     f"{fmt(r['iterations'], 'd')} | {fmt(r['align_ms_per_iteration'], '.2f')} | {fmt(r['ratio'])} | "
                     f"{fmt(r['error_mm'], '.3f')} | {fmt(r['error_deg'], '.4f')} |")
    lines += ["", "Fitted log-log slopes (time ~ size^slope):", "",
              "| threads | sweep | method | total | build | align | align / it |", "| ---: | --- | --- | ---: | ---: | ---: | ---: |"]
    for b in blocks:
        for key, f in b["fits"].items():
            sweep, label = key.split("|", 1)
            lines.append(f"| {b['threads']} | {sweep} | {label} | {fmt(f.get('total_ms'))} | {fmt(f.get('build_ms'))} | "
                         f"{fmt(f.get('align_ms'))} | {fmt(f.get('align_ms_per_iteration'))} |")
    return with_notes(lines, blocks)


def memory_tables(mem: Dict[str, Any]) -> str:
    lines = ["### memory", ""]
    per = mem.get("per_point")
    if per:
        lines += [per["info"] + ".", "", "| method | model points | peak MB | resident MB | peak MB per million | "
                  "bytes per point |", "| --- | ---: | ---: | ---: | ---: | ---: |"]
        for r in per["rows"]:
            lines.append(f"| {r['kind']} | {r['n']} | {r['peak_mb']:.1f} | {r['resident_mb']:.1f} | "
                         f"{r['peak_mb_per_million']:.1f} | {r['bytes_per_point']:.0f} |")
        lines += [f"- {n}" for n in per["notes"]]
    seq = mem.get("sequence")
    if seq:
        s = seq["samples"]
        lines += ["", f"Long run: {seq['frames']} frames, {seq['scan']}; statuses {seq['statuses']}; "
                  f"VmRSS {s[0]['rss_mb']:.0f} MB before the first frame, {s[-1]['rss_mb']:.0f} MB after "
                  f"{s[-1]['frame']} (peak {seq['peak_rss_mb']:.0f} MB); over the second loop VmRSS changes by "
                  f"{fmt(seq['rss_growth_mb_per_100_frames_second_loop'])} MB and the model by "
                  f"{fmt(seq['model_growth_points_per_100_frames_second_loop'], '.0f')} points per 100 frames "
                  f"(linear fit; {fmt(seq['rss_bytes_per_added_model_point_second_loop'], '.0f')} bytes of VmRSS per "
                  f"added model point); model {s[-1]['model_points']} points at the end.", "",
                  "| frame | VmRSS MB | model points |", "| ---: | ---: | ---: |"]
        for x in s:
            lines.append(f"| {x['frame']} | {x['rss_mb']:.1f} | {x['model_points']} |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- plots


def plot_all(results: Dict[str, Any], out: Path) -> List[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    reg_cases = [c for c in results if c.startswith("dense/") or (c.startswith("lidar") and c != "lidar_skipped")]
    if reg_cases:
        fig, axes = plt.subplots(1, len(reg_cases), figsize=(6.5 * len(reg_cases), 5.2), squeeze=False)
        for ax, case in zip(axes[0], reg_cases):
            rows = [r for b in results[case] for r in b["rows"]]
            labels = list(dict.fromkeys(r["method"] for r in rows))
            threads = sorted({r["threads"] for r in rows})
            width = 0.8 / len(threads)
            for j, t in enumerate(threads):
                vals = [next((r["median_ms"] for r in rows if r["method"] == m and r["threads"] == t), np.nan)
                        for m in labels]
                bars = ax.barh(np.arange(len(labels)) + j * width, vals, height=width, label=f"{t} thread(s)")
                for bar, m in zip(bars, labels):
                    r = next((r for r in rows if r["method"] == m and r["threads"] == t), None)
                    if r is not None:
                        ax.text(bar.get_width(), bar.get_y() + bar.get_height() / 2,
                                f" {r['error_mm']:.2f} mm / {r['error_deg']:.3f}°", va="center", fontsize=6)
            ax.set_yticks(np.arange(len(labels)) + width * (len(threads) - 1) / 2)
            ax.set_yticklabels(labels, fontsize=7)
            ax.invert_yaxis()
            ax.set_xlabel("median ms per call (index build included); label: error vs reference")
            ax.set_title(case)
            ax.legend(fontsize=7)
            ax.grid(axis="x", lw=0.3)
            ax.set_xlim(0, ax.get_xlim()[1] * 1.45)
        fig.tight_layout()
        written.append(out / "registration.png")
        fig.savefig(written[-1], dpi=130)
        plt.close(fig)
    if "loop" in results:
        fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
        for b in results["loop"]:
            for r in b["rows"]:
                axes[0].plot(r["per_frame_ms"], label=f"{r['method']} ({b['threads']} t)", lw=1)
        axes[0].set_xlabel("frame")
        axes[0].set_ylabel("ms per frame (raw depth in -> merged)")
        axes[0].legend(fontsize=7)
        axes[0].grid(lw=0.3)
        rows = [(f"{r['method']}\n{b['threads']} t", r) for b in results["loop"] for r in b["rows"]]
        axes[1].bar(range(len(rows)), [r["hz"] or 0 for _, r in rows])
        for i, (_, r) in enumerate(rows):
            axes[1].text(i, r["hz"] or 0, f"ATE {fmt(r.get('ate_rmse_mm'))} mm", ha="center", va="bottom", fontsize=7)
        axes[1].set_xticks(range(len(rows)))
        axes[1].set_xticklabels([lbl for lbl, _ in rows], fontsize=7)
        axes[1].set_ylabel("median frames per second")
        axes[1].grid(axis="y", lw=0.3)
        fig.tight_layout()
        written.append(out / "loop.png")
        fig.savefig(written[-1], dpi=130)
        plt.close(fig)
    if "scaling" in results:
        fig, axes = plt.subplots(1, 2, figsize=(13, 5))
        for ax, (sweep, key, xl) in zip(axes, (("source", "source_points", "source points (model fixed)"),
                                               ("model", "model_points", "model points (source fixed)"))):
            for b in results["scaling"]:
                for label in dict.fromkeys(r["method"] for r in b["rows"] if r["sweep"] == sweep):
                    pts = [r for r in b["rows"] if r["sweep"] == sweep and r["method"] == label]
                    x = [r[key] for r in pts]
                    f = b["fits"].get(f"{sweep}|{label}", {})
                    line, = ax.loglog(x, [r["total_ms"] for r in pts], "o-",
                                      label=f"{label}, {b['threads']} t: total, slope {fmt(f.get('total_ms'))}")
                    if sweep == "model":
                        ax.loglog(x, [r["align_ms"] for r in pts], "s--", color=line.get_color(), alpha=0.7,
                                  label=f"{label}, {b['threads']} t: align only, slope {fmt(f.get('align_ms'))}")
            ax.set_xlabel(xl)
            ax.set_ylabel("ms")
            ax.grid(which="both", lw=0.3)
            ax.legend(fontsize=6)
            ax.set_title(f"{sweep} sweep")
        fig.tight_layout()
        written.append(out / "scaling.png")
        fig.savefig(written[-1], dpi=130)
        plt.close(fig)
    mem = results.get("memory")
    if mem:
        fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
        per = mem.get("per_point")
        if per and per["rows"]:
            kinds = list(dict.fromkeys(r["kind"] for r in per["rows"]))
            for kind in kinds:
                pts = [r for r in per["rows"] if r["kind"] == kind]
                axes[0].plot([r["n"] / 1e6 for r in pts], [r["peak_mb"] for r in pts], "o-", label=kind)
            axes[0].set_xlabel("model points (millions)")
            axes[0].set_ylabel("peak MB above the inputs")
            axes[0].legend(fontsize=7)
            axes[0].grid(lw=0.3)
        seq = mem.get("sequence")
        if seq:
            f = [s["frame"] for s in seq["samples"]]
            axes[1].plot(f, [s["rss_mb"] for s in seq["samples"]], "o-")
            axes[1].set_xlabel("frame")
            axes[1].set_ylabel("VmRSS MB")
            axes[1].set_title(f"resident memory over {seq['frames']} frames")
            axes[1].grid(lw=0.3)
            axes[2].plot(f, [s["model_points"] for s in seq["samples"]], "o-", color="tab:green")
            axes[2].set_xlabel("frame")
            axes[2].set_ylabel("model points")
            axes[2].grid(lw=0.3)
        fig.tight_layout()
        written.append(out / "memory.png")
        fig.savefig(written[-1], dpi=130)
        plt.close(fig)
    return written


# ----------------------------------------------------------------------------- main


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sections", nargs="+", default=list(SECTIONS),
                    help=f"any of {' '.join(SECTIONS)} (default: all)")
    ap.add_argument("--quick", action="store_true", help="smoke run (< 2 minutes): small sizes, 2 repeats")
    ap.add_argument("--repeats", type=int, default=None, help="interleaved repeats per case (default 9; --quick 2)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts, one child each (1 2)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "peers"), help="output folder")
    ap.add_argument("--loop-repeats", type=int, default=1, help="whole passes of the loop section (1)")
    ap.add_argument("--loop-frames", type=int, default=0, help="use only the first N demo frames in the loop")
    ap.add_argument("--scaling-repeats", type=int, default=3, help="repeats per scaling size (3; --quick 1)")
    ap.add_argument("--scaling-budget", type=float, default=30.0,
                    help="skip a peer's larger sizes once one call takes longer, seconds (30)")
    ap.add_argument("--seq-frames", type=int, default=0,
                    help="memory: frames of the long run, twice round the loop (500; --quick 60)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--child-threads", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--child-json", help=argparse.SUPPRESS)
    ap.add_argument("--inputs", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.repeats is None:
        args.repeats = 2 if args.quick else 9
    bad = [s for s in args.sections if s not in SECTIONS + ("memory-sequence",)]
    if bad:
        ap.error(f"unknown section(s) {bad}; choose from {SECTIONS}")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.child:
        return child_main(args)
    t_start = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    peers = load_peers()
    for name in ("open3d", "small_gicp"):
        if peer(peers, name) is None:
            log(f"[bench_peers] {peers[name]}: its rows are skipped")
    results: Dict[str, Any] = {}
    per_thread = [s for s in args.sections if s in ("dense", "lidar", "loop", "scaling")]
    with tempfile.TemporaryDirectory(prefix="bench_peers_") as tmp:
        inputs = Path(tmp)
        if "dense" in per_thread:
            log("[bench_peers] dense: rendering the demo scan and building the models (frames 0-9)")
            build_dense_inputs(inputs / "dense.npz")
        if "lidar" in per_thread:
            log("[bench_peers] lidar: loading small_gicp's LiDAR pair")
            from scanalign.data import downloads as datasets

            try:
                build_lidar_inputs(inputs / "lidar.npz")
            except datasets.DatasetUnavailableError as exc:
                log(f"[bench_peers] lidar skipped: {exc}")
                per_thread.remove("lidar")
                results["lidar_skipped"] = str(exc)
        if per_thread:
            for t in args.threads:
                log(f"[bench_peers] child process: {t} thread(s), sections {' '.join(per_thread)}")
                child = run_child(args, t, per_thread, inputs)
                for key, block in child.items():
                    results.setdefault(key, []).append(block)
        if "memory" in args.sections:
            log("[bench_peers] memory: per million model points (child processes)")
            mem: Dict[str, Any] = {"per_point": memory_per_point(args, peers)}
            log("[bench_peers] memory: long reconstruction run (child process)")
            t = max(args.threads)
            child = run_child(argparse.Namespace(**{**vars(args), "sections": ["memory-sequence"]}), t,
                              ["memory-sequence"], inputs)
            mem["sequence"] = child["memory_sequence"]
            results["memory"] = mem
    # Tables.
    tables = []
    for case in [c for c in results if c.startswith("dense/")] + [c for c in results if c.startswith("lidar")
                                                                  and c != "lidar_skipped"]:
        tables.append(registration_table(case, results[case]))
    if "loop" in results:
        tables.append(loop_table(results["loop"]))
    if "scaling" in results:
        tables.append(scaling_table(results["scaling"]))
    if "memory" in results:
        tables.append(memory_tables(results["memory"]))
    text = "\n\n".join(tables)
    print(text)
    pngs = plot_all(results, out)
    report = dict(
        command=" ".join([Path(sys.executable).name, *sys.argv]),
        machine=dict(platform=platform.platform(), processor=platform.processor(), cpus=os.cpu_count()),
        versions=versions(peers), args={k: v for k, v in vars(args).items() if not k.startswith("child")},
        ratio="method time / scanalign float32 time of the same case and thread count (>1: slower than scanalign)",
        settings_mapping=__doc__[__doc__.index("How each peer"):], seconds=time.perf_counter() - t_start,
        results=results)
    (out / "peers.json").write_text(json.dumps(_jsonable(report), indent=1))
    (out / "peers.md").write_text(text + "\n")
    log(f"[bench_peers] wrote {out / 'peers.json'}, {out / 'peers.md'}, " + ", ".join(str(p) for p in pngs)
        + f" ({time.perf_counter() - t_start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
