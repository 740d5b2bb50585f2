"""A path tracer for scenes with lights that cast no shadow (Blender's ``use_shadow=False``).

Mitsuba's own ``path`` integrator tests the visibility of every emitter sample. Blender's non-shadowing
lights skip that test: their light reaches every surface point, occluded or not (at every bounce). This
module registers the integrator ``blendify_path``: the same unidirectional path tracer as Mitsuba's
``path`` (next-event estimation combined with BSDF sampling by the power heuristic, Russian roulette from
``rr_depth`` on, ``hide_emitters`` hiding emission seen from the camera directly or through null surfaces
(such as other lights' shapes, as Mitsuba 3.9 passes camera rays through them), the alpha set once a path
continues from a non-null surface), except that next-event samples of the emitters named in ``no_shadow``
(their ids, comma-separated) are not tested for visibility, and with ``transparent_shadows`` = n > 0 the
other samples' shadow rays pass through up to n surfaces with a null component (alpha < 1), keeping their
null transmission (Cycles' transparent shadows; ``volpath`` does the same for scenes without such lights).
BSDF-sampled rays still hit an area light only where nothing is in between (as in Cycles, which also only
skips the shadow ray).

With ``no_caustics`` a vertex reached by a diffuse bounce evaluates and samples only its diffuse (and null)
lobes: light reaching a diffuse surface through a glossy or refractive one is left out, as with Cycles'
``caustics_reflective`` / ``caustics_refractive`` off (``RenderSettings.caustics``).

The translator uses it only when a scene has such a light or caustics are off. In the vectorised variants its
bounces are one symbolic loop (``drjit.while_loop``: one kernel, no Python per bounce), about as fast per sample
as ``path`` (0.7-2.2x on 48 px renders of a few hundredths of a second); the scalar variants run the same loop
body in Python per sample, 13-79x slower than ``path`` (measured in benchmarks/results/mitsuba_no_shadow.md and at
``NO_CAUSTICS_COST``).

Mitsuba is imported inside the functions; :func:`register` is called with the variant set (the session's
engine lock held).
"""

from __future__ import annotations

from typing import Any

from .variant import register_plugin

__all__ = ["INTEGRATOR", "register"]

#: the plugin name of the integrator
INTEGRATOR = "blendify_path"


def register() -> str:
    """Register :data:`INTEGRATOR` for the current Mitsuba variant (once per variant); its name."""
    return register_plugin("integrator", INTEGRATOR, _integrator_class)


def _mis(a: Any, b: Any) -> Any:
    """The power heuristic weight of a sample with pdf ``a`` against the other strategy's ``b``."""
    import drjit as dr

    a2 = a * a
    den = a2 + b * b
    w = a2 / dr.select(den > 0, den, 1.0)
    return dr.detach(dr.select(dr.isfinite(w), w, 0.0))


