"""Re-centring far-away scenes in float64 before any engine sees them.

Engines work in float32, whose spacing at 1e6 is 6 cm: a 1 m object a thousand kilometres from the origin
would jitter and crack. :func:`recentred_view` returns a view of the scene translated so that the camera
sits near the origin (and, for geometry given in far-away object coordinates, with the vertices shifted
towards their own centre), computed in float64. Pictures, depth and normals are unchanged by a
translation; only the numbers handed to the engine become small.

The view keeps every object's ``uid``; its revisions are tuples that include the chosen origin, so a
backend's cache stays valid while the origin does not move (the origin is snapped to a grid the size of
the scene, so small camera moves keep it).
"""

from __future__ import annotations

import copy
import enum
from collections.abc import Hashable
from typing import Literal, TypeVar

import numpy as np

from blendify_core._memo import magnitude_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.cameras import Camera
from blendify_core.ir.lights import LightsCollection
from blendify_core.ir.renderables import RenderablesCollection, _column_bounds
from blendify_core.ir.scene import Scene
from blendify_core.ir.transforms import Positionable
from blendify_core.typing import Float64Array, FloatArray

__all__ = ["needs_recentring", "recentred_view", "Bounds", "FAR_RATIO"]

#: re-centre when coordinates exceed this many times the scene's size
FAR_RATIO = 1e3

#: world-space axis-aligned bounds (lo, hi) of a scene's renderables, as ``Scene.bounds()`` returns them
Bounds = tuple[Float64Array, Float64Array]

_P = TypeVar("_P", bound=Positionable)


class _Unknown(enum.Enum):
    BOUNDS = "not computed yet"


_BOUNDS_UNKNOWN = _Unknown.BOUNDS
_MaybeBounds = Bounds | None | Literal[_Unknown.BOUNDS]


def _camera(scene: Scene) -> Camera:
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera")
    return scene.camera


def _scene_scale(scene: Scene, bounds: _MaybeBounds = _BOUNDS_UNKNOWN) -> tuple[float, float]:
    """(largest coordinate magnitude, scene size) from the camera position and the bounds
    (``bounds``: ``scene.bounds()`` when the caller has it already)."""
    cam = _camera(scene)
    magnitude = float(np.abs(cam.translation).max())
    if bounds is _BOUNDS_UNKNOWN:
        bounds = scene.bounds()
    if bounds is None:
        return magnitude, 1.0
    lo, hi = bounds
    magnitude = max(magnitude, float(np.abs(lo).max()), float(np.abs(hi).max()))
    centre = (lo + hi) / 2
    size = max(float(np.linalg.norm(hi - lo)), float(np.linalg.norm(cam.translation - centre)), 1e-300)
    return magnitude, size


def _magnitude_and_size(v: FloatArray) -> tuple[float, float]:
    lo, hi = _column_bounds(v)
    return float(max(np.abs(lo).max(), np.abs(hi).max())), float(np.linalg.norm(hi - lo))


def _vertex_magnitude(r: Positionable) -> tuple[float, float]:
    for attr in ("_vertices", "keypoints"):
        v = getattr(r, attr, None)
        if v is not None and len(v):
            magnitude, size = magnitude_memo(v, _magnitude_and_size)
            return float(magnitude), float(size)
    return 0.0, 1.0


def needs_recentring(scene: Scene, bounds: _MaybeBounds = _BOUNDS_UNKNOWN) -> bool:
    """True when the scene's coordinates are so large relative to its size that float32 engines would
    lose precision (see :func:`recentred_view`)."""
    magnitude, size = _scene_scale(scene, bounds)
    if magnitude > FAR_RATIO * size:
        return True
    for r in scene.renderables:
        m, s = _vertex_magnitude(r)
        if m > FAR_RATIO * max(s, 1e-300):  # spans < 1e-3 of its coordinates: float32 keeps < ~2e4 steps across it
            return True
    return False


def _snap(x: Float64Array, grid: float) -> Float64Array:
    snapped: Float64Array = np.round(x / grid) * grid
    return snapped


class _Revisions:
    """Revisions of a view object: the original's, tagged with the view's origin."""

    def __init__(self, original: Positionable, key: Hashable, geometry_key: Hashable = None) -> None:
        self._original = original
        self._key = key
        self._geometry_key = geometry_key

    def __call__(self, kind: str) -> Hashable:
        base = self._original.revision(kind)
        if kind == "transform":
            return (base, self._key)
        if kind == "geometry" and self._geometry_key is not None:
            return (base, self._geometry_key)
        return base


def _shift_object(obj: _P, origin: Float64Array, key: Hashable) -> _P:
    view = copy.copy(obj)
    geometry_key = None
    rot = obj.rotation_matrix
    translation = obj.translation - origin
    for attr in ("_vertices", "keypoints"):
        v = getattr(obj, attr, None)
        if v is None or not len(v):
            continue
        m, s = float(np.abs(v).max()), float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        if m > FAR_RATIO * max(s, 1e-300):  # spans < 1e-3 of its coordinates: float32 keeps < ~2e4 steps across it
            c = _snap((v.max(axis=0) + v.min(axis=0)) / 2, max(s, 1e-12))
            shifted = np.asarray(v, dtype=np.float64) - c
            shifted.flags.writeable = False
            # straight into the view's __dict__: `keypoints` is a validated parameter whose setter would
            # bump the revision counters the view shares with the original object
            view.__dict__["_keypoints" if attr == "keypoints" else attr] = shifted
            translation = translation + rot @ c
            geometry_key = ("shift", tuple(c.tolist()))
    view._translation = translation
    view._translation.flags.writeable = False
    view.__dict__["revision"] = _Revisions(obj, key, geometry_key)  # the instance's revision(kind)
    return view


def recentred_view(scene: Scene, bounds: _MaybeBounds = _BOUNDS_UNKNOWN) -> tuple[Scene, Float64Array]:
    """A view of ``scene`` translated by ``-origin`` (float64) and the origin used."""
    magnitude, size = _scene_scale(scene, bounds)
    grid = float(2.0 ** np.ceil(np.log2(max(size, 1e-300))))
    cam = _camera(scene)
    origin = _snap(cam.translation, grid)
    key = ("recentred", tuple(origin.tolist()))
    view = scene.with_camera(_shift_object(cam, origin, key))
    renderables = RenderablesCollection()
    for r in scene.renderables:
        renderables._items[r.tag] = _shift_object(r, origin, key)
    renderables.revision = (scene.renderables.revision, key)  # type: ignore[assignment]
    lights = LightsCollection()
    for light in scene.lights:
        lights._lights[light.tag] = _shift_object(light, origin, key)
    lights.background = scene.lights.background
    lights.environment = scene.lights.environment
    lights.revision = (scene.lights.revision, key)  # type: ignore[assignment]
    view.renderables = renderables
    view.lights = lights
    return view, origin
