"""Point cloud -> textured triangle mesh (blendify's ``PCMeshifier``, re-done).

Pipeline: normals (:func:`estimate_normals` when not given) -> surface reconstruction with Open3D
(ball pivoting as in the blendify paper, or screened Poisson) -> quadric decimation to a face budget ->
a per-triangle UV atlas (two triangles per square cell of a grid, with gutters so bilinear filtering never
mixes two triangles) -> texture: each texel's 3D point on its triangle gets the inverse-distance-weighted
colour of its k nearest input points (scipy KD-tree, vectorised; every texel of the atlas is filled, so
there is nothing to bleed). Open3D is an optional extra (``pip install open3d``, imported lazily).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import FacesUV, TextureColors
from blendify_core.ir.materials import DiffuseMaterial
from blendify_core.ir.validate import as_array, as_float, strict_api, strict_arguments
from blendify_core.utils._implicit import cluster_simplify, marching_tetrahedra, signed_distance_grid
from blendify_core.utils.normals import _points, estimate_normals

__all__ = [
    "MeshifyResult",
    "meshify_pointcloud",
    "add_meshified",
    "atlas_uv",
    "atlas_texel_faces",
    "bake_texture",
    "sample_texture",
]

METHODS = ("ball_pivoting", "poisson", "implicit")
_MARGIN = 1.0  # texels between a triangle and its cell border
_GAP = 2.0  # half-gap (in u+v texel units) between the two triangles of a cell: bilinear taps stay inside


@strict_api
@dataclass
class MeshifyResult:
    """A textured mesh ready for :meth:`RenderablesCollection.add_mesh`.

    ``vertices`` (V, 3) float64, ``faces`` (F, 3) int32, ``faces_uv`` (F, 3, 2) float32 (UV (0, 0) =
    bottom-left), ``texture`` (H, W, 3) uint8 (row 0 = top) in ``color_space`` (that of the input colours),
    ``timings`` in seconds per stage, ``info`` (radii, face counts, texels per cell...)."""

    vertices: np.ndarray
    faces: np.ndarray
    faces_uv: np.ndarray
    texture: np.ndarray
    color_space: str = "srgb"
    timings: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def colors(self) -> Any:
        """The mesh's colour source: :class:`TextureColors` with a :class:`FacesUV` map."""
        return TextureColors(self.texture, FacesUV(self.faces_uv), color_space=self.color_space)

    def add_to(self, scene: Any, material: Any = None, **kwargs: Any) -> Any:
        """Add the mesh to ``scene`` (default material: a diffuse one); returns the IR Mesh."""
        return add_meshified(scene, self, material, **kwargs)

    def save(self, folder: Any) -> None:
        """Write ``mesh.ply`` (trimesh), ``texture.png`` and ``faces_uv.npy`` into ``folder``."""
        from pathlib import Path

        import trimesh
        from PIL import Image

        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        trimesh.Trimesh(self.vertices, self.faces, process=False).export(out / "mesh.ply")
        Image.fromarray(self.texture).save(out / "texture.png")
        np.save(out / "faces_uv.npy", self.faces_uv)


@strict_arguments
def add_meshified(scene: Any, result: MeshifyResult, material: Any = None, **kwargs: Any) -> Any:
    """Add a :class:`MeshifyResult` to ``scene`` as a textured mesh (kwargs: tag, translation, ...)."""
    if not isinstance(result, MeshifyResult):
        raise InvalidSceneError(f"result: expected a MeshifyResult from meshify_pointcloud, got {_describe(result)}")
    material = DiffuseMaterial() if material is None else material
    return scene.renderables.add_mesh(result.vertices, result.faces, material, result.colors(), **kwargs)


# -------------------------------------------------------------------------------------------------
# UV atlas and texture baking (pure numpy/scipy)
# -------------------------------------------------------------------------------------------------