def _integrator_class() -> type:
    """The integrator class for the current variant (Mitsuba's base classes differ per variant)."""
    import drjit as dr
    import mitsuba as mi

    class NoShadowPath(mi.SamplingIntegrator):  # type: ignore[misc,name-defined]
        """``path`` with per-emitter visibility tests (see the module's documentation)."""

        def __init__(self, props: Any) -> None:
            # the base class warns that Python integrators are slow in scalar variants: the cost is
            # measured and documented (benchmarks/results/mitsuba_no_shadow.md), not news at every render
            logger = mi.logger()
            level = logger.log_level()
            logger.set_log_level(mi.LogLevel.Error)
            try:
                super().__init__(props)
            finally:
                logger.set_log_level(level)
            self.max_depth = int(props.get("max_depth", -1))
            self.rr_depth = int(props.get("rr_depth", 5))
            self.hide = bool(props.get("hide_emitters", False))
            self.no_shadow = {s for s in str(props.get("no_shadow", "")).split(",") if s}
            #: surfaces with a null component (alpha < 1) a shadow ray may cross (0: shadow rays are opaque)
            self.transparent_shadows = int(props.get("transparent_shadows", 0))
            self.no_caustics = bool(props.get("no_caustics", False))
            self._jit = dr.is_jit_v(mi.Float)
            # a scalar variant's masks are Python bools (``~True == -2``)
            self._not = (lambda m: ~m) if self._jit else (lambda m: not m)

        def _shadowless(self, pointers: list[Any], emitter: Any) -> Any:
            """Whether the sampled ``emitter`` casts no shadow (a mask in the vectorised variants, where
            ``pointers`` are the shadowless emitters of the scene)."""
            if not self._jit:
                return emitter is not None and emitter.id() in self.no_shadow
            mask = mi.Bool(False)
            for ptr in pointers:
                mask |= emitter == ptr
            return mask

        def _transmittance(self, scene: Any, si: Any, ds: Any, active: Any) -> Any:
            """The light a shadow ray from ``si`` to the emitter sample ``ds`` keeps: the product of the null
            transmissions (1 - alpha) of the surfaces it crosses, 0 when it meets an opaque one or more than
            ``transparent_shadows`` surfaces (Cycles' limit of transparent bounces). Unrolled: in the
            vectorised variants it is part of the loop's kernel (masked, no early exit)."""
            tr = mi.Spectrum(1.0)
            it = mi.Interaction3f(si)
            active = mi.Bool(active)
            for _ in range(self.transparent_shadows + 1):
                ray = it.spawn_ray_to(ds.p)
                hit = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=False, active=active)
                active &= hit.is_valid()
                if not self._jit and not active:
                    return tr
                tr = dr.select(active, tr * hit.bsdf(ray).eval_null_transmission(hit, active), tr)
                active &= dr.max(tr) > 0
                it = dr.select(active, mi.Interaction3f(hit), it)
            return dr.select(active, 0.0, tr)  # still crossing surfaces after the limit: blocked

        def sample(
            self, scene: Any, sampler: Any, ray_: Any, medium: Any = None, active: Any = True
        ) -> tuple[Any, Any, list[Any]]:
            """One path per lane. The vectorised variants run the bounces as one symbolic loop (one kernel
            with Mitsuba's own ``path``'s structure: no evaluation per bounce, no Python per bounce); the
            scalar variants run the same loop body in Python until the path ends."""
            pointers = [mi.EmitterPtr(e) for e in scene.emitters() if e.id() in self.no_shadow] if self._jit else []
            state = (
                sampler,
                mi.Ray3f(ray_),
                mi.UInt32(0),  # depth
                mi.Spectrum(1.0),  # throughput
                mi.Spectrum(0.0),  # result
                mi.Float(1.0),  # eta
                mi.Bool((not self.hide) and scene.environment() is not None),  # valid
                dr.zeros(mi.Interaction3f),  # the previous vertex
                mi.Float(1.0),  # its BSDF sample's pdf
                mi.Bool(True),  # whether that sample was a delta lobe's
                mi.Bool(True),  # camera: the path has only passed through null surfaces since the camera
                mi.Bool(False),  # after_diffuse: the last bounce (not through a null surface) was diffuse
                mi.Bool(active),
            )

            def body(*state: Any) -> tuple[Any, ...]:
                return self._bounce(scene, pointers, *state)

            if self._jit:
                state = dr.while_loop(
                    state=state,
                    cond=lambda *s: s[-1],
                    body=body,
                    labels=(
                        "sampler",
                        "ray",
                        "depth",
                        "throughput",
                        "result",
                        "eta",
                        "valid",
                        "prev_si",
                        "prev_pdf",
                        "prev_delta",
                        "camera",
                        "after_diffuse",
                        "active",
                    ),
                    label="blendify_path",
                )
            else:
                while state[-1]:
                    state = body(*state)
            return state[4], state[6], []

        def _bounce(
            self,
            scene: Any,
            pointers: list[Any],
            sampler: Any,
            ray: Any,
            depth: Any,
            throughput: Any,
            result: Any,
            eta: Any,
            valid: Any,
            prev_si: Any,
            prev_pdf: Any,
            prev_delta: Any,
            camera: Any,
            after_diffuse: Any,
            active: Any,
        ) -> tuple[Any, ...]:
            """One bounce of the path (the loop body of :meth:`sample`): masked Dr.Jit operations, with Python
            branches only in the scalar variants (where masks are Python bools)."""

            def state(alive: Any) -> tuple[Any, ...]:  # the loop state with these variables' latest values
                return (sampler, ray, depth, throughput, result, eta, valid, prev_si, prev_pdf, prev_delta, camera,
                        after_diffuse, alive)  # fmt: skip

            ctx = mi.BSDFContext()
            no = self._not
            max_depth = self.max_depth if self.max_depth >= 0 else 2**31 - 1
            si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=depth == 0, active=active)
            # emission reached by the previous BSDF sample (or by the camera ray)
            shown = active & no(mi.Bool(self.hide) & camera)
            ds = mi.DirectionSample3f(scene, si=si, ref=prev_si)
            if self._jit or (shown and ds.emitter is not None):
                em_pdf = scene.pdf_emitter_direction(prev_si, ds, no(prev_delta) & shown)
                em_pdf = dr.select(prev_delta, 0.0, em_pdf)
                emitted = ds.emitter.eval(si, (prev_pdf > 0) & shown)
                result = dr.select(shown, result + throughput * emitted * _mis(prev_pdf, em_pdf), result)
            active_next = active & (depth + 1 < max_depth) & si.is_valid()
            if not self._jit and not active_next:
                return state(False)
            bsdf = si.bsdf(ray)
            # next-event estimation; shadowing emitters' samples are tested for visibility here
            active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
            ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), False, active_em)
            test = active_em & (ds.pdf != 0) & no(self._shadowless(pointers, ds.emitter))
            if self._jit or test:
                if self.transparent_shadows > 0:
                    em_weight = dr.select(test, em_weight * self._transmittance(scene, si, ds, test), em_weight)
                else:
                    occluded = scene.ray_test(si.spawn_ray_to(ds.p), test)
                    em_weight = dr.select(test & occluded, 0.0, em_weight)
            wo = si.to_local(ds.d)
            s1 = sampler.next_1d()
            s2 = sampler.next_2d()
            val, pdf, bs, weight = self._eval_pdf_sample(bsdf, ctx, after_diffuse, si, wo, s1, s2, active_next)
            mis_em = dr.select(ds.delta, 1.0, _mis(ds.pdf, pdf))
            result = dr.select(active_em, result + throughput * val * em_weight * mis_em, result)
            # the next vertex
            ray = dr.select(active_next, si.spawn_ray(si.to_world(bs.wo)), ray)
            prev_si = dr.select(active_next, mi.Interaction3f(si), prev_si)
            prev_pdf = dr.select(active_next, bs.pdf, prev_pdf)
            prev_delta = dr.select(active_next, mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta), prev_delta)
            throughput = dr.select(active_next, throughput * weight, throughput)
            eta = dr.select(active_next, eta * bs.eta, eta)
            valid |= active_next & no(mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null))
            camera &= no(active_next) | mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null)
            if self.no_caustics:
                passed = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null)
                diffuse = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Diffuse)
                after_diffuse = dr.select(active_next & no(passed), diffuse, after_diffuse)
            depth = dr.select(active_next, depth + 1, depth)
            # Russian roulette
            t_max = dr.max(throughput)
            rr_prob = dr.minimum(t_max * eta * eta, 0.95)
            rr_active = depth >= self.rr_depth
            rr_go = sampler.next_1d() < rr_prob
            throughput = dr.select(rr_active, throughput / dr.maximum(rr_prob, 1e-30), throughput)
            active = active_next & (no(rr_active) | rr_go) & (t_max != 0)
            return state(active)

        def _eval_pdf_sample(
            self, bsdf: Any, ctx: Any, after_diffuse: Any, si: Any, wo: Any, s1: Any, s2: Any, active: Any
        ) -> Any:
            """``bsdf.eval_pdf_sample`` with all lobes, or (``no_caustics``) only the diffuse (and null) ones where
            the path arrived by a diffuse bounce, as Cycles' caustics switches drop glossy and refractive closures
            there (a vectorised variant evaluates both where needed and selects per lane)."""
            if not self.no_caustics:
                return bsdf.eval_pdf_sample(ctx, si, wo, s1, s2, active)
            ctx_diffuse = mi.BSDFContext()
            ctx_diffuse.type_mask = mi.BSDFFlags.Diffuse | mi.BSDFFlags.Null
            if not self._jit:
                return bsdf.eval_pdf_sample(ctx_diffuse if after_diffuse else ctx, si, wo, s1, s2, active)
            full = bsdf.eval_pdf_sample(ctx, si, wo, s1, s2, active & ~after_diffuse)
            diff = bsdf.eval_pdf_sample(ctx_diffuse, si, wo, s1, s2, active & after_diffuse)
            return tuple(dr.select(after_diffuse, d, f) for d, f in zip(diff, full))

        def aov_names(self) -> list[str]:
            return []

        def to_string(self) -> str:
            return (
                f"NoShadowPath[max_depth={self.max_depth}, no_shadow={sorted(self.no_shadow)}, "
                f"transparent_shadows={self.transparent_shadows}, no_caustics={self.no_caustics}]"
            )

    return NoShadowPath
