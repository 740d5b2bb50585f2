"""Dependency-free surface reconstruction (numpy/scipy only), used by ``meshify_pointcloud(method="implicit")``
and as its fallback when Open3D is not installed.

- Signed distance to the oriented points (Hoppe et al. 1992: distance to the tangent planes of the nearest
  points, Gaussian-weighted over k neighbours), evaluated only on grid nodes within a narrow band around the
  points, so holes stay holes instead of being bridged by invented surface.
- Marching tetrahedra on the Freudenthal (Kuhn) split of every grid cube into 6 tetrahedra, which is
  conforming across cubes, so the mesh is connected (vertices shared through edge keys) without a case table.
- Vertex-clustering simplification to a face budget.
"""

from __future__ import annotations

import numpy as np

# Freudenthal split of the unit cube: the 6 monotone paths from corner (0,0,0) to (1,1,1).
# Corner c = (dx, dy, dz) -> index dx + 2 dy + 4 dz.
_TETS = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
_CORNERS = np.array([[(c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])


def signed_distance_grid(
    points: np.ndarray, normals: np.ndarray, voxel: float, band: float = 2.5, k: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance on a grid (nodes at ``origin + voxel * index``): (values, valid mask, origin).
    Nodes farther than ``band`` voxels from every point are invalid."""
    from scipy.ndimage import binary_dilation
    from scipy.spatial import cKDTree

    lo = points.min(axis=0) - 2 * voxel
    hi = points.max(axis=0) + 2 * voxel
    shape = tuple(int(s) for s in np.ceil((hi - lo) / voxel).astype(int) + 1)
    occ = np.zeros(shape, dtype=bool)
    idx = np.clip(np.round((points - lo) / voxel).astype(np.int64), 0, np.array(shape) - 1)
    occ[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    r = int(np.ceil(band))
    mask = binary_dilation(occ, iterations=r)
    nodes = np.argwhere(mask)
    x = lo + nodes * voxel
    tree = cKDTree(points)
    kk = min(k, len(points))
    dist, nn = tree.query(x, k=kk, workers=-1)
    dist, nn = dist.reshape(len(x), kk), nn.reshape(len(x), kk)
    sigma = max(float(np.median(dist[:, 0])), voxel)
    w = np.exp(-((dist / sigma) ** 2))
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    plane = np.einsum("nkc,nkc->nk", x[:, None, :] - points[nn], normals[nn])
    sd = np.einsum("nk,nk->n", w, plane)
    keep = dist[:, 0] <= band * voxel
    values = np.zeros(shape)
    valid = np.zeros(shape, dtype=bool)
    values[nodes[keep, 0], nodes[keep, 1], nodes[keep, 2]] = sd[keep]
    valid[nodes[keep, 0], nodes[keep, 1], nodes[keep, 2]] = True
    return values, valid, lo


def marching_tetrahedra(values: np.ndarray, valid: np.ndarray, origin: np.ndarray, voxel: float) -> tuple:
    """Zero level set of ``values`` over cubes whose 8 corners are valid: (vertices (V, 3), faces (F, 3)),
    faces oriented so that their normals point towards positive values (outside)."""
    nx, ny, nz = values.shape
    pos = values >= 0
    cube_ok = np.ones((nx - 1, ny - 1, nz - 1), dtype=bool)
    any_pos = np.zeros_like(cube_ok)
    all_pos = np.ones_like(cube_ok)
    for dx, dy, dz in _CORNERS:
        sl = (slice(dx, nx - 1 + dx), slice(dy, ny - 1 + dy), slice(dz, nz - 1 + dz))
        cube_ok &= valid[sl]
        any_pos |= pos[sl]
        all_pos &= pos[sl]
    cubes = np.argwhere(cube_ok & any_pos & ~all_pos)  # (C, 3)
    if len(cubes) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    strides = np.array([ny * nz, nz, 1], dtype=np.int64)
    corner_ids = (cubes[:, None, :] + _CORNERS[None]) @ strides  # (C, 8) flat node ids
    tet_ids = corner_ids[:, _TETS].reshape(-1, 4)  # (6C, 4)
    flat_vals = values.ravel()
    s = flat_vals[tet_ids]
    p = s >= 0
    npos = p.sum(axis=1)
    tris_a: list[np.ndarray] = []  # (T, 3, 2) node-id pairs per triangle corner
    tris_dir: list[np.ndarray] = []  # (T, 2) (a positive node, a negative node) for orientation
    # one positive or one negative vertex: a triangle around it
    for lone_positive in (True, False):
        sel = np.flatnonzero(npos == (1 if lone_positive else 3))
        if len(sel):
            pp = p[sel] if lone_positive else ~p[sel]
            lone = np.argmax(pp, axis=1)
            others = np.array([[j for j in range(4) if j != i] for i in range(4)])[lone]  # (n, 3)
            ids = tet_ids[sel]
            lone_id = ids[np.arange(len(sel)), lone]
            other_ids = np.take_along_axis(ids, others, axis=1)
            pairs = np.stack([np.repeat(lone_id[:, None], 3, axis=1), other_ids], axis=2)
            tris_a.append(pairs)
            if lone_positive:
                tris_dir.append(np.stack([lone_id, other_ids[:, 0]], axis=1))
            else:
                tris_dir.append(np.stack([other_ids[:, 0], lone_id], axis=1))
    sel = np.flatnonzero(npos == 2)
    if len(sel):
        ids = tet_ids[sel]
        order = np.argsort(~p[sel], axis=1, kind="stable")  # positives first
        a, b, c, d = (np.take_along_axis(ids, order[:, j : j + 1], axis=1)[:, 0] for j in range(4))
        quad = [np.stack([a, c], 1), np.stack([a, d], 1), np.stack([b, d], 1), np.stack([b, c], 1)]
        tris_a.append(np.stack([quad[0], quad[1], quad[2]], axis=1))
        tris_a.append(np.stack([quad[0], quad[2], quad[3]], axis=1))
        tris_dir.append(np.stack([a, c], 1))
        tris_dir.append(np.stack([a, c], 1))
    pairs = np.concatenate(tris_a)  # (T, 3, 2)
    dirs = np.concatenate(tris_dir)
    lo_id, hi_id = pairs.min(axis=2), pairs.max(axis=2)
    n_nodes = values.size
    keys = lo_id.astype(np.int64) * n_nodes + hi_id
    uniq, inverse = np.unique(keys.ravel(), return_inverse=True)
    e0, e1 = uniq // n_nodes, uniq % n_nodes
    v0, v1 = flat_vals[e0], flat_vals[e1]
    denom = v0 - v1
    t = np.where(np.abs(denom) > 1e-300, v0 / np.where(np.abs(denom) > 1e-300, denom, 1.0), 0.5)
    t = np.clip(t, 0.0, 1.0)

    def node_xyz(ids: np.ndarray) -> np.ndarray:
        i = ids // strides[0]
        j = (ids // strides[1]) % ny
        kz = ids % nz
        return origin + voxel * np.stack([i, j, kz], axis=1)

    verts = node_xyz(e0) * (1 - t)[:, None] + node_xyz(e1) * t[:, None]
    faces = inverse.reshape(-1, 3).astype(np.int64)
    # orientation: normal along (positive node - negative node)
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    grad = node_xyz(dirs[:, 0]) - node_xyz(dirs[:, 1])
    flip = np.einsum("ij,ij->i", fn, grad) < 0
    faces[flip] = faces[flip][:, ::-1]
    return _clean(verts, faces)


def _clean(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop degenerate and duplicated triangles and unreferenced vertices."""
    good = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = faces[good]
    if len(faces):
        area2 = np.linalg.norm(
            np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]]), axis=1
        )
        faces = faces[area2 > 1e-18 * max(float(np.ptp(verts, axis=0).max()) ** 2, 1e-300)]
        srt = np.sort(faces, axis=1)
        _, first = np.unique(srt, axis=0, return_index=True)
        faces = faces[np.sort(first)]
    used, remap = np.unique(faces, return_inverse=True)
    return verts[used], remap.reshape(-1, 3).astype(np.int64)


