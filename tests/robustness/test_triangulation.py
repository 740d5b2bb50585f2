"""Concave polygon faces are triangulated inside the polygon (a fan from the first corner covered area
outside an L-shaped hexagon, depending on which corner came first)."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.ir.geometry import triangulate_polygons

L_SHAPE = np.array([[1, 1], [1, 2], [0, 2], [0, 0], [2, 0], [2, 1]], float)  # area 3, one reflex corner


def _area(v2: np.ndarray, tris: np.ndarray) -> float:
    a, b, c = v2[tris[:, 0]], v2[tris[:, 1]], v2[tris[:, 2]]
    return float(np.abs(np.cross(b - a, c - a)).sum() / 2)


def _signed(v2: np.ndarray, tris: np.ndarray) -> np.ndarray:
    a, b, c = v2[tris[:, 0]], v2[tris[:, 1]], v2[tris[:, 2]]
    return np.cross(b - a, c - a)


@pytest.mark.parametrize("start", range(6))
@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("ragged", [False, True])
def test_concave_polygon_is_covered_exactly(start, reverse, ragged):
    """An L-shaped hexagon from any start corner, either winding: 4 triangles of total area 3, same winding."""
    poly = np.roll(np.arange(6), -start)
    if reverse:
        poly = poly[::-1]
    v3 = np.c_[L_SHAPE, np.zeros(6)]
    faces = [poly, np.array([0, 3, 4])] if ragged else poly[None]
    tris, pidx, corner = triangulate_polygons(faces, v3)
    mine = tris[pidx == 0]
    assert len(mine) == 4
    assert _area(L_SHAPE, mine) == pytest.approx(3.0), "triangles cover area outside the polygon"
    signs = np.sign(_signed(L_SHAPE, mine))
    assert (signs == (-1 if reverse else 1)).all(), "winding changed"
    for t, p, c in zip(tris, pidx, corner, strict=True):
        assert np.array_equal(np.asarray(faces[p])[c], t)  # corners index back into the polygon


def test_convex_polygons_keep_the_fan():
    """Convex polygons are triangulated as before (fan from the first corner)."""
    v3 = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    tris, _, _ = triangulate_polygons(np.array([[0, 1, 2, 3]]), v3)
    assert tris.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_mesh_with_a_concave_face_has_the_polygon_area():
    """Mesh(faces=[concave polygon]) triangles cover exactly the polygon."""
    scene = bf.Scene()
    poly = np.roll(np.arange(6), -1)
    mesh = scene.renderables.add_mesh(
        np.c_[L_SHAPE, np.zeros(6)], [poly], bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="L"
    )
    assert _area(L_SHAPE, np.asarray(mesh.faces)) == pytest.approx(3.0)


def test_huge_concave_polygon_keeps_the_fan_with_a_warning():
    """A concave polygon of more than MAX_EAR_CLIP_CORNERS corners is not ear-clipped (that would take
    minutes): fan triangles and a warning naming the face, immediately."""
    from blendify_core.ir.geometry import MAX_EAR_CLIP_CORNERS

    k = MAX_EAR_CLIP_CORNERS + 2
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    r = np.where(np.arange(k) % 2, 0.5, 1.0)  # a star: every other corner is reflex
    v = np.c_[r * np.cos(t), r * np.sin(t), np.zeros(k)]
    with pytest.warns(UserWarning, match=r"faces\[0\]: concave polygon"):
        tris, _, _ = triangulate_polygons([np.arange(k)], v)
    assert len(tris) == k - 2 and (tris[:, 0] == 0).all()


@pytest.mark.parametrize("reflex_corner", range(4))
def test_concave_quads_are_split_through_their_reflex_corner(reflex_corner):
    """Dart-shaped quads (M, 4), vectorised: the diagonal goes through the reflex corner."""
    dart = np.array([[0, 0], [2, 1], [0, 2], [0.5, 1]], float)  # reflex at corner 3, area 1.5
    quad = np.roll(np.arange(4), -((3 - reflex_corner) % 4))
    v3 = np.c_[dart, np.zeros(4)]
    tris, _, corner = triangulate_polygons(np.array([quad, quad]), v3)
    assert _area(dart, tris[:2]) == pytest.approx(1.5) and _area(dart, tris[2:]) == pytest.approx(1.5)
    assert (np.sign(_signed(dart, tris)) == 1).all()
    assert np.array_equal(np.repeat(np.array([quad, quad]), 2, axis=0)[np.arange(4)[:, None], corner], tris)


def test_a_million_random_quads():
    """1M random (often folded) quads go through the vectorised path: 2 triangles each, every quad
    covered with its own corners (~1 s; a Python loop per concave quad took minutes)."""
    rng = np.random.default_rng(0)
    m = 1_000_000
    v = rng.normal(size=(4 * m, 3))
    faces = np.arange(4 * m).reshape(m, 4)
    tris, poly, _ = triangulate_polygons(faces, v)
    assert len(tris) == 2 * m
    assert (tris // 4 == poly[:, None]).all()
