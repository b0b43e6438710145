"""The built-in parts (block, bracket, standoff): closed, outward, the documented sizes, and
their symmetry is what BUILTIN_PARTS says, checked against the analytic solids."""

import itertools
import math

import numpy as np
import pytest

from scanalign import _core
from scanalign.data import parts
from scanalign.evaluation.mesh_distance import point_to_mesh_distance


def _closed_and_outward(m):
    """Every directed edge once and its reverse once; returns (volume, area, centroid)."""
    e = np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]])
    directed = {tuple(x) for x in e.tolist()}
    assert len(directed) == len(e)
    assert all((b, a) in directed for a, b in directed)
    c = m.vertices[m.faces]
    six_v = np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2]))  # signed tetrahedra from the origin
    cross = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    assert np.all(np.linalg.norm(cross, axis=1) > 1e-12)  # no degenerate triangle
    centroid = (six_v[:, None] * c.sum(axis=1) / 4).sum(axis=0) / six_v.sum()
    return six_v.sum() / 6, np.linalg.norm(cross, axis=1).sum() / 2, centroid


def _polygon(n, r):
    """Area and perimeter of the inscribed n-gon of radius r (the mesh's exact cylinder section)."""
    return n / 2 * r * r * math.sin(2 * math.pi / n), 2 * n * r * math.sin(math.pi / n)


def test_builtin_parts_names_symmetries_and_the_default_is_the_block():
    assert list(parts.BUILTIN_PARTS) == ["block", "bracket", "standoff"]
    orders = {k: s.order for k, s in parts.BUILTIN_PARTS.items()}
    assert orders == {"block": 1, "bracket": 1, "standoff": 6}
    s = parts.BUILTIN_PARTS["standoff"]
    np.testing.assert_array_equal(s.axis, [0, 0, 1])
    np.testing.assert_array_equal(s.point, [0, 0, 0])
    a, b = parts.builtin_mesh(24), parts.builtin_mesh(segments=24, name="block")
    np.testing.assert_array_equal(a.vertices, b.vertices)
    with pytest.raises(ValueError, match="name"):
        parts.builtin_mesh(name="washer")
    with pytest.raises(ValueError, match="name"):
        _core.synthetic.builtin_part_mesh(24, "washer")
    with pytest.raises(ValueError, match="segments"):
        parts.builtin_mesh(4, name="standoff")


def test_bracket_is_closed_outward_and_has_the_documented_size():
    m = parts.builtin_mesh(name="bracket")
    volume, area, _ = _closed_and_outward(m)
    mm3, mm2 = 1e-9, 1e-6
    # base 70x40x6 + upright 6x40x34 above it + gusset (20x20/2) x 6
    assert volume == pytest.approx((70 * 40 * 6 + 6 * 40 * 34 + 200 * 6) * mm3, rel=1e-12)
    l_profile = 70 * 6 + 6 * 34
    l_perimeter = 2 * 70 + 2 * 40
    gusset_perimeter_change = 20 * math.sqrt(2) - 40  # the hypotenuse replaces the two legs
    # caps: the L at -y, the L + gusset at +y, the gusset's step face at y = 0.014
    expected_area = (2 * l_profile + 2 * 200 + 40 * l_perimeter + 6 * gusset_perimeter_change) * mm2
    assert area == pytest.approx(expected_area, rel=1e-12)
    np.testing.assert_allclose(m.vertices.min(0), [-0.035, -0.020, 0], atol=1e-15)
    np.testing.assert_allclose(m.vertices.max(0), [0.035, 0.020, 0.040], atol=1e-15)


@pytest.mark.parametrize("segments", [8, 24, 96])
def test_standoff_is_closed_outward_with_the_analytic_volume_and_area(segments):
    m = parts.builtin_mesh(segments, name="standoff")
    volume, area, centroid = _closed_and_outward(m)
    n = 6 * math.ceil(segments / 6)
    hex_area, hex_perimeter = 2 * math.sqrt(3) * 0.015**2, 6 * 0.030 / math.sqrt(3)
    stud_area, stud_perimeter = _polygon(n, 0.006)
    assert volume == pytest.approx(hex_area * 0.020 + stud_area * 0.015, rel=1e-12)
    # bottom + (top minus the stud's foot) + stud top = 2 hex areas
    assert area == pytest.approx(2 * hex_area + hex_perimeter * 0.020 + stud_perimeter * 0.015, rel=1e-12)
    assert volume == pytest.approx(hex_area * 0.020 + math.pi * 0.006**2 * 0.015, rel=5e-3)  # chord error
    np.testing.assert_allclose(centroid[:2], 0, atol=1e-12)  # on the symmetry axis
    np.testing.assert_allclose(m.vertices.min(0)[2], 0, atol=1e-15)
    np.testing.assert_allclose(m.vertices.max(0)[2], 0.035, atol=1e-15)


def _rotz(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_standoff_symmetry_is_6_fold_about_z_and_nothing_less():
    m = parts.builtin_mesh(name="standoff")
    for k in range(1, 6):
        d = point_to_mesh_distance(m.vertices @ _rotz(k * math.pi / 3).T, m.vertices, m.faces)
        assert d.max() < 1e-9, k
    for angle in (math.pi / 6, math.pi / 4, math.pi / 2):  # not a multiple of 60°: a corner lands off
        d = point_to_mesh_distance(m.vertices @ _rotz(angle).T, m.vertices, m.faces)
        assert d.max() > 1e-3, angle
    flip = np.diag([1.0, -1.0, -1.0])  # upside down about x through the centroid: the stud moves
    _, _, c = _closed_and_outward(m)
    d = point_to_mesh_distance((m.vertices - c) @ flip.T + c, m.vertices, m.faces)
    assert d.max() > 1e-3


def test_bracket_has_no_symmetry_under_any_axis_permutation_or_mirror():
    m = parts.builtin_mesh(name="bracket")
    _, _, c = _closed_and_outward(m)  # a symmetry would keep the volume centroid fixed
    tested = 0
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            M = np.zeros((3, 3))
            M[range(3), perm] = signs
            if np.allclose(M, np.eye(3)):
                continue
            d = point_to_mesh_distance((m.vertices - c) @ M.T + c, m.vertices, m.faces)
            assert d.max() > 1e-3, (perm, signs)
            tested += 1
    for angle in (math.pi / 3, 2 * math.pi / 3):
        d = point_to_mesh_distance((m.vertices - c) @ _rotz(angle).T + c, m.vertices, m.faces)
        assert d.max() > 1e-3
    assert tested == 47
