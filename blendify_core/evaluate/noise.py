"""The noise-aware colour verdict between two path-traced images: agree within noise, fail on a bias.

A path tracer's image is a random estimate of the expected image. Two correct engines (or one engine
with two seeds) give different pictures; a fixed tolerance on their difference is either too tight for
the noise or too loose to see a real bias. Here each image comes with the variance of its own estimate,
measured from K >= 2 independent passes (the samples split into K renders with different seeds; see
:func:`estimate_from_passes` and ``RenderResult.rgb_var``), and the verdict asks a statistical question:
*is the difference between the two expected images larger than a small practical margin?*

For every block of pixels (``tile`` x ``tile`` tiles, and the whole image) and every colour channel:

- ``D`` = sum of the per-pixel differences of the two means, ``S`` = sum of their average (the block's
  brightness), ``V`` = sum of both per-pixel variances of the means (the variance of ``D``);
- the block *rejects* when ``(|D| - margin) / sqrt(V)`` exceeds the Student-t critical value with the
  block's Welch-Satterthwaite degrees of freedom (``V**2 / sum(v_i**2 / dof_i)``: K - 1 per pixel, more
  for a block pooling many pixels), Šidák-corrected over the blocks and channels of its family;
- ``margin = rel * max(|S|, floor * n_pixels * image_mean)`` with ``rel = margin_global`` for the whole
  image and ``margin_tile`` for a tile; ``image_mean`` is the mean pixel value over *all* channels, so
  ``floor`` keeps dark tiles and dark channels (the red of a green object) from being held to a zero
  margin, where the tiny absolute differences of two engines' specular lobes would fail. The reported
  relative differences use the same base: ``D / max(|S|, floor * n_pixels * image_mean)``.

The two families (tiles, global) get ``alpha / 2`` each, so when the two engines' expected images are
equal the probability of a false failure is at most ``alpha`` (the margin only makes the test more
lenient); benchmarks/crosscheck_calibration.py measures it on real renders and measures how often
injected defects (a 1 % brightness bias, a 0.5 px shift, a wrong colour space, a mirrored texture) are
caught. Blocks, not single pixels: a per-pixel test at Šidák levels with K - 1 = 3 degrees of freedom
has almost no power, while a bias spread over a block adds up linearly in ``D`` and its noise only as
the square root. Channels are tested separately because the channels of one pixel share their noise
(a white light on a grey surface). Pixels are treated as independent: a sampler that correlates
neighbouring pixels negatively (Cycles) only makes the block tests conservative.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.evaluate.stats import sidak_alpha
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.render import render as bf_render
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import Float64Array

__all__ = ["NoiseTest", "noise_test", "estimate_from_passes", "render_passes", "combine_passes", "DEFAULT_PASSES"]

#: family-wise false-failure level of :func:`noise_test` (calibrated in docs/crosscheck.md)
DEFAULT_ALPHA = 0.01
#: tile size of the block test (pixels)
DEFAULT_TILE = 8
#: fraction of the image's mean brightness below which a tile's margin stops shrinking
DEFAULT_FLOOR = 0.1


@dataclass
class NoiseTest:
    """Outcome of :func:`noise_test` (a is compared with the reference b).

    ``global_rel_diff``: per channel, (sum a - sum b) relative to the channel's brightness (the mean of both
    sums; at least ``floor`` x the image's mean brightness over all channels); ``global_excess``: the
    largest per-channel statistic ``(|D| - margin) / sqrt(V)`` of the whole image; ``global_crit``: its critical value;
    ``tile_excess`` / ``tile_crit``: (tiles_y, tiles_x, C) the same per tile; ``n_tile_reject``: tiles where
    any channel rejects; ``reasons``: readable failures.
    """

    passed: bool
    alpha: float
    tile: int
    margin_global: float
    margin_tile: float
    global_rel_diff: np.ndarray
    global_excess: float
    global_crit: float
    tile_excess: np.ndarray = field(repr=False)
    tile_crit: np.ndarray = field(repr=False)
    n_tile_reject: int = 0
    reasons: list[str] = field(default_factory=list)

    @property
    def n_tiles(self) -> int:
        return int(self.tile_excess.shape[0] * self.tile_excess.shape[1])

    @property
    def tile_reject(self) -> np.ndarray:
        """(tiles_y, tiles_x) bool: tiles where a channel rejects."""
        out: np.ndarray = (self.tile_excess > self.tile_crit).any(axis=-1)
        return out

    def reject_map(self, height: int, width: int) -> np.ndarray:
        """(height, width) bool: pixels of rejecting tiles."""
        t = self.tile_reject
        return t[np.arange(height)[:, None] // self.tile, np.arange(width)[None, :] // self.tile]

    def __repr__(self) -> str:
        verdict = "PASS" if self.passed else "FAIL"
        rel = ", ".join(f"{x:+.3%}" for x in np.atleast_1d(self.global_rel_diff))
        return (
            f"NoiseTest({verdict}, tiles rejected {self.n_tile_reject}/{self.n_tiles}, global excess "
            f"{self.global_excess:.2f} (critical {self.global_crit:.2f}), global rel diff [{rel}])"
        )


def estimate_from_passes(passes: Sequence[ArrayLike] | ArrayLike) -> tuple[Float64Array, Float64Array, int]:
    """Mean image, per-pixel variance *of that mean*, and degrees of freedom (K - 1) from K >= 2
    independent passes with equal sample counts ((K, H, W[, C]) or a sequence of images)."""
    stack = np.asarray(passes, dtype=np.float64)
    if stack.ndim not in (3, 4) or stack.shape[0] < 2:
        raise InvalidSceneError(
            f"passes: expected K >= 2 independent images stacked as (K, H, W[, C]), got shape {stack.shape}"
        )
    if not np.all(np.isfinite(stack)):
        raise InvalidSceneError("passes: contain non-finite values (NaN or inf)")
    k = stack.shape[0]
    return stack.mean(axis=0), stack.var(axis=0, ddof=1) / k, k - 1


def _image(name: str, value: ArrayLike) -> Float64Array:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3:
        raise InvalidSceneError(f"{name}: expected an (H, W) or (H, W, C) image, got shape {np.shape(value)}")
    if not np.all(np.isfinite(a)):
        raise InvalidSceneError(f"{name}: contains non-finite values (NaN or inf)")
    return a


def _variance(name: str, value: ArrayLike, shape: tuple[int, ...]) -> Float64Array:
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == 2:
        v = v[..., None]
    try:
        out: Float64Array = np.broadcast_to(v, shape)
    except ValueError:
        raise InvalidSceneError(f"{name}: shape {np.shape(value)} does not match the image {shape}") from None
    if not np.all(np.isfinite(out)) or np.any(out < 0):
        raise InvalidSceneError(f"{name}: expected finite non-negative variances")
    return out


def _block_sums(x: Float64Array, tile: int) -> Float64Array:
    """(tiles_y, tiles_x, C) sums of ``x`` (H, W, C) over ``tile`` x ``tile`` blocks (partial at the edges)."""
    h, w, c = x.shape
    th, tw = -(-h // tile), -(-w // tile)
    pad = np.zeros((th * tile, tw * tile, c))
    pad[:h, :w] = x
    out: Float64Array = pad.reshape(th, tile, tw, tile, c).sum(axis=(1, 3))
    return out


def _excess(
    d: Float64Array,
    s: Float64Array,
    v: Float64Array,
    q: Float64Array,
    n_px: Float64Array,
    rel: float,
    floor: float,
    image_mean: Float64Array,
) -> tuple[Float64Array, Float64Array]:
    """(|D| - margin) / sqrt(V) per block and the blocks' Welch-Satterthwaite degrees of freedom."""
    margin = rel * _base(s, n_px, floor, image_mean)
    gap = np.abs(d) - margin
    with np.errstate(divide="ignore", invalid="ignore"):
        sd = np.sqrt(v)
        # V = 0 (both images noise-free there): any difference beyond the margin is certain
        z = np.where(
            sd > 0, gap / np.where(sd > 0, sd, 1.0), np.where(gap > 1e-9 * (np.abs(s) + 1e-30), np.inf, -np.inf)
        )
        dof = np.where(q > 0, v * v / np.where(q > 0, q, 1.0), np.inf)
    return z, dof


