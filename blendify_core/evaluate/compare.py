"""Compare two renders (``bf.compare``) and cross-check one scene across backends (``bf.crosscheck``).

``compare(a, b)`` treats ``b`` as the reference and returns a :class:`CompareReport`: per-output metrics,
a verdict against a named tolerance tier (:data:`TIERS`), human-readable failures and a heat-map diff
image per output. ``crosscheck(scene)`` renders one scene with every available backend at comparable
settings (box filter, no denoiser, no clamping, fixed seed) and compares every pair at the tier that fits
the pair (path tracer vs path tracer, rasteriser vs path tracer) and the scene (delta lights or not,
Lambertian materials or not): :func:`choose_tier`. Statistical (noise-aware) comparison of path-traced
images lives in :mod:`blendify_core.evaluate.stats`.

Metrics (``report.metrics[output][metric]``):

- ``rgb`` (premultiplied linear colour, over pixels with alpha > 0 in both): ``mean_rel_error`` and
  ``max_rel_error`` of ``|a - r| / max(|r|, 0.02)`` per channel (Mitsuba's error with its 2e-2 floor),
  ``mean_rel_error_interior`` (the same over interior pixels, see below), ``rel_mse`` = mean
  ``(a - r)^2 / (r^2 + 0.01)``, ``mean_ratio`` (sum a / sum r: a units check) and ``ratio_error`` =
  ``|mean_ratio - 1|``, ``alpha_mean_abs_error`` (all pixels), and on the sRGB-encoded images composited
  over black: ``ssim`` (scikit-image), ``flip`` (NVIDIA ꟻLIP, LDR, mean error) and ``psnr`` (dB).
- ``depth`` (where both hit): quantiles ``rel_diff_q50``/``rel_diff_q99``/``rel_diff_q999`` and
  ``rel_diff_max`` of ``|a - r| / r``.
- ``mask`` (hit masks: from depth, else instance, else alpha >= 0.5): ``iou``, ``n_disagree``,
  ``n_disagree_interior`` (disagreeing pixels that are not within 1 px of both masks' boundaries, i.e.
  not explained by a silhouette moved by <= 1 px: holes, specks, shifts of >= 2 px) and
  ``edge_disagree_fraction`` (``n_disagree`` / boundary pixels).
- ``normal`` (interior pixels): ``angle_mean_deg``, ``angle_q50_deg``, ``angle_q99_deg``,
  ``angle_q999_deg``, ``angle_max_deg``; over every pixel both hit: ``angle_q99_deg_all``,
  ``angle_max_deg_all``, ``flipped_fraction`` (angle > 90 degrees: opposite sidedness conventions).
- ``instance`` (where both hit, ids matched by tag name through ``instance_tags``): ``agreement``,
  ``n_disagree``.
- ``albedo``: ``mean_rel_error``, ``max_rel_error`` (interior pixels), ``*_all`` (every pixel both hit).

*Interior* pixels (:func:`interior_mask`) have a 3x3 neighbourhood that is one surface in both results (no
silhouette, no border between instances, no crease): only there is a pass that an engine filters over
the pixel (Cycles' normal/albedo passes, anti-aliased colour) comparable with one sampled at the pixel
centre (Mitsuba's AOVs, pyrender). Metrics over interior pixels are NaN when there are none (e.g. 1-2 px
points); tiers then skip them with a note.

scikit-image, flip-evaluator and Pillow are imported inside the functions that need them; without the
``metrics`` extra (scikit-image, flip-evaluator) ``ssim`` and ``flip`` are NaN and the report says how to
install them (a tier that thresholds them then fails with that hint).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import BackendUnavailableError, InvalidSceneError, RenderError, UnsupportedFeatureError
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.pipeline.result import RenderResult, depth_to_image, instance_to_image

__all__ = [
    "TIERS",
    "TIER_NOTES",
    "PATH_TRACERS",
    "CompareReport",
    "CrosscheckReport",
    "compare",
    "crosscheck",
    "crosscheck_main",
    "choose_tier",
    "is_path_tracer",
    "alpha_centroids",
    "hit_mask",
    "interior_mask",
    "heat_map",
]

#: the error floor of the relative error (Mitsuba's test_ad_integrators uses 2e-2)
REL_FLOOR = 0.02
#: backends that are unbiased path tracers (the others are rasterisers)
PATH_TRACERS = frozenset({"cycles", "mitsuba"})
COMPARED_OUTPUTS = ("rgb", "depth", "mask", "normal", "albedo", "instance")
#: metrics computed over interior pixels only (see interior_mask): NaN when there are none
_INTERIOR_METRICS = {
    "rgb": frozenset({"mean_rel_error_interior"}),
    "normal": frozenset({"angle_mean_deg", "angle_q50_deg", "angle_q99_deg", "angle_q999_deg", "angle_max_deg"}),
    "albedo": frozenset({"mean_rel_error", "max_rel_error"}),
    "depth": frozenset(),
    "mask": frozenset(),
    "instance": frozenset(),
}
#: the pixel count behind the other metrics of each output (a NaN metric over 0 pixels is not a failure)
_COUNT_KEYS = {"rgb": "n_covered", "depth": "n_both", "normal": "n_valid", "albedo": "n_both", "instance": "n_both"}
#: metrics where larger is better (thresholds are minimums); every other metric is an upper bound
HIGHER_IS_BETTER = frozenset({"ssim", "psnr", "iou", "agreement"})

# ---------------------------------------------------------------------------------------------------
# Tolerance tiers: output -> metric -> threshold (upper bound, or lower bound for HIGHER_IS_BETTER).
# Every number cites the measurement behind it. "CONV" = docs/conventions.md, section "Measurements behind
# the tolerance tiers" (made with the same engine versions); "XC" = benchmarks/crosscheck_report.py, whose
# measured table is in docs/crosscheck.md (re-run it after changing a backend, then revisit the numbers).
# ---------------------------------------------------------------------------------------------------
_GEOMETRY: dict[str, dict[str, float]] = {
    # CONV §11: depth <= 1e-3 relative with identical tessellation and the Mitsuba near-clip correction.
    # The q99 (not the max): silhouette pixels whose centre ray grazes an edge may hit different surfaces.
    # XC: Cycles/pyrender vs the analytic ray cast of tessellated marker spheres 6.7e-4 / 9.8e-4 (sagitta of
    # the 64x32 UV sphere); tilted plane 5e-6; every mesh scene <= 8e-5.
    "depth": {"rel_diff_q99": 1e-3},
    # CONV §13: pyrender/OSMesa and Cycles matched an exact ray cast pixel for pixel on the marker scene.
    # XC: every pair on every mesh scene has 0 interior disagreements; the only edge disagreements are
    # pixel centres within 0.004 px of a silhouette (tessellation), <= 3 px per scene.
    # (IoU is reported but not thresholded: one edge pixel moves the IoU of a 30-pixel marker by 3 %.)
    "mask": {"n_disagree_interior": 0, "edge_disagree_fraction": 0.05},
    # interior pixels only (no silhouette/crease: see interior_mask). XC: Mitsuba vs pyrender <= 2e-4 deg
    # (both pixel-centre); Cycles' normal pass is averaged over the pixel: 2.0 deg (bunny) / 2.1 deg
    # (orthographic bunny) at q99 on a curved dense mesh. A flipped/mirrored normal shows as ~180 deg.
    "normal": {"angle_q99_deg": 3.0, "flipped_fraction": 0.01},
    # XC: >= 0.9999 on every scene (one pixel on an instance border of the orthographic bunny)
    "instance": {"agreement": 0.999},
}

TIERS: dict[str, dict[str, dict[str, float]]] = {
    # Two results of the same deterministic computation (golden tests of a raster backend, unit tests).
    "identical": {
        "rgb": {"max_rel_error": 1e-6, "alpha_mean_abs_error": 1e-6},
        "depth": {"rel_diff_max": 1e-6},
        "mask": {"n_disagree": 0},
        "normal": {"angle_max_deg_all": 1e-2},
        "instance": {"agreement": 1.0},
        "albedo": {"max_rel_error_all": 1e-6},
    },
    # Geometric outputs only (colour unchecked): camera, depth, masks, normals, instance ids.
    "geometry": dict(_GEOMETRY),
    # Cycles vs Mitsuba, Lambertian materials lit by delta lights only (point/spot without radius, sun
    # without angle). CONV §11: mean rel <= 0.5 % (noise-free cases 0.03 %); CONV §13 planes 1.0005/0.9995.
    # XC: planes 2e-7 (sun) / 9e-4 (point, spot at 16 spp: pixel-footprint sampling), per-face-material
    # scene 1.5e-3 interior, ratio 0.9996. Albedo is noise-free: XC <= 2e-6.
    "pathtracer_delta": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.005, "ratio_error": 0.005},
        "albedo": {"mean_rel_error": 0.01},
    },
    # Cycles vs Mitsuba, Lambertian materials with area lights or a background/environment light.
    # CONV §11: area/world lights mean rel <= 2 % at 256 spp (Monte-Carlo noise dominates). XC at 256 spp:
    # area 0.72 %, disk 0.62 %, background 1.27 % (Mitsuba's env noise; Cycles is noise-free there),
    # textured quad 1.28 %; ratios within 0.9998-1.0001.
    "pathtracer": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.02, "ratio_error": 0.01},
        "albedo": {"mean_rel_error": 0.01},
    },
    # Cycles vs Mitsuba with non-Lambertian materials (Principled with a specular layer, plastic, metal,
    # glossy, emission, ...): the engines' BSDFs differ. CONV §6.2: plastic sum ratio 0.935, mean |rel|
    # 7.3 %; metal 1.008 / 1.5 %. XC: bunny (Principled, roughness 0.6) 5.4 % / ratio 0.981, orthographic
    # bunny 5.8 %, primitives (plastic + metal) 5.5 % / 0.993.
    "pathtracer_material": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.08, "ratio_error": 0.08},
        "albedo": {"mean_rel_error": 0.01},
    },
    # pyrender vs a path tracer, Lambertian materials. pyrender keeps an F0 = 0.04 GGX lobe (CONV §6.1: +-1 %
    # on grey, but +0.01 absolute on every channel, i.e. >100 % relative on dark channels of saturated
    # colours), has no GI and shadow-mapped shadows: per-channel relative error is meaningless there
    # (XC: 28 % on the per-face-material scene whose images look alike). The tier therefore bounds the
    # overall brightness (ratio) and the perceptual error (FLIP on sRGB). XC: ratio error <= 0.02 on the
    # planes, 0.05 fuze, 0.085 point cloud (pyrender's coarser point spheres); FLIP <= 0.044 on the planes,
    # <= 0.067 on every other Lambertian scene. An area light (pyrender: a spot light) gives ratio 1.45.
    # Geometry keeps the tight tier (CONV §13; XC pixel-exact except pyrender's level-of-detail points).
    # Albedo: pyrender samples minified textures through mipmaps, the path tracers per sample / at the
    # pixel centre: XC 4.6 % (Cycles) and 5.0 % (Mitsuba) on fuze.obj.
    "raster": {
        **_GEOMETRY,
        "rgb": {"ratio_error": 0.10, "flip": 0.08},
        "albedo": {"mean_rel_error": 0.08},
    },
    # pyrender vs a path tracer with non-Lambertian materials. CONV §6.2: pyrender/Mitsuba plastic 0.911,
    # 9.6 %. XC: FLIP 0.058-0.108 (bunny, orthographic bunny, primitives), ratio error <= 0.017.
    "raster_material": {
        **_GEOMETRY,
        "rgb": {"ratio_error": 0.10, "flip": 0.12},
        "albedo": {"mean_rel_error": 0.08},
    },
}

#: one line per tier: what it is for and the measurement behind its numbers (docs/crosscheck.md prints it)
TIER_NOTES: dict[str, str] = {
    "identical": "same deterministic computation twice (same backend, same seed): bit-level agreement.",
    "geometry": "depth q99 <= 1e-3 (CONV §11; measured <= 9.8e-4 on tessellated spheres, 5e-6 on a plane), "
    "no interior mask disagreement (measured 0 on every mesh scene), normals q99 <= 3 deg on interior pixels "
    "(Mitsuba/pyrender 2e-4 deg; Cycles' area-filtered normal pass 2.1 deg on the bunny), ids >= 0.999.",
    "pathtracer_delta": "Cycles vs Mitsuba, Lambertian, delta lights: colour <= 0.5 % interior mean rel and "
    "ratio within 0.5 % (CONV §11; measured 2e-7 sun plane, 9e-4 point/spot plane, 1.5e-3 per-face scene).",
    "pathtracer": "Cycles vs Mitsuba, Lambertian, area/sky light: <= 2 % at 256 spp (CONV §11; measured 0.6-1.3 %"
    ", ratio within 2e-4); below ~128 spp noise alone may fail it: use repeats (statistical test).",
    "pathtracer_material": "Cycles vs Mitsuba with Principled/plastic/metal: <= 8 % and ratio within 8 % "
    "(CONV §6.2 plastic 7.3 % / 0.935; measured bunny 5.4 % / 0.981, primitives 5.5 % / 0.993).",
    "raster": "pyrender vs a path tracer, Lambertian: brightness ratio within 10 % and FLIP <= 0.08 (per-channel "
    "relative error is meaningless with pyrender's F0 = 0.04 lobe on dark channels; measured ratio <= 1.02 on "
    "planes, FLIP <= 0.067); geometry as tight as the geometry tier; albedo <= 8 % (mipmapped textures: "
    "measured 4.6-5.0 % on fuze.obj).",
    "raster_material": "pyrender vs a path tracer with non-Lambertian materials: ratio within 10 %, FLIP <= 0.12 "
    "(CONV §6.2 plastic 0.911 / 9.6 %; measured FLIP 0.058-0.108).",
}

# the heat-map scales (log10 range for relative errors, linear degrees for normals)
_REL_LOG_RANGE = (-4.0, 0.0)
_DEPTH_LOG_RANGE = (-6.0, -1.0)
_ANGLE_RANGE_DEG = 20.0

# inferno-like anchors (position, RGB) for the heat maps
_CMAP = np.array(
    [
        [0.00, 0, 0, 4],
        [0.14, 40, 11, 84],
        [0.29, 101, 21, 110],
        [0.43, 159, 42, 99],
        [0.57, 212, 72, 66],
        [0.71, 245, 125, 21],
        [0.86, 250, 193, 39],
        [1.00, 252, 255, 164],
    ]
)


def heat_map(values: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """(H, W) values in [0, 1] -> (H, W, 3) uint8 inferno-like colours; ``~valid`` pixels are dark grey."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float64), nan=1.0, posinf=1.0), 0.0, 1.0)
    out = np.stack([np.interp(v, _CMAP[:, 0], _CMAP[:, c]) for c in (1, 2, 3)], axis=-1)
    out = np.round(out).astype(np.uint8)
    if valid is not None:
        out[~valid] = (40, 40, 40)
    return out


