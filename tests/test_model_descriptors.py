"""CBD descriptors cached in model views (C++ describeModelViews, ModelView.cbd): estimate_pose
uses them when its settings match and recomputes otherwise, with the same result either way."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import pose
from scanalign.pose import model_views as cad
from scanalign.data import parts
from scanalign._core import pose as P


@pytest.fixture(scope="module")
def scene():
    views = cad.render_views(parts.builtin_mesh(name="bracket"))
    rng = np.random.default_rng(0)
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R *= np.linalg.det(R)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [0.1, 0.2, 0.3]
    cloud = views[5].points @ R.T + T[:3, 3] + rng.normal(scale=2e-4, size=views[5].points.shape)
    return views, cloud, T


def settings(**cbd):
    return pose.pose_task_settings(pose.PoseSettings, method="cbd", num_threads=1, **cbd)


def test_described_views_give_the_same_pose(scene):
    views, cloud, T = scene
    s = settings()
    described = P.describe_model_views(views, s)
    assert all(v.cbd is None for v in views) and all(v.cbd is not None and len(v.cbd) > 0 for v in described)
    ids = [5, 6, 20]
    fresh, cached = P.estimate_pose(views, cloud, s, ids), P.estimate_pose(described, cloud, s, ids)
    assert fresh.found and fresh.view == 5
    np.testing.assert_allclose(np.asarray(fresh.T_scene_model), T, atol=2e-3)
    np.testing.assert_array_equal(np.asarray(cached.T_scene_model), np.asarray(fresh.T_scene_model))
    assert (cached.fitness, cached.coverage, cached.view) == (fresh.fitness, fresh.coverage, fresh.view)


def test_matching_cached_features_are_used_and_others_recomputed(scene):
    views, cloud, _ = scene
    s = settings()
    described = P.describe_model_views(views, s)
    wrong = described[5]
    wrong.cbd = described[30].cbd  # another view's keypoints: a pose from them cannot be view 5's
    alone = [wrong]
    used = P.estimate_pose(alone, cloud, s)
    fresh = P.estimate_pose([views[5]], cloud, s)
    assert fresh.found and not np.array_equal(np.asarray(used.T_scene_model), np.asarray(fresh.T_scene_model))
    kept = P.describe_model_views(alone, s)[0]  # already described with these settings: left alone
    np.testing.assert_array_equal(kept.cbd.keypoints, described[30].cbd.keypoints)
    other = settings(radius=0.008)  # other settings: the cache does not apply, the pose is the fresh one
    a, b = P.estimate_pose(alone, cloud, other), P.estimate_pose([views[5]], cloud, other)
    np.testing.assert_array_equal(np.asarray(a.T_scene_model), np.asarray(b.T_scene_model))
    redone = P.describe_model_views(alone, other)[0]
    assert redone.cbd_settings.radius == 0.008
    assert not np.array_equal(redone.cbd.keypoints, described[30].cbd.keypoints)


def test_describe_refuses_bad_settings(scene):
    s = settings()
    s.inlier_threshold = -1.0
    with pytest.raises(ValueError, match="inlier_threshold"):
        P.describe_model_views(scene[0][:1], s)
