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
The BSDF context's lobe mask (diffuse vs glossy reflection here; reflection vs transmission for the glass)
restricts eval, pdf and sampling to the enabled lobes, their sampling odds renormalised over them, as Mitsuba's
own plugins do (the curve tubes' sidedness wrapper, sided.py, evaluates the halves in different frames).

Two-sided like every blendify surface: seen from behind it scatters like its front with the normal flipped.

Cycles' transmission layer is a second plugin (:data:`GLASS_PLUGIN`): rough GGX glass (a solid, one-sided),
reflection and refraction by the real Fresnel with height-correlated shadowing, scaled per viewing cosine by
Cycles' multiple-scattering compensation on the side the view is on (``1 + F_ms (1 - E) / E`` with ``E`` the
single-scattering glass albedo of that side and ``F_ss`` the transmission tint,
:func:`blendify_mitsuba.principled.glass_compensation`).
The plugin is registered per Mitsuba variant (:func:`register`); it is used in the JIT variants, where Dr.Jit
traces it once into the rendering kernel. In ``scalar_rgb`` Mitsuba would call the Python methods once per
sample, which costs far more (measured in benchmarks/results/material_sweep.md), so that variant keeps the
lobe sum (``meta["approximations"]`` says so).
"""

from __future__ import annotations

import json
from typing import Any

from .variant import register_plugin

__all__ = ["PLUGIN", "register", "spec_json"]

#: the plugin name of the BSDF
PLUGIN = "blendify_principled"
#: the plugin name of the glass BSDF (Cycles' transmission layer)
GLASS_PLUGIN = "blendify_glass"
#: use the plugin at all (off: the lobe sum everywhere; for comparisons)
ENABLED = True
#: use the plugin in ``scalar_rgb`` too (for measuring its cost there; off: the lobe sum)
USE_IN_SCALAR = False


def register() -> str:
    """Register :data:`PLUGIN` and :data:`GLASS_PLUGIN` for the current Mitsuba variant (once per variant);
    :data:`PLUGIN`."""
    register_plugin("bsdf", GLASS_PLUGIN, _glass_class)
    return register_plugin("bsdf", PLUGIN, _bsdf_class)


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
            #: the base colour as a texture (vertex colours, image textures), else None (folded into tables)
            self.base = props["base_color"] if "base_color" in props else None
            if self.base is not None and not isinstance(self.base, mi.Texture):  # a constant colour
                self.base = mi.load_dict({"type": "srgb", "color": self.base})
            self.lobes = spec["lobes"]
            self.n_mu = len(self.lobes[0]["table"]) // 3
            total = sum(max(float(lb["p"]), 0.0) for lb in self.lobes) or 1.0
            self.odds = [max(float(lb["p"]), 0.0) / total for lb in self.lobes]
            #: the odds of sampling a diffuse lobe (the lobe-mask wrapper of sided.py mixes its halves by it)
            self.diffuse_odds = sum(self.odds[k] for k, lb in enumerate(self.lobes) if lb["kind"] == "diffuse")
            self.jit = dr.is_jit_v(mi.Float)
            tables = [[float(v) for v in lb["table"]] for lb in self.lobes]
            self.tables = [mi.Float(t) for t in tables] if self.jit else tables
            # E(mu) of the lobes whose compensation depends on the textured base colour (F82 metal)
            e = {k: [float(v) for v in lb["e"] for _ in range(3)] for k, lb in enumerate(self.lobes) if "e" in lb}
            self.e_tables = {k: (mi.Float(t) if self.jit else t) for k, t in e.items()}
            self.ggx = [i for i, lb in enumerate(self.lobes) if lb["kind"] == "ggx"]
            self.diffuse = [i for i, lb in enumerate(self.lobes) if lb["kind"] == "diffuse"]
            flags = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            comps = []
            #: each lobe's type, for the context's lobe mask
            self.types = []
            for lb in self.lobes:
                kind = mi.BSDFFlags.GlossyReflection if lb["kind"] == "ggx" else mi.BSDFFlags.DiffuseReflection
                comps.append(kind | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide)
                self.types.append(kind)
                flags = flags | kind
            self.m_components = comps
            self.m_flags = flags

        # -- pieces -------------------------------------------------------------------------------------
        def _odds(self, ctx: Any) -> tuple[list[float], list[bool]]:
            """The lobes the context's lobe mask enables, and their sampling odds renormalised over them (0
            for the others); the plain odds when every lobe is enabled."""
            on = [bool(ctx.is_enabled(t, k)) for k, t in enumerate(self.types)]
            if all(on):
                return self.odds, on
            total = sum(o for o, e in zip(self.odds, on, strict=True) if e)
            return [o / total if e and total > 0 else 0.0 for o, e in zip(self.odds, on, strict=True)], on

        def _table(self, k: int, mu: Any, tables: Any = None) -> Any:
            table = (self.tables if tables is None else tables)[k]
            x = dr.clip(mu * self.n_mu - 0.5, 0.0, self.n_mu - 1.0)
            i0 = dr.minimum(mi.UInt32(dr.floor(x)), self.n_mu - 2)
            t = x - mi.Float(i0)
            if self.jit:
                a = dr.gather(mi.Color3f, table, i0)
                b = dr.gather(mi.Color3f, table, i0 + 1)
            else:  # scalar_rgb: one sample at a time
                j = 3 * int(i0)
                a, b = mi.Color3f(*table[j : j + 3]), mi.Color3f(*table[j + 3 : j + 6])
            return dr.lerp(a, b, t)

        @staticmethod
        def _lambda(cos_t: Any, alpha: float) -> Any:
            c2 = dr.maximum(cos_t * cos_t, 1e-12)
            return 0.5 * (dr.sqrt(1.0 + alpha * alpha * dr.maximum(1.0 - c2, 0.0) / c2) - 1.0)

        @staticmethod
        def _f82_b(f0: Any, tint: Any) -> Any:
            """Cycles' F82-tint factor b: the value at cos = 1/7 is Schlick's times ``tint``."""
            c82 = 1.0 / 7.0
            s82 = f0 + (1.0 - f0) * (1.0 - c82) ** 5
            return s82 * (1.0 - tint) / (c82 * (1.0 - c82) ** 6)

        def _metal_tex(self, k: int, lb: dict[str, Any], base: Any, c: Any, mu: Any) -> Any:
            """F82-tint Fresnel times the compensation of a metal whose F0 is the textured base colour."""
            f0 = base
            b = self._f82_b(f0, mi.Color3f(*lb["tint"]))
            m = dr.clip(1.0 - c, 0.0, 1.0)
            m5 = dr.square(dr.square(m)) * m
            f = dr.clip(f0 + (1.0 - f0) * m5 - b * c * m5 * m, 0.0, 1.0)
            if k not in self.e_tables:
                return f
            e = dr.maximum(self._table(k, mu, self.e_tables), 1e-6)
            e_avg = float(lb["e_avg"])
            f_ss = dr.clip(f0 + (1.0 - f0) / 21.0 - b / 126.0, 0.0, 1.0)  # Cycles' mean F82-tint Fresnel
            f_ms = f_ss * e_avg / (1.0 - f_ss * (1.0 - e_avg))
            return f * (1.0 + f_ms * (1.0 - e) / e)

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

        def _eval_pdf(self, si: Any, wi: Any, wo: Any, active: Any, odds: list[float], on: list[bool]) -> Any:
            """Value and pdf of the lobes enabled by ``on`` with the sampling ``odds`` (:meth:`_odds`)."""
            cos_i, cos_o = wi.z, wo.z
            active = active & (cos_i > 0) & (cos_o > 0)
            base = self.base.eval(si, active) if self.base is not None else None
            value = mi.Color3f(0.0)
            pdf = mi.Float(0.0)
            h = dr.normalize(wi + wo)
            ih = dr.dot(wi, h)
            inv4 = dr.rcp(4.0 * dr.maximum(cos_i, 1e-8))
            for k in self.ggx:
                if not on[k]:
                    continue
                lb = self.lobes[k]
                alpha = float(lb["alpha"])
                d = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True).eval(h)
                lam_i, lam_o = self._lambda(cos_i, alpha), self._lambda(cos_o, alpha)
                g2 = dr.rcp(1.0 + lam_i + lam_o)
                if lb["fresnel"] == "f82_texture":
                    fresnel = self._metal_tex(k, lb, base, ih, cos_i)
                else:
                    fresnel = self._fresnel(lb, ih)
                value += self._table(k, cos_i) * fresnel * (d * g2 * inv4)
                pdf += odds[k] * d * inv4 / (1.0 + lam_i)
            for k in self.diffuse:
                if not on[k]:
                    continue
                tint = base if self.lobes[k].get("base") else 1.0
                value += self._table(k, cos_i) * tint * (cos_o * dr.inv_pi)
                pdf += odds[k] * cos_o * dr.inv_pi
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
            return self._eval_pdf(si, wi, wo, mi.Bool(active), *self._odds(ctx))[0]

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            wi, wo, _ = self._front(si, wo)
            return self._eval_pdf(si, wi, wo, mi.Bool(active), *self._odds(ctx))[1]

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            wi, wo, _ = self._front(si, wo)
            return self._eval_pdf(si, wi, wo, mi.Bool(active), *self._odds(ctx))

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True) -> Any:
            active = mi.Bool(active)
            back = si.wi.z < 0
            wi = mi.Vector3f(si.wi.x, si.wi.y, dr.abs(si.wi.z))
            # the lobe: by the odds (of the lobes the context enables), from sample1
            odds, on = self._odds(ctx)
            enabled = [k for k, o in enumerate(odds) if o > 0]
            if not enabled:  # the mask leaves no lobe to sample
                return dr.zeros(mi.BSDFSample3f), mi.Color3f(0.0)
            last = enabled[-1] if odds is not self.odds else len(self.lobes) - 1
            chosen = mi.UInt32(last)
            edge = 0.0
            for k in range(len(self.lobes) - 1):
                if k == last or (odds[k] <= 0 and odds is not self.odds):
                    continue
                edge += odds[k]
                chosen = dr.select((sample1 < edge) & (chosen == last), k, chosen)
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
            value, pdf = self._eval_pdf(si, wi, wo, active, odds, on)
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
                tint = self.base.eval(si, active) if self.lobes[k].get("base") and self.base is not None else 1.0
                value += self._table(k, dr.abs(si.wi.z)) * tint
            return value

        def traverse(self, callback: Any) -> None:
            pass

        def parameters_changed(self, keys: Any = None) -> None:
            pass

        def to_string(self) -> str:
            return f"CyclesPrincipled[{len(self.lobes)} lobes]"

    return CyclesPrincipled


def _glass_class() -> type:
    """The glass BSDF class for the current variant: rough GGX glass (a solid: one-sided, relative IOR
    ``eta`` entering through the front), height-correlated shadowing, reflection tinted by ``reflect`` and
    transmission by ``transmit`` per crossing, both scaled per viewing cosine by Cycles' multiple-scattering
    compensation (tables ``outside`` / ``inside``, N_MU x 3, for the side the view is on)."""
    import drjit as dr
    import mitsuba as mi

    class CyclesGlass(mi.BSDF):  # type: ignore[misc,name-defined]
        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            spec = json.loads(props["spec"])
            self.alpha = float(spec["alpha"])
            self.eta = float(spec["eta"])
            self.reflect = mi.Color3f(*spec["reflect"])
            self.transmit = mi.Color3f(*spec["transmit"])
            self.n_mu = len(spec["outside"]) // 3
            self.jit = dr.is_jit_v(mi.Float)
            tables = [[float(v) for v in spec[k]] for k in ("outside", "inside")]
            self.tables = [mi.Float(t) for t in tables] if self.jit else tables
            r = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            t = mi.BSDFFlags.GlossyTransmission | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            t = t | mi.BSDFFlags.NonSymmetric
            self.m_components = [r, t]
            self.m_flags = r | t

        def _comp(self, cos_i: Any) -> Any:
            mu = dr.abs(cos_i)
            x = dr.clip(mu * self.n_mu - 0.5, 0.0, self.n_mu - 1.0)
            i0 = dr.minimum(mi.UInt32(dr.floor(x)), self.n_mu - 2)
            t = x - mi.Float(i0)
            out = []
            for table in self.tables:
                if self.jit:
                    a = dr.gather(mi.Color3f, table, i0)
                    b = dr.gather(mi.Color3f, table, i0 + 1)
                else:
                    j = 3 * int(i0)
                    a, b = mi.Color3f(*table[j : j + 3]), mi.Color3f(*table[j + 3 : j + 6])
                out.append(dr.lerp(a, b, t))
            return dr.select(cos_i > 0, out[0], out[1])

        def _lambda(self, cos_t: Any) -> Any:
            c2 = dr.maximum(cos_t * cos_t, 1e-12)
            return 0.5 * (dr.sqrt(1.0 + self.alpha * self.alpha * dr.maximum(1.0 - c2, 0.0) / c2) - 1.0)

        def _lobes(self, ctx: Any) -> tuple[bool, bool]:
            """Whether the context's lobe mask enables the reflection, the transmission."""
            r, t = mi.BSDFFlags.GlossyReflection, mi.BSDFFlags.GlossyTransmission
            return bool(ctx.is_enabled(r, 0)), bool(ctx.is_enabled(t, 1))

        def _eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any) -> tuple[Any, Any]:
            has_r, has_t = self._lobes(ctx)
            wi = si.wi
            cos_i, cos_o = wi.z, wo.z
            reflect = cos_i * cos_o > 0
            eta = dr.select(cos_i > 0, self.eta, 1.0 / self.eta)  # relative IOR across the boundary
            m = dr.normalize(wi + wo * dr.select(reflect, 1.0, eta))
            m = dr.mulsign(m, m.z)
            distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alpha, True)
            d = distr.eval(m)
            lam_i, lam_o = self._lambda(cos_i), self._lambda(cos_o)
            g2 = dr.rcp(1.0 + lam_i + lam_o)
            im, om = dr.dot(wi, m), dr.dot(wo, m)
            f = mi.fresnel(im, self.eta)[0]
            abs_i = dr.maximum(dr.abs(cos_i), 1e-8)
            denom = im + eta * om
            denom2 = dr.maximum(denom * denom, 1e-12)
            # the visible-normal density of m, seen from wi's side
            d_vis = d * dr.abs(im) / (abs_i * (1.0 + lam_i))
            comp = self._comp(cos_i)
            # radiance transport: the transmitted radiance is divided by eta^2 (Mitsuba's convention)
            v_r = self.reflect * (f * d * g2 / (4.0 * abs_i))
            v_t = self.transmit * ((1.0 - f) * d * g2 * dr.abs(im * om) / (abs_i * denom2))
            p_r = f * d_vis / (4.0 * dr.maximum(dr.abs(om), 1e-8))
            p_t = (1.0 - f) * d_vis * eta * eta * dr.abs(om) / denom2
            # microfacets facing away from either direction scatter nothing
            ok = active & (cos_i != 0) & (cos_o != 0) & (im * cos_i > 0) & (om * cos_o > 0)
            if not (has_r and has_t):  # one lobe (or none): its value, its pdf with the choice's odds at 1
                ok &= reflect == has_r
                ok &= has_r or has_t
                p_r = p_r / dr.maximum(f, 1e-12)
                p_t = p_t / dr.maximum(1.0 - f, 1e-12)
            value = dr.select(ok, comp * dr.select(reflect, v_r, v_t), 0.0)
            pdf = dr.select(ok, dr.select(reflect, p_r, p_t), 0.0)
            return value, pdf

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self._eval_pdf(ctx, si, wo, mi.Bool(active))[0]

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self._eval_pdf(ctx, si, wo, mi.Bool(active))[1]

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self._eval_pdf(ctx, si, wo, mi.Bool(active))

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True) -> Any:
            active = mi.Bool(active)
            wi = si.wi
            distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alpha, True)
            m = distr.sample(dr.mulsign(wi, wi.z), sample2)[0]
            f, cos_t, _eta_it, eta_ti = mi.fresnel(dr.dot(wi, m), self.eta)
            has_r, has_t = self._lobes(ctx)
            reflect = sample1 <= f if has_r and has_t else mi.Bool(has_r)
            active &= has_r or has_t
            wo = dr.select(reflect, mi.reflect(wi, m), mi.refract(wi, m, cos_t, eta_ti))
            value, pdf = self._eval_pdf(ctx, si, wo, active)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = pdf
            bs.eta = dr.select(reflect, 1.0, _eta_it)
            bs.sampled_type = mi.UInt32(
                dr.select(reflect, int(mi.BSDFFlags.GlossyReflection), int(mi.BSDFFlags.GlossyTransmission))
            )
            bs.sampled_component = dr.select(reflect, mi.UInt32(0), mi.UInt32(1))
            # a refraction that stays on wi's side (or a reflection through the surface) scatters nothing
            ok = active & (pdf > 0) & (reflect == (wi.z * wo.z > 0))
            weight = dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
            return bs, weight

        def traverse(self, callback: Any) -> None:
            pass

        def parameters_changed(self, keys: Any = None) -> None:
            pass

        def to_string(self) -> str:
            return f"CyclesGlass[alpha={self.alpha}, eta={self.eta}]"

    return CyclesGlass
