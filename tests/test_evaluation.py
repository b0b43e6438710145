"""scanalign.evaluation, scanalign.evaluation.trajectory and scanalign.viz.plots against independent truth:
evo (the reference implementation of the TUM metrics), scipy's rotations, Open3D's mesh
distance, brute-force oracles and analytic cases."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers import rigid
from scanalign.evaluation import (
    MeshDistanceIndex,
    absolute_trajectory_error,
    associate,
    evaluate_reconstruction,
    mesh_distance_stats,
    point_to_mesh_distance,
    relative_pose_error,
    umeyama_alignment,
)
from scanalign.evaluation.trajectory import Trajectory, associate_timestamps, matrix_from_quaternion, quaternion_from_matrix


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------

def random_rotation(rng: np.random.Generator, scale: float = np.pi) -> np.ndarray:
    axis = rng.normal(size=3)
    return rigid(axis, rng.uniform(-scale, scale), np.zeros(3))[:3, :3]


def random_trajectory(rng: np.random.Generator, n: int, step: float = 0.02, dt: float = 0.1) -> Trajectory:
    """A smooth-ish random walk of camera poses (m, s)."""
    T = np.tile(np.eye(4), (n, 1, 1))
    R = np.eye(3)
    p = np.zeros(3)
    for i in range(n):
        R = R @ random_rotation(rng, 0.1)
        p = p + rng.normal(0.0, step, 3)
        T[i, :3, :3] = R
        T[i, :3, 3] = p
    return Trajectory(np.arange(n) * dt, T)


def perturbed(rng: np.random.Generator, traj: Trajectory, sigma_t: float, sigma_r: float,
              world: np.ndarray | None = None) -> Trajectory:
    n = len(traj)
    N = np.tile(np.eye(4), (n, 1, 1))
    for i in range(n):
        N[i, :3, :3] = random_rotation(rng, sigma_r)
    N[:, :3, 3] = rng.normal(0.0, sigma_t, (n, 3))
    W = np.eye(4) if world is None else world
    return Trajectory(traj.timestamps.copy(), W @ traj.poses @ N)


def translations(points: np.ndarray) -> Trajectory:
    T = np.tile(np.eye(4), (len(points), 1, 1))
    T[:, :3, 3] = points
    return Trajectory(np.arange(len(points), dtype=float), T)


def stamps(t) -> Trajectory:
    t = np.asarray(t, dtype=float)
    return Trajectory(t, np.tile(np.eye(4), (t.size, 1, 1)))


STATS = ("rmse", "mean", "median", "std", "min", "max", "sse")


# --------------------------------------------------------------------------------------
# ATE / RPE: exact and analytic cases
# --------------------------------------------------------------------------------------

def test_identity_gives_zero_errors():
    rng = np.random.default_rng(0)
    ref = random_trajectory(rng, 50)
    ate = absolute_trajectory_error(ref, ref)
    assert ate.rmse < 1e-12 and ate.translation.max < 1e-12 and ate.rotation.max < 1e-6
    np.testing.assert_allclose(ate.T_reference_estimate, np.eye(4), atol=1e-12)
    for all_pairs in (False, True):
        rpe = relative_pose_error(ref, ref, all_pairs=all_pairs)
        assert rpe.translation.max < 1e-12 and rpe.rotation.max < 1e-6


def test_rigid_offset_is_removed_by_alignment_only():
    rng = np.random.default_rng(1)
    ref = random_trajectory(rng, 60)
    G = rigid([1, 2, 3], 0.7, [0.5, -0.2, 1.0])
    est = ref.transformed(np.linalg.inv(G))  # estimate lives in another world frame
    ate = absolute_trajectory_error(est, ref)
    assert ate.rmse < 1e-12 and ate.rotation.max < 1e-6
    np.testing.assert_allclose(ate.T_reference_estimate, G, atol=1e-12)
    np.testing.assert_allclose(ate.aligned.poses, ref.poses, atol=1e-12)
    raw = absolute_trajectory_error(est, ref, align=False)
    np.testing.assert_allclose(raw.translation.errors, np.linalg.norm(est.positions - ref.positions, axis=1))
    assert raw.rmse > 0.1
    # pure translation offset, no alignment: every error is |c|
    c = np.array([0.03, -0.04, 0.0])
    shifted = ref.transformed(rigid([0, 0, 1], 0.0, c))
    raw = absolute_trajectory_error(shifted, ref, align=False)
    np.testing.assert_allclose(raw.translation.errors, 0.05, atol=1e-14)
    assert raw.rotation.max < 1e-6
    # RPE does not see a change of world frame
    assert relative_pose_error(est, ref, all_pairs=True).translation.max < 1e-12


def test_known_per_pose_perturbation_analytic():
    # reference: 8 centres on a circle (z = 0); estimate: +-eps along z, alternating.  The
    # cross-covariance stays symmetric, so the optimal alignment is the identity and every
    # ATE error is eps; consecutive RPE errors are 2 eps, RPE with delta 2 is zero.
    n, eps = 8, 0.01
    ang = 2 * np.pi * np.arange(n) / n
    q = np.stack([0.3 * np.cos(ang), 0.3 * np.sin(ang), np.zeros(n)], axis=1)
    s = (-1.0) ** np.arange(n)
    ref = translations(q)
    est = translations(q + eps * s[:, None] * np.array([0, 0, 1.0]))
    ate = absolute_trajectory_error(est, ref)
    np.testing.assert_allclose(ate.translation.errors, eps, rtol=1e-10)
    assert ate.rmse == pytest.approx(eps, rel=1e-10)
    assert ate.translation.std == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(ate.T_reference_estimate, np.eye(4), atol=1e-12)
    rpe = relative_pose_error(est, ref, all_pairs=True)
    np.testing.assert_allclose(rpe.translation.errors, 2 * eps, rtol=1e-10)
    assert rpe.rotation.max < 1e-6
    assert relative_pose_error(est, ref, delta=2, all_pairs=True).translation.max < 1e-12


def test_rotation_perturbation_analytic():
    # Identity orientations, camera i rotated by alpha_i about its own z axis: positions are
    # unchanged (ATE 0 m), ATE rotation |alpha_i|; RPE for the pair (i, j) with centre step d:
    # rotation |alpha_j - alpha_i|, translation |Rz(-alpha_i) d - d| = 2 |d_xy| sin(|alpha_i| / 2).
    rng = np.random.default_rng(2)
    n = 20
    q = np.cumsum(rng.normal(0, 0.05, (n, 3)), axis=0)
    alpha = rng.uniform(-0.3, 0.3, n)
    ref = translations(q)
    P = ref.poses.copy()
    for i in range(n):
        P[i] = P[i] @ rigid([0, 0, 1], alpha[i], np.zeros(3))
    est = Trajectory(ref.timestamps, P)
    ate = absolute_trajectory_error(est, ref)
    assert ate.translation.max < 1e-12
    np.testing.assert_allclose(ate.rotation.errors, np.degrees(np.abs(alpha)), rtol=1e-9)
    rpe = relative_pose_error(est, ref, all_pairs=True)
    d = np.diff(q, axis=0)
    np.testing.assert_allclose(rpe.rotation.errors, np.degrees(np.abs(np.diff(alpha))), rtol=1e-9, atol=1e-9)
    expect = 2 * np.linalg.norm(d[:, :2], axis=1) * np.abs(np.sin(alpha[:-1] / 2))
    np.testing.assert_allclose(rpe.translation.errors, expect, rtol=1e-9, atol=1e-15)


def test_scale_alignment_recovers_a_scaled_estimate():
    rng = np.random.default_rng(3)
    ref = random_trajectory(rng, 40)
    P = ref.poses.copy()
    P[:, :3, 3] *= 0.25  # monocular-style scale
    est = Trajectory(ref.timestamps, P)
    assert absolute_trajectory_error(est, ref).rmse > 1e-3
    ate = absolute_trajectory_error(est, ref, with_scale=True)
    assert ate.rmse < 1e-12 and ate.scale == pytest.approx(4.0, rel=1e-12)


def test_stats_definitions():
    rng = np.random.default_rng(4)
    ref = random_trajectory(rng, 30)
    est = perturbed(rng, ref, 0.01, 0.01)
    e = absolute_trajectory_error(est, ref).translation
    x = e.errors
    assert e.count == 30
    assert e.rmse == pytest.approx(np.sqrt(np.mean(x ** 2)), rel=1e-14)
    assert e.sse == pytest.approx(np.sum(x ** 2), rel=1e-14)
    assert e.std == pytest.approx(np.std(x, ddof=0), rel=1e-12)
    assert e.median == pytest.approx(np.median(x)) and e.min == x.min() and e.max == x.max()
    json.dumps(e.as_dict(include_errors=True))


# --------------------------------------------------------------------------------------
# agreement with evo
# --------------------------------------------------------------------------------------

def _evo(traj: Trajectory):
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=[T.copy() for T in traj.poses], timestamps=traj.timestamps.copy())


def _evo_stats(metric) -> dict:
    from evo.core.metrics import StatisticsType

    return {k: metric.get_statistic(getattr(StatisticsType, k)) for k in STATS}


def _assert_same(ours, evo_errors, evo_stats, tol=1e-9):
    assert ours.count == len(evo_errors)
    np.testing.assert_allclose(ours.errors, evo_errors, rtol=0, atol=tol)
    for k in STATS:
        assert abs(getattr(ours, k) - evo_stats[k]) <= tol * max(1.0, abs(evo_stats[k])), k


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("with_scale", [False, True])
def test_ate_matches_evo(seed, with_scale):
    pytest.importorskip("evo")
    from evo.core import metrics

    rng = np.random.default_rng(100 + seed)
    ref = random_trajectory(rng, int(rng.integers(20, 300)))
    world = rigid(rng.normal(size=3), rng.uniform(-3, 3), rng.normal(size=3))
    est = perturbed(rng, ref, 0.01, 0.02, world)
    if with_scale:
        est.poses[:, :3, 3] *= 1.7
    ours = absolute_trajectory_error(est, ref, with_scale=with_scale)
    e_ref, e_est = _evo(ref), _evo(est)
    R, t, s = e_est.align(e_ref, correct_scale=with_scale)
    for relation, mine in ((metrics.PoseRelation.translation_part, ours.translation),
                           (metrics.PoseRelation.rotation_angle_deg, ours.rotation)):
        m = metrics.APE(relation)
        m.process_data((e_ref, e_est))
        _assert_same(mine, m.error, _evo_stats(m))
    np.testing.assert_allclose(ours.T_reference_estimate[:3, :3], s * R, atol=1e-9)
    np.testing.assert_allclose(ours.T_reference_estimate[:3, 3], t, atol=1e-9)
    np.testing.assert_allclose(ours.aligned.poses, np.array(e_est.poses_se3), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("delta,unit", [(1, "frames"), (3, "frames"), (10, "frames"), (0.1, "meters"),
                                        (0.4, "meters")])
@pytest.mark.parametrize("all_pairs", [False, True])
def test_rpe_matches_evo(seed, delta, unit, all_pairs):
    pytest.importorskip("evo")
    from evo.core import metrics
    from evo.core.units import Unit

    rng = np.random.default_rng(200 + seed)
    ref = random_trajectory(rng, int(rng.integers(40, 250)))
    est = perturbed(rng, ref, 0.005, 0.01, rigid(rng.normal(size=3), 1.0, rng.normal(size=3)))
    for from_ref in (False, True):
        ours = relative_pose_error(est, ref, delta=delta, delta_unit=unit, all_pairs=all_pairs,
                                   pairs_from_reference=from_ref)
        for relation, mine in ((metrics.PoseRelation.translation_part, ours.translation),
                               (metrics.PoseRelation.rotation_angle_deg, ours.rotation)):
            m = metrics.RPE(relation, delta=delta, delta_unit=getattr(Unit, unit), all_pairs=all_pairs,
                            pairs_from_reference=from_ref)
            m.process_data((_evo(ref), _evo(est)))
            _assert_same(mine, m.error, _evo_stats(m))
            assert [int(j) for j in ours.pairs[:, 1]] == list(m.delta_ids)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_association_nearest_matches_evo(seed):
    pytest.importorskip("evo")
    from evo.core import sync

    rng = np.random.default_rng(300 + seed)
    ref = random_trajectory(rng, 200, dt=0.01)  # 100 Hz reference
    ref.timestamps += rng.normal(0, 0.001, 200)
    ref.timestamps.sort()
    for n_est in (40, 200, 200 + 10 * seed + 5):  # estimate shorter, as long, longer
        idx = np.sort(rng.choice(200, min(n_est, 200), replace=False))
        est = perturbed(rng, ref[idx], 0.01, 0.01)
        if n_est > 200:  # extra poses interleaved
            extra = perturbed(rng, ref[: n_est - 200], 0.01, 0.01)
            extra.timestamps = extra.timestamps + 0.004
            order = np.argsort(np.concatenate([est.timestamps, extra.timestamps]), kind="stable")
            est = Trajectory(np.concatenate([est.timestamps, extra.timestamps])[order],
                             np.concatenate([est.poses, extra.poses])[order])
        est.timestamps = est.timestamps - 0.05 + rng.normal(0, 0.003, len(est))  # clock offset + jitter
        est.timestamps.sort()
        for offset in (0.0, 0.05):
            e_ref, e_est = sync.associate_trajectories(_evo(ref), _evo(est), max_diff=0.004, offset_2=offset)
            a_est, a_ref = associate(est, ref, max_difference=0.004, offset=offset, method="nearest")
            assert len(a_est) == e_est.num_poses > 0
            np.testing.assert_array_equal(a_est.timestamps, e_est.timestamps)
            np.testing.assert_array_equal(a_ref.timestamps, e_ref.timestamps)
            np.testing.assert_array_equal(a_est.poses, np.array(e_est.poses_se3))
            np.testing.assert_array_equal(a_ref.poses, np.array(e_ref.poses_se3))


# --------------------------------------------------------------------------------------
# trajectories: quaternions and interpolation against scipy, the TUM file round trip
# --------------------------------------------------------------------------------------

def test_quaternions_match_scipy_over_the_whole_rotation_group():
    Rotation = pytest.importorskip("scipy.spatial.transform").Rotation
    rng = np.random.default_rng(20)
    rot = Rotation.random(500, random_state=21)
    R = rot.as_matrix()
    R[:4] = [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]  # angle 0 and pi
    expect = Rotation.from_matrix(R).as_quat()  # (x, y, z, w)
    expect[expect[:, 3] < 0] *= -1
    q = quaternion_from_matrix(R.reshape(50, 10, 3, 3)).reshape(-1, 4)
    assert np.all(q[:, 3] >= 0)
    np.testing.assert_allclose(np.abs(np.sum(q * expect, axis=1)), 1.0, atol=1e-12)  # same up to sign at qw = 0
    np.testing.assert_allclose(matrix_from_quaternion(q), R, atol=1e-12)
    scaled = rng.uniform(0.1, 10, (500, 1)) * rot.as_quat()
    np.testing.assert_allclose(matrix_from_quaternion(scaled), rot.as_matrix(), atol=1e-12)
    with pytest.raises(ValueError, match="non-zero"):
        matrix_from_quaternion([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        matrix_from_quaternion([np.nan, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="3, 3"):
        quaternion_from_matrix(np.eye(4))


def test_interpolation_matches_scipy_slerp_and_linear_positions(tmp_path):
    transform = pytest.importorskip("scipy.spatial.transform")
    rng = np.random.default_rng(22)
    traj = random_trajectory(rng, 40, step=0.05)
    traj.poses[5, :3, :3] = traj.poses[4, :3, :3] @ rigid([0, 0, 1], 3.0, np.zeros(3))[:3, :3]  # near pi apart
    t = np.sort(rng.uniform(traj.timestamps[0], traj.timestamps[-1], 300))
    t[:3] = traj.timestamps[[0, 7, -1]]  # exact hits return the stored pose
    out = traj.interpolate(t)
    slerp = transform.Slerp(traj.timestamps, transform.Rotation.from_matrix(traj.rotations))
    np.testing.assert_allclose(out.rotations, slerp(t).as_matrix(), atol=1e-12)
    for k in range(3):
        np.testing.assert_allclose(out.positions[:, k], np.interp(t, traj.timestamps, traj.positions[:, k]),
                                   atol=1e-14)
    np.testing.assert_allclose(out.poses[:3], traj.poses[[0, 7, -1]], atol=1e-14)
    with pytest.raises(ValueError, match="span"):
        traj.interpolate([traj.timestamps[-1] + 1.0])
    with pytest.raises(ValueError, match="gap"):
        traj.interpolate([0.05], max_gap=0.01)
    # TUM text round trip keeps full precision
    traj.write_tum(tmp_path / "t.txt", header="test")
    back = Trajectory.read_tum(tmp_path / "t.txt")
    np.testing.assert_allclose(back.poses, traj.poses, atol=1e-14)
    np.testing.assert_allclose(back.timestamps, traj.timestamps, atol=1e-6)


# --------------------------------------------------------------------------------------
# association: the one greedy rule, against a brute-force oracle
# --------------------------------------------------------------------------------------

def _greedy_oracle(t_first, t_second, max_difference, offset=0.0):
    """The documented rule written out over every pair of sorted streams: candidates with
    |dt| <= max_difference (inclusive), closest first, ties by first then second index,
    each index used once; pairs returned by first index."""
    cands = sorted((abs(a - (b + offset)), i, j) for i, a in enumerate(t_first) for j, b in enumerate(t_second)
                   if abs(a - (b + offset)) <= max_difference)
    used_i, used_j, pairs = set(), set(), []
    for _, i, j in cands:
        if i not in used_i and j not in used_j:
            used_i.add(i)
            used_j.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def test_associate_timestamps_matches_oracle_and_keeps_the_bound():
    rng = np.random.default_rng(3)
    for trial in range(300):
        a = np.sort(np.round(rng.uniform(0, 1, rng.integers(0, 30)), 2))  # coarse: ties and repeats
        b = np.sort(np.round(rng.uniform(0, 1, rng.integers(0, 30)), 2))
        md = float(rng.choice([0.0, 0.01, 0.02, 0.05, 0.5]))
        got = associate_timestamps(a, b, md)
        assert got.dtype == np.int64 and got.shape == (len(got), 2)
        assert [tuple(p) for p in got.tolist()] == _greedy_oracle(a, b, md), trial
    # |dt| == max_difference exactly (binary fractions): inclusive, like evo's matcher
    assert associate_timestamps([0.0, 1.0], [0.5, 1.25], 0.25).tolist() == [[1, 1]]
    assert associate_timestamps([0.0, 1.0], [0.5, 1.25], 0.5).tolist() == [[0, 0], [1, 1]]
    assert associate_timestamps([1.0], [1.0], 0.0).tolist() == [[0, 0]]
    # closest first: 1.0 takes 1.01 (0.01) although 1.02 is also within reach of 1.01
    assert associate_timestamps([1.0, 1.02], [1.01, 1.015], 0.02).tolist() == [[0, 0], [1, 1]]
    assert associate_timestamps([], [1.0], 0.1).shape == (0, 2)
    with pytest.raises(ValueError, match="sorted"):
        associate_timestamps([2.0, 1.0], [1.0], 0.1)
    with pytest.raises(ValueError, match="non-finite"):
        associate_timestamps([1.0, np.nan], [1.0], 0.1)
    for bad in (-1.0, np.inf, np.nan):
        with pytest.raises(ValueError, match="max_difference"):
            associate_timestamps([1.0], [1.0], bad)


@pytest.mark.parametrize("seed", range(8))
def test_association_greedy_matches_oracle(seed):
    rng = np.random.default_rng(400 + seed)
    for trial in range(40):
        n_e, n_r = rng.integers(1, 50, 2)
        t_e = np.sort(rng.uniform(0, 2, n_e))
        t_r = np.sort(rng.uniform(0, 2, n_r))
        if trial % 3 == 0:  # many exact ties
            t_e, t_r = np.round(t_e, 1), np.round(t_r, 1)
        if trial % 4 == 1:  # clock drift: long chains of near-equal candidates
            t_r = np.arange(n_r) * 0.05 * 1.003
            t_e = np.arange(n_e) * 0.05 + 0.026
        offset = float(rng.uniform(-0.1, 0.1))
        md = float(rng.uniform(0.005, 0.3))
        if trial % 5 == 2:  # a pair exactly at the bound is kept
            t_e, t_r, offset, md = np.array([0.0, 0.5]), np.array([0.25, 1.0]), 0.0, 0.25
        pairs = _greedy_oracle(t_r, t_e, md, offset)
        if not pairs:
            with pytest.raises(ValueError, match="no timestamps match"):
                associate(stamps(t_e), stamps(t_r), md, offset)
            continue
        ir, ie = (list(x) for x in zip(*pairs))
        est, ref, a, b = associate(stamps(t_e), stamps(t_r), md, offset, return_indices=True)
        assert a.tolist() == ie and b.tolist() == ir
        np.testing.assert_array_equal(est.timestamps, t_e[ie])
        np.testing.assert_array_equal(ref.timestamps, t_r[ir])


def test_association_of_unsorted_trajectories_maps_back_to_rows():
    rng = np.random.default_rng(9)
    t_r = np.sort(rng.uniform(0, 5, 60))
    t_e = np.sort(t_r[rng.choice(60, 40, replace=False)] + rng.normal(0, 0.004, 40))
    pe, pr = rng.permutation(40), rng.permutation(60)
    _, _, a, b = associate(stamps(t_e[pe]), stamps(t_r[pr]), 0.01, return_indices=True)
    _, _, a0, b0 = associate(stamps(t_e), stamps(t_r), 0.01, return_indices=True)
    assert len(a0) > 30 and sorted(zip(pe[a], pr[b])) == sorted(zip(a0, b0))


def test_association_long_drift_chain():
    # every estimate stamp has two candidates whose quality decays monotonically along the
    # sequence: a long chain in which each choice depends on the previous one
    t_r = np.arange(600) * 0.1 * (1 + 2e-4)
    t_e = np.arange(600) * 0.1 + 0.05
    ir, ie = (list(x) for x in zip(*_greedy_oracle(t_r, t_e, 0.08)))
    _, _, a, b = associate(stamps(t_e), stamps(t_r), 0.08, return_indices=True)
    assert a.tolist() == ie and b.tolist() == ir


def test_ate_with_association_and_offset():
    rng = np.random.default_rng(5)
    ref = random_trajectory(rng, 300, dt=0.01)
    idx = np.arange(0, 300, 7)
    est = perturbed(rng, ref[idx], 0.0, 0.0, rigid([0, 1, 0], 0.4, [1, 0, 0]))
    est.timestamps = est.timestamps + 0.5  # estimate clock runs 0.5 s late
    wrong = absolute_trajectory_error(est, ref, associate=True, max_difference=0.003)  # pairs shifted 50 poses
    assert wrong.rmse > 1e-3
    ate = absolute_trajectory_error(est, ref, associate=True, max_difference=0.003, offset=-0.5)
    assert ate.translation.count == idx.size and ate.rmse < 1e-12
    rpe = relative_pose_error(est, ref, associate=True, max_difference=0.003, offset=-0.5)
    assert rpe.translation.max < 1e-12


def test_rpe_seconds_matches_oracle():
    rng = np.random.default_rng(6)
    ref = random_trajectory(rng, 120)
    ref.timestamps = np.cumsum(rng.uniform(0.02, 0.06, 120))  # irregular stamps
    est = perturbed(rng, ref, 0.01, 0.01)
    t = ref.timestamps
    for delta in (0.1, 0.33, 1.0):
        # consecutive: from the last pair end, the first pose at least delta s later
        ids = [0]
        for k in range(1, len(t)):
            if t[k] - t[ids[-1]] >= delta:
                ids.append(k)
        r = relative_pose_error(est, ref, delta=delta, delta_unit="seconds")
        assert r.pairs.tolist() == [[a, b] for a, b in zip(ids, ids[1:])]
        # all pairs: for each i, the first j > i nearest to t_i + delta, within 10 %
        expect = []
        for i in range(len(t) - 1):
            err = np.abs((t[i + 1:] - t[i]) - delta)
            j = int(np.argmin(err))
            if err[j] <= 0.1 * delta:
                expect.append([i, i + 1 + j])
        r = relative_pose_error(est, ref, delta=delta, delta_unit="seconds", all_pairs=True)
        assert r.pairs.tolist() == expect
        # errors for those pairs from the definition, pose by pose
        i, j = r.pairs[0]
        Q, P = ref.poses, est.poses
        E = np.linalg.inv(np.linalg.inv(Q[i]) @ Q[j]) @ (np.linalg.inv(P[i]) @ P[j])
        assert r.translation.errors[0] == pytest.approx(np.linalg.norm(E[:3, 3]), abs=1e-12)
        ang = np.degrees(np.arccos(np.clip((np.trace(E[:3, :3]) - 1) / 2, -1, 1)))
        assert r.rotation.errors[0] == pytest.approx(ang, abs=1e-5)


# --------------------------------------------------------------------------------------
# Umeyama
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(5))
def test_umeyama_recovers_known_transform(seed):
    rng = np.random.default_rng(500 + seed)
    x = rng.normal(size=(int(rng.integers(3, 200)), 3))
    G = rigid(rng.normal(size=3), rng.uniform(-np.pi, np.pi), rng.normal(size=3))
    y = x @ G[:3, :3].T + G[:3, 3]
    R, t, s = umeyama_alignment(x, y)
    np.testing.assert_allclose(R, G[:3, :3], atol=1e-10)
    np.testing.assert_allclose(t, G[:3, 3], atol=1e-10)
    assert s == 1.0
    R, t, s = umeyama_alignment(x, 2.5 * y, with_scale=True)
    np.testing.assert_allclose(R, G[:3, :3], atol=1e-10)
    np.testing.assert_allclose(t, 2.5 * G[:3, 3], atol=1e-10)
    assert s == pytest.approx(2.5, rel=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", range(5))
def test_umeyama_matches_scipy_and_closed_form(seed):
    scipy_rot = pytest.importorskip("scipy.spatial.transform")
    rng = np.random.default_rng(600 + seed)
    x = rng.normal(size=(50, 3))
    y = x @ random_rotation(rng).T + rng.normal(size=3) + rng.normal(0, 0.1, (50, 3))
    R, t, s = umeyama_alignment(x, y, with_scale=True)
    xc, yc = x - x.mean(0), y - y.mean(0)
    rot, _ = scipy_rot.Rotation.align_vectors(yc, xc)  # min sum |yc - R xc|^2 (Kabsch)
    np.testing.assert_allclose(R, rot.as_matrix(), atol=1e-9)
    # closed forms: s = tr(D S) / var_x = sum(yc . R xc) / sum |xc|^2, t = my - s R mx
    assert s == pytest.approx(np.sum(yc * (xc @ R.T)) / np.sum(xc * xc), rel=1e-10)
    np.testing.assert_allclose(t, y.mean(0) - s * R @ x.mean(0), atol=1e-12)
    # optimality: no small perturbation of R reduces the cost
    cost = np.sum((y - (s * x @ R.T + t)) ** 2)
    for _ in range(20):
        dR = rigid(rng.normal(size=3), 1e-3, np.zeros(3))[:3, :3]
        t2 = y.mean(0) - s * (R @ dR) @ x.mean(0)
        assert np.sum((y - (s * x @ (R @ dR).T + t2)) ** 2) >= cost


def test_umeyama_reflection_is_not_returned():
    rng = np.random.default_rng(7)
    x = rng.normal(size=(30, 3))
    y = x * np.array([1, 1, -1])  # a mirror image: best proper rotation, det +1
    R, _, _ = umeyama_alignment(x, y)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_umeyama_bad_input():
    x = np.random.default_rng(8).normal(size=(10, 3))
    with pytest.raises(ValueError, match="at least 3"):
        umeyama_alignment(x[:2], x[:2])
    with pytest.raises(ValueError, match="equal shape"):
        umeyama_alignment(x, x[:9])
    line = np.outer(np.linspace(0, 1, 10), [1, 2, 3])
    with pytest.raises(ValueError, match="collinear"):
        umeyama_alignment(line, line + 1)
    with pytest.raises(ValueError, match="collinear"):
        umeyama_alignment(np.ones((5, 3)), np.ones((5, 3)))
    bad = x.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        umeyama_alignment(bad, x)


# --------------------------------------------------------------------------------------
# bad input for the trajectory metrics
# --------------------------------------------------------------------------------------

def test_trajectory_metric_bad_input():
    rng = np.random.default_rng(9)
    ref = random_trajectory(rng, 20)
    with pytest.raises(ValueError, match="paired by index"):
        absolute_trajectory_error(ref[:19], ref)
    with pytest.raises(ValueError, match="paired by index"):
        relative_pose_error(ref, ref[:10])
    with pytest.raises(ValueError, match="at least 3"):
        absolute_trajectory_error(ref[:2], ref[:2])
    assert absolute_trajectory_error(ref[:2], ref[:2], align=False).rmse == 0.0
    with pytest.raises(ValueError, match="collinear"):
        line = translations(np.outer(np.arange(5.0), [1, 0, 0]))
        absolute_trajectory_error(line, line)
    with pytest.raises(ValueError, match="at least 2"):
        relative_pose_error(ref[:1], ref[:1])
    with pytest.raises(ValueError, match="no pose pair"):
        relative_pose_error(ref, ref, delta=50)
    with pytest.raises(ValueError, match="delta_unit"):
        relative_pose_error(ref, ref, delta_unit="degrees")
    with pytest.raises(ValueError, match="integer"):
        relative_pose_error(ref, ref, delta=1.5)
    with pytest.raises(ValueError, match="positive"):
        relative_pose_error(ref, ref, delta=0)
    poses = ref.poses.copy()
    poses[4, 0, 3] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        absolute_trajectory_error(poses, ref)
    with pytest.raises(TypeError):
        absolute_trajectory_error(np.zeros((5, 3)), ref)
    with pytest.raises(ValueError, match="method"):
        associate(ref, ref, method="linear")
    with pytest.raises(ValueError, match="max_difference"):
        associate(ref, ref, max_difference=-1)


def test_evaluate_reconstruction_report_is_json():
    rng = np.random.default_rng(10)
    ref = random_trajectory(rng, 30)
    est = perturbed(rng, ref, 0.01, 0.01)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    f = np.array([[0, 1, 2]])
    pts = np.array([[0.2, 0.2, 0.5], [np.nan, 0, 0]])
    rep = evaluate_reconstruction(est, ref, points=pts, mesh=(v, f))
    s = json.loads(json.dumps(rep))
    assert s["poses"] == 30
    assert s["ate"]["translation_m"]["rmse"] == pytest.approx(absolute_trajectory_error(est, ref).rmse)
    assert s["rpe"]["translation_m"]["count"] == 29 and s["rpe"]["all_pairs"] is True
    assert s["cloud_to_mesh_m"]["max"] == pytest.approx(0.5) and s["cloud_to_mesh_m"]["dropped"] == 1
    with pytest.raises(ValueError, match="both"):
        evaluate_reconstruction(est, ref, points=pts)


# --------------------------------------------------------------------------------------
# point-to-mesh distance
# --------------------------------------------------------------------------------------

def _ericson_oracle(points, vertices, faces):
    """Brute force over all triangles with Ericson's closest-point-on-triangle (Real-Time
    Collision Detection, 5.1.5), one point at a time."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    out = np.empty(len(points))
    for k, p in enumerate(points):
        ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
        d1, d2 = np.sum(ab * ap, 1), np.sum(ac * ap, 1)
        d3, d4 = np.sum(ab * bp, 1), np.sum(ac * bp, 1)
        d5, d6 = np.sum(ab * cp, 1), np.sum(ac * cp, 1)
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        q = np.empty_like(a)
        todo = np.ones(len(a), dtype=bool)

        def put(mask, value):
            m = mask & todo
            q[m] = value[m]
            todo[m] = False

        with np.errstate(all="ignore"):
            put((d1 <= 0) & (d2 <= 0), a)
            put((d3 >= 0) & (d4 <= d3), b)
            put((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab)
            put((d6 >= 0) & (d5 <= d6), c)
            put((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac)
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            put((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + w[:, None] * (c - b))
            den = 1.0 / (va + vb + vc)
            put(np.ones(len(a), dtype=bool), a + ab * (vb * den)[:, None] + ac * (vc * den)[:, None])
        out[k] = np.sqrt(np.min(np.sum((q - p) ** 2, axis=1)))
    return out


def _segment_oracle(points, p0, p1):
    """Brute-force distance to a set of segments (for degenerate triangles)."""
    d = p1 - p0
    out = np.empty(len(points))
    for k, p in enumerate(points):
        L = np.sum(d * d, 1)
        t = np.clip(np.sum((p - p0) * d, 1) / np.where(L > 0, L, 1), 0, 1)
        out[k] = np.sqrt(np.min(np.sum((p0 + t[:, None] * d - p) ** 2, 1)))
    return out


def _torus(nu=60, nv=30, R=0.1, r=0.03):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False), np.linspace(0, 2 * np.pi, nv, endpoint=False),
                       indexing="ij")
    X = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return X, F


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("leaf_size", [1, 3, 8])
def test_mesh_distance_matches_brute_force_random_soup(seed, leaf_size):
    rng = np.random.default_rng(700 + seed)
    V = rng.normal(size=(400, 3))
    F = rng.integers(0, 400, (700, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    P = rng.normal(size=(300, 3)) * 1.5
    d = MeshDistanceIndex(V, F, leaf_size=leaf_size).distance(P)
    np.testing.assert_allclose(d, _ericson_oracle(P, V, F), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_mesh_distance_long_thin_and_mixed_size_triangles(seed):
    rng = np.random.default_rng(800 + seed)
    # slivers: length ~1, width 1e-4 .. 1e-2, random orientation
    n = 600
    a = rng.uniform(-1, 1, (n, 3))
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = rng.normal(size=(n, 3))
    w -= np.sum(w * u, 1, keepdims=True) * u
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    b = a + u * rng.uniform(0.5, 2.0, (n, 1))
    c = a + u * rng.uniform(0, 1, (n, 1)) + w * 10 ** rng.uniform(-4, -2, (n, 1))
    # plus one huge triangle and a cluster of tiny ones
    big = np.array([[-50, -50, 3.0], [50, -50, 3.0], [0, 60, 3.5]])
    tiny = rng.uniform(-0.01, 0.01, (200, 3, 3)) * 0.01 + np.array([2.0, 2.0, 2.0])
    V = np.concatenate([np.concatenate([a, b, c], 1).reshape(-1, 3), big, tiny.reshape(-1, 3)])
    F = np.arange(len(V)).reshape(-1, 3)
    P = np.concatenate([rng.uniform(-2, 3, (300, 3)), rng.normal([2, 2, 2], 0.01, (50, 3)),
                        rng.uniform(-40, 40, (50, 3))])
    d = point_to_mesh_distance(P, V, F)
    np.testing.assert_allclose(d, _ericson_oracle(P, V, F), rtol=1e-9, atol=1e-12)


def test_mesh_distance_points_on_vertices_edges_faces():
    rng = np.random.default_rng(11)
    V, F = _torus()
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    k = rng.choice(len(F), 200)
    w = rng.dirichlet([1, 1, 1], 200)
    on_face = w[:, :1] * a[k] + w[:, 1:2] * b[k] + w[:, 2:] * c[k]
    t = rng.uniform(0, 1, (200, 1))
    on_edge = a[k] + t * (b[k] - a[k])
    for P in (V, on_face, on_edge):
        assert np.max(point_to_mesh_distance(P, V, F)) < 1e-12
    # a torus mesh with noisy points near it: brute force on a sample
    P = V[rng.choice(len(V), 300)] + rng.normal(0, 0.003, (300, 3))
    np.testing.assert_allclose(point_to_mesh_distance(P, V, F), _ericson_oracle(P, V, F), rtol=1e-10, atol=1e-13)


def test_mesh_distance_analytic_unit_square():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    F = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    rng = np.random.default_rng(12)
    xy = rng.uniform(0, 1, (500, 2))
    h = rng.uniform(-2, 2, 500)
    P = np.column_stack([xy, h])
    np.testing.assert_allclose(point_to_mesh_distance(P, V, F), np.abs(h), rtol=1e-12, atol=1e-15)
    # outside the square: distance to the nearest boundary point in the plane, then height
    xy_out = rng.uniform(-1, 2, (500, 2))
    P = np.column_stack([xy_out, h])
    lateral = np.linalg.norm(xy_out - np.clip(xy_out, 0, 1), axis=1)
    np.testing.assert_allclose(point_to_mesh_distance(P, V, F), np.hypot(lateral, h), rtol=1e-12, atol=1e-15)


def test_mesh_distance_analytic_tetrahedron():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.uint8)
    P = np.array([[0.1, 0.1, 0.1],        # inside: nearest are the three axis planes
                  [0.1, 0.2, 0.3],        # inside: x = 0 face
                  [1, 1, 1],              # outside: slanted face, foot (1/3, 1/3, 1/3)
                  [-1, -1, -1],           # outside: vertex at the origin
                  [0.5, 0.5, -2.0],       # below the z = 0 face... foot (0.5, 0.5) is on edge x + y = 1
                  [0.25, 0.25, 0.25]])    # on the slanted face? no: x+y+z = 0.75 < 1, inside
    expect = [0.1, 0.1, 2 / np.sqrt(3), np.sqrt(3), 2.0, min(0.25, 0.25 / np.sqrt(3))]
    np.testing.assert_allclose(point_to_mesh_distance(P, V, F), expect, rtol=1e-6)


def test_mesh_distance_degenerate_triangles_are_their_edges():
    rng = np.random.default_rng(13)
    p0 = rng.normal(size=(40, 3))
    p1 = p0 + rng.normal(size=(40, 3))
    mid = p0 + rng.uniform(0, 1, (40, 1)) * (p1 - p0)  # collinear third vertex
    V = np.concatenate([p0, p1, mid])
    F = np.stack([np.arange(40), np.arange(40, 80), np.arange(80, 120)], axis=1)
    F[:10, 2] = F[:10, 0]  # repeated vertex
    P = rng.normal(size=(200, 3)) * 2
    np.testing.assert_allclose(point_to_mesh_distance(P, V, F), _segment_oracle(P, p0, p1), rtol=1e-10, atol=1e-12)


def test_mesh_distance_inputs_and_stats():
    V, F = _torus()
    rng = np.random.default_rng(14)
    P = V[rng.choice(len(V), 100)] + rng.normal(0, 0.002, (100, 3))
    P[[3, 50], 1] = [np.nan, np.inf]
    d = point_to_mesh_distance(P, V, F)
    assert np.isnan(d[3]) and np.isnan(d[50]) and np.all(np.isfinite(np.delete(d, [3, 50])))
    np.testing.assert_allclose(point_to_mesh_distance(P.astype(np.float32), V, F)[:3], d[:3], rtol=1e-5)
    s = mesh_distance_stats(P, V, F)
    e = d[np.isfinite(d)]
    assert s.count == 98 and s.dropped == 2
    assert s.mean == pytest.approx(e.mean()) and s.median == pytest.approx(np.median(e))
    assert s.p95 == pytest.approx(np.percentile(e, 95)) and s.max == pytest.approx(e.max())
    assert s.rmse == pytest.approx(np.sqrt(np.mean(e ** 2)))
    json.dumps(s.as_dict())
    with pytest.raises(ValueError, match="no finite point"):
        mesh_distance_stats(np.full((3, 3), np.nan), V, F)
    with pytest.raises(TypeError, match="points"):
        point_to_mesh_distance(np.zeros((3, 3), dtype=int), V, F)
    with pytest.raises(ValueError, match="points"):
        point_to_mesh_distance(P[:, :2], V, F)
    with pytest.raises(TypeError, match="faces"):
        point_to_mesh_distance(P, V, F.astype(float))
    with pytest.raises(TypeError, match="vertices"):
        point_to_mesh_distance(P, V.astype(np.int64), F)
    with pytest.raises(ValueError, match="faces"):
        point_to_mesh_distance(P, V, F[:, :2])
    with pytest.raises(ValueError, match="no triangles"):
        point_to_mesh_distance(P, V, F[:0])
    with pytest.raises(ValueError, match="indices"):
        point_to_mesh_distance(P, V, F + len(V) // 2)
    with pytest.raises(ValueError, match="indices"):
        point_to_mesh_distance(P, V, F - 1)
    V_bad = V.copy()
    V_bad[F[0, 0]] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        point_to_mesh_distance(P, V_bad, F)
    V_extra = np.concatenate([V, [[np.nan, 0, 0]]])  # unused vertex: ignored
    np.testing.assert_array_equal(point_to_mesh_distance(P, V_extra, F), d)
    np.testing.assert_array_equal(point_to_mesh_distance(P.tolist(), V.tolist(), F.tolist()), d)  # array-likes
    with pytest.raises(TypeError, match="vertices"):
        point_to_mesh_distance(P, V.astype(int).tolist(), F)  # integer coordinates are rejected


def test_mesh_distance_far_points_threads_and_reuse():
    # points far from a fine mesh keep many boxes in reach: still the exact minimum, and
    # the same bits whatever the thread count or entry point
    V, F = _torus(80, 40)
    rng = np.random.default_rng(15)
    P = rng.normal(size=(64, 3))
    idx = MeshDistanceIndex(V, F, leaf_size=2)
    d = idx.distance(P)
    np.testing.assert_allclose(d, _ericson_oracle(P, V, F), rtol=1e-10)
    np.testing.assert_array_equal(idx.distance(P, num_threads=1), d)
    np.testing.assert_array_equal(idx(P), d)
    assert idx.n_faces == len(F)
    assert idx.distance(np.zeros((0, 3))).shape == (0,)
    with pytest.raises(ValueError, match="leaf_size"):
        MeshDistanceIndex(V, F, leaf_size=0)
    with pytest.raises(ValueError, match="num_threads"):
        idx.distance(P, num_threads=-1)


def test_mesh_closest_points_lie_on_their_triangles():
    V, F = _torus(30, 15)
    rng = np.random.default_rng(17)
    P = rng.normal(0, 0.1, (200, 3))
    P[7] = np.nan
    d, Q, tri = MeshDistanceIndex(V, F).closest_points(P)
    ok = np.arange(200) != 7
    np.testing.assert_allclose(d[ok], _ericson_oracle(P[ok], V, F), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(Q - P, axis=1)[ok], d[ok], rtol=1e-12)
    # the returned point is on the returned triangle: its distance to that triangle is 0
    on_own = [_ericson_oracle(Q[k:k + 1], V, F[tri[k]:tri[k] + 1])[0] for k in np.flatnonzero(ok)]
    assert max(on_own) < 1e-12
    assert np.isnan(d[7]) and tri[7] == -1 and np.all(np.isnan(Q[7]))


@pytest.mark.data
def test_mesh_distance_matches_open3d_on_the_cgal_bunny(dataset_cache):
    o3d = pytest.importorskip("open3d")
    from scanalign.data import downloads as datasets

    mesh = datasets.load_cgal_mesh("bunny00")
    # Open3D computes in float32: give both the same float32-rounded inputs
    V = mesh.vertices.astype(np.float32)
    F = np.asarray(mesh.faces)
    rng = np.random.default_rng(18)
    P = (V[rng.choice(len(V), 5000)] + rng.normal(0, 0.02, (5000, 3))).astype(np.float32)
    P = np.concatenate([P, rng.uniform(-1, 1, (500, 3)).astype(np.float32)])  # far from the surface too
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(V), o3d.core.Tensor(F.astype(np.uint32)))
    expect = scene.compute_distance(o3d.core.Tensor(P)).numpy()
    d = point_to_mesh_distance(P, V, F)
    assert d.dtype == np.float64
    np.testing.assert_allclose(d, expect, rtol=0, atol=1e-6)  # the bunny spans about 1 unit


# --------------------------------------------------------------------------------------
# plots
# --------------------------------------------------------------------------------------

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _assert_png(path, min_bytes=5000):
    data = open(path, "rb").read()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > min_bytes


def test_plots_write_png(tmp_path):
    pytest.importorskip("matplotlib")
    from scanalign.viz import plots

    rng = np.random.default_rng(16)
    ref = random_trajectory(rng, 60)
    est = perturbed(rng, ref, 0.01, 0.01, rigid([0, 0, 1], 0.5, [0.2, 0, 0]))
    for kw in ({}, {"aligned": False, "plane": "xz", "units": "m", "title": "raw"}):
        out = plots.plot_trajectory_topdown(est, ref, tmp_path / f"traj{len(kw)}.png", **kw)
        _assert_png(out)
    rows = [{"time": 0.05 + 0.01 * i, "iterations": 10 + i % 5, "fitness": 0.9, "model_points": 1000 * i}
            for i in range(20)]
    rows[4]["skipped"] = True
    rows[7]["time"] = None
    _assert_png(plots.plot_frame_stats(rows, tmp_path / "frames.png", title="t"))
    cols = {"seconds": [0.1, 0.2, float("nan")], "model_size": [1, 2, 3]}
    _assert_png(plots.plot_frame_stats(cols, tmp_path / "sub" / "frames_cols.png"))
    x = [4, 8, 17, 34, 69]
    _assert_png(plots.plot_series(x, {"scanalign": [1, 2, 4, 8, 16], "PCL": [4, 9, 17, 40, float("nan")]},
                                  tmp_path / "series.png", xlabel="images", ylabel="time (s)", logx=True,
                                  logy=True, errors={"scanalign": [0.1] * 5}))
    with pytest.raises(ValueError, match="plane"):
        plots.plot_trajectory_topdown(est, ref, tmp_path / "x.png", plane="xx")
    with pytest.raises(ValueError, match="values"):
        plots.plot_series(x, {"a": [1, 2]}, tmp_path / "y.png")
    with pytest.raises(ValueError, match="time"):
        plots.plot_frame_stats([{"iterations": 3}], tmp_path / "z.png")


def test_plots_without_matplotlib_raise_a_clear_error(monkeypatch, tmp_path):
    import sys

    from scanalign.viz import plots

    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backends.backend_agg", None)
    with pytest.raises(ImportError, match="pip install matplotlib"):
        plots.plot_series([1, 2], {"a": [1, 2]}, tmp_path / "a.png")
