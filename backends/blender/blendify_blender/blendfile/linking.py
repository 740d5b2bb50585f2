"""The Cycles side of an attached .blend: its appended scene linked into the render scene.

:func:`append_blend_content` appends a file (same protections as :func:`.attach.attach_blend`) and returns
its objects by their names in the file; :class:`FileContent` links the scene the IR was parsed from into
the render scene (one collection holding the file scene's objects and collections, the file's view-layer
exclusions, holdouts and indirect-only flags kept) and shows or hides each parsed group's file object as
:func:`.origins.file_plan` says: a group still exactly as parsed renders from the file (its original
materials, modifiers, attributes), an edited one stays hidden (the IR renders it). Objects the IR never
parsed (volumes, hair, rejected objects) always render from the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from blendify_blender import session
from blendify_blender.blendfile.origins import FilePlan
from blendify_blender.blendfile.safety import appended_blend, check_blend_path, scripts_auto_execute_disabled

__all__ = ["FileContent", "append_blend_content"]


def append_blend_content(path: str) -> tuple[list[tuple[str, Any]], dict[str, Any], list[str]]:
    """Append every scene of ``path`` (auto-run off, Python removed): ((file scene name, appended scene),
    {object name in the file: appended object}, notes). The caller owns the new datablocks."""
    bpy = session.bpy_module()
    p = check_blend_path(path)
    with session.BPY_LOCK, scripts_auto_execute_disabled(), appended_blend(p) as (scenes, notes, new_ids):
        objects = {str(idb.name): idb for idb in new_ids if isinstance(idb, bpy.types.Object)}
        return scenes, objects, notes


def _copy_layer_flags(src: Any, dst_by_collection: dict[int, Any]) -> None:
    """The file view layer's exclude / holdout / indirect-only flags onto the render scene's layer collections."""
    stack = list(src.children)
    while stack:
        lc = stack.pop()
        dst = dst_by_collection.get(lc.collection.as_pointer())
        if dst is not None:
            for flag in ("exclude", "holdout", "indirect_only"):
                if getattr(dst, flag) != getattr(lc, flag):
                    setattr(dst, flag, getattr(lc, flag))
        stack.extend(lc.children)


@dataclass
class FileContent:
    """One attached file's appended scene, linked into the render scene ``sc``."""

    path: str
    scene_name: str
    root: Any  #: the collection holding the file scene's content inside the render scene
    objects: dict[str, Any] = field(default_factory=dict)  #: object name in the file -> appended object
    world: Any = None
    #: original values of what the plan changes: object -> (hide_render, pass_index)
    original: dict[int, tuple[bool, int]] = field(default_factory=dict)

    @classmethod
    def link(cls, sc: Any, path: str, scene_name: str, scenes: list[tuple[str, Any]], objects: dict[str, Any]) -> Any:
        """Link the appended scene ``scene_name`` into ``sc`` (None when the file has no such scene)."""
        bpy = session.bpy_module()
        match = [s for n, s in scenes if n == scene_name]
        if not match:
            return None
        fsc = match[0]
        root = bpy.data.collections.new(f"bf_attached_{scene_name}"[:60])
        sc.collection.children.link(root)
        for obj in fsc.collection.objects:
            root.objects.link(obj)
        for child in fsc.collection.children:
            root.children.link(child)
        file_layer = next((vl for vl in fsc.view_layers if vl.use), fsc.view_layers[0])
        dst: dict[int, Any] = {}
        for vl in sc.view_layers:
            stack = [vl.layer_collection]
            while stack:
                lc = stack.pop()
                dst[lc.collection.as_pointer()] = lc
                stack.extend(lc.children)
        _copy_layer_flags(file_layer.layer_collection, dst)
        content = cls(path, scene_name, root, objects, fsc.world)
        content.original = {o.as_pointer(): (bool(o.hide_render), int(o.pass_index)) for o in objects.values()}
        return content

    def apply(self, plan: FilePlan, index_of: dict[str, int] | None) -> None:
        """Show the plan's file-rendered groups, hide the others; with ``index_of`` (group -> IR index + 1,
        for the instance output) set pass indices (0 for every other file object), else keep the file's."""
        key = (self.path, self.scene_name)
        hidden = plan.hidden.get(key, set())
        for name, obj in self.objects.items():
            hide0, index0 = self.original.get(obj.as_pointer(), (bool(obj.hide_render), int(obj.pass_index)))
            hide = True if name in hidden else hide0
            if bool(obj.hide_render) != hide:
                obj.hide_render = hide
            index = index0 if index_of is None else index_of.get(name, 0)
            if obj.pass_index != index:
                obj.pass_index = index
