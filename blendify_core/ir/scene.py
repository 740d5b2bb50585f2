"""The scene: renderables, lights and one camera. A plain object; any number may coexist."""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import Camera, OrthographicCamera, PerspectiveCamera, camera_from_opencv
from blendify_core.ir.lights import LightsCollection
from blendify_core.ir.renderables import RenderablesCollection
from blendify_core.ir.serialize import fingerprint, load_scene, save_scene
from blendify_core.ir.validate import as_bool, strict_api, strict_arguments
from blendify_core.registry import FORMAT_SUFFIXES, backend_for_format, core_tool, exporter_for_format
from blendify_core.typing import AnyArray

__all__ = ["Scene"]

#: blendify 2.1's Scene methods that blendify-core spells differently
_BLENDIFY_METHODS = {
    "render": "bf.render(scene, backend, quality='final', samples=..., outputs=(...)) (returns a RenderResult)",
    "preview": "bf.render(scene, quality='preview')",
    "read_image": "the arrays of the RenderResult (result.rgba, result.depth, ...)",
    "read_exr_distmap": "result.depth of bf.render(scene, outputs=('rgb', 'depth'))",
    "check_any_exists": "pathlib.Path(...).exists()",
}


@strict_api
class Scene:
    """A scene described in plain numpy: ``scene.renderables``, ``scene.lights`` and ``scene.camera``."""

    def __init__(self) -> None:
        self.renderables = RenderablesCollection()
        self.lights = LightsCollection()
        self._camera: Camera | None = None
        #: files attached for a backend that understands their format (``attach_blend`` adds .blend files)
        self.attachments: list[Attachment] = []

    # -- camera ------------------------------------------------------------------------------------
    @property
    def camera(self) -> Camera | None:
        return self._camera

    @camera.setter
    def camera(self, value: Camera | None) -> None:
        if value is not None and not isinstance(value, Camera):
            raise InvalidSceneError(f"camera: expected a PerspectiveCamera or OrthographicCamera, got {type(value)}")
        self._camera = value

    @strict_arguments
    def set_perspective_camera(
        self,
        resolution: Any,
        focal_dist: float | None = None,
        fov_x: float | None = None,
        fov_y: float | None = None,
        center: Any = None,
        near: float = 0.1,
        far: float = 100.0,
        tag: str = "camera",
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        resolution_percentage: int = 100,
        K: Any = None,  # noqa: N803
        distortion: Any = None,
    ) -> PerspectiveCamera:
        """Replace the camera by a pinhole camera (see :class:`PerspectiveCamera`)."""
        cam = PerspectiveCamera(
            resolution,
            focal_dist=focal_dist,
            fov_x=fov_x,
            fov_y=fov_y,
            center=center,
            K=K,
            near=near,
            far=far,
            distortion=distortion,
            tag=tag,
            resolution_percentage=resolution_percentage,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
        )
        self._camera = cam
        return cam

    @strict_arguments
    def set_orthographic_camera(
        self,
        resolution: Any,
        ortho_scale: float = 1.0,
        near: float = 0.1,
        far: float = 100.0,
        tag: str = "camera",
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        resolution_percentage: int = 100,
        center: Any = None,
    ) -> OrthographicCamera:
        """Replace the camera by an orthographic camera seeing ``ortho_scale`` world units across."""
        cam = OrthographicCamera(
            resolution,
            ortho_scale=ortho_scale,
            near=near,
            far=far,
            center=center,
            tag=tag,
            resolution_percentage=resolution_percentage,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
        )
        self._camera = cam
        return cam

    @strict_arguments
    def set_camera_from_opencv(
        self,
        K: Any,
        R: Any,
        t: Any,
        resolution: Any,
        distortion: Any = None,  # noqa: N803
        near: float = 0.1,
        far: float = 100.0,
    ) -> PerspectiveCamera:
        """Set a pinhole camera from OpenCV intrinsics ``K`` and extrinsics ``x_cam = R @ x_world + t``.
        The way back is ``scene.camera.K`` and ``scene.camera.opencv_extrinsics()``."""
        cam = camera_from_opencv(K, R, t, resolution, distortion, near, far)
        self._camera = cam
        return cam

    # -- views used by the renderer ----------------------------------------------------------------
    def with_camera(self, camera: Camera) -> Scene:
        """A shallow view of this scene (same renderables and lights) with another camera."""
        if not isinstance(camera, Camera):
            raise InvalidSceneError(
                f"camera: expected a PerspectiveCamera or OrthographicCamera, got {type(camera).__name__}"
            )
        view = copy.copy(self)
        view._camera = camera
        return view

    def clear(self) -> None:
        self.renderables.clear()
        self.lights.clear()
        self._camera = None

    # -- files -------------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str], relative_paths: bool = True) -> None:
        """Write the scene to one portable ``.npz`` file (JSON header + arrays, no pickle), atomically.
        Texture files are referenced by path (relative to the scene file when ``relative_paths``)."""
        save_scene(self, path, relative_paths=as_bool("relative_paths", relative_paths))

    @classmethod
    def load(cls, path: str | os.PathLike[str], allow_outside: bool = False) -> Scene:
        """Read a scene file. Relative texture paths resolve against the file's folder and may not leave
        it unless ``allow_outside=True``."""
        allow = as_bool("allow_outside", allow_outside)
        return load_scene(cls(), path, allow_outside=allow)  # type: ignore[no-any-return]

    def fingerprint(self) -> str:
        """A stable content hash (hex SHA-256) of everything that affects the picture."""
        return fingerprint(self)

    # -- files of a backend's own format (found through the registry; .blend: the Cycles backend) ------
    @property
    def attached_blends(self) -> tuple[str, ...]:
        """Paths of the attached .blend files (read-only: the ``"blend"`` entries of :attr:`attachments`)."""
        return tuple(a.path for a in self.attachments if a.format == "blend")

    def export_blend(self, path: str | os.PathLike[str], **kwargs: Any) -> None:
        """Write a .blend file that renders this scene in Blender (needs the ``cycles`` backend)."""
        backend_for_format("blend").export_file(self, "blend", path, **kwargs)

    def attach_blend(self, path: str | os.PathLike[str], with_camera: bool = False, **kwargs: Any) -> Any:
        """Import a .blend file's meshes, materials, lights (and camera) into this scene (needs ``cycles``)."""
        return backend_for_format("blend").attach_file(self, "blend", path, with_camera=with_camera, **kwargs)

    # -- standard formats and a look before rendering (docs/export.md) -------------------------------
    def export(self, path: str | os.PathLike[str], format: str | None = None, **kwargs: Any) -> Any:  # noqa: A002
        """Write the scene to ``path`` in the format its suffix names: ``.glb`` / ``.gltf`` (glTF 2.0,
        written by the core), ``.html`` (the offline viewer page), ``.blend`` (needs ``cycles``), ``.xml``
        (a Mitsuba 3 scene, needs ``mitsuba``); ``format`` overrides the suffix. ``kwargs`` go to the
        exporter (e.g. ``y_up=False`` for glTF). Returns the written path."""
        if format is None:
            suffix = Path(os.fspath(path)).suffix.lower()
            format = FORMAT_SUFFIXES.get(suffix)
            if format is None:
                raise InvalidSceneError(
                    f"path: cannot tell the format from the suffix {suffix!r}; expected one of "
                    f"{sorted(FORMAT_SUFFIXES)} or format=..."
                )
        elif format not in FORMAT_SUFFIXES.values():
            raise InvalidSceneError(f"format: expected one of {sorted(set(FORMAT_SUFFIXES.values()))}, got {format!r}")
        return exporter_for_format(format)(self, path, **kwargs)

    def export_mitsuba(self, path: str | os.PathLike[str], **kwargs: Any) -> Any:
        """Write a Mitsuba 3 scene file (``mitsuba.load_file`` renders it as the ``mitsuba`` backend does);
        meshes go to ``.ply`` files in a folder beside it. Needs the ``mitsuba`` backend."""
        return self.export(path, format="mitsuba", **kwargs)

    def show(self, **kwargs: Any) -> Any:
        """Look at the scene before rendering: pyrender's interactive viewer when a display exists,
        otherwise a self-contained HTML page (three.js, offline) shown inline in a notebook or written
        to a file. See :func:`blendify_core.export.viewer.show` for the keywords."""
        return core_tool("show")(self, **kwargs)

    # -- summaries -------------------------------------------------------------------------------
    def bounds(self) -> tuple[AnyArray, AnyArray] | None:
        """World-space axis-aligned bounds of all renderables, or None for an empty scene."""
        boxes = [r.world_bounds() for r in self.renderables]
        if not boxes:
            return None
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        return lo, hi

    def __getattr__(self, name: str) -> Any:
        # only reached for attributes the scene does not have: blendify 2.1's scene methods say what to call
        if name in _BLENDIFY_METHODS:
            raise AttributeError(f"Scene.{name}: blendify 2.1's method; did you mean {_BLENDIFY_METHODS[name]}?")
        raise AttributeError(f"'Scene' object has no attribute {name!r}")

    def __repr__(self) -> str:
        cam = type(self._camera).__name__ if self._camera else "no camera"
        return f"Scene({len(self.renderables)} renderables, {len(self.lights)} lights, {cam})"
