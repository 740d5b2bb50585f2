"""Large point clouds as one Mitsuba ``linearcurve`` shape: every point an Embree round linear curve of one
short segment (a sphere-capped capsule centred on the point, 1e-4..1e-2 of the radius long: see
:func:`capsule_length`), all in one shape with one BSDF, its buffers set in memory (Mitsuba 3.9's curve
plugins read only text files: a two-line placeholder is loaded and its buffers replaced through
``mi.traverse``, so no curve file of the points is written or parsed).

Measured on ``testing.pointcloud_scene(1_000_000)`` at 128x128, 16 spp
(``benchmarks/results/mitsuba_pointcloud_options.md``): the IR's merged icosphere mesh (80 million triangles)
took 198 s and ~11 GB for the first render; one curve shape takes a few seconds and under 0.5 GB, most of it
Embree's BVH build inside ``mi.load_dict``. Geometric accuracy, against exact spheres, for camera rays aimed
near points of radius 0.015 seen from 4 units: no ray hits where a sphere is missed or the other way round,
0.15 % of the hits are more than 5 % of the radius off (the icosphere mesh, whose faces lie up to 5 % of the
radius inside the sphere: 80 %). Shorter capsules are not more exact there: at 0.1 % of that radius a third
of such hits are more than 5 % of the radius off (Embree's single precision). Mitsuba 3.9.1's
``ellipsoids`` shape, the other one-shape option, hits small spheres at the wrong distance (its
intersection starts the quadratic from a point off the ray's closest approach by the factor 1/scale, so in
single precision it loses the small sphere; instancing scales the ray the same way), so it is not used.

Per-point colours (and alphas) are a 1 x N bitmap read at the curve's v = (v_local + segment) / segments:
every point's capsule is followed by a spacer segment so that v stays inside the point's own texel row
(v_local is 1 on the end cap). All spacers are one shared segment of negative radius (:data:`SPACER_RADIUS`),
which Embree leaves out of its BVH: 2 segments per point for the texture, 1 for the BVH build.

Curves are used for opaque, non-emissive, non-transmissive point clouds under a similarity transform (the
backface-culled capsules have no inside, cannot be sampled as emitters, and are round) whose points are not
too small for their distance to the camera (:data:`MIN_SIZE_RATIO`): the translator asks :func:`curves_fit`.

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
    "CAPSULE_LENGTH",
    "CAPSULE_SPACINGS",
    "MIN_CAPSULE_LENGTH",
    "MIN_SIZE_RATIO",
    "SPACER_RADIUS",
    "capsule_buffers",
    "capsule_length",
    "curve_file_text",
    "curves_fit",
    "curve_points",
    "point_bitmap",
]

#: the longest capsule segment, relative to the point's radius (the points smallest for their distance)
CAPSULE_LENGTH = 1e-2
#: the shortest capsule segment, relative to the radius (the shortest measured to be intersected cleanly)
MIN_CAPSULE_LENGTH = 1e-4
#: the capsule's segment in float32 spacings (2^-23) of the scene's extent (camera distance, coordinates).
#: Measured (camera rays aimed at points 4-5 units away, against exact spheres): at 25 spacings a third of
#: the hits are more than 5 % of the radius off, at 80 none, at 250 (radius 0.015, length 1e-2) none.
CAPSULE_SPACINGS = 250.0
#: the smallest radius / camera distance for curves. Measured (camera rays aimed at points 4 units away,
#: against exact spheres): radius/distance 2.5e-3: 0.17 % of the rays hit or miss wrongly, 1.5e-3: 0.27 %,
#: 7.5e-4: 7.8 %. Smaller points keep the merged icosphere mesh.
MIN_SIZE_RATIO = 1e-3
#: the radius of the shared spacer segment: negative, so Embree drops it from the BVH as an invalid curve,
#: and tiny, so Mitsuba's bounding box (control points grown by their radius) stays the capsules'
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


def capsule_length(size_ratio: float) -> float:
    """The capsule's segment length relative to the radius for a cloud whose smallest radius over the scene's
    extent (the farthest camera distance or coordinate) is ``size_ratio``: :data:`CAPSULE_SPACINGS` float32
    spacings of that extent, within [:data:`MIN_CAPSULE_LENGTH`, :data:`CAPSULE_LENGTH`]. The capsule differs
    from the sphere by about half its length, so a point large for its distance gets a shorter, closer one
    (depth within ~2e-5 relative of the exact sphere where the length is not at its upper bound)."""
    if not np.isfinite(size_ratio) or size_ratio <= 0:
        return CAPSULE_LENGTH
    return float(np.clip(CAPSULE_SPACINGS * 2.0**-23 / size_ratio, MIN_CAPSULE_LENGTH, CAPSULE_LENGTH))


def point_bitmap(values: np.ndarray, tensor: Any = None) -> dict[str, Any]:
    """A ``bitmap`` of one texel row per point ((N, C) linear values), read by :func:`curve_points`'s v.
    ``tensor``: what makes the texel array (None: ``mi.TensorXf``; the exporter passes its stand-in)."""
    if tensor is None:
        import mitsuba as mi

        tensor = mi.TensorXf
    data = np.ascontiguousarray(np.asarray(values, dtype=np.float32).reshape(len(values), 1, -1))
    return {"type": "bitmap", "data": tensor(data), "raw": True, "filter_type": "nearest", "wrap_mode": "clamp"}


def capsule_buffers(
    centres: np.ndarray, radii: np.ndarray, length: float = CAPSULE_LENGTH, axis: Any = (0.0, 0.0, 1.0)
) -> tuple[np.ndarray, np.ndarray]:
    """The ``linearcurve`` buffers of one capsule per point: (2N + 2, 4) float32 control points (x, y, z,
    radius) and (2N,) uint32 segment starts.

    Control points ``2i`` and ``2i + 1`` are point ``i``'s capsule, centred on the point along ``axis`` (the
    translator passes the camera's right vector: Mitsuba 3.9's curves miss an orthographic camera's rays
    within about a degree of their axis -- a cloud seen straight down along z vanished; radius
    shrunk so that the capsule's surface, hence its mean projected area, is the sphere's:
    4 pi r'^2 (1 + L/2) = 4 pi r^2); the last two are one shared spacer segment of negative radius at the first
    point, which Embree leaves out of its BVH (an invalid curve), so the spacers cost no build time (measured
    at 1M points: half the ``mi.load_dict`` time of a spacer of radius 0 per point). Segment ``2i`` is point
    ``i``'s capsule, segment ``2i + 1`` the shared spacer."""
    centres = np.asarray(centres, dtype=np.float64)
    n = len(centres)
    r = np.asarray(radii, dtype=np.float64) / np.sqrt(1.0 + length / 2.0)
    cp = np.empty((n + 1, 2, 4), np.float32)
    cp[:n, :, :3] = centres[:, None, :]
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    offset = (r * (length / 2.0))[:, None] * a[None, :]
    cp[:n, 0, :3] -= offset
    cp[:n, 1, :3] += offset
    cp[:n, :, 3] = r[:, None]
    # the shared spacer: at the first point (so the shape's bounding box is the capsules'), radius < 0
    cp[n, :, :3] = centres[0]
    cp[n, :, 3] = SPACER_RADIUS
    segments = np.empty((n, 2), np.uint32)
    segments[:, 0] = np.arange(0, 2 * n, 2, dtype=np.uint32)
    segments[:, 1] = 2 * n
    return cp.reshape(-1, 4), segments.ravel()


def curve_points(
    centres: np.ndarray, radii: np.ndarray, bsdf: Any, length: float = CAPSULE_LENGTH, axis: Any = (0.0, 0.0, 1.0)
) -> Any:
    """A loaded ``linearcurve`` shape of one capsule per point (world ``centres``, world ``radii``; ``length``:
    the segment relative to the radius, see :func:`capsule_length`; buffers: :func:`capsule_buffers`)."""
    cp, segments = capsule_buffers(centres, radii, length, axis)
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


def curve_file_text(
    centres: np.ndarray, radii: np.ndarray, length: float = CAPSULE_LENGTH, axis: Any = (0.0, 0.0, 1.0)
) -> str:
    """The capsules of :func:`capsule_buffers` as a ``linearcurve`` file (one ``x y z radius`` line per control
    point, curves separated by empty lines): the text format has no shared spacer, so every point is a curve
    of three control points, its capsule and a spacer segment to a point of negative radius (Embree leaves it
    out, as the shared one; the texel rows read at v stay the same: two segments per point)."""
    cp, _segments = capsule_buffers(centres, radii, length, axis)
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
