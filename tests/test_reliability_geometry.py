"""Confident wrong answers of the geometry modules (issue 16): CGA objects built from NaN,
complex or overflowing input, inverse kinematics of stretched arms with a nearly singular
wrist, flag and PCL feature alignment of degenerate clouds, model views that would exhaust
memory, and CBD / shape factors at huge scales. Each case now gives a clear exception or a
failure status, and what is still answered is checked against independent truth."""

from __future__ import annotations

import time

import numpy as np
import pytest

from scanalign import cga, features, fitting, kinematics, pose
from scanalign.pose import model_views as cad
from scanalign.pose import cbd
from scanalign.data import parts
from scanalign.common import rigid as se3

# ----------------------------------------------------------------------------- CGA


@pytest.mark.parametrize("call, name", [
    (lambda: cga.up([np.nan, 0, 0]), "x"),
    (lambda: cga.Sphere([0, np.inf, 0], 1.0), "center"),
    (lambda: cga.Sphere([0, 0, 0], np.nan), "radius"),
    (lambda: cga.Plane([np.nan, 0, 1], 0.0), "normal"),
    (lambda: cga.Line([0, 0, 0], [0, np.nan, 1]), "direction"),
    (lambda: cga.Multivector(np.nan), "scalar"),
    (lambda: cga.e1 * np.inf, "scalar"),
    (lambda: cga.Multivector.vector([0, 0, np.nan]), "v"),
    (lambda: cga.Multivector.from_null(np.full(32, np.nan)), "coefficients"),
    (lambda: cga.from_vector5([1, 0, 0, np.nan, 1]), "x"),
    (lambda: cga.Motor.from_quaternion([np.nan, 0, 0, 1], [0, 0, 0]), "wxyz"),
    (lambda: cga.Motor.from_matrix(np.full((4, 4), np.nan)), "T"),
    (lambda: cga.rotor([0, 0, 1], np.nan), "angle"),
    (lambda: cga.point_distance([0, 0, 0], [np.inf, 0, 0]), "b"),
])
def test_cga_non_finite_input_is_a_value_error_naming_the_argument(call, name):
    """These used to return NaN objects (Multivector(nan), vector(nan), from_null) or were
    refused without the argument's name."""
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        call()


@pytest.mark.parametrize("call, name", [
    (lambda: cga.up(np.array([1 + 2j, 0, 0])), "x"),
    (lambda: cga.Sphere(np.array([1j, 0, 0]), 1.0), "center"),
    (lambda: cga.Multivector.from_null(np.full(32, 1j)), "coefficients"),
    (lambda: cga.Motor.from_quaternion(np.array([1, 0, 0, 1j]), [0, 0, 0]), "wxyz"),
    (lambda: cga.up("abc"), "x"),
    (lambda: cga.up(None), "x"),
    (lambda: cga.point_pair([0, 0, 0], None), "b"),
])
def test_cga_complex_and_non_numeric_input_is_a_type_error(call, name):
    """up() of a complex vector used to drop the imaginary part (a ComplexWarning at most)."""
    with pytest.raises(TypeError, match=rf"^{name}\b"):
        call()


@pytest.mark.parametrize("call", [
    lambda: cga.up([1e300, 0, 0]),
    lambda: cga.up(np.array([[0, 1e300, 0]])),
    lambda: cga.Point([0, 0, 1e200]),
    lambda: cga.Sphere([1e300, 0, 0], 1.0),
    lambda: cga.Sphere([0, 0, 0], 1e300),
    lambda: cga.Plane([0, 0, 1], 1e300),
    lambda: cga.Line([1e300, 0, 0], [0, 1, 0]),
    lambda: cga.translator([1e300, 0, 0]),
    lambda: cga.Motor.from_matrix(np.array([[1, 0, 0, 1e300], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])),
    lambda: cga.Multivector(1e200) * cga.Multivector(1e200),
    lambda: cga.Multivector.vector([1e200, 0, 0]) ^ cga.Multivector.vector([0, 1e200, 0]),
    lambda: cga.Multivector.vector([1e200, 0, 0]) | cga.Multivector.vector([1e200, 0, 0]),
    lambda: cga.up([1e100, 0, 0]) * cga.up([0, 1e100, 0]),
    lambda: cga.geometric_product_many(np.full((2, 32), 1e200), np.full((2, 32), 1e200)),
    lambda: cga.down(np.array([[1.0, 0, 0, 1, 1e-300]])),
])
def test_cga_overflow_is_a_value_error_not_an_inf_or_nan_object(call):
    """Finite input whose squares overflow used to give objects full of inf and NaN."""
    with pytest.raises(ValueError, match="overflow"):
        call()


