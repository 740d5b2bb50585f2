"""Cycles' Principled layers with their view-dependent weights: a Mitsuba BSDF written with Dr.Jit.

Cycles weighs each layer of the Principled BSDF by functions of the viewing cosine ``mu = cos(wi)`` (the
attenuation by the layers above, the multiple-scattering compensation ``1 + F_ms (1 - E(mu)) / E(mu)``, the
coat tint's path length); a sum of Mitsuba's built-in lobes can only hold their means. This BSDF evaluates

    f(wi, wo) cos(wo) = sum_k T_k(mu) F_k(wi . h) D(h) G2(wi, wo) / (4 mu)  +  T_d(mu) cos(wo) / pi

with GGX ``D``, height-correlated Smith ``G2`` (Cycles' shadowing), each lobe's own Fresnel (the real dielectric
Fresnel remapped by the specular tint, Cycles' F82-tint metal Fresnel, or none) and per-lobe tables ``T_k(mu)``
(RGB over :data:`blendify_mitsuba.principled.N_MU` viewing cosines, linear in between) computed with numpy by
:func:`blendify_mitsuba.principled.principled_lobes`. Sampling picks a lobe with fixed odds, then the GGX
visible normals or the cosine hemisphere; the pdf is the mixture's (one-sample MIS over the lobes).

Two-sided like every blendify surface: seen from behind it scatters like its front with the normal flipped.
The plugin is registered per Mitsuba variant (:func:`register`); it is used in the JIT variants, where Dr.Jit
traces it once into the rendering kernel. In ``scalar_rgb`` Mitsuba would call the Python methods once per
sample, which costs far more (measured in benchmarks/results/material_sweep.md), so that variant keeps the
lobe sum (``meta["approximations"]`` says so).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["PLUGIN", "register", "spec_json"]

#: the plugin name of the BSDF
PLUGIN = "blendify_principled"
#: use the plugin at all (off: the lobe sum everywhere; for comparisons)
ENABLED = True
#: use the plugin in ``scalar_rgb`` too (for measuring its cost there; off: the lobe sum)
USE_IN_SCALAR = False

_REGISTERED: set[str] = set()


def register() -> str:
    """Register :data:`PLUGIN` for the current Mitsuba variant (once per variant); its name."""
    import mitsuba as mi

    variant = mi.variant()
    if variant not in _REGISTERED:
        cls = _bsdf_class()
        mi.register_bsdf(PLUGIN, lambda props: cls(props))
        _REGISTERED.add(variant)
    return PLUGIN


def spec_json(lobes: list[dict[str, Any]]) -> str:
    """The plugin's ``spec`` property: the lobes (each ``kind`` "ggx" or "diffuse", ``table`` N_MU x 3
    row-major, ``p`` the sampling odds; GGX lobes ``alpha`` and ``fresnel``) as JSON."""
    return json.dumps({"lobes": lobes}, separators=(",", ":"))


def _bsdf_class() -> type:
    """The BSDF class for the current variant (Mitsuba's base classes differ per variant)."""
    import drjit as dr
    import mitsuba as mi

    class CyclesPrincipled(mi.BSDF):  # type: ignore[misc,name-defined]
        """See the module's documentation."""

        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            spec = json.loads(props["spec"])
            self.lobes = spec["lobes"]
            self.n_mu = len(self.lobes[0]["table"]) // 3
            total = sum(max(float(lb["p"]), 0.0) for lb in self.lobes) or 1.0
            self.odds = [max(float(lb["p"]), 0.0) / total for lb in self.lobes]
            self.jit = dr.is_jit_v(mi.Float)
            tables = [[float(v) for v in lb["table"]] for lb in self.lobes]
            self.tables = [mi.Float(t) for t in tables] if self.jit else tables
            self.ggx = [i for i, lb in enumerate(self.lobes) if lb["kind"] == "ggx"]
            self.diffuse = [i for i, lb in enumerate(self.lobes) if lb["kind"] == "diffuse"]
            flags = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            comps = []
            for lb in self.lobes:
                kind = mi.BSDFFlags.GlossyReflection if lb["kind"] == "ggx" else mi.BSDFFlags.DiffuseReflection
                comps.append(kind | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide)
                flags = flags | kind
            self.m_components = comps
            self.m_flags = flags

        # -- pieces -------------------------------------------------------------------------------------
        def _table(self, k: int, mu: Any) -> Any:
            x = dr.clip(mu * self.n_mu - 0.5, 0.0, self.n_mu - 1.0)
            i0 = dr.minimum(mi.UInt32(dr.floor(x)), self.n_mu - 2)
            t = x - mi.Float(i0)
            if self.jit:
                a = dr.gather(mi.Color3f, self.tables[k], i0)
                b = dr.gather(mi.Color3f, self.tables[k], i0 + 1)
            else:  # scalar_rgb: one sample at a time
                j = 3 * int(i0)
                a, b = mi.Color3f(*self.tables[k][j : j + 3]), mi.Color3f(*self.tables[k][j + 3 : j + 6])
            return dr.lerp(a, b, t)

        @staticmethod
        def _lambda(cos_t: Any, alpha: float) -> Any:
            c2 = dr.maximum(cos_t * cos_t, 1e-12)
            return 0.5 * (dr.sqrt(1.0 + alpha * alpha * dr.maximum(1.0 - c2, 0.0) / c2) - 1.0)

        @staticmethod
        def _fresnel(lb: dict[str, Any], c: Any) -> Any:
            kind = lb["fresnel"]
            if kind == "none":
                return mi.Color3f(1.0)
            if kind == "dielectric":  # real Fresnel of eta remapped from [F0, 1] to [F0 * tint, 1]
                f = mi.fresnel(c, lb["eta"])[0]
                f0 = lb["f0"]
                s = dr.clip((f - f0) / (1.0 - f0), 0.0, 1.0)
                f0t = mi.Color3f(*[f0 * t for t in lb["tint"]])
                return f0t + (1.0 - f0t) * s
            # "f82": Schlick with F0 minus b c (1 - c)^6 (Cycles' F82-tint)
            f0 = mi.Color3f(*lb["f0"])
            b = mi.Color3f(*lb["b"])
            m = dr.clip(1.0 - c, 0.0, 1.0)
            m5 = dr.square(dr.square(m)) * m
            return dr.clip(f0 + (1.0 - f0) * m5 - b * c * m5 * m, 0.0, 1.0)

        def _eval_pdf(self, wi: Any, wo: Any, active: Any) -> tuple[Any, Any]:
            cos_i, cos_o = wi.z, wo.z
            active = active & (cos_i > 0) & (cos_o > 0)
            value = mi.Color3f(0.0)
            pdf = mi.Float(0.0)
            h = dr.normalize(wi + wo)
            ih = dr.dot(wi, h)
            inv4 = dr.rcp(4.0 * dr.maximum(cos_i, 1e-8))
            for k in self.ggx:
                lb = self.lobes[k]
                alpha = float(lb["alpha"])
                d = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True).eval(h)
                lam_i, lam_o = self._lambda(cos_i, alpha), self._lambda(cos_o, alpha)
                g2 = dr.rcp(1.0 + lam_i + lam_o)
                value += self._table(k, cos_i) * self._fresnel(lb, ih) * (d * g2 * inv4)
                pdf += self.odds[k] * d * inv4 / (1.0 + lam_i)
            for k in self.diffuse:
                value += self._table(k, cos_i) * (cos_o * dr.inv_pi)
                pdf += self.odds[k] * cos_o * dr.inv_pi
            value = dr.select(active, value, 0.0)
            pdf = dr.select(active, pdf, 0.0)
            return value, pdf

        @staticmethod
        def _front(si: Any, wo: Any) -> tuple[Any, Any, Any]:
            """wi, wo mirrored to the front side when wi is behind the surface (two-sided), and the flag."""
            back = si.wi.z < 0
            wi = mi.Vector3f(si.wi.x, si.wi.y, dr.abs(si.wi.z))
            wo = mi.Vector3f(wo.x, wo.y, dr.select(back, -wo.z, wo.z))
            return wi, wo, back

        # -- the BSDF interface -------------------------------------------------------------------------
        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            wi, wo, _ = self._front(si, wo)
            return self._eval_pdf(wi, wo, mi.Bool(active))[0]

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            wi, wo, _ = self._front(si, wo)
            return self._eval_pdf(wi, wo, mi.Bool(active))[1]

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            wi, wo, _ = self._front(si, wo)
            return self._eval_pdf(wi, wo, mi.Bool(active))

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True) -> Any:
            active = mi.Bool(active)
            back = si.wi.z < 0
            wi = mi.Vector3f(si.wi.x, si.wi.y, dr.abs(si.wi.z))
            # the lobe: by the odds, from sample1
            chosen = mi.UInt32(len(self.lobes) - 1)
            edge = 0.0
            for k in range(len(self.lobes) - 1):
                edge += self.odds[k]
                chosen = dr.select((sample1 < edge) & (chosen == len(self.lobes) - 1), k, chosen)
            is_diffuse = mi.Bool(False)
            alpha = mi.Float(1.0)
            for k in self.diffuse:
                is_diffuse |= chosen == k
            for k in self.ggx:
                alpha = dr.select(chosen == k, float(self.lobes[k]["alpha"]), alpha)
            m = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True).sample(wi, sample2)[0]
            wo_ggx = mi.reflect(wi, m)
            wo_dif = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = dr.select(is_diffuse, wo_dif, wo_ggx)
            value, pdf = self._eval_pdf(wi, wo, active)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = mi.Vector3f(wo.x, wo.y, dr.select(back, -wo.z, wo.z))
            bs.pdf = pdf
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(
                dr.select(is_diffuse, int(mi.BSDFFlags.DiffuseReflection), int(mi.BSDFFlags.GlossyReflection))
            )
            bs.sampled_component = chosen
            ok = active & (pdf > 0)
            weight = dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
            return bs, weight

        def eval_diffuse_reflectance(self, si: Any, active: Any = True) -> Any:
            value = mi.Color3f(0.0)
            for k in self.diffuse:
                value += self._table(k, dr.abs(si.wi.z))
            return value

        def traverse(self, callback: Any) -> None:
            pass

        def parameters_changed(self, keys: Any = None) -> None:
            pass

        def to_string(self) -> str:
            return f"CyclesPrincipled[{len(self.lobes)} lobes]"

    return CyclesPrincipled
