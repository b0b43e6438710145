"""Recordings as sequences of frames: :func:`open_source` opens every recording a command, a
batch job or a pipeline reads."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

from scanalign import synthetic
from scanalign.datasets.sources import BagSequence, ImageFolderSequence, is_bag, is_image_folder
from scanalign.datasets.tum import PathLike, TumSequence, is_tum_folder, write_tum_sequence

__all__ = ["BagSequence", "ImageFolderSequence", "TumSequence", "is_bag", "is_image_folder", "is_tum_folder",
           "is_recording", "open_source", "write_tum_sequence", "SYNTHETIC_SUFFIXES"]

#: Suffixes of synthetic-scan config files (:class:`scanalign.synthetic.SyntheticConfig`).
SYNTHETIC_SUFFIXES = (".json", ".yaml", ".yml")
_READERS = ((is_tum_folder, TumSequence), (is_bag, BagSequence), (is_image_folder, ImageFolderSequence))


def is_recording(path: Any) -> bool:
    """True for a TUM RGB-D folder, a ROS bag or an image folder."""
    return any(test(path) for test, _ in _READERS)


def open_source(source: PathLike, *, synthetic_overrides: Optional[dict] = None, **options: Any):
    """The frames of ``source``:

    - a TUM RGB-D folder (``depth.txt``): a :class:`TumSequence`;
    - a ROS 1 ``.bag``, a ROS 2 bag folder, ``.mcap`` or ``.db3``: a :class:`BagSequence`;
    - a folder with ``depth/*.png`` and a camera file: an :class:`ImageFolderSequence`;
    - ``"builtin"`` or a synthetic-scan config (``.json`` / ``.yaml``): the rendered
      :class:`scanalign.synthetic.SyntheticScan` (its ``frames``, exact ``reference`` and
      ``mesh``), with ``synthetic_overrides`` (:class:`scanalign.synthetic.SyntheticConfig`
      fields, e.g. ``n_frames``, ``noise``, ``seed``, ``robot``) applied to the config.

    ``options`` go to the recording's class (``intrinsics``, ``depth_scale``, ``start``,
    ``stride``, ``limit`` are common to all three; None values are left out).

    Raises:
        FileNotFoundError: no such path. ValueError: a path that is none of these, or a
        malformed recording (naming the file). ImportError: a bag without ``rosbags``.
    """
    options = {k: v for k, v in options.items() if v is not None}
    given = {k: v for k, v in (synthetic_overrides or {}).items() if v is not None}
    if str(source) == "builtin":
        return synthetic.SyntheticConfig(**given).build()
    p = Path(source)
    if p.is_file() and p.suffix.lower() in SYNTHETIC_SUFFIXES:
        config = synthetic.SyntheticConfig.from_file(p)
        return (synthetic.SyntheticConfig(**{**config.to_dict(), **given}) if given else config).build()
    for test, reader in _READERS:
        if test(p):
            return reader(p, **options)
    if not p.exists():
        raise FileNotFoundError(f"{source}: no such folder or file")
    raise ValueError(f"{source}: not a recording: expected a TUM RGB-D folder (depth.txt), a ROS bag (.bag, .mcap, "
                     ".db3 or a ROS 2 bag folder with metadata.yaml), a folder of depth/*.png with a camera file, a "
                     "synthetic config (.json/.yaml) or 'builtin'")