def test_cga_point_at_infinity_has_no_euclidean_point():
    with pytest.raises(ValueError):
        cga.down(cga.einf)
    with pytest.raises(ValueError):
        cga.down(np.array([[1.0, 2, 3, 4, 0]]))


def test_cga_large_but_representable_input_stays_exact():
    """Up to ~1e150 m the objects are finite and round-trip exactly; a plane normal of
    1e300 no longer overflows its own length into a zero normal."""
    x = np.array([[3e149, -1e149, 2e149]])
    np.testing.assert_allclose(cga.up(x), [[*x[0], 0.5 * 14e298, 1.0]], rtol=1e-15)
    np.testing.assert_array_equal(cga.down(cga.up(x * 1e-140)), x * 1e-140)
    p = cga.Plane([1e300, 1e300, 0], 2.0)  # used to give the zero multivector
    np.testing.assert_allclose(p.normal, [2 ** -0.5, 2 ** -0.5, 0], rtol=1e-15)
    assert p.distance == pytest.approx(2.0 / (2 ** 0.5 * 1e300), rel=1e-15)
    np.testing.assert_allclose(cga.rotation_axis(cga.rotation_plane_from_axis([0, 0, 1e300])), [0, 0, 1])


def test_cga_distances_far_from_the_origin_are_exact():
    """The null vectors of far points hold 1/2 |x|^2 in e+ and e-, and the products cancel them:
    at 1e6 m the distance of two points 1 m apart came out as 8192 m. Distances are now taken
    with the first point moved to the origin (the inner product is translation-invariant)."""
    for s in (1e3, 1e6, 1e9):
        a, b = np.array([s, -s, 0.5 * s]), np.array([s + 0.6, -s + 0.8, 0.5 * s])
        d = np.linalg.norm(b - a)  # 1 m up to the rounding of b itself
        assert d == pytest.approx(1.0, abs=1e-6) and cga.point_distance(a, b) == pytest.approx(d, abs=1e-12)
        sphere = cga.Sphere(a, 2.0)
        assert cga.sphere_point_inner(sphere, b) == pytest.approx(0.5 * (4.0 - d * d), abs=1e-12)
        assert cga.point_sphere_distance(b, sphere) == pytest.approx(d - 2.0, abs=1e-12)
        assert cga.point_plane_distance(b, cga.Plane.through_point([0, 0, 1], a)) == pytest.approx(0.0, abs=1e-9)


def test_sphere_fit_is_scale_safe_and_refuses_what_it_cannot_represent():
    """A sphere of 2e30 m radius is recovered as well as one of 2 m; at 1e200 m the dual
    sphere would overflow, which used to be reported as 'all points coincide'."""
    rng = np.random.default_rng(1)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    for scale in (1.0, 1e30, 1e100):
        r = fitting.fit_sphere((2 * d + [1, 0, 0]) * scale)
        np.testing.assert_allclose(np.asarray(r.center) / scale, [1, 0, 0], atol=1e-12)
        assert r.radius / scale == pytest.approx(2.0, rel=1e-12)
    with pytest.raises(ValueError, match="overflow"):
        fitting.fit_sphere((2 * d + [1, 0, 0]) * 1e200)
    with pytest.raises(ValueError, match="collinear"):
        fitting.fit_sphere(np.c_[np.linspace(0, 1, 20), np.zeros(20), np.zeros(20)])
    with pytest.raises(ValueError, match="at least 5"):
        fitting.fit_sphere(np.eye(3))


# ----------------------------------------------------------------------------- kinematics


@pytest.mark.parametrize("robot, elbow", [(kinematics.ur5(), 2), (kinematics.kuka_kr6_r900_sixx(), 2)])
def test_stretched_arm_with_nearly_singular_wrist_is_reachable_and_exact(robot, elbow):
    """Poses made by FK of joints near the stretched elbow and the singular wrist (offsets of
    1e-5 to 1e-11 rad): about 12 % of such UR5 poses used to come back unreachable (the wrist
    point carries an error ~1e-16 / sin(q5), which pushed the tangent elbow pair imaginary).
    Oracle: forward kinematics of the returned joints."""
    rng = np.random.default_rng(0)
    for scale in (1e-5, 1e-7, 1e-9, 1e-11):
        q = rng.uniform(-np.pi, np.pi, (60, 6))
        q[:, elbow] = rng.normal(size=60) * scale
        q[:, 4] = rng.normal(size=60) * scale
        for qi in q:
            T = robot.fk(qi)
            sol = robot.ik(T, respect_limits=False)
            ok = [s for s, st in zip(sol.q, sol.status) if st == "ok"]
            assert ok, (scale, qi, sol.status, sol.unreachable_step)
            for s in ok:  # every solution marked ok reaches the pose
                np.testing.assert_allclose(robot.fk(s), T, atol=1e-9)


