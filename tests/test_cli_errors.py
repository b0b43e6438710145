"""Every ``scanalign`` command given bad input exits non-zero with one line naming the argument
or file at fault: no traceback, no raw pybind11 signature dump, no KeyError, and never
status 0 for a run that did nothing or could not write its output."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import apply, rigid
from scanalign import cli

JOINTS = ["0.3", "-1.2", "1.1", "-1.4", "-1.2", "0.5"]


@pytest.fixture()
def files(tmp_path, monkeypatch):
    """A folder of good and bad inputs; the tests run inside it."""
    monkeypatch.chdir(tmp_path)
    Path("file.txt").write_text("not a folder")
    Path("ok.pcd").write_bytes(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nPOINTS 3\nDATA ascii\n"
                               b"0 0 0\n1 0 0\n0 1 0\n")
    Path("noxyz.pcd").write_bytes(b"FIELDS a\nSIZE 4\nTYPE F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1\n")
    Path("lying.pcd").write_bytes(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000000000\n"
                                  b"POINTS 1000000000000\nDATA binary\n" + bytes(12))
    Path("truncated.stl").write_bytes(b"solid but binary".ljust(80) + (2).to_bytes(4, "little") + bytes(50))
    Path("init3.txt").write_text("1 0 0\n")
    Path("cfg.json").write_text("{not json")
    Path("tum").mkdir()
    Path("tum/depth.txt").write_text("1305031102.160407 depth/1305031102.160407.png\n")
    return tmp_path


CASES = [  # argv, fragment the one-line message must contain
    (["synth", "builtin", "s0", "--frames", "0"], "n_frames"),
    (["synth", "builtin", "s1", "--frames", "-3"], "n_frames"),
    (["synth", "cfg.json", "s2"], "cfg.json"),
    (["synth", "builtin", "file.txt/sub", "--frames", "2"], "file.txt/sub"),
    (["demo", "--frames", "0", "--out", "d0"], "n_frames"),
    (["demo", "--noise", "bogus", "--out", "d1"], "noise"),
    (["reconstruct", "nope"], "nope: no such folder or file"),
    (["reconstruct", "tum", "--intrinsics", "tum_fr1"], "listed depth image"),
    (["reconstruct", "tum", "--intrinsics", "bogus"], "intrinsics 'bogus'"),
    (["reconstruct", "builtin", "--frames", "0"], "n_frames"),
    (["register", "noxyz.pcd", "ok.pcd"], "noxyz.pcd: PCD file has no x, y, z fields"),
    (["register", "lying.pcd", "ok.pcd"], "lying.pcd: PCD binary data is truncated"),
    (["register", "file.txt", "ok.pcd"], "file.txt: unsupported cloud format"),
    (["register", "missing.pcd", "ok.pcd"], "missing.pcd"),
    (["register", "ok.pcd", "ok.pcd", "--init", "init3.txt"], "--init init3.txt: expected a text file holding a 4x4"),
    (["register", "ok.pcd", "ok.pcd", "--init", "missing.txt"], "--init missing.txt"),
    (["register", "ok.pcd", "ok.pcd", "--max-distance", "nan"], "max_correspondence_distance"),
    (["register-demo", "--noise", "nan", "--out", "rd"], "--noise"),
    (["register-demo", "--out", "file.txt/rd"], "file.txt/rd"),
    (["ik", "--robot", "ur5", "--joints", *JOINTS, "--plot", "file.txt/ik.png"], "file.txt/ik.png"),
    (["ik", "--robot", "bogus", "--joints", *JOINTS], "unknown robot 'bogus'"),
    (["ik", "--robot", "ur5", "--joints", "nan", *JOINTS[1:]], "non-finite"),
    (["ik", "--robot", "ur5", "--pose", "0.4", "0", "0.3", "inf", "0", "0"], "--pose"),
    (["ik", "--robot", "ur5", "--joints", *JOINTS, "--closest", "nan", *JOINTS[1:]], "q_current"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--out", "p"], "truncated.stl: neither a binary STL"),
    (["pose", "--model", "missing.stl", "--scene", "ok.pcd"], "missing.stl: no such model file"),
    (["pose", "--model", "file.txt", "--scene", "ok.pcd"], "unsupported model extension"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--model-scale", "nan"], "--model-scale"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--model-scale", "0"], "--model-scale"),
]


@pytest.mark.parametrize("argv, fragment", CASES, ids=[" ".join(c[0][:3]) + f" #{k}" for k, c in enumerate(CASES)])
def test_bad_input_is_one_line_naming_the_culprit(files, capsys, argv, fragment):
    rc = cli.main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("scanalign")]
    assert rc == 2, (rc, err)
    assert len(lines) == 1 and lines[0].startswith(f"scanalign {argv[0]}: error: "), err
    assert fragment in lines[0], lines[0]
    assert "Traceback" not in err and "incompatible function arguments" not in err


def test_synth_with_zero_frames_writes_nothing(files, capsys):
    """``--frames 0`` used to be read as "the default, 36" and wrote a 36-frame folder."""
    assert cli.main(["synth", "builtin", "out", "--frames", "0"]) == 2
    assert not Path("out").exists()


def test_unwritable_outputs_fail_in_a_fresh_process(files):
    """The installed entry point: non-zero status and a one-line message, no traceback (an
    unwritable plot path used to end in a NotADirectoryError traceback, a PCD without x, y,
    z in a KeyError)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}  # the scanalign under test
    for argv, fragment in [(["ik", "--robot", "ur5", "--joints", *JOINTS, "--plot", "file.txt/ik.png"],
                            "Not a directory"),
                           (["register", "noxyz.pcd", "ok.pcd"], "no x, y, z fields")]:
        r = subprocess.run([sys.executable, "-c", "import sys; from scanalign.cli import main; sys.exit(main())",
                            *argv], capture_output=True, text=True, env=env, timeout=120)
        assert r.returncode == 2 and fragment in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_good_register_run_still_succeeds(files, capsys):
    """The control: with good files the same command recovers a known motion (1 degree about
    z, 2 mm along x) and writes the aligned cloud."""
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.05, 0.05, (2, 4000))
    target = np.c_[u, v, 0.4 + 0.01 * np.sin(60 * u) * np.cos(50 * v)]
    T = rigid((0, 0, 1), np.deg2rad(1.0), (0.002, 0.0, 0.0))
    source = apply(np.linalg.inv(T), target)
    for name, cloud in (("target.pcd", target), ("source.pcd", source)):
        header = f"FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH {len(cloud)}\nPOINTS {len(cloud)}\nDATA binary\n"
        Path(name).write_bytes(header.encode() + cloud.astype("<f8").tobytes())
    assert cli.main(["register", "source.pcd", "target.pcd", "--out", "aligned.ply", "--normal-radius", "0.01"]) == 0
    result = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(result["T_target_source"], T, atol=1e-5)
    assert Path("aligned.ply").stat().st_size > 4000 * 12


