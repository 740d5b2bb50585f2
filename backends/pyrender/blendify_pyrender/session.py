"""The live side of the backend: one OpenGL context, one renderer and the cached pyrender scene.

The cached scene is updated, not rebuilt. What changed since the last frame comes from the core's
:class:`~blendify_core.pipeline.changes.ChangeTracker`: added and rebuilt renderables (geometry,
appearance, materials or colours changed) are translated again, moved ones only get a new node pose,
removed ones lose their node; lights are rebuilt when any of them changes, the ambient term when the world
changes. The camera node gets the camera's projection and pose every frame (a few numbers; clip distances
and the principal point have no revision counter). Translation goes through :class:`PyrenderTranslator`
(translate.py); rendering through :func:`blendify_pyrender.render.render_frame`.
"""

from __future__ import annotations

import atexit
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.ir.lights import EnvironmentMap
from blendify_core.pipeline.changes import ChangeTracker
from blendify_core.pipeline.translator import TranslationContext

from ._platform import GLContext
from .translate import (
    DIFFUSE_COMPENSATION,
    Built,
    CameraBuild,
    PyrenderTranslator,
    emitter_lights,
    environment_background,
    environment_light,
    environment_radiance,
    environment_sun,
    uniform_sh,
)

__all__ = ["Engine", "Frame", "Entry"]


@dataclass
class Entry:
    """A renderable in the cached scene: its mesh node (None when it has no faces), the object-space
    offset folded into the pose, the approximations its translation made, and its shadow roles."""

    node: Any
    offset: np.ndarray
    notes: list[str]
    catcher: bool
    casts_shadow: bool


@dataclass
class Frame:
    """What :meth:`Engine.sync` returns and :func:`~blendify_pyrender.render.render_frame` consumes: the
    entries of the renderables (in ``scene.renderables`` order), the camera, the lights' nodes and the
    ambient radiance, and what the translation noted."""

    entries: list[Entry]
    tags: list[str]
    camera: CameraBuild
    light_nodes: list[tuple[Any, Any, bool]]
    ambient: np.ndarray
    #: the film's background on an opaque film (computed on demand): the environment map through each pixel
    background: Callable[[], np.ndarray] | None = None
    #: the world's radiance in given directions ((N, 3) -> (N, 3)), the map's sun left out (None: uniform / SH)
    sky: Callable[[np.ndarray], np.ndarray] | None = None
    notes: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    sync_seconds: float = 0.0
    rebuilt: int = 0
    shadow_key: Any = None

    @property
    def nodes(self) -> list[Any]:
        """The mesh nodes in ``scene.renderables`` order (None for empty renderables)."""
        return [e.node for e in self.entries]


