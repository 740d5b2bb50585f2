"""attach_blend: parse a .blend into the IR; append_blend_scenes: its raw content for Cycles renders.

:func:`attach_blend` reads a .blend WITHOUT opening it as Blender's main file: the file's scenes are
appended into the running bpy session under the auto-run guard (:mod:`.safety`: embedded Python never
runs), parsed into the numpy IR, and every datablock the load created is removed again before
returning, so the bpy session (and the Cycles backend's state) is left as it was.

The objects are evaluated through the depsgraph with the RENDER visibility and the render subdivision
levels of their modifiers, then parsed (``scene`` must be a :class:`blendify_core.ir.scene.Scene`):

- meshes, everything that converts to a mesh, and point clouds (:mod:`.geometry`), with their
  materials and colour sources (:mod:`.nodes`, images by :mod:`.images`); ``visible_shadow`` ->
  ``emit_shadows``; an object's IR tag is its name, or the ``blendify_tag`` custom property written by
  ``export_blend``, so an exported scene attaches back with the same tags;
- lights and the world (:mod:`.lights`); the world is imported only when the scene has neither a
  background nor an environment yet, unless ``with_world=True``;
- with ``with_camera=True``: the scene camera (:mod:`.camera`).

What cannot be parsed (procedural shader trees, volumes, hair curves, panoramic cameras, Python drivers,
depth of field, shadow catchers, ...) is listed in ONE :class:`BlendAttachWarning` (also in the result's
``unparsed``). The parsed objects are added all or nothing. The resolved file path is appended to
``scene.attachments`` (``Attachment("blend", path)``, also in ``scene.attached_blends``), so the Cycles
backend can append the raw file content again for Cycles-only rendering of those features, through
:func:`append_blend_scenes` (same protections; the caller owns and removes the new datablocks); the
other backends render the parsed IR.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from blendify_blender import session
from blendify_blender.blendfile.bake import DEFAULT_BAKE_RESOLUTION, Baker
from blendify_blender.blendfile.camera import camera_spec
from blendify_blender.blendfile.common import Notes, matrix_array, saved_tag
from blendify_blender.blendfile.geometry import MESH_TYPES, mesh_spec, points_spec
from blendify_blender.blendfile.images import ImageReader
from blendify_blender.blendfile.lights import light_spec, world_specs
from blendify_blender.blendfile.nodes import MaterialReader
from blendify_blender.blendfile.origins import record_attach
from blendify_blender.blendfile.safety import (
    appended_blend,
    check_blend_path,
    loaded_blend,
    scripts_auto_execute_disabled,
)
from blendify_blender.blendfile.settings import (
    UNIMPORTED,
    apply_old_defaults,
    describe_unimported,
    file_render_settings,
    file_version,
)
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, strict_arguments

__all__ = ["AttachedBlend", "BlendAttachWarning", "append_blend_scenes", "attach_blend"]

#: evaluated object types that are neither parsed nor reported (no geometry of their own)
_SILENT_TYPES = ("EMPTY", "CAMERA", "ARMATURE", "LATTICE", "SPEAKER")


class BlendAttachWarning(UserWarning):
    """Parts of a .blend file that could not be parsed into the IR (listed in the message)."""


class AttachedBlend(list):  # type: ignore[type-arg]
    """The renderables added by :func:`attach_blend` (a list), plus what else was imported.

    Attributes: ``path`` (resolved .blend path), ``lights`` (added lights), ``camera`` (the new camera or
    None), ``background`` (the new background light / environment or None), ``unparsed`` (the warning
    lines), ``texture_dir`` (where packed textures were unpacked, or None), ``scene_name``;
    ``render_settings`` / ``cycles_settings`` (with ``render_settings=True``: the file's render settings as
    ``bf.render`` keywords / the Cycles backend's ``cycles_settings`` option; else None).
    """

    def __init__(self, renderables: list[Any]) -> None:
        super().__init__(renderables)
        self.path: str = ""
        self.scene_name: str = ""
        self.lights: list[Any] = []
        self.camera: Any = None
        self.background: Any = None
        self.unparsed: list[str] = []
        self.texture_dir: str | None = None
        self.render_settings: dict[str, Any] | None = None
        self.cycles_settings: dict[str, Any] | None = None


@dataclass
class _Pending:
    """Everything parsed from the file, committed to the IR scene only when parsing succeeded."""

    notes: Notes
    scene_label: str = ""
    texture_dir: Path | None = None
    meshes: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    points: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    lights: list[tuple[str, str, dict[str, Any]]] = field(default_factory=list)
    camera: tuple[str, dict[str, Any]] | None = None
    world: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    render_settings: dict[str, Any] | None = None
    cycles_settings: dict[str, Any] | None = None
    world_considered: bool = False
    #: IR uid -> the file object (group) it was parsed from
    groups: dict[int, str] = field(default_factory=dict)


@strict_arguments
def attach_blend(
    scene: Any,
    path: str | os.PathLike[str],
    with_camera: bool = False,
    *,
    scene_name: str | None = None,
    with_world: bool | None = None,
    texture_dir: str | os.PathLike[str] | None = None,
    warn: bool = True,
    render_settings: bool = False,
    bake_resolution: int | None = DEFAULT_BAKE_RESOLUTION,
) -> AttachedBlend:
    """Append a .blend's content into the IR ``scene``; returns the added renderables (see module docs).

    Args:
        scene: the :class:`blendify_core.ir.scene.Scene` to extend.
        path: the .blend file (never opened as the main file; embedded Python never runs).
        with_camera: also replace ``scene.camera`` by the file's scene camera.
        scene_name: which scene of the file to import (default: the only one, or the first by name, with a
            warning).
        with_world: import the world's background (None: only when ``scene`` has no background or
            environment yet; True: replace it; False: never).
        texture_dir: where PACKED images are unpacked (default:
            :func:`blendify_blender.blendfile.images.default_texture_cache_dir`).
        warn: emit one :class:`BlendAttachWarning` listing what could not be parsed.
        render_settings: read the file scene's render settings into ``result.render_settings`` (``bf.render``
            keywords: samples, seed, bounce limits, pixel filter and width, clamps, filter glossy, adaptive,
            denoise, transparent_background) and ``result.cycles_settings`` (the Cycles-only rest: volume
            bounces, caustics, light threshold, film exposure: the Cycles backend's ``cycles_settings``
            option). Off by default: the settings that differ from ``bf.render``'s are then named in the
            warning as not imported.
        bake_resolution: procedural colours (Checker, Noise, Gradient, Voronoi, ... feeding a colour input)
            are baked with Cycles' baker into an image of this width and height through the object's UV map
            (listed as an approximation); None: use their default value (noted).
    """
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core Scene, got {type(scene).__name__}")
    with_camera = as_bool("with_camera", with_camera)
    with_world = None if with_world is None else as_bool("with_world", with_world)
    warn = as_bool("warn", warn)
    if scene_name is not None and not isinstance(scene_name, str):
        raise InvalidSceneError(f"scene_name: expected a scene name (str) or None, got {scene_name!r}")
    if bake_resolution is not None and (
        isinstance(bake_resolution, bool) or not isinstance(bake_resolution, int) or not 4 <= bake_resolution <= 8192
    ):
        raise InvalidSceneError(f"bake_resolution: expected an integer in [4, 8192] or None, got {bake_resolution!r}")
    if not isinstance(render_settings, bool):
        raise InvalidSceneError(f"render_settings: expected True or False, got {render_settings!r}")
    if texture_dir is not None and not isinstance(texture_dir, (str, os.PathLike)):
        raise InvalidSceneError(f"texture_dir: expected a directory path or None, got {texture_dir!r}")
    p = check_blend_path(path)
    bpy = session.bpy_module()
    with session.BPY_LOCK, session.capture_output("attach .blend") as cap:
        with session.engine_errors(f"attach_blend({str(p)!r})", cap):
            pend = _parse_blend(
                bpy, scene, p, with_camera, scene_name, with_world, texture_dir, render_settings, bake_resolution
            )
    result = _commit(scene, p, pend, with_camera)
    if warn and pend.notes:
        lines = "\n  - ".join(pend.notes)
        warnings.warn(
            f"attach_blend({str(p)!r}): {len(pend.notes)} item(s) not (fully) parsed into the IR "
            f"(the file stays attached for Cycles):\n  - {lines}",
            BlendAttachWarning,
            stacklevel=2,
        )
    return result


def append_blend_scenes(path: str | os.PathLike[str]) -> tuple[list[Any], list[str]]:
    """For the Cycles backend: append the scenes of ``path`` into the current bpy session with the same
    protections as :func:`attach_blend` (auto-run off during the load, Python drivers and text blocks
    removed). Returns (appended bpy scenes, notes about removed Python). The caller owns the new
    datablocks and must keep auto-run off while evaluating them (drivers are already gone)."""
    p = check_blend_path(path)
    with session.BPY_LOCK, scripts_auto_execute_disabled(), appended_blend(p) as (scenes, notes, _new):
        return [sc for _name, sc in scenes], notes


# ---------------------------------------------------------------------------------------------------
# parsing (inside the bpy lock, with the file appended)
# ---------------------------------------------------------------------------------------------------


def _parse_blend(
    bpy: Any,
    scene: Any,
    p: Path,
    with_camera: bool,
    scene_name: str | None,
    with_world: bool | None,
    texture_dir: str | os.PathLike[str] | None,
    render_settings: bool,
    bake_resolution: int | None,
) -> _Pending:
    pend = _Pending(notes=Notes())
    notes = pend.notes
    images = ImageReader(bpy, p, texture_dir, notes)
    baker = Baker(notes, bake_resolution) if bake_resolution is not None else None
    materials = MaterialReader(images, notes, baker)
    with scripts_auto_execute_disabled(), loaded_blend(p) as (scenes, removed, new_ids):
        notes.extend(removed)
        pend.scene_label, sc = _pick_scene(scenes, scene_name, p, notes)
        apply_old_defaults(sc, file_version(bpy, p))
        portable, cycles, setting_notes = file_render_settings(sc)
        if render_settings:
            pend.render_settings, pend.cycles_settings = portable, cycles
            notes.extend(setting_notes)
        else:
            line = describe_unimported(portable, cycles)
            if line:
                notes.add(line)
        view_layer = next((vl for vl in sc.view_layers if vl.use), sc.view_layers[0])
        for msg in _render_visibility(bpy, new_ids, view_layer):
            notes.add(msg)
        with bpy.context.temp_override(scene=sc, view_layer=view_layer):
            dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        _parse_instances(dg, materials, pend)
        if with_world or (with_world is None and scene.lights.background is None and scene.lights.environment is None):
            pend.world = world_specs(sc.world, images, notes)
            pend.world_considered = True
        if with_camera:
            if sc.camera is None:
                raise InvalidSceneError(f"with_camera: scene {sc.name!r} of {str(p)!r} has no camera")
            pend.camera = camera_spec(sc, sc.camera.evaluated_get(dg), notes)
        if baker is not None:  # last: baking evaluates the scene again
            baker.run(bpy, sc, view_layer)
            baker.apply(pend.meshes)
    pend.texture_dir = images.texture_dir
    return pend


def _pick_scene(scenes: list[tuple[str, Any]], scene_name: str | None, p: Path, notes: Notes) -> tuple[str, Any]:
    """(name in the file, appended scene) to import: ``scene_name``, or the first by name (noted)."""
    if scene_name is None:
        if len(scenes) > 1:
            notes.add(
                f"the file has {len(scenes)} scenes {[n for n, _ in scenes]}; imported {scenes[0][0]!r}, the "
                "first by name (pass scene_name= to choose)"
            )
        return scenes[0]
    match = [(n, s) for n, s in scenes if n == scene_name]
    if not match:
        raise InvalidSceneError(
            f"scene_name: {str(p)!r} has no scene {scene_name!r}; its scenes: {[n for n, _ in scenes]}"
        )
    return match[0]


def _render_visibility(bpy: Any, new_ids: list[Any], view_layer: Any) -> Iterator[str]:
    """Make the appended (temporary) data evaluate like a render in the viewport depsgraph: render
    visibility of objects and collections, no view-layer hiding, render levels of modifiers."""
    for idb in new_ids:
        if isinstance(idb, bpy.types.Object):
            idb.hide_viewport = bool(idb.hide_render)
            idb.show_instancer_for_viewport = bool(idb.show_instancer_for_render)
            for md in idb.modifiers:
                md.show_viewport = bool(md.show_render)
                if md.type in ("SUBSURF", "MULTIRES"):
                    md.levels = md.render_levels
            for psys in idb.particle_systems:
                if psys.settings.render_type == "PATH" or psys.settings.type == "HAIR":
                    yield f"object {idb.name!r}: hair particles not parsed"
                if psys.settings.display_percentage != 100:
                    psys.settings.display_percentage = 100
        elif isinstance(idb, bpy.types.Collection):
            idb.hide_viewport = bool(idb.hide_render)
    stack = [view_layer.layer_collection]
    while stack:
        lc = stack.pop()
        lc.hide_viewport = False
        stack.extend(lc.children)
    for ob in view_layer.objects:
        if not ob.hide_render and ob.hide_get(view_layer=view_layer):
            ob.hide_set(False, view_layer=view_layer)


def _own_mesh_components(dg: Any) -> set[str]:
    """Objects whose evaluated geometry also comes as their own mesh component (curves with a bevel,
    text, ...): the component is parsed, the object's own to_mesh() would duplicate it."""
    own_mesh: set[str] = set()
    for inst in dg.object_instances:
        if inst.is_instance and inst.parent is not None and inst.object.type == "MESH":
            if inst.parent.original == inst.object.original:
                own_mesh.add(inst.object.original.name)
    return own_mesh


