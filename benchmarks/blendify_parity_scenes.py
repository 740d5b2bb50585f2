"""The scenes of the blendify 2.1 parity benchmark, written once as data (numbers only) so that the blendify 2.1
side (``blendify_parity_reference.py``, run in a separate environment with ``blendify==2.1.0``) and the
blendify-core side (``blendify_parity.py``) build the same thing, each through its own API.

Every scene here is asset-free: the examples of blendify 2.1 that read its own assets (the Cornell box and
light box .blend files, knot/lucy/bunny/donut meshes) are not redistributable here. Each scene re-creates
what one blendify example or README snippet exercises (listed in ``what``): the same kinds of objects,
materials, colours, lights and camera conventions, with procedural geometry instead of the asset.

This module imports numpy only (it is read by both environments).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

#: image size and samples of every parity render (blendify 2.1's render default is 128 spp)
RESOLUTION = (200, 150)
SAMPLES = 128


def _midpoint(verts: list[np.ndarray], cache: dict[tuple[int, int], int], a: int, b: int) -> int:
    """Index of the unit-sphere point between vertices a and b (added once)."""
    key = (min(a, b), max(a, b))
    if key not in cache:
        m = verts[a] + verts[b]
        verts.append(m / np.linalg.norm(m))
        cache[key] = len(verts) - 1
    return cache[key]


def icosphere(subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere (vertices, triangles): the procedural stand-in for a scanned mesh."""
    t = (1.0 + 5**0.5) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]  # fmt: skip
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]  # fmt: skip
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = f
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}
        new = []
        for a, b, c in faces:
            ab, bc, ca = (_midpoint(verts, cache, i, j) for i, j in ((a, b), (b, c), (c, a)))
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = new
    return np.array(verts), np.array(faces, dtype=np.int64)


def bumpy_blob() -> tuple[np.ndarray, np.ndarray]:
    """A lumpy closed mesh (icosphere with a smooth radial bump field), about 1 m across."""
    v, f = icosphere(3)
    r = 1.0 + 0.15 * np.sin(3 * v[:, 0]) * np.cos(4 * v[:, 1]) + 0.1 * np.sin(5 * v[:, 2])
    return v * r[:, None] * 0.5, f


def checker(size: int = 64, cells: int = 8) -> np.ndarray:
    """(size, size, 3) uint8 texture: two-colour checker with a red border row at the top (row 0)."""
    y, x = np.mgrid[0:size, 0:size]
    on = ((x * cells // size) + (y * cells // size)) % 2 == 0
    tex = np.where(on[..., None], np.array([230, 200, 60], np.uint8), np.array([40, 90, 170], np.uint8))
    tex[:4] = (200, 30, 30)
    return tex.astype(np.uint8)


def quad_grid(n: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A wavy 2 x 2 m sheet of n x n quads (vertices, quad faces, per-vertex UVs)."""
    s = np.linspace(-1, 1, n + 1)
    X, Y = np.meshgrid(s, s)
    Z = 0.15 * np.sin(2.5 * X) * np.cos(2.0 * Y)
    v = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    faces = np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], axis=1)
    uv = np.stack([(X.ravel() + 1) / 2, (Y.ravel() + 1) / 2], axis=1)
    return v, faces, uv


def spiral_points(n: int = 1500) -> tuple[np.ndarray, np.ndarray]:
    """A point cloud on a twisted band with rainbow sRGB colours (N, 3) and (N, 3) in [0, 1]."""
    rng = np.random.default_rng(21)
    t = rng.uniform(0, 4 * np.pi, n)
    w = rng.uniform(-0.25, 0.25, n)
    pts = np.stack([(1 + w * np.cos(t / 2)) * np.cos(t) * 0.8, (1 + w * np.cos(t / 2)) * np.sin(t) * 0.8,
                    w * np.sin(t / 2) + 0.1 * t - 0.6], axis=1)  # fmt: skip
    hue = t / (4 * np.pi)
    cols = np.stack([0.5 + 0.5 * np.cos(2 * np.pi * (hue + k / 3)) for k in range(3)], axis=1)
    return pts, cols


#: name -> what the scene reproduces (the blendify example it stands for)
SCENES = {
    "readme_cube": "README example: cube, Principled default, point light, quaternion camera",
    "nurbs_primitives": "example 06: NURBS sphere, curve tube, circle and cylinder primitives, sun",
    "materials_catcher": "example 07: Plastic / Metal / Plastic-wireframe presets on a mesh, shadow catcher, "
    "point + spot + background light, look_at camera",
    "cornell_primitives": "example 01 without its .blend: plane walls, square area light, glass and metallic "
    "NURBS spheres, Glossy cylinder, metallic circle",
    "textured_sheet": "example 03: mesh with VertexUV + TextureColors (uint8), sun",
    "pointcloud": "example 04: point cloud with VertexColors, point lights",
}


#: blendify 2.1's own examples, run on its assets: read from the project's third-party cache folder
#: ($BLENDIFY_THIRD_PARTY_DIR, tests/third_party/SOURCES.md), skipped with the reason when absent.
#: name -> (asset path relative to the cache, what, resolution)
ASSET_SCENES = {
    "ex01_cornell_box": (
        "scenes/blendify/cornell_box.blend",
        "example 01 itself: attach_blend of its Cornell box, glass / metal spheres (coat_ior 0.2, 0.8), Glossy "
        "cylinder, metal circle, area light, denoised",
        (160, 160),
    ),
    "ex07_materials": (
        "scenes/blendify/lucy.ply",
        "example 07 itself: Lucy x3 (Plastic, Metal, Plastic wireframe), shadow catcher, point + spot + "
        "background light, camera look_at a mesh",
        (240, 135),
    ),
}


def asset_path(relative: str) -> Path | None:
    """The cached asset, or None when $BLENDIFY_THIRD_PARTY_DIR is unset or lacks it."""
    cache = os.environ.get("BLENDIFY_THIRD_PARTY_DIR")
    if not cache or not (Path(cache) / relative).is_file():
        return None
    return Path(cache) / relative
