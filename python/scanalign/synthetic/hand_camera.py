"""A colour hand camera looking down at textured parts, for the 2D step of the two-step pose (Kleppe et al.,
"Automated assembly using 3D and 2D cameras", Robotics 6 (2017) 14, the thesis's Paper 3): the parts' top-face
reference images (a printed label that SIFT can lock onto, or a weakly textured face as the paper's object A) and the
images a webcam (Logitech C930e-like: 1280x720, about 78 deg across) takes of them.

The part's top face is a plane, so the camera sees it through the exact homography of
:func:`scanalign.pose.image_matching.homography_of_part`: the image is the reference warped by it onto a table
background, then blurred and given sensor noise. Only the top face is drawn (a camera above the part sees little of
its sides); the part's own shadow and lighting are not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence, Tuple

import numpy as np

from scanalign.data.labels import printed_label
from scanalign.pose.image_matching import ReferenceImageGeometry, homography_of_part
from scanalign.reconstruction.camera import Intrinsics

__all__ = ["WEBCAM", "TABLE_TINT", "LABEL_TINT", "TopLabel", "top_label", "render_top_view", "render_labels"]

#: A Logitech C930e-like webcam: 1280x720, 900 px focal length (about 71 x 44 deg), the paper's hand camera.
WEBCAM = Intrinsics(1280, 720, 900.0, 900.0, 639.5, 359.5)


@dataclass
class TopLabel:
    """A part's top-face reference image (grey, uint8) and where it lies on the part."""

    image: np.ndarray
    geometry: ReferenceImageGeometry
    textured: bool


def _cv2() -> Any:
    import cv2  # an optional dependency, as for the matching itself

    return cv2


def top_label(size: Tuple[float, float] = (0.06, 0.04), top_height: float = 0.025, *, textured: bool = True,
              seed: int = 0, pixels_per_metre: float = 5000.0) -> TopLabel:
    """A reference image of a part's top face, ``size`` (x, y) metres, ``top_height`` m above the part origin, centred
    on it: with ``textured`` a printed label (random shapes, lines and letters, fixed by ``seed``) whose keypoints
    SIFT, AKAZE and ORB find; without it a plain face with a faint gradient (the paper's weakly textured object A)."""
    w, h = int(round(size[0] * pixels_per_metre)), int(round(size[1] * pixels_per_metre))
    if w < 16 or h < 16:
        raise ValueError(f"size: a label of {w}x{h} px is too small; give at least 16 px per side")
    img = printed_label(w, h, textured=textured, seed=seed)
    g = ReferenceImageGeometry(width=w, height=h, pixels_per_metre=pixels_per_metre,
                               origin_pixel=((w - 1) / 2.0, (h - 1) / 2.0), top_height=top_height)
    return TopLabel(img, g, textured)


def render_top_view(label: TopLabel, T_base_part: Any, T_base_camera: Any, intrinsics: Intrinsics = WEBCAM, *,
                    blur_sigma: float = 0.8, noise_sigma: float = 2.0, seed: int = 0) -> np.ndarray:
    """The (H, W) uint8 grey image the camera at ``T_base_camera`` (4x4, m) takes of the label of a part at
    ``T_base_part`` (upright, 4x4, m): the label warped by the exact homography onto a faintly textured table, a
    Gaussian blur of ``blur_sigma`` px and Gaussian noise of ``noise_sigma`` grey levels (``seed``)."""
    return render_labels([(label.image, label.geometry, T_base_part)], T_base_camera, intrinsics,
                         blur_sigma=blur_sigma, noise_sigma=noise_sigma, seed=seed)


#: RGB gains of the colour image (:func:`render_labels` with ``colour``): a warm wooden table top, and labels printed
#: in black on white paper (neutral).
TABLE_TINT: Tuple[float, float, float] = (1.0, 0.88, 0.72)
LABEL_TINT: Tuple[float, float, float] = (1.0, 1.0, 1.0)


def render_labels(labels: Sequence[Tuple[Any, Any, Any]], T_base_camera: Any, intrinsics: Intrinsics = WEBCAM, *,
                  blur_sigma: float = 0.8, noise_sigma: float = 2.0, seed: int = 0, colour: bool = False) -> np.ndarray:
    """As :func:`render_top_view` for several parts in one image: ``labels`` holds (reference image, its
    :class:`ReferenceImageGeometry`, ``T_base_part``) per part; a label nearer the camera covers one behind it. With
    ``colour`` an (H, W, 3) uint8 RGB image (the table tinted by :data:`TABLE_TINT`, the labels by
    :data:`LABEL_TINT`, the noise drawn per channel), else (H, W) grey."""
    cv2 = _cv2()
    rng = np.random.default_rng(seed)
    T_cam = np.asarray(T_base_camera, float)
    size = (intrinsics.width, intrinsics.height)
    table = rng.normal(110.0, 4.0, (intrinsics.height // 8 + 1, intrinsics.width // 8 + 1))
    table = cv2.resize(table, size, interpolation=cv2.INTER_CUBIC)  # a smooth, weakly textured table top
    tints = tuple(zip(TABLE_TINT, LABEL_TINT)) if colour else ((1.0, 1.0),)
    planes = [table * t for t, _ in tints]
    depth = lambda item: -float((np.linalg.inv(T_cam) @ np.asarray(item[2], float))[2, 3])  # noqa: E731
    for image, geometry, T_base_part in sorted(labels, key=depth):  # farthest first
        H = homography_of_part(geometry, intrinsics, T_cam, np.asarray(T_base_part, float))
        face = cv2.warpPerspective(np.asarray(image).astype(np.float64), H, size, flags=cv2.INTER_LINEAR)
        mask = cv2.warpPerspective(np.ones(np.shape(image)[:2], np.float64), H, size, flags=cv2.INTER_LINEAR)
        planes = [p * (1.0 - mask) + face * ink for p, (_, ink) in zip(planes, tints)]
    if blur_sigma > 0:
        planes = [cv2.GaussianBlur(p, (0, 0), blur_sigma) for p in planes]
    out = np.dstack(planes) if colour else planes[0]
    out = out + rng.normal(0.0, noise_sigma, out.shape)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
