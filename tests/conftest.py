"""Shared pytest configuration and real-data fixtures."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Tuple

import numpy as np
import pytest


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "data: needs the real test data (Debian packages fetched by scanalign.data.downloads; "
        "deselect with -m 'not data')",
    )


@pytest.fixture(scope="session")
def dataset_cache() -> Path:
    """Fetch the data packages once per session; skip the test if they are unavailable."""
    from scanalign.data import downloads as datasets

    try:
        datasets.fetch_all()
    except datasets.DatasetUnavailableError as exc:
        # In CI the README's test command fetches the data first: a failure there is an
        # error, not a reason to pass silently.
        if os.environ.get("CI") or os.environ.get("SCANALIGN_REQUIRE_DATA"):
            pytest.fail(f"test data unavailable: {exc}")
        pytest.skip(f"test data unavailable: {exc}")
    return datasets.cache_dir()


def _surface(name: str, n_points: int, seed: int) -> Tuple[np.ndarray, np.ndarray]:
    """A CGAL demo mesh scaled to 15 cm and placed 50 cm in front of a camera at the
    origin, sampled area-uniformly with exact face normals (metres)."""
    from scanalign.data import downloads as datasets
    from scanalign.data import parts

    mesh = datasets.load_cgal_mesh(name)
    v = mesh.vertices - mesh.vertices.mean(axis=0)
    v = v * (0.15 / np.ptp(v, axis=0).max()) + np.array([0.0, 0.0, 0.5])
    points, normals = parts.sample_mesh((v, mesh.faces), n_points, seed=seed)
    return points, normals


@pytest.fixture(scope="session")
def bunny(dataset_cache: Path) -> Tuple[np.ndarray, np.ndarray]:
    """The Stanford bunny (CGAL's bunny00.off), 30k points with normals, metres."""
    return _surface("bunny00", 30000, seed=1)


@pytest.fixture(scope="session")
def fandisk(dataset_cache: Path) -> Tuple[np.ndarray, np.ndarray]:
    """CGAL's fandisk mechanical part, 30k points with normals, metres."""
    return _surface("fandisk", 30000, seed=2)
