"""Geometry helpers shared by the IR and every backend: triangulation, normals and the tessellations
of parametric primitives (so that all backends that tessellate use the very same triangles)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.typing import BoolArray, Float64Array, FloatArray, Int32Array, IntArray

__all__ = [
    "TriMesh",
    "triangulate_polygons",
    "face_normals",
    "vertex_normals",
    "uv_sphere",
    "icosphere",
    "tube_along_polyline",
]


@dataclass
class TriMesh:
    """A plain triangle mesh in object space.

    ``uv`` is per triangle corner (F, 3, 2) or None; ``normals`` per vertex (N, 3) for smooth shading or
    None for flat shading; ``face_polygon`` maps each triangle to the polygon (material slot face) it
    came from.
    """

    vertices: FloatArray
    faces: IntArray
    normals: FloatArray | None = None
    uv: FloatArray | None = None
    face_polygon: IntArray | None = None
    smooth: bool = False

    @property
    def is_empty(self) -> bool:
        return len(self.faces) == 0


def triangulate_polygons(
    polygons: Sequence[ArrayLike] | IntArray, vertices: ArrayLike | None = None
) -> tuple[Int32Array, Int32Array, Int32Array]:
    """Triangulate polygons: (F, 3) int32 triangles, (F,) int32 polygon index, (F, 3) int32 corner
    index within the polygon (for per-corner data such as FacesUV).

    Convex polygons (and every polygon when ``vertices`` is None) are fan-triangulated from their first
    corner; with ``vertices``, concave polygons are ear-clipped in their best-fit plane instead (a fan
    would cover area outside them). Either way a k-gon gives k - 2 triangles with its winding."""
    if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
        m, k = polygons.shape
        if k == 3:
            return (
                polygons.astype(np.int32),
                np.arange(m, dtype=np.int32),
                np.tile(np.array([0, 1, 2], dtype=np.int32), (m, 1)),
            )
        j = np.arange(1, k - 1)
        corners = np.stack([np.zeros_like(j), j, j + 1], axis=1)  # (k-2, 3)
        all_corners = np.tile(corners, (m, 1)).astype(np.int32)
        if vertices is not None and m:
            reflex = _reflex(np.asarray(vertices, dtype=np.float64)[polygons])
            if k == 4:  # vectorised: a quad reflex at corner 1 or 3 is split along the diagonal 1-3
                flip = reflex[:, 1] | reflex[:, 3]
                quads = all_corners.reshape(m, 2, 3)
                quads[flip] = [[1, 2, 3], [1, 3, 0]]
                all_corners = quads.reshape(-1, 3)
            else:
                for i in np.flatnonzero(reflex.any(axis=1)):
                    ear = _ear_clip_checked(np.asarray(vertices, dtype=np.float64)[polygons[i]], int(i))
                    if ear is not None:
                        all_corners[i * (k - 2) : (i + 1) * (k - 2)] = ear
        tris = np.take_along_axis(np.repeat(polygons, k - 2, axis=0), all_corners, axis=1)
        poly = np.repeat(np.arange(m, dtype=np.int32), k - 2)
        return tris.astype(np.int32), poly, all_corners
    tris_l: list[IntArray] = []
    poly_l: list[IntArray] = []
    corner_l: list[IntArray] = []
    for i, polygon in enumerate(polygons):
        p = np.asarray(polygon)
        j = np.arange(1, len(p) - 1)
        corners = np.stack([np.zeros_like(j), j, j + 1], axis=1)
        if vertices is not None and len(p) > 3:
            pts = np.asarray(vertices, dtype=np.float64)[p]
            if _concave(pts[None])[0]:
                ear = _ear_clip_checked(pts, i)
                corners = corners if ear is None else ear
        tris_l.append(p[corners])
        poly_l.append(np.full(len(j), i))
        corner_l.append(corners)
    if not tris_l:
        return np.zeros((0, 3), np.int32), np.zeros(0, np.int32), np.zeros((0, 3), np.int32)
    return (
        np.concatenate(tris_l).astype(np.int32),
        np.concatenate(poly_l).astype(np.int32),
        np.concatenate(corner_l).astype(np.int32),
    )


def _newell(pts: Float64Array) -> Float64Array:
    """(M, 3) Newell normals of polygons (M, k, 3) (area-weighted, robust for non-planar polygons)."""
    nxt = np.roll(pts, -1, axis=1)
    normals: Float64Array = np.cross(pts, nxt).sum(axis=1)
    return normals


def _reflex(pts: Float64Array) -> BoolArray:
    """(M, k) bool: reflex corners of polygons (M, k, 3) (turning against their Newell normal)."""
    n = _newell(pts)
    e = np.roll(pts, -1, axis=1) - pts  # edge i: corner i -> i + 1
    turn = np.einsum("mkj,mj->mk", np.cross(e, np.roll(e, -1, axis=1)), n)  # turn at corner i + 1
    scale = np.linalg.norm(e, axis=2) * np.linalg.norm(np.roll(e, -1, axis=1), axis=2)
    scale = scale * np.linalg.norm(n, axis=1, keepdims=True)
    flags: BoolArray = (turn < -1e-9 * scale) & (np.linalg.norm(n, axis=1) > 0)[:, None]
    return np.roll(flags, 1, axis=1)


def _concave(pts: Float64Array) -> BoolArray:
    """(M,) bool: polygons (M, k, 3) with a reflex corner."""
    concave: BoolArray = _reflex(pts).any(axis=1)
    return concave


#: concave polygons with more corners than this keep the fan (ear clipping here is O(k^2): ~1 s at 1000)
MAX_EAR_CLIP_CORNERS = 1000


def _ear_clip_checked(pts: Float64Array, index: int) -> Int32Array | None:
    if len(pts) > MAX_EAR_CLIP_CORNERS:
        import warnings

        warnings.warn(
            f"faces[{index}]: concave polygon of {len(pts)} corners (> {MAX_EAR_CLIP_CORNERS}) is fan-triangulated "
            "and may cover area outside it; triangulate it before passing it in",
            stacklevel=4,
        )
        return None
    return _ear_clip(pts)


def _ear_clip(pts: Float64Array) -> Int32Array | None:
    """(k - 2, 3) corner triples triangulating the simple polygon ``pts`` (k, 3) by ear clipping in its
    Newell plane, keeping its winding; None when it is not simple (the caller keeps the fan)."""
    n = _newell(pts[None])[0]
    n = n / np.linalg.norm(n)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    q = np.stack([(pts - pts[0]) @ u, (pts - pts[0]) @ w], axis=1)  # counter-clockwise about n

    def cross(o: Float64Array, a: Float64Array, b: Float64Array) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    eps = 1e-12 * float(np.ptp(q, axis=0).max()) ** 2
    idx = list(range(len(q)))
    out: list[tuple[int, ...]] = []
    while len(idx) > 3:
        for t in range(len(idx)):
            a, b, c = idx[t - 1], idx[t], idx[(t + 1) % len(idx)]
            if cross(q[a], q[b], q[c]) <= eps:
                continue  # reflex or flat corner: not an ear
            inside = False
            for o in idx:
                if o in (a, b, c):
                    continue
                if (
                    cross(q[a], q[b], q[o]) >= -eps
                    and cross(q[b], q[c], q[o]) >= -eps
                    and cross(q[c], q[a], q[o]) >= -eps
                ):
                    inside = True
                    break
            if not inside:
                out.append((a, b, c))
                del idx[t]
                break
        else:
            return None
    out.append(tuple(idx))
    return np.array(out, dtype=np.int32)


def face_normals(vertices: ArrayLike, faces: IntArray) -> Float64Array:
    """(F, 3) unit face normals (zero for degenerate triangles, never NaN)."""
    v = np.asarray(vertices, dtype=np.float64)
    n = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    unit: Float64Array = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    return unit


def vertex_normals(vertices: ArrayLike, faces: IntArray) -> Float64Array:
    """(N, 3) unit vertex normals, angle-weighted: the sum over the triangles around a vertex of the
    triangle's unit normal times its corner angle at the vertex (zero where undefined, never NaN).

    This is the project's one vertex-normal rule; every backend receives these normals (Cycles as custom
    normals, Mitsuba and pyrender as mesh normals). It is Blender's and trimesh's rule: the corners of a
    planar polygon's triangles at a vertex add up to the polygon's corner, so an n-gon weighs the same
    whether it is triangulated or not (area weighting gives a fan's first vertex all of the cap)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    acc = np.zeros_like(v)
    if len(f) == 0 or len(v) == 0:
        return acc
    p = v[f]  # (F, 3 corners, 3)
    e = np.roll(p, -1, axis=1) - p  # edge from corner k to k+1
    n = np.cross(e[:, 0], -e[:, 2])  # (p1 - p0) x (p2 - p0)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    unit = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    # corner angle at k: between the edges to k+1 and to k-1
    a, b = e, -np.roll(e, 1, axis=1)
    cos = np.einsum("fki,fki->fk", a, b)
    sin = np.linalg.norm(np.cross(a, b), axis=2)
    angle = np.arctan2(sin, cos)  # (F, 3), 0 for degenerate corners
    for k in range(3):
        w = unit * angle[:, k : k + 1]
        for j in range(3):
            acc[:, j] += np.bincount(f[:, k], weights=w[:, j], minlength=len(v))
    norm = np.linalg.norm(acc, axis=1, keepdims=True)
    out: Float64Array = np.divide(acc, norm, out=np.zeros_like(acc), where=norm > 0)
    return out


def leaning_area_fraction(vertices: ArrayLike, faces: IntArray, normals: ArrayLike, degrees: float) -> float:
    """The fraction of a smooth mesh's area on triangles with a corner whose vertex normal leans more than
    ``degrees`` from the triangle's own normal (sign-free: a flipped winding leans 0). Where shading
    normals lean far from the faces, engines that pick a surface's side by different normals (Cycles by
    the geometric one, Mitsuba's ``twosided`` by the shading one) shade differently."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64)
    if len(f) == 0:
        return 0.0
    p = v[f]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    area = np.linalg.norm(fn, axis=1)
    unit = np.divide(fn, area[:, None], out=np.zeros_like(fn), where=area[:, None] > 0)
    cos = np.abs(np.einsum("fi,fki->fk", unit, n[f]))
    leans = (cos < np.cos(np.deg2rad(degrees))).any(axis=1) & (area > 0)
    total = float(area.sum())
    return float(area[leans].sum() / total) if total > 0 else 0.0


def uv_sphere(radius: float = 1.0, segments: int = 64, rings: int = 32) -> TriMesh:
    """A UV sphere (poles on +/-Z) with per-vertex normals and UVs (u around Z, v from south to north)."""
    theta = np.linspace(0.0, np.pi, rings + 1)  # from north pole
    phi = np.linspace(0.0, 2 * np.pi, segments + 1)
    tt, pp = np.meshgrid(theta, phi, indexing="ij")  # (rings+1, segments+1)
    n = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
    uv = np.stack([pp / (2 * np.pi), 1.0 - tt / np.pi], axis=-1).reshape(-1, 2)
    idx = np.arange((rings + 1) * (segments + 1)).reshape(rings + 1, segments + 1)
    a, b = idx[:-1, :-1], idx[:-1, 1:]
    c, d = idx[1:, :-1], idx[1:, 1:]
    top = np.stack([a, c, d], axis=-1)[0]  # north cap: a is the pole
    bottom = np.stack([a, c, b], axis=-1)[-1]
    mid_a = np.stack([a, c, d], axis=-1)[1:-1].reshape(-1, 3)
    mid_b = np.stack([a, d, b], axis=-1)[1:-1].reshape(-1, 3)
    faces = np.concatenate([top, mid_a, mid_b, bottom]).astype(np.int32)
    tri_uv = uv[faces].astype(np.float32)
    return TriMesh(vertices=n * radius, faces=faces, normals=n.copy(), uv=tri_uv, smooth=True)


def icosphere(subdivisions: int = 1, radius: float = 1.0) -> TriMesh:
    """An icosphere (subdivided icosahedron), smooth normals, no UVs."""
    t = (1.0 + 5**0.5) / 2.0
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        dtype=np.float64,
    )
    f = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ],
        dtype=np.int64,
    )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        mids = v[uniq[:, 0]] + v[uniq[:, 1]]
        mids /= np.linalg.norm(mids, axis=1, keepdims=True)
        m = inv.reshape(3, -1).T + len(v)  # per face: mid of (0,1), (1,2), (2,0)
        v = np.concatenate([v, mids])
        f = np.concatenate(
            [
                np.stack([f[:, 0], m[:, 0], m[:, 2]], 1),
                np.stack([f[:, 1], m[:, 1], m[:, 0]], 1),
                np.stack([f[:, 2], m[:, 2], m[:, 1]], 1),
                m,
            ]
        )
    return TriMesh(vertices=v * radius, faces=f.astype(np.int32), normals=v.copy(), smooth=True)


def _frames(points: Float64Array) -> tuple[Float64Array, Float64Array, Float64Array]:
    """Rotation-minimising frames (double reflection) along a polyline: tangents, normals, binormals."""
    seg = np.diff(points, axis=0)
    seg_len = np.linalg.norm(seg, axis=1, keepdims=True)
    seg_t = seg / np.maximum(seg_len, 1e-300)
    t = np.empty_like(points)
    t[0], t[-1] = seg_t[0], seg_t[-1]
    if len(points) > 2:
        mid = seg_t[:-1] + seg_t[1:]
        ln = np.linalg.norm(mid, axis=1, keepdims=True)
        t[1:-1] = np.where(ln > 1e-9, mid / np.maximum(ln, 1e-300), seg_t[1:])
    helper = np.array([0.0, 0.0, 1.0]) if abs(t[0][2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    n0 = np.cross(t[0], helper)
    n0 /= np.linalg.norm(n0)
    normals = np.empty_like(points)
    normals[0] = n0
    for i in range(len(points) - 1):
        v1 = points[i + 1] - points[i]
        c1 = v1 @ v1
        if c1 < 1e-300:
            normals[i + 1] = normals[i]
            continue
        r_l = normals[i] - (2.0 / c1) * (v1 @ normals[i]) * v1
        t_l = t[i] - (2.0 / c1) * (v1 @ t[i]) * v1
        v2 = t[i + 1] - t_l
        c2 = v2 @ v2
        r = r_l - (2.0 / c2) * (v2 @ r_l) * v2 if c2 > 1e-300 else r_l
        r -= (r @ t[i + 1]) * t[i + 1]
        normals[i + 1] = r / max(np.linalg.norm(r), 1e-300)
    binormals = np.cross(t, normals)
    return t, normals, binormals


def tube_along_polyline(points: ArrayLike, radius: float, segments: int = 16, caps: bool = True) -> TriMesh:
    """A tube of ``radius`` around a polyline (consecutive duplicate points removed), smooth sides,
    flat caps at both ends. The cross-section keeps a constant radius (mitred joints are not widened)."""
    pts = np.asarray(points, dtype=np.float64)
    keep = np.ones(len(pts), bool)
    keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12 * max(1.0, float(np.abs(pts).max()))
    pts = pts[keep]
    if len(pts) < 2:
        return TriMesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), np.int32), smooth=True)
    t, n, b = _frames(pts)
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.cos(ang)[None, :, None] * n[:, None, :] + np.sin(ang)[None, :, None] * b[:, None, :]  # (K,S,3)
    verts = (pts[:, None, :] + radius * ring).reshape(-1, 3)
    norms = ring.reshape(-1, 3)
    k, s = len(pts), segments
    idx = np.arange(k * s).reshape(k, s)
    a, bb = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = idx[1:], np.roll(idx[1:], -1, axis=1)
    faces = np.concatenate([np.stack([a, bb, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    if caps:
        cap_faces: list[IntArray] = []
        cap_verts: list[Float64Array] = []
        cap_norms: list[Float64Array] = []
        base = len(verts)
        for end, sign in ((0, -1.0), (k - 1, 1.0)):
            centre = base + len(cap_verts)
            cap_verts.append(pts[end])
            cap_norms.append(sign * t[end])
            ring_start = base + len(cap_verts)
            cap_verts.extend(verts[idx[end]])
            cap_norms.extend([sign * t[end]] * s)
            j = np.arange(s)
            tri = np.stack([np.full(s, centre), ring_start + j, ring_start + (j + 1) % s], 1)
            cap_faces.append(tri if sign > 0 else tri[:, [0, 2, 1]])
        verts = np.concatenate([verts, np.array(cap_verts)])
        norms = np.concatenate([norms, np.array(cap_norms)])
        faces = np.concatenate([faces, *cap_faces])
    return TriMesh(vertices=verts, faces=faces.astype(np.int32), normals=norms, smooth=True)


def torus(
    major_radius: float = 1.0, minor_radius: float = 0.4, major_segments: int = 64, minor_segments: int = 32
) -> TriMesh:
    """A torus around +Z (a donut lying flat), smooth normals, UVs (u around Z, v around the tube)."""
    u = np.linspace(0, 2 * np.pi, major_segments, endpoint=False)
    v = np.linspace(0, 2 * np.pi, minor_segments, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    centre = np.stack([np.cos(uu), np.sin(uu), np.zeros_like(uu)], axis=-1)
    n = np.stack([np.cos(vv) * np.cos(uu), np.cos(vv) * np.sin(uu), np.sin(vv)], axis=-1)
    verts = (centre * major_radius + n * minor_radius).reshape(-1, 3)
    idx = np.arange(major_segments * minor_segments).reshape(major_segments, minor_segments)
    a = idx
    b = np.roll(idx, -1, axis=0)
    c = np.roll(idx, -1, axis=1)
    d = np.roll(b, -1, axis=1)
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    uv = np.stack([uu / (2 * np.pi), vv / (2 * np.pi)], axis=-1).reshape(-1, 2)
    return TriMesh(
        vertices=verts,
        faces=faces.astype(np.int32),
        normals=n.reshape(-1, 3),
        uv=uv[faces].astype(np.float32),
        smooth=True,
    )
