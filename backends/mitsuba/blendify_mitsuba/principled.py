"""Cycles' Principled BSDF (docs/conventions.md, "Materials"): its layers' albedos and view-dependent weights,
and the model as a sum of Mitsuba's built-in lobes.

In the JIT variants the layers are rendered by :mod:`blendify_mitsuba.layered` (a Dr.Jit BSDF) with the weight
tables computed here (:attr:`Lobe.jit`, :func:`layered_bsdf`, :func:`glass_layered`). ``scalar_rgb`` would call
a Python BSDF once per sample (22-39x slower, measured), and exported scene files need plain plugins, so there
the model is mapped onto built-in plugins whose sum Mitsuba renders natively:

- every GGX lobe of Cycles (dielectric specular, metal, coat) becomes a ``roughconductor`` whose complex
  IOR (per channel) is fitted to the lobe's Fresnel curve (real dielectric Fresnel, Blender's tint remapping,
  the F82-tint metal Fresnel), scaled per channel so that its albedo equals Cycles' (multiple-scattering
  compensation of ``MULTI_GGX`` included; Mitsuba's single-scattering GGX with separable shadowing is darker);
- the diffuse lobe is Lambertian with the base colour times the attenuation of the layers above it;
- the lobes are summed with nested ``blendbsdf`` (weights = scale factors; the scales go into raw bitmaps,
  which Mitsuba does not clamp to [0, 1]);
- glass is ``roughdielectric`` (solid, one-sided) with the transmission colour ``sqrt(base colour)`` per
  crossing and the multiple-scattering energy of Cycles' glass restored by a scale.

Cycles attenuates the lower layers and compensates multiple scattering as functions of the viewing angle; a
sum of plugins holds constants, so each lobe gets the cosine-weighted mean over viewing angles of its
attenuated albedo (what a convex object seen whole averages; per pixel the grazing angles differ). The albedos
are computed here (numpy, GGX with visible-normal sampling over a fixed stratified grid, no randomness),
cached per parameter set: about 1-3 ms per material at translation, nothing per ray.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "N_MU",
    "Lobe",
    "ggx_albedo",
    "cos_mean",
    "fresnel_dielectric",
    "fresnel_conductor",
    "f82_tint",
    "fit_conductor",
    "fit_conductor_albedo",
    "principled_lobes",
    "glass_scale",
    "sum_lobes",
    "principled_bsdf",
    "glossy_scale",
    "cycles_albedo_of",
    "raw_rgb",
    "with_bitmaps",
]

#: viewing cosines of the albedo tables (midpoints of N_MU equal bins)
N_MU = 32
_MU = (np.arange(N_MU) + 0.5) / N_MU
_GRID = 24  # stratified (u1, u2) samples per viewing cosine: _GRID^2
_U1, _U2 = np.meshgrid((np.arange(_GRID) + 0.5) / _GRID, (np.arange(_GRID) + 0.5) / _GRID, indexing="ij")
_U1, _U2 = _U1.ravel(), _U2.ravel()

Fresnel = Callable[[np.ndarray], np.ndarray]  # cos(theta) (...,) -> reflectance (..., C)


def cos_mean(values: np.ndarray) -> np.ndarray:
    """The cosine-weighted mean over viewing angles, ``2 int_0^1 f(mu) mu dmu``, of (N_MU, ...) values."""
    w = 2.0 * _MU / N_MU
    return np.tensordot(w, values, axes=(0, 0))


def fresnel_dielectric(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance (...,) of a dielectric of relative IOR ``eta`` seen from outside."""
    c = np.clip(cos_i, 0.0, 1.0)
    g2 = eta * eta - 1.0 + c * c
    tir = g2 < 0
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / np.maximum(g + c, 1e-12)
    b = (c * (g + c) - 1.0) / np.maximum(c * (g - c) + 1.0, 1e-12)
    f = 0.5 * a * a * (1.0 + b * b)
    return np.where(tir, 1.0, f)


