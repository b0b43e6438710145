"""Printed top-face labels of the built-in parts, for the 2D step of the two-step pose (Kleppe et al., "Automated
assembly using 3D and 2D cameras", Robotics 6 (2017) 14, the thesis's Paper 3): a part file's ``reference_image``
may name ``"builtin:label-<seed>"`` (random shapes, lines and letters: SIFT, AKAZE and ORB find hundreds of keypoints)
``"builtin:sparse-<seed>"`` (twelve faint shapes and three words: a weakly textured face, as the paper's object A) or
``"builtin:plain"`` (a plain face with a faint gradient: nothing to match) instead of a file.
OpenCV draws them (``pip install opencv-python-headless``)."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

__all__ = ["printed_label", "builtin_label"]

_LETTERS = "ABCDEFGHJKLMNPRSTUVWXYZ0123456789"


def _cv2() -> Any:
    try:
        import cv2
    except ImportError as e:  # an optional dependency, as for the matching itself
        raise ImportError("the built-in labels are drawn with OpenCV: pip install opencv-python-headless") from e
    return cv2


def printed_label(width: int, height: int, *, textured: bool = True, seed: int = 0, sparse: bool = False) -> np.ndarray:
    """A (height, width) uint8 grey label: with ``textured`` 40 random shapes and lines, 12 three-letter words and a
    frame, fixed by ``seed``; with ``sparse`` too only 12 faint shapes and three words (a weakly textured face, as
    the paper's object A: a few dozen SIFT keypoints); without ``textured`` a plain face (grey 185..195, a gradient
    along u). ValueError: under 16 px."""
    if int(width) != width or int(height) != height or width < 16 or height < 16:
        raise ValueError(f"label size: expected integers of at least 16 px, got {width}x{height}")
    w, h = int(width), int(height)
    if not textured:
        return (185 + 10 * np.linspace(0, 1, w)[None, :] * np.ones((h, 1))).astype(np.uint8)
    cv2 = _cv2()
    rng = np.random.default_rng(seed)
    if sparse:
        return _sparse(cv2, rng, w, h)
    img = np.full((h, w), 200, np.uint8)
    for _ in range(40):
        kind, color = rng.integers(0, 3), int(rng.integers(0, 120))
        p = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        if kind == 0:
            cv2.circle(img, p, int(rng.integers(3, max(4, h // 6))), color, -1 if rng.random() < 0.5 else 2)
        elif kind == 1:
            q = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            cv2.rectangle(img, p, q, color, -1 if rng.random() < 0.3 else 2)
        else:
            q = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            cv2.line(img, p, q, color, int(rng.integers(1, 4)))
    for _ in range(12):
        text = "".join(rng.choice(list(_LETTERS), 3))
        org = (int(rng.integers(0, max(1, w - 20))), int(rng.integers(12, max(13, h))))
        cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, float(rng.uniform(0.4, 1.0)), int(rng.integers(0, 90)),
                    int(rng.integers(1, 3)), cv2.LINE_AA)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), 30, 3)
    return img


def _sparse(cv2: Any, rng: Any, w: int, h: int) -> np.ndarray:
    img = np.full((h, w), 190, np.uint8)
    for _ in range(12):
        p = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        color = int(rng.integers(100, 150))
        if rng.random() < 0.5:
            cv2.circle(img, p, int(rng.integers(max(3, h // 14), max(4, h // 7))), color,
                       -1 if rng.random() < 0.5 else 2)
        else:
            q = (p[0] + int(rng.integers(w // 12, w // 4)), p[1] + int(rng.integers(h // 12, h // 4)))
            cv2.rectangle(img, p, q, color, -1)
    for _ in range(3):
        word = "".join(rng.choice(list(_LETTERS), 2))
        org = (int(rng.integers(0, max(1, w - w // 3))), int(rng.integers(h // 4, h)))
        cv2.putText(img, word, org, cv2.FONT_HERSHEY_SIMPLEX, max(0.3, h / 250), 120, 1, cv2.LINE_AA)
    return img


def builtin_label(name: str, width: int, height: int) -> np.ndarray:
    """The label a part file names: ``"builtin:label-<seed>"`` (textured), ``"builtin:sparse-<seed>"`` (weakly
    textured) or ``"builtin:plain"``, ``width`` x ``height`` px. ValueError for another name."""
    if name == "builtin:plain":
        return printed_label(width, height, textured=False)
    if m := re.fullmatch(r"builtin:(label|sparse)-(\d{1,9})", name):
        return printed_label(width, height, seed=int(m.group(2)), sparse=m.group(1) == "sparse")
    raise ValueError(f"reference image {name!r}: the built-in labels are 'builtin:label-<seed>', "
                     "'builtin:sparse-<seed>' (a non-negative integer seed) and 'builtin:plain'")