def test_every_ok_solution_reaches_its_pose():
    """The C++ solver now checks FK of every solution before calling it ok (fk_check)."""
    rng = np.random.default_rng(5)
    for robot in (kinematics.ur5(), kinematics.kuka_kr6_r900_sixx()):
        poses = robot.fk(rng.uniform(-3, 3, (300, 6)))
        b = robot.ik_batch(poses)
        for i, j in zip(*np.nonzero(b.status == 0)):
            np.testing.assert_allclose(robot.fk(b.q[i, j]), poses[i], atol=1e-6)
    assert kinematics.STEP_NAMES == ("", "shoulder", "elbow", "fk_check")


def test_bad_poses_and_joints_are_refused():
    """A pose holding a NaN used to give 8 (UR5) / 4 (KR6) solutions marked ok, a rotation
    block scaled by 2 ok solutions 9 cm / 33 cm away from the input."""
    for robot in (kinematics.ur5(), kinematics.kuka_kr6_r900_sixx()):
        T = robot.fk([0.3, -1.0, 1.2, -0.5, 0.8, 0.4])
        bad_nan, bad_scale = T.copy(), T.copy()
        bad_nan[0, 3] = np.nan
        bad_scale[:3, :3] *= 2
        for bad, why in ((bad_nan, "non-finite"), (bad_scale, "orthonormal")):
            with pytest.raises(ValueError, match=f"T_base_tool.*{why}"):
                robot.ik(bad)
            with pytest.raises(ValueError, match="T_base_tool"):
                robot.ik_closest(bad, np.zeros(6))
            assert set(robot.ik_batch(bad[None]).status.ravel()) == {3}  # invalid_input, never ok
        with pytest.raises(TypeError, match="T_base_tool"):
            robot.ik(T.astype(complex))
        with pytest.raises(ValueError, match="q"):
            robot.fk(np.full(6, 1e300))  # cos/sin of 1e300 rad is noise, not a pose
        with pytest.raises(ValueError, match="q"):
            robot.fk(np.zeros((2, 3, 6)))
        with pytest.raises(TypeError, match="q"):
            robot.fk("abc")
    with pytest.raises(TypeError, match="name"):
        kinematics.Robot.by_name(None)
    with pytest.raises(ValueError, match="^a"):  # FK of 1e308 m links used to be inf
        kinematics.Robot.from_dh([1e308] * 6, [0] * 6, [0] * 6)
    with pytest.raises(ValueError, match="^index"):  # 99 used to name blade 99 & 31
        cga.Multivector.blade_name(99)


# ----------------------------------------------------------------------------- pose


@pytest.fixture(scope="module")
def patch():
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.05, 0.05, (2, 2000))
    p = np.c_[u, v, 0.01 * np.sin(60 * u) + 0.005 * np.cos(40 * v)]
    n = np.c_[-0.6 * np.cos(60 * u), 0.2 * np.sin(40 * v), np.ones_like(u)]
    return p, n / np.linalg.norm(n, axis=1)[:, None]


def test_align_flags_refuses_degenerate_clouds(patch):
    """Five points, collinear points and 1e30 coordinates used to be reported valid."""
    p, n = patch
    T = se3.rigid([0.2, -0.3, 1.0], 0.4, [0.02, -0.01, 0.03])
    good = pose.align_flags(p, n, p @ T[:3, :3].T + T[:3, 3], n @ T[:3, :3].T)
    assert good.valid
    np.testing.assert_allclose(good.T_target_source, T, atol=1e-6)
    five = pose.align_flags(p[:5], n[:5], p[:5], n[:5])
    assert not five.valid and "min_points" in five.message
    line = np.c_[np.linspace(0, 0.1, 200), np.zeros(200), np.zeros(200)]
    collinear = pose.align_flags(line, n[:200], p, n)
    assert not collinear.valid and "collinear" in collinear.message
    with pytest.raises(ValueError, match="1e6 m"):
        pose.align_flags(p * 1e30, n, p * 1e30, n)


def test_pcl_feature_alignment_does_not_converge_on_a_collinear_source(patch):
    p, _ = patch
    line = np.c_[np.linspace(0, 0.1, 500), np.zeros(500), np.zeros(500)]
    r = pose.pcl_feature_alignment(line, p)
    assert not r.converged and r.message
    with pytest.raises(ValueError, match="max_iterations"):  # 1e9 used to run for more than ten minutes
        pose.pcl_feature_alignment(p, p, max_iterations=10 ** 9)