def fresnel_conductor(cos_i: np.ndarray, n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex IOR ``n + ik`` (broadcasting)."""
    c = np.clip(cos_i, 1e-6, 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    n2, k2 = n * n, k * k
    t0 = n2 - k2 - s2
    a2b2 = np.sqrt(t0 * t0 + 4.0 * n2 * k2)
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * c * a
    rs = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rp + rs)


def f82_tint(cos_i: np.ndarray, f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """Cycles' metal Fresnel (..., 3): Schlick with F0 = base colour, bent so that at cos = 1/7 it is
    Schlick's times ``tint`` (Kutz et al.'s F82-tint model)."""
    c = np.clip(cos_i, 0.0, 1.0)[..., None]
    schlick = f0 + (1.0 - f0) * (1.0 - c) ** 5
    c82 = 1.0 / 7.0
    s82 = f0 + (1.0 - f0) * (1.0 - c82) ** 5
    b = s82 * (1.0 - tint) / (c82 * (1.0 - c82) ** 6)
    return np.clip(schlick - b * c * (1.0 - c) ** 6, 0.0, 1.0)


def _smith_lambda(cos_t: np.ndarray, alpha: float) -> np.ndarray:
    c2 = np.clip(cos_t * cos_t, 1e-12, 1.0)
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2) - 1.0)


@functools.lru_cache(maxsize=64)
def _vndf(alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Visible-normal samples for every viewing cosine (isotropic GGX, Heitz 2018): cos(v, h) and the
    reflected direction's cosine, the Smith lambdas of v and l, shape (N_MU, _GRID^2)."""
    mu = _MU[:, None]
    v = np.stack([np.sqrt(1.0 - mu * mu) * np.ones_like(_U1), np.zeros_like(mu * _U1), mu * np.ones_like(_U1)], -1)
    vh = v * np.array([alpha, alpha, 1.0])
    vh /= np.linalg.norm(vh, axis=-1, keepdims=True)
    t1 = np.zeros_like(vh)
    t1[..., 1] = 1.0  # v lies in the xz plane: T1 = (-vh.y, vh.x, 0) / |.| = (0, 1, 0)
    t2 = np.cross(vh, t1)
    r = np.sqrt(_U1)
    phi = 2.0 * math.pi * _U2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    nh = p1[..., None] * t1 + p2[..., None] * t2 + np.sqrt(np.maximum(1.0 - p1 * p1 - p2 * p2, 0.0))[..., None] * vh
    h = nh * np.array([alpha, alpha, 1.0])
    h[..., 2] = np.maximum(h[..., 2], 1e-9)
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    vdoth = np.sum(v * h, axis=-1)
    cos_l = 2.0 * vdoth * h[..., 2] - v[..., 2]
    _H_Z[alpha] = h[..., 2]
    return vdoth, cos_l, _smith_lambda(v[..., 2], alpha), _smith_lambda(cos_l, alpha)


_H_Z: dict[float, np.ndarray] = {}  # the microfacet normals' cosines of _vndf(alpha)


def glass_albedo(alpha: float, eta: float) -> np.ndarray:
    """Directional albedo (N_MU,) of single-scattering GGX glass of relative IOR ``eta`` (< 1: seen from
    inside) with height-correlated shadowing: reflection plus transmission, real Fresnel, as energy (no
    ``eta^2`` radiance factor)."""
    alpha = max(float(alpha), 1e-4)
    vdoth, cos_l, lam_v, lam_l = _vndf(alpha)
    h_z = _H_Z[alpha]
    mu = _MU[:, None]
    c = np.clip(vdoth, 0.0, 1.0)
    f = fresnel_dielectric(c, eta)
    sin2_t = (1.0 - c * c) / (eta * eta)
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    o_z = (c / eta - cos_t) * h_z - mu / eta  # the refracted direction's cosine (negative: through)
    g_r = np.where(cos_l > 0, (1.0 + lam_v) / (1.0 + lam_v + lam_l), 0.0)
    g_t = np.where((o_z < 0) & (sin2_t < 1.0), (1.0 + lam_v) / (1.0 + lam_v + _smith_lambda(o_z, alpha)), 0.0)
    return np.asarray((f * g_r + (1.0 - f) * g_t).mean(axis=1))


def glass_compensation(alpha: float, eta: float, tint: np.ndarray) -> np.ndarray:
    """Cycles' multiple-scattering factor (N_MU, 3) of MULTI_GGX glass of relative IOR ``eta`` seen from the
    side that ``eta`` says, per viewing cosine: ``1 + F_ms (1 - E) / E`` with ``E`` :func:`glass_albedo` and
    ``F_ss`` the transmission tint (per channel)."""
    e = glass_albedo(alpha, eta)[:, None]
    e_avg = float(cos_mean(e)[0])
    t = np.clip(np.asarray(tint, dtype=np.float64)[:3], 0.0, 1.0)[None, :]
    f_ms = t * e_avg / (1.0 - t * (1.0 - e_avg))
    return np.asarray(1.0 + f_ms * (1.0 - e) / np.maximum(e, 1e-6))


def ggx_albedo(alpha: float, fresnel: Fresnel | None, correlated: bool) -> np.ndarray:
    """Directional albedo (N_MU, C) of single-scattering GGX reflection with ``fresnel`` (None: 1) at the
    viewing cosines; ``correlated``: height-correlated Smith shadowing (Cycles), else separable (Mitsuba)."""
    alpha = max(float(alpha), 1e-4)
    vdoth, cos_l, lam_v, lam_l = _vndf(alpha)
    above = cos_l > 0
    if correlated:
        g = (1.0 + lam_v) / (1.0 + lam_v + lam_l)
    else:
        g = 1.0 / (1.0 + lam_l)  # G1(v) G1(l) / G1(v)
    g = np.where(above, g, 0.0)
    f = np.ones(vdoth.shape + (1,)) if fresnel is None else fresnel(vdoth)
    if f.ndim == vdoth.ndim:
        f = f[..., None]
    return np.asarray((f * g[..., None]).mean(axis=1))


def _fresnel_mean(fresnel: Fresnel) -> np.ndarray:
    """The cosine-weighted mean Fresnel (C,) over incidence angles (Cycles' F_ss)."""
    f = fresnel(_MU)
    return cos_mean(f if f.ndim > 1 else f[:, None])


