"""The live side of the backend: one OpenGL context, one renderer and the cached pyrender scene.

The cached scene is updated, not rebuilt: renderables are keyed by ``uid`` and rebuilt only when their
geometry/appearance revisions (or their materials' revisions) change; a transform change only moves the
node; the camera is updated every frame; lights are rebuilt when any of them changes.
"""

from __future__ import annotations

import atexit
import time
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import RenderError
from blendify_core.ir.cameras import OrthographicCamera
from blendify_core.ir.lights import AreaLight, SpotLight, SunLight
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings

from ._platform import GLContext

__all__ = ["Engine", "Frame", "AntiAliasing", "linearise_rgba8", "apply_coverage", "box_downsample"]

_GAMMA = 2.2
#: dense GL-point clouds are thinned to this many points per covered pixel (never below POINTS_MIN_DRAWN)
POINTS_PER_PIXEL = 8
POINTS_MIN_DRAWN = 100_000
#: the coverage pass of the "coverage" anti-aliasing is rendered at 3x the resolution (9 samples/pixel)
COVERAGE_SUPERSAMPLE = 3
_LIN8 = ((np.arange(256, dtype=np.float64) / 255.0) ** _GAMMA).astype(np.float32)
_ALPHA8 = (np.arange(256, dtype=np.float64) / 255.0).astype(np.float32)


def _translate_mod() -> Any:
    from . import _translate

    return _translate


@dataclass(frozen=True)
class AntiAliasing:
    """How the colour pass is anti-aliased: ``mode`` "none", "coverage" (plain shading + multisampled
    coverage), "msaa" (multisampled shading) or "ssaa" (supersampling by ``supersample``)."""

    mode: str
    msaa: int = 0
    supersample: int = 1

    def describe(self) -> dict[str, Any]:
        return {"mode": self.mode, "msaa": self.msaa, "supersample": self.supersample}


@dataclass
class _Entry:
    key: tuple[Any, ...]
    transform_rev: int
    node: Any
    offset: np.ndarray
    notes: list[str]
    catcher: bool
    casts_shadow: bool


@dataclass
class Frame:
    """What :meth:`Engine.sync` returns and :meth:`Engine.render` consumes: the scene (IR), the mesh
    nodes in ``scene.renderables`` order (None for empty renderables) and the notes collected."""

    scene: Any
    nodes: list[Any]
    tags: list[str]
    notes: list[str] = field(default_factory=list)
    sync_seconds: float = 0.0
    rebuilt: int = 0
    shadow_key: Any = None


def _renderable_key(r: Any) -> tuple[Any, ...]:
    return (
        type(r).__name__,
        r.revision("geometry"),
        r.revision("appearance"),
        tuple((id(m), m.revision) for m in r.materials),
        tuple(id(c) for c in r.colors_list),
    )


def _lights_key(lights: Any) -> tuple[Any, ...]:
    items = tuple(
        (l.uid, l.revision("transform"), l.revision("appearance"), l.revision("geometry"), repr(l._params()))
        for l in lights  # noqa: E741
    )
    bg = lights.background
    env = lights.environment
    return (
        items,
        None if bg is None else (bg.strength, tuple(bg.color), bg.color_space),
        None if env is None else (id(env), env.strength),
    )


def linearise_rgba8(img: np.ndarray) -> np.ndarray:
    """pyrender's 8-bit colour (gamma 1/2.2, premultiplied by coverage when multisampled) to linear
    premultiplied float32: straight = C / A, linear = straight^2.2, times A (a table for opaque pixels)."""
    h, w = img.shape[:2]
    out = np.empty((h, w, 4), dtype=np.float32)
    for c in range(3):
        np.take(_LIN8, img[..., c], out=out[..., c])
    np.take(_ALPHA8, img[..., 3], out=out[..., 3])
    a8 = img[..., 3]
    partial = (a8 > 0) & (a8 < 255)
    if np.any(partial):
        a = out[..., 3][partial][:, None]
        c = img[..., :3][partial].astype(np.float32) / 255.0
        straight = np.clip(c / a, 0.0, 1.0)
        out[partial, :3] = (straight**_GAMMA) * a
    return out


