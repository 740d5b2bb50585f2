"""blendify-core backend ``mitsuba``: the IR rendered by Mitsuba 3, the independent cross-check of Cycles.

Where things live: :mod:`blendify_mitsuba.translate` (one handler per IR type: the IR as a Mitsuba scene
dictionary, with the capabilities declared beside the handlers), :mod:`blendify_mitsuba.render` (the
colour image, compositing, the shadow-catcher emulation and the geometric outputs from pixel-centre rays),
:mod:`blendify_mitsuba.session` (the variant, the engine lock and the cached translation),
:mod:`blendify_mitsuba.capabilities` (the table), :mod:`blendify_mitsuba.variant` (choosing a variant
without crashing the process) and :mod:`blendify_mitsuba.aniso` (non-square pixels).

The engine is imported lazily (on the first translate/render), never at module import time, so the
registry and :meth:`MitsubaBackend.probe` stay cheap. The variant is chosen by
:mod:`blendify_mitsuba.variant` (JIT variants are probed in a subprocess first: an unsuitable libLLVM
aborts the process that uses it).
"""

from __future__ import annotations

import importlib.util
import logging
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.backend import Backend, DeviceChoice, parse_device
from blendify_core.pipeline.capabilities import Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.registry import BackendStatus

from . import capabilities as _capabilities
from . import variant as _variant
from .render import render_native
from .session import DEFAULT_MAX_ANALYTIC_OPAQUE, DEFAULT_MAX_ANALYTIC_SPHERES, MitsubaNative, MitsubaSession
from .translate import DEFAULT_SAMPLER, MitsubaTranslator
from .variant import KNOWN_VARIANTS, VariantChoice, describe

# a library logs, the application decides where to: no "No handlers could be found" output by default
logging.getLogger("blendify_mitsuba").addHandler(logging.NullHandler())

__all__ = [
    "MitsubaBackend",
    "MitsubaNative",
    "MitsubaTranslator",
    "DEFAULT_MAX_ANALYTIC_OPAQUE",
    "DEFAULT_MAX_ANALYTIC_SPHERES",
]


#: the time per sample of ``blendify_path`` with ``no_caustics`` relative to Mitsuba's ``path`` (what ``final``'s
#: caustics pilot weighs its samples by): scalar_rgb runs its bounces in Python, measured 13-33x on a plastic ball
#: and cube under a sun (64 px, benchmarks/effects_pay.py) and 31-79x in benchmarks/results/mitsuba_no_shadow.md (48
#: px, loaded); the vectorised variants run it as one symbolic loop (one kernel, as ``path``): llvm_ad_rgb 0.7-1.1x
#: per sample (median about 1.0; 128 px, 64 spp, plastic under a sun, under a sun and a sky, Lambertian; paired,
#: under load), weighed 1.25 here (it was 45x there while the loop was evaluated bounce by bounce)
NO_CAUSTICS_COST = {"scalar": 30.0, "jit": 1.25}

#: the fixed time of one render call (a pass of ``final``) in pixel-samples, per variant family: measured on a warm
#: backend as (time of 1 spp) less 1/32 of (33 spp - 1 spp), plastic ball and cube under a sky and the floating
#: bunny at 32 and 96 px: scalar_rgb 3.3-5.7 ms per call against 0.7-1.5 us per pixel-sample on one thread
#: (2.2e3-3.9e3; about twice that on two threads), llvm_ad_rgb 10-13 ms against 0.34-0.86 us (1.2e4-4.0e4); the
#: lowest, so a pilot is never refused for a cost it does not have
PASS_OVERHEAD = {"scalar": 2.2e3, "jit": 1.2e4}

#: the extra time of the first call with other settings (a pilot's: the scene is translated and loaded again
#: for them) in pixel-samples, per variant family: measured on the plastic ball and cube under a sun and a sky
#: at 32 px, a 16-spp pass with max_bounces=0 right after full ones against the same pass again: +25-40 ms in
#: scalar_rgb (3.5e4-5e4 pixel-samples at 0.7 us each on two threads) and +26 ms in llvm_ad_rgb with its
#: kernels in Dr.Jit's cache (6e4 at 0.43 us; compiling them costs another 0.75-1 s, not counted: a cached
#: kernel does not pay it). One pass call (PASS_OVERHEAD) was counted before, and a scalar pilot that kept the
#: light ran 0.79x at 32 px (the pilot, 2 passes with the scene's translation and load, took 0.10-0.16 s where
#: a 0.65 s render counted it as 38 samples, 0.045 s)
SWITCH_OVERHEAD = {"scalar": 3.0e4, "jit": 3.0e4}