def compensation(alpha: float, fresnel: Fresnel, multiscatter: bool) -> np.ndarray:
    """Cycles' multiple-scattering factor (N_MU, C) of a GGX reflection lobe per viewing cosine,
    ``1 + F_ms (1 - E) / E`` when compensated, else 1 (docs/conventions.md, "Roughness")."""
    f_ss = _fresnel_mean(fresnel)
    if not multiscatter:
        return np.ones((N_MU, f_ss.shape[0]))
    e = ggx_albedo(alpha, None, correlated=True)  # (N_MU, 1)
    e_avg = float(cos_mean(e)[0])
    f_ms = f_ss * e_avg / (1.0 - f_ss * (1.0 - e_avg))
    return np.asarray(1.0 + f_ms * (1.0 - e) / np.maximum(e, 1e-6))


def cycles_albedo(alpha: float, fresnel: Fresnel, multiscatter: bool) -> np.ndarray:
    """Cycles' directional albedo (N_MU, C) of a GGX reflection lobe: single scattering (height-correlated
    shadowing) times :func:`compensation`."""
    return ggx_albedo(alpha, fresnel, correlated=True) * compensation(alpha, fresnel, multiscatter)


# -- fitting a complex IOR to a Fresnel curve --------------------------------------------------------
_FIT_N = np.concatenate([np.linspace(1.0, 1.6, 61)[1:], np.geomspace(1.6, 30.0, 60), np.geomspace(0.03, 1.0, 50)])
_FIT_K = np.concatenate([[0.0], np.geomspace(0.01, 12.0, 70)])
_FIT_C = np.linspace(0.005, 1.0, 64)


@functools.lru_cache(maxsize=1)
def _fit_table() -> np.ndarray:
    n, k = np.meshgrid(_FIT_N, _FIT_K, indexing="ij")
    return np.asarray(fresnel_conductor(_FIT_C[:, None, None], n[None], k[None]))  # (C, N, K)


@functools.lru_cache(maxsize=1)
def _fit_means() -> np.ndarray:
    return np.maximum(np.tensordot(_FIT_C, _fit_table(), axes=(0, 0)) / np.sum(_FIT_C), 1e-9)


