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
from typing import Any, Optional, Tuple

import numpy as np

from scanalign.pose.image_matching import ReferenceImageGeometry, homography_of_part
from scanalign.reconstruction.camera import Intrinsics

__all__ = ["WEBCAM", "TopLabel", "top_label", "render_top_view"]

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
    cv2 = _cv2()
    w, h = int(round(size[0] * pixels_per_metre)), int(round(size[1] * pixels_per_metre))
    if w < 16 or h < 16:
        raise ValueError(f"size: a label of {w}x{h} px is too small; give at least 16 px per side")
    rng = np.random.default_rng(seed)
    img = np.full((h, w), 200, np.uint8)
    if textured:
        for _ in range(40):
            kind = rng.integers(0, 3)
            color = int(rng.integers(0, 120))
            p = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            if kind == 0:
                cv2.circle(img, p, int(rng.integers(3, max(4, h // 6))), color, -1 if rng.random() < 0.5 else 2)
            elif kind == 1:
                q = (int(rng.integers(0, w)), int(rng.integers(0, h)))
                cv2.rectangle(img, p, q, color, -1 if rng.random() < 0.3 else 2)
            else:
                q = (int(rng.integers(0, w)), int(rng.integers(0, h)))
                cv2.line(img, p, q, color, int(rng.integers(1, 4)))
        letters = "ABCDEFGHJKLMNPRSTUVWXYZ0123456789"
        for _ in range(12):
            text = "".join(rng.choice(list(letters), 3))
            org = (int(rng.integers(0, w - 20)), int(rng.integers(12, h)))
            cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, float(rng.uniform(0.4, 1.0)), int(rng.integers(0, 90)),
                        int(rng.integers(1, 3)), cv2.LINE_AA)
        cv2.rectangle(img, (0, 0), (w - 1, h - 1), 30, 3)
    else:
        img = (185 + 10 * np.linspace(0, 1, w)[None, :] * np.ones((h, 1))).astype(np.uint8)
    g = ReferenceImageGeometry(width=w, height=h, pixels_per_metre=pixels_per_metre,
                               origin_pixel=((w - 1) / 2.0, (h - 1) / 2.0), top_height=top_height)
    return TopLabel(img, g, textured)


def render_top_view(label: TopLabel, T_base_part: Any, T_base_camera: Any, intrinsics: Intrinsics = WEBCAM, *,
                    blur_sigma: float = 0.8, noise_sigma: float = 2.0, seed: int = 0) -> np.ndarray:
    """The (H, W) uint8 grey image the camera at ``T_base_camera`` (4x4, m) takes of the label of a part at
    ``T_base_part`` (upright, 4x4, m): the label warped by the exact homography onto a faintly textured table, a
    Gaussian blur of ``blur_sigma`` px and Gaussian noise of ``noise_sigma`` grey levels (``seed``)."""
    cv2 = _cv2()
    rng = np.random.default_rng(seed)
    H = homography_of_part(label.geometry, intrinsics, np.asarray(T_base_camera, float), np.asarray(T_base_part, float))
    size = (intrinsics.width, intrinsics.height)
    table = rng.normal(110.0, 4.0, (intrinsics.height // 8 + 1, intrinsics.width // 8 + 1))
    out = cv2.resize(table, size, interpolation=cv2.INTER_CUBIC)  # a smooth, weakly textured table top
    face = cv2.warpPerspective(label.image.astype(np.float64), H, size, flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.ones(label.image.shape, np.float64), H, size, flags=cv2.INTER_LINEAR)
    out = out * (1.0 - mask) + face
    if blur_sigma > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur_sigma)
    out = out + rng.normal(0.0, noise_sigma, out.shape)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
