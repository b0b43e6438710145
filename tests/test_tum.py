"""Tests for scanalign.datasets.tum: TUM RGB-D benchmark sequence folders.

Independent truth used here: a minimal PNG encoder/decoder written from the PNG
specification (zlib + the five row filters), a brute-force O(N*M) version of the
benchmark's association rule, and an analytic constant-velocity trajectory (constant
linear velocity, constant angular velocity about a body-fixed axis), for which linear /
spherical-linear interpolation between samples is exact.
"""

from __future__ import annotations

import json
import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from helpers import rigid
from scanalign.datasets import tum
from scanalign.reconstruction.camera import INTRINSICS_PRESETS, Frame, Intrinsics
from scanalign.evaluation.trajectory import Trajectory, associate_timestamps
from scanalign.datasets.tum import TumFormatError, TumSequence, is_tum_folder, write_tum_sequence

SMALL = Intrinsics(16, 12, 20.0, 21.0, 7.5, 5.5)  # (H, W) = (12, 16)
T0 = 1305031102.175304  # a real TUM timestamp (freiburg1_xyz)


# --------------------------------------------------------------------------- helpers: PNG


def png_encode(arr: np.ndarray, bit_depth: int, colour_type: int) -> bytes:
    """PNG bytes of ``arr`` (H, W) or (H, W, C), filter 0 on every row, no interlace."""
    a = np.asarray(arr)
    h, w = a.shape[:2]
    dtype = ">u2" if bit_depth == 16 else "u1"
    rows = a.astype(dtype).reshape(h, -1)
    raw = b"".join(b"\x00" + rows[r].tobytes() for r in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, bit_depth, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def png_decode(path) -> tuple:
    """(bit_depth, colour_type, array) of a non-interlaced greyscale or RGB PNG."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, bit_depth, colour_type, _, _, interlace = ihdr
    assert interlace == 0 and bit_depth in (8, 16) and colour_type in (0, 2)
    channels = {0: 1, 2: 3}[colour_type]
    bpp = channels * bit_depth // 8
    stride = w * bpp
    raw = zlib.decompress(idat)
    out = np.zeros((h, stride), dtype=np.int64)
    prev = np.zeros(stride, dtype=np.int64)
    for r in range(h):
        ftype = raw[r * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, r * (stride + 1) + 1).astype(np.int64)
        cur = np.zeros(stride, dtype=np.int64)
        for i in range(stride):
            a = cur[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if ftype == 0:
                pred = 0
            elif ftype == 1:
                pred = a
            elif ftype == 2:
                pred = b
            elif ftype == 3:
                pred = (a + b) // 2
            else:  # Paeth
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[i] = (line[i] + pred) & 0xFF
        out[r] = cur
        prev = cur
    bytes_ = out.astype(np.uint8)
    if bit_depth == 16:
        values = bytes_.reshape(h, -1, 2)
        values = values[..., 0].astype(np.int64) * 256 + values[..., 1]
    else:
        values = bytes_.astype(np.int64)
    return bit_depth, colour_type, values.reshape((h, w) if channels == 1 else (h, w, channels))


# --------------------------------------------------------------------------- helpers: truth


def brute_force_associate(a, b, max_difference):
    """The benchmark's associate.py rule, literally: every pair, sorted by |dt|, greedy."""
    cands = sorted((abs(ta - tb), i, j) for i, ta in enumerate(a) for j, tb in enumerate(b)
                   if abs(ta - tb) <= max_difference)
    used_a, used_b, pairs = set(), set(), []
    for _, i, j in cands:
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def quat_mul(p, q):
    """Hamilton product of (x, y, z, w) quaternions."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array([pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz])


class ConstantVelocity:
    """p(t) = p0 + v (t - t0); R(t) = R0 Rot(axis, w (t - t0)) (body-fixed axis)."""

    def __init__(self, t0):
        self.t0 = t0
        self.p0 = np.array([1.3563, 0.6305, 1.6380])
        self.v = np.array([0.21, -0.13, 0.05])  # m/s
        self.axis0, self.angle0 = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5]), 2.1
        self.axis = np.array([0.6, 0.7, -0.2]) / np.linalg.norm([0.6, 0.7, -0.2])
        self.w = 0.9  # rad/s

    def matrix(self, t):
        T = rigid(self.axis0, self.angle0, self.p0 + self.v * (t - self.t0))
        T[:3, :3] = T[:3, :3] @ rigid(self.axis, self.w * (t - self.t0), np.zeros(3))[:3, :3]
        return T

    def tum_row(self, t):
        h0, h = self.angle0 / 2, self.w * (t - self.t0) / 2
        q = quat_mul(np.r_[self.axis0 * math.sin(h0), math.cos(h0)], np.r_[self.axis * math.sin(h), math.cos(h)])
        return np.r_[self.p0 + self.v * (t - self.t0), q]


def random_pose(rng):
    axis = rng.normal(size=3)
    return rigid(axis, rng.uniform(0, math.pi), rng.uniform(-2, 2, 3))


def write_list(path: Path, header: str, entries) -> None:
    with open(path, "w") as f:
        f.write(header)
        for t, name in entries:
            f.write(f"{t} {name}\n")


def make_folder(root: Path, n=4, intr=SMALL, rgb=True, camera=True, depth_scale=None, name="seq"):
    """A small hand-written sequence: depth values encode (frame, row, col)."""
    folder = root / name
    (folder / "depth").mkdir(parents=True)
    h, w = intr.shape
    d_entries, r_entries = [], []
    for k in range(n):
        t = f"{T0 + 0.04 * k:.6f}"
        depth = (1000 * (k + 1) + np.arange(h * w).reshape(h, w)).astype(np.uint16)
        (folder / f"depth/{t}.png").write_bytes(png_encode(depth, 16, 0))
        d_entries.append((t, f"depth/{t}.png"))
        if rgb:
            (folder / "rgb").mkdir(exist_ok=True)
            tr = f"{T0 + 0.04 * k - 0.005:.6f}"
            img = np.full((h, w, 3), k, dtype=np.uint8)
            (folder / f"rgb/{tr}.png").write_bytes(png_encode(img, 8, 2))
            r_entries.append((tr, f"rgb/{tr}.png"))
    write_list(folder / "depth.txt", "# depth maps\n# file: 'x.bag'\n# timestamp filename\n", d_entries)
    if rgb:
        write_list(folder / "rgb.txt", "# color images\n# file: 'x.bag'\n# timestamp filename\n", r_entries)
    if camera:
        d = intr.to_dict()
        if depth_scale is not None:
            d["depth_scale"] = depth_scale
        (folder / "camera.json").write_text(json.dumps(d))
    return folder


# --------------------------------------------------------------------------- round trips


def test_write_read_round_trip_random_frames(tmp_path):
    rng = np.random.default_rng(7)
    n = 9
    stamps = T0 + np.cumsum(rng.uniform(0.02, 0.05, n)) + rng.uniform(0, 1e-6, n)  # sub-microsecond parts
    frames = []
    for k in range(n):
        depth = rng.integers(0, 65536, SMALL.shape, dtype=np.uint16)
        depth[rng.random(SMALL.shape) < 0.2] = 0  # holes
        depth[0, :4] = [0, 0x00FF, 0xFF00, 0xFFFF]  # byte-order probes
        rgb = rng.integers(0, 256, SMALL.shape + (3,), dtype=np.uint8)
        frames.append(Frame(depth=depth, intrinsics=SMALL, rgb=rgb, depth_scale=1 / 5000, timestamp=stamps[k],
                            T_base_camera=random_pose(rng), index=k))
    shuffled = [frames[k] for k in rng.permutation(n)]  # written in time order regardless
    out = write_tum_sequence(tmp_path / "seq", shuffled)
    assert out == str(tmp_path / "seq")
    assert is_tum_folder(out)

    seq = TumSequence(out)
    assert len(seq) == n and seq.name == "seq" and seq.intrinsics == SMALL
    assert seq.depth_scale == 1 / 5000 and seq.has_rgb and seq.dropped_depth_frames == 0
    np.testing.assert_allclose(seq.timestamps, stamps, rtol=0, atol=1e-6)
    for k, (got, want) in enumerate(zip(seq, frames)):
        assert got.depth.dtype == np.uint16 and got.depth.shape == SMALL.shape
        np.testing.assert_array_equal(got.depth, want.depth)
        assert got.rgb.dtype == np.uint8
        np.testing.assert_array_equal(got.rgb, want.rgb)
        assert abs(got.timestamp - want.timestamp) <= 1e-6
        np.testing.assert_allclose(got.T_base_camera, want.T_base_camera, rtol=0, atol=1e-9)
        assert got.index == k and got.depth_scale == 1 / 5000 and got.intrinsics == SMALL
        # The files themselves, decoded independently of Pillow: 16-bit greyscale / 8-bit RGB.
        bit_depth, colour_type, values = png_decode(got.meta["depth_file"])
        assert (bit_depth, colour_type) == (16, 0)
        np.testing.assert_array_equal(values, want.depth)
        bit_depth, colour_type, values = png_decode(got.meta["rgb_file"])
        assert (bit_depth, colour_type) == (8, 2)
        np.testing.assert_array_equal(values, want.rgb)
        np.testing.assert_allclose(got.depth_metres(), np.where(want.depth == 0, np.nan,
                                                                 want.depth.astype(np.float32) / np.float32(5000)),
                                   rtol=1e-6)
    ref = seq.reference_trajectory()
    assert isinstance(ref, Trajectory) and len(ref) == n
    np.testing.assert_allclose(ref.poses, np.stack([f.T_base_camera for f in frames]), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(ref.timestamps, seq.timestamps)
    # The text files look like the benchmark's: 6 decimals, 'timestamp filename'.
    lines = [l for l in (tmp_path / "seq/depth.txt").read_text().splitlines() if not l.startswith("#")]
    assert lines[0] == f"{stamps[0]:.6f} depth/{stamps[0]:.6f}.png"
    assert json.loads((tmp_path / "seq/camera.json").read_text())["depth_scale"] == 1 / 5000


def test_depth_written_by_independent_encoder_is_read_bit_exact(tmp_path):
    folder = tmp_path / "seq"
    (folder / "depth").mkdir(parents=True)
    rng = np.random.default_rng(3)
    h, w = SMALL.shape
    images = [np.arange(h * w, dtype=np.uint16).reshape(h, w) * 331 + 1, rng.integers(0, 65536, (h, w)).astype(np.uint16)]
    images[0][0, :3] = [0, 0xFFFF, 0x0100]
    for k, img in enumerate(images):
        (folder / f"depth/{k}.png").write_bytes(png_encode(img, 16, 0))
    (folder / "depth.txt").write_text("1.0 depth/0.png\n2.0 depth/1.png\n")
    seq = TumSequence(folder, intrinsics=SMALL)
    assert seq.depth_scale == 1 / 5000  # TUM default
    for frame, img in zip(seq, images):
        assert frame.depth.dtype == np.uint16 and frame.rgb is None
        np.testing.assert_array_equal(frame.depth, img)


def test_float_and_millimetre_depth_are_quantised_to_the_target_scale(tmp_path):
    rng = np.random.default_rng(11)
    units = rng.integers(1, 65536, SMALL.shape)
    noise = rng.uniform(-0.45, 0.45, SMALL.shape)
    metres = (units + noise) / 5000.0
    metres[0, 0], metres[0, 1], metres[0, 2], metres[0, 3] = np.nan, np.inf, -0.5, 0.0
    mm = rng.integers(0, 13000, SMALL.shape).astype(np.uint16)  # <= 13 m fits 1/5000
    frames = [Frame(depth=metres.astype(np.float64), intrinsics=SMALL, timestamp=10.0),
              Frame(depth=metres.astype(np.float32), intrinsics=SMALL, timestamp=10.1),
              Frame(depth=mm, intrinsics=SMALL, depth_scale=0.001, timestamp=10.2)]
    seq = TumSequence(write_tum_sequence(tmp_path / "q", frames, write_groundtruth=True))
    assert not (tmp_path / "q/groundtruth.txt").exists()  # no frame has a pose
    assert seq.reference_trajectory() is None and not (tmp_path / "q/rgb.txt").exists()
    expected = units.copy()
    expected[0, :4] = 0
    np.testing.assert_array_equal(seq[0].depth, expected)
    # float32 metres lose a little precision; still within half a unit of the noisy value
    np.testing.assert_array_less(np.abs(seq[1].depth.astype(float) - expected), 1.0)
    np.testing.assert_array_equal(seq[2].depth, mm.astype(np.int64) * 5)
    assert seq[0].rgb is None and seq[0].T_base_camera is None


def test_write_other_depth_scale_and_explicit_intrinsics(tmp_path):
    depth = np.arange(SMALL.width * SMALL.height, dtype=np.uint16).reshape(SMALL.shape) * 7
    f = Frame(depth=depth, intrinsics=SMALL, depth_scale=0.001, timestamp=1.0)
    other = Intrinsics(16, 12, 30.0, 30.0, 8.0, 6.0)
    folder = write_tum_sequence(tmp_path / "mm", [f], intrinsics=other, depth_scale=0.001)
    seq = TumSequence(folder)
    assert seq.intrinsics == other and seq.depth_scale == 0.001
    np.testing.assert_array_equal(seq[0].depth, depth)  # same scale: copied bit for bit


def test_partial_ground_truth_is_interpolated_between_posed_frames(tmp_path):
    traj = ConstantVelocity(100.0)
    stamps = 100.0 + 0.05 * np.arange(6)
    frames = [Frame(depth=np.ones(SMALL.shape, np.uint16), intrinsics=SMALL, timestamp=t,
                    T_base_camera=traj.matrix(t) if k in (1, 2, 4) else None) for k, t in enumerate(stamps)]
    seq = TumSequence(write_tum_sequence(tmp_path / "p", frames))
    poses = seq.poses()
    assert poses[0] is None and poses[5] is None  # outside the ground-truth span
    for k in (1, 2, 3, 4):  # 3 lies between 2 and 4 (0.1 s apart <= max_groundtruth_gap)
        np.testing.assert_allclose(poses[k], traj.matrix(stamps[k]), rtol=0, atol=1e-9)
    assert seq[3].T_base_camera is not None
    assert len(seq.reference_trajectory()) == 4
    # a smaller allowed gap leaves frame 3 without a pose
    assert TumSequence(tmp_path / "p", max_groundtruth_gap=0.06).poses()[3] is None
    # no ground truth when asked not to write it
    write_tum_sequence(tmp_path / "n", frames, write_groundtruth=False)
    assert not (tmp_path / "n/groundtruth.txt").exists()
    assert TumSequence(tmp_path / "n").reference_trajectory() is None


# --------------------------------------------------------------------------- a real-looking folder


def test_real_layout_association_and_ground_truth_interpolation(tmp_path):
    rng = np.random.default_rng(2024)
    folder = tmp_path / "rgbd_dataset_freiburg1_xyz"
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    h, w = SMALL.shape
    # Kinect streams at ~30 Hz, not synchronised, with jitter; rgb drops frames 20..24.
    n = 60
    t_depth = np.round(T0 + 1 / 30 * np.arange(n) + rng.uniform(-0.004, 0.004, n), 6)
    t_rgb = np.round(T0 + 0.011 + 1 / 30 * np.arange(n + 3) + rng.uniform(-0.006, 0.006, n + 3), 6)
    t_rgb = np.delete(t_rgb, np.arange(20, 25))
    d_entries, r_entries = [], []
    for k, t in enumerate(t_depth):
        name = f"depth/{t:.6f}.png"
        (folder / name).write_bytes(png_encode(np.full((h, w), 5000 + k, np.uint16), 16, 0))
        d_entries.append((f"{t:.6f}", name))
    for k, t in enumerate(t_rgb):
        name = f"rgb/{t:.6f}.png"
        img = np.zeros((h, w, 3), np.uint8)
        img[..., 0], img[..., 1] = k % 256, k // 256  # the image knows its index
        (folder / name).write_bytes(png_encode(img, 8, 2))
        r_entries.append((f"{t:.6f}", name))
    write_list(folder / "rgb.txt", "# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n",
               r_entries)
    write_list(folder / "depth.txt", "# depth maps\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n",
               d_entries)
    # Ground truth at 100 Hz with 4 decimals (like the benchmark), starting after the 3rd
    # depth frame, ending before the last 4, with a 0.3 s tracking loss in the middle.
    traj = ConstantVelocity(T0)
    t_gt = np.array([float(f"{t:.4f}") for t in np.arange(t_depth[2] + 0.003, t_depth[-4], 0.01)])
    t_gt = t_gt[(t_gt < T0 + 1.0) | (t_gt > T0 + 1.3)]
    with open(folder / "groundtruth.txt", "w") as f:
        f.write("# ground truth trajectory\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
                "# timestamp tx ty tz qx qy qz qw\n")
        for t in t_gt:
            f.write(f"{t:.4f} " + " ".join(repr(float(v)) for v in traj.tum_row(t)) + "\n")
    (folder / "camera.yaml").write_text("# test camera\n" + "".join(f"{k}: {v}\n" for k, v in SMALL.to_dict().items()))

    seq = TumSequence(folder)
    oracle = brute_force_associate(t_depth, t_rgb, 0.02)
    assert len(seq) == len(oracle) and seq.dropped_depth_frames == n - len(oracle)
    assert seq.dropped_depth_frames > 0  # the rgb gap cost depth frames
    assert seq.name == "rgbd_dataset_freiburg1_xyz" and seq.depth_scale == 1 / 5000
    np.testing.assert_array_equal(seq.timestamps, t_depth[[i for i, _ in oracle]])
    np.testing.assert_array_equal(seq.rgb_timestamps, t_rgb[[j for _, j in oracle]])
    gt_lo, gt_hi = t_gt[0], t_gt[-1]
    n_posed = 0
    for frame, (i, j) in zip(seq, oracle):
        assert frame.depth[0, 0] == 5000 + i  # the right depth file
        assert int(frame.rgb[0, 0, 0]) + 256 * int(frame.rgb[0, 0, 1]) == j  # the right colour file
        assert frame.meta["rgb_timestamp"] == t_rgb[j] and abs(t_depth[i] - t_rgb[j]) <= 0.02
        t = frame.timestamp
        k = np.searchsorted(t_gt, t)
        covered = gt_lo <= t <= gt_hi and (t_gt[k] == t or t_gt[k] - t_gt[k - 1] <= 0.1)
        if covered:
            n_posed += 1
            np.testing.assert_allclose(frame.T_base_camera, traj.matrix(t), rtol=0, atol=1e-9)
        else:
            assert frame.T_base_camera is None, t
    assert 0 < n_posed < len(seq) - 6  # frames before, after and inside the tracking loss
    ref = seq.reference_trajectory()
    assert len(ref) == n_posed
    for t, T in zip(ref.timestamps, ref.poses):
        np.testing.assert_allclose(T, traj.matrix(t), rtol=0, atol=1e-9)
    assert seq.groundtruth is not None and len(seq.groundtruth) == len(t_gt)


def test_associate_timestamps_matches_brute_force():
    rng = np.random.default_rng(5)
    for trial in range(200):
        a = np.sort(np.round(rng.uniform(0, 1, rng.integers(0, 30)), 2))  # coarse: ties happen
        b = np.sort(np.round(rng.uniform(0, 1, rng.integers(0, 30)), 2))
        a, b = np.unique(a), np.unique(b)
        md = float(rng.choice([0.0, 0.01, 0.02, 0.05, 0.5]))
        got = associate_timestamps(a, b, md)
        assert got.shape[1] == 2
        assert [tuple(p) for p in got.tolist()] == brute_force_associate(a, b, md), trial
    # a hand-checked case: 1.00 takes 1.01 (|dt| 0.01) over 1.015 is left for 1.02
    pairs = associate_timestamps([1.0, 1.02], [1.01, 1.015], 0.02)
    assert pairs.tolist() == [[0, 0], [1, 1]]
    assert associate_timestamps([1.0], [1.0], 0.0).tolist() == [[0, 0]]
    with pytest.raises(ValueError, match="sorted"):
        associate_timestamps([2.0, 1.0], [1.0], 0.1)
    with pytest.raises(ValueError, match="max_difference"):
        associate_timestamps([1.0], [1.0], -1)


def test_max_time_difference_controls_association(tmp_path):
    folder = make_folder(tmp_path, n=3)  # rgb is 5 ms before depth
    assert len(TumSequence(folder)) == 3
    with pytest.raises(TumFormatError, match="max_time_difference"):
        TumSequence(folder, max_time_difference=0.004)


# --------------------------------------------------------------------------- intrinsics and depth_scale


def test_intrinsics_and_depth_scale_precedence(tmp_path):
    big = INTRINSICS_PRESETS["tum_fr1"]
    folder = make_folder(tmp_path, n=2, intr=big, depth_scale=0.001, name="a")
    other_file = tmp_path / "other.yaml"
    other_file.write_text("".join(f"{k}: {v}\n" for k, v in INTRINSICS_PRESETS["tum_fr3"].to_dict().items())
                          + "depth_scale: 0.0005\n")
    nodepth_file = tmp_path / "nodepth.json"
    nodepth_file.write_text(json.dumps(INTRINSICS_PRESETS["tum_fr2"].to_dict()))

    s = TumSequence(folder)  # folder camera file
    assert s.intrinsics == big and s.depth_scale == 0.001 and s[0].depth_scale == 0.001
    s = TumSequence(folder, intrinsics="tum_fr2")  # preset; depth_scale still the folder's
    assert s.intrinsics == INTRINSICS_PRESETS["tum_fr2"] and s.depth_scale == 0.001
    s = TumSequence(folder, intrinsics=other_file)  # explicit file with depth_scale
    assert s.intrinsics == INTRINSICS_PRESETS["tum_fr3"] and s.depth_scale == 0.0005
    s = TumSequence(folder, intrinsics=str(nodepth_file))  # explicit file without depth_scale
    assert s.intrinsics == INTRINSICS_PRESETS["tum_fr2"] and s.depth_scale == 0.001
    s = TumSequence(folder, intrinsics=other_file, depth_scale=0.002)  # argument wins
    assert s.depth_scale == 0.002 and s[1].depth_scale == 0.002
    np.testing.assert_allclose(s[1].depth_metres()[0, 0], float(s[1].depth[0, 0]) * 0.002, rtol=1e-6)
    obj = Intrinsics(640, 480, 500.0, 500.0, 320.0, 240.0)
    assert TumSequence(folder, intrinsics=obj).intrinsics == obj

    bare = make_folder(tmp_path, n=1, intr=big, camera=False, name="b")
    s = TumSequence(bare, intrinsics="tum_fr1")
    assert s.depth_scale == 1 / 5000  # TUM default


def test_missing_intrinsics_error_suggests_the_option(tmp_path):
    folder = make_folder(tmp_path, n=1, camera=False, name="rgbd_dataset_freiburg2_desk")
    with pytest.raises(TumFormatError, match="--intrinsics") as e:
        TumSequence(folder)
    assert "tum_fr2" in str(e.value) and str(folder) in str(e.value)
    with pytest.raises(ValueError, match="neither a preset"):
        TumSequence(folder, intrinsics="tum_fr9")
    with pytest.raises(TypeError, match="intrinsics"):
        TumSequence(folder, intrinsics=42)


def test_bad_camera_files(tmp_path):
    folder = make_folder(tmp_path, n=1, name="two")
    (folder / "intrinsics.yaml").write_text("width: 16\n")
    with pytest.raises(TumFormatError, match="more than one camera file"):
        TumSequence(folder)
    (folder / "intrinsics.yaml").unlink()

    cam = folder / "camera.json"
    cam.write_text('{"width": 16, "height": 12, "fx": 20}')
    with pytest.raises(TumFormatError, match=r"camera\.json.*missing keys"):
        TumSequence(folder)
    cam.write_text('{"width": 16, "height": 12, "fx": 20, ')
    with pytest.raises(TumFormatError, match=r"camera\.json.*JSON"):
        TumSequence(folder)
    for bad in ("-0.001", "0", '"1/5000"'):
        cam.write_text(json.dumps(SMALL.to_dict())[:-1] + f', "depth_scale": {bad}}}')
        with pytest.raises(TumFormatError, match=r"camera\.json.*depth_scale"):
            TumSequence(folder)
    cam.write_text(json.dumps({**SMALL.to_dict(), "fx": -3}))
    with pytest.raises(TumFormatError, match=r"camera\.json.*focal"):
        TumSequence(folder)
    cam.unlink()
    (folder / "camera.yaml").write_text("width 16\n")
    with pytest.raises(TumFormatError, match=r"camera\.yaml.*key: value"):
        TumSequence(folder)
    with pytest.raises(ValueError, match="depth_scale"):
        TumSequence(folder, intrinsics=SMALL, depth_scale=0)


# --------------------------------------------------------------------------- selection


def test_stride_start_limit_and_indexing(tmp_path):
    folder = make_folder(tmp_path, n=10)
    full = TumSequence(folder)
    all_t = full.timestamps
    s = TumSequence(folder, start=2, stride=3, limit=2)
    np.testing.assert_array_equal(s.timestamps, all_t[2::3][:2])
    assert [f.index for f in s] == [0, 1]
    assert [f.meta["source_index"] for f in s] == [2, 5]
    assert [int(f.depth[0, 0]) for f in s] == [3000, 6000]  # depth images of frames 2 and 5
    assert [int(f.rgb[0, 0, 0]) for f in s] == [2, 5]
    assert len(TumSequence(folder, stride=4)) == 3
    assert len(TumSequence(folder, start=9)) == 1
    assert len(TumSequence(folder, start=10)) == 0
    assert len(TumSequence(folder, limit=0)) == 0
    assert TumSequence(folder, start=10).reference_trajectory() is None
    assert full[-1].timestamp == all_t[-1] and full[-1].index == 9
    with pytest.raises(IndexError):
        full[10]
    with pytest.raises(IndexError):
        full[-11]
    with pytest.raises(TypeError):
        full[1.0]
    for kwargs in ({"stride": 0}, {"start": -1}, {"limit": -1}, {"max_time_difference": -0.1},
                   {"max_time_difference": float("nan")}, {"max_groundtruth_gap": 0}):
        with pytest.raises(ValueError):
            TumSequence(folder, **kwargs)
    with pytest.raises(TypeError):
        TumSequence(folder, stride=1.5)


def test_depth_only_sequences(tmp_path):
    folder = make_folder(tmp_path, n=3, rgb=False)
    s = TumSequence(folder)
    assert len(s) == 3 and not s.has_rgb and s.rgb_timestamps is None and s.rgb_files is None
    assert all(f.rgb is None for f in s)
    (folder / "rgb.txt").write_text("# color images\n# none\n# timestamp filename\n")
    assert len(TumSequence(folder)) == 3  # an empty rgb.txt is the same as none


def test_unsorted_lists_are_sorted_and_duplicates_rejected(tmp_path):
    folder = make_folder(tmp_path, n=4)
    lines = (folder / "depth.txt").read_text().splitlines()
    header, body = lines[:3], lines[3:]
    (folder / "depth.txt").write_text("\n".join(header + body[::-1] + [""]))
    gt = folder / "groundtruth.txt"
    traj = ConstantVelocity(T0)
    rows = [f"{float(t)!r} " + " ".join(repr(float(v)) for v in traj.tum_row(t)) for t in T0 - 0.1 + 0.01 * np.arange(40)]
    gt.write_text("\n".join(rows[::-1]) + "\n")
    s = TumSequence(folder)
    assert np.all(np.diff(s.timestamps) > 0)
    assert [int(f.depth[0, 0]) for f in s] == [1000, 2000, 3000, 4000]
    assert np.all(np.diff(s.groundtruth.timestamps) > 0)
    for f in s:
        np.testing.assert_allclose(f.T_base_camera, traj.matrix(f.timestamp), rtol=0, atol=1e-9)

    gt.write_text(rows[0] + "\n" + rows[1] + "\n" + rows[0] + "\n")
    with pytest.raises(TumFormatError, match=r"groundtruth\.txt.*appears twice"):
        TumSequence(folder)
    gt.unlink()
    (folder / "depth.txt").write_text("\n".join(header + body + [body[1]] + [""]))
    with pytest.raises(TumFormatError, match=r"depth\.txt:8: .*appears twice \(lines 5 and 8\)") as e:
        TumSequence(folder)
    assert e.value.line == 8 and e.value.path.endswith("depth.txt")


# --------------------------------------------------------------------------- bad input


def test_missing_folder_and_lists(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such sequence folder"):
        TumSequence(tmp_path / "nope")
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(NotADirectoryError):
        TumSequence(tmp_path / "file.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match=r"depth\.txt"):
        TumSequence(tmp_path / "empty", intrinsics=SMALL)
    assert not is_tum_folder(tmp_path / "empty") and not is_tum_folder(tmp_path / "nope")
    assert not is_tum_folder(tmp_path / "file.txt") and not is_tum_folder(None)
    folder = make_folder(tmp_path, n=1)
    assert is_tum_folder(folder) and is_tum_folder(str(folder))


@pytest.mark.parametrize("line, message", [
    ("1305031102.1 depth/a.png extra", "expected 'timestamp filename'"),
    ("1305031102.1", "expected 'timestamp filename'"),
    ("12:30 depth/a.png", "not a number"),
    ("nan depth/a.png", "not finite"),
])
def test_malformed_list_lines_name_file_and_line(tmp_path, line, message):
    folder = make_folder(tmp_path, n=2)
    text = (folder / "depth.txt").read_text()
    (folder / "depth.txt").write_text(text + line + "\n")
    with pytest.raises(TumFormatError, match=message) as e:
        TumSequence(folder)
    assert e.value.line == 6 and str(e.value).startswith(f"{folder / 'depth.txt'}:6: ")
    (folder / "depth.txt").write_text(text)
    (folder / "rgb.txt").write_text((folder / "rgb.txt").read_text() + line + "\n")
    with pytest.raises(TumFormatError, match=message) as e:
        TumSequence(folder)
    assert e.value.path == str(folder / "rgb.txt")


def test_missing_listed_images(tmp_path):
    folder = make_folder(tmp_path, n=3)
    victim = sorted((folder / "depth").iterdir())[1]
    victim.unlink()
    with pytest.raises(FileNotFoundError, match=rf"depth\.txt:5: listed depth image .*{victim.name}"):
        TumSequence(folder)
    assert len(TumSequence(folder, limit=1)) == 1  # only selected frames are required
    folder = make_folder(tmp_path, n=3, name="r")
    sorted((folder / "rgb").iterdir())[2].unlink()
    with pytest.raises(FileNotFoundError, match=r"rgb\.txt:6: listed colour image"):
        TumSequence(folder)


def _replace_depth(folder: Path, k: int, data: bytes) -> Path:
    path = sorted((folder / "depth").iterdir())[k]
    path.write_bytes(data)
    return path


def test_depth_png_that_is_not_16_bit_greyscale(tmp_path):
    h, w = SMALL.shape
    cases = [
        (png_encode(np.zeros((h, w), np.uint8), 8, 0), "8-bit greyscale"),
        (png_encode(np.zeros((h, w, 3), np.uint8), 8, 2), "8-bit RGB"),
        (png_encode(np.zeros((h, w, 3), np.uint16), 16, 2), "16-bit RGB"),
        (png_encode(np.zeros((h, w, 2), np.uint16), 16, 4), "16-bit greyscale\\+alpha"),
        (b"this is not an image\n", "not a PNG"),
        (b"\x89PNG\r\n\x1a\n\x00\x00", "truncated"),
    ]
    for k, (data, message) in enumerate(cases):
        folder = make_folder(tmp_path, n=2, name=f"c{k}")
        path = _replace_depth(folder, 0, data)  # first frame: found on construction
        with pytest.raises(TumFormatError, match=message) as e:
            TumSequence(folder)
        assert e.value.path == str(path)
        path = _replace_depth(make_folder(tmp_path, n=2, name=f"d{k}"), 1, data)  # found on load
        s = TumSequence(path.parent.parent)
        s[0]
        with pytest.raises(TumFormatError, match=message):
            s[1]


def test_corrupt_png_data(tmp_path):
    folder = make_folder(tmp_path, n=2)
    good = sorted((folder / "depth").iterdir())[1].read_bytes()
    idat = good.index(b"IDAT")
    corrupt = good[:idat + 4] + bytes(b ^ 0x5A for b in good[idat + 4:idat + 40]) + good[idat + 40:]
    path = _replace_depth(folder, 1, corrupt)
    s = TumSequence(folder)
    with pytest.raises(TumFormatError, match="unreadable PNG") as e:
        s[1]
    assert e.value.path == str(path)
    _replace_depth(folder, 1, good[: len(good) // 2])  # truncated
    with pytest.raises(TumFormatError, match="unreadable PNG"):
        TumSequence(folder)[1]


def test_image_sizes_must_match(tmp_path):
    folder = make_folder(tmp_path, n=2)
    with pytest.raises(TumFormatError, match="depth image is 16x12 pixels but the intrinsics are 640x480"):
        TumSequence(folder, intrinsics="tum_fr1")
    _replace_depth(folder, 1, png_encode(np.zeros((6, 8), np.uint16), 16, 0))
    s = TumSequence(folder)
    with pytest.raises(TumFormatError, match="depth image is 8x6"):
        s[1]
    folder = make_folder(tmp_path, n=2, name="rgbsize")
    rgb = sorted((folder / "rgb").iterdir())[0]
    rgb.write_bytes(png_encode(np.zeros((12, 15, 3), np.uint8), 8, 2))
    with pytest.raises(TumFormatError, match="colour image is 15x12") as e:
        TumSequence(folder)
    assert e.value.path == str(rgb)
    rgb.write_bytes(png_encode(np.zeros((12, 16, 3), np.uint16), 16, 2))
    with pytest.raises(TumFormatError, match="8 bits per channel"):
        TumSequence(folder)


def test_greyscale_colour_image_is_expanded(tmp_path):
    folder = make_folder(tmp_path, n=1)
    rgb = sorted((folder / "rgb").iterdir())[0]
    grey = np.arange(12 * 16, dtype=np.uint8).reshape(12, 16)
    rgb.write_bytes(png_encode(grey, 8, 0))
    f = TumSequence(folder)[0]
    assert f.rgb.shape == (12, 16, 3)
    for c in range(3):
        np.testing.assert_array_equal(f.rgb[..., c], grey)


def test_malformed_ground_truth(tmp_path):
    folder = make_folder(tmp_path, n=2)
    (folder / "groundtruth.txt").write_text("# ground truth\n1305031102.1 1 2 3 0 0 0\n")
    with pytest.raises(TumFormatError, match=r"groundtruth\.txt:2: expected 8 values"):
        TumSequence(folder)
    (folder / "groundtruth.txt").write_text("# ground truth trajectory\n")  # empty: no poses
    s = TumSequence(folder)
    assert s.reference_trajectory() is None and s[0].T_base_camera is None


def test_write_rejects_bad_frames(tmp_path):
    d = np.ones(SMALL.shape, np.uint16)
    rgb = np.zeros(SMALL.shape + (3,), np.uint8)
    f = lambda t, **kw: Frame(**{"depth": d, "intrinsics": SMALL, "timestamp": t, **kw})  # noqa: E731
    with pytest.raises(ValueError, match="no frames"):
        write_tum_sequence(tmp_path / "a", [])
    with pytest.raises(ValueError, match="no colour image"):
        write_tum_sequence(tmp_path / "b", [f(1.0, rgb=rgb), f(2.0)])
    with pytest.raises(ValueError, match="intrinsics"):
        write_tum_sequence(tmp_path / "c", [f(1.0), f(2.0, intrinsics=SMALL.scaled(0.5), depth=d[::2, ::2])])
    with pytest.raises(ValueError, match="same timestamp at microsecond"):
        write_tum_sequence(tmp_path / "d", [f(1.0), f(1.0000001)])
    with pytest.raises(ValueError, match="does not match the intrinsics"):
        write_tum_sequence(tmp_path / "e", [f(1.0)], intrinsics=INTRINSICS_PRESETS["tum_fr1"])
    with pytest.raises(ValueError, match="rgb must be"):
        write_tum_sequence(tmp_path / "f", [f(1.0, rgb=rgb.astype(np.float32))])
    with pytest.raises(ValueError, match="exceeds the largest value"):
        write_tum_sequence(tmp_path / "g", [f(1.0, depth=np.full(SMALL.shape, 14.0))])
    with pytest.raises(ValueError, match="depth_scale"):
        write_tum_sequence(tmp_path / "h", [f(1.0)], depth_scale=0)
    with pytest.raises(ValueError, match="non-finite timestamp"):
        write_tum_sequence(tmp_path / "i", [f(float("nan"))])
    with pytest.raises(ValueError, match="T_base_camera"):
        write_tum_sequence(tmp_path / "j", [f(1.0, T_base_camera=np.eye(3))])
    with pytest.raises(TypeError, match="Frame"):
        write_tum_sequence(tmp_path / "k", [d])
    write_tum_sequence(tmp_path / "ok", [f(1.0)])
    with pytest.raises(FileExistsError, match="already holds a sequence"):
        write_tum_sequence(tmp_path / "ok", [f(2.0)])


def test_sequence_can_be_rewritten(tmp_path):
    """A TumSequence is itself an iterable of frames: copy a sequence, subsampled."""
    folder = make_folder(tmp_path, n=6, depth_scale=0.001)
    traj = ConstantVelocity(T0)
    rows = [f"{t:.4f} " + " ".join(repr(float(v)) for v in traj.tum_row(t))
            for t in np.arange(T0 - 0.05, T0 + 0.3, 0.01)]
    (folder / "groundtruth.txt").write_text("\n".join(rows) + "\n")
    src = TumSequence(folder, stride=2)
    out = TumSequence(write_tum_sequence(tmp_path / "copy", src))  # default depth_scale 1/5000
    assert len(out) == 3 and out.depth_scale == 1 / 5000
    for a, b in zip(src, out):
        np.testing.assert_array_equal(b.depth, a.depth.astype(np.int64) * 5)  # mm -> 1/5000 m
        np.testing.assert_array_equal(b.rgb, a.rgb)
        assert abs(a.timestamp - b.timestamp) <= 1e-6
        np.testing.assert_allclose(b.T_base_camera, a.T_base_camera, rtol=0, atol=1e-9)


def test_depth_decoded_as_32_bit_mode_by_older_pillow(tmp_path, monkeypatch):
    """Pillow before 10.x decodes 16-bit greyscale PNGs in mode "I" (int32): same values."""
    from PIL import Image

    folder = make_folder(tmp_path, n=1)
    expected = png_decode(sorted((folder / "depth").iterdir())[0])[2]
    real_open = Image.open

    def open_as_int32(path, *args, **kwargs):
        # What Pillow 9 hands out for such a file: mode "I", while its format and raw mode
        # (the stored layout) still say 16-bit greyscale PNG.
        with real_open(path, *args, **kwargs) as im:
            if not im.mode.startswith("I;16"):
                return im.copy()
            tile, out = im.tile, im.convert("I")
        out.format, out.tile = "PNG", tile
        return out

    monkeypatch.setattr(Image, "open", open_as_int32)
    frame = TumSequence(folder)[0]
    assert frame.depth.dtype == np.uint16
    np.testing.assert_array_equal(frame.depth, expected)


def _png_header_only(w: int, h: int) -> bytes:
    """A 16-bit greyscale PNG whose header claims w x h pixels, with a few bytes of pixel data."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(100))) + chunk(b"IEND", b"")


def test_huge_image_headers_are_refused_before_decoding(tmp_path):
    """A header claiming 144 M pixels used to be decoded (about 300 MB) before its size was
    compared with the intrinsics, so the error was 'unreadable PNG'; one claiming 900 M pixels
    raised Pillow's DecompressionBombError, which is not a ValueError."""
    folder = make_folder(tmp_path, n=2)
    path = _replace_depth(folder, 1, _png_header_only(12000, 12000))
    s = TumSequence(folder)
    with pytest.raises(TumFormatError, match="depth image is 12000x12000 pixels but the intrinsics are 16x12") as e:
        s[1]
    assert e.value.path == str(path)
    _replace_depth(folder, 1, _png_header_only(30000, 30000))
    with pytest.raises(TumFormatError, match="DecompressionBombError"):
        s[1]
    _replace_depth(folder, 0, _png_header_only(30000, 30000))
    with pytest.raises(TumFormatError, match="DecompressionBombError"):
        TumSequence(folder)