def fit_conductor(target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per channel, the conductor IOR ``(n, k)`` whose Fresnel is closest (cosine-weighted least squares,
    over a fixed grid) to ``target`` (len(_FIT_C), C) sampled at :data:`_FIT_C`."""
    table, means = _fit_table(), _fit_means()
    w = _FIT_C[:, None, None] ** 3  # near-normal reflection dominates what a surface shows
    ns, ks = [], []
    for ch in range(target.shape[1]):
        t = target[:, ch]
        t_mean = max(float(np.sum(_FIT_C * t) / np.sum(_FIT_C)), 1e-9)  # the cosine-weighted mean
        # the shape (the curve over its mean; the albedo scale sets the level) and the level, relative
        err = np.sum(w * (table / means - (t / t_mean)[:, None, None]) ** 2, axis=0) / np.sum(w)
        i, j = np.unravel_index(int(np.argmin(err)), err.shape)
        ns.append(_FIT_N[i])
        ks.append(_FIT_K[j])
    return np.array(ns), np.array(ks)


@functools.lru_cache(maxsize=64)
def _albedo_operator(alpha: float) -> np.ndarray:
    """(N_MU, len(_FIT_C)): Mitsuba's single-scattering GGX albedo is linear in the Fresnel curve,
    ``A(mu) = op[mu] @ F(_FIT_C)`` (the visible-normal samples binned by cos(v, h), separable shadowing)."""
    vdoth, cos_l, _lam_v, lam_l = _vndf(max(alpha, 1e-4))
    g = np.where(cos_l > 0, 1.0 / (1.0 + lam_l), 0.0)
    edges = np.concatenate([[0.0], 0.5 * (_FIT_C[1:] + _FIT_C[:-1]), [1.0]])
    op = np.zeros((N_MU, len(_FIT_C)))
    for i in range(N_MU):
        op[i] = np.histogram(np.clip(vdoth[i], 0.0, 1.0), bins=edges, weights=g[i])[0] / vdoth.shape[1]
    return op


#: how much each viewing cosine counts where a conductor's albedo curve cannot follow Cycles' (the F82 dip of
#: a dark specular tint: no conductor dips so deep): mu^2, near-normal views first (the middle of an object,
#: what reflects the lights in front of it; measured on the sweep: tinted metals 6-12 % -> 2-4 %); elsewhere
#: the cosine weight mu (the mean over a convex object seen whole)
DIP_WEIGHT = _MU**2


def fit_conductor_albedo(alpha: float, target: np.ndarray, weight: np.ndarray = _MU) -> tuple[np.ndarray, np.ndarray]:
    """Per channel, the conductor IOR ``(n, k)`` (over a fixed grid) whose Mitsuba albedo curve, at its best
    scale, is closest to ``target`` (N_MU, C), Cycles' albedo curve (cosine-weighted least squares): the
    fit that matters for the picture, where Cycles' Fresnel has shapes no conductor has (the F82 dip)."""
    cand = (_albedo_operator(alpha) @ _fit_table().reshape(len(_FIT_C), -1)).T  # (candidates, N_MU)
    w = weight
    ns, ks = [], []
    for ch in range(target.shape[1]):
        t = target[:, ch]
        s = (cand * t * w).sum(axis=1) / np.maximum((cand * cand * w).sum(axis=1), 1e-12)
        err = ((s[:, None] * cand - t) ** 2 * w).sum(axis=1)
        i, j = np.unravel_index(int(np.argmin(err)), (len(_FIT_N), len(_FIT_K)))
        ns.append(_FIT_N[i])
        ks.append(_FIT_K[j])
    return np.array(ns), np.array(ks)


@functools.lru_cache(maxsize=256)
def _conductor_lobe(alpha: float, key: tuple[float, ...], kind: str, multiscatter: bool) -> tuple[Any, ...]:
    """(n, k, albedo scale, Cycles albedo (N_MU, 3)) of one GGX lobe of Cycles (cached by parameters)."""
    fresnel = _fresnel_of(kind, key)
    target = fresnel(_FIT_C)
    if target.ndim == 1:
        target = np.repeat(target[:, None], 3, axis=1)
    a_cyc = cycles_albedo(alpha, fresnel, multiscatter)
    if a_cyc.shape[1] == 1:
        a_cyc = np.repeat(a_cyc, 3, axis=1)
    weight = DIP_WEIGHT if kind == "f82" and min(key[3:6]) < 1.0 else _MU
    n, k = fit_conductor_albedo(alpha, a_cyc, weight)
    a_mi = ggx_albedo(alpha, lambda c: fresnel_conductor(c[..., None], n, k), correlated=False)
    w = weight[:, None]
    scale = np.sum(w * a_cyc, axis=0) / np.maximum(np.sum(w * a_mi, axis=0), 1e-9)
    return n, k, scale, a_cyc


def _fresnel_of(kind: str, key: tuple[float, ...]) -> Fresnel:
    if kind == "dielectric":  # (eta, f0 tint r, g, b): the real Fresnel remapped to [F0 * tint, 1]
        eta, tint = key[0], np.array(key[1:4])
        f0 = ((eta - 1.0) / (eta + 1.0)) ** 2

        def remapped(c: np.ndarray) -> np.ndarray:
            f = fresnel_dielectric(c, eta)[..., None]
            f0t = f0 * tint
            return np.asarray(f0t + (1.0 - f0t) * (f - f0) / (1.0 - f0))

        return remapped
    # "f82": (F0 r, g, b, tint r, g, b)
    f0v, tint = np.array(key[0:3]), np.array(key[3:6])
    return lambda c: f82_tint(c, f0v, tint)


# -- the lobes of a Principled material ----------------------------------------------------------------
@dataclass
class Lobe:
    """One term of the sum: a Mitsuba BSDF dict built by ``make(scale)`` with the per-channel ``scale``
    (3,) folded into its reflectance, the scale Cycles' model gives it, and Cycles' albedo of the lobe."""

    make: Callable[[np.ndarray], dict[str, Any]]
    scale: np.ndarray
    #: Cycles' directional albedo of the lobe (N_MU, 3), attenuation by the layers above included
    cycles: np.ndarray
    #: the lobe for :mod:`blendify_mitsuba.layered`: ``kind``, GGX ``alpha`` and ``fresnel``, and ``table``
    #: (N_MU, 3), the lobe's weight per viewing cosine (attenuation above x compensation x layer weight)
    jit: dict[str, Any] | None = None


def effective_eta(ior: float, level: float) -> tuple[float, float]:
    """Blender's Specular IOR Level: (eta, F0) with ``F0 = F0(ior) * 2 * level`` (eta 1: no layer)."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    f0 = min(max(f0, 0.0), 0.99)
    if f0 <= 0.0:
        return 1.0, 0.0
    s = math.sqrt(f0)
    return (1.0 + s) / (1.0 - s), f0


def raw_rgb(values: Any) -> dict[str, Any]:
    """A constant RGB as a raw 2x2 bitmap (values above 1 allowed, unlike Mitsuba's ``rgb``); its ``bitmap``
    is a numpy array, which the translator turns into the engine's ``Bitmap`` (:func:`with_bitmaps`: a
    ``Bitmap`` survives loading the same dictionary twice, a ``TensorXf`` does not)."""
    v = np.asarray(values, dtype=np.float32).reshape(3)
    data = np.ascontiguousarray(np.tile(v, (2, 2, 1)))
    return {"type": "bitmap", "bitmap": data, "raw": True, "filter_type": "nearest"}


def with_bitmaps(d: Any, bitmap: Callable[[np.ndarray], Any]) -> Any:
    """``d`` (a BSDF dict tree) with every numpy ``bitmap`` replaced by ``bitmap(array)``."""
    if isinstance(d, dict):
        return {
            k: bitmap(v) if k == "bitmap" and isinstance(v, np.ndarray) else with_bitmaps(v, bitmap)
            for k, v in d.items()
        }
    return d


def _ggx_lobe(alpha: float, n: np.ndarray, k: np.ndarray) -> Callable[[np.ndarray], dict[str, Any]]:
    def make(scale: np.ndarray) -> dict[str, Any]:
        d: dict[str, Any] = {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": max(alpha, 1e-4),
            "eta": raw_rgb(n),
            "k": raw_rgb(k),
            "specular_reflectance": raw_rgb(scale),
        }
        if alpha <= 0.0:
            del d["alpha"], d["distribution"]
            d["type"] = "conductor"
        return d

    return make


def _diffuse_lobe(make_color: Callable[[np.ndarray], Any]) -> Callable[[np.ndarray], dict[str, Any]]:
    return lambda scale: {"type": "diffuse", "reflectance": make_color(scale)}


def principled_lobes(material: Any, base: np.ndarray) -> list[Lobe]:
    """The opaque part of Cycles' Principled model for ``material`` with the constant linear ``base`` colour
    (3,), as lobes with their per-channel scales (transmission excluded: see :func:`glass_scale`)."""
    multi = material.distribution == "MULTI_GGX"
    rough = float(material.roughness)
    alpha = rough * rough
    w = np.ones((N_MU, 1))  # the attenuation handed to the layers below, per viewing cosine
    lobes: list[Lobe] = []

    sheen = float(material.sheen_weight)
    if sheen > 0:
        tint = material.linear("sheen_tint")[:3] * sheen
        a_sheen = sheen_albedo(float(material.sheen_roughness))[:, None] * tint  # (N_MU, 3)
        s_alpha = sheen_alpha(float(material.sheen_roughness))
        n, k, shape = _sheen_lobe(float(material.sheen_roughness))
        e_shape = ggx_albedo(s_alpha, None, correlated=True)
        jit = {"kind": "ggx", "alpha": s_alpha, "fresnel": "none", "table": w * a_sheen / np.maximum(e_shape, 1e-6)}
        lobes.append(Lobe(_ggx_lobe(s_alpha, n, k), cos_mean(w * a_sheen) / shape, w * a_sheen, jit))
        w = w * (1.0 - np.max(a_sheen, axis=1, keepdims=True))

    coat = float(material.coat_weight)
    if coat > 0:
        c_alpha = float(material.coat_roughness) ** 2
        eta = max(float(material.coat_ior), 1.0)
        if eta > 1.0:
            n, k, scale, a_coat = _conductor_lobe(c_alpha, (eta, 1.0, 1.0, 1.0), "dielectric", True)
            comp = compensation(c_alpha, _fresnel_of("dielectric", (eta, 1.0, 1.0, 1.0)), True)
            jit = _dielectric_jit(c_alpha, eta, np.ones(3), w * coat * comp)
            lobes.append(
                Lobe(
                    _ggx_lobe(c_alpha, n, k),
                    scale * cos_mean(w * coat * a_coat) / cos_mean(a_coat),
                    w * coat * a_coat,
                    jit,
                )
            )
            w = w * (1.0 - coat * a_coat[:, :1])
        tint = material.linear("coat_tint")[:3]
        if np.any(tint < 1.0):
            cos_t = np.sqrt(1.0 - (1.0 - _MU**2) / (eta * eta))[:, None]
            w = w * (1.0 - coat + coat * np.power(np.maximum(tint, 1e-6), 1.0 / cos_t))

    metal = float(material.metallic)
    if metal > 0:
        spec_tint = material.linear("specular_tint")[:3]
        key = tuple(float(x) for x in np.concatenate([base, spec_tint]))
        n, k, scale, a_metal = _conductor_lobe(alpha, key, "f82", multi)
        comp = compensation(alpha, _fresnel_of("f82", key), multi)
        c82 = 1.0 / 7.0
        s82 = base + (1.0 - base) * (1.0 - c82) ** 5
        jit = {
            "kind": "ggx",
            "alpha": alpha,
            "fresnel": "f82",
            "f0": [float(x) for x in base],
            "b": [float(x) for x in s82 * (1.0 - spec_tint) / (c82 * (1.0 - c82) ** 6)],
            "table": w * metal * comp,
            # for a textured base colour: the tint, and E(mu) for the compensation computed per point
            "tint": [float(x) for x in spec_tint],
            "table_textured": w * metal,
        }
        if multi:
            e = ggx_albedo(alpha, None, correlated=True)[:, 0]
            jit["e"], jit["e_avg"] = [float(x) for x in e], float(cos_mean(e[:, None])[0])
        lobes.append(
            Lobe(
                _ggx_lobe(alpha, n, k),
                scale * cos_mean(w * metal * a_metal) / cos_mean(a_metal),
                w * metal * a_metal,
                jit,
            )
        )
        w = w * (1.0 - metal)
    w = w * (1.0 - float(material.transmission_weight))

    eta, f0 = effective_eta(float(material.ior), float(material.specular_ior))
    if f0 > 0:
        spec_tint = material.linear("specular_tint")[:3]
        key = (eta, *(float(x) for x in spec_tint))
        n, k, scale, a_spec = _conductor_lobe(alpha, key, "dielectric", multi)
        jit = _dielectric_jit(alpha, eta, spec_tint, w * compensation(alpha, _fresnel_of("dielectric", key), multi))
        lobes.append(Lobe(_ggx_lobe(alpha, n, k), scale * cos_mean(w * a_spec) / cos_mean(a_spec), w * a_spec, jit))
        # with "GGX" the layers below lose the single-scattering albedo over the lobe's albedo without
        # Fresnel, A_ss / E (measured with white-furnace spheres in Cycles: at normal incidence 1 - F0 for
        # every roughness)
        a_below = a_spec if multi else a_spec / np.maximum(ggx_albedo(alpha, None, correlated=True), 1e-6)
        w = w * (1.0 - np.max(a_below, axis=1, keepdims=True))
    lobes.append(Lobe(_diffuse_lobe(raw_rgb), base * cos_mean(w), w * base, {"kind": "diffuse", "table": w * base}))
    return lobes


def _dielectric_jit(alpha: float, eta: float, tint: np.ndarray, table: np.ndarray) -> dict[str, Any]:
    f0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    return {
        "kind": "ggx",
        "alpha": alpha,
        "fresnel": "dielectric",
        "eta": float(eta),
        "f0": float(f0),
        "tint": [float(x) for x in tint],
        "table": table,
    }


# Cycles' microfiber sheen albedo is not reproduced from Cycles' tables here: it is approximated by the
# albedo of a sheen-only Principled sphere measured in Cycles (see sheen_albedo).
_SHEEN_ROUGH = np.array([0.0, 0.25, 0.5, 0.75, 1.0])


def sheen_alpha(roughness: float) -> float:
    """The GGX alpha of the lobe standing in for Cycles' sheen of ``roughness``: broad, so that its conductor
    Fresnel (fitted to the sheen's albedo curve) puts the energy where the sheen has it, towards grazing."""
    return max(roughness, 0.1)


@functools.lru_cache(maxsize=32)
def _sheen_lobe(roughness: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, k, cosine-weighted mean albedo of that conductor lobe) of the roughconductor whose albedo curve
    follows the shape of Cycles' sheen albedo at ``roughness``."""
    a = np.repeat(sheen_albedo(roughness)[:, None], 3, axis=1)
    if float(np.max(a)) <= 0.0:
        a = np.ones_like(a)
    n, k = fit_conductor_albedo(sheen_alpha(roughness), a)
    a_mi = ggx_albedo(sheen_alpha(roughness), lambda c: fresnel_conductor(c[..., None], n, k), correlated=False)
    return n, k, np.maximum(cos_mean(a_mi), 1e-9)


def sheen_albedo(roughness: float) -> np.ndarray:
    """Directional albedo (N_MU,) of Cycles' sheen layer of weight 1 and white tint (approximation)."""
    table = _sheen_table()
    i = float(np.interp(roughness, _SHEEN_ROUGH, np.arange(len(_SHEEN_ROUGH))))
    lo = int(math.floor(i))
    hi = min(lo + 1, len(_SHEEN_ROUGH) - 1)
    t = i - lo
    return np.asarray((1 - t) * table[lo] + t * table[hi])


def _sheen_table() -> np.ndarray:
    """(len(_SHEEN_ROUGH), N_MU): measured in Cycles (see :data:`SHEEN_MEASURED`), interpolated in mu."""
    out = []
    for row in SHEEN_MEASURED:
        out.append(np.interp(_MU, SHEEN_MU, row))
    return np.array(out)


#: viewing cosines and sheen albedos per sheen roughness (rows: _SHEEN_ROUGH), measured with Cycles (bpy
#: 5.0.1, benchmarks/measure_sheen_albedo.py, 1024 spp): a sheen-only Principled sphere (black base, no
#: specular layer) under a uniform white background; mu below 0.1 takes the value at 0.1
SHEEN_MU = np.array([0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 1.0])
SHEEN_MEASURED = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.262, 0.1787, 0.0664, 0.0077, 0.0015, 0.0004, 0.0003],
        [0.398, 0.4291, 0.3205, 0.1552, 0.0698, 0.0296, 0.0206],
        [0.4598, 0.5549, 0.484, 0.3476, 0.2441, 0.1682, 0.1439],
        [0.5133, 0.6465, 0.5965, 0.4993, 0.4233, 0.3657, 0.3462],
    ]
)


