"""``scene.show()`` with a display: pyrender's interactive Viewer (a pyglet window) on the scene as this
backend translates it (the same meshes, lights, ambient light and camera as its renders).

The Viewer needs an on-screen OpenGL platform (GLX on Linux): a process that already rendered offscreen
with this backend has chosen EGL or OSMesa for good, and is told so (BackendUnavailableError; the core then
writes the HTML view instead).
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.pipeline.translator import TranslationContext

from .translate import DIFFUSE_COMPENSATION, PyrenderTranslator

__all__ = ["build_viewer_scene", "show_scene"]


def _check_platform() -> None:
    platform = os.environ.get("PYOPENGL_PLATFORM", "")
    if "OpenGL" in sys.modules and platform in ("egl", "osmesa"):
        raise BackendUnavailableError(
            f"pyrender viewer: this process already uses the offscreen OpenGL platform {platform!r} (from a "
            "pyrender render); call scene.show() before rendering, or use scene.show(viewer='html')"
        )


def build_viewer_scene(scene: Any) -> tuple[Any, tuple[int, int]]:
    """A ``pyrender.Scene`` of ``scene`` (meshes, lights, ambient light, the camera as its main camera) and
    the camera's resolution."""
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the pyrender viewer starts at the scene's camera; set one first")
    import pyrender

    from .render import MatrixCamera

    tr = PyrenderTranslator()
    ctx = TranslationContext()
    ambient = np.zeros(3)
    for world in (scene.lights.background, scene.lights.environment):
        if world is not None:
            ambient = ambient + tr.dispatch(world, ctx)
    pscene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=ambient * DIFFUSE_COMPENSATION)  # as the session
    for r in scene.renderables:
        built = tr.dispatch(r, TranslationContext())
        if built.mesh is not None:
            offset = np.eye(4)
            offset[:3, 3] = built.offset
            pscene.add(built.mesh, name=r.tag, pose=r.matrix_world @ offset)
    for light in scene.lights:
        lb = tr.dispatch(light, ctx)
        if lb is not None:
            pscene.add(lb.light, name=light.tag, pose=lb.pose)
    cam = tr.dispatch(scene.camera, ctx)
    pscene.add(MatrixCamera(cam.projection, cam.znear, cam.zfar), name="camera", pose=cam.pose)
    return pscene, (int(scene.camera.width), int(scene.camera.height))


def show_scene(scene: Any, **viewer_kwargs: Any) -> Any:
    """Open pyrender's Viewer on ``scene`` (blocks until the window is closed unless
    ``run_in_thread=True``); ``viewer_kwargs`` go to ``pyrender.Viewer``. Returns the Viewer."""
    _check_platform()
    try:
        pscene, size = build_viewer_scene(scene)
        import pyrender

        return pyrender.Viewer(pscene, viewport_size=size, **viewer_kwargs)
    except (BackendUnavailableError, InvalidSceneError):
        raise
    except Exception as exc:  # no display, no GLX, pyglet missing, ...
        raise BackendUnavailableError(f"pyrender viewer: cannot open a window ({type(exc).__name__}: {exc})") from exc