def _instance_name(inst: Any, obj: Any) -> str | None:
    """The IR tag candidate of a depsgraph instance, or None when the instance does not render."""
    orig = obj.original if obj.original is not None else obj
    parent = inst.parent.original if (inst.is_instance and inst.parent is not None) else None
    # a geometry component of the object itself (e.g. points made by Geometry Nodes) is not an
    # instance of another object
    own_component = parent is not None and parent == orig
    name = orig.name if parent is None or own_component else f"{parent.name}/{orig.name}"
    tag = saved_tag(obj)
    if tag is not None and (parent is None or own_component):
        name = tag
    if parent is None and orig.hide_render:
        return None
    if parent is None and orig.parent is not None and orig.parent.instance_type in ("VERTS", "FACES"):
        return None  # children of vertex/face instancers render only as instances
    if obj.type != "LIGHT" and not inst.show_self:
        return None  # e.g. a vertex/face/particle instancer whose own geometry does not render
    return name


def _instance_group(inst: Any, obj: Any) -> str:
    """The file object whose rendering makes this instance: the object itself, or its instancer."""
    orig = obj.original if obj.original is not None else obj
    parent = inst.parent.original if (inst.is_instance and inst.parent is not None) else None
    return str(parent.name if parent is not None else orig.name)


def _parse_instances(dg: Any, materials: MaterialReader, pend: _Pending) -> None:
    """Every rendered object instance of the evaluated depsgraph -> pending meshes, points and lights."""
    notes = materials.notes
    unsupported: dict[str, int] = {}
    own_mesh = _own_mesh_components(dg)
    for inst in dg.object_instances:
        obj = inst.object
        typ = obj.type
        if typ in _SILENT_TYPES:
            continue
        if not inst.is_instance and typ in ("CURVE", "SURFACE", "FONT", "META") and obj.original.name in own_mesh:
            continue
        name = _instance_name(inst, obj)
        if name is None:
            continue
        matrix = matrix_array(inst.matrix_world)
        group = _instance_group(inst, obj)
        if typ == "LIGHT":
            light = light_spec(obj, matrix, name, notes)
            if light is not None:
                light[1]["_group"] = group
                pend.lights.append((name, *light))
            continue
        if typ in MESH_TYPES:
            spec, target = mesh_spec(materials, obj, matrix, name), pend.meshes
        elif typ == "POINTCLOUD":
            spec, target = points_spec(materials, obj, matrix, name), pend.points
        else:
            unsupported[typ] = unsupported.get(typ, 0) + 1
            continue
        if spec is None:
            continue
        orig = obj.original if obj.original is not None else obj
        spec["emit_shadows"] = bool(orig.visible_shadow)
        spec["_group"] = group
        if orig.is_shadow_catcher:
            notes.add(f"object {name!r}: shadow catcher read as a normal surface")
        if not orig.visible_camera:
            notes.add(f"object {name!r}: hidden from the camera in Blender, visible in the IR")
        target.append((name, spec))
    for typ, n in unsupported.items():
        notes.add(f"{n} object(s) of type {typ} not parsed (kept for Cycles only)")