class Engine:
    """Context + renderer + cached pyrender scene of one backend instance."""

    def __init__(self, platform: str, device: int = 0) -> None:
        self.context = GLContext(platform, device)  # prepares the platform before OpenGL is imported
        self.context.make_current()
        import pyrender

        from .render import FrameRenderer, MatrixCamera

        self._matrix_camera = MatrixCamera
        self.renderer = FrameRenderer()
        self.pscene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=np.zeros(3))
        self.translator = PyrenderTranslator()
        self.tracker = ChangeTracker()
        self.entries: dict[int, Entry] = {}
        self._light_nodes: list[tuple[Any, Any, bool]] = []  # (node, IR light, casts)
        self._ambient = np.zeros(3)
        self._camera_node: Any = None
        self._shadow_generation = 0  # bumped whenever shadow maps may change (geometry, poses, lights)
        self._emitter_uids: set[int] = set()  # the emissive renderables the current lights stand in for
        self._emitter_notes: list[str] = []
        self._world_light_nodes: list[tuple[Any, Any, bool]] = []  # the environment map's sun
        self._world_notes: list[str] = []
        self._sun_luminance = float("inf")  # the environment map's sun pixels (translate.EnvironmentLight)
        self.msaa_supported = self.renderer.max_samples >= 2
        ref = weakref.ref(self)

        def _close_at_exit() -> None:  # before the interpreter tears PyOpenGL down
            engine = ref()
            if engine is not None:
                engine.close()

        atexit.register(_close_at_exit)

    # -- scene sync --------------------------------------------------------------------------------
    def sync(self, scene: Any) -> Frame:
        """Bring the cached pyrender scene up to date with ``scene`` (only what changed) and return the frame.
        If translation fails, the next call starts over (the tracker forgets the recorded state)."""
        t0 = time.perf_counter()
        self.context.make_current()
        changes = self.tracker.update(scene)
        try:
            return self._sync(scene, changes, t0)
        except BaseException:
            self.tracker.reset()
            raise

    def _sync(self, scene: Any, changes: Any, t0: float) -> Frame:
        tr = self.translator
        if changes.first:
            self._clear()
        for uid in changes.removed:
            entry = self.entries.pop(uid, None)
            if entry is not None and entry.node is not None:
                self.pscene.remove_node(entry.node)
        rebuild = set(changes.added) | set(changes.rebuilt)
        moved = set(changes.moved)
        entries: list[Entry] = []
        notes: list[str] = []
        rebuilt = 0
        for r in scene.renderables:
            entry = self.entries.get(r.uid)
            if entry is None or r.uid in rebuild:
                if entry is not None and entry.node is not None:
                    self.pscene.remove_node(entry.node)
                ctx = TranslationContext()
                built: Built = tr.dispatch(r, ctx)
                node = None
                if built.mesh is not None:
                    node = self.pscene.add(built.mesh, pose=self._pose(r, built.offset))
                entry = Entry(node, built.offset, list(ctx.approximations), built.catcher, r.emit_shadows)
                self.entries[r.uid] = entry
                rebuilt += 1
            elif r.uid in moved and entry.node is not None:
                self.pscene.set_pose(entry.node, self._pose(r, entry.offset))
            entries.append(entry)
            notes += entry.notes
        if changes.first or rebuild or moved or changes.removed or changes.lights or changes.world:
            self._shadow_generation += 1
        ctx = TranslationContext()
        emitters = [r for r in scene.renderables if any(getattr(m, "is_emissive", False) for m in r.materials)]
        uids = {r.uid for r in emitters}
        emitters_changed = uids != self._emitter_uids or bool(uids & (rebuild | moved))
        if emitters_changed and not (changes.first or rebuild or moved or changes.removed or changes.lights):
            self._shadow_generation += 1
        if changes.first or changes.lights or emitters_changed:
            self._sync_lights(scene.lights, ctx, emitters)
            self._emitter_uids = uids
        if changes.first or changes.world:
            self._sync_world(scene.lights, ctx)
        camera = self._sync_camera(scene.camera, ctx)
        for attachment in scene.attachments:
            tr.dispatch(attachment, ctx)
        return Frame(
            entries=entries,
            tags=[r.tag for r in scene.renderables],
            camera=camera,
            light_nodes=self._light_nodes + self._world_light_nodes,
            ambient=self._ambient,
            background=self._background(scene),
            sky=self._sky(scene),
            notes=sorted(set(notes + ctx.approximations + self._emitter_notes + self._world_notes)),
            ignored=list(ctx.ignored),
            sync_seconds=time.perf_counter() - t0,
            rebuilt=rebuilt,
            shadow_key=self._shadow_generation,
        )

    def _clear(self) -> None:
        """Drop every renderable and light node (the tracker starts over)."""
        for entry in self.entries.values():
            if entry.node is not None:
                self.pscene.remove_node(entry.node)
        self.entries = {}
        for node, _, _ in self._light_nodes + self._world_light_nodes:
            self.pscene.remove_node(node)
        self._light_nodes = []
        self._world_light_nodes = []

    @staticmethod
    def _pose(r: Any, offset: np.ndarray) -> np.ndarray:
        t = np.eye(4)
        t[:3, 3] = offset
        return r.matrix_world @ t

    def _sync_lights(self, lights: Any, ctx: TranslationContext, emitters: list[Any]) -> None:
        """The scene's lights, then the lights standing in for the emissive renderables (emitter_lights)."""
        for node, _, _ in self._light_nodes:
            self.pscene.remove_node(node)
        self._light_nodes = []
        extra = [light for r in emitters for light in emitter_lights(r)]
        self._emitter_notes = []
        if extra:
            self._emitter_notes.append(
                f"emissive surfaces light the scene as {len(extra)} lights of their power (pi x radiance x area "
                "per side): planar emitters as back-to-back rectangle area lights, others as point lights"
            )
        for light in [*lights, *extra]:
            built = self.translator.dispatch(light, ctx)
            if built is None:  # strength 0
                continue
            node = self.pscene.add(built.light, pose=built.pose)
            self._light_nodes.append((node, light, built.casts))

    def _sync_world(self, lights: Any, ctx: TranslationContext) -> None:
        """The world's light as 9 SH coefficients (background: uniform; environment map: its directional
        distribution) for the shaders, and the uniform mean radiance (the film's background colour)."""
        total = np.zeros(3)
        sh = np.zeros((9, 3))
        for node, _, _ in self._world_light_nodes:
            self.pscene.remove_node(node)
        self._world_light_nodes = []
        self._world_notes = []
        for world in (lights.background, lights.environment):
            if world is not None:
                mean = self.translator.dispatch(world, ctx)
                total += mean
                if isinstance(world, EnvironmentMap) and world.strength > 0:
                    env = environment_light(world)
                    self._sun_luminance = env.sun_luminance
                    sh += env.sh
                    sun = environment_sun(env)
                    if sun is not None:  # the map's sun as a shadowing directional light
                        built = self.translator.dispatch(sun, ctx)
                        node = self.pscene.add(built.light, pose=built.pose)
                        self._world_light_nodes.append((node, sun, built.casts))
                        self._world_notes.append(
                            "environment map: its sun (the pixels above 10 % of its peak) drawn as a "
                            "directional light of the same irradiance, with shadow-mapped shadows"
                        )
                else:
                    sh += uniform_sh(mean)
        self.renderer.env_sh = sh.astype(np.float32)
        self._ambient = total
        # pyrender's ambient term has no 0.96 factor: scale it so base/0.96 x ambient = albedo x radiance
        self.pscene.ambient_light = total * DIFFUSE_COMPENSATION

    def _sky(self, scene: Any) -> Callable[[np.ndarray], np.ndarray] | None:
        env = scene.lights.environment
        if env is None or env.strength <= 0:
            return None
        bg = scene.lights.background
        uniform = bg.radiance if bg is not None and bg.strength > 0 else np.zeros(3)
        sun = self._sun_luminance
        return lambda dirs: environment_radiance(env, dirs, uniform, sun)

    def _background(self, scene: Any) -> Callable[[], np.ndarray] | None:
        env = scene.lights.environment
        if env is None or env.strength <= 0:
            return None
        bg = scene.lights.background
        uniform = bg.radiance if bg is not None and bg.strength > 0 else np.zeros(3)
        camera = scene.camera
        return lambda: environment_background(env, camera, uniform)

    def _sync_camera(self, cam: Any, ctx: TranslationContext) -> CameraBuild:
        built: CameraBuild = self.translator.dispatch(cam, ctx)
        if self._camera_node is None:
            camera = self._matrix_camera(built.projection, built.znear, built.zfar)
            self._camera_node = self.pscene.add(camera, pose=built.pose)
        else:
            c = self._camera_node.camera
            c.projection = built.projection
            c.znear, c.zfar = built.znear, built.zfar
            self.pscene.set_pose(self._camera_node, built.pose)
        return built

    @property
    def software(self) -> bool:
        """True on a software rasteriser (llvmpipe, softpipe, swrast), where MSAA shades every sample."""
        name = self.renderer.gl_renderer.lower()
        return any(k in name for k in ("llvmpipe", "softpipe", "swrast", "software"))

    def close(self) -> None:
        """Free the GL objects and release the context (idempotent)."""
        if not self.context.alive:
            return
        try:
            self.context.make_current()
            self.renderer.delete()
            self.renderer._shadow_fb = None  # pyrender's delete() leaves it set (a second delete would use it)
        finally:
            self.context.release()