#: roughness and IOR of :data:`GLASS_T_SCALE`
GLASS_ROUGH = np.array([0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0])
GLASS_IOR = np.array([1.2, 1.45, 1.9, 2.5])
#: transmittance factors of Mitsuba's ``roughdielectric`` that make a white glass sphere in a white furnace
#: as bright as Cycles' compensated MULTI_GGX glass (Cycles: 0.98-1.0; Mitsuba loses energy at each rough
#: interaction, most in rough total internal reflection); measured by bisection with
#: benchmarks/calibrate_mitsuba_glass.py (bpy 5.0.1, Mitsuba 3.9.1 scalar_rgb, 128 spp; below roughness
#: 0.3 within the noise of 1; 2.5 was the search's limit)
GLASS_T_SCALE = np.array(
    [
        [1.0, 1.0, 1.0, 1.0],
        [1.0, 1.0, 1.0, 1.0],
        [1.006, 1.018, 1.029, 1.053],
        [1.041, 1.076, 1.123, 1.217],
        [1.1, 1.182, 1.322, 1.533],
        [1.229, 1.404, 1.732, 2.225],
        [1.404, 1.721, 2.307, 2.5],
    ]
)


def glass_scale(material: Any) -> tuple[float, float]:
    """(reflection, transmission) factors of Mitsuba's ``roughdielectric`` for Cycles' glass: reflection 1
    (a scaled reflection would amplify the rough internal reflections), transmission from
    :data:`GLASS_T_SCALE` (bilinear in roughness and IOR, clamped to the table); 1 for "GGX"."""
    r = float(material.roughness)
    if r <= GLASS_ROUGH[0] or material.distribution != "MULTI_GGX":
        return 1.0, 1.0
    ior = float(np.clip(float(material.ior), GLASS_IOR[0], GLASS_IOR[-1]))
    by_ior = np.array([np.interp(ior, GLASS_IOR, row) for row in GLASS_T_SCALE])
    return 1.0, float(np.interp(min(r, 1.0), GLASS_ROUGH, by_ior))


