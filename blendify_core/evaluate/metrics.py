"""Per-output metrics between two results (colour, depth, masks, normals, instance ids, albedo).

Metrics (``report.metrics[output][metric]``):

- ``rgb`` (premultiplied linear colour, over pixels with alpha > 0 in both): ``mean_rel_error`` and
  ``max_rel_error`` of ``|a - r| / max(|r|, 0.02)`` per channel (Mitsuba's error with its 2e-2 floor),
  ``mean_rel_error_interior`` (the same over interior pixels, see below), ``rel_mse`` = mean
  ``(a - r)^2 / (r^2 + 0.01)``, ``mean_ratio`` (sum a / sum r: a units check) and ``ratio_error`` =
  ``|mean_ratio - 1|``, ``alpha_mean_abs_error`` (all pixels), and on the sRGB-encoded images composited
  over black: ``ssim`` (scikit-image), ``flip`` (NVIDIA FLIP, LDR, mean error) and ``psnr`` (dB).
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
  ``n_disagree``, ``n_tie`` (different ids at the same depth on the border of the same two objects in both
  results: a pixel-centre ray through a seam, which either engine may break; counted as agreeing).
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

import math
from collections.abc import Sequence

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.pipeline.result import RenderResult

__all__ = [
    "COMPARED_OUTPUTS",
    "HIGHER_IS_BETTER",
    "REL_FLOOR",
    "alpha_centroids",
    "heat_map",
    "hit_mask",
    "interior_mask",
]

#: the error floor of the relative error (Mitsuba's test_ad_integrators uses 2e-2)
REL_FLOOR = 0.02
#: backends that are unbiased path tracers (the others are rasterisers)
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


def _instance_metrics(
    a: RenderResult, b: RenderResult, depth_tol: float | None = None
) -> tuple[dict[str, float], np.ndarray, str]:
    """Instance agreement where both hit (ids matched by tag). A pixel whose ids differ is a *tie*, not a
    disagreement, when the pixel-centre ray met two objects at the same place: both results have depth, the
    depths agree within ``depth_tol`` (relative; the tier's depth threshold), and each result's id appears in
    the other's 3x3 neighbourhood (the pixel lies on the border between the same two objects in both, e.g. a
    seam where two walls meet exactly through the pixel centre). ``agreement`` counts ties as agreeing;
    ``n_disagree`` counts the rest, ``n_tie`` the ties. Without depth or ``depth_tol`` nothing is a tie."""
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
    tie = _instance_ties(ga, gb, a.depth, b.depth, depth_tol, both & ~agree)
    n = int(both.sum())
    n_tie = int(tie.sum())
    m = {
        "agreement": float((agree.sum() + n_tie) / n) if n else 1.0,
        "n_disagree": float(n - agree.sum() - n_tie),
        "n_tie": float(n_tie),
        "n_both": float(n),
    }
    img = np.zeros(ga.shape + (3,), dtype=np.uint8)
    img[agree] = (110, 110, 110)
    img[both & ~agree] = (255, 40, 40)
    img[tie] = (255, 200, 0)
    return m, img, "grey same instance, red different instance, yellow a tie (two objects at the same depth)"


def _instance_ties(
    ga: np.ndarray,
    gb: np.ndarray,
    da: np.ndarray | None,
    db: np.ndarray | None,
    depth_tol: float | None,
    differ: np.ndarray,
) -> np.ndarray:
    """Of the pixels ``differ``, those that are ties (see :func:`_instance_metrics`)."""
    if da is None or db is None or depth_tol is None or not differ.any():
        return np.zeros(ga.shape, dtype=bool)
    za, zb = da.astype(np.float64), db.astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        same_depth = np.isfinite(za) & np.isfinite(zb) & (np.abs(za - zb) <= depth_tol * np.abs(zb))
    a_near_b = np.zeros(ga.shape, dtype=bool)  # a's id among b's neighbours
    b_near_a = np.zeros(ga.shape, dtype=bool)
    for nb_a, nb_b in zip(_neighbours(ga), _neighbours(gb), strict=True):
        a_near_b |= nb_b == ga
        b_near_a |= nb_a == gb
    return differ & same_depth & a_near_b & b_near_a


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


def _backend_of(result: RenderResult) -> str | None:
    name = result.meta.get("backend") if isinstance(result.meta, dict) else None
    return str(name) if name else None


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
