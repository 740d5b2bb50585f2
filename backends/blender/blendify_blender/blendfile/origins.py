"""Where the IR objects of an attached .blend came from, so the Cycles backend can render the file's own
objects (their original material node trees, modifiers, attributes) while the IR is left as parsed.

:func:`attach_blend` records, for every renderable and light it adds, the file, the scene, the *group* (the
file object whose rendering produced it: the object itself, or the instancer of an instance) and the IR
object's state at that moment; and the world it imported. :func:`file_plan` tells the Cycles translator,
for one IR scene, which of those are still exactly as parsed (not edited through the IR: same geometry,
materials, colours, pose and parameters; every member of the group still in the scene): those render from
the file, everything else from the IR. The records live in this process only (keyed by the IR objects'
``uid``): the isolated worker gets them with the scene (:func:`export_origins`, :func:`import_origins`); a
scene saved to a scene file and loaded again renders from the IR (the file's unparsed content still from
the file).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

from blendify_core.pipeline.changes import renderable_state, world_state

__all__ = ["FilePlan", "export_origins", "file_plan", "import_origins", "record_attach"]


@dataclass(frozen=True)
class _Origin:
    path: str
    scene: str
    group: str
    group_size: int
    state: tuple[object, ...]


#: IR object uid -> its origin in a file (renderables and lights)
_ORIGINS: dict[int, _Origin] = {}
#: (path, scene name in the file) -> every group parsed into the IR from it
_PARSED_GROUPS: dict[tuple[str, str], set[str]] = defaultdict(set)
#: (path, id of the background light, id of the environment map) -> (scene name, world state at attach)
_WORLDS: dict[tuple[str, int, int], tuple[str, tuple[object, ...]]] = {}


def _light_state(light: Any) -> tuple[object, ...]:
    return (type(light), light.revision("transform"), light.revision("appearance"), light.revision("geometry"))


def _renderable_state(r: Any) -> tuple[object, ...]:
    return (*renderable_state(r), r.revision("transform"), bool(r.emit_shadows))


def record_attach(
    path: str,
    scene_name: str,
    renderables: list[tuple[Any, str]],
    lights: list[tuple[Any, str]],
    lights_collection: Any | None,
) -> None:
    """Record what one :func:`attach_blend` added: (IR renderable, group) and (IR light, group) pairs, and
    the scene's lights collection when the file's world was imported into it (else None)."""
    sizes: dict[str, int] = defaultdict(int)
    for _obj, group in renderables + lights:
        sizes[group] += 1
    for r, group in renderables:
        _ORIGINS[r.uid] = _Origin(path, scene_name, group, sizes[group], _renderable_state(r))
    for light, group in lights:
        _ORIGINS[light.uid] = _Origin(path, scene_name, group, sizes[group], _light_state(light))
    _PARSED_GROUPS[(path, scene_name)].update(sizes)
    if lights_collection is not None:
        key = (path, id(lights_collection.background), id(lights_collection.environment))
        _WORLDS[key] = (scene_name, world_state(lights_collection))


@dataclass
class FilePlan:
    """For one IR scene: what the Cycles backend renders from its attached files.

    ``renderables`` / ``lights``: uids rendered by the file's own objects (no IR build); ``shown`` /
    ``hidden``: per (path, scene name), the parsed groups whose file objects render / stay hidden (the IR
    renders them); ``world``: (path, scene name) whose world is used, or None; ``scenes``: the scene of
    each attached path that the IR was parsed from (paths with no record are absent)."""

    renderables: set[int] = field(default_factory=set)
    lights: set[int] = field(default_factory=set)
    shown: dict[tuple[str, str], set[str]] = field(default_factory=dict)
    hidden: dict[tuple[str, str], set[str]] = field(default_factory=dict)
    world: tuple[str, str] | None = None
    scenes: dict[str, str] = field(default_factory=dict)
    groups: dict[int, str] = field(default_factory=dict)  #: file-rendered uid -> its group
    reasons: list[str] = field(default_factory=list)


def file_plan(scene: Any, outputs: tuple[str, ...] = ("rgb",)) -> FilePlan:
    """Which parsed objects of ``scene``'s attached .blend files are exactly as parsed (see the module).
    With the ``albedo`` output everything renders from the IR (the file's materials write no albedo AOV);
    with ``instance``, groups of several IR objects do (one file object cannot carry several indices)."""
    plan = FilePlan()
    attached = set(getattr(scene, "attached_blends", ()))
    if not attached:
        return plan
    members: dict[tuple[str, str, str], list[tuple[int, bool, bool]]] = defaultdict(list)
    for objs, is_light in ((list(scene.renderables), False), (list(scene.lights), True)):
        for obj in objs:
            o = _ORIGINS.get(obj.uid)
            if o is None or o.path not in attached:
                continue
            plan.scenes.setdefault(o.path, o.scene)
            state = _light_state(obj) if is_light else _renderable_state(obj)
            members[(o.path, o.scene, o.group)].append((obj.uid, is_light, state == o.state))
    if "albedo" in outputs and members:
        plan.reasons.append("the albedo output: attached objects render from the IR parse")
    for path in attached:
        sname = plan.scenes.get(path)
        if sname is None:
            continue
        shown, hidden = set(), set()
        for group in _PARSED_GROUPS.get((path, sname), ()):
            got = members.get((path, sname, group), [])
            size = max((_ORIGINS[uid].group_size for uid, _l, _ok in got), default=0)
            ok = bool(got) and len(got) == size and all(v for _u, _l, v in got) and "albedo" not in outputs
            if ok and "instance" in outputs and size > 1:
                ok = False
            if ok:
                shown.add(group)
                for uid, is_light, _v in got:
                    (plan.lights if is_light else plan.renderables).add(uid)
                    plan.groups[uid] = group
            else:
                hidden.add(group)
        plan.shown[(path, sname)], plan.hidden[(path, sname)] = shown, hidden
    lights = scene.lights
    for path in attached:
        rec = _WORLDS.get((path, id(lights.background), id(lights.environment)))
        if rec is not None and rec[1] == world_state(lights) and "albedo" not in outputs:
            plan.world = (path, rec[0])
            break
    return plan


def export_origins(scene: Any) -> dict[str, Any]:
    """The records of ``scene``'s objects as JSON-able data (by position: renderables and lights keep their
    order in a scene file), for an isolated worker that loads the scene again (:func:`import_origins`)."""
    out: dict[str, Any] = {"objects": [], "groups": [], "world": None}
    for kind, objs, state in (
        ("renderable", list(scene.renderables), _renderable_state),
        ("light", list(scene.lights), _light_state),
    ):
        for i, obj in enumerate(objs):
            o = _ORIGINS.get(obj.uid)
            if o is not None:
                out["objects"].append([kind, i, o.path, o.scene, o.group, o.group_size, state(obj) == o.state])
    seen = {(o[2], o[3]) for o in out["objects"]}
    out["groups"] = [[p, s, sorted(_PARSED_GROUPS.get((p, s), ()))] for p, s in sorted(seen)]
    lights = scene.lights
    for path in getattr(scene, "attached_blends", ()):
        rec = _WORLDS.get((path, id(lights.background), id(lights.environment)))
        if rec is not None:
            out["world"] = [path, rec[0], rec[1] == world_state(lights)]
            break
    return out


def import_origins(scene: Any, data: dict[str, Any]) -> None:
    """Records for a scene loaded from a scene file, from :func:`export_origins` of the original scene: an
    object unchanged there is recorded as it is now, a changed one with a state it cannot have."""
    renderables, lights = list(scene.renderables), list(scene.lights)
    for kind, i, path, sname, group, size, unchanged in data.get("objects", []):
        objs, state = (renderables, _renderable_state) if kind == "renderable" else (lights, _light_state)
        if i < len(objs):
            obj = objs[i]
            _ORIGINS[obj.uid] = _Origin(path, sname, group, size, state(obj) if unchanged else ("edited",))
    for path, sname, groups in data.get("groups", []):
        _PARSED_GROUPS[(path, sname)].update(groups)
    world = data.get("world")
    if world:
        path, sname, unchanged = world
        ws = world_state(scene.lights) if unchanged else ("edited",)
        _WORLDS[(path, id(scene.lights.background), id(scene.lights.environment))] = (sname, ws)
