"""What changed in a scene since a backend last translated it: computed once, here, for every backend.

A backend keeps one :class:`ChangeTracker` per cached native scene and asks it, at every translation,
for the :class:`SceneChanges` since the previous one. Objects are followed by their ``uid`` and their
revision counters (``transform``, ``geometry``, ``appearance``; materials by identity and revision,
colour sources by identity: they are immutable), so a moved camera or light rebuilds no mesh.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "ChangeTracker",
    "SceneChanges",
    "camera_state",
    "file_stamp",
    "lights_state",
    "renderable_state",
    "world_state",
]


def file_stamp(obj: Any) -> tuple[object, ...] | None:
    """(path, modification time, size) of the file an IR object reads (a file texture, an environment map
    given by path), so a file rewritten between two renders counts as a change; None without a file."""
    path = getattr(obj, "texture_path", None) or getattr(obj, "path", None)
    if not isinstance(path, str):
        return None
    try:
        st = os.stat(path)
    except OSError:
        return (path, None, None)
    return (path, st.st_mtime_ns, st.st_size)


def renderable_state(r: Any) -> tuple[object, ...]:
    """Everything about a renderable except its pose that a translation depends on (files by their stamp)."""
    return (
        type(r),
        r.revision("geometry"),
        r.revision("appearance"),
        tuple((id(m), m.revision) for m in r.materials),
        tuple((id(c), file_stamp(c)) for c in r.colors_list),
    )


def lights_state(lights: Any) -> tuple[object, ...]:
    """The lights (not the world): identity, pose and parameters of each."""
    return tuple(
        (light.uid, type(light), light.revision("transform"), light.revision("appearance"), light.revision("geometry"))
        for light in lights
    )


def world_state(lights: Any) -> tuple[object, ...]:
    """The background light and the environment map (a map read from a file by its stamp)."""
    bg, env = lights.background, lights.environment
    return (
        None if bg is None else (bg.strength, tuple(bg.color), bg.color_space),
        None
        if env is None
        else (id(env), env.strength, env.color_space, tuple(env.quaternion.tolist()), file_stamp(env)),
    )


def camera_state(camera: Any) -> str | None:
    """The camera by content (type, intrinsics, clip range, distortion, pose), not identity: ``bf.render``
    passes engines copies of the camera (resolution percentage, distortion margins, re-centring) and an
    equal copy is no change, while any parameter change is one (whether or not it bumps a revision)."""
    if camera is None:
        return None
    d = camera.to_dict()
    d.pop("tag", None)
    return f"{type(camera).__qualname__}:{json.dumps(d, sort_keys=True)}"


@dataclass(frozen=True)
class SceneChanges:
    """The difference between a scene and the state last recorded. Renderables are given by ``uid``.

    ``first`` is True when nothing was recorded (translate everything). ``added`` renderables are new,
    ``rebuilt`` ones changed geometry, materials or colours (translate again), ``moved`` ones changed
    only their pose, ``removed`` are gone. ``lights``, ``world``, ``camera`` and ``attachments`` say
    whether that part changed."""

    first: bool
    added: tuple[int, ...] = ()
    rebuilt: tuple[int, ...] = ()
    moved: tuple[int, ...] = ()
    removed: tuple[int, ...] = ()
    lights: bool = False
    world: bool = False
    camera: bool = False
    attachments: bool = False
    order: bool = False  #: the renderables' order changed (instance ids follow the order)

    @property
    def any(self) -> bool:
        return (
            self.first
            or bool(self.added or self.rebuilt or self.moved or self.removed or self.lights or self.world)
            or self.camera
            or self.attachments
            or self.order
        )

    @property
    def geometry_only_camera(self) -> bool:
        """Only the camera changed."""
        return self.camera and not (
            self.first
            or self.added
            or self.rebuilt
            or self.moved
            or self.removed
            or self.lights
            or self.world
            or self.attachments
            or self.order
        )


@dataclass
class ChangeTracker:
    """Records the state of the scene a backend translated and reports :class:`SceneChanges`."""

    _renderables: dict[int, tuple[object, ...]] = field(default_factory=dict)
    _poses: dict[int, int] = field(default_factory=dict)
    _order: tuple[int, ...] = ()
    _lights: tuple[object, ...] | None = None
    _world: tuple[object, ...] | None = None
    _camera: str | None = None
    _attachments: tuple[object, ...] | None = None
    _recorded: bool = False
    #: the objects followed by ``id()`` (materials, colour sources, the environment map), kept alive while
    #: recorded so a new object cannot reuse a recorded id
    _alive: tuple[object, ...] = ()

    def reset(self) -> None:
        """Forget everything: the next :meth:`update` reports ``first``."""
        self.__init__()  # type: ignore[misc]

    def peek(self, scene: Any) -> SceneChanges:
        """The changes since the last :meth:`update`, without recording the new state."""
        return self._diff(scene, record=False)

    def update(self, scene: Any) -> SceneChanges:
        """The changes since the last call, and record the scene's state."""
        return self._diff(scene, record=True)

    def _diff(self, scene: Any, record: bool) -> SceneChanges:
        states = {r.uid: renderable_state(r) for r in scene.renderables}
        poses = {r.uid: r.revision("transform") for r in scene.renderables}
        order = tuple(r.uid for r in scene.renderables)
        lights = lights_state(scene.lights)
        world = world_state(scene.lights)
        camera = camera_state(scene.camera)
        attachments = tuple((a.format, a.path) for a in scene.attachments)
        if not self._recorded:
            changes = SceneChanges(first=True)
        else:
            old = self._renderables
            added = tuple(u for u in order if u not in old)
            rebuilt = tuple(u for u in order if u in old and old[u] != states[u])
            moved = tuple(u for u in order if u in old and old[u] == states[u] and self._poses.get(u) != poses[u])
            removed = tuple(u for u in old if u not in states)
            kept_old = tuple(u for u in self._order if u in states)
            kept_new = tuple(u for u in order if u in old)
            changes = SceneChanges(
                first=False,
                added=added,
                rebuilt=rebuilt,
                moved=moved,
                removed=removed,
                lights=lights != self._lights,
                world=world != self._world,
                camera=camera != self._camera,
                attachments=attachments != self._attachments,
                order=kept_old != kept_new,
            )
        if record:
            self._renderables, self._poses, self._order = states, poses, order
            self._lights, self._world, self._camera, self._attachments = lights, world, camera, attachments
            self._recorded = True
            self._alive = (
                *(m for r in scene.renderables for m in r.materials),
                *(c for r in scene.renderables for c in r.colors_list),
                scene.lights.environment,
            )
        return changes
