"""One settings schema from the C++ structs to the command line: ``scanalign dump-config
COMMAND``, ``--config FILE`` (nested YAML / JSON of the structs' fields), ``--set PATH=VALUE``,
the alias flags, and the effective config written beside every output
(scanalign.common.settings, scanalign.cli.settings)."""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from helpers import apply, rigid
from scanalign import cli
from scanalign.cli import commands as cli_main
from scanalign.cli.settings import resolve
from scanalign.common import settings as schema

COMMANDS = dict(cli_main.COMMANDS)


@pytest.fixture()
def clouds(tmp_path, monkeypatch):
    """A source and a target cloud (a wavy 10 x 10 cm patch moved by 1 degree about z and
    2 mm along x), written as PCD; the tests run in this folder."""
    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.05, 0.05, (2, 3000))
    target = np.c_[u, v, 0.4 + 0.01 * np.sin(60 * u) * np.cos(50 * v)]
    source = apply(np.linalg.inv(rigid((0, 0, 1), np.deg2rad(1.0), (0.002, 0.0, 0.0))), target)
    for name, cloud in (("target.pcd", target), ("source.pcd", source)):
        header = f"FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH {len(cloud)}\nPOINTS {len(cloud)}\nDATA binary\n"
        Path(name).write_bytes(header.encode() + cloud.astype("<f8").tobytes())
    return tmp_path


def register(capsys, *extra: str) -> tuple:
    """Runs ``scanalign register source.pcd target.pcd EXTRA``; (exit status, result without
    its timing)."""
    rc = cli.main(["register", "source.pcd", "target.pcd", *extra])
    out = capsys.readouterr().out
    result = json.loads(out)
    result.pop("seconds")
    return rc, result


def settings_of(path: Path) -> dict:
    """A written config without its comments."""
    return yaml.safe_load(path.read_text())


# --------------------------------------------------------------------------- dump-config


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_dump_config_lists_every_field_and_loads_back_to_the_defaults(command, capsys):
    assert cli.main(["dump-config", command]) == 0
    text = capsys.readouterr().out
    root = COMMANDS[command].root()
    assert yaml.safe_load(text) == schema.to_dict(root)
    paths = [p for p, _, _, _ in schema.leaves(root)]
    assert len(paths) == len(set(paths)) and len(paths) >= 5
    # Every leaf appears as a key line, preceded by its comment (unit in brackets when it has one).
    lines = text.splitlines()
    for path, unit, doc, _ in schema.leaves(root):
        depth, name = path.count("."), path.rsplit(".", 1)[-1]
        k = next(i for i, line in enumerate(lines) if line.startswith("  " * depth + name + ":"))
        if doc:
            assert lines[k - 1].lstrip().startswith("#"), path
        if unit:
            block = []
            for line in reversed(lines[:k]):
                if not line.lstrip().startswith("#"):
                    break
                block.insert(0, line)
            assert f"[{unit}]" in block[0], (path, block)


def test_reconstruct_schema_holds_every_field_of_its_structs(capsys):
    """dump-config reconstruct: every field of ReconstructionSettings, FrameToModelSettings
    (nested), IcpSettings and BilateralFilterSettings, from the C++ field tables."""
    from scanalign.reconstruction import BilateralFilterSettings, FrameToModelSettings, ReconstructionSettings
    from scanalign.registration import IcpSettings

    assert cli.main(["dump-config", "reconstruct"]) == 0
    dumped = yaml.safe_load(capsys.readouterr().out)
    for struct, node in ((ReconstructionSettings, dumped), (FrameToModelSettings, dumped["frame_to_model"]),
                         (IcpSettings, dumped["frame_to_model"]["icp"]), (BilateralFilterSettings, dumped["depth_filter"])):
        assert list(node) == list(schema.field_names(struct)), struct.__name__


# --------------------------------------------------------------------------- each field reaches C++


def _choices(doc: str) -> list:
    return re.findall(r"'(\w+)'", doc)


