"""The Mitsuba engine state that lives across renders: the variant, the engine lock and the last
translated scene.

The variant is chosen once per session by :mod:`blendify_mitsuba.variant` (JIT variants are probed in a
subprocess first: an unsuitable libLLVM aborts the process that uses it). ``mi.set_variant`` is
process-global: every use of the engine holds one process-wide lock with the session's variant set, and
the previous variant (another backend's or the user's own) is restored afterwards.

The last translation is kept and reused when nothing changed since it was made: the scene, as reported by
the core's change detection (:class:`blendify_core.pipeline.changes.ChangeTracker`), and the settings the
translation depends on (samples, pixel filter, bounces, effects, transparency, variant). A new seed, for
example, renders the loaded scene again (``meta["translate_cached"]``). When only the camera changed, its
sensor is translated again and the loaded scene is kept if the sensor is the same (``bf.render`` hands the
backend a copy of the camera for resolution percentages, lens distortion and re-centred scenes); any other
change translates the whole scene again.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import BlendifyError, InvalidSceneError, RenderError
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.changes import ChangeTracker
from blendify_core.pipeline.settings import RenderSettings

from .aniso import SquarePixelPlan
from .translate import MitsubaContext, MitsubaTranslator, ShapeInfo
from .variant import (
    VARIANT_ENV,
    VariantChoice,
    before_engine_import,
    choose_variant,
    quiet_engine_import,
    variant_from_environment,
    with_source,
)

__all__ = ["DEFAULT_MAX_ANALYTIC_OPAQUE", "DEFAULT_MAX_ANALYTIC_SPHERES", "MitsubaNative", "MitsubaSession"]

#: point clouds up to this many points become analytic spheres (exact), larger ones the merged icosphere mesh
#: when they cannot be one curve shape (emissive, partly transparent, too small for their distance: see
#: blendify_mitsuba.points.curves_fit). Measured (benchmarks/results/mitsuba_pointcloud_*.md): in scalar_rgb
#: analytic spheres load and render faster than the merged mesh up to ~100k points; in the JIT variants one
#: BSDF per sphere makes rendering slow (llvm_ad_rgb, 5k points: 9.2 s vs 0.35 s as curves).
DEFAULT_MAX_ANALYTIC_SPHERES = {"scalar": 100_000, "jit": 500}
#: clouds that can be one curve shape of spheres (blendify_mitsuba.points) are analytic spheres only up to this
#: many points, in every variant: the curves intersect the same spheres (per-point colours in a bitmap)
#: and load faster from a few hundred points on (scalar_rgb, 128x128, load + render: 1000 points
#: 0.75 s vs 0.29 s, 20k points 5.0 s vs 0.47 s). An explicit ``max_analytic_spheres`` applies to every cloud.
DEFAULT_MAX_ANALYTIC_OPAQUE = 500

# mi.set_variant is process-global: every use of the engine holds this lock and sets its variant
_ENGINE_LOCK = threading.RLock()


@dataclass
class MitsubaNative:
    """A translated scene: the loaded Mitsuba scene(s), the dictionary and what each shape stands for."""

    variant: str
    scene: Any
    scene_dict: dict[str, Any]
    shapes: dict[str, ShapeInfo]
    camera: Any
    spp: int = 1  # samples per rendered pixel (differs from settings.samples for fx != fy)
    samples: int = 1  # settings.samples it renders now (the square-pixel plan was made for it)
    aniso: SquarePixelPlan | None = None  # the square-pixel plan for fx != fy (see aniso)
    coverage_scene: Any = None  # shapes only: coverage alpha (when compositing)
    sky_scene: Any = None  # background/environment only: what the sky adds behind partial pixels (also when
    # an opaque film's emitters are hidden: added back behind uncovered pixels)
    sky_radiance: list[float] | None = None  # a constant sky's radiance: what sky_scene renders, without a render
    catcher_scene: Any = None  # shadow catchers alone (unshadowed radiance)
    catchers: list[int] = field(default_factory=list)  # renderable indices of the shadow catchers
    objects_scene: Any = None  # everything but the shadow catchers (what the other objects look like)
    light_shapes: list[str] = field(default_factory=list)  # light shapes to remove from the camera's view
    integrator: dict[str, Any] = field(default_factory=dict)
    effects: Any = None
    n_analytic_spheres: int = 0
    ignored: list[str] = field(default_factory=list)  # IR objects the translation ignored, and why
    approximations: list[str] = field(default_factory=list)  # beyond the capability table (meta)
    parallel_rays: bool = False  # the camera's rays are parallel (orthographic): planar depth = ray length
    translate_cached: bool = False  # reused from the previous render (nothing changed)


#: translations of one scene kept per session, by their settings (final's full passes and one pilot's)
CACHED_TRANSLATIONS = 2


class MitsubaSession:
    """One backend instance's engine state: its variant (resolved on first use), the engine lock and the
    cached translation."""

    def __init__(self, requested_variant: str | None, max_analytic_spheres: int | None, sampler: str) -> None:
        #: the requested variant comes from $BLENDIFY_MITSUBA_VARIANT (the code asked for none)
        self.from_env = False
        if requested_variant is None:
            try:
                requested_variant = variant_from_environment()
            except ValueError as exc:
                raise InvalidSceneError(str(exc)) from None
            self.from_env = requested_variant is not None
        self.requested_variant = requested_variant
        self._max_analytic_spheres = max_analytic_spheres
        self.sampler = sampler
        self._choice: VariantChoice | None = None
        self._tracker = ChangeTracker()
        #: the latest translations by their settings key, most recent last (at most CACHED_TRANSLATIONS)
        self._cache: dict[tuple[Any, ...], MitsubaNative] = {}

    # -- the variant and the engine ---------------------------------------------------------------------
    @property
    def variant_choice(self) -> VariantChoice:
        """The resolved :class:`~blendify_mitsuba.variant.VariantChoice` (probes on first use)."""
        if self._choice is None:
            source = f"{VARIANT_ENV}={self.requested_variant}" if self.from_env else None
            self._choice = with_source(choose_variant(self.requested_variant), source)
        return self._choice

    @property
    def variant(self) -> str:
        return self.variant_choice.variant

    @property
    def max_analytic_spheres(self) -> int:
        """Point clouds up to this size become analytic spheres (default depends on the variant)."""
        if self._max_analytic_spheres is not None:
            return self._max_analytic_spheres
        return DEFAULT_MAX_ANALYTIC_SPHERES["scalar" if self.variant.startswith("scalar") else "jit"]

    @property
    def max_analytic_opaque(self) -> int:
        """Clouds that can be one curve shape are analytic spheres up to this size (an explicit
        ``max_analytic_spheres``, else :data:`DEFAULT_MAX_ANALYTIC_OPAQUE` within the variant's limit)."""
        if self._max_analytic_spheres is not None:
            return self._max_analytic_spheres
        return min(DEFAULT_MAX_ANALYTIC_OPAQUE, self.max_analytic_spheres)

    def set_variant(self) -> Any:
        """Import mitsuba (the first import chooses Dr.Jit's libLLVM) and set this session's variant."""
        variant = self.variant  # resolve (and probe) before the first import of mitsuba/drjit
        before_engine_import()
        with quiet_engine_import(variant):
            import mitsuba as mi

        if mi.variant() != variant:
            try:
                mi.set_variant(variant)
            except Exception as exc:  # e.g. a variant missing from this build
                raise RenderError(f"mitsuba: cannot set variant {variant!r}: {exc}") from exc
        return mi

    @contextlib.contextmanager
    def engine(self) -> Iterator[Any]:
        """Hold the engine lock with this session's variant set; the previous variant (another backend's or
        the user's own ``mi.set_variant``) is restored afterwards."""
        with _ENGINE_LOCK:
            previous = sys.modules["mitsuba"].variant() if "mitsuba" in sys.modules else None
            mi = self.set_variant()
            try:
                yield mi
            finally:
                if previous is not None and previous != mi.variant():
                    mi.set_variant(previous)

    # -- translation ------------------------------------------------------------------------------------
    def translate(self, scene: Scene, settings: RenderSettings) -> MitsubaNative:
        """The native scene of ``scene``: the previous one when neither the scene (core change detection)
        nor the translation settings changed, or only the camera changed but not its sensor; else a new
        translation. A new sample count alone reuses it too (``mi.render`` takes the count per call; only the
        square-pixel plan of a camera with fx != fy depends on it): ``final``'s passes of new sizes used to
        reload the whole scene each time. The last ``CACHED_TRANSLATIONS`` settings keep theirs, so ``final``'s
        pilot (other bounces or caustics) and the full passes after it load the scene once each."""
        if not isinstance(scene, Scene):
            raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
        if scene.camera is None:
            raise InvalidSceneError("scene.camera: the scene has no camera")
        key = (
            settings.pixel_filter,
            settings.max_bounces,
            settings.effects,
            settings.caustics,
            settings.transparent_background,
            self.variant,
        )
        changes = self._tracker.update(scene)
        cache, self._cache = self._cache, {}
        try:
            if changes.any:  # only the translation asked for can be checked against a camera-only change
                kept, cache = cache.get(key), {}
                if kept is not None and changes.geometry_only_camera and self._same_sensor(kept, scene, settings):
                    cache[key] = kept
            cached = cache.pop(key, None)
            if cached is not None and (cached.aniso is None or cached.samples == settings.samples):
                if cached.aniso is None:
                    cached.spp = cached.samples = int(settings.samples)
                cached.camera = scene.camera
                cached.translate_cached = True
                native = cached
            else:
                native = self._load(scene, settings)
        except BaseException:
            self._tracker.reset()  # the recorded state was never translated
            raise
        cache[key] = native
        while len(cache) > CACHED_TRANSLATIONS:
            del cache[next(iter(cache))]
        self._cache = cache
        return native

    @property
    def native(self) -> MitsubaNative | None:
        """The translation of the latest render (None before the first or after :meth:`close`)."""
        return next(reversed(self._cache.values()), None)

    def _translator(self, settings: RenderSettings) -> MitsubaTranslator:
        return MitsubaTranslator(
            settings,
            max_analytic_spheres=self.max_analytic_spheres,
            max_analytic_opaque=self.max_analytic_opaque,
            sampler=self.sampler,
        )

    def _same_sensor(self, native: MitsubaNative, scene: Scene, settings: RenderSettings) -> bool:
        """Whether the camera of ``scene`` translates to the sensor ``native`` was loaded with."""
        with self.engine():  # at the sample count it was loaded with: only the camera is compared
            sensor = self._translator(settings.replace(samples=native.samples)).sensor(MitsubaContext(scene=scene))
        return _same_value(sensor, native.scene_dict["sensor"])

    def _load(self, scene: Scene, settings: RenderSettings) -> MitsubaNative:
        """Translate ``scene`` and load its dictionaries (errors of the engine become RenderError)."""
        translator = self._translator(settings)
        with self.engine() as mi:
            try:
                tr = translator.translate(scene)
            except BlendifyError:
                raise
            except Exception as exc:
                raise RenderError(f"mitsuba: translating the scene failed: {type(exc).__name__}: {exc}") from exc
            try:
                mi_scene = mi.load_dict(tr.scene_dict)
                cov_scene = sky_scene = catcher_scene = objects_scene = None
                if tr.catcher_dict is not None:
                    catcher_scene = mi.load_dict(tr.catcher_dict)
                if tr.objects_dict is not None:
                    objects_scene = mi.load_dict(tr.objects_dict)
                if tr.coverage_dict is not None:
                    cov_scene = mi.load_dict(tr.coverage_dict)
                if tr.background_dict is not None:
                    sky_scene = mi.load_dict(tr.background_dict)
            except Exception as exc:
                raise RenderError(f"mitsuba: mi.load_dict failed: {exc}") from exc
        return MitsubaNative(
            variant=self.variant,
            scene=mi_scene,
            scene_dict=tr.scene_dict,
            shapes=tr.shapes,
            camera=scene.camera,
            spp=tr.spp,
            samples=int(settings.samples),
            aniso=tr.aniso,
            coverage_scene=cov_scene,
            sky_scene=sky_scene,
            sky_radiance=tr.sky_radiance,
            catcher_scene=catcher_scene,
            objects_scene=objects_scene,
            catchers=tr.catchers,
            light_shapes=tr.light_shapes,
            integrator=tr.integrator,
            effects=tr.effects,
            n_analytic_spheres=tr.n_analytic_spheres,
            ignored=tr.ignored,
            approximations=tr.approximations,
            parallel_rays=tr.parallel_rays,
        )

    def close(self) -> None:
        """Drop the cached translation."""
        self._cache = {}
        self._tracker.reset()


def _same_value(a: Any, b: Any) -> bool:
    """Equality of two sensor dictionaries (nested dictionaries, numbers, strings and Mitsuba transforms)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same_value(a[k], b[k]) for k in a)
    if type(a) is not type(b):
        return False
    if hasattr(a, "matrix"):  # mi.ScalarTransform4f
        return bool(np.array_equal(np.array(a.matrix), np.array(b.matrix)))
    return bool(a == b)
