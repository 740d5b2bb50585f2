"""Rendering a translated scene: the colour image with ``mi.render`` and the geometric outputs (depth,
normal, albedo, instance) from our own rays through the pixel centres (exact, not filtered).

This module imports mitsuba: import it only after the variant is set.
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ._translate import ShapeInfo

__all__ = ["render_rgba", "cast_outputs"]

_MAX_PASS_THROUGH = 8  # light shapes (null BSDF) a geometric ray may pass through


def render_rgba(scene: Any, spp: int, seed: int) -> np.ndarray:
    """(H, W, 4) float32 linear premultiplied RGBA."""
    img = np.array(mi.render(scene, spp=int(spp), seed=int(seed)), dtype=np.float32)
    if img.ndim == 3 and img.shape[2] == 3:
        img = np.concatenate([img, np.ones(img.shape[:2] + (1,), np.float32)], axis=2)
    return img[..., :4]


def _rays(camera: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixel-centre rays clipped to [near, far] (planar): origins, directions, t_near, t_far, cos."""
    o, d = camera.pixel_rays()
    cos = d @ camera.viewdir
    if camera.kind == "orthographic":
        cos = np.ones(len(d))
    tn = camera.near / cos
    tf = camera.far / cos
    return o, d, tn, tf, cos


def cast_outputs(
    scene: Any,
    camera: Any,
    shapes: dict[str, ShapeInfo],
    outputs: tuple[str, ...],
    vectorised: bool,
) -> dict[str, np.ndarray]:
    """Depth (planar z, +inf background), normal (world, shading, facing the camera), albedo (the
    material colour input, linear) and instance (renderable index, -1 background) per pixel centre."""
    o, d, tn, tf, cos = _rays(camera)
    n = len(d)
    shape_list = list(scene.shapes())
    ids = [s.id() for s in shape_list]
    hit_t = np.full(n, np.inf)
    hit_shape = np.full(n, -1, dtype=np.int64)
    normal = np.zeros((n, 3), np.float32)
    albedo = np.zeros((n, 3), np.float32)
    want_albedo = "albedo" in outputs
    if vectorised:
        _cast_vector(scene, shape_list, ids, shapes, o, d, tn, tf, hit_t, hit_shape, normal, albedo, want_albedo)
    else:
        _cast_scalar(scene, ids, shapes, o, d, tn, tf, hit_t, hit_shape, normal, albedo, want_albedo)
    h, w = camera.height, camera.width
    out: dict[str, np.ndarray] = {}
    valid = hit_shape >= 0
    if "depth" in outputs:
        z = np.where(valid, hit_t * cos, np.inf)
        out["depth"] = z.reshape(h, w).astype(np.float32)
    if "normal" in outputs:
        out["normal"] = normal.reshape(h, w, 3)
    if "albedo" in outputs:
        out["albedo"] = albedo.reshape(h, w, 3)
    if "instance" in outputs:
        table = np.array([shapes[i].renderable if i in shapes else -1 for i in ids] + [-1], dtype=np.int32)
        out["instance"] = table[hit_shape].reshape(h, w)
    return out


def _cast_scalar(
    scene: Any,
    ids: list[str],
    shapes: dict[str, ShapeInfo],
    o: np.ndarray,
    d: np.ndarray,
    tn: np.ndarray,
    tf: np.ndarray,
    hit_t: np.ndarray,
    hit_shape: np.ndarray,
    normal: np.ndarray,
    albedo: np.ndarray,
    want_albedo: bool,
) -> None:
    index = {sid: i for i, sid in enumerate(ids)}
    for k in range(len(d)):
        start = float(tn[k])
        dk = d[k]
        for _ in range(_MAX_PASS_THROUGH):
            ray = mi.Ray3f(o[k] + dk * start, dk)
            ray.maxt = float(tf[k]) - start
            si = scene.ray_intersect(ray)
            if not si.is_valid():
                break
            sid = si.shape.id()
            info = shapes.get(sid)
            if info is None:  # an area light's null-BSDF shape: look through it
                start += float(si.t) * (1.0 + 1e-6) + 1e-6
                continue
            hit_t[k] = start + float(si.t)
            hit_shape[k] = index[sid]
            nn = np.array(si.sh_frame.n, dtype=np.float64)
            if nn @ dk > 0:
                nn = -nn
            normal[k] = nn
            if want_albedo:
                if info.albedo is not None:
                    albedo[k] = info.albedo
                else:
                    albedo[k] = np.array(info.albedo_texture.eval(si), dtype=np.float32)[:3]
            break


