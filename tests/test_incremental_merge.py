"""The reconstruction's incremental merge against its definition on real-like frames: after
every merge the model equals the voxel grid of (previous model + new frame), each model
point counting as one point, normals averaged and re-normalised, colours averaged and
rounded half away from zero, as the merge did by re-gridding the whole model."""

from __future__ import annotations

import numpy as np

from scanalign import _core, synthetic
from scanalign.reconstruction import Reconstructor, frame_to_cloud


def regrid(points, normals, colors, leaf):
    """Today's merge written out in NumPy around the (PCL-identical) voxel grid."""
    attrs = np.hstack([normals.astype(np.float64), colors.astype(np.float64)])
    centroids, a, _ = _core.reconstruction.voxel_grid(np.ascontiguousarray(points, np.float32), leaf, attrs, 1)
    n = a[:, :3]
    length = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = np.where(length > 1e-6, 1.0 / length, np.nan)
    normals = (n * inv[:, None]).astype(np.float32)
    colors = np.clip(np.floor(a[:, 3:] + 0.5), 0, 255).astype(np.uint8)  # lround of values >= 0
    return centroids.astype(np.float32), normals, colors


def sorted_rows(points, *others):
    order = np.lexsort(points.T[::-1])
    return (points[order],) + tuple(o[order] for o in others)


def test_merge_equals_regridding_the_model_on_a_synthetic_scan():
    scan = synthetic.builtin_scan(n_frames=12)
    # Frames are placed at their reference poses; the clouds are moved into the base frame
    # here (float32) so the merge's own transform is the identity and exact.
    rec = Reconstructor(crop_box=None, normal_radius=0.01, frame_voxel_size=0.001)
    core = rec._core
    core.reset(np.eye(4))
    leaf = rec.settings.model_voxel_size
    grown = []
    for f in scan.frames[:5]:
        p, c = frame_to_cloud(f)
        T = f.T_base_camera
        p_base = (p.astype(np.float64) @ T[:3, :3].T + T[:3, 3]).astype(np.float32)
        near = (np.abs(p[:, 0]) < 0.1) & (np.abs(p[:, 1]) < 0.1)  # the demo's crop: the part and the table
        prepared = core.prepare(np.ascontiguousarray(p_base[near]), np.ascontiguousarray(c[near]))
        if core.model_size:
            before = (core.model_points(), core.model_normals(), core.model_colors())
        else:
            before = (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8))
        want = regrid(np.vstack([before[0], prepared.points]), np.vstack([before[1], prepared.normals]),
                      np.vstack([before[2], prepared.colors]), leaf)
        size = core.merge(prepared, np.eye(4))
        got = (core.model_points(), core.model_normals(), core.model_colors())
        assert size == len(want[0]) == len(got[0])
        grown.append(size)
        g, w = sorted_rows(*got), sorted_rows(*want)
        np.testing.assert_array_equal(g[0], w[0])  # centroids: bit for bit
        np.testing.assert_array_equal(g[2], w[2])  # colours
        np.testing.assert_array_equal(np.isnan(g[1]), np.isnan(w[1]))
        # Normals: bit for bit where the frame went; voxels it missed keep their unit normal,
        # which the re-grid re-normalises once more (a change of float rounding only).
        np.testing.assert_allclose(g[1], w[1], rtol=0, atol=3e-7)
    assert grown[-1] > grown[0]  # new voxels appear as the camera moves