def _base(s: Float64Array, n_px: Float64Array, floor: float, image_mean: Float64Array) -> Float64Array:
    """What a block's margin and relative difference are relative to: its brightness, at least ``floor``
    times the image's mean brightness (over all channels) per pixel."""
    out: Float64Array = np.maximum(np.abs(s), floor * n_px * image_mean)
    return out


def _critical(alpha_one: float, dof: Float64Array) -> Float64Array:
    """Two-sided Student-t critical values at level ``alpha_one`` (normal where dof is infinite)."""
    from scipy import stats

    finite = np.isfinite(dof)
    out = np.full(dof.shape, float(stats.norm.isf(alpha_one / 2.0)))
    if finite.any():
        out[finite] = stats.t.isf(alpha_one / 2.0, np.maximum(dof[finite], 1.0))
    return out


def noise_test(
    mean_a: ArrayLike,
    var_a: ArrayLike,
    dof_a: float,
    mean_b: ArrayLike,
    var_b: ArrayLike,
    dof_b: float,
    *,
    margin_global: float = 0.0025,
    margin_tile: float = 0.02,
    alpha: float = DEFAULT_ALPHA,
    tile: int = DEFAULT_TILE,
    floor: float = DEFAULT_FLOOR,
    mask: ArrayLike | None = None,
) -> NoiseTest:
    """Do two noisy images have the same expected value, up to a practical margin? See the module docstring.

    ``mean_*``: the images (H, W[, C]); ``var_*``: the variance of each image's pixels as estimates of the
    expected image (``RenderResult.rgb_var``; 0 for a noise-free image); ``dof_*``: the degrees of freedom
    of those variances (K - 1 for K passes; ``inf`` for a known variance). ``margin_global`` /
    ``margin_tile``: relative differences that count as agreement for the whole image / a tile.
    ``mask``: (H, W) bool, pixels to include (default all).
    """
    ma, mb = _image("mean_a", mean_a), _image("mean_b", mean_b)
    if ma.shape != mb.shape:
        raise InvalidSceneError(f"mean_b: shape {mb.shape} does not match mean_a {ma.shape}")
    va, vb = _variance("var_a", var_a, ma.shape), _variance("var_b", var_b, ma.shape)
    for name, dof in (("dof_a", dof_a), ("dof_b", dof_b)):
        if not (isinstance(dof, (int, float, np.integer, np.floating)) and dof > 0):
            raise InvalidSceneError(f"{name}: expected a positive number of degrees of freedom (K - 1), got {dof!r}")
    if not (0.0 < alpha < 1.0):
        raise InvalidSceneError(f"alpha: expected a significance level in (0, 1), got {alpha!r}")
    if not isinstance(tile, (int, np.integer)) or tile < 1:
        raise InvalidSceneError(f"tile: expected a positive integer, got {tile!r}")
    for name, m in (("margin_global", margin_global), ("margin_tile", margin_tile), ("floor", floor)):
        if not (isinstance(m, (int, float)) and 0.0 <= m < np.inf):
            raise InvalidSceneError(f"{name}: expected a non-negative number, got {m!r}")
    keep = np.ones(ma.shape[:2], dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if keep.shape != ma.shape[:2]:
        raise InvalidSceneError(f"mask: shape {keep.shape} does not match the image {ma.shape[:2]}")
    w = keep[..., None].astype(np.float64)
    d = (ma - mb) * w
    s = 0.5 * (ma + mb) * w
    v = (va + vb) * w
    # Satterthwaite: sum of v_i^2 / dof_i (dof inf -> 0)
    q = (va * va / float(dof_a) + vb * vb / float(dof_b)) * w
    n_px = np.broadcast_to(w, ma.shape)
    n_total = max(float(keep.sum()), 1.0)
    image_mean = np.full(ma.shape[2], float(np.abs(s.sum(axis=(0, 1))).mean()) / n_total)
    a_family = alpha / 2.0
    c = ma.shape[2]

    tz, tdof = _excess(
        _block_sums(d, tile),
        _block_sums(s, tile),
        _block_sums(v, tile),
        _block_sums(q, tile),
        _block_sums(n_px, tile),
        margin_tile,
        floor,
        image_mean,
    )
    n_blocks = int(_block_sums(n_px, tile)[..., 0].astype(bool).sum()) * c
    tcrit = _critical(sidak_alpha(a_family, max(n_blocks, 1)), tdof)
    n_tile_reject = int((tz > tcrit).any(axis=-1).sum())

    sums = [x.sum(axis=(0, 1)) for x in (d, s, v, q, n_px)]
    gz, gdof = _excess(sums[0], sums[1], sums[2], sums[3], sums[4], margin_global, floor, image_mean)
    gcrit = _critical(sidak_alpha(a_family, c), gdof)
    worst = int(np.argmax(gz - gcrit))
    base = _base(sums[1], sums[4], floor, image_mean)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(base > 0, sums[0] / np.where(base > 0, base, 1.0), 0.0)
    reasons = []
    if n_tile_reject:
        reasons.append(
            f"{n_tile_reject} of {tz.shape[0] * tz.shape[1]} {tile}x{tile} tiles differ by more than "
            f"{margin_tile:.1%} beyond their noise (level {alpha / 2:g}, Šidák over {n_blocks} tile-channels)"
        )
    global_bad = bool((gz > gcrit).any())
    if global_bad:
        reasons.append(
            f"the whole image differs by {rel[worst]:+.2%} in channel {worst}, more than the {margin_global:.1%} "
            f"margin beyond its noise (excess {gz[worst]:.2f} > {gcrit[worst]:.2f})"
        )
    return NoiseTest(
        passed=not reasons,
        alpha=alpha,
        tile=int(tile),
        margin_global=float(margin_global),
        margin_tile=float(margin_tile),
        global_rel_diff=rel,
        global_excess=float(gz[worst]),
        global_crit=float(gcrit[worst]),
        tile_excess=tz,
        tile_crit=tcrit,
        n_tile_reject=n_tile_reject,
        reasons=reasons,
    )


#: default number of independent passes a path-traced render is split into for the noise estimate
DEFAULT_PASSES = 4


def pass_samples(samples: int | None, passes: int) -> int | None:
    """Samples per pass when ``samples`` are split into ``passes`` passes (at least 1; None stays None)."""
    return None if samples is None else max(1, -(-int(samples) // int(passes)))


def combine_passes(first: RenderResult, extra: Sequence[RenderResult]) -> RenderResult:
    """Make ``first`` (a pass with every output) the mean of itself and the ``extra`` passes (colour
    only; different seeds, same sample count): its ``rgba`` becomes their mean, ``rgb_var`` the
    variance of that mean per pixel-channel, ``meta["passes"]`` K and ``meta["samples"]`` the total.
    Geometric outputs stay those of the first pass."""
    colours = [first.rgba] + [r.rgba for r in extra]
    if any(c is None for c in colours):
        raise InvalidSceneError("passes: every pass needs the 'rgb' output")
    stack = np.stack([np.asarray(c, dtype=np.float64) for c in colours if c is not None])
    if len(stack) >= 2:
        first.rgba = stack.mean(axis=0).astype(np.float32)
        first.rgb_var = (stack[..., :3].var(axis=0, ddof=1) / len(stack)).astype(np.float32)
    first.meta["passes"] = len(stack)
    per_pass = first.meta.get("samples")
    if isinstance(per_pass, (int, np.integer)):
        first.meta["samples"] = int(per_pass) * len(stack)
    return first


def render_passes(
    scene: Scene,
    backend: str | None = None,
    samples: int | None = 256,
    passes: int = DEFAULT_PASSES,
    seed: int = 0,
    outputs: str | Sequence[str] = ("rgb",),
    **kwargs: Any,
) -> RenderResult:
    """``bf.render`` with the ``samples`` split into ``passes`` independent passes (seeds ``seed``,
    ``seed + 1``, ...) for a path tracer: the result's colour is their mean and ``rgb_var`` its variance,
    so :func:`~blendify_core.compare` between two such results gives the noise-aware verdict. A raster
    backend renders once (``rgb_var`` None: its error is bias, not noise)."""
    if not isinstance(passes, (int, np.integer)) or passes < 2:
        raise InvalidSceneError(f"passes: expected an integer >= 2 independent passes, got {passes!r}")
    first = bf_render(
        scene, backend=backend, samples=pass_samples(samples, passes), seed=seed, outputs=outputs, **kwargs
    )
    if not first.meta.get("path_tracer") or first.rgba is None:
        return first
    extra = [
        bf_render(
            scene, backend=backend, samples=pass_samples(samples, passes), seed=seed + i, outputs=("rgb",), **kwargs
        )
        for i in range(1, int(passes))
    ]
    return combine_passes(first, extra)
