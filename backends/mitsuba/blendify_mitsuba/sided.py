"""Cycles' sidedness rule for a surface whose shading normals lean far from its faces (the IR's curve tubes).

Mitsuba's ``twosided`` BSDF decides which side of a surface the camera (or the previous path vertex) is on
by the *shading* normal, and samples the next direction in the shading normal's hemisphere. Cycles decides
by the *geometric* normal (turning both normals to the viewer on a back face), evaluates its diffuse lobe
with the shading normal whatever side the viewer is on, and drops a sampled reflection that points below
the geometric surface. The two rules agree wherever the viewer is on the same side of both normals; they
differ where the view grazes a smooth surface between its face and its interpolated normal. On the IR's
curve tubes that zone is large: 16 sides (11.25 deg between a face and its corner normals) and ring normals
that bisect every bend of the polyline (up to half the bend angle off the faces). There Mitsuba turned the
BSDF to the tube's inside, lit it through the wall and let sampled rays leak through it.

This module registers the BSDF ``blendify_sided``, which wraps another BSDF and applies Cycles' rule: the
side by the geometric normal (both frames turned with it on back faces); the diffuse lobes in the
interpolated normal's frame with the incident direction lifted onto its horizon when it lies below it (so
they evaluate as the front, as Cycles' diffuse does whatever side the viewer is on); the glossy lobes in the
frame of Cycles' valid-reflection normal (:func:`valid_reflection_normal`), split from the diffuse ones by the
BSDF context's lobe mask; sampled directions below the geometric surface dropped. A wrapped BSDF that says
how often it samples its diffuse lobes (``diffuse_odds``: the layered Principled of the JIT variants, whose
lobe mask renormalises its lobe odds) is sampled as that mixture of its two halves, with the mixture's pdf;
Mitsuba's plugins are sampled with both masks and the same random numbers (the call whose mask allows the
lobe that sample1 picks succeeds). The diffuse half sees the view raised to the glossy half's cosine where
it is lower (Cycles weighs the layers by the glossy layers' albedo at that cosine; a Lambertian lobe depends
on the view's side only). It is for reflecting BSDFs only (the translator does not wrap
transmitting or masked ones: their pass-through must stay below the surface).

It runs in Python (per call in the scalar variants), so the translator uses it only for the curve tubes
and for smooth meshes whose normals lean far from their faces over much of their area (a low-poly smooth
box: 0.89x Cycles with Mitsuba's rule, 1.00x with this one in ``llvm_ad_rgb``); other meshes keep Mitsuba's
rule, where the two differ only in a sub-pixel band at smooth silhouettes (measured on the bunny: the same
image mean at 22x the cost). Mitsuba is imported inside the functions; :func:`register`
is called with the variant set (the session's engine lock held).
"""

from __future__ import annotations

from typing import Any

from .variant import register_plugin

__all__ = ["SIDED_BSDF", "register"]

#: the plugin name of the wrapper BSDF
SIDED_BSDF = "blendify_sided"

#: the smallest cosine the lifted incident direction keeps with the shading normal
_HORIZON = 1e-4


def valid_reflection_normal(ng: Any, wi: Any, n: Any) -> Any:
    """Cycles' shading normal for glossy reflection (its ``ensure_valid_specular_reflection``): ``n`` turned
    towards the geometric normal ``ng`` just enough that the mirror direction of ``wi`` about it leaves the
    surface at least min(0.9 cos(ng, wi), 0.01) above its tangent plane; ``n`` itself when it already does.
    Unit vectors with ``wi`` on ``ng``'s side; Dr.Jit types of the current variant."""
    import drjit as dr

    r = 2 * dr.dot(n, wi) * n - wi
    iz = dr.dot(wi, ng)
    t = dr.minimum(0.9 * iz, 0.01)
    x = n - dr.dot(n, ng) * ng  # the part of n along the surface: n' keeps its direction
    x = x / dr.maximum(dr.norm(x), 1e-12)
    ix = dr.dot(wi, x)
    # 2 sqrt(1 - z^2) ix z = t + iz (1 - 2 z^2) for z = n'.ng: a quadratic in z^2 (its valid root by ix's sign)
    a = dr.maximum(ix * ix + iz * iz, 1e-12)
    b = 2 * (a + iz * t)
    c = (t + iz) * (t + iz)
    root = dr.safe_sqrt(b * b - 4 * a * c)
    z2 = dr.clip(dr.select(ix < 0, 0.25 * (b + root) / a, 0.25 * (b - root) / a), 0.0, 1.0)
    bent = dr.normalize(dr.sqrt(1 - z2) * x + dr.sqrt(z2) * ng)
    return dr.select(dr.dot(ng, r) >= t, n, bent)


