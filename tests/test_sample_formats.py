"""Sample recordings made by the project itself: ``scanalign synth --format tum|bag|png`` writes the
synthetic scan as a TUM folder, a ROS 1 / ROS 2 bag or a PNG folder, and ``open_source`` reads each
back to the renderer's truth: noise-free depth (within half a depth unit), the intrinsics, the
timestamps, the scanner's camera poses (1e-9) and the arm's joints."""

from __future__ import annotations

import json

import numpy as np
import pytest

from scanalign import datasets, synthetic
from scanalign.cli import main
from scanalign.evaluation.trajectory import read_tum_trajectory

N_FRAMES = 3


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    """A small noise-free config file and its scan rendered with the true depth (float32 m, NaN: no hit)."""
    path = tmp_path_factory.mktemp("cfg") / "scan.json"
    path.write_text(json.dumps({"n_frames": N_FRAMES, "resolution_scale": 0.25, "noise": "none"}))
    return path, synthetic.SyntheticConfig.from_file(path).build(keep_ground_truth=True)


@pytest.mark.parametrize("fmt, name, reader", [
    (None, "tum", datasets.TumSequence), ("png", "png", datasets.ImageFolderSequence),
    ("bag", "scan.bag", datasets.BagSequence), ("bag", "ros2", datasets.BagSequence)])
def test_synth_writes_what_open_source_reads(config, tmp_path, fmt, name, reader):
    if fmt == "bag":
        pytest.importorskip("rosbags")
    path, truth = config
    out = tmp_path / name
    assert main(["synth", str(path), str(out)] + (["--format", fmt] if fmt else [])) == 0
    seq = datasets.open_source(out)
    assert type(seq) is reader and len(seq) == N_FRAMES
    assert seq.intrinsics == truth.intrinsics
    poses = [f.T_base_camera for f in seq]
    if fmt == "png":  # the reader has no poses: they are in groundtruth.txt beside the images
        assert poses == [None] * N_FRAMES
        gt = read_tum_trajectory(out / "groundtruth.txt")
        np.testing.assert_allclose(gt.timestamps, truth.reference.timestamps, atol=1e-6)
        poses = gt.poses
    np.testing.assert_allclose(np.stack(poses), truth.reference.poses, atol=1e-9 if fmt == "bag" else 1e-6)
    for k, f in enumerate(seq):
        assert f.timestamp == pytest.approx(truth.reference.timestamps[k], abs=1e-9)
        true, hit = truth.frames[k].meta["depth_true"], f.depth > 0
        assert hit.mean() > 0.5 and np.array_equal(hit, np.isfinite(true))
        np.testing.assert_allclose(f.depth[hit] * seq.depth_scale, true[hit], rtol=0, atol=0.5 * seq.depth_scale + 1e-6)
        assert f.rgb.shape == truth.intrinsics.shape + (3,) and f.rgb.std() > 10  # a picture, not a blank
        if fmt == "bag":
            np.testing.assert_allclose(f.meta["joints"], truth.joints[k], atol=1e-12)


def test_bag_writer_refuses_an_existing_path(tmp_path, config):
    pytest.importorskip("rosbags")
    (tmp_path / "x.bag").write_text("")
    with pytest.raises(FileExistsError, match="x.bag: exists"):
        datasets.sources.write_bag(tmp_path / "x.bag", config[1].frames)
