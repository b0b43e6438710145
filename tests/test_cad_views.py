"""Viewpoint sampling of a CAD model (Kleppe, PhD thesis, NTNU 2018, §7.3)."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import evaluation
from scanalign.pose import model_views as cad
from scanalign.data import parts


@pytest.mark.parametrize("level,nv,nf", [(0, 12, 20), (1, 42, 80), (2, 162, 320)])
def test_tessellated_sphere_counts_and_closure(level, nv, nf):  # §7.3: the 42 views
    V, F = cad.tessellated_sphere(level)
    assert V.shape == (nv, 3) and F.shape == (nf, 3)
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 1.0, atol=1e-15)
    edges = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2) and nv - len(counts) + nf == 2  # closed, Euler characteristic 2
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n, V[F].mean(axis=1)) > 0)  # wound outwards


def test_views_lie_on_the_surface_face_their_camera_and_cover_the_part():
    mesh = parts.builtin_mesh()
    views = cad.render_views(mesh, resolution=120)
    assert len(views) == 42
    index = evaluation.MeshDistanceIndex(mesh.vertices, mesh.faces)
    allpts = []
    for v in views:
        assert len(v) > 1000
        assert index.distance(v.points).max() < 1e-6  # exact depth: on the true surface
        pc = v.points_in_camera()
        assert np.all(pc[:, 2] > 0)
        u = v.intrinsics.fx * pc[:, 0] / pc[:, 2] + v.intrinsics.cx
        np.testing.assert_allclose(u, v.pixels[:, 0], atol=1e-3)  # back-projection inverts projection
        assert np.all(np.einsum("ij,ij->i", v.normals, v.viewpoint - v.points) > 0)  # normals towards the camera
        allpts.append(v.points)
    # every part of the surface is seen by some view: surface samples near a view point
    from scipy.spatial import cKDTree
    from scanalign.data.parts import sample_mesh

    samples, _ = sample_mesh(mesh, 3000, seed=1)
    d, _ = cKDTree(np.vstack(allpts)).query(samples)
    assert np.mean(d < 2e-3) > 0.97


def test_bad_input():
    with pytest.raises(ValueError):
        cad.tessellated_sphere(-1)
    with pytest.raises(ValueError):
        cad.view_intrinsics(1)
    with pytest.raises(ValueError):
        cad.render_views((np.zeros((3, 3)), np.array([[0, 1, 2]])))  # all vertices coincide
    with pytest.raises(ValueError):
        cad.render_views((np.full((3, 3), np.nan), np.array([[0, 1, 2]])))
    with pytest.raises(TypeError):
        cad.render_views("not a mesh")
