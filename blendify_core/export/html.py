"""A self-contained HTML view of a scene (``scene.export("x.html")``, and ``scene.show()`` without a display):
three.js draws the scene's glTF (:mod:`blendify_core.export.gltf`, in the IR's +Z-up axes) from the render
camera, with its exact intrinsics, plus the camera's frustum and the lights; drag to orbit, R goes back to
the render camera.

Everything is inlined (three.js r160.1 and four of its example modules, shipped as package data from the
npm package with their MIT licence, see ``web/SOURCES.md``; the viewer's own ``web/viewer.js``; the scene),
so the page works offline and from any folder.
"""

from __future__ import annotations

import base64
import json
import math
import os
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.export.gltf import glb_bytes, gltf_document
from blendify_core.io.output import atomic_write
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.lights import AreaLight, SunLight
from blendify_core.ir.transforms import look_at_rotation, quaternion_from_rotation
from blendify_core.ir.validate import as_bool, strict_arguments

__all__ = ["export_html", "html_document", "LIBRARIES"]

#: the inlined JavaScript libraries: element id -> file in ``blendify_core/export/web``
LIBRARIES = {
    "lib-three": "three.module.min.js",
    "lib-gltf-loader": "GLTFLoader.js",
    "lib-geometry-utils": "BufferGeometryUtils.js",
    "lib-orbit-controls": "OrbitControls.js",
    "lib-room-environment": "RoomEnvironment.js",
}
_DEFAULT_BACKGROUND = (0.05, 0.05, 0.05)


@cache
def _web_file(name: str) -> str:
    text = resources.files("blendify_core.export").joinpath("web").joinpath(name).read_text(encoding="utf-8")
    if "</script" in text.lower() or "<!--" in text:
        raise RuntimeError(f"{name} cannot be inlined in a <script> element")  # checked by the tests
    return text


def _view_camera(scene: Any) -> Any:
    """The scene's camera, or (none set) a 960x720 camera looking at the scene's bounds."""
    if scene.camera is not None:
        return scene.camera
    bounds = scene.bounds()
    lo, hi = (np.zeros(3) - 1, np.zeros(3) + 1) if bounds is None else bounds
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    eye = centre + np.array([1.0, -1.2, 0.8]) / np.linalg.norm([1.0, -1.2, 0.8]) * radius * 2.6
    q = quaternion_from_rotation("rotmat", look_at_rotation(eye, centre))
    return PerspectiveCamera(
        (960, 720), fov_x=math.radians(50), near=radius * 0.01, far=radius * 20, rotation=q, translation=eye
    )


def _payload(scene: Any, show_helpers: bool) -> tuple[dict[str, Any], list[str]]:
    cam = _view_camera(scene)
    bounds = scene.bounds()
    lo, hi = (cam.translation - 1, cam.translation + 1) if bounds is None else bounds
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    centre = (lo + hi) / 2.0
    # the render camera: intrinsics, pose (column-major, three.js' Matrix4.fromArray) and a look-at distance
    depth = float(np.dot(centre - cam.translation, cam.viewdir))
    info: dict[str, Any] = {
        "type": "orthographic" if isinstance(cam, OrthographicCamera) else "perspective",
        "width": int(cam.width),
        "height": int(cam.height),
        "cx": float(cam.cx),
        "cy": float(cam.cy),
        "near": float(cam.near),
        "far": float(cam.far),
        "matrix": [float(x) for x in cam.matrix_world.T.ravel()],
        "target_distance": depth if depth > cam.near else radius,
    }
    if isinstance(cam, PerspectiveCamera):
        info.update(fx=float(cam.fx), fy=float(cam.fy))
    else:
        info["ortho_scale"] = float(cam.ortho_scale)
    # its frustum: the image corners' rays from the camera to the far side of the scene
    w, h = cam.width, cam.height
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    origins, dirs = cam.pixel_rays(corners)
    reach = max(depth + radius, radius) / max(float(np.min(dirs @ cam.viewdir)), 1e-3)
    far_pts = origins + dirs * reach
    segments = [[origins[i].tolist(), far_pts[i].tolist()] for i in range(4)]
    segments += [[far_pts[i].tolist(), far_pts[(i + 1) % 4].tolist()] for i in range(4)]
    lights = []
    for light in scene.lights:
        item: dict[str, Any] = {
            "kind": type(light).__name__,
            "position": [float(x) for x in light.translation],
            "color": [float(x) for x in np.clip(light.linear_color / max(float(light.linear_color.max()), 1e-9), 0, 1)],
        }
        if isinstance(light, SunLight) or hasattr(light, "spot_size") or isinstance(light, AreaLight):
            item["direction"] = [float(x) for x in light.direction]
        if isinstance(light, AreaLight):
            a, b = light.size
            t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
            if light.shape in ("circle", "ellipse"):
                local = np.stack([a / 2 * np.cos(t), b / 2 * np.sin(t), 0 * t], axis=1)
            else:
                local = np.array([[-a / 2, -b / 2, 0], [a / 2, -b / 2, 0], [a / 2, b / 2, 0], [-a / 2, b / 2, 0]])
            item["outline"] = (local @ light.rotation_matrix.T + light.translation).tolist()
        lights.append(item)
    bg = scene.lights.background
    background = _DEFAULT_BACKGROUND if bg is None else tuple(float(x) for x in np.clip(bg.radiance, 0, 1))
    gltf, blob, notes = gltf_document(scene, y_up=False)
    summary = (
        f"{len(scene.renderables)} renderables, {len(scene.lights)} lights. "
        "drag: orbit, right-drag: pan, wheel: zoom, R: back to the render camera, F: frustum and lights on/off, "
        "H: hide this"
    )
    if scene.camera is None:
        summary = "no camera set: a default view. " + summary
    if notes:  # what the glTF (and so this view) does not show as the renders do
        summary += ". Shown approximately: " + "; ".join(notes)
    payload = {
        "camera": info,
        "frustum": [p for seg in segments for p in seg],
        "lights": lights,
        "marker_size": radius * 0.03,
        "background": list(background),
        "show_helpers": show_helpers,
        "summary": summary,
    }
    return {**payload, "_glb": glb_bytes(gltf, blob)}, notes