@pytest.fixture()
def no_work(monkeypatch):
    """Every entry point of a command's work fails the test if called: the checks below must
    stop the command before any scene is rendered or loaded, or any registration runs."""
    from scanalign import datasets, pose
    from scanalign.cli import commands
    from scanalign.pipelines import pick

    def forbidden(name):
        def call(*args, **kwargs):
            raise AssertionError(f"work started ({name}) before the input was checked")
        return call

    for owner, name in [(datasets, "open_source"), (commands, "pick_cell"), (pick, "pick"), (pose, "find_objects"),
                        (pose, "estimate_pose"), (commands, "icp"), (commands, "reconstruct")]:
        monkeypatch.setattr(owner, name, forbidden(name))


BEFORE_WORK = [  # argv (all with --out out), what the one-line message must contain
    (["reconstruct", "builtin", "--intrinsics", "tum_fr9"], "--intrinsics 'tum_fr9': neither a preset (tum_default, "),
    (["reconstruct", "builtin", "--intrinsics", "tum_fr1"], "--intrinsics applies to recordings"),  # was ignored
    (["reconstruct", "builtin", "--limit", "3"], "--limit applies to recordings"),
    (["reconstruct", "tum", "--frames", "3"], "--frames applies to synthetic scans"),
    (["reconstruct", "builtin", "--max-distance", "-1"], "--max-distance -1: reconstruction: frame_to_model: ICP"),
    (["demo", "--max-distance", "-1"], "--max-distance -1: "),
    (["reconstruct", "builtin", "--min-depth", "5"], "--min-depth 5: reconstruction: need 0 <= min_depth"),
    (["reconstruct", "builtin", "--set", "frame_to_model.min_fitness=2"], "--set frame_to_model.min_fitness=2: "),
    (["register", "ok.pcd", "ok.pcd", "--max-distance", "-1"], "--max-distance -1: ICP settings: max_corr"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--up", "nan", "0", "1"], "--up nan 0 1: table"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--inlier-threshold", "-1"], "--inlier-threshold -1: "),
    (["pick", "--scene", "tum", "--parts", "block"], "missing --robot: pick needs --scene, --parts and --robot"),
    (["pick", "--scene", "tum", "--robot", "ur5"], "missing --parts: "),
    (["pick", "--parts", "block", "--robot", "ur5"], "missing --scene: "),
    (["pick", "--robot", "ur5"], "missing --scene, --parts: "),
    (["pick", "--scene", "tum", "--parts", "block", "--robot", "ur5", "--joints", "no.csv"], "--joints no.csv: no such"),
    (["pick", "--scene", "tum", "--parts", "block", "--robot", "ur5", "--noise", "zivid"], "--noise applies to --demo"),
    (["pick", "--demo", "--scene", "tum"], "--scene does not apply to the built-in pick cell"),
    (["pick", "--demo", "--q-current", "nan", "0", "0", "0", "0", "0"], "--q-current nan 0 0 0 0 0: "),
    (["demo", "--view-save", "file.txt/x.rrd"], "--view-save file.txt/x.rrd: file.txt is not a folder"),
    (["reconstruct", "builtin", "--out", "file.txt/o"], "--out file.txt/o: file.txt is not a folder"),
    (["pose", "--model", "truncated.stl", "--scene", "ok.pcd", "--out", "file.txt/o"], "--out file.txt/o: file.txt"),
]