# ---------------------------------------------------------------------------------------------------
# committing to the IR scene (all or nothing)
# ---------------------------------------------------------------------------------------------------


def _unique_tag(base: str, taken: set[str]) -> str:
    base = base.strip() or "Object"
    tag, n = base, 1
    while tag in taken:
        tag = f"{base}.{n:03d}"
        n += 1
    taken.add(tag)
    return tag


def _commit(scene: Any, p: Path, pend: _Pending, with_camera: bool) -> AttachedBlend:
    """Add the parsed objects to the IR scene (all or nothing; an object the IR rejects is skipped and
    noted); records the attachment and returns the result."""
    added_r: list[Any] = []
    added_l: list[Any] = []
    old_bg, old_env, old_cam = scene.lights.background, scene.lights.environment, scene.camera
    try:
        _add_renderables(scene, pend, added_r)
        _add_lights(scene, pend, added_l)
        background = None
        for kind, spec in pend.world:
            if kind == "environment":
                background = scene.lights.set_environment_map(**spec)
            else:
                background = scene.lights.set_background_light(**spec)
        camera = None
        if pend.camera is not None:
            kind, spec = pend.camera
            if kind == "ortho":
                camera = scene.set_orthographic_camera(**spec)
            else:
                camera = scene.set_perspective_camera(**spec)
    except Exception:
        for r in added_r:
            scene.renderables.remove(r)
        for lt in added_l:
            scene.lights.remove(lt)
        scene.lights.background, scene.lights.environment = old_bg, old_env
        scene.camera = old_cam
        raise
    if with_camera and camera is None:
        pend.notes.add("no usable camera in the file; scene.camera unchanged")
    limits = tuple(n for n in pend.notes if not n.startswith(UNIMPORTED))  # the settings are bf.render's anyway
    scene.attachments.append(Attachment("blend", str(p), approximations=limits))
    record_attach(
        str(p),
        pend.scene_label,
        [(r, pend.groups[r.uid]) for r in added_r],
        [(lt, pend.groups[lt.uid]) for lt in added_l],
        scene.lights if pend.world_considered else None,
    )
    result = AttachedBlend(added_r)
    result.path = str(p)
    result.scene_name = pend.scene_label
    result.lights = added_l
    result.camera = camera
    result.background = background
    result.unparsed = list(pend.notes)
    result.texture_dir = str(pend.texture_dir) if pend.texture_dir is not None else None
    result.render_settings = pend.render_settings
    result.cycles_settings = pend.cycles_settings
    return result