def cluster_simplify(verts: np.ndarray, faces: np.ndarray, target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering on a grid whose cell size is searched so that at most ``target_faces`` remain."""
    if len(faces) <= target_faces:
        return verts, faces
    extent = float(np.ptp(verts, axis=0).max())
    lo = verts.min(axis=0)

    def cluster(cell: float) -> tuple[np.ndarray, np.ndarray]:
        key = np.floor((verts - lo) / cell).astype(np.int64)
        _, label = np.unique(key, axis=0, return_inverse=True)
        label = label.ravel()
        n = int(label.max()) + 1
        counts = np.bincount(label, minlength=n).astype(np.float64)
        sums = np.stack([np.bincount(label, weights=verts[:, c], minlength=n) for c in range(3)], 1)
        centres = sums / counts[:, None]
        return _clean(centres, label[faces])

    # the face count falls roughly with the square of the cell size
    edge = np.median(np.linalg.norm(verts[faces[:, 0]] - verts[faces[:, 1]], axis=1))
    cell = max(edge * np.sqrt(len(faces) / target_faces), extent * 1e-6)
    best = None
    for _ in range(30):
        v, f = cluster(cell)
        if len(f) <= target_faces:
            best = (v, f)
            if len(f) >= 0.85 * target_faces:
                break
            cell *= 0.93
        else:
            cell *= 1.12
        if best is not None and len(f) > target_faces:
            break
    return best if best is not None else cluster(extent)