def sum_lobes(lobes: list[Lobe]) -> dict[str, Any]:
    """The sum of the lobes as nested ``blendbsdf``: lobe i sits under blend weights whose product is
    1 / n, so it is built with n times its scale."""
    live = [lb for lb in lobes if float(np.max(lb.scale)) > 0]
    if not live:
        return {"type": "diffuse", "reflectance": raw_rgb(np.zeros(3))}
    n = len(live)
    node = live[-1].make(live[-1].scale * n)
    for i in range(n - 2, -1, -1):
        m = n - i  # lobes in this node
        node = {"type": "blendbsdf", "weight": (m - 1) / m, "bsdf_0": live[i].make(live[i].scale * n), "bsdf_1": node}
    return node


def glass_lobe(material: Any, base: np.ndarray) -> dict[str, Any]:
    """Cycles' transmission layer: ``roughdielectric`` (a solid: one-sided, relative IOR ``ior``), the
    transmission colour ``sqrt(base colour)`` per crossing, reflection scaled by the tint remapping's mean,
    both scaled by :func:`glass_scale`."""
    eta = float(material.ior)
    r = float(material.roughness)
    s_r, s_t = glass_scale(material)
    tint = material.linear("specular_tint")[:3]
    f_real = cos_mean(fresnel_dielectric(_MU, eta))
    f_tint = cos_mean(_fresnel_of("dielectric", (eta, *(float(x) for x in tint)))(_MU))
    d: dict[str, Any] = {
        "type": "roughdielectric",
        "distribution": "ggx",
        "alpha": max(r * r, 1e-4),
        "int_ior": max(eta, 1.0001),
        "ext_ior": 1.0,
        "specular_reflectance": raw_rgb(s_r * f_tint / max(float(f_real), 1e-6)),
        "specular_transmittance": raw_rgb(s_t * np.sqrt(np.clip(base, 0.0, None))),
    }
    if r <= 0.0:
        del d["alpha"], d["distribution"]
        d["type"] = "dielectric"
    return d


