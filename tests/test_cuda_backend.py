"""The ICP backends (issue 29): ``backend="cpu" | "cuda"`` on ``registration.icp``, ``Icp``, the
reconstruction pipeline and the commands, as one settings field (``IcpSettings.backend``).

On any machine: the field, its flags and config key, ``--version``, and the error a build
without CUDA or a machine without a CUDA device gives. On a machine with a CUDA device
(``scripts/gpu_check.sh``): the CUDA engine against the CPU engine on the same inputs, poses to
1e-6 and the same statuses, its determinism, and the frame loop. Oracle: the CPU engine, itself
tested against known transforms and PCL elsewhere."""

from __future__ import annotations

import re

import numpy as np
import pytest

from scanalign import _core, cli
from scanalign.registration import Icp, IcpSettings, cuda_devices, icp

DEVICES = cuda_devices()
needs_device = pytest.mark.skipif(not DEVICES, reason="no CUDA device (or scanalign built without CUDA)")


def _surface(n: int = 120, seed: int = 1):
    """A wavy height field and a sphere (all six motions constrained) with exact normals, metres."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(-0.1, 0.1, n), np.linspace(-0.1, 0.1, n))
    x = x.ravel() + rng.uniform(-3e-4, 3e-4, x.size)
    y = y.ravel() + rng.uniform(-3e-4, 3e-4, y.size)
    z = 0.6 + 0.01 * np.sin(40 * x) * np.cos(30 * y) + 0.2 * x * x
    grad = np.stack([-(0.4 * np.cos(40 * x) * np.cos(30 * y) + 0.4 * x), 0.3 * np.sin(40 * x) * np.sin(30 * y),
                     np.ones_like(x)], axis=1)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = np.vstack([np.stack([x, y, z], axis=1), np.array([0.03, -0.02, 0.55]) + 0.03 * u])
    nrm = np.vstack([-grad / np.linalg.norm(grad, axis=1, keepdims=True), u])
    return pts, nrm


def _motion(rx: float, ry: float, rz: float, t) -> np.ndarray:
    c, s = np.cos, np.sin
    Rx = np.array([[1, 0, 0], [0, c(rx), -s(rx)], [0, s(rx), c(rx)]])
    Ry = np.array([[c(ry), 0, s(ry)], [0, 1, 0], [-s(ry), 0, c(ry)]])
    Rz = np.array([[c(rz), -s(rz), 0], [s(rz), c(rz), 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry @ Rx
    T[:3, 3] = t
    return T


def test_backend_is_one_settings_field_with_the_cpu_default():
    assert IcpSettings().backend == "cpu"
    assert IcpSettings(backend="cuda").backend == "cuda"
    with pytest.raises(ValueError, match="backend"):
        IcpSettings(backend="gpu")
    from scanalign.reconstruction import make_reconstruction_settings

    s = make_reconstruction_settings(backend="cuda")
    assert s.frame_to_model.icp.backend == "cuda"
    with pytest.raises(ValueError, match="backend"):
        make_reconstruction_settings(backend="opencl")


@pytest.mark.parametrize("command", ["reconstruct", "register"])
def test_the_commands_take_backend_as_a_flag_and_a_config_key(command, capsys, tmp_path):
    assert cli.main(["dump-config", command]) == 0
    assert re.search(r"^\s*backend: cpu\b", capsys.readouterr().out, flags=re.M)
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    assert re.search(r"--backend \{cpu,cuda\}", capsys.readouterr().out)


def test_version_says_whether_the_cuda_backend_is_built(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--version"])
    out = capsys.readouterr().out
    assert ("with the CUDA backend" in out) == bool(_core.built_with_cuda), out
    assert ("without the CUDA backend (SCANALIGN_WITH_CUDA)" in out) == (not _core.built_with_cuda), out
    if not _core.built_with_cuda:
        assert DEVICES == []


@pytest.mark.skipif(bool(DEVICES), reason="a CUDA device is present")
def test_without_a_build_or_a_device_cuda_fails_with_the_reason():
    pts, nrm = _surface(40)
    want = "no usable CUDA device" if _core.built_with_cuda else "SCANALIGN_WITH_CUDA=ON"
    with pytest.raises(RuntimeError, match=re.escape(want)):
        icp(pts, pts, nrm, backend="cuda")
    with pytest.raises(RuntimeError, match=re.escape(want)):
        Icp(pts, nrm, backend="cuda")
    # The same data on the CPU is fine.
    assert icp(pts, pts, nrm, backend="cpu").converged


def test_demo_with_cuda_says_why_it_cannot_run(capsys, tmp_path):
    if DEVICES:
        pytest.skip("a CUDA device is present: test_demo_runs_on_the_gpu runs instead")
    code = cli.main(["demo", "--frames", "4", "--backend", "cuda", "--out", str(tmp_path / "demo"), "--no-progress",
                     "--quiet", "--no-plots"])
    assert code != 0
    err = capsys.readouterr().err
    assert "SCANALIGN_WITH_CUDA=ON" in err or "no usable CUDA device" in err, err


# --- on a CUDA device ---------------------------------------------------------------------------------------------


@needs_device
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("overrides", [
    {}, {"estimator": "point_to_point"}, {"estimator": "dual_quaternion"}, {"box": (-0.08, 0.08, -0.08, 0.08, 1e-4, 10)},
    {"robust_kernel": "cauchy", "robust_scale": 0.002}, {"coarse_stride": 8},
    {"search": "left_balanced_kdtree", "search_stack_depth": 3},
], ids=["point_to_plane", "point_to_point", "dual_quaternion", "box", "cauchy", "coarse", "stack_3"])
def test_cuda_gives_the_cpu_engines_pose(dtype, overrides):
    pts, nrm = _surface()
    truth = _motion(0.03, -0.02, 0.04, [0.006, -0.004, 0.005])
    rng = np.random.default_rng(3)
    src = (pts - truth[:3, 3]) @ truth[:3, :3] + rng.normal(0, 5e-4, pts.shape)
    src[7] = np.nan
    args = (src.astype(dtype), pts.astype(dtype), nrm.astype(dtype))
    cpu = icp(*args, max_correspondence_distance=0.03, backend="cpu", **overrides)
    gpu = icp(*args, max_correspondence_distance=0.03, backend="cuda", **overrides)
    assert gpu.status == cpu.status and gpu.iterations == cpu.iterations
    assert np.abs(gpu.T_target_source - cpu.T_target_source).max() < 1e-6
    assert gpu.correspondence_count == cpu.correspondence_count
    assert gpu.exact_search == cpu.exact_search
    if "search_stack_depth" not in overrides:
        assert np.linalg.norm(gpu.T_target_source[:3, 3] - truth[:3, 3]) < 1e-3


@needs_device
def test_cuda_is_deterministic_and_gives_the_cpu_statuses_on_bad_input():
    pts, nrm = _surface()
    engine = Icp(pts, nrm, backend="cuda")
    src = (pts - [0.003, 0.002, -0.001]).astype(np.float64)
    first = engine.align(src)
    for _ in range(3):
        again = engine.align(src)
        assert np.array_equal(again.T_target_source, first.T_target_source)  # bit for bit
    far = pts + [0, 0, 5.0]
    nan = np.full_like(pts, np.nan)
    for backend in ("cpu", "cuda"):
        assert icp(far, pts, nrm, backend=backend).status == "not_enough_correspondences"
        r = icp(nan, pts, nrm, backend=backend)
        assert r.status == "not_enough_correspondences" and r.source_points_used == 0


@needs_device
def test_the_frame_loop_on_cuda_tracks_as_on_the_cpu():
    from scanalign import synthetic
    from scanalign.pipelines.reconstruct import DEMO_SETTINGS, reconstruct

    scan = synthetic.builtin_scan(12)
    cpu = reconstruct(scan.frames, progress=False, backend="cpu", **DEMO_SETTINGS)
    gpu = reconstruct(scan.frames, progress=False, backend="cuda", **DEMO_SETTINGS)
    assert gpu.summary()["merged"] == cpu.summary()["merged"]
    a = np.array([r.T_model_camera for r in cpu.records])
    b = np.array([r.T_model_camera for r in gpu.records])
    assert np.abs(a - b).max() < 1e-6


@needs_device
def test_demo_runs_on_the_gpu(tmp_path):
    assert cli.main(["demo", "--frames", "6", "--backend", "cuda", "--out", str(tmp_path / "demo"), "--no-progress",
                     "--quiet", "--no-plots"]) == 0
    assert "backend: cuda" in (tmp_path / "demo" / "config.yaml").read_text()


def test_the_gpu_benchmark_runs_in_its_quick_mode(tmp_path):
    """bench/bench_gpu.py is what scripts/gpu_check.sh runs on a GPU: it must not first fail there."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, str(root / "bench/bench_gpu.py"), "--quick", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    import json

    report = json.loads((tmp_path / "bench_gpu.json").read_text())
    rows = report["registration"]
    ours = [r for r in rows if not r["backend"].startswith("small_gicp")]
    assert {r["backend"] for r in ours} >= {"cpu, 1 thread"} and all(r["error_mm"] < 0.5 for r in ours), rows
    assert report["frame_loop"][0]["merged"] == 3 and report["frame_loop"][0]["ate_mm"] < 5.0
    assert ("cuda" in {r["backend"] for r in rows}) == bool(DEVICES)
    assert (tmp_path / "bench_gpu.md").read_text().startswith("# CUDA backend benchmark")
