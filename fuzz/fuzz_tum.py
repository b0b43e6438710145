"""atheris target: TUM RGB-D text files (trajectories, image lists) through
scanalign.evaluation.trajectory.read_tum_trajectory / scanalign.datasets.tum.read_timestamp_list,
then the parsed timestamps through association and the trajectory through interpolation (byte
0 picks the reader, the rest is the file)."""

from __future__ import annotations

import numpy as np

import _fuzzlib

with _fuzzlib.instrumented():
    from scanalign import evaluation
    from scanalign.datasets import tum
    from scanalign.evaluation import trajectory


def seeds() -> dict:
    traj = ("# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
            "1305031102.1753 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
            "1305031102.1853 1.3403 0.6275 1.6574 0.6579 0.6124 -0.2949 -0.3241\n"
            "1305031102.1953,1.3404,0.6281,1.6572,0.6577,0.6121,-0.2955,-0.3245\n"
            "1305031102.2053\t1.3408\t0.6289\t1.6570\t0.6571\t0.6117\t-0.2960\t-0.3259\n")
    images = ("# depth maps\n# timestamp filename\n1305031102.160407 depth/1305031102.160407.png\n"
              "1305031102.194330 depth/1305031102.194330.png\n1305031102.226738 depth/1305031102.226738.png\n")
    return {"groundtruth.txt": b"\0" + traj.encode(), "depth.txt": b"\1" + images.encode()}


def check_trajectory(traj: trajectory.Trajectory) -> None:
    R = traj.rotations
    assert np.isfinite(traj.poses).all() and np.isfinite(traj.timestamps).all()
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-9), "a rotation is not orthonormal"
    try:
        mid = traj.interpolate(traj.timestamps[:1] if len(traj) else [])
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    assert np.isfinite(mid.poses).all()


def test_one_input(data: bytes) -> None:
    if not data:
        return
    path = _fuzzlib.as_file(data[1:], ".txt")
    try:
        if data[0] % 2 == 0:
            traj = trajectory.read_tum_trajectory(path)
            check_trajectory(traj)
            t = traj.timestamps
        else:
            t, names, lines = tum.read_timestamp_list(path)
            assert len(names) == len(lines) == len(t) and np.all(np.diff(t) > 0)
        pairs = trajectory.associate_timestamps(np.sort(t), np.sort(t) + 0.01, 0.02)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    assert len(set(pairs[:, 0])) == len(pairs) == len(set(pairs[:, 1])), "association is not one-to-one"
    if len(pairs):
        assert np.abs(np.sort(t)[pairs[:, 0]] - np.sort(t)[pairs[:, 1]] - 0.01).max() <= 0.02 + 1e-9
    if data[0] % 2 == 0 and len(t):
        est = trajectory.Trajectory(t, traj.poses)
        try:
            evaluation.associate(est, est, max_difference=0.0, method="nearest" if data[0] & 2 else "greedy")
        except _fuzzlib.ALLOWED as e:
            _fuzzlib.outcome(f"{type(e).__name__}: {e}")
            return


if __name__ == "__main__":
    _fuzzlib.run(test_one_input, seeds())