def glass_layered(material: Any, base: np.ndarray) -> dict[str, Any] | None:
    """Cycles' transmission layer as a :data:`blendify_mitsuba.layered.GLASS_PLUGIN` BSDF (rough GGX glass with
    Cycles' view-dependent multiple-scattering compensation per side), or None for smooth glass (the lobe
    sum's ``dielectric``, exact)."""
    from .layered import GLASS_PLUGIN

    r, eta = float(material.roughness), float(material.ior)
    alpha = r * r
    if alpha < LAYERED_MIN_ALPHA or abs(eta - 1.0) < 1e-4:
        return None
    tint_t = np.sqrt(np.clip(np.asarray(base, dtype=np.float64)[:3], 0.0, None))
    spec_tint = material.linear("specular_tint")[:3]
    f_real = cos_mean(fresnel_dielectric(_MU, eta))
    f_tint = cos_mean(_fresnel_of("dielectric", (eta, *(float(x) for x in spec_tint)))(_MU))
    multi = material.distribution == "MULTI_GGX"
    if multi:
        outside, inside = glass_compensation(alpha, eta, tint_t), glass_compensation(alpha, 1.0 / eta, tint_t)
    else:
        outside = inside = np.ones((N_MU, 3))
    spec = {
        "alpha": float(alpha),
        "eta": eta,
        "reflect": [float(x) for x in np.broadcast_to(f_tint / max(float(f_real), 1e-6), (3,))],
        "transmit": [float(x) for x in tint_t],
        "outside": [float(v) for v in np.float32(outside).ravel()],
        "inside": [float(v) for v in np.float32(inside).ravel()],
    }
    return {"type": GLASS_PLUGIN, "spec": json.dumps(spec, separators=(",", ":"))}