def register() -> str:
    """Register :data:`SIDED_BSDF` for the current Mitsuba variant (once per variant); its name."""
    return register_plugin("bsdf", SIDED_BSDF, _bsdf_class)


def _bsdf_class() -> type:
    """The wrapper class for the current variant (Mitsuba's base classes differ per variant)."""
    import drjit as dr
    import mitsuba as mi

    diffuse_mask = int(mi.BSDFFlags.Diffuse)
    other_mask = int(mi.BSDFFlags.Glossy) | int(mi.BSDFFlags.Delta)
    scalar = not dr.is_jit_v(mi.Float)

    class GeometricSides(mi.BSDF):  # type: ignore[misc,name-defined]
        """A BSDF evaluated with Cycles' sidedness rule (see the module's documentation)."""

        def __init__(self, props: Any) -> None:
            logger = mi.logger()
            level = logger.log_level()
            logger.set_log_level(mi.LogLevel.Error)  # the scalar-variant warning about Python plugins
            try:
                super().__init__(props)
            finally:
                logger.set_log_level(level)
            self.inner = props["bsdf"]
            self.m_flags = self.inner.flags()
            self.m_components = [self.inner.flags(i) for i in range(self.inner.component_count())]
            # the odds of the diffuse half when the wrapped BSDF renormalises its lobe odds under a mask
            odds = getattr(self.inner, "diffuse_odds", None)
            self.p_d = None if odds is None else float(odds)

        def _mix(self, ctx: Any) -> float:
            """The odds of sampling the diffuse half under ``ctx``'s mask (for a BSDF with ``diffuse_odds``)."""
            if not ctx.type_mask & diffuse_mask:
                return 0.0
            if not ctx.type_mask & other_mask:
                return 1.0
            return float(self.p_d)

        @staticmethod
        def _lobes(ctx: Any) -> tuple[Any, Any]:
            """``ctx`` restricted to the diffuse lobes, and to the others."""
            d = mi.BSDFContext(ctx.mode, ctx.type_mask & diffuse_mask, ctx.component)
            g = mi.BSDFContext(ctx.mode, ctx.type_mask & ~diffuse_mask, ctx.component)
            return d, g

        @staticmethod
        def _agree(si: Any) -> bool:
            """Scalar variants: whether both rules see the same thing at ``si`` (the viewer in front of the face
            and of the shading normal, whose mirror direction already leaves the surface): then the wrapped
            BSDF is evaluated as it is, without the Python-side frames (most calls)."""
            iz = dr.dot(si.n, si.to_world(si.wi))
            cos_n = si.wi.z
            return bool(iz > 0 and cos_n > 0 and 2 * cos_n * dr.dot(si.sh_frame.n, si.n) - iz >= min(0.9 * iz, 0.01))

        @staticmethod
        def _frames(si: Any) -> tuple[Any, Any, Any, Any, Any]:
            """The interactions the wrapped BSDF sees for its diffuse lobes (the shading normal) and for the
            others (Cycles' valid-reflection normal), their frames, and the geometric normal on the
            viewer's side."""
            wi = si.to_world(si.wi)
            front = dr.dot(si.n, wi) > 0
            ng = dr.select(front, si.n, -si.n)
            sh = si.sh_frame
            # turned on a back face, as Cycles turns both normals (one tangent too: a right-handed frame)
            n = dr.select(front, sh.n, -sh.n)
            f_d = mi.Frame3f(sh.s, dr.select(front, sh.t, -sh.t), n)
            n_g = valid_reflection_normal(ng, wi, n)
            s_g = dr.normalize(sh.s - dr.dot(sh.s, n_g) * n_g)
            f_g = mi.Frame3f(s_g, dr.cross(n_g, s_g), n_g)
            out = []
            for frame in (f_d, f_g):
                local = frame.to_local(wi)
                local.z = dr.maximum(local.z, _HORIZON)  # Cycles' diffuse ignores the viewer's side
                inner_si = mi.SurfaceInteraction3f(si)
                inner_si.sh_frame = frame
                inner_si.wi = dr.normalize(local)
                out.append(inner_si)
            # the diffuse half sees the view at least at the glossy cosine: Cycles weighs its layers by the
            # glossy layers' albedo at that cosine (a Lambertian lobe depends on the view's side only)
            local = f_d.to_local(wi)
            cz = dr.maximum(dr.dot(n_g, wi), _HORIZON)
            xy = dr.sqrt(dr.maximum(local.x * local.x + local.y * local.y, 1e-24))
            scale = dr.sqrt(dr.maximum(1.0 - cz * cz, 0.0)) / xy
            out[0].wi = dr.select(local.z < cz, mi.Vector3f(local.x * scale, local.y * scale, cz), out[0].wi)
            return out[0], f_d, out[1], f_g, ng

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True) -> Any:
            if scalar and self._agree(si):
                bs, weight = self.inner.sample(ctx, si, sample1, sample2, active)
                if dr.dot(si.n, si.to_world(bs.wo)) <= 0:  # Cycles drops a reflection below the surface
                    bs.pdf = 0.0
                    weight = mi.Spectrum(0.0)
                return bs, weight
            si_d, f_d, si_g, f_g, ng = self._frames(si)
            c_d, c_g = self._lobes(ctx)
            if self.p_d is not None:  # the mixture of the halves, by the wrapped BSDF's odds
                p = self._mix(ctx)
                active = mi.Bool(active)
                use_d = mi.Bool(sample1 < p)
                s_d = dr.minimum(sample1 / max(p, 1e-12), 0.99999994)
                s_g = dr.clip((sample1 - p) / max(1.0 - p, 1e-12), 0.0, 0.99999994)
                bs_d, _ = self.inner.sample(c_d, si_d, s_d, sample2, active & use_d)
                bs_g, _ = self.inner.sample(c_g, si_g, s_g, sample2, active & ~use_d)
                bs = dr.select(use_d, bs_d, bs_g)
                wo = dr.select(use_d, f_d.to_world(bs_d.wo), f_g.to_world(bs_g.wo))
                bs.wo = si.to_local(wo)
                value, pdf = self.eval_pdf(ctx, si, bs.wo, active)
                ok = (dr.dot(ng, wo) > 0) & (pdf > 0)  # Cycles drops a reflection below the geometric surface
                bs.pdf = dr.select(ok, pdf, 0.0)
                return bs, dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
            # the wrapped BSDF picks its lobe from sample1 alone: the call whose mask allows it succeeds
            bs_d, w_d = self.inner.sample(c_d, si_d, sample1, sample2, active)
            bs_g, w_g = self.inner.sample(c_g, si_g, sample1, sample2, active)
            use_d = bs_d.pdf > 0
            bs = dr.select(use_d, bs_d, bs_g)
            weight = dr.select(use_d, w_d, w_g)
            wo = dr.select(use_d, f_d.to_world(bs_d.wo), f_g.to_world(bs_g.wo))
            above = dr.dot(ng, wo) > 0  # Cycles drops a reflection below the geometric surface
            bs.wo = si.to_local(wo)
            bs.pdf = dr.select(above, bs.pdf, 0.0)
            return bs, dr.select(above, weight, 0.0)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar and self._agree(si):
                return self.inner.eval(ctx, si, wo, active)
            si_d, f_d, si_g, f_g, _ = self._frames(si)
            c_d, c_g = self._lobes(ctx)
            w = si.to_world(wo)
            return self.inner.eval(c_d, si_d, f_d.to_local(w), active) + self.inner.eval(
                c_g, si_g, f_g.to_local(w), active
            )

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar and self._agree(si):
                return self.inner.pdf(ctx, si, wo, active)
            si_d, f_d, si_g, f_g, _ = self._frames(si)
            c_d, c_g = self._lobes(ctx)
            w = si.to_world(wo)
            p_d = self.inner.pdf(c_d, si_d, f_d.to_local(w), active)
            p_g = self.inner.pdf(c_g, si_g, f_g.to_local(w), active)
            if self.p_d is not None:
                p = self._mix(ctx)
                return p * p_d + (1.0 - p) * p_g
            return p_d + p_g

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar and self._agree(si):
                return self.inner.eval_pdf(ctx, si, wo, active)
            si_d, f_d, si_g, f_g, _ = self._frames(si)
            c_d, c_g = self._lobes(ctx)
            w = si.to_world(wo)
            v_d, p_d = self.inner.eval_pdf(c_d, si_d, f_d.to_local(w), active)
            v_g, p_g = self.inner.eval_pdf(c_g, si_g, f_g.to_local(w), active)
            if self.p_d is not None:
                p = self._mix(ctx)
                return v_d + v_g, p * p_d + (1.0 - p) * p_g
            return v_d + v_g, p_d + p_g

        def traverse(self, callback: Any) -> None:
            pass

        def to_string(self) -> str:
            return f"GeometricSides[{self.inner}]"

    return GeometricSides