def apply_coverage(rgba: np.ndarray, coverage: np.ndarray) -> np.ndarray:
    """Anti-aliased silhouettes from a plain (one sample per pixel) colour pass and a supersampled
    coverage. The plain pass gives each pixel's straight colour and opacity (alpha < 1 only for
    translucent materials); pixels whose centre missed every surface take the mean of their covered
    8-neighbours; the output alpha is coverage x opacity (premultiplied colour)."""
    opacity = rgba[..., 3].copy()
    hit = opacity > 0
    h, w = hit.shape
    straight = np.zeros((h, w, 3), dtype=np.float32)
    np.divide(rgba[..., :3], opacity[..., None], out=straight, where=hit[..., None])
    cov = coverage.astype(np.float32, copy=True)
    ys, xs = np.nonzero((~hit) & (cov > 0))
    if len(ys):
        acc = np.zeros((len(ys), 4), dtype=np.float32)
        cnt = np.zeros(len(ys), dtype=np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy == 0 and dx == 0:
                    continue
                yy, xx = ys + dy, xs + dx
                ok = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
                yy, xx = np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)
                m = ok & hit[yy, xx]
                acc[m, :3] += straight[yy[m], xx[m]]
                acc[m, 3] += opacity[yy[m], xx[m]]
                cnt += m
        mean = acc / np.maximum(cnt, 1.0)[:, None]
        straight[ys, xs] = mean[:, :3]
        opacity[ys, xs] = mean[:, 3]
    alpha = cov * opacity
    out = np.empty_like(rgba)
    out[..., :3] = straight * alpha[..., None]
    out[..., 3] = alpha
    return out


def box_downsample(img: np.ndarray, k: int) -> np.ndarray:
    if k == 1:
        return img
    h, w = img.shape[0] // k, img.shape[1] // k
    return img.reshape(h, k, w, k, *img.shape[2:]).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)