def _another(value, doc: str):
    """A valid value different from ``value`` (a field's default)."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, int):
        return value - 1 if value >= 2**62 else value + 1  # "no limit" defaults sit at the type's maximum
    if isinstance(value, float):
        if not math.isfinite(value):
            return 1.0
        return 0.5 if value == 0 else value * (0.5 if 0 < value <= 1 else 1.5)
    if isinstance(value, str):
        return next(c for c in _choices(doc) if c != value)
    if value is None:  # an optional box, or an optional point
        return [0.01, 0.02, 0.03] if doc.startswith("(3,)") else [-1.0, 1.0, -1.0, 1.0, 0.0, 2.0]
    if isinstance(value, list):
        return [v + 0.25 for v in value]
    raise AssertionError(f"no test value for {value!r}")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_value_in_a_config_file_reaches_the_cpp_struct_for_every_field(command, tmp_path):
    spec = COMMANDS[command]
    defaults = spec.root()
    checked = 0
    for path, _, doc, value in schema.leaves(defaults):
        members = getattr(type(schema.get_path(defaults, path)), "__members__", None)
        new = next(m for m in members if m != value) if members else _another(value, doc)
        nested: dict = {}
        node = nested
        *parents, last = path.split(".")
        for key in parents:
            node = node.setdefault(key, {})
        node[last] = new
        f = tmp_path / "one.yaml"
        f.write_text(yaml.safe_dump(nested))
        root = resolve(spec, argparse.Namespace(config=str(f), set_values=[]))
        got = schema.get_path(root, path)
        shown = schema.to_dict({"v": got})["v"]  # enums by name, boxes as 6 numbers, arrays as lists
        assert shown == pytest.approx(new) if isinstance(new, (float, list)) else shown == new, (path, shown, new)
        # and nothing else moved
        others = {p: v for p, _, _, v in schema.leaves(root) if p != path}
        assert others == {p: v for p, _, _, v in schema.leaves(defaults) if p != path}, path
        checked += 1
    assert checked == len(list(schema.leaves(defaults)))


# --------------------------------------------------------------------------- runs


def test_a_config_file_changes_the_run_like_the_flags(clouds, capsys):
    rc0, default = register(capsys)
    Path("run.yaml").write_text("icp:\n  estimator: point_to_point\n  max_correspondence_distance: 0.004\n"
                                "normals:\n  radius: 0.01\n")
    rc1, from_file = register(capsys, "--config", "run.yaml")
    rc2, from_flags = register(capsys, "--estimator", "point_to_point", "--normal-radius", "0.01",
                               "--max-distance", "0.004")
    rc3, from_set = register(capsys, "--set", "icp.estimator=point_to_point", "--set", "normals.radius=0.01",
                             "--set", "icp.max_correspondence_distance=0.004")
    assert rc0 == 0 and rc1 == rc2 == rc3
    assert from_file == from_flags == from_set
    assert from_file != default
    # JSON is YAML: the same settings as a .json file.
    Path("run.json").write_text(json.dumps({"icp": {"estimator": "point_to_point", "max_correspondence_distance": 0.004},
                                            "normals": {"radius": 0.01}}))
    assert register(capsys, "--config", "run.json") == (rc1, from_file)


def test_flags_override_the_file_and_set_overrides_both(clouds, capsys):
    Path("run.yaml").write_text("icp:\n  max_iterations: 1\nnormals:\n  radius: 0.01\n")
    rc, capped = register(capsys, "--config", "run.yaml")
    assert capped["iterations"] == 1 and not capped["converged"] and rc == 2
    rc, result = register(capsys, "--config", "run.yaml", "--max-iterations", "50", "--out", "aligned.ply")
    assert rc == 0 and result["converged"] and result["iterations"] > 1
    assert register(capsys, "--normal-radius", "0.01") == (rc, result)  # the file's other setting kept
    written = settings_of(Path("aligned.config.yaml"))
    assert (written["icp"]["max_iterations"], written["normals"]["radius"]) == (50, 0.01)
    rc, again = register(capsys, "--config", "run.yaml", "--max-iterations", "50", "--set", "icp.max_iterations=1")
    assert again["iterations"] == 1 and rc == 2


def test_the_effective_config_repeats_the_run(clouds, capsys):
    Path("run.yaml").write_text("normals:\n  radius: 0.01\nicp:\n  box: [-1, 1, -1, 1, 0, 2]\n")
    rc, first = register(capsys, "--config", "run.yaml", "--max-distance", "0.03", "--out", "aligned.ply")
    effective = Path("aligned.config.yaml")
    text = effective.read_text()
    assert "scanalign register source.pcd target.pcd --config aligned.config.yaml" in text
    s = settings_of(effective)
    assert s["icp"]["max_correspondence_distance"] == 0.03 and s["normals"]["radius"] == 0.01
    assert s["icp"]["box"] == [-1.0, 1.0, -1.0, 1.0, 0.0, 2.0] and s["icp"]["estimator"] == "point_to_plane"
    aligned = Path("aligned.ply").read_bytes()
    Path("aligned.ply").unlink()
    # Fed back, alone (with the same output): the same result, the same aligned cloud, the same settings.
    assert register(capsys, "--config", str(effective), "--out", "aligned.ply") == (rc, first)
    assert Path("aligned.ply").read_bytes() == aligned
    assert settings_of(effective) == s


def test_reconstruct_writes_its_config_into_the_output_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("run.yaml").write_text("frame_to_model:\n  frame_voxel_size: 0.004\n")
    assert cli.main(["reconstruct", "builtin", "--frames", "2", "--no-plots", "--no-progress", "--out", "first",
                     "--config", "run.yaml", "--threads", "2"]) == 0
    assert "wrote first/config.yaml" in capsys.readouterr().out
    s = settings_of(Path("first/config.yaml"))
    assert (s["frame_to_model"]["frame_voxel_size"], s["frame_to_model"]["num_threads"]) == (0.004, 2)
    assert len(Path("first/frames.csv").read_text().splitlines()) == 1 + 2
    # Fed back with another output folder: the same trajectory, the same settings.
    assert cli.main(["reconstruct", "builtin", "--frames", "2", "--config", "first/config.yaml", "--out", "second",
                     "--quiet"]) == 0
    assert Path("second/trajectory.txt").read_text() == Path("first/trajectory.txt").read_text()
    assert settings_of(Path("second/config.yaml")) == s


# --------------------------------------------------------------------------- bad files


BAD = [  # file text, fragments of the one-line message (after "scanalign register: error: run.yaml: ")
    ("icp:\n  max_iteratons: 3\n", ["icp.max_iteratons: unknown setting", "did you mean icp.max_iterations?"]),
    ("icp:\n  max_correspondence_distance: far\n", ["icp.max_correspondence_distance", "expected a real number, got 'far'"]),
    ("icp:\n  max_correspondence_distance: true\n", ["icp.max_correspondence_distance", "expected a real number"]),
    ("icp:\n  max_iterations: 2.5\n", ["icp.max_iterations", "expected an integer"]),
    ("icp:\n  max_iterations: null\n", ["icp.max_iterations", "expected an integer"]),
    ("icp:\n  estimator: point_to_line\n", ["icp.estimator", "point_to_line"]),
    ("icp:\n  box: [0, 1, 0, 1]\n", ["icp.box"]),
    ("icp: 3\n", ["icp: expected a mapping of IcpSettings fields, got int"]),
    ("icp:\n  max_correspondence_distance: [0.1\n", ["malformed YAML/JSON at line 3"]),
    ("{\"icp\": 0.1,,}\n", ["malformed YAML/JSON at line 1"]),
    ("- icp\n", ["expected a mapping of settings (key: value), got list"]),
    ("config: other.yaml\n", ["config: unknown setting"]),
    ("icp:\n  max_correspondence_distance: -1\n", ["max_correspondence_distance"]),
]


@pytest.mark.parametrize("text, fragments", BAD, ids=[f"#{k}" for k in range(len(BAD))])
def test_a_bad_config_file_is_one_line_naming_file_and_key(clouds, capsys, text, fragments):
    Path("run.yaml").write_text(text)
    assert cli.main(["register", "source.pcd", "target.pcd", "--config", "run.yaml"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("scanalign register: error: run.yaml: "), captured.err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_a_bad_set_or_flag_is_named(clouds, capsys):
    assert cli.main(["register", "source.pcd", "target.pcd", "--set", "icp.max_iterations"]) == 2
    assert "expected PATH=VALUE" in capsys.readouterr().err
    assert cli.main(["register", "source.pcd", "target.pcd", "--set", "icp.nope=3"]) == 2
    assert "icp.nope: unknown setting" in capsys.readouterr().err
    assert cli.main(["register", "source.pcd", "target.pcd", "--max-distance", "-1"]) == 2
    assert "max_correspondence_distance" in capsys.readouterr().err


def test_a_missing_config_file_is_named(clouds, capsys):
    assert cli.main(["register", "source.pcd", "target.pcd", "--config", "nope.yaml"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("scanalign register: error: nope.yaml: cannot read the settings file") and err.count("\n") == 1


def test_other_commands_take_no_config(capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["ik", "--robot", "ur5", "--config", "x.yaml"])
    assert info.value.code == 2
    with pytest.raises(SystemExit):
        cli.main(["dump-config", "ik"])
    capsys.readouterr()
