"""Large point clouds as one Mitsuba ``linearcurve`` shape: every point an Embree round linear curve of one
segment whose end sphere is the point's sphere (centre and radius exact) and whose start is a smaller sphere
inside it (:func:`sphere_buffers`), all in one shape with one BSDF, its buffers set in memory (Mitsuba 3.9's
curve plugins read only text files: a two-line placeholder is loaded and its buffers replaced through
``mi.traverse``, so no curve file of the points is written or parsed).

Why a sphere inside a sphere and not a short capsule: Embree's round-linear-curve test accepts cone hits
whose projection on the segment, y = (hit - start) . (end - start), is above -2^-23 in absolute squared
world units. A capsule 1e-2 of a 0.0025 radius long (the 6000-point bunny seen from 0.4 units) thereby grew
a cylinder about 3 radii long behind its start: hits up to 3 radii from the point, with cylinder normals
(faceted look) and other points' colours (the hit is on one point's phantom, over another point). When the
start sphere lies inside the end sphere (offset + start radius <= radius) Embree sees no cone at all
(``g <= 0``) and intersects the two spheres exactly; the whole end sphere is kept while offset < (1 - start
radius)^2 (its clipping plane lies behind it). Measured (camera rays 0.4 units away at points of radius
0.0025, 300 random points, and of radius 0.05 at 10 units): every hit is the first exact sphere hit, normals
within 0.03 degrees, every hit reads its own texel. The capsules, on ``testing.pointcloud_catcher_scene``'s
6000 points (3 rays at each): 37 % of the hits were on another point than the one first along the ray, 56 %
read another point's texel.

Measured on ``testing.pointcloud_scene(1_000_000)`` at 128x128, 16 spp (with the capsules,
``benchmarks/results/mitsuba_pointcloud_options.md``): the IR's merged icosphere mesh (80 million triangles)
took 198 s and ~11 GB for the first render; one curve shape takes a few seconds and under 0.5 GB, most of it
Embree's BVH build inside ``mi.load_dict``. Mitsuba 3.9.1's ``ellipsoids`` shape, the other one-shape
option, hits small spheres at the wrong distance (its intersection starts the quadratic from a point off the
ray's closest approach by the factor 1/scale, so in single precision it loses the small sphere; instancing
scales the ray the same way), so it is not used.

Per-point colours (and alphas) are a 1 x N bitmap read at the curve's v = (v_local + segment) / segments:
every hit is on a segment's end sphere (Embree's v_local = 1), and every point's segment is followed by a
spacer segment, so point i reads v = (i + 0.5) / N, the centre of its own texel row. All spacers are one
shared segment of negative radius (:data:`SPACER_RADIUS`), which Embree leaves out of its BVH: 2 segments per
point for the texture, 1 for the BVH build.

Curves are used for opaque, non-emissive, non-transmissive point clouds under a similarity transform (the
backface-culled spheres have no inside and cannot be sampled as emitters) whose points are not too small for
their distance to the camera (:data:`MIN_SIZE_RATIO`): the translator asks :func:`curves_fit`.

Mitsuba is imported inside the functions that use it.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from typing import Any

import numpy as np

from blendify_core.ir.physics import material_lobes

__all__ = [
    "INNER_OFFSET",
    "INNER_RADIUS",
    "MIN_SIZE_RATIO",
    "SPACER_RADIUS",
    "sphere_buffers",
    "curve_file_text",
    "curves_fit",
    "curve_points",
    "point_bitmap",
]

#: each segment starts this many radii behind its point, along the axis ...
INNER_OFFSET = 0.25
#: ... with a sphere of this many radii: inside the point's sphere (INNER_OFFSET + INNER_RADIUS <= 1, so
#: Embree sees no cone), and INNER_OFFSET < (1 - INNER_RADIUS)^2 keeps the whole point sphere
INNER_RADIUS = 0.25
#: the smallest radius / scene extent for curves. Measured (300 random points 4 units from the camera, 30
#: rays within 1.3 radii of each, silhouette grazers left out, against exact spheres): no ray hit or missed
#: wrongly, nor more than 5 % of the radius off, at radius/distance 2.5e-3 down to 1e-5, nor with the points
#: 20 units from the origin (down to 5e-5); the hit's position, rounded at the camera's distance, tilts the
#: normal by ~0.07 degrees at 5e-5. (The earlier capsules: 2 % of the rays wrong at 1.5e-3, 26 % at 7.5e-4,
#: so they stopped at 1e-3.) Smaller points keep the merged icosphere mesh.
MIN_SIZE_RATIO = 5e-5
#: the radius of the shared spacer segment: negative, so Embree drops it from the BVH as an invalid curve,
#: and tiny, so Mitsuba's bounding box (control points grown by their radius) stays the spheres'
SPACER_RADIUS = -1e-30


def curves_fit(
    material: Any, opacity_needed: bool, emissive: bool, matrix: np.ndarray, size_ratio: float = 1.0
) -> str | None:
    """Why a point cloud cannot be one ``linearcurve`` shape (None: it can). ``size_ratio``: the smallest
    world radius over the scene's extent seen from the cloud (the largest distance from the camera to it, or
    the largest coordinate; see :data:`MIN_SIZE_RATIO`)."""
    if size_ratio < MIN_SIZE_RATIO:
        return "points too small for their distance: Embree's single-precision curves would miss them"
    if emissive:
        return "emissive points need an emitter shape"
    if opacity_needed:
        return "alpha < 1 needs the inside of each sphere"
    if material_lobes(material).transmission:
        return "transmission needs the inside of each sphere"
    s = np.linalg.svd(np.asarray(matrix, dtype=np.float64)[:3, :3], compute_uv=False)
    if not np.allclose(s, s[0], rtol=1e-6):
        return "a non-uniform scale turns the spheres into ellipsoids"
    return None


def point_bitmap(values: np.ndarray, tensor: Any = None) -> dict[str, Any]:
    """A ``bitmap`` of one texel row per point ((N, C) linear values), read by :func:`curve_points`'s v.
    ``tensor``: what makes the texel array (None: ``mi.TensorXf``; the exporter passes its stand-in)."""
    if tensor is None:
        import mitsuba as mi

        tensor = mi.TensorXf
    data = np.ascontiguousarray(np.asarray(values, dtype=np.float32).reshape(len(values), 1, -1))
    return {"type": "bitmap", "data": tensor(data), "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}


def sphere_buffers(
    centres: np.ndarray, radii: np.ndarray, axis: Any = (0.0, 0.0, 1.0)
) -> tuple[np.ndarray, np.ndarray]:
    """The ``linearcurve`` buffers of one sphere per point: (2N + 2, 4) float32 control points (x, y, z,
    radius) and (2N,) uint32 segment starts.

    Control point ``2i + 1`` is point ``i``'s sphere (its centre and radius), ``2i`` the start of its segment:
    :data:`INNER_OFFSET` radii behind the centre along ``axis`` (the translator passes the camera's right
    vector), a sphere of :data:`INNER_RADIUS` radii inside the point's, so that Embree intersects the point's
    sphere exactly (no cone: see the module docstring). The last two are one shared spacer segment of negative
    radius at the first point, which Embree leaves out of its BVH (an invalid curve), so the spacers cost no
    build time (measured at 1M points: half the ``mi.load_dict`` time of a spacer of radius 0 per point).
    Segment ``2i`` is point ``i``'s, segment ``2i + 1`` the shared spacer."""
    centres = np.asarray(centres, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    n = len(centres)
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    cp = np.empty((n + 1, 2, 4), np.float32)
    cp[:n, 0, :3] = centres - (radii * INNER_OFFSET)[:, None] * a[None, :]
    cp[:n, 0, 3] = radii * INNER_RADIUS
    cp[:n, 1, :3] = centres
    cp[:n, 1, 3] = radii
    # the shared spacer: at the first point (so the shape's bounding box is the spheres'), radius < 0
    cp[n, :, :3] = centres[0]
    cp[n, :, 3] = SPACER_RADIUS
    segments = np.empty((n, 2), np.uint32)
    segments[:, 0] = np.arange(0, 2 * n, 2, dtype=np.uint32)
    segments[:, 1] = 2 * n
    return cp.reshape(-1, 4), segments.ravel()


def curve_points(centres: np.ndarray, radii: np.ndarray, bsdf: Any, axis: Any = (0.0, 0.0, 1.0)) -> Any:
    """A loaded ``linearcurve`` shape of one sphere per point (world ``centres``, world ``radii``; buffers:
    :func:`sphere_buffers`)."""
    cp, segments = sphere_buffers(centres, radii, axis)
    return curve_shape(cp, segments, bsdf)


def curve_shape(control_points: np.ndarray, segments: np.ndarray, bsdf: Any) -> Any:
    """A loaded ``linearcurve`` shape holding ``control_points`` ((N, 4) float32: x, y, z, radius) and
    ``segments`` (the index of each segment's first control point), set in memory: Mitsuba 3.9.1 builds curves
    only from a file, so a two-point placeholder file is loaded and its buffers replaced."""
    import mitsuba as mi

    cp = np.asarray(control_points, dtype=np.float32)
    fd, path = tempfile.mkstemp(prefix="blendify-curves-", suffix=".txt")
    try:
        os.write(fd, b"0 0 0 1\n0 0 1 1\n")  # a placeholder curve: the real buffers are set below
        os.close(fd)
        shape = mi.load_dict({"type": "linearcurve", "filename": path, "bsdf": bsdf})
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
    params = mi.traverse(shape)
    # the buffers change size: set them without SceneParameters.__setitem__'s equality shortcut
    for key, value in (
        ("control_point_count", len(cp)),
        ("control_points", type(params["control_points"])(cp.ravel())),
        ("segment_indices", type(params["segment_indices"])(np.asarray(segments, dtype=np.uint32).ravel())),
    ):
        cur, value_type, node, _flags = params.properties[key]
        params.set_dirty(key)
        if value_type is None:
            params.set_property(cur, value)
        else:
            params.set_property(cur, value_type, value)
    params.update()
    return shape


def curve_file_text(centres: np.ndarray, radii: np.ndarray, axis: Any = (0.0, 0.0, 1.0)) -> str:
    """The spheres of :func:`sphere_buffers` as a ``linearcurve`` file (one ``x y z radius`` line per control
    point, curves separated by empty lines): the text format has no shared spacer, so every point is a curve
    of three control points, its segment and a spacer segment to a point of negative radius at its centre
    (Embree leaves it out, as the shared one, and it clips nothing of the sphere: the spacer has no length;
    the texel rows read at v stay the same: two segments per point)."""
    cp, _segments = sphere_buffers(centres, radii, axis)
    n = (len(cp) - 2) // 2
    rows = np.empty((n, 3, 4), np.float32)
    rows[:, :2] = cp[: 2 * n].reshape(n, 2, 4)
    rows[:, 2, :3] = rows[:, 1, :3]
    rows[:, 2, 3] = SPACER_RADIUS
    line = "%.9g %.9g %.9g %.9g\n"
    block = line * 3 + "\n"
    flat = rows.reshape(n, 12).astype(np.float64)
    chunk = 4096
    return "".join((block * len(part)) % tuple(part.ravel()) for part in np.array_split(flat, max(1, n // chunk)))