def test_model_views_refuse_what_would_exhaust_memory():
    """resolution 8192 (42 views) or level 6 (40962 views) used to be rendered until memory ran
    out; the check happens before anything is allocated."""
    mesh = parts.builtin_mesh(24)
    obj = parts.sample_mesh(mesh, 2000)[0]
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="max_memory_bytes"):
        pose.estimate_pose(mesh, obj, resolution=8192)
    with pytest.raises(ValueError, match="max_memory_bytes"):
        cad.render_views(mesh, level=6)
    assert time.perf_counter() - t0 < 10
    assert cad.ModelViewSettings().max_memory_bytes == 4 * 2 ** 30


def test_malformed_cad_meshes_and_tiny_scenes():
    mesh = parts.builtin_mesh(24)
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    obj = parts.sample_mesh(mesh, 2000)[0]
    bad = V.copy()
    bad[0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        cad.render_views((bad, F))
    with pytest.raises(TypeError, match="mesh vertices"):
        cad.render_views((V.astype(complex), F))
    with pytest.raises(ValueError, match="out of range"):
        cad.render_views((V, np.where(F == F.max(), 10 ** 9, F)))
    with pytest.raises(ValueError, match="zero area"):  # used to say 'no consensus' after all views
        pose.estimate_pose((V, np.zeros((5, 3), int)), obj)
    line = np.c_[np.arange(5.0), np.zeros(5), np.zeros(5)] * 0.01
    with pytest.raises(ValueError, match="zero area"):
        cad.render_views((line, np.array([[0, 1, 2], [2, 3, 4]])))
    for scene in (np.zeros((0, 3)), obj[:3], obj[:5]):
        assert not pose.estimate_pose(mesh, scene, method="flags").found


# ----------------------------------------------------------------------------- CBD, shape factors


def test_shape_factors_and_cbd_at_huge_scales():
    """Eigenvalues near 1e308 m^2 used to overflow their sum into NaN factors; CBD of points
    beyond 1e100 m gave NaN neighbourhoods."""
    np.testing.assert_allclose(features.shape_factors(np.array([1e308, 1e308, 1e308])), [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(features.shape_factors(np.array([3e300, 2e300, 1e300])), [1 / 6, 2 / 6, 3 / 6])
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.05, 0.05, (2, 3000))
    p = np.c_[u, v, 0.01 * np.sin(60 * u)]
    counts, ev = cbd.neighbourhood_pca(p * 1e20, radius=0.01 * 1e20)
    c1, e1 = cbd.neighbourhood_pca(p, radius=0.01)
    np.testing.assert_array_equal(counts, c1)
    np.testing.assert_allclose(ev / 1e40, e1, rtol=1e-9, atol=1e-18)
    with pytest.raises(ValueError, match="overflow"):
        cbd.neighbourhood_pca(p * 1e160, radius=0.01 * 1e160)
    with pytest.raises(ValueError, match="overflow"):
        cbd.compute(p * 1e160, radius=0.01, min_neighbors=5)
    f = cbd.compute(p, radius=0.01, min_neighbors=5)
    assert len(f.keypoints) > 0 and np.all(np.isfinite(f.descriptors))


# ----------------------------------------------------------------------------- Python layer


@pytest.mark.parametrize("call, exc, name", [
    (lambda: se3.rotation_about(None, 0.1), TypeError, "axis"),
    (lambda: se3.rotation_about([1, 2], 0.1), ValueError, "axis"),
    (lambda: se3.rotation_about([0, 0, 0], 0.1), ValueError, "axis"),
    (lambda: se3.rotation_about([1j, 0, 0], 0.1), TypeError, "axis"),
    (lambda: se3.rotation_about([0, 0, 1], None), TypeError, "angle"),
    (lambda: se3.rotation_about([0, 0, 1], np.nan), ValueError, "angle"),
    (lambda: se3.rigid([0, 0, 1], 0.1, None), TypeError, "t"),
    (lambda: se3.rigid([0, 0, 1], 0.1, [1, 2]), ValueError, "t"),
    (lambda: se3.inverse(None), TypeError, "T"),
    (lambda: se3.inverse("abc"), TypeError, "T"),
    (lambda: se3.inverse(np.zeros((3, 3))), ValueError, "T"),
    (lambda: se3.inverse(np.eye(4, dtype=complex)), TypeError, "T"),
    (lambda: se3.rotation_angle(None), TypeError, "R"),
    (lambda: se3.pose_error(None, np.eye(4)), TypeError, "T_est"),
    (lambda: se3.pose_error(np.eye(4), np.eye(4, dtype=complex)), TypeError, "T_ref"),
    (lambda: se3.rigid_problem(None), TypeError, "m"),
    (lambda: se3.rigid_problem(np.zeros((3, 3))), ValueError, "m"),
])
def test_se3_bad_input_names_the_argument(call, exc, name):
    """These used to raise IndexError, 'NoneType is not subscriptable', a pybind11
    signature dump, or drop a complex part with a warning."""
    with pytest.raises(exc, match=rf"^{name}\b"):
        call()
