"""export_blend: write an IR scene as a .blend that opens in Blender and renders the same picture.

The bpy scene is built by the Cycles translator (:func:`blendify_blender.translate.build_scene`, the
same translation the renders use), the images are packed into the file and it is written with
``bpy.data.libraries.write`` (no ``.blend1`` backup, the main file and the working directory are
untouched). Objects carry their IR tag as the custom property ``blendify_tag``, so an exported scene
attaches back (:func:`blendify_blender.blendfile.attach_blend`) with the same tags.

This module sits above the translator, which sits above the .blend parsing and safety package (blendfile/).
"""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path
from typing import Any

from blendify_blender import session
from blendify_blender.blendfile.common import TAG_PROPERTY
from blendify_blender.blendfile.settings import PORTABLE_KEYS, SETTINGS_PROPERTY
from blendify_blender.render import set_sample_window
from blendify_blender.translate import build_scene
from blendify_core.errors import InvalidSceneError, OutputError, RenderError
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, strict_arguments
from blendify_core.pipeline.settings import resolve_settings

__all__ = ["export_blend"]


@strict_arguments
def export_blend(scene: Any, path: str | os.PathLike[str], pack_textures: bool = True, **settings: Any) -> Path:
    """Write ``scene`` as a .blend that opens in Blender and renders the same picture.

    The bpy scene is built by the Cycles translator (:func:`blendify_blender.translate.build_scene`,
    which resets the bpy session to an empty factory scene first); in-memory images are always packed,
    texture FILES are packed when ``pack_textures`` (default; otherwise referenced by absolute path),
    each object gets its IR tag as the custom property ``blendify_tag`` (so ``attach_blend`` gives
    the same tags back), and the file is written with ``bpy.data.libraries.write`` to a temporary name
    then renamed: no ``.blend1`` backup, the main file path and the working directory do not change.
    The built datablocks are removed afterwards. ``settings`` are render settings
    (:func:`blendify_core.pipeline.settings.resolve_settings` keywords, e.g. ``quality="final", samples=64``)
    stored in the file; the file renders the samples blendify's colour renders take (a sample subset past
    Cycles' first sample, :func:`blendify_blender.render.sample_window`). Returns the written path.
    """
    out, render_settings = _checked_arguments(scene, path, pack_textures, settings)
    bpy = session.bpy_module()
    with session.BPY_LOCK:
        built = build_scene(scene, render_settings, reset=True)
        tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp.blend")
        try:
            with session.capture_output("export .blend") as cap, session.engine_errors("export_blend", cap):
                _tag_objects(scene, built)
                bl_scene = built.bscene
                # the blendify settings, read back by attach_blend(render_settings=True) as given
                bl_scene[SETTINGS_PROPERTY] = json.dumps({k: getattr(render_settings, k) for k in PORTABLE_KEYS})
                # Blender renders the file's colour from the samples blendify's colour renders take
                set_sample_window(bl_scene.cycles, int(bl_scene.cycles.samples))
                for img in _scene_images(bpy, bl_scene):
                    # in-memory images (no file behind them) are always packed, files only when asked
                    in_memory = img.source == "GENERATED" or not (img.filepath_raw or img.filepath)
                    if img.packed_file is None and (in_memory or (pack_textures and img.source == "FILE")):
                        img.pack()
                bpy.data.libraries.write(str(tmp), {bl_scene}, path_remap="ABSOLUTE", fake_user=False, compress=True)
            os.replace(tmp, out)
        except OSError as exc:
            raise RenderError(f"export_blend: could not write {str(out)!r}: {exc}") from exc
        finally:
            if tmp.exists():
                tmp.unlink()
            built.remove()
    return out


def _checked_arguments(scene: Any, path: Any, pack_textures: Any, settings: dict[str, Any]) -> tuple[Path, Any]:
    """(absolute output path, its folder created; resolved render settings), or InvalidSceneError."""
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core Scene, got {type(scene).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidSceneError(f"path: expected a file path ending in .blend, got {type(path).__name__} {path!r}")
    out = Path(path).expanduser()
    if out.suffix.lower() != ".blend":
        raise InvalidSceneError(f"path: expected a file name ending in .blend, got {str(out)!r}")
    if out.is_dir():
        raise OutputError(f"path: {str(out)!r} is a directory, not a .blend file to write", str(out), errno.EISDIR)
    pack_textures = as_bool("pack_textures", pack_textures)
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera; call scene.set_perspective_camera(...) first")
    try:
        render_settings = resolve_settings(**settings)
    except TypeError as exc:
        raise InvalidSceneError(f"export_blend: unknown render setting(s) {sorted(settings)} ({exc})") from None
    out = out.absolute()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(
            f"path: cannot create the folder {str(out.parent)!r} ({exc})", str(out.parent), exc.errno
        ) from None
    return out, render_settings


def _tag_objects(scene: Any, built: Any) -> None:
    """Store each IR tag on the first Blender object built for it (custom property ``blendify_tag``)."""
    for r in scene.renderables:
        entry = built.entries.get(r.uid)
        if entry is not None and entry.objects:
            entry.objects[0][TAG_PROPERTY] = r.tag
    for light, obj in zip(scene.lights, built.lights.objects):
        obj[TAG_PROPERTY] = light.tag
    if built.camera_object is not None:
        built.camera_object[TAG_PROPERTY] = scene.camera.tag


def _scene_images(bpy: Any, bl_scene: Any) -> list[Any]:
    """Images used by the objects' materials and the world of ``bl_scene``."""
    seen: dict[int, Any] = {}

    def walk(tree: Any) -> None:
        if tree is None:
            return
        for n in tree.nodes:
            img = getattr(n, "image", None)
            if img is not None and isinstance(img, bpy.types.Image):
                seen[img.as_pointer()] = img
            sub = getattr(n, "node_tree", None)
            if sub is not None and sub.as_pointer() not in seen:
                seen[sub.as_pointer()] = None
                walk(sub)

    for ob in bl_scene.objects:
        for slot in ob.material_slots:
            if slot.material is not None:
                walk(slot.material.node_tree)
        for md in ob.modifiers:
            if md.type == "NODES" and md.node_group is not None:
                walk(md.node_group)
    if bl_scene.world is not None:
        walk(bl_scene.world.node_tree)
    return [i for i in seen.values() if i is not None]