#: ``device=`` -> the variant asked for ("cpu": the fastest CPU variant, llvm_ad_rgb else scalar_rgb)
#: ("gpu": cuda_ad_rgb, else the fastest CPU variant, with the reason)
_DEVICE_VARIANT = {
    "cpu": "cpu",
    "gpu": "gpu",
    "cuda": "gpu",
    "llvm": "llvm_ad_rgb",
    "scalar": "scalar_rgb",
}
_DEVICE_MEANING = {
    "cpu": "a CPU variant (llvm or scalar)",
    "gpu": "a CUDA variant",
    "cuda": "a CUDA variant",
    "llvm": "an llvm variant",
    "scalar": "a scalar variant",
}
DEVICE_FAMILIES = ("cuda", "llvm", "scalar")


def _family(variant: str) -> str:
    """The variant family: "cuda", "llvm", "scalar"; "cpu" for the CPU request (llvm and scalar both
    satisfy it); "cuda" for the GPU request."""
    if variant in ("cpu", "gpu"):
        return "cpu" if variant == "cpu" else "cuda"
    return variant.split("_", 1)[0]


class MitsubaBackend(Backend):
    """Mitsuba 3 backend.

    Options: ``variant`` (None = the variant named by ``$BLENDIFY_MITSUBA_VARIANT`` when set, else the fastest
    variant that passes a subprocess probe, else ``scalar_rgb``; or a variant name such as "scalar_rgb",
    "llvm_ad_rgb"; an unusable JIT variant falls back to ``scalar_rgb`` with the reason in
    ``result.meta["variant_reason"]``),
    ``max_analytic_spheres`` (point clouds up to this size are analytic spheres, larger ones one curve shape
    of spheres when they are opaque and not emissive, else the IR's merged icosphere mesh; None = the measured
    defaults: DEFAULT_MAX_ANALYTIC_OPAQUE for clouds that can be curves, DEFAULT_MAX_ANALYTIC_SPHERES of the
    variant for the others) and
    ``device`` (None: as ``variant``; "cpu": llvm_ad_rgb when its probe passes, else scalar_rgb; "gpu" or
    "cuda": cuda_ad_rgb; "llvm" / "scalar": that variant; without the device ``bf.render`` warns and renders
    on the variant that works, or raises ``BackendUnavailableError`` with ``strict=True``, as it does for an
    explicit ``variant`` that falls back; ``result.meta["device"]`` says what ran),
    ``sampler`` (Mitsuba's sampler plugin, one of :attr:`SAMPLERS`; default ``multijitter``, measured in
    benchmarks/results/mitsuba_noise.md).
    """

    path_tracer = True  # target_error: independent passes until the estimated error is reached
    name = "mitsuba"
    engine = "mitsuba"
    qualities = ("final", "draft", "preview")
    translator_class = MitsubaTranslator
    #: ``scene.export_mitsuba("x.xml")`` / ``scene.export("x.xml")`` (see :mod:`blendify_mitsuba.export`)
    file_formats = ("mitsuba",)
    #: Mitsuba's path tracer has no sample clamp, no Filter Glossy and one depth limit for every kind of bounce
    unapplied_settings = ("clamp_direct", "clamp_indirect", "filter_glossy", "bounce_limits")
    # measured with Mitsuba 3.9.1 (tests/robustness/test_hard_cases_round2.py): a sphere 4.5e13 m away renders,
    # 4.5e14 m away nothing; near 1e-18 m renders, 1e-19 m nothing
    numeric_limits = {"max_distance": 1e14, "min_near": 1e-18}

    SAMPLERS = ("independent", "stratified", "multijitter", "ldsampler", "orthogonal")

    def __init__(
        self,
        variant: str | None = None,
        max_analytic_spheres: int | None = None,
        sampler: str = DEFAULT_SAMPLER,
        device: str | None = None,
        **options: Any,
    ) -> None:
        super().__init__(**options)
        #: None (automatic, as ``variant=None``), "cpu", "gpu", or a variant family: "cuda", "llvm", "scalar"
        self.device = None if device is None else parse_device(device, DEVICE_FAMILIES)
        if sampler not in self.SAMPLERS:
            raise InvalidSceneError(f"sampler: expected one of {list(self.SAMPLERS)}, got {sampler!r}")
        if variant is not None and (not isinstance(variant, str) or variant not in KNOWN_VARIANTS):
            raise InvalidSceneError(
                f"variant: expected None or one of {list(KNOWN_VARIANTS)} (RGB variants), got {variant!r}"
            )
        if max_analytic_spheres is not None and (
            isinstance(max_analytic_spheres, bool)
            or not isinstance(max_analytic_spheres, (int, np.integer))
            or max_analytic_spheres < 0
        ):
            raise InvalidSceneError(
                f"max_analytic_spheres: expected None or an integer >= 0, got {max_analytic_spheres!r}"
            )
        if self.device is not None:
            implied = _DEVICE_VARIANT[self.device]
            if variant is not None and _family(variant) != _family(implied):
                raise InvalidSceneError(
                    f"device={device!r} and variant={variant!r} disagree (device {device!r} means "
                    f"{_DEVICE_MEANING[self.device]}); give one of them"
                )
            variant = variant or implied
        self.session = MitsubaSession(
            variant, None if max_analytic_spheres is None else int(max_analytic_spheres), sampler
        )

    def pilot_sample_cost(self, settings: RenderSettings) -> float:
        """``caustics=False`` renders with the Python integrator ``blendify_path``: per sample about
        :data:`NO_CAUSTICS_COST` times Mitsuba's ``path`` in its variant family (measured; see there)."""
        if settings.caustics:
            return 1.0
        return NO_CAUSTICS_COST[self._cost_family()]

    def pass_overhead(self, settings: RenderSettings) -> float:
        """One render call's fixed time in pixel-samples of its variant family (:data:`PASS_OVERHEAD`)."""
        return PASS_OVERHEAD[self._cost_family()]

    def switch_overhead(self, settings: RenderSettings) -> float:
        """The first call with other settings: a translation and load of the scene (:data:`SWITCH_OVERHEAD`)."""
        return SWITCH_OVERHEAD[self._cost_family()]

    def _cost_family(self) -> str:
        """The key of the measured per-variant costs (NO_CAUSTICS_COST, PASS_OVERHEAD): "scalar" or "jit"."""
        return "scalar" if self.session.variant_choice.variant.startswith("scalar") else "jit"

    def device_choice(self) -> DeviceChoice | None:
        """What this backend renders on: the variant chosen (probes run once per process) and, when the
        device or variant asked for is not the one that runs (no GPU for ``cuda_ad_rgb``, no usable
        libLLVM for ``llvm_ad_rgb``), why. ``bf.render`` refuses that under ``strict=True``."""
        requested = self.session.requested_variant
        choice = self.session.variant_choice
        used = f"{'GPU' if choice.variant.startswith('cuda') else 'CPU'} ({choice.variant})"
        label = self.device or requested or "auto"
        fallback = None
        if requested not in (None, "cpu") and _family(choice.variant) != _family(requested):
            family = _family(requested)
            causes = [a.summary for a in choice.attempts if _family(a.variant) == family]
            fallback = (
                f"{family} variants unavailable: {'; '.join(causes)}" if causes else choice.summary or choice.reason
            )
        gpus = tuple(f"GPU {g}" for g in _variant.gpu_devices())
        return DeviceChoice(label, used, fallback, ("CPU", *gpus), "device" if self.device else "variant")

    # -- discovery -------------------------------------------------------------------------------
    @classmethod
    def probe(cls) -> BackendStatus:
        if importlib.util.find_spec("mitsuba") is None or importlib.util.find_spec("drjit") is None:
            return BackendStatus(False, "the 'mitsuba' package is not installed (pip install mitsuba)", None)
        return BackendStatus(True, None, cls.engine_version())

    @classmethod
    def info_details(cls) -> list[str]:
        """Lines for ``blendify info``: the variant a default ``MitsubaBackend()`` uses here and why, one line
        per variant probe (the probes run now when the probe cache has no result for them)."""
        gpus = _variant.gpu_devices()
        try:
            requested = _variant.variant_from_environment()
        except ValueError as exc:
            return [f"unusable setting: {exc}"]
        lines = describe(requested, None if requested is None else f"{_variant.VARIANT_ENV}={requested}")
        return [*lines, f"devices: CPU; GPU: {', '.join(gpus) if gpus else 'none (no NVIDIA device node)'}"]

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return _capabilities.capabilities()

    @classmethod
    def export_file(cls, scene: Any, file_format: str, path: Any, **kwargs: Any) -> Any:
        """Write ``scene`` as a Mitsuba 3 XML file (see :func:`blendify_mitsuba.export.export_mitsuba`)."""
        if file_format != "mitsuba":
            return super().export_file(scene, file_format, path, **kwargs)
        from .export import export_mitsuba

        return export_mitsuba(scene, path, **kwargs)

    # -- the session's state -----------------------------------------------------------------------
    @property
    def sampler(self) -> str:
        return self.session.sampler

    @property
    def requested_variant(self) -> str | None:
        return self.session.requested_variant

    @property
    def variant_choice(self) -> VariantChoice:
        """The resolved :class:`~blendify_mitsuba.variant.VariantChoice` (probes on first use)."""
        return self.session.variant_choice

    @property
    def variant(self) -> str:
        return self.session.variant

    @property
    def max_analytic_spheres(self) -> int:
        """Point clouds up to this size become analytic spheres (default depends on the variant)."""
        return self.session.max_analytic_spheres

    # -- work --------------------------------------------------------------------------------------
    def translate(self, scene: Scene, settings: RenderSettings) -> MitsubaNative:
        """The loaded Mitsuba scene (reused while neither the scene nor the translation settings change)."""
        return self.session.translate(scene, settings)

    def render(self, native: MitsubaNative, settings: RenderSettings) -> RenderResult:
        """Render a native scene from :meth:`translate` (see :mod:`blendify_mitsuba.render`)."""
        return render_native(native, settings, self.session, self.name, self.engine_version())

    def close(self) -> None:
        self.session.close()
        super().close()