def cycles_albedo_of(material: Any, base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cycles' directional albedo (N_MU, 3) of an opaque Principled material (the sum of its lobes) at the
    viewing cosines (N_MU,): what a white uniform background shows of it."""
    lobes = principled_lobes(material, np.asarray(base, dtype=np.float64)[:3])
    return _MU.copy(), np.asarray(sum(np.broadcast_to(lb.cycles, (N_MU, 3)) for lb in lobes))


#: the smallest GGX alpha :mod:`blendify_mitsuba.layered` takes; nearly mirror-like lobes (roughness below
#: about 0.03) keep the lobe sum, whose smooth plugins are exact mirrors
LAYERED_MIN_ALPHA = 1e-3
#: the smallest sampling odds of a lobe in the layered BSDF, relative to the sum of the odds
LAYERED_MIN_ODDS = 0.05


def layered_bsdf(lobes: list[Lobe], factor: float = 1.0, textured: bool = False) -> dict[str, Any] | None:
    """The opaque lobes as one :data:`blendify_mitsuba.layered.PLUGIN` BSDF (two-sided; its tables times
    ``factor``), or None when a lobe is nearly a mirror (see :data:`LAYERED_MIN_ALPHA`). ``textured``: the
    lobes were made with a white base colour and the plugin gets the real one as its ``base_color`` texture
    (the diffuse lobe takes it as colour, the metal as its F82-tint F0, compensation computed per point)."""
    from .layered import PLUGIN, spec_json

    live = [lb for lb in lobes if lb.jit is not None and float(np.max(lb.jit["table"])) > 0]
    if not live:
        return None
    if any(lb.jit["kind"] == "ggx" and float(lb.jit["alpha"]) < LAYERED_MIN_ALPHA for lb in live if lb.jit):
        return None
    odds = np.array([float(cos_mean(np.broadcast_to(lb.cycles, (N_MU, 3)).mean(axis=1))) for lb in live])
    odds = np.maximum(odds, LAYERED_MIN_ODDS * max(float(odds.sum()), 1e-9))
    out = []
    for lb, p in zip(live, odds / odds.sum(), strict=True):
        d = dict(lb.jit or {})
        if textured and d["kind"] == "diffuse":
            d["base"] = True
        if textured and d.get("fresnel") == "f82":
            d["fresnel"], d["table"] = "f82_texture", d["table_textured"]
        else:
            d.pop("e", None)
        for key in ("table_textured", "f0", "b") if d.get("fresnel") == "f82_texture" else ("table_textured",):
            d.pop(key, None)
        table = np.broadcast_to(np.asarray(d["table"], dtype=np.float64) * factor, (N_MU, 3))
        d["table"] = [float(v) for v in np.float32(table).ravel()]
        d["p"] = float(p)
        if "alpha" in d:
            d["alpha"] = float(d["alpha"])
        out.append(d)
    return {"type": PLUGIN, "spec": spec_json(out)}


def principled_bsdf(
    material: Any, base: np.ndarray, wrap: Callable[[dict[str, Any]], dict[str, Any]], layered: bool = False
) -> dict[str, Any]:
    """The Mitsuba BSDF of a Principled material with the constant linear ``base`` colour (3,): the opaque
    lobes summed and made two-sided (``layered``: as one :mod:`blendify_mitsuba.layered` BSDF with Cycles'
    view-dependent weights, when it takes them), blended with the one-sided glass of the transmission layer;
    ``wrap`` wraps each part (the normal map)."""
    base = np.asarray(base, dtype=np.float64)[:3]
    tw = float(material.transmission_weight)
    lobes = principled_lobes(material, base)
    g = 0.0
    if tw > 0.0:
        g = min(max(transmission_weight_above(material) * tw, 0.0), 1.0)
    glass = None
    if tw > 0.0:
        glass = wrap((glass_layered(material, base) if layered else None) or glass_lobe(material, base))
    if glass is not None and g >= 1.0 - 1e-6:
        return glass
    lay = layered_bsdf(lobes, 1.0 / (1.0 - g)) if layered else None
    if lay is not None:
        opaque = wrap(lay)
    else:
        for lb in lobes:
            lb.scale = lb.scale / (1.0 - g)
        opaque = {"type": "twosided", "bsdf": wrap(sum_lobes(lobes))}
    if glass is None:
        return opaque
    return {"type": "blendbsdf", "weight": g, "bsdf_0": opaque, "bsdf_1": glass}


def transmission_weight_above(material: Any) -> float:
    """The mean attenuation (scalar) the sheen, coat and metal layers hand to the transmission layer."""
    w = np.ones((N_MU, 1))
    sheen = float(material.sheen_weight)
    if sheen > 0:
        tint = material.linear("sheen_tint")[:3] * sheen
        w = w * (1.0 - np.max(sheen_albedo(float(material.sheen_roughness))[:, None] * tint, axis=1, keepdims=True))
    coat, eta = float(material.coat_weight), max(float(material.coat_ior), 1.0)
    if coat > 0 and eta > 1.0:
        a_coat = _conductor_lobe(float(material.coat_roughness) ** 2, (eta, 1.0, 1.0, 1.0), "dielectric", True)[3]
        w = w * (1.0 - coat * a_coat[:, :1])
    return float(cos_mean(w)[0]) * (1.0 - float(material.metallic))


def glossy_scale(roughness: float, distribution: str, color: np.ndarray) -> np.ndarray:
    """Per channel, the factor taking Mitsuba's ``roughconductor`` with a perfect-mirror Fresnel (separable
    shadowing, single scattering) to Cycles' Glossy BSDF of colour ``color`` (GGX: height-correlated
    shadowing; MULTI_GGX: compensated with ``F_ss`` = the colour)."""
    alpha = roughness * roughness
    if roughness <= 0.0 or distribution not in ("GGX", "MULTI_GGX"):
        return np.ones(3)
    out = []
    for c in np.asarray(color, dtype=np.float64)[:3]:
        a_cyc = cycles_albedo(alpha, _constant_fresnel(float(c)), distribution == "MULTI_GGX")
        a_mi = ggx_albedo(alpha, None, correlated=False) * c
        out.append(float(cos_mean(a_cyc)[0] / max(float(cos_mean(a_mi)[0]), 1e-9)))
    return np.array(out)


def _constant_fresnel(value: float) -> Fresnel:
    return lambda c: np.full(np.shape(c) + (1,), value)