def _cast_vector(
    scene: Any,
    shape_list: list[Any],
    ids: list[str],
    shapes: dict[str, ShapeInfo],
    o: np.ndarray,
    d: np.ndarray,
    tn: np.ndarray,
    tf: np.ndarray,
    hit_t: np.ndarray,
    hit_shape: np.ndarray,
    normal: np.ndarray,
    albedo: np.ndarray,
    want_albedo: bool,
) -> None:
    # pointer id of every shape -> its index in scene.shapes()
    ptr_ids = np.array(dr.reinterpret_array(mi.UInt32, scene.shapes_dr()), dtype=np.int64)
    lookup = {int(p): i for i, p in enumerate(ptr_ids)}
    is_light = np.array([sid not in shapes for sid in ids] + [False])
    todo = np.arange(len(d))
    start = tn.astype(np.float64).copy()
    for _ in range(_MAX_PASS_THROUGH):
        if len(todo) == 0:
            break
        si = _intersect(scene, o[todo], d[todo], start[todo], tf[todo])
        valid = np.array(si.is_valid(), dtype=bool)
        t = np.array(si.t, dtype=np.float64)
        ptr = np.array(dr.reinterpret_array(mi.UInt32, si.shape), dtype=np.int64)
        idx = np.array([lookup.get(int(p), len(ids)) for p in ptr], dtype=np.int64)
        idx[~valid] = len(ids)
        through = valid & is_light[idx]
        done = valid & ~through
        rows = todo[done]
        hit_t[rows] = start[rows] + t[done]
        hit_shape[rows] = idx[done]
        nn = _vec3(si.sh_frame.n)
        nn = nn[done]
        flip = np.einsum("ij,ij->i", nn, d[rows]) > 0
        nn[flip] *= -1
        normal[rows] = nn
        start[todo[through]] += t[through] * (1.0 + 1e-6) + 1e-6
        todo = todo[through]
    if not want_albedo:
        return
    hit = hit_shape >= 0
    const = np.zeros((len(ids) + 1, 3), np.float32)
    varying: list[int] = []
    for i, sid in enumerate(ids):
        info = shapes.get(sid)
        if info is None:
            continue
        if info.albedo is not None:
            const[i] = info.albedo
        else:
            varying.append(i)
    albedo[hit] = const[hit_shape[hit]]
    for i in varying:
        rows = np.nonzero(hit_shape == i)[0]
        if len(rows) == 0:
            continue
        si = _intersect(scene, o[rows], d[rows], tn[rows], tf[rows])
        val = _vec3(shapes[ids[i]].albedo_texture.eval(si))
        albedo[rows] = val


def _vec3(v: Any) -> np.ndarray:
    """(N, 3) numpy array from a vectorised 3-vector or colour."""
    return np.stack([np.array(v[j], dtype=np.float64) for j in range(3)], axis=1)


def _intersect(scene: Any, o: np.ndarray, d: np.ndarray, start: np.ndarray, tf: np.ndarray) -> Any:
    oo = o + d * start[:, None]
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(np.ascontiguousarray(oo[:, j], dtype=np.float32)) for j in range(3))),
        mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, j], dtype=np.float32)) for j in range(3))),
    )
    ray.maxt = mi.Float(np.ascontiguousarray(tf - start, dtype=np.float32))
    return scene.ray_intersect(ray)
