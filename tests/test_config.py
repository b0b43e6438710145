"""Config files: ``scanalign COMMAND --config FILE``, ``scanalign dump-config COMMAND`` and the
effective config written beside every output (scanalign.config)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from helpers import apply, rigid
from scanalign import cli, config


@pytest.fixture()
def parsers(monkeypatch, capsys):
    """The parser of each config-file command, as ``scanalign`` builds it."""
    found = {}
    real = config.use_config_file

    def spy(subparsers, argv):
        found.update({name: subparsers.choices[name] for name in config.COMMANDS})
        return real(subparsers, argv)

    monkeypatch.setattr(config, "use_config_file", spy)
    assert cli.main(["dump-config", "register"]) == 0
    capsys.readouterr()
    return found


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


@pytest.mark.parametrize("command", config.COMMANDS)
def test_dump_config_loads_back_to_the_defaults(command, parsers, capsys, tmp_path):
    assert cli.main(["dump-config", command]) == 0
    text = capsys.readouterr().out
    dumped = yaml.safe_load(text)
    parser = parsers[command]
    every = config.settings(parser)
    assert set(dumped) == {s.key for s in every} and "config" not in dumped and "help" not in dumped
    for s in every:  # the defaults, as YAML values (tuples as lists, flags as true/false)
        assert dumped[s.key] == s.default, s.key
    # Every setting is preceded by a comment naming its option, and read back by load()
    # it gives the parser's defaults.
    lines = text.splitlines()
    for s in every:
        k = next(i for i, line in enumerate(lines) if line.startswith(f"{s.key}: "))
        comment = []
        while lines[k - 1 - len(comment)].startswith("# ") and not lines[k - 1 - len(comment)].startswith("# --- "):
            comment.append(lines[k - 1 - len(comment)])
        assert comment and comment[-1].startswith(f"# {s.option}"), (s.key, comment)
    path = tmp_path / f"{command}.yaml"
    path.write_text(text)
    assert config.load(path, parser, command) == {s.dest: s.default for s in every}


def test_dump_config_states_units(capsys):
    assert cli.main(["dump-config", "register"]) == 0
    text = capsys.readouterr().out
    assert "# --max-distance [m]: max correspondence distance, m (0.05)\nmax_distance: 0.05\n" in text
    assert "# --normal-radius [m]:" in text and "max_iterations: 50\n" in text
    assert "estimator: point_to_plane\n" in text and "one of point_to_plane, point_to_point" in text
    assert cli.main(["dump-config", "pick"]) == 0
    assert "# --q-current [Q1, Q2, Q3, Q4, Q5, Q6] [rad]:" in capsys.readouterr().out
    assert cli.main(["dump-config", "pose"]) == 0
    assert "# --resolution [px]:" in capsys.readouterr().out


def test_settings_come_from_the_parser():
    """A new option is a new key with its default, unit and type, with nothing listed by hand."""
    p = argparse.ArgumentParser()
    g = p.add_argument_group("things")
    g.add_argument("--step-size", type=float, default=0.25, help="step, m (0.25)")
    g.add_argument("--angles", type=float, nargs=2, help="in radians")
    p.add_argument("--mode", choices=["a", "b"], default="a")
    p.add_argument("--fast", action="store_true")
    p.add_argument("positional")
    s = {x.key: x for x in config.settings(p)}
    assert list(s) == ["step_size", "angles", "mode", "fast"]
    assert (s["step_size"].unit, s["step_size"].default, s["step_size"].group) == ("m", 0.25, "things")
    assert s["angles"].unit == "rad" and s["fast"].is_flag and s["mode"].unit is None


# --------------------------------------------------------------------------- precedence


def test_a_config_file_changes_the_run_like_the_flags(clouds, capsys):
    rc0, default = register(capsys)
    Path("run.yaml").write_text("estimator: point_to_point\nnormal-radius: 0.01\nmax_distance: 0.004\n")
    rc1, from_file = register(capsys, "--config", "run.yaml")
    rc2, from_flags = register(capsys, "--estimator", "point_to_point", "--normal-radius", "0.01",
                               "--max-distance", "0.004")
    assert rc0 == 0 and rc1 == rc2
    assert from_file == from_flags
    assert from_file != default
    # JSON is YAML: the same settings as a .json file.
    Path("run.json").write_text(json.dumps({"estimator": "point_to_point", "normal_radius": 0.01,
                                            "max-distance": 0.004}))
    assert register(capsys, "--config", "run.json") == (rc1, from_file)


def test_flags_override_the_file(clouds, capsys):
    Path("run.yaml").write_text("max_iterations: 1\nnormal_radius: 0.01\nout: from_file.ply\n")
    rc, capped = register(capsys, "--config", "run.yaml")
    assert capped["iterations"] == 1 and not capped["converged"] and rc == 2
    rc, result = register(capsys, "--config", "run.yaml", "--max-iterations", "50", "--out", "aligned.ply")
    assert rc == 0 and result["converged"] and result["iterations"] > 1
    assert register(capsys, "--normal-radius", "0.01") == (rc, result)  # the file's other setting kept
    written = settings_of(Path("aligned.config.yaml"))
    assert (written["max_iterations"], written["normal_radius"], written["out"]) == (50, 0.01, "aligned.ply")


def test_the_effective_config_repeats_the_run(clouds, capsys):
    Path("run.yaml").write_text("normal_radius: 0.01\nbox: [-1, 1, -1, 1, 0, 2]\n")
    rc, first = register(capsys, "--config", "run.yaml", "--max-distance", "0.03", "--out", "aligned.ply")
    effective = Path("aligned.config.yaml")
    text = effective.read_text()
    assert "scanalign register source.pcd target.pcd --config aligned.config.yaml" in text
    s = settings_of(effective)
    assert s["max_distance"] == 0.03 and s["normal_radius"] == 0.01 and s["box"] == [-1.0, 1.0, -1.0, 1.0, 0.0, 2.0]
    assert s["init"] is None and s["estimator"] == "point_to_plane" and "config" not in s
    aligned = Path("aligned.ply").read_bytes()
    Path("aligned.ply").unlink()
    # Fed back, alone: the same result, the same aligned cloud, the same settings.
    assert register(capsys, "--config", str(effective)) == (rc, first)
    assert Path("aligned.ply").read_bytes() == aligned
    assert settings_of(effective) == s


def test_reconstruct_writes_its_config_into_the_output_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("run.yaml").write_text("frames: 2\nno_plots: true\nno_progress: true\nout: first\nframe_voxel: 0.004\n")
    assert cli.main(["reconstruct", "builtin", "--config", "run.yaml", "--threads", "2"]) == 0
    assert "wrote first/config.yaml" in capsys.readouterr().out
    s = settings_of(Path("first/config.yaml"))
    assert (s["frames"], s["frame_voxel"], s["threads"], s["no_plots"]) == (2, 0.004, 2, True)
    assert len(Path("first/frames.csv").read_text().splitlines()) == 1 + 2
    # Fed back with another output folder: the same trajectory.
    assert cli.main(["reconstruct", "builtin", "--config", "first/config.yaml", "--out", "second",
                     "--quiet"]) == 0
    assert Path("second/trajectory.txt").read_text() == Path("first/trajectory.txt").read_text()
    assert settings_of(Path("second/config.yaml")) == {**s, "out": "second", "quiet": True}


def test_a_file_can_give_a_required_option(tmp_path, monkeypatch, capsys):
    """``pose`` requires --model and --scene: a config file may give them."""
    monkeypatch.chdir(tmp_path)
    Path("pose.yaml").write_text("model: missing.stl\nscene: missing.ply\n")
    assert cli.main(["pose", "--config", "pose.yaml"]) == 2
    assert "missing.stl: no such model file" in capsys.readouterr().err


# --------------------------------------------------------------------------- bad files


BAD = [  # file text, fragment of the one-line message (after "scanalign register: error: run.yaml: ")
    ("max_distnce: 0.1\n", "max_distnce: unknown setting of 'scanalign register'; did you mean max_distance?"),
    ("max_distance: far\n", "max_distance: expected a number, got 'far'"),
    ("max_distance: true\n", "max_distance: expected a number, got True"),
    ("max_iterations: 2.5\n", "max_iterations: expected an integer, got 2.5"),
    ("max_iterations: null\n", "max_iterations: null is not allowed; expected an integer (default 50)"),
    ("estimator: point_to_line\n", "estimator: 'point_to_line' is not one of point_to_plane, point_to_point"),
    ("box: [0, 1, 0, 1]\n", "box: expected a list of 6 values, each a number, got [0, 1, 0, 1]"),
    ("max_distance: [0.1\n", "malformed YAML/JSON at line 2"),
    ("{\"max_distance\": 0.1,,}\n", "malformed YAML/JSON at line 1"),
    ("- max_distance\n", "expected a mapping of settings (key: value), got list"),
    ("max_distance: 0.1\nmax-distance: 0.2\n", "max-distance: given twice (also as max_distance)"),
    ("config: other.yaml\n", "config: unknown setting"),
]


@pytest.mark.parametrize("text, fragment", BAD, ids=[b[1].split(":")[0] + f" #{k}" for k, b in enumerate(BAD)])
def test_a_bad_config_file_is_one_line_naming_file_and_key(clouds, capsys, text, fragment):
    Path("run.yaml").write_text(text)
    assert cli.main(["register", "source.pcd", "target.pcd", "--config", "run.yaml"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("scanalign register: error: run.yaml: "), captured.err
    assert fragment in lines[0], lines[0]


def test_a_missing_config_file_is_named(clouds, capsys):
    assert cli.main(["register", "source.pcd", "target.pcd", "--config", "nope.yaml"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("scanalign register: error: nope.yaml: cannot read the config file") and err.count("\n") == 1


def test_other_commands_take_no_config(capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["ik", "--robot", "ur5", "--config", "x.yaml"])
    assert info.value.code == 2
    with pytest.raises(SystemExit):
        cli.main(["dump-config", "ik"])
    capsys.readouterr()