def _grid(n_faces: int) -> int:
    """Cells per side of the atlas grid (two triangles per cell)."""
    return int(np.ceil(np.sqrt(max(1, (n_faces + 1) // 2))))


def _atlas_layout(n_faces: int, texture_size: int | None, cell: int | None) -> tuple[int, int, int]:
    """(grid columns G, cell size in texels c, texture size: ``texture_size`` or G*c)."""
    grid = _grid(n_faces)
    if texture_size is None:
        c = 8 if cell is None else int(cell)
    else:
        c = int(texture_size) // grid
    if c < 6:
        raise InvalidSceneError(
            f"texture_size: {texture_size} texels across is too small for {n_faces} faces (each pair of "
            f"triangles needs a cell of at least 6x6 texels; use texture_size >= {6 * grid} or fewer faces)"
        )
    return grid, c, grid * c if texture_size is None else int(texture_size)


def _local_corners(c: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Corners (3, 2) of the lower (A) and upper (B) triangle of a c x c cell, and the leg length."""
    m, d = _MARGIN, _GAP
    leg = c - d - 2 * m
    a = np.array([[m, m], [m + leg, m], [m, m + leg]])
    b = np.array([[c - m, c - m], [c - m - leg, c - m], [c - m, c - m - leg]])
    return a, b, leg


def atlas_uv(n_faces: int, texture_size: int | None = None, cell: int | None = None) -> tuple[np.ndarray, int, int]:
    """Per-triangle UV atlas: (F, 3, 2) float32 UVs, the texture size (square) and the cell size.

    Triangle 2k is the lower-left half of cell k, triangle 2k+1 the upper-right half, both inset by a
    1-texel margin and separated by a gutter so a bilinear lookup inside one triangle only reads texels
    that belong to it."""
    grid, c, size = _atlas_layout(n_faces, texture_size, cell)
    a, b, _ = _local_corners(c)
    k = np.arange(n_faces)
    cellidx = k // 2
    cx, cy = cellidx % grid, cellidx // grid  # cy counts from the bottom
    local = np.where((k % 2 == 0)[:, None, None], a[None], b[None])  # (F, 3, 2) texel units
    st = local + np.stack([cx * c, cy * c], axis=1)[:, None, :]
    return (st / size).astype(np.float32), size, c


def _texel_owner(size: int, cell: int, n_faces: int, start: int, stop: int) -> tuple[np.ndarray, ...]:
    """For flat texel indices [start, stop): the owning face (-1 for unused cells) and the clamped
    barycentric coordinates (l0, l1, l2) of the texel centre in that face's atlas triangle."""
    grid = _grid(n_faces)
    a_loc, b_loc, leg = _local_corners(cell)
    idx = np.arange(start, stop)
    row, col = idx // size, idx % size
    sx = col + 0.5
    ty = size - (row + 0.5)  # from the bottom
    cx, cy = (sx // cell).astype(np.int64), (ty // cell).astype(np.int64)
    la, lb = sx - cx * cell, ty - cy * cell
    upper = la + lb >= cell
    face = 2 * (cy * grid + cx) + upper
    face = np.where((face < n_faces) & (cx < grid) & (cy < grid), face, -1)
    # barycentrics in the right-isosceles local triangle, clamped to it
    l1 = np.where(upper, (b_loc[0, 0] - la) / leg, (la - a_loc[0, 0]) / leg)
    l2 = np.where(upper, (b_loc[0, 1] - lb) / leg, (lb - a_loc[0, 1]) / leg)
    l1, l2 = np.clip(l1, 0.0, 1.0), np.clip(l2, 0.0, 1.0)
    tot = np.maximum(l1 + l2, 1.0)
    l1, l2 = l1 / tot, l2 / tot
    return face, 1.0 - l1 - l2, l1, l2


def atlas_texel_faces(n_faces: int, size: int, cell: int) -> np.ndarray:
    """(size, size) int64: the face whose colour each texel of the atlas holds (-1: unused), row 0 = top."""
    return _texel_owner(size, cell, n_faces, 0, size * size)[0].reshape(size, size)


def bake_texture(
    vertices: np.ndarray,
    faces: np.ndarray,
    points: np.ndarray,
    colors: np.ndarray,
    size: int,
    cell: int,
    knn: int = 3,
    chunk: int = 1 << 20,
) -> np.ndarray:
    """Fill the atlas of :func:`atlas_uv`: (size, size, C) float64 colours, row 0 = top. Every texel of a
    used cell maps to the 3D point of its own triangle (clamped barycentrics), whose colour is the
    inverse-distance-weighted mean of the ``knn`` nearest input points; unused cells get the mean colour."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    kk = max(1, min(int(knn), len(points)))
    out = np.empty((size * size, colors.shape[1]))
    mean = colors.mean(axis=0)
    for s in range(0, size * size, chunk):
        e = min(s + chunk, size * size)
        face, l0, l1, l2 = _texel_owner(size, cell, len(faces), s, e)
        used = face >= 0
        res = np.broadcast_to(mean, (e - s, colors.shape[1])).copy()
        if used.any():
            tri = faces[face[used]]
            p3 = (
                l0[used, None] * vertices[tri[:, 0]]
                + l1[used, None] * vertices[tri[:, 1]]
                + l2[used, None] * vertices[tri[:, 2]]
            )
            dist, nn = tree.query(p3, k=kk, workers=-1)
            dist, nn = dist.reshape(len(p3), kk), nn.reshape(len(p3), kk)
            w = 1.0 / np.maximum(dist, 1e-12)
            w /= w.sum(axis=1, keepdims=True)
            res[used] = np.einsum("nk,nkc->nc", w, colors[nn])
        out[s:e] = res
    return out.reshape(size, size, colors.shape[1])


def sample_texture(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of ``texture`` (H, W, C), row 0 = top, at UVs (N, 2) with (0, 0) = bottom-left
    (the renderers' convention); float64 (N, C) in the texture's units."""
    tex = np.asarray(texture, dtype=np.float64)
    if tex.ndim == 2:
        tex = tex[..., None]
    h, w = tex.shape[:2]
    x = np.asarray(uv[:, 0], dtype=np.float64) * w - 0.5
    y = (1.0 - np.asarray(uv[:, 1], dtype=np.float64)) * h - 0.5
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0c, x1c = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    y0c, y1c = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    top = tex[y0c, x0c] * (1 - fx) + tex[y0c, x1c] * fx
    bottom = tex[y1c, x0c] * (1 - fx) + tex[y1c, x1c] * fx
    return top * (1 - fy) + bottom * fy


# -------------------------------------------------------------------------------------------------
# reconstruction
# -------------------------------------------------------------------------------------------------


def _open3d() -> Any:
    try:
        import open3d as o3d
    except ImportError as exc:
        raise BackendUnavailableError(
            "meshify_pointcloud: ball pivoting and Poisson reconstruction need Open3D, an optional extra: "
            "pip install open3d (or open3d-cpu; on Linux it also needs the system library libusb-1.0); "
            "method='implicit' needs no extra dependency. "
            f"Import failed with: {exc}"
        ) from None
    return o3d


def _open3d_or_none() -> Any:
    try:
        import open3d as o3d
    except ImportError:
        return None
    return o3d


def _colors01(colors: Any, n: int) -> tuple[np.ndarray, bool]:
    raw = np.asarray(colors) if not isinstance(colors, (str, bytes)) else None
    if raw is None or raw.dtype.kind not in "uif" or raw.ndim != 2 or raw.shape != (n, raw.shape[1]):
        raise InvalidSceneError(f"colors: expected (N, 3|4) colours for N={n} points, got {_describe(colors)}")
    if raw.shape[1] not in (3, 4):
        raise InvalidSceneError(f"colors: expected 3 (RGB) or 4 (RGBA) channels, got {_describe(raw)}")
    if raw.dtype.kind in "iu":
        if raw.size and (raw.min() < 0 or raw.max() > 255):
            raise InvalidSceneError("colors: integer colours must be 0-255")
        return raw.astype(np.float64) / 255.0, True
    return as_array("colors", raw, dtype=np.float64, min_value=0.0, max_value=1.0), False


@strict_arguments
def meshify_pointcloud(
    points: Any,
    colors: Any,
    normals: Any = None,
    target_faces: int | None = 100_000,
    texture_size: int | None = None,
    method: str = "ball_pivoting",
    radii: Any = None,
    poisson_depth: int = 8,
    density_quantile: float = 0.0,
    trim_distance: float | None = None,
    knn: int = 3,
    color_space: str = "srgb",
    voxel_size: float | None = None,
) -> MeshifyResult:
    """Reconstruct a textured triangle mesh from a coloured point cloud.

    ``points`` (N, 3); ``colors`` (N, 3|4) float in [0, 1] or uint8 (interpolated as given, in
    ``color_space``, the colour space of the resulting texture); ``normals`` (N, 3) or None (estimated
    with :func:`estimate_normals`, k=16, consistently oriented).
    ``method``: ``"ball_pivoting"`` (the blendify paper's; follows the points, keeps holes; ``radii``
    default = (1.5, 3) x the median nearest-neighbour spacing) or ``"poisson"`` (watertight, smooth;
    ``poisson_depth`` octree depth; the surface Poisson invents to close holes is trimmed: vertices
    farther than ``trim_distance`` from every point are removed, default 3 x the median spacing, 0 = keep
    all; optionally also those in the lowest ``density_quantile`` of sample density, Open3D's usual
    recipe, which also opens holes where the scan is merely sparse) -- both need Open3D (optional
    extra; BackendUnavailableError with the install command otherwise) -- or ``"implicit"``, which needs
    nothing beyond numpy/scipy: the signed distance to the points' tangent planes on a narrow-band grid
    (``voxel_size``, default 1.5 x the median spacing, at most 256 voxels across) and marching tetrahedra
    (smoother and more regular than ball pivoting, holes stay open).
    ``target_faces``: simplification budget (None = keep all): Open3D's quadric decimation, or vertex
    clustering without Open3D. ``texture_size``: square texture side in texels (None = 8x8 texels per
    pair of triangles; with a given size, cells are as large as fit, any remainder stays unused);
    ``knn``: input points blended per texel.
    """
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    p = _points("points", points)
    if len(p) < 4:
        raise InvalidSceneError(f"points: need at least 4 points to reconstruct a surface, got {len(p)}")
    cols, was_uint8 = _colors01(colors, len(p))
    if method not in METHODS:
        raise InvalidSceneError(f"method: expected one of {list(METHODS)}, got {method!r}")
    if color_space not in ("srgb", "linear"):
        raise InvalidSceneError(f"color_space: expected 'srgb' or 'linear', got {color_space!r}")
    if target_faces is not None and (
        isinstance(target_faces, bool) or not isinstance(target_faces, (int, np.integer)) or target_faces < 2
    ):
        raise InvalidSceneError(f"target_faces: expected an integer >= 2 or None, got {target_faces!r}")
    if texture_size is not None and (
        isinstance(texture_size, bool) or not isinstance(texture_size, (int, np.integer)) or texture_size < 8
    ):
        raise InvalidSceneError(f"texture_size: expected an integer >= 8 texels or None, got {texture_size!r}")
    if isinstance(knn, bool) or not isinstance(knn, (int, np.integer)) or knn < 1:
        raise InvalidSceneError(f"knn: expected a positive integer, got {knn!r}")
    density_quantile = as_float("density_quantile", density_quantile, min_value=0.0, max_value=1.0, exclusive_max=True)
    if trim_distance is not None:
        trim_distance = as_float("trim_distance", trim_distance, min_value=0.0)
    o3d = _open3d() if method != "implicit" else _open3d_or_none()

    t0 = time.perf_counter()
    if normals is None:
        n = estimate_normals(p, k=16, orient="propagate")
    else:
        n = as_array("normals", normals, dtype=np.float64, shape=(len(p), 3))
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), np.array([0.0, 0.0, 1.0]))
    timings["normals"] = time.perf_counter() - t0

    from scipy.spatial import cKDTree

    t0 = time.perf_counter()
    info: dict[str, Any] = {"method": method, "n_points": len(p)}
    d, _ = cKDTree(p).query(p, k=2, workers=-1)
    spacing = float(np.median(d[:, 1]))
    if not spacing > 0:
        raise InvalidSceneError("points: the median point spacing is 0 (all points coincide?)")
    if method == "implicit":
        extent = float(np.ptp(p, axis=0).max())
        if voxel_size is None:
            voxel = max(1.5 * spacing, extent / 256.0)
        else:
            voxel = float(as_array("voxel_size", voxel_size, shape=(), min_value=0.0))
            if not voxel > 0 or extent / voxel > 1024:
                raise InvalidSceneError(
                    f"voxel_size: expected a positive size giving at most 1024 voxels across, got {voxel_size!r}"
                )
        values, valid, origin = signed_distance_grid(p, n, voxel)
        verts, faces = marching_tetrahedra(values, valid, origin, voxel)
        info["voxel_size"] = voxel
    else:
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(p)))
        pcd.normals = o3d.utility.Vector3dVector(np.array(n))
        if method == "ball_pivoting":
            if radii is None:
                r = [1.5 * spacing, 3.0 * spacing]
            else:
                r = as_array("radii", np.atleast_1d(radii), ndim=1, min_value=0.0).tolist()
                if not r or min(r) <= 0:
                    raise InvalidSceneError(f"radii: expected positive ball radii, got {radii!r}")
            info["radii"] = r
            mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(pcd, o3d.utility.DoubleVector(r))
        else:
            if isinstance(poisson_depth, bool) or not isinstance(poisson_depth, (int, np.integer)):
                raise InvalidSceneError(f"poisson_depth: expected an integer octree depth, got {poisson_depth!r}")
            if not 1 <= poisson_depth <= 14:
                raise InvalidSceneError(f"poisson_depth: expected 1-14, got {poisson_depth}")
            mesh, density = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=int(poisson_depth))
            density = np.asarray(density)
            drop = np.zeros(len(density), dtype=bool)
            if density_quantile > 0 and len(density):
                drop |= density < np.quantile(density, float(density_quantile))
            trim = 3.0 * spacing if trim_distance is None else float(trim_distance)
            if trim > 0:
                far, _ = cKDTree(p).query(np.asarray(mesh.vertices), k=1, workers=-1)
                drop |= far > trim
            if drop.any():
                mesh.remove_vertices_by_mask(drop)
            info.update(poisson_depth=int(poisson_depth), trim_distance=trim, vertices_trimmed=int(drop.sum()))
        mesh.remove_degenerate_triangles()
        mesh.remove_duplicated_triangles()
        mesh.remove_unreferenced_vertices()
        verts = np.asarray(mesh.vertices, dtype=np.float64).copy()
        faces = np.asarray(mesh.triangles, dtype=np.int64).copy()
    info["faces_reconstructed"] = len(faces)
    timings["reconstruct"] = time.perf_counter() - t0
    if len(faces) == 0:
        raise InvalidSceneError(
            f"points: {method} produced no triangles (too sparse or too noisy for the radii {info.get('radii')}?)"
        )

    t0 = time.perf_counter()
    if target_faces is not None and len(faces) > target_faces:
        if o3d is not None:
            mesh = o3d.geometry.TriangleMesh(
                o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(faces.astype(np.int32))
            )
            mesh = mesh.simplify_quadric_decimation(target_number_of_triangles=int(target_faces))
            mesh.remove_degenerate_triangles()
            mesh.remove_unreferenced_vertices()
            verts = np.asarray(mesh.vertices, dtype=np.float64).copy()
            faces = np.asarray(mesh.triangles, dtype=np.int64).copy()
            info["simplification"] = "quadric (Open3D)"
        else:
            verts, faces = cluster_simplify(verts, faces, int(target_faces))
            info["simplification"] = "vertex clustering (no Open3D)"
    timings["simplify"] = time.perf_counter() - t0
    info["faces"] = len(faces)

    t0 = time.perf_counter()
    faces_uv, size, cell = atlas_uv(len(faces), texture_size)
    timings["uv_atlas"] = time.perf_counter() - t0
    info.update(texture_size=size, cell_texels=cell)

    t0 = time.perf_counter()
    tex = bake_texture(verts, faces, p, cols, size, cell, knn=int(knn))
    texture = np.round(np.clip(tex, 0.0, 1.0) * 255.0).astype(np.uint8)
    if texture.shape[2] == 4 and np.all(texture[..., 3] == 255):
        texture = texture[..., :3]
    timings["texture"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    info["input_uint8"] = was_uint8
    return MeshifyResult(verts, faces.astype(np.int32), faces_uv, texture, color_space, timings, info)
