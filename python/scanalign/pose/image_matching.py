"""The 2D step of the two-step pose (Kleppe et al., "Automated assembly using 3D and 2D cameras", Robotics 6 (2017) 14,
the thesis's Paper 3, §3.3): match a part's top-face reference image in a hand camera's image, fit the homography
robustly and read the part's fine planar pose off it (eqs. (5)-(6), in C++: :func:`planar_pose_from_homography`).

OpenCV does the keypoints and the RANSAC fit (``pip install opencv-python-headless``); the geometry is C++. Settings:
:class:`Refine2dSettings` (``matching``: :class:`ImageMatchSettings`; ``homography``: :class:`HomographyPoseSettings`),
one C++ struct with its defaults and units.

Frames and units: metres, radians, pixels. ``T_base_camera`` is the hand camera's pose when the image was taken
(camera x right, y down, z forward), ``T_base_part_rough`` the 3D estimate (the part upright on the table, base z up).
The reference image is an orthographic top view: pixel u along part +x, v along part -y
(:class:`ReferenceImageGeometry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional, Tuple

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_transform
from scanalign.common.settings import with_overrides

__all__ = ["ReferenceImageGeometry", "HomographyPose", "HomographyPoseSettings", "ImageMatchSettings",
           "Refine2dSettings", "ImageMatch", "Refine2dStep", "match_reference", "refine_planar_pose",
           "planar_pose_from_homography", "homography_of_part"]

_P = _core.pose
ReferenceImageGeometry = _P.ReferenceImageGeometry
HomographyPose = _P.HomographyPose
HomographyPoseSettings = _P.HomographyPoseSettings
ImageMatchSettings = _P.ImageMatchSettings
Refine2dSettings = _P.Refine2dSettings
#: ``planar_pose_from_homography(H_image_reference, reference, intrinsics, T_base_camera, T_base_part_rough,
#: settings=HomographyPoseSettings())`` -> :class:`HomographyPose` (C++).
planar_pose_from_homography = _P.planar_pose_from_homography
#: ``homography_of_part(reference, intrinsics, T_base_camera, T_base_part)`` -> (3, 3) reference -> camera pixels.
homography_of_part = _P.homography_of_part


def _cv2() -> Any:
    try:
        import cv2
    except ImportError as e:  # an optional dependency: only the 2D step needs it
        raise ImportError("the 2D refinement matches keypoints with OpenCV: pip install opencv-python-headless") from e
    return cv2


@dataclass
class ImageMatch:
    """Keypoints of the reference matched in the image, and the homography fitted to them."""

    #: "ok", "too_few_features" (a textureless reference or image), "too_few_matches" (after the ratio test) or
    #: "too_few_inliers" (RANSAC found no consistent homography).
    status: str
    reason: str = ""
    H_image_reference: Optional[np.ndarray] = None  #: (3, 3) reference pixels -> image pixels
    keypoints: Tuple[int, int] = (0, 0)  #: in the reference, in the image
    matches: int = 0  #: pairs passing the ratio test
    inliers: int = 0  #: of those, RANSAC inliers of H
    reference_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  #: (inliers, 2) px
    image_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  #: (inliers, 2) px

    def __bool__(self) -> bool:
        return self.status == "ok"


def _gray(image: Any, name: str) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        a = a[..., :3].astype(np.float64) @ [0.299, 0.587, 0.114]  # ITU-R BT.601 luma
    if a.ndim != 2 or a.shape[0] < 8 or a.shape[1] < 8:
        raise ValueError(f"{name}: expected an (H, W) grey or (H, W, 3) colour image of at least 8x8 pixels, "
                         f"got shape {a.shape}")
    if a.dtype != np.uint8:
        if not np.issubdtype(a.dtype, np.number) or not np.isfinite(a).all():
            raise ValueError(f"{name}: expected finite numbers (uint8 0..255 or floats 0..255)")
        a = np.clip(np.rint(a), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(a)


def _detector(cv2: Any, s: Any) -> Tuple[Any, int]:
    if s.detector == "sift":
        return cv2.SIFT_create(nfeatures=s.max_features), cv2.NORM_L2
    if s.detector == "orb":
        return cv2.ORB_create(nfeatures=s.max_features), cv2.NORM_HAMMING
    return cv2.AKAZE_create(), cv2.NORM_HAMMING


def _features(cv2: Any, detector: Any, image: np.ndarray, limit: int) -> Tuple[list, Optional[np.ndarray]]:
    kp, desc = detector.detectAndCompute(image, None)
    if desc is None or len(kp) == 0:
        return [], None
    if len(kp) > limit:  # AKAZE has no cap of its own: keep the strongest
        keep = np.argsort([-k.response for k in kp], kind="stable")[:limit]
        kp, desc = [kp[i] for i in keep], desc[keep]
    return list(kp), desc


def match_reference(reference: Any, image: Any, settings: Optional[ImageMatchSettings] = None,
                    **overrides: Any) -> ImageMatch:
    """Matches the reference image's keypoints in ``image`` and fits the homography reference -> image by RANSAC.

    ``reference``, ``image``: (H, W) grey or (H, W, 3) RGB arrays (uint8, or floats 0..255). ``settings``: an
    :class:`ImageMatchSettings` (default its C++ defaults), keyword overrides on top. Returns an :class:`ImageMatch`
    whose ``status`` says why no homography was found; never raises for a picture without texture. ValueError: not an
    image, bad settings."""
    s = with_overrides(ImageMatchSettings, settings, overrides, "ImageMatchSettings")
    s.validate()
    ref, img = _gray(reference, "reference"), _gray(image, "image")
    cv2 = _cv2()
    detector, norm = _detector(cv2, s)
    kp_r, d_r = _features(cv2, detector, ref, s.max_features)
    kp_i, d_i = _features(cv2, detector, img, s.max_features)
    out = ImageMatch("too_few_features", keypoints=(len(kp_r), len(kp_i)))
    if len(kp_r) < s.min_matches or len(kp_i) < s.min_matches:
        out.reason = (f"{len(kp_r)} keypoints in the reference and {len(kp_i)} in the image, fewer than min_matches "
                      f"{s.min_matches}: too little texture for {s.detector}")
        return out
    pairs = cv2.BFMatcher(norm).knnMatch(d_r, d_i, k=2)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < s.ratio * p[1].distance]
    out.matches = len(good)
    if len(good) < s.min_matches:
        out.status, out.reason = "too_few_matches", (f"{len(good)} matches pass the ratio test {s.ratio}, fewer than "
                                                     f"min_matches {s.min_matches}")
        return out
    src = np.float64([kp_r[m.queryIdx].pt for m in good])
    dst = np.float64([kp_i[m.trainIdx].pt for m in good])
    H, mask = cv2.findHomography(src, dst, cv2.USAC_MAGSAC, s.ransac_threshold, maxIters=s.ransac_iterations,
                                 confidence=0.999)
    inl = np.zeros(len(good), bool) if mask is None else mask.ravel().astype(bool)
    out.inliers = int(inl.sum())
    if H is None or out.inliers < s.min_inliers:
        out.status, out.reason = "too_few_inliers", (f"{out.inliers} of {len(good)} matches fit one homography "
                                                     f"within {s.ransac_threshold} px, fewer than min_inliers "
                                                     f"{s.min_inliers}")
        return out
    # Least squares on the inliers (OpenCV's RANSAC already refines; this keeps the fit independent of its version).
    H, _ = cv2.findHomography(src[inl], dst[inl], 0)
    if H is None or not np.isfinite(H).all():
        out.status, out.reason = "too_few_inliers", "the inliers do not determine a homography (collinear points)"
        return out
    out.status, out.H_image_reference = "ok", H / H[2, 2]
    out.reference_points, out.image_points = src[inl], dst[inl]
    return out


@dataclass
class Refine2dStep:
    """One 2D step: the match and the planar pose read off it."""

    #: "ok", a matching status (:class:`ImageMatch`) or a :class:`HomographyPose` status ("non_rigid",
    #: "part_outside_image", "not_in_view", "not_finite").
    status: str
    reason: str
    match: ImageMatch
    pose: Optional[Any] = None  #: :class:`HomographyPose` when a homography was found
    T_base_part: Optional[np.ndarray] = None  #: (4, 4) the refined pose when ``status == "ok"``

    def __bool__(self) -> bool:
        return self.status == "ok"


def _undistorted(cv2: Any, image: Any, intrinsics: Any) -> Tuple[Any, Any]:
    """The image as a pinhole camera of the same K sees it, and those intrinsics."""
    d = np.asarray(intrinsics.distortion, np.float64)
    if not d.any():
        return image, intrinsics
    K = np.array([[intrinsics.fx, 0.0, intrinsics.cx], [0.0, intrinsics.fy, intrinsics.cy], [0.0, 0.0, 1.0]])
    pinhole = type(intrinsics)(intrinsics.width, intrinsics.height, intrinsics.fx, intrinsics.fy, intrinsics.cx,
                               intrinsics.cy)
    return cv2.undistort(np.asarray(image), K, d), pinhole


def refine_planar_pose(image: Any, reference: Any, geometry: ReferenceImageGeometry, intrinsics: Any,
                       T_base_camera: Any, T_base_part_rough: Any, settings: Optional[Refine2dSettings] = None,
                       **overrides: Any) -> Refine2dStep:
    """One 2D refinement step: :func:`match_reference`, then :func:`planar_pose_from_homography`.

    ``image``: the hand camera's image (its lens distortion is removed first); ``reference``: the part's top-face
    reference image with its ``geometry``; ``intrinsics``: the hand camera's
    :class:`scanalign.reconstruction.camera.Intrinsics`; ``T_base_camera``: its pose for this image (4x4, m);
    ``T_base_part_rough``: the estimate to refine (4x4, m; its height gives the top plane). ``settings``: a
    :class:`Refine2dSettings`, overrides on top. A step that cannot give a pose says why in ``status`` / ``reason``
    and has ``T_base_part`` None."""
    s = with_overrides(Refine2dSettings, settings, overrides, "Refine2dSettings")
    s.validate()
    cv2 = _cv2()
    image, pinhole = _undistorted(cv2, image, intrinsics)
    match = match_reference(reference, image, s.matching)
    if not match:
        return Refine2dStep(match.status, match.reason, match)
    pose = planar_pose_from_homography(match.H_image_reference, geometry, pinhole, as_transform(T_base_camera),
                                       as_transform(T_base_part_rough), s.homography)
    if not pose:
        return Refine2dStep(pose.status, pose.reason, match, pose)
    return Refine2dStep("ok", "", match, pose, np.asarray(pose.T_base_part))