class Engine:
    """Context + renderer + cached pyrender scene of one backend instance."""

    def __init__(self, platform: str, device: int = 0) -> None:
        self.context = GLContext(platform, device)  # prepares the platform before OpenGL is imported
        self.context.make_current()
        import pyrender

        from ._renderer import FrameRenderer

        self.renderer = FrameRenderer()
        self.pscene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=np.zeros(3))
        self.entries: dict[int, _Entry] = {}
        self._lights_key: Any = None
        self._light_nodes: list[tuple[Any, Any, bool]] = []  # (node, IR light, casts)
        self._camera_node: Any = None
        self._point_notes: list[str] = []
        self.msaa_supported = self.renderer.max_samples >= 2
        ref = weakref.ref(self)

        def _close_at_exit() -> None:  # before the interpreter tears PyOpenGL down
            engine = ref()
            if engine is not None:
                engine.close()

        atexit.register(_close_at_exit)

    # -- scene sync --------------------------------------------------------------------------------
    def sync(self, scene: Any) -> Frame:
        t0 = time.perf_counter()
        tr = _translate_mod()
        self.context.make_current()
        seen: set[int] = set()
        nodes: list[Any] = []
        notes: list[str] = []
        rebuilt = 0
        for r in scene.renderables:
            seen.add(r.uid)
            key = _renderable_key(r)
            entry = self.entries.get(r.uid)
            if entry is None or entry.key != key:
                if entry is not None and entry.node is not None:
                    self.pscene.remove_node(entry.node)
                built = tr.build_renderable(r)
                node = None
                if built.mesh is not None:
                    node = self.pscene.add(built.mesh, pose=self._pose(r, built.offset))
                entry = _Entry(
                    key,
                    r.revision("transform"),
                    node,
                    built.offset,
                    built.notes,
                    tr.is_shadow_catcher(r),
                    r.emit_shadows,
                )
                self.entries[r.uid] = entry
                rebuilt += 1
            elif entry.transform_rev != r.revision("transform"):
                if entry.node is not None:
                    self.pscene.set_pose(entry.node, self._pose(r, entry.offset))
                entry.transform_rev = r.revision("transform")
            nodes.append(entry.node)
            notes += entry.notes
        for uid in [u for u in self.entries if u not in seen]:
            entry = self.entries.pop(uid)
            if entry.node is not None:
                self.pscene.remove_node(entry.node)
        self._sync_lights(scene.lights)
        self._sync_camera(scene.camera)
        shadow_key = (
            tuple((uid, e.key, e.transform_rev, e.casts_shadow) for uid, e in self.entries.items()),
            self._lights_key,
        )
        return Frame(
            scene=scene,
            nodes=nodes,
            tags=[r.tag for r in scene.renderables],
            notes=sorted(set(notes)),
            sync_seconds=time.perf_counter() - t0,
            rebuilt=rebuilt,
            shadow_key=shadow_key,
        )

    @staticmethod
    def _pose(r: Any, offset: np.ndarray) -> np.ndarray:
        t = np.eye(4)
        t[:3, 3] = offset
        return r.matrix_world @ t

    def _sync_lights(self, lights: Any) -> None:
        key = _lights_key(lights)
        if key == self._lights_key:
            return
        tr = _translate_mod()
        for node, _, _ in self._light_nodes:
            self.pscene.remove_node(node)
        self._light_nodes = []
        for light, pl, pose, casts in tr.build_lights(lights):
            node = self.pscene.add(pl, pose=pose)
            self._light_nodes.append((node, light, casts))
        # pyrender's ambient term has no 0.96 factor: scale it so base/0.96 x ambient = albedo x radiance
        self.pscene.ambient_light = tr.ambient_radiance(lights) * tr.DIFFUSE_COMPENSATION
        self._lights_key = key

    def _sync_camera(self, cam: Any) -> None:
        tr = _translate_mod()
        proj = tr.projection_matrix(cam)
        if self._camera_node is None:
            self._camera_node = self.pscene.add(tr.MatrixCamera(proj, cam.near, cam.far), pose=cam.matrix_world)
        else:
            c = self._camera_node.camera
            c.projection = proj
            c.znear, c.zfar = cam.near, cam.far
            self.pscene.set_pose(self._camera_node, cam.matrix_world)

    # -- rendering ---------------------------------------------------------------------------------
    def _shadow_flags(self, frame: Frame) -> int:
        from pyrender.constants import RenderFlags

        casters = any(
            self.entries[r.uid].casts_shadow and self.entries[r.uid].node is not None for r in frame.scene.renderables
        )
        flags = 0
        for _node, light, casts in self._light_nodes:
            if not casts:
                continue
            if isinstance(light, SunLight) and casters:
                flags |= RenderFlags.SHADOWS_DIRECTIONAL
            elif isinstance(light, (SpotLight, AreaLight)) and casters:
                flags |= RenderFlags.SHADOWS_SPOT
        return flags

    @property
    def software(self) -> bool:
        """True on a software rasteriser (llvmpipe, softpipe, swrast), where MSAA shades every sample."""
        name = self.renderer.gl_renderer.lower()
        return any(k in name for k in ("llvmpipe", "softpipe", "swrast", "software"))

    def _point_pixels(self, frame: Frame) -> float:
        """Pixel size (at the camera resolution) of clouds drawn as GL points: the projected diameter at the
        cloud centre's planar depth (the largest over such clouds; 1 if there are none). Also chooses how
        many points of each such cloud are drawn: at most ``POINTS_PER_PIXEL`` points per covered pixel
        (a prefix of the randomly ordered points), all of them when the cloud is not that dense."""
        cam = frame.scene.camera
        best = 1.0
        self._point_notes = []
        for node in frame.nodes:
            if node is None:
                continue
            for prim in node.mesh.primitives:
                d = getattr(prim, "point_diameter", None)
                if d is None:
                    continue
                centre = self.pscene.get_pose(node)[:3, 3]
                if isinstance(cam, OrthographicCamera):
                    px, extent_px = d / cam.pixel_size, prim.point_extent / cam.pixel_size
                else:
                    z = max(float(np.dot(centre - cam.translation, cam.viewdir)), cam.near)
                    px, extent_px = d * cam.fx / z, prim.point_extent * cam.fx / z
                best = max(best, px)
                n = len(prim.point_all_indices)
                area = min(np.pi * extent_px**2, float(cam.width * cam.height))
                m = int(min(n, max(POINTS_MIN_DRAWN, np.ceil(POINTS_PER_PIXEL * area / max(px, 1.0) ** 2))))
                if not prim._in_context():
                    m = n  # the element buffer is uploaded from the current indices: upload all of them
                prim._indices = prim.point_all_indices[:m]  # the element buffer holds all; draw a prefix
                if m < n:
                    self._point_notes.append(
                        f"pointcloud LOD: {m} of {n} points drawn (a random subset: about {POINTS_PER_PIXEL} "
                        "points per covered pixel at this view)"
                    )
        return best

    def _color(self, frame: Frame, w: int, h: int, aa: AntiAliasing, flags: int) -> np.ndarray:
        """Linear premultiplied (H, W, 4) colour with the anti-aliasing scheme ``aa``."""
        r = self.renderer
        px = self._point_pixels(frame)
        if aa.mode in ("none", "coverage"):
            r.point_size = px
            rgba = linearise_rgba8(r.render_color(self.pscene, w, h, 0, flags))
            if aa.mode == "coverage":
                ids = {node: i for i, node in enumerate(frame.nodes) if node is not None}
                # supersampled, not multisampled: llvmpipe's MSAA is 4x slower even for a trivial shader
                k = COVERAGE_SUPERSAMPLE
                r.point_size = px * k
                cov = box_downsample(r.render_coverage(self.pscene, w * k, h * k, 0, ids), k)
                rgba = apply_coverage(rgba, cov)
            return rgba
        if aa.mode == "msaa":
            r.point_size = px
            return linearise_rgba8(r.render_color(self.pscene, w, h, aa.msaa, flags))
        k = max(1, aa.supersample)  # "ssaa"
        r.point_size = px * k
        return box_downsample(linearise_rgba8(r.render_color(self.pscene, w * k, h * k, 0, flags)), k)

    def render(self, frame: Frame, settings: RenderSettings, aa: AntiAliasing) -> RenderResult:
        cam = frame.scene.camera
        w, h = cam.width, cam.height
        timings: dict[str, float] = {"sync": frame.sync_seconds}
        approximations = list(frame.notes)
        self.context.make_current()
        renderer = self.renderer
        renderer.no_shadow_nodes = {
            self.entries[r.uid].node for r in frame.scene.renderables if not self.entries[r.uid].casts_shadow
        }
        renderer.no_shadow_lights = {node for node, _, casts in self._light_nodes if not casts}
        point_px = self._point_pixels(frame)
        counts = tuple(
            len(p.indices)
            for n in frame.nodes
            if n is not None
            for p in n.mesh.primitives
            if hasattr(p, "point_diameter")
        )
        approximations += self._point_notes
        renderer.shadow_key = (frame.shadow_key, "all", counts, round(point_px, 3))
        catchers = [
            (i, node)
            for i, (r, node) in enumerate(zip(frame.scene.renderables, frame.nodes))
            if node is not None and self.entries[r.uid].catcher
        ]
        want = set(settings.outputs)
        kinds = [type(node.light).__name__ for node, _, _ in self._light_nodes]
        if any(kinds.count(k) > 4 for k in set(kinds)):
            approximations.append("lights: pyrender shades at most 4 lights of each type (the nearest are used)")
        if "rgb" in want and aa.mode == "coverage":
            approximations.append(
                "anti-aliasing: coverage scheme (silhouettes against the background are anti-aliased from a "
                "supersampled coverage pass; edges between objects are not)"
            )
        result = RenderResult(instance_tags=list(frame.tags))
        flags = self._shadow_flags(frame)
        gbuf = None
        try:
            if want & {"depth", "normal", "albedo", "instance"} or catchers:
                t0 = time.perf_counter()
                ids = {node: i for i, node in enumerate(frame.nodes) if node is not None}
                renderer.point_size = self._point_pixels(frame)
                gbuf = renderer.render_gbuffer(self.pscene, w, h, ids)
                timings["gbuffer"] = time.perf_counter() - t0
            if "rgb" in want:
                t0 = time.perf_counter()
                rgba = self._color(frame, w, h, aa, flags)
                timings["color"] = time.perf_counter() - t0
                if catchers:
                    t0 = time.perf_counter()
                    rgba = self._apply_catchers(frame, rgba, gbuf, catchers, w, h, aa, flags)
                    timings["shadow_catcher"] = time.perf_counter() - t0
                if not settings.transparent_background:
                    bg = np.clip(_translate_mod().ambient_radiance(frame.scene.lights), 0, None).astype(np.float32)
                    rgba[..., :3] += (1.0 - rgba[..., 3:4]) * bg
                    rgba[..., 3] = 1.0
                result.rgba = rgba
        except RenderError:
            raise
        except Exception as exc:
            raise RenderError(f"pyrender: rendering failed ({type(exc).__name__}: {exc})") from exc
        if gbuf is not None:
            if "depth" in want:
                result.depth = gbuf.depth
            if "normal" in want:
                result.normal = gbuf.normal
            if "albedo" in want:
                result.albedo = gbuf.albedo
            if "instance" in want:
                result.instance = gbuf.instance
        result.meta.update(
            backend="pyrender",
            platform=self.context.platform,
            gl_renderer=renderer.gl_renderer,
            antialiasing=aa.describe() if "rgb" in want else None,
            approximations=sorted(set(approximations)),
            timings=timings,
            rebuilt_renderables=frame.rebuilt,
        )
        return result

    def _apply_catchers(
        self,
        frame: Frame,
        rgba: np.ndarray,
        gbuf: Any,
        catchers: list[tuple[int, Any]],
        w: int,
        h: int,
        aa: AntiAliasing,
        flags: int,
    ) -> np.ndarray:
        """Shadow catchers: render the catchers alone (unoccluded light), then replace catcher pixels by
        black with alpha = 1 - shadowed / unshadowed luminance (Cycles' shadow-catcher compositing)."""
        catcher_nodes = {node for _, node in catchers}
        hidden = [n for n in self.pscene.mesh_nodes if n not in catcher_nodes and n.mesh.is_visible]
        for n in hidden:
            n.mesh.is_visible = False
        key = self.renderer.shadow_key
        self.renderer.shadow_key = (key, "catchers")
        try:
            alone = self._color(frame, w, h, aa, flags)
        finally:
            for n in hidden:
                n.mesh.is_visible = True
            self.renderer.shadow_key = key
        lum_w = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
        inst = gbuf.instance
        catcher_ids = [i for i, _ in catchers]
        in_front = (inst >= 0) & ~np.isin(inst, catcher_ids)  # another object is the first hit
        region = (alone[..., 3] > 0) & ~in_front  # catcher pixels, including its anti-aliased edges

        def luminance(img: np.ndarray) -> np.ndarray:
            straight = np.divide(img[..., :3], img[..., 3:4], out=np.zeros_like(img[..., :3]), where=img[..., 3:4] > 0)
            return straight @ lum_w

        with_occ, without = luminance(rgba), luminance(alone)
        ratio = np.divide(with_occ, without, out=np.ones_like(with_occ), where=without > 1e-6)
        shadow_alpha = np.clip(1.0 - ratio, 0.0, 1.0) * alone[..., 3]
        out = rgba.copy()
        out[region, :3] = 0.0
        out[region, 3] = shadow_alpha[region]
        return out

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