def _add_renderables(scene: Any, pend: _Pending, added: list[Any]) -> None:
    """Meshes then point clouds, under unique tags; ``added`` collects them (for the rollback), with their
    groups in ``pend.groups``."""
    taken = set(scene.renderables.keys())
    for name, spec in pend.meshes + pend.points:
        emit = spec.pop("emit_shadows", True)
        group = spec.pop("_group", name)
        add = scene.renderables.add_pointcloud if "point_size" in spec else scene.renderables.add_mesh
        tag = _unique_tag(name, taken)
        try:
            r = add(tag=tag, **spec)
        except InvalidSceneError as exc:  # data the IR rejects: skip this object, keep the rest
            pend.notes.add(f"object {name!r} not imported: {exc}")
            taken.discard(tag)
            continue
        r.emit_shadows = emit
        added.append(r)
        pend.groups[r.uid] = group


def _add_lights(scene: Any, pend: _Pending, added: list[Any]) -> None:
    """The lights, under unique tags; ``added`` collects them (for the rollback)."""
    adders = {
        "point": scene.lights.add_point,
        "sun": scene.lights.add_sun,
        "spot": scene.lights.add_spot,
        "area": scene.lights.add_area,
    }
    taken = set(scene.lights.keys())
    for name, kind, spec in pend.lights:
        tag = _unique_tag(name, taken)
        group = spec.pop("_group", name)
        try:
            added.append(adders[kind](tag=tag, **spec))
            pend.groups[added[-1].uid] = group
        except InvalidSceneError as exc:
            pend.notes.add(f"light {name!r} not imported: {exc}")
            taken.discard(tag)