@pytest.mark.parametrize("argv, fragment", BEFORE_WORK, ids=[" ".join(c[0]) for c in BEFORE_WORK])
def test_a_mistake_is_named_as_typed_before_any_work(files, no_work, capsys, argv, fragment):
    """Unknown presets, settings a flag or --set made invalid, missing or misplaced inputs and
    unwritable outputs: exit 2 with the option as typed (not only the C++ field), nothing run,
    nothing written (a run used to render for minutes, or to fail at the end, or to ignore it)."""
    before = sorted(os.listdir())
    rc = cli.main(argv + ([] if "--out" in argv else ["--out", "out"]))
    err = capsys.readouterr().err
    assert rc == 2 and err.count("scanalign") == 1 and fragment in err, err
    assert sorted(os.listdir()) == before


def test_box_flags_set_the_box(files, monkeypatch):
    """--box and --box-preset, two flags of one field, each set it (each used to read the
    other's value: 'could not convert string to float')."""
    from scanalign.cli import commands
    from scanalign.registration import Box

    got = []
    monkeypatch.setitem(commands.HANDLERS, "reconstruct", lambda args: got.append(args.settings) or 0)
    assert cli.main(["reconstruct", "builtin", "--box-preset", "banana", "--out", "a"]) == 0
    assert cli.main(["reconstruct", "builtin", "--box", "-1", "1", "-2", "2", "0", "3", "--out", "b"]) == 0
    assert got[0].frame_to_model.icp.box.as_tuple() == Box.banana_preset().as_tuple()
    assert got[1].frame_to_model.icp.box.as_tuple() == (-1, 1, -2, 2, 0, 3)