def _log_scale(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        lv = np.log10(np.maximum(values, 10.0**lo))
    return (lv - lo) / (hi - lo)


# ---------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------
def hit_mask(result: RenderResult) -> np.ndarray | None:
    """Pixel-centre hit mask: from depth, else instance, else alpha >= 0.5 (None without any of them)."""
    if result.depth is not None:
        return np.isfinite(result.depth)
    if result.instance is not None:
        return result.instance >= 0
    if result.rgba is not None:
        return result.rgba[..., 3] >= 0.5
    return None


def _edge_zone(mask: np.ndarray) -> np.ndarray:
    """Pixels within 1 px (8-neighbourhood) of the mask's boundary, on either side."""
    from scipy import ndimage

    st = np.ones((3, 3), dtype=bool)
    dil = ndimage.binary_dilation(mask, structure=st, border_value=0)
    ero = ndimage.binary_erosion(mask, structure=st, border_value=1)
    return dil & ~ero


def _inner_boundary(mask: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    return mask & ~ndimage.binary_erosion(mask, structure=np.ones((3, 3), dtype=bool), border_value=1)


EDGE_ANGLE_DEG = 20.0  # a normal jump above this between neighbouring pixels is a crease (face edge)


def _neighbours(x: np.ndarray) -> list[np.ndarray]:
    """The 8 neighbours of every pixel (edge-padded), as arrays shaped like ``x``."""
    h, w = x.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (x.ndim - 2)
    xp = np.pad(x, pad, mode="edge")
    return [xp[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]


def interior_mask(a: RenderResult, b: RenderResult) -> np.ndarray:
    """(H, W) bool: pixels hit in both results whose whole 3x3 neighbourhood is hit in both, belongs to the
    same instance (when both have instance ids) and has no crease (normals within ``EDGE_ANGLE_DEG`` of
    the centre pixel's, when both have normals).

    Only these pixels are comparable between an engine that filters a pass over the pixel's area (Cycles'
    normal/albedo passes, anti-aliased colour) and one that samples it at the pixel centre (Mitsuba's
    AOVs, pyrender); at silhouettes, instance borders and creases the two definitions legitimately differ."""
    ma, mb = hit_mask(a), hit_mask(b)
    if ma is None or mb is None:
        shape = a.resolution[::-1]  # type: ignore[index]
        ma = mb = np.ones(shape, dtype=bool)
    both = ma & mb
    ok = both.copy()
    for nb in _neighbours(both):
        ok &= nb
    for r in (a, b):
        if r.instance is not None:
            for nb in _neighbours(r.instance):
                ok &= nb == r.instance
        if r.normal is not None:
            n = r.normal.astype(np.float64)
            cos_lim = np.cos(np.radians(EDGE_ANGLE_DEG))
            for nb in _neighbours(n):
                ok &= np.sum(nb * n, axis=-1) >= cos_lim * np.linalg.norm(nb, axis=-1) * np.linalg.norm(n, axis=-1)
    return ok


def _quantiles(values: np.ndarray, prefix: str, suffix: str = "") -> dict[str, float]:
    if values.size == 0:
        return {f"{prefix}_{q}{suffix}": math.nan for q in ("q50", "q99", "q999")} | {f"{prefix}_max{suffix}": math.nan}
    q = np.quantile(values, [0.5, 0.99, 0.999])
    return {
        f"{prefix}_q50{suffix}": float(q[0]),
        f"{prefix}_q99{suffix}": float(q[1]),
        f"{prefix}_q999{suffix}": float(q[2]),
        f"{prefix}_max{suffix}": float(values.max()),
    }


def _srgb_over_black(rgb: np.ndarray) -> np.ndarray:
    return linear_to_srgb(np.clip(rgb, 0.0, 1.0).astype(np.float32)).astype(np.float32)


_MISSING_METRICS: set[str] = set()  # optional metric packages found missing (ssim: scikit-image, flip)
_INSTALL_HINT = "install the optional metrics: pip install 'blendify-core[metrics]' (scikit-image, flip-evaluator)"


def _ssim(a: np.ndarray, b: np.ndarray) -> float:
    try:
        from skimage.metrics import structural_similarity
    except ImportError:
        _MISSING_METRICS.add("ssim")
        return math.nan

    h, w = a.shape[:2]
    win = min(7, h, w)
    if win % 2 == 0:
        win -= 1
    if win < 3:
        return math.nan
    return float(structural_similarity(a, b, channel_axis=-1, data_range=1.0, win_size=win))


def _flip(test: np.ndarray, reference: np.ndarray) -> tuple[float, np.ndarray]:
    try:
        import flip_evaluator
    except ImportError:
        _MISSING_METRICS.add("flip")
        return math.nan, np.zeros(test.shape[:2], dtype=np.float32)

    err_map, mean, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(reference, dtype=np.float32),
        np.ascontiguousarray(test, dtype=np.float32),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
    )
    return float(mean), np.asarray(err_map)[..., 0]


def _psnr(test: np.ndarray, reference: np.ndarray) -> float:
    mse = float(np.mean((test.astype(np.float64) - reference.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else float(10.0 * np.log10(1.0 / mse))


# ---------------------------------------------------------------------------------------------------
# per-output metrics: each returns (metrics, diff image, legend)
# ---------------------------------------------------------------------------------------------------
def _rgb_metrics(a: RenderResult, b: RenderResult, interior: np.ndarray) -> tuple[dict[str, float], np.ndarray, str]:
    ra = a.rgba[..., :3].astype(np.float64)  # type: ignore[index]
    rb = b.rgba[..., :3].astype(np.float64)  # type: ignore[index]
    aa = a.rgba[..., 3].astype(np.float64)  # type: ignore[index]
    ab = b.rgba[..., 3].astype(np.float64)  # type: ignore[index]
    covered = (aa > 0) & (ab > 0)
    rel = np.abs(ra - rb) / np.maximum(np.abs(rb), REL_FLOOR)
    m: dict[str, float] = {"n_covered": float(covered.sum())}
    if covered.any():
        rc = rel[covered]
        m["mean_rel_error"] = float(rc.mean())
        m["max_rel_error"] = float(rc.max())
        m["rel_mse"] = float(np.mean((ra[covered] - rb[covered]) ** 2 / (rb[covered] ** 2 + 0.01)))
        sb = float(rb[covered].sum())
        m["mean_ratio"] = float(ra[covered].sum() / sb) if sb > 0 else math.nan
        m["ratio_error"] = abs(m["mean_ratio"] - 1.0)
    else:
        for k in ("mean_rel_error", "max_rel_error", "rel_mse", "mean_ratio", "ratio_error"):
            m[k] = math.nan
    interior = covered & interior
    m["n_interior"] = float(interior.sum())
    m["mean_rel_error_interior"] = float(rel[interior].mean()) if interior.any() else math.nan
    m["alpha_mean_abs_error"] = float(np.abs(aa - ab).mean())
    sa, sb8 = _srgb_over_black(ra), _srgb_over_black(rb)
    m["ssim"] = _ssim(sa, sb8)
    m["flip"], _ = _flip(sa, sb8)
    m["psnr"] = _psnr(sa, sb8)
    per_pixel = rel.mean(axis=-1)
    alpha_only = (aa > 0) ^ (ab > 0)
    img = heat_map(_log_scale(per_pixel, *_REL_LOG_RANGE), covered | alpha_only)
    img[alpha_only] = np.maximum(img[alpha_only], heat_map(_log_scale(np.abs(aa - ab), *_REL_LOG_RANGE))[alpha_only])
    return m, img, f"relative error, log10 scale {_REL_LOG_RANGE[0]:g}..{_REL_LOG_RANGE[1]:g}"


def _depth_metrics(a: RenderResult, b: RenderResult) -> tuple[dict[str, float], np.ndarray, str]:
    da = a.depth.astype(np.float64)  # type: ignore[union-attr]
    db = b.depth.astype(np.float64)  # type: ignore[union-attr]
    both = np.isfinite(da) & np.isfinite(db)
    rel = np.zeros(da.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel[both] = np.abs(da[both] - db[both]) / np.maximum(np.abs(db[both]), 1e-12)
    m = {"n_both": float(both.sum())}
    m.update(_quantiles(rel[both], "rel_diff"))
    img = heat_map(_log_scale(rel, *_DEPTH_LOG_RANGE), both)
    return m, img, f"relative depth difference, log10 scale {_DEPTH_LOG_RANGE[0]:g}..{_DEPTH_LOG_RANGE[1]:g}"


def _mask_metrics(ma: np.ndarray, mb: np.ndarray) -> tuple[dict[str, float], np.ndarray, str]:
    union = ma | mb
    inter = ma & mb
    dis = ma ^ mb
    # an anti-aliasing / tessellation disagreement lies on a silhouette moved by at most 1 px: within 1 px
    # of BOTH masks' boundaries. A hole, a speck or a silhouette moved by >= 2 px is an interior disagreement.
    zone = _edge_zone(ma) & _edge_zone(mb)
    interior = dis & ~zone
    n_boundary = int((_inner_boundary(ma) | _inner_boundary(mb)).sum())
    m = {
        "iou": float(inter.sum() / union.sum()) if union.any() else 1.0,
        "n_disagree": float(dis.sum()),
        "n_disagree_interior": float(interior.sum()),
        "edge_disagree_fraction": float(dis.sum() / n_boundary) if n_boundary else float(dis.any()),
        "n_boundary": float(n_boundary),
    }
    img = np.zeros(ma.shape + (3,), dtype=np.uint8)
    img[inter] = (110, 110, 110)
    img[ma & ~mb] = (220, 60, 60)
    img[mb & ~ma] = (60, 110, 230)
    img[interior] = (255, 255, 0)
    return m, img, "grey both, red only A, blue only B, yellow interior disagreement"


def _normal_metrics(
    a: RenderResult, b: RenderResult, both: np.ndarray, interior: np.ndarray
) -> tuple[dict[str, float], np.ndarray, str]:
    na = a.normal.astype(np.float64)  # type: ignore[union-attr]
    nb = b.normal.astype(np.float64)  # type: ignore[union-attr]
    la = np.linalg.norm(na, axis=-1)
    lb = np.linalg.norm(nb, axis=-1)
    valid = both & (la > 0.5) & (lb > 0.5)
    ang = np.zeros(both.shape)
    cos = np.sum(na[valid] * nb[valid], axis=-1) / (la[valid] * lb[valid])
    ang[valid] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    inner = valid & interior
    vals = ang[inner]
    m = {
        "n_valid": float(valid.sum()),
        "n_interior": float(inner.sum()),
        "angle_mean_deg": float(vals.mean()) if vals.size else math.nan,
        "flipped_fraction": float((ang[valid] > 90).mean()) if valid.any() else math.nan,
    }
    m.update(_quantiles(vals, "angle", "_deg"))
    allv = ang[valid]
    m["angle_q99_deg_all"] = float(np.quantile(allv, 0.99)) if allv.size else math.nan
    m["angle_max_deg_all"] = float(allv.max()) if allv.size else math.nan
    img = heat_map(ang / _ANGLE_RANGE_DEG, valid)
    return m, img, f"angular error, 0..{_ANGLE_RANGE_DEG:g} degrees"


def _instance_metrics(a: RenderResult, b: RenderResult) -> tuple[dict[str, float], np.ndarray, str]:
    ia, ib = a.instance, b.instance
    names: dict[str, int] = {}
    for t in list(a.instance_tags) + list(b.instance_tags):
        names.setdefault(str(t), len(names))

    def remap(ids: np.ndarray, tags: Sequence[str]) -> np.ndarray:
        table = np.array([names[str(t)] for t in tags] + [-1], dtype=np.int64)
        ids = ids.astype(np.int64)
        bad = (ids >= len(tags)) | (ids < -1)
        if bad.any():
            raise InvalidSceneError(
                f"instance: ids up to {int(ids.max())} but only {len(tags)} instance_tags (ids must index them)"
            )
        return table[np.where(ids < 0, len(tags), ids)]

    ga = remap(ia, a.instance_tags)  # type: ignore[arg-type]
    gb = remap(ib, b.instance_tags)  # type: ignore[arg-type]
    both = (ga >= 0) & (gb >= 0)
    agree = both & (ga == gb)
    n = int(both.sum())
    m = {
        "agreement": float(agree.sum() / n) if n else 1.0,
        "n_disagree": float(n - agree.sum()),
        "n_both": float(n),
    }
    img = np.zeros(ga.shape + (3,), dtype=np.uint8)
    img[agree] = (110, 110, 110)
    img[both & ~agree] = (255, 40, 40)
    return m, img, "grey same instance, red different instance"


def _albedo_metrics(
    a: RenderResult, b: RenderResult, both: np.ndarray, interior: np.ndarray
) -> tuple[dict[str, float], np.ndarray, str]:
    xa = a.albedo.astype(np.float64)  # type: ignore[union-attr]
    xb = b.albedo.astype(np.float64)  # type: ignore[union-attr]
    rel = np.abs(xa - xb) / np.maximum(np.abs(xb), REL_FLOOR)
    inner = both & interior
    m: dict[str, float] = {"n_both": float(both.sum()), "n_interior": float(inner.sum())}
    m["mean_rel_error"] = float(rel[inner].mean()) if inner.any() else math.nan
    m["max_rel_error"] = float(rel[inner].max()) if inner.any() else math.nan
    m["mean_rel_error_all"] = float(rel[both].mean()) if both.any() else math.nan
    m["max_rel_error_all"] = float(rel[both].max()) if both.any() else math.nan
    img = heat_map(_log_scale(rel.mean(axis=-1), *_REL_LOG_RANGE), both)
    return m, img, f"relative error, log10 scale {_REL_LOG_RANGE[0]:g}..{_REL_LOG_RANGE[1]:g}"


# ---------------------------------------------------------------------------------------------------
# the report
# ---------------------------------------------------------------------------------------------------
def _fmt(v: float) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    if float(v).is_integer() and abs(v) < 1e9:
        return str(int(v))
    return f"{v:.4g}"


@dataclass
class CompareReport:
    """Result of :func:`compare` (``b`` is the reference).

    ``metrics``: output -> metric -> float; ``tier``: the tier's name; ``thresholds``: output -> metric ->
    threshold actually applied; ``passed``; ``failures``: readable strings; ``checks``: every applied
    check as (output, metric, value, op, threshold, ok); ``diff_images``: output -> (H, W, 3) uint8 heat
    map; ``legends``: output -> what the colours mean; ``names``: labels of a and b.
    """

    metrics: dict[str, dict[str, float]]
    tier: str
    thresholds: dict[str, dict[str, float]]
    passed: bool
    failures: list[str]
    checks: list[tuple[str, str, float, str, float, bool]]
    diff_images: dict[str, np.ndarray] = field(repr=False)
    legends: dict[str, str] = field(default_factory=dict, repr=False)
    names: tuple[str, str] = ("a", "b")
    notes: list[str] = field(default_factory=list)
    #: the compared results (a, b), kept so :meth:`save` can write them next to the diff maps
    results: tuple[RenderResult, RenderResult] | None = field(default=None, repr=False, compare=False)

    def summary(self) -> str:
        """Markdown: verdict, failures, and a table of every metric with its threshold."""
        a, b = self.names
        lines = [
            f"### {a} vs {b} (reference): {'PASS' if self.passed else 'FAIL'} at tier `{self.tier}`",
            "",
        ]
        for f in self.failures:
            lines.append(f"- FAIL: {f}")
        for n in self.notes:
            lines.append(f"- note: {n}")
        if self.failures or self.notes:
            lines.append("")
        lines += ["| output | metric | value | threshold |", "|---|---|---|---|"]
        limits = {(o, k): (op, t, ok) for o, k, _, op, t, ok in self.checks}
        for out, ms in self.metrics.items():
            for k, v in ms.items():
                lim = limits.get((out, k))
                th = "" if lim is None else f"{lim[0]} {_fmt(lim[1])}{'' if lim[2] else ' **FAIL**'}"
                lines.append(f"| {out} | {k} | {_fmt(v)} | {th} |")
        return "\n".join(lines) + "\n"

    def save(self, folder: str | os.PathLike[str]) -> Path:
        """Write ``diff_<output>.png`` for every output, the compared images (``a_<output>.png`` and
        ``b_<output>.png``, 8-bit previews), ``report.md`` and ``metrics.json`` into ``folder`` (created if
        needed); returns the folder. Each file is written atomically with the usual file mode; a file that
        cannot be written raises :class:`~blendify_core.errors.OutputError` naming it."""
        from PIL import Image

        from blendify_core._output import atomic_write, ensure_folder

        out = ensure_folder(folder, arg="folder")
        for name, img in self.diff_images.items():
            atomic_write(
                out / f"diff_{name}.png",
                lambda tmp, img=img: Image.fromarray(img).save(tmp, format="PNG"),
                arg="folder",
            )
        if self.results is not None:
            for label, r in zip(("a", "b"), self.results):
                for o in self.diff_images:
                    if (
                        o in ("rgb", "depth", "normal", "albedo", "instance")
                        and getattr(r, "rgba" if o == "rgb" else o) is not None
                    ):
                        r.save(out / f"{label}_{o}.png", output=o)
        legend = "\n".join(f"- `diff_{k}.png`: {v}" for k, v in self.legends.items())
        _write_text(out / "report.md", self.summary() + "\nDiff images:\n\n" + legend + "\n")
        _write_text(
            out / "metrics.json",
            json.dumps(
                {"tier": self.tier, "passed": self.passed, "failures": self.failures, "metrics": _json(self.metrics)},
                indent=1,
            ),
        )
        return out

    def __repr__(self) -> str:
        head = f"CompareReport({self.names[0]} vs {self.names[1]}: {'PASS' if self.passed else 'FAIL'}"
        key = []
        for out, metric in (
            ("rgb", "mean_rel_error"),
            ("depth", "rel_diff_q99"),
            ("mask", "iou"),
            ("normal", "angle_q99_deg"),
            ("instance", "agreement"),
            ("albedo", "mean_rel_error"),
        ):
            if metric in self.metrics.get(out, {}) and not math.isnan(self.metrics[out][metric]):
                key.append(f"{out}.{metric}={_fmt(self.metrics[out][metric])}")
        text = f"{head} at tier {self.tier!r}; " + ", ".join(key)
        if self.failures:
            text += "; failures: " + "; ".join(self.failures)
        return text + ")"


def _json(metrics: Mapping[str, Mapping[str, float]]) -> dict[str, dict[str, Any]]:
    return {
        o: {k: (v if isinstance(v, float) and math.isfinite(v) else str(v)) for k, v in ms.items()}
        for o, ms in metrics.items()
    }


def _backend_of(result: RenderResult) -> str | None:
    name = result.meta.get("backend") if isinstance(result.meta, dict) else None
    return str(name) if name else None


def is_path_tracer(backend: str | None) -> bool:
    """Whether backend ``backend`` is a path tracer (:data:`PATH_TRACERS` or its class's ``path_tracer``)."""
    if backend is None:
        return False
    if backend in PATH_TRACERS:
        return True
    from blendify_core.pipeline.backend import get_backend_class

    try:
        return bool(getattr(get_backend_class(backend), "path_tracer", False))
    except (BackendUnavailableError, InvalidSceneError):
        return False


def choose_tier(backend_a: str | None, backend_b: str | None, scene: Any = None) -> str:
    """The tier for a backend pair and (optionally) the scene.

    Two path tracers: "pathtracer_delta" (Lambertian materials, delta lights only), "pathtracer"
    (Lambertian, any light) or "pathtracer_material" (any non-Lambertian material). With a rasteriser:
    "raster" or "raster_material". Without a scene the Lambertian tiers are assumed ("pathtracer" /
    "raster"). Unknown backends (None) count as path tracers."""
    pt_a = backend_a is None or is_path_tracer(backend_a)
    pt_b = backend_b is None or is_path_tracer(backend_b)
    material = scene is not None and _non_lambertian(scene)
    if not (pt_a and pt_b):
        return "raster_material" if material else "raster"
    if material:
        return "pathtracer_material"
    if scene is not None and _delta_lights(scene):
        return "pathtracer_delta"
    return "pathtracer"


_NON_DELTA = ("light.point.soft", "light.sun.soft", "light.area", "light.area.disk")
_NON_DELTA += ("light.background", "light.environment")
_NON_DIFFUSE = (
    "material.principled",
    "material.metallic",
    "material.glossy",
    "material.transmission",
    "material.coat",
    "material.sheen",
    "material.subsurface",
    "material.emission",
    "material.alpha",
    "material.wireframe",
    "material.roughness_map",
    "material.metallic_map",
    "material.normal_map",
    "pointcloud.emission",
)


def _delta_lights(scene: Any) -> bool:
    from blendify_core.pipeline.capabilities import scene_features

    used = scene_features(scene, ("rgb",))
    return not any(f in used for f in _NON_DELTA)


def _non_lambertian(scene: Any) -> bool:
    from blendify_core.pipeline.capabilities import scene_features

    used = scene_features(scene, ("rgb",))
    return any(f in used for f in _NON_DIFFUSE)


def _resolve_tier(
    tier: Any, a: RenderResult, b: RenderResult, scene: Any = None
) -> tuple[str, dict[str, dict[str, float]]]:
    if tier is None or tier == "auto":
        name = choose_tier(_backend_of(a), _backend_of(b), scene)
        return name, TIERS[name]
    if isinstance(tier, str):
        if tier not in TIERS:
            raise InvalidSceneError(f"tier: unknown tier {tier!r}; expected one of {sorted(TIERS)}, 'auto' or a dict")
        return tier, TIERS[tier]
    if isinstance(tier, Mapping):
        th: dict[str, dict[str, float]] = {}
        for out, ms in tier.items():
            if out not in COMPARED_OUTPUTS or not isinstance(ms, Mapping):
                raise InvalidSceneError(
                    f"tier: expected a dict output -> {{metric: threshold}} with outputs from "
                    f"{list(COMPARED_OUTPUTS)}, got key {out!r} -> {ms!r}"
                )
            th[out] = {str(k): float(v) for k, v in ms.items()}
        return "custom", th
    raise InvalidSceneError(f"tier: expected a tier name from {sorted(TIERS)}, 'auto' or a dict, got {tier!r}")


def _check_shapes(a: RenderResult, b: RenderResult) -> None:
    ra, rb = a.resolution, b.resolution
    if ra is None or rb is None:
        raise InvalidSceneError("compare: both results need at least one output")
    if ra != rb:
        raise InvalidSceneError(f"compare: resolutions differ ({ra} vs {rb}); render both at the same resolution")


def compare(
    a: RenderResult,
    b: RenderResult,
    tier: str | Mapping[str, Mapping[str, float]] | None = "auto",
    outputs: Iterable[str] | None = None,
    names: tuple[str, str] | None = None,
    scene: Any = None,
) -> CompareReport:
    """Compare render ``a`` with reference ``b``; see the module docstring for the metrics.

    ``tier``: a name from :data:`TIERS`, "auto" (from ``meta["backend"]`` of both results:
    :func:`choose_tier`; pass the rendered ``scene`` so it can tell delta lights and non-Lambertian
    materials apart) or a dict output -> metric -> threshold. ``names``: labels for the report.
    ``outputs``: the outputs to compare (from "rgb", "depth", "mask", "normal", "albedo", "instance");
    default: every output present in both ("mask" whenever a hit mask can be derived from both).
    Requesting an output one of the results lacks raises :class:`InvalidSceneError`.
    """
    if not isinstance(a, RenderResult) or not isinstance(b, RenderResult):
        raise InvalidSceneError(f"compare: expected two RenderResult, got {type(a).__name__} and {type(b).__name__}")
    _check_shapes(a, b)
    tier_name, thresholds = _resolve_tier(tier, a, b, scene)
    attr = {"rgb": "rgba", "depth": "depth", "normal": "normal", "albedo": "albedo", "instance": "instance"}
    ma, mb = hit_mask(a), hit_mask(b)

    def has(r: RenderResult, out: str, m: np.ndarray | None) -> bool:
        return m is not None if out == "mask" else getattr(r, attr[out]) is not None

    if outputs is None:
        wanted = [o for o in COMPARED_OUTPUTS if has(a, o, ma) and has(b, o, mb)]
    else:
        if isinstance(outputs, str):
            outputs = (outputs,)
        wanted = []
        for o in outputs:
            o = "rgb" if o == "rgba" else o
            if o not in COMPARED_OUTPUTS:
                raise InvalidSceneError(f"outputs: unknown output {o!r}; expected names from {list(COMPARED_OUTPUTS)}")
            for label, r, m in (("a", a, ma), ("b", b, mb)):
                if not has(r, o, m):
                    raise InvalidSceneError(f"outputs: result {label} has no {o!r} output")
            if o not in wanted:
                wanted.append(o)
    if not wanted:
        raise InvalidSceneError("compare: the two results have no output in common")

    both = (ma & mb) if (ma is not None and mb is not None) else None
    if both is None:
        both = np.ones(a.resolution[::-1], dtype=bool)  # type: ignore[index]
    interior = interior_mask(a, b)
    _MISSING_METRICS.clear()
    metrics: dict[str, dict[str, float]] = {}
    diffs: dict[str, np.ndarray] = {}
    legends: dict[str, str] = {}
    for o in wanted:
        if o == "rgb":
            res = _rgb_metrics(a, b, interior)
        elif o == "depth":
            res = _depth_metrics(a, b)
        elif o == "mask":
            res = _mask_metrics(ma, mb)  # type: ignore[arg-type]
        elif o == "normal":
            res = _normal_metrics(a, b, both, interior)
        elif o == "instance":
            res = _instance_metrics(a, b)
        else:
            res = _albedo_metrics(a, b, both, interior)
        metrics[o], diffs[o], legends[o] = res

    failures: list[str] = []
    notes: list[str] = []
    checks: list[tuple[str, str, float, str, float, bool]] = []
    applied: dict[str, dict[str, float]] = {}
    for out, ms in thresholds.items():
        if out not in metrics:
            if outputs is not None and out in wanted:
                notes.append(f"{out}: not compared")
            continue
        for metric, limit in ms.items():
            if metric not in metrics[out]:
                raise InvalidSceneError(f"tier: unknown metric {out}.{metric}; known: {sorted(metrics[out])}")
            value = metrics[out][metric]
            if math.isnan(value):
                count_key = "n_interior" if metric in _INTERIOR_METRICS[out] else _COUNT_KEYS.get(out, "")
                if metrics[out].get(count_key, 1.0) == 0:
                    what = (
                        "interior pixels (objects of 1-2 px, e.g. small points)"
                        if count_key == "n_interior"
                        else ("pixels covered by both")
                    )
                    notes.append(f"{out}.{metric}: not checked, no {what}")
                    continue
            higher = metric in HIGHER_IS_BETTER
            op = ">=" if higher else "<="
            ok = (value >= limit) if higher else (value <= limit)
            if isinstance(value, float) and math.isnan(value):
                ok = False
            checks.append((out, metric, value, op, limit, bool(ok)))
            applied.setdefault(out, {})[metric] = limit
            if not ok:
                hint = f"; {_INSTALL_HINT}" if out == "rgb" and metric in _MISSING_METRICS else ""
                failures.append(
                    f"{out}.{metric} = {_fmt(value)}, expected {op} {_fmt(limit)} (tier {tier_name!r}){hint}"
                )
    if "rgb" in metrics:
        missing = sorted(m for m in ("ssim", "flip") if m in _MISSING_METRICS and math.isnan(metrics["rgb"][m]))
        if missing:
            notes.append(f"rgb: {', '.join(missing)} not computed: {_INSTALL_HINT}")
    la = names[0] if names else (_backend_of(a) or "a")
    lb = names[1] if names else (_backend_of(b) or "b")
    if la == lb and names is None:
        la, lb = f"{la} (a)", f"{lb} (b)"
    return CompareReport(
        metrics=metrics,
        tier=tier_name,
        thresholds=applied,
        passed=not failures,
        failures=failures,
        checks=checks,
        diff_images=diffs,
        legends=legends,
        names=(la, lb),
        notes=notes,
        results=(a, b),
    )


# ---------------------------------------------------------------------------------------------------
# marker centroids (camera self-test)
# ---------------------------------------------------------------------------------------------------
def alpha_centroids(result: RenderResult, expected: np.ndarray, window: int = 7) -> np.ndarray:
    """Alpha-weighted centroids (OpenCV pixel coordinates, pixel (i, j) centre at (i, j)) of the blobs
    near each ``expected`` (N, 2) pixel position, inside a (2 * window + 1)^2 window. Rows are NaN when
    the window holds no coverage. Uses the alpha of ``rgba`` (anti-aliased coverage: binary masks are
    biased by up to 0.14 px, CONVENTIONS §13), falling back to the hit mask."""
    exp = np.asarray(expected, dtype=np.float64)
    if exp.ndim != 2 or exp.shape[1] != 2:
        raise InvalidSceneError(f"expected: expected an (N, 2) array of pixel positions, got shape {exp.shape}")
    if result.rgba is not None:
        weight = result.rgba[..., 3].astype(np.float64)
    else:
        m = hit_mask(result)
        if m is None:
            raise InvalidSceneError("result: needs an 'rgb' output (alpha) or a depth/instance output")
        weight = m.astype(np.float64)
    h, w = weight.shape
    out = np.full(exp.shape, np.nan)
    for i, (u, v) in enumerate(exp):
        x0, x1 = max(int(round(u)) - window, 0), min(int(round(u)) + window + 1, w)
        y0, y1 = max(int(round(v)) - window, 0), min(int(round(v)) + window + 1, h)
        if x0 >= x1 or y0 >= y1:
            continue
        wt = weight[y0:y1, x0:x1]
        s = wt.sum()
        if s <= 0:
            continue
        ys, xs = np.mgrid[y0:y1, x0:x1]
        out[i] = (float((wt * xs).sum() / s), float((wt * ys).sum() / s))
    return out


# ---------------------------------------------------------------------------------------------------
# crosscheck
# ---------------------------------------------------------------------------------------------------
@dataclass
class CrosscheckReport:
    """Result of :func:`crosscheck`: ``results`` backend -> RenderResult, ``pairs`` (a, b) ->
    CompareReport (b is the reference), ``skipped`` backend -> reason, ``errors`` backend -> message of
    a failed render, ``notes`` free-form remarks (outputs dropped because a backend lacks them, ...)."""

    results: dict[str, RenderResult]
    pairs: dict[tuple[str, str], CompareReport]
    skipped: dict[str, str]
    errors: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    scene_name: str = "scene"
    #: backend -> ReferenceEstimate of its colour (``crosscheck(repeats=k)``, path tracers only)
    estimates: dict[str, Any] = field(default_factory=dict, repr=False)
    #: (a, b) -> ZTestResult of the two-sample test between two path tracers' estimates
    ztests: dict[tuple[str, str], Any] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Every pair passed its tier (and its statistical test, with ``repeats``), no available backend
        failed to render, and at least one pair was compared (nothing compared proves nothing)."""
        return (
            not self.errors
            and bool(self.pairs)
            and all(r.passed for r in self.pairs.values())
            and all(z.passed for z in self.ztests.values())
        )

    def summary(self) -> str:
        """Markdown report: settings, per-backend timings, skipped backends, pair verdicts and metrics."""
        lines = [f"## Crosscheck of {self.scene_name}: {'PASS' if self.passed else 'FAIL'}", ""]
        if self.settings:
            lines.append("Settings: " + ", ".join(f"`{k}={v}`" for k, v in self.settings.items()))
            lines.append("")
        lines += ["| backend | status | render time (s) |", "|---|---|---|"]
        for name, r in self.results.items():
            t = r.meta.get("timings", {}) if isinstance(r.meta, dict) else {}
            total = sum(v for v in t.values() if isinstance(v, (int, float)))
            lines.append(f"| {name} | rendered | {total:.2f} |")
        for name, why in self.skipped.items():
            lines.append(f"| {name} | skipped: {why} | |")
        for name, why in self.errors.items():
            lines.append(f"| {name} | ERROR: {why} | |")
        lines.append("")
        for n in self.notes:
            lines.append(f"- {n}")
        if self.notes:
            lines.append("")
        for (a, b), z in self.ztests.items():
            verdict = "consistent" if z.passed else "DIFFERENT"
            lines.append(
                f"- statistical test {a} vs {b} ({self.settings.get('repeats')} renders each): **{verdict}**; "
                f"{z.n_reject} pixel-channels and {z.n_tile_reject}/{z.n_tiles} tiles reject, "
                f"global p = {z.global_p:.3g}" + (f" ({'; '.join(z.reasons)})" if z.reasons else "")
            )
        if self.ztests:
            lines.append("")
        for rep in self.pairs.values():
            lines.append(rep.summary())
        return "\n".join(lines)

    def __repr__(self) -> str:
        pairs = ", ".join(f"{a}/{b}: {'PASS' if r.passed else 'FAIL'}" for (a, b), r in self.pairs.items())
        skipped = ", ".join(self.skipped) or "none"
        return f"CrosscheckReport({self.scene_name}: {pairs or 'no pairs'}; skipped: {skipped})"

    def contact_sheet(self, tile: int = 160) -> np.ndarray:
        """(H, W, 3) uint8 labelled sheet: one row per backend (colour over a checkerboard, depth, normal,
        albedo, instance ids) and one row per pair (the heat maps of every compared output, each tile
        marked ok/FAIL against the pair's tier). Tiles are scaled (nearest) to ``tile`` px wide."""
        from PIL import Image, ImageDraw

        rows: list[tuple[str, list[tuple[str, np.ndarray]]]] = []
        for name, r in self.results.items():
            row = []
            if r.rgba is not None:
                row.append(("rgb", _over_checker(r)))
            if r.depth is not None:
                row.append(("depth", np.repeat(depth_to_image(r.depth)[..., None], 3, axis=-1)))
            if r.normal is not None:
                row.append(("normal", np.round(np.clip(r.normal * 0.5 + 0.5, 0, 1) * 255).astype(np.uint8)))
            if r.albedo is not None:
                row.append(("albedo", np.round(linear_to_srgb(r.albedo) * 255).astype(np.uint8)))
            if r.instance is not None:
                row.append(("instance", instance_to_image(r.instance)))
            rows.append((name, row))
        for (a, b), rep in self.pairs.items():
            row = [
                (f"{out} diff: {'ok' if _output_ok(rep, out) else 'FAIL'}", img) for out, img in rep.diff_images.items()
            ]
            verdict = "PASS" if rep.passed else "FAIL"
            rows.append((f"{a}\nvs {b}\n{rep.tier}\n{verdict}", row))
        if not any(row for _, row in rows):
            return np.zeros((32, 32, 3), dtype=np.uint8)
        h0, w0 = next(img for _, row in rows for _, img in row).shape[:2]
        tw = max(int(tile), 16)
        th = max(int(round(h0 * tw / max(w0, 1))), 1)
        label_h, pad, head_w = 14, 4, 110
        ncols = max(len(row) for _, row in rows)
        width = head_w + ncols * (tw + pad) + pad
        height = len(rows) * (th + label_h + pad) + pad
        sheet = Image.new("RGB", (width, height), (255, 255, 255))
        draw = ImageDraw.Draw(sheet)
        for ri, (head, row) in enumerate(rows):
            y = pad + ri * (th + label_h + pad)
            colour = (180, 0, 0) if head.endswith("FAIL") else (0, 0, 0)
            draw.multiline_text((pad, y + label_h), head, fill=colour, spacing=2)
            for ci, (label, img) in enumerate(row):
                x = head_w + ci * (tw + pad)
                im = Image.fromarray(np.ascontiguousarray(img[..., :3])).resize((tw, th), Image.NEAREST)
                sheet.paste(im, (x, y + label_h))
                draw.text((x + 1, y + 1), label, fill=(180, 0, 0) if label.endswith("FAIL") else (0, 0, 0))
        return np.asarray(sheet)

    def save(self, folder: str | os.PathLike[str], name: str = "crosscheck") -> Path:
        """Write ``<name>.png`` (contact sheet), ``<name>.md`` (report) and per-pair diff folders, each file
        atomically with the usual file mode (:class:`~blendify_core.errors.OutputError` when one cannot be
        written)."""
        from PIL import Image

        from blendify_core._output import atomic_write, ensure_folder

        out = ensure_folder(folder, arg="folder")
        sheet = self.contact_sheet()
        atomic_write(out / f"{name}.png", lambda tmp: Image.fromarray(sheet).save(tmp, format="PNG"), arg="name")
        _write_text(out / f"{name}.md", f"![contact sheet]({name}.png)\n\n" + self.summary(), arg="name")
        for (a, b), rep in self.pairs.items():
            rep.save(out / f"{a}_vs_{b}")
        return out


def _write_text(path: Path, text: str, arg: str = "folder") -> None:
    """A report file, atomically (UTF-8)."""
    from blendify_core._output import atomic_write

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)

    atomic_write(path, write, arg=arg)


def _output_ok(rep: CompareReport, out: str) -> bool:
    return all(ok for o, _, _, _, _, ok in rep.checks if o == out)


def _over_checker(r: RenderResult) -> np.ndarray:
    """sRGB of a premultiplied render over a light checkerboard (so transparency is visible)."""
    rgba = r.rgba.astype(np.float64)  # type: ignore[union-attr]
    h, w = rgba.shape[:2]
    cb = ((np.indices((h, w)) // 4).sum(axis=0) % 2) * 0.15 + 0.6
    lin = rgba[..., :3] + (1 - rgba[..., 3:4]) * cb[..., None] ** 2.2
    return np.round(linear_to_srgb(lin) * 255).astype(np.uint8)


def crosscheck(
    scene: Any,
    backends: Sequence[str] = ("cycles", "mitsuba", "pyrender"),
    outputs: Sequence[str] = ("rgb", "depth", "normal", "albedo", "instance"),
    samples: int | None = 256,
    tier: str | Mapping[str, Mapping[str, float]] | None = None,
    seed: int = 0,
    backend_options: Mapping[str, Mapping[str, Any]] | None = None,
    scene_name: str = "scene",
    repeats: int = 1,
    **settings: Any,
) -> CrosscheckReport:
    """Render ``scene`` with each of ``backends`` and compare every pair.

    Comparable settings are forced: box pixel filter, no denoiser, no clamping, no adaptive sampling,
    seed ``seed``, ``samples`` samples per pixel; ``settings`` may override other RenderSettings fields
    (e.g. ``max_bounces``). ``backend_options``: per-backend options (``{"mitsuba": {"variant": ...}}``).
    ``tier``: None = per pair by :func:`choose_tier` (path tracer pair on delta lights and diffuse
    materials -> "pathtracer_delta", other path tracer pairs -> "pathtracer", with a rasteriser ->
    "raster"), or a tier name / dict for every pair. Unavailable backends are skipped with their reason;
    outputs a backend does not support are dropped for that backend (noted in ``report.notes``); a
    backend whose render raises is reported in ``report.errors`` (and the report does not pass).
    Pairs (a, b) follow the order of ``backends``; the later backend is the reference b.

    ``repeats`` (>= 2): each path tracer renders the scene ``repeats`` times with seeds ``seed``,
    ``seed + 1``, ...; its colour becomes the mean of the renders (geometry from the first), its mean and
    variance estimate go to ``report.estimates``, and every path-tracer pair also gets a two-sample
    statistical test (:meth:`ReferenceEstimate.compare`) in ``report.ztests``, which must pass too: are
    the two engines' expected images equal, given their noise?
    """
    from blendify_core.ir.scene import Scene
    from blendify_core.pipeline.backend import available_backends
    from blendify_core.pipeline.render import render

    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    if isinstance(backends, str):
        backends = (backends,)
    if not backends or len(set(backends)) != len(backends):
        raise InvalidSceneError(f"backends: expected a non-empty sequence of distinct names, got {backends!r}")
    forbidden = {"pixel_filter", "denoise", "clamp_direct", "clamp_indirect", "adaptive"} & set(settings)
    if forbidden:
        raise InvalidSceneError(
            f"crosscheck: {sorted(forbidden)} are fixed by crosscheck (box filter, no denoiser/clamping/adaptive)"
        )
    from blendify_core.pipeline.settings import _outputs

    outputs = _outputs(outputs if isinstance(outputs, str) else tuple(outputs))  # bad names: error up front
    backend_options = dict(backend_options or {})
    status = available_backends()
    results: dict[str, RenderResult] = {}
    skipped: dict[str, str] = {}
    errors: dict[str, str] = {}
    notes: list[str] = []
    if not isinstance(repeats, (int, np.integer)) or repeats < 1:
        raise InvalidSceneError(f"repeats: expected a positive integer, got {repeats!r}")
    fixed = dict(pixel_filter="box", denoise=False, clamp_direct=0.0, clamp_indirect=0.0, adaptive=False)
    estimates: dict[str, Any] = {}
    for name in backends:
        st = status.get(name)
        if st is None:
            skipped[name] = f"not registered (registered: {sorted(status)})"
            continue
        if not st.available:
            skipped[name] = st.reason or "unavailable"
            continue
        outs = list(outputs)
        while True:
            try:
                results[name] = render(
                    scene,
                    backend=name,
                    samples=samples,
                    seed=seed,
                    outputs=tuple(outs),
                    **fixed,
                    **settings,
                    **dict(backend_options.get(name, {})),
                )
                if repeats > 1 and is_path_tracer(name) and results[name].rgba is not None:
                    extra = [
                        render(
                            scene,
                            backend=name,
                            samples=samples,
                            seed=seed + i,
                            outputs=("rgb",),
                            **fixed,
                            **settings,
                            **dict(backend_options.get(name, {})),
                        ).rgba
                        for i in range(1, repeats)
                    ]
                    estimates[name] = _average_repeats(results[name], extra, samples)
                break
            except UnsupportedFeatureError as exc:
                feat = getattr(exc, "feature", None) or ""
                if feat.startswith("output.") and feat[7:] in outs and len(outs) > 1:
                    outs.remove(feat[7:])
                    notes.append(f"{name}: output {feat[7:]!r} unsupported, not compared ({exc})")
                    continue
                skipped[name] = f"unsupported: {exc}"
                break
            except BackendUnavailableError as exc:
                skipped[name] = str(exc)
                break
            except (RenderError, InvalidSceneError) as exc:
                errors[name] = f"{type(exc).__name__}: {exc}"
                break
    pairs: dict[tuple[str, str], CompareReport] = {}
    names = list(results)
    n_pt = sum(is_path_tracer(n) for n in names)
    if n_pt >= 1 and samples is not None and samples * max(repeats, 1) < 128 and not _delta_lights(scene):
        notes.append(
            f"samples={samples}: the colour tiers for area/sky light were measured at 256 spp; at fewer samples "
            "Monte-Carlo noise alone may fail them (use more samples, or repeats=k for the statistical test)"
        )
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            a, b = names[i], names[j]
            t = tier if tier is not None else choose_tier(a, b, scene)
            pairs[(a, b)] = compare(results[a], results[b], tier=t, names=(a, b))
    ztests = {(a, b): estimates[a].compare(estimates[b]) for (a, b) in pairs if a in estimates and b in estimates}
    used_settings = {"samples": samples, "seed": seed, **fixed, **settings}
    if repeats > 1:
        used_settings["repeats"] = repeats
    return CrosscheckReport(
        results=results,
        pairs=pairs,
        skipped=skipped,
        errors=errors,
        notes=notes,
        settings=used_settings,
        scene_name=scene_name,
        estimates=estimates,
        ztests=ztests,
    )


def _average_repeats(first: RenderResult, extra: list[Any], samples: int | None) -> Any:
    """Replace ``first.rgba`` by the mean of all repeats; return the ReferenceEstimate of the colour."""
    from blendify_core.evaluate.stats import ReferenceEstimate

    stack = [first.rgba] + [x for x in extra if x is not None]
    est = ReferenceEstimate.from_images([x[..., :3] for x in stack], int(samples or 1))
    first.rgba = np.mean(np.stack(stack), axis=0).astype(np.float32)
    first.meta["repeats"] = len(stack)
    return est


def crosscheck_main(argv: Sequence[str] | None = None) -> int:
    """``blendify crosscheck SCENE [-o FOLDER] [--backends ...] [--samples N] ...``: render a scene file
    with every available backend, write the contact sheet and the markdown report into FOLDER. Returns
    0 when every pair passed, 1 when one failed (or fewer than two backends could render), 2 on bad
    usage."""
    from blendify_core.ir.scene import Scene

    p = argparse.ArgumentParser(
        prog="blendify crosscheck",
        description="Render a scene file with several backends and compare them pairwise.",
    )
    p.add_argument("scene", help="scene file written by Scene.save (.npz)")
    p.add_argument("-o", "--output", default="crosscheck_out", help="folder for the sheet and report")
    p.add_argument("--backends", default="cycles,mitsuba,pyrender", help="comma-separated backend names")
    p.add_argument("--outputs", default="rgb,depth,normal,albedo,instance", help="comma-separated outputs")
    p.add_argument("--samples", type=int, default=256, help="samples per pixel (default 256)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tier", default=None, help=f"tier for every pair (default: per pair); one of {sorted(TIERS)}")
    p.add_argument("--max-bounces", type=int, default=None)
    p.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="render each path tracer N times (seeds seed..seed+N-1) and add a statistical test per pair",
    )
    try:
        args = p.parse_args(list(argv) if argv is not None else None)
    except SystemExit as exc:  # argparse exits on --help / errors; turn that into a return code
        return int(exc.code or 0)
    try:
        scene = Scene.load(args.scene)
        extra = {} if args.max_bounces is None else {"max_bounces": args.max_bounces}
        t0 = time.perf_counter()
        report = crosscheck(
            scene,
            backends=tuple(b.strip() for b in args.backends.split(",") if b.strip()),
            outputs=tuple(o.strip() for o in args.outputs.split(",") if o.strip()),
            samples=args.samples,
            seed=args.seed,
            tier=args.tier,
            scene_name=Path(args.scene).name,
            repeats=args.repeats,
            **extra,
        )
        folder = report.save(args.output)
    except (InvalidSceneError, FileNotFoundError, BackendUnavailableError) as exc:
        sys.stderr.write(f"blendify crosscheck: {exc}\n")
        return 2
    sys.stdout.write(f"{report!r}\n")
    if not report.pairs:
        sys.stderr.write(
            "blendify crosscheck: fewer than two backends rendered the scene, nothing was compared "
            f"(skipped: {report.skipped or 'none'}; errors: {report.errors or 'none'})\n"
        )
    elapsed = time.perf_counter() - t0
    sys.stdout.write(f"wrote {folder / 'crosscheck.png'} and {folder / 'crosscheck.md'} ({elapsed:.1f} s)\n")
    return 0 if report.passed and report.pairs else 1