@strict_arguments
def html_document(scene: Any, title: str | None = None, show_helpers: bool = True) -> str:
    """The viewer page of ``scene`` as one HTML string (see :func:`export_html`)."""
    show_helpers = as_bool("show_helpers", show_helpers)
    if title is not None and not isinstance(title, str):
        raise InvalidSceneError(f"title: expected a string or None, got {type(title).__name__}")
    payload, _ = _payload(scene, show_helpers)
    glb = base64.b64encode(payload.pop("_glb")).decode("ascii")
    data = json.dumps(payload).replace("</", "<\\/")  # never ends the <script> element
    name = (title or "blendify scene").replace("&", "&amp;").replace("<", "&lt;")
    libs = "\n".join(
        f'<script id="{element}" type="text/plain">{_web_file(file)}</script>' for element, file in LIBRARIES.items()
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{name}</title>
<style>
html, body {{ margin: 0; height: 100%; background: #111; overflow: hidden; }}
#blendify-view {{ display: flex; align-items: center; justify-content: center; width: 100%; height: 100%; }}
#blendify-view canvas {{ display: block; }}
#blendify-status {{ position: fixed; left: 6px; bottom: 6px; margin: 0; padding: 3px 6px; max-width: 90%;
  font: 12px sans-serif; color: #ddd; background: rgba(0, 0, 0, 0.5); border-radius: 3px; }}
</style></head>
<body>
<div id="blendify-view"></div>
<p id="blendify-status">loading the scene...</p>
{libs}
<script id="blendify-glb" type="text/plain">{glb}</script>
<script id="blendify-scene" type="application/json">{data}</script>
<script type="module">
{_web_file("viewer.js")}
</script>
</body></html>
"""


@strict_arguments
def export_html(scene: Any, path: str | os.PathLike[str], title: str | None = None, show_helpers: bool = True) -> Path:
    """Write the offline viewer page of ``scene`` (one self-contained ``.html`` file; open it in any browser
    with WebGL). The view starts at the render camera, drawn with its exact intrinsics (principal point,
    fx != fy) at its resolution's aspect ratio; without a camera, at a default view of the scene. The
    camera's frustum and the lights are drawn as helpers (``show_helpers``; F toggles them). The scene is
    lit by a neutral room and a headlight, not by its own lights. Returns the written path."""
    p = Path(os.fspath(path)).expanduser()
    if p.suffix.lower() not in (".html", ".htm"):
        raise InvalidSceneError(f"path: expected a .html file name, got {str(path)!r}")
    page = html_document(scene, title=title, show_helpers=show_helpers)
    return atomic_write(p, lambda tmp: Path(tmp).write_text(page, encoding="utf-8"))
