"""What an install holds and says about itself: one version everywhere, ``scanalign --version``,
a top-level ``--help`` naming every command, and the optional PCL part (issue 19 §1).

The PCL-free build is checked on a real build of it when ``SCANALIGN_LIGHT_BUILD`` names its
folder (``scripts/test.sh`` builds it with ``-DSCANALIGN_WITH_PCL=OFF -DSCANALIGN_WITH_CUDA=ON``):
its module must not link PCL or a shared CUDA runtime, must run the engine, must refuse every PCL
baseline with a message naming the build option, and without a GPU must refuse the CUDA backend
naming the missing device."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import scanalign
from scanalign import _core, cli

ROOT = Path(__file__).resolve().parents[1]


def _cmake_version() -> str:
    m = re.search(r"project\(scanalign\s+VERSION\s+([0-9.]+)", (ROOT / "CMakeLists.txt").read_text())
    assert m, "CMakeLists.txt has no project(scanalign VERSION ...)"
    return m.group(1)


def test_one_version_source():
    assert scanalign.__version__ == _core.__version__ == _cmake_version()
    assert metadata.version("scanalign") == _cmake_version()
    assert "version" not in (ROOT / "python/scanalign/__init__.py").read_text().split("__getattr__")[0].replace(
        "__version__", "")


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith(f"scanalign {_cmake_version()} (")
    assert ("with the PCL baselines" in out) == bool(_core.built_with_pcl)


def test_top_level_help_lists_every_command(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = capsys.readouterr().out
    parser_commands = re.findall(r"^    (\S+)\s{2,}\S", out.split("COMMAND", 2)[-1], flags=re.M)
    # Every sub-command is listed once with its one-line help, and --version is offered.
    assert {"demo", "pick", "reconstruct", "synth", "register", "register-demo", "ik", "pose", "batch"} <= set(
        parser_commands), parser_commands
    assert "--version" in out


def test_license_matches_the_declared_licence():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 3-Clause License")
    assert 'license = { file = "LICENSE" }' in (ROOT / "pyproject.toml").read_text()
    installed = metadata.metadata("scanalign")
    assert "BSD 3-Clause License" in (installed.get("License") or installed.get_payload() or "")


def test_the_full_build_has_the_pcl_baselines():
    """The README's commands install Debian's PCL: the baselines must be there (a silently
    light build would skip every PCL comparison)."""
    assert _core.built_with_pcl
    from scanalign.registration import pcl_icp

    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.1, 0.1, (500, 3))
    r = pcl_icp(pts, pts, variant="svd")
    assert np.abs(r.T_target_source - np.eye(4)).max() < 1e-6
    assert np.array_equal(r.transformation, r.T_target_source)


LIGHT = os.environ.get("SCANALIGN_LIGHT_BUILD")


@pytest.mark.skipif(not LIGHT, reason="SCANALIGN_LIGHT_BUILD names no PCL-free build (scripts/test.sh makes one)")
def test_light_build_runs_the_engine_and_refuses_pcl_by_name(tmp_path):
    build = Path(LIGHT)
    modules = list(build.glob("_core*.so"))
    assert len(modules) == 1, f"no compiled module in {build}"
    libs = subprocess.run(["ldd", str(modules[0])], capture_output=True, text=True, check=True).stdout
    assert "libpcl" not in libs and "libvtk" not in libs and "libboost" not in libs, libs
    assert "libcudart" not in libs and "libcuda." not in libs, libs  # the CUDA runtime is linked statically
    # The package's Python files with the light module beside them, in a fresh interpreter.
    pkg = tmp_path / "scanalign"
    pkg.mkdir()
    for f in (ROOT / "python/scanalign").iterdir():
        (pkg / f.name).symlink_to(f)
    (pkg / modules[0].name).symlink_to(modules[0])
    script = r"""
import numpy as np, scanalign
from scanalign import _core, registration, pose, kinematics
assert not _core.built_with_pcl
assert _core.built_with_cuda  # scripts/test.sh builds it with SCANALIGN_WITH_CUDA=ON
rng = np.random.default_rng(1)
model = rng.uniform(-0.1, 0.1, (3000, 3)); model[:, 2] = 0.02 * np.sin(20 * model[:, 0])
c, s = np.cos(0.03), np.sin(0.03)
T = np.array([[c, -s, 0, 0.004], [s, c, 0, -0.002], [0, 0, 1, 0.001], [0, 0, 0, 1.0]])
src = (model - T[:3, 3]) @ T[:3, :3]
r = registration.icp(src, model, max_correspondence_distance=0.02, estimator="point_to_point")
assert np.abs(r.transformation - T).max() < 1e-4, r.transformation
q = np.array([0.3, -1.0, 1.2, -0.5, 1.1, 0.4])
ur5 = kinematics.Robot.by_name("ur5")
sol = ur5.ik(ur5.fk(q))
assert any(np.allclose(sol.q[i], q, atol=1e-9) for i in np.flatnonzero(sol.ok))
for call in (lambda: registration.pcl_icp(src, model, variant="svd"),
             lambda: pose.pcl_feature_alignment(src, model)):
    try:
        call()
    except RuntimeError as e:
        assert "SCANALIGN_WITH_PCL=ON" in str(e) and "libpcl-dev" in str(e), e
    else:
        raise AssertionError("a PCL baseline ran in a build without PCL")
if not registration.cuda_devices():
    try:
        registration.icp(src, model, estimator="point_to_point", backend="cuda")
    except RuntimeError as e:
        assert "no usable CUDA device" in str(e), e
    else:
        raise AssertionError("the CUDA backend ran without a device")
print("light ok", scanalign.__version__)
"""
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(tmp_path)}, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.strip() == f"light ok {_cmake_version()}"
