"""Point cloud -> textured mesh: the UV atlas has no bleeding, texture colours match the points."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.utils.meshify import (
    MeshifyResult,
    add_meshified,
    atlas_texel_faces,
    atlas_uv,
    bake_texture,
    meshify_pointcloud,
    sample_texture,
)
from blendify_core.utils.normals import closest_points_on_mesh


def _bilinear_taps(uv, size):
    x = uv[:, 0] * size - 0.5
    y = (1.0 - uv[:, 1]) * size - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    taps = []
    for dy in (0, 1):
        for dx in (0, 1):
            taps.append((np.clip(y0 + dy, 0, size - 1), np.clip(x0 + dx, 0, size - 1)))
    return taps


@pytest.mark.parametrize("n_faces, texture_size", [(1, None), (7, None), (200, 256), (5000, None)])
def test_atlas_gutters_keep_bilinear_lookups_inside_their_triangle(rng, n_faces, texture_size):
    uv, size, cell = atlas_uv(n_faces, texture_size)
    assert uv.shape == (n_faces, 3, 2) and uv.dtype == np.float32
    assert uv.min() >= 0 and uv.max() <= 1
    owner = atlas_texel_faces(n_faces, size, cell)
    # random points inside every triangle, including its corners and edges
    bary = rng.dirichlet((0.3, 0.3, 0.3), size=(n_faces, 8))
    bary[:, 0] = (1, 0, 0)
    bary[:, 1] = (0.5, 0.5, 0)
    pts = np.einsum("fsk,fkc->fsc", bary, uv.astype(np.float64)).reshape(-1, 2)
    face = np.repeat(np.arange(n_faces), 8)
    for r, c in _bilinear_taps(pts, size):
        assert np.all(owner[r, c] == face)


def test_atlas_rejects_a_too_small_texture():
    with pytest.raises(bf.InvalidSceneError, match="texture_size"):
        atlas_uv(10_000, 64)


def test_baked_texture_has_no_colour_bleeding_between_triangles(rng):
    # 50 disconnected triangles far apart, each covered by points of one random colour
    n = 50
    centres = rng.uniform(-100, 100, size=(n, 3))
    base = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    verts = (centres[:, None, :] + base[None]).reshape(-1, 3)
    faces = np.arange(3 * n).reshape(n, 3)
    w = rng.dirichlet((1, 1, 1), size=(n, 30))
    pts = np.einsum("fsk,fkc->fsc", w, verts[faces]).reshape(-1, 3)
    face_col = rng.uniform(0, 1, size=(n, 3))
    cols = np.repeat(face_col, 30, axis=0)
    uv, size, cell = atlas_uv(n)
    tex = bake_texture(verts, faces, pts, cols, size, cell, knn=3)
    bary = rng.dirichlet((0.2, 0.2, 0.2), size=(n, 20))
    bary[:, 0] = (0, 0, 1)
    q = np.einsum("fsk,fkc->fsc", bary, uv.astype(np.float64)).reshape(-1, 2)
    got = sample_texture(tex, q).reshape(n, 20, 3)
    np.testing.assert_allclose(got, np.repeat(face_col[:, None], 20, axis=1), atol=1e-9)


def test_sample_texture_convention():
    tex = np.zeros((2, 2, 1))
    tex[0, 0] = 1.0  # top-left texel
    np.testing.assert_allclose(sample_texture(tex, np.array([[0.25, 0.75], [0.75, 0.25]])), [[1.0], [0.0]])


def test_missing_open3d_gives_a_clear_error(monkeypatch, rng):
    monkeypatch.setitem(sys.modules, "open3d", None)
    with pytest.raises(bf.BackendUnavailableError, match="pip install open3d"):
        meshify_pointcloud(rng.normal(size=(100, 3)), rng.uniform(size=(100, 3)))


def test_bad_arguments(rng):
    p = rng.normal(size=(50, 3))
    with pytest.raises(bf.InvalidSceneError, match="colors"):
        meshify_pointcloud(p, np.zeros((49, 3)))
    with pytest.raises(bf.InvalidSceneError, match="method"):
        meshify_pointcloud(p, np.zeros((50, 3)), method="alpha_shape")
    with pytest.raises(bf.InvalidSceneError, match="points"):
        meshify_pointcloud(p[:3], np.zeros((3, 3)))
    with pytest.raises(bf.InvalidSceneError, match="target_faces"):
        meshify_pointcloud(p, np.zeros((50, 3)), target_faces=1)
    with pytest.raises(bf.InvalidSceneError, match="colors"):
        meshify_pointcloud(p, np.full((50, 3), 2.0))


def _sphere_cloud(rng, n=6000):
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    cols = 0.5 + 0.4 * np.stack([p[:, 0], p[:, 1] * p[:, 2], np.sin(2 * p[:, 2])], axis=1)
    return p, cols


def _texture_error(res: MeshifyResult, pts, cols):
    fid, bary, dist = closest_points_on_mesh(pts, res.vertices, res.faces.astype(np.int64))
    uv = np.einsum("nk,nkc->nc", bary, res.faces_uv[fid].astype(np.float64))
    got = sample_texture(res.texture, uv) / 255.0
    return np.abs(got - cols).mean(), np.sqrt(dist).max()


@pytest.mark.parametrize("method", ["ball_pivoting", "poisson"])
def test_meshify_sphere_with_open3d(open3d, rng, method):
    pts, cols = _sphere_cloud(rng)
    res = meshify_pointcloud(pts, cols, target_faces=3000, method=method)
    assert 0 < len(res.faces) <= 3000 and res.faces.dtype == np.int32
    assert res.texture.dtype == np.uint8 and res.texture.shape[2] == 3
    assert res.faces_uv.shape == (len(res.faces), 3, 2)
    np.testing.assert_allclose(np.linalg.norm(res.vertices, axis=1), 1.0, atol=0.05)
    mae, far = _texture_error(res, pts, cols)
    assert mae < 0.02, mae  # < 5 sRGB levels on average
    assert far < 0.15  # points over holes or decimated curvature
    assert set(res.timings) >= {"normals", "reconstruct", "simplify", "uv_atlas", "texture", "total"}
    scene = bf.Scene()
    mesh = add_meshified(scene, res, tag="meshified")
    assert isinstance(mesh, bf.Mesh) and len(scene.renderables) == 1
    assert isinstance(mesh.colors, bf.TextureColors) and isinstance(mesh.colors.uv_map, bf.FacesUV)


def test_meshify_uint8_colours_and_given_normals(open3d, rng):
    pts, cols = _sphere_cloud(rng, 3000)
    res = meshify_pointcloud(
        pts, np.round(cols * 255).astype(np.uint8), normals=pts, target_faces=None, texture_size=1024
    )
    assert res.texture.shape[:2] == (1024, 1024)
    mae, _ = _texture_error(res, pts, cols)
    assert mae < 0.02


def test_implicit_method_needs_no_open3d(monkeypatch, rng, tmp_path):
    """The dependency-free path: narrow-band signed distance + marching tetrahedra + vertex clustering."""
    monkeypatch.setitem(sys.modules, "open3d", None)
    pts, cols = _sphere_cloud(rng, 4000)
    res = meshify_pointcloud(pts, cols, method="implicit", target_faces=4000)
    assert 0 < len(res.faces) <= 4000
    assert res.info["simplification"] == "vertex clustering (no Open3D)"
    np.testing.assert_allclose(np.linalg.norm(res.vertices, axis=1), 1.0, atol=0.06)
    mae, far = _texture_error(res, pts, cols)
    assert mae < 0.02 and far < 0.1
    # closed, consistently oriented outwards: positive signed volume of about 4/3 pi
    v, f = res.vertices, res.faces
    volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0
    assert volume == pytest.approx(4 / 3 * np.pi, rel=0.1)
    res.save(tmp_path / "out")
    assert {p.name for p in (tmp_path / "out").iterdir()} == {"mesh.ply", "texture.png", "faces_uv.npy"}
    np.testing.assert_array_equal(np.load(tmp_path / "out" / "faces_uv.npy"), res.faces_uv)


def test_marching_tetrahedra_plane_is_connected_and_oriented():
    from blendify_core.utils._implicit import marching_tetrahedra

    z = np.arange(6) - 2.5
    values = np.broadcast_to(z[None, None, :], (5, 5, 6)).astype(float)  # plane z = 0 (grid units)
    verts, faces = marching_tetrahedra(values, np.ones(values.shape, bool), np.zeros(3), 1.0)
    np.testing.assert_allclose(verts[:, 2], 2.5)
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    assert np.all(fn[:, 2] > 0)  # towards positive values
    assert len(verts) == len(np.unique(np.round(verts, 9), axis=0))  # shared vertices, no duplicates
    area = 0.5 * np.linalg.norm(fn, axis=1).sum()
    assert area == pytest.approx(16.0)  # the 4 x 4 grid cells, exactly covered


def test_given_texture_size_is_exact_and_the_remainder_is_unused():
    uv, size, cell = atlas_uv(200, 257)
    assert size == 257 and cell == 25  # 10 x 10 cells of 25 texels, 7 texels left over
    owner = atlas_texel_faces(200, size, cell)
    assert np.all(owner[:7, :] == -1) and np.all(owner[:, 250:] == -1)  # top rows and right columns
    assert set(np.unique(owner)) == set(range(-1, 200))


def test_poisson_trims_the_surface_it_invents(open3d, rng):
    pts, cols = _sphere_cloud(rng, 6000)
    upper = pts[:, 2] > 0.0  # an open hemisphere: Poisson closes it with a made-up surface
    res = meshify_pointcloud(pts[upper], cols[upper], method="poisson", target_faces=None)
    assert res.vertices[:, 2].min() > -0.1
    assert res.info["vertices_trimmed"] > 0
    kept = meshify_pointcloud(pts[upper], cols[upper], method="poisson", target_faces=None, trim_distance=0)
    assert kept.vertices[:, 2].min() < -0.3
    with pytest.raises(bf.InvalidSceneError, match="trim_distance"):
        meshify_pointcloud(pts, cols, method="poisson", trim_distance=-1)
