"""The two-step pose's 2D step (Kleppe et al., Robotics 6 (2017) 14, the thesis's Paper 3, §3.3; issue 30 §1): the
homography-to-pose geometry against OpenCV's own homography of projected points, and the refinement loop on the
synthetic hand camera against the cell's truth (1 mm and 0.5 deg from a rough pose 2 cm / 10 deg off), with a status
and a reason, never a wrong pose, for a textureless part, a part outside the view and an unreachable view."""

from __future__ import annotations

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from scanalign.grasp import ViewPlannerSettings, camera_above, hand_camera_mount, plan_camera_view  # noqa: E402
from scanalign.pipelines.refine2d import refine_2d  # noqa: E402
from scanalign.pose.image_matching import (Refine2dSettings, homography_of_part, match_reference,  # noqa: E402
                                           planar_pose_from_homography, refine_planar_pose)
from scanalign.synthetic.hand_camera import WEBCAM, render_top_view, top_label  # noqa: E402

Q_UR5 = [0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]
T_FLANGE_CAMERA = np.array([[1.0, 0, 0, 0], [0, 1, 0, 0.03], [0, 0, 1, 0.05], [0, 0, 0, 1]])


def upright(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = [x, y, z]
    return T


def yaw_error_deg(T: np.ndarray, truth: np.ndarray) -> float:
    D = np.linalg.inv(truth) @ T
    return abs(float(np.degrees(np.arctan2(D[1, 0], D[0, 0]))))


def test_the_pose_from_opencvs_homography_of_projected_points_is_exact():
    # Oracle: OpenCV's least-squares homography through reference corners projected by the camera model (not ours).
    # OpenCV's fit itself is good to a few 1e-8 (the C++ tests check hand-written homographies to 1e-9).
    label = top_label(seed=0)
    g = label.geometry
    rng = np.random.default_rng(4)
    for _ in range(20):
        truth = upright(0.45 + rng.uniform(-0.03, 0.03), 0.1 + rng.uniform(-0.03, 0.03), 0.01, rng.uniform(-3, 3))
        cam = camera_above(upright(0.45, 0.1, 0.01, 0.0), g.top_height, 0.2, rng.uniform(-3, 3))
        cam[:3, :3] = cam[:3, :3] @ cv2.Rodrigues(rng.uniform(-0.15, 0.15, 3))[0]  # tilted up to 15 deg
        ref = np.array([[0, 0], [g.width - 1, 0], [g.width - 1, g.height - 1], [0, g.height - 1], [40, 70]], float)
        X = np.array([(np.linalg.inv(cam) @ truth @ np.append(g.part_point(u, v), 1.0))[:3] for u, v in ref])
        img = np.c_[WEBCAM.fx * X[:, 0] / X[:, 2] + WEBCAM.cx, WEBCAM.fy * X[:, 1] / X[:, 2] + WEBCAM.cy]
        H, _ = cv2.findHomography(ref, img, 0)
        assert np.abs(H / H[2, 2] - homography_of_part(g, WEBCAM, cam, truth)).max() < 1e-6 * np.abs(H).max()
        rough = truth.copy()
        rough[:2, 3] += [0.02, -0.01]
        p = planar_pose_from_homography(H, g, WEBCAM, cam, rough)
        assert p.status == "ok", p.reason
        assert np.abs(p.T_base_part - truth).max() < 1e-6


@pytest.mark.parametrize("seed", range(5))
def test_refinement_from_a_2cm_10deg_rough_pose_reaches_1mm_half_a_degree(seed):
    rng = np.random.default_rng(seed)
    label = top_label(seed=seed)
    truth = upright(0.45 + rng.uniform(-0.05, 0.05), 0.15 + rng.uniform(-0.05, 0.05), 0.0, rng.uniform(-np.pi, np.pi))
    a = rng.uniform(0, 2 * np.pi)
    rough = upright(truth[0, 3] + 0.02 * np.cos(a), truth[1, 3] + 0.02 * np.sin(a), 0.002,
                    np.arctan2(truth[1, 0], truth[0, 0]) + np.radians(10) * rng.choice([-1, 1]))
    images = []

    def capture(T_base_camera):
        images.append(T_base_camera)
        return render_top_view(label, truth, T_base_camera, seed=seed)

    r = refine_2d(rough, label.image, label.geometry, capture, intrinsics=WEBCAM, robot="ur5",
                  camera_mount=hand_camera_mount(T_FLANGE_CAMERA), q_current=Q_UR5)
    assert r.status == "ok", r.reason
    assert np.linalg.norm(r.T_base_part[:2, 3] - truth[:2, 3]) < 0.001
    assert yaw_error_deg(r.T_base_part, truth) < 0.5
    assert r.T_base_part[2, 3] == rough[2, 3]  # height: the rough pose's (the table's), not the image's
    assert 2 <= len(r.views) <= Refine2dSettings().max_steps and len(images) == len(r.views)
    # The first view looked at the rough estimate, the last at the refined one (straight down, the planned height).
    first, last = r.views[0].T_base_camera, r.views[-1].T_base_camera
    assert np.linalg.norm(first[:2, 3] - rough[:2, 3]) < 1e-9 and last[2, 2] == pytest.approx(-1.0)
    assert r.views[0].correction_m > 0.015 and r.views[-1].correction_m < Refine2dSettings().converged_translation


@pytest.mark.parametrize("detector", ["akaze", "orb"])
def test_the_free_substitutes_refine_a_textured_part(detector):
    label = top_label(seed=2)
    truth = upright(0.47, 0.12, 0.0, 0.8)
    rough = upright(0.485, 0.135, 0.0, 0.8 + np.radians(8))
    s = Refine2dSettings()
    s.matching.detector = detector
    r = refine_2d(rough, label.image, label.geometry, lambda T: render_top_view(label, truth, T, seed=2),
                  intrinsics=WEBCAM, robot="ur5", camera_mount=hand_camera_mount(T_FLANGE_CAMERA), q_current=Q_UR5,
                  settings=s)
    assert r.status == "ok", r.reason
    assert np.linalg.norm(r.T_base_part[:2, 3] - truth[:2, 3]) < 0.001 and yaw_error_deg(r.T_base_part, truth) < 0.5


def test_a_textureless_part_gives_a_status_not_a_pose():
    label = top_label(seed=1, textured=False)
    truth, rough = upright(0.45, 0.15, 0.0, 0.3), upright(0.46, 0.14, 0.0, 0.4)
    r = refine_2d(rough, label.image, label.geometry, lambda T: render_top_view(label, truth, T), intrinsics=WEBCAM,
                  robot="ur5", camera_mount=hand_camera_mount(T_FLANGE_CAMERA), q_current=Q_UR5)
    assert r.status in ("too_few_features", "too_few_matches", "too_few_inliers") and "view 1" in r.reason
    assert np.array_equal(r.T_base_part, rough) and not r


def test_a_part_outside_the_view_gives_a_status_not_a_pose():
    label = top_label(seed=3)
    truth = upright(0.45, 0.15, 0.0, 0.3)
    rough = upright(0.45, 0.35, 0.0, 0.3)  # 20 cm off: the camera above it does not see the part
    r = refine_2d(rough, label.image, label.geometry, lambda T: render_top_view(label, truth, T), intrinsics=WEBCAM,
                  robot="ur5", camera_mount=hand_camera_mount(T_FLANGE_CAMERA), q_current=Q_UR5)
    assert r.status != "ok" and np.array_equal(r.T_base_part, rough), r.status
    # With a fixed camera that sees only the part's corner beyond the image border: the origin is outside.
    cam = camera_above(truth, label.geometry.top_height, 0.18, 0.0)
    cam[0, 3] += 0.135  # the part origin 13.5 cm left of the optical axis: beyond the image's left edge
    step = refine_planar_pose(render_top_view(label, truth, cam), label.image, label.geometry, WEBCAM, cam, truth)
    assert step.status in ("part_outside_image", "too_few_matches", "too_few_inliers", "too_few_features")
    assert step.T_base_part is None


def test_an_unreachable_view_gives_a_status():
    label = top_label(seed=0)
    far = upright(2.5, 0.0, 0.0, 0.0)
    r = refine_2d(far, label.image, label.geometry, lambda T: pytest.fail("no image without a view"),
                  intrinsics=WEBCAM, robot="ur5", camera_mount=hand_camera_mount(T_FLANGE_CAMERA), q_current=Q_UR5)
    assert r.status == "unreachable" and "unreachable" in r.reason and not r.views
    plan = plan_camera_view("ur5", far, 0.025, camera_mount=hand_camera_mount(T_FLANGE_CAMERA))
    assert not plan and len(plan.plan.candidates) == 4 * 8


def test_bad_input_is_refused_by_name():
    label = top_label(seed=0)
    cam = camera_above(upright(0.45, 0.1, 0.0, 0.0), 0.025, 0.18, 0.0)
    with pytest.raises(ValueError, match="image"):
        match_reference(label.image, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="detector"):
        match_reference(label.image, label.image, detector="surf")
    with pytest.raises(ValueError, match="T_base_camera"):
        planar_pose_from_homography(np.eye(3), label.geometry, WEBCAM, np.ones((4, 4)), np.eye(4))
    with pytest.raises(ValueError, match="height"):
        plan_camera_view("ur5", np.eye(4), 0.025, camera_mount=hand_camera_mount(T_FLANGE_CAMERA),
                         settings=ViewPlannerSettings(height=-0.1))
    with pytest.raises(ValueError, match="robot"):
        refine_2d(np.eye(4), label.image, label.geometry, lambda T: None, intrinsics=WEBCAM)
    assert planar_pose_from_homography(np.zeros((3, 3)), label.geometry, WEBCAM, cam, np.eye(4)).status == "not_finite"
