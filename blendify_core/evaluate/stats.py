"""Statistical comparison of path-traced images: a reference mean + variance and a per-pixel Z-test.

A path tracer's pixel is the mean of ``n`` random samples, so two correct renders of one scene differ by
noise. Comparing them with a fixed tolerance is either flaky (tolerance too tight for the noise) or blind
(tolerance loose enough to hide a real bias). The test here follows Mitsuba 3's own render tests
(``src/render/tests/test_renders.py``): the reference is a mean image plus a per-sample variance image;
each pixel-channel of the tested image gets a Z statistic ``(image - ref_mean) / sqrt(var / n_image)``;
the significance level is Šidák-corrected for the number of pixel-channels,
``alpha_1 = 1 - (1 - alpha) ** (1 / n_tests)``; the reference variance is clamped to ``>= var_floor``
(Mitsuba: 1e-4) so constant pixels do not make the statistic explode.

Two rules decide the verdict (``rule=``):

- ``"familywise"`` (the default, stricter and calibrated): the image passes when *every* pixel-channel
  accepts at the Šidák-corrected level. Under the null hypothesis (same distribution) the probability of
  a false failure is ``alpha`` (0.01), independent of the image size; ``tests/core/test_compare.py``
  measures it.
- ``"mitsuba"``: passes when at least ``min_accept_fraction`` (99.75 %) of pixel-channels accept, as
  Mitsuba does; tolerates a few heavy-tailed pixels (fireflies), but its false-failure rate is not
  ``alpha`` (it is far lower) and it cannot see a bias confined to < 0.25 % of the pixels.

A per-pixel test cannot see a small *global* bias hidden in per-pixel noise (a 2 % bias at 5 % per-pixel
noise moves each Z by 0.4 while the Šidák threshold is ~5). So the test also aggregates, per colour
channel: the differences and their variances are summed over ``tile`` x ``tile`` squares and over the
whole image (normal tests of the tile / image means, Šidák-corrected over tiles x channels and over the
channels); they must accept too. That is what makes "a 2 % bias fails" true at realistic noise levels
while the false-failure rate stays ``alpha``: the pixel, tile and global families get ``alpha / 3`` each
(Bonferroni across the three). Design notes, measured on real renders: summing per-pixel statistics
instead (Stouffer) is not calibrated at low sample counts (per-pixel means are skewed and their K-render
variance estimates correlate with them: 2 false tile rejections in 8 Mitsuba renders at 8 spp); summing
the channels of a pixel understates the variance (a white light on a grey surface gives the same noise in
R, G and B); a sampler that correlates pixels negatively (Cycles: its image mean varies ~25x less than
independent pixels would give) only makes the aggregates conservative.

When the reference variance is *estimated* from K independent renders (:func:`estimate_reference`) the
statistic follows a Student t distribution with K - 1 degrees of freedom, not a normal one; using the
normal tail there would give many false failures at Šidák levels (t tails are much heavier), so the test
uses the exact t distribution (``dof=``) and includes the reference mean's own variance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.evaluate.progress import progress_bar
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool
from blendify_core.pipeline.render import render as bf_render
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import Float64Array

__all__ = ["ZTestResult", "ReferenceEstimate", "z_test", "estimate_reference", "sidak_alpha"]


def sidak_alpha(alpha: float, n_tests: int) -> float:
    """Per-test level so that ``n_tests`` independent tests have family-wise error ``alpha`` (Šidák)."""
    if not (0.0 < alpha < 1.0):
        raise InvalidSceneError(f"alpha: expected a significance level in (0, 1), got {alpha!r}")
    n = max(int(n_tests), 1)
    return float(-np.expm1(np.log1p(-alpha) / n))


@dataclass
class ZTestResult:
    """Outcome of :func:`z_test`.

    ``p_values``: per pixel-channel two-sided p-values (shape of the image); ``z``: the statistics;
    ``accept_fraction``: fraction of pixel-channels accepted at ``alpha_pixel``; ``tile_p``: (tiles_y,
    tiles_x, C) p-values of the tile-mean tests; ``n_tile_reject``: tiles where any channel rejects;
    ``global_p``: the smallest per-channel p-value of the whole-image mean test; ``passed``.
    """

    passed: bool
    rule: str
    alpha: float
    alpha_pixel: float
    alpha_tile: float
    accept_fraction: float
    n_reject: int
    n_tests: int
    global_p: float
    tile_p: np.ndarray
    n_tile_reject: int
    p_values: np.ndarray = field(repr=False)
    z: np.ndarray = field(repr=False)
    reasons: list[str] = field(default_factory=list)

    @property
    def n_tiles(self) -> int:
        """Number of aggregation tiles (each tested per channel)."""
        return int(self.tile_p.shape[0] * self.tile_p.shape[1]) if self.tile_p.ndim >= 2 else int(self.tile_p.size)

    def reject_map(self) -> np.ndarray:
        """(H, W) bool: pixels where any channel rejected the null hypothesis."""
        r = self.p_values <= self.alpha_pixel
        return r.any(axis=-1) if r.ndim == 3 else r

    def __repr__(self) -> str:
        verdict = "PASS" if self.passed else "FAIL"
        return (
            f"ZTestResult({verdict}, rule={self.rule!r}, accepted={self.accept_fraction:.4%} of {self.n_tests}, "
            f"rejected={self.n_reject}, tiles rejected={self.n_tile_reject}/{self.n_tiles}, "
            f"global p={self.global_p:.3g})"
        )


def _as_image(name: str, value: ArrayLike) -> Float64Array:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim not in (2, 3):
        raise InvalidSceneError(f"{name}: expected an (H, W) or (H, W, C) image, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidSceneError(f"{name}: contains non-finite values (NaN or inf)")
    return a


def _two_sided_p(z: np.ndarray, dof: float | None) -> np.ndarray:
    from scipy import stats

    if dof is None or not np.isfinite(dof):
        return 2.0 * stats.norm.sf(np.abs(z))
    return 2.0 * stats.t.sf(np.abs(z), dof)


def z_test(
    image: ArrayLike,
    ref_mean: ArrayLike,
    ref_var: ArrayLike,
    n_samples_image: int,
    *,
    ref_mean_var: ArrayLike = 0.0,
    dof: float | None = None,
    alpha: float = 0.01,
    var_floor: float = 1e-4,
    rule: str = "familywise",
    min_accept_fraction: float = 0.9975,
    tile: int = 8,
    aggregate: bool = True,
) -> ZTestResult:
    """Per-pixel Z-test of ``image`` (a mean of ``n_samples_image`` samples per pixel) against a reference.

    ``ref_mean``: the reference mean image; ``ref_var``: the per-*sample* variance image (the variance of
    one sample's value, as Mitsuba stores it; clamped to ``>= var_floor``); ``ref_mean_var``: the variance
    of the reference mean itself (0 for a converged reference; :class:`ReferenceEstimate` fills it in);
    ``dof``: degrees of freedom of the variance estimate (None = known variance, normal distribution).
    ``rule``: "familywise" (every pixel-channel must accept; calibrated false-failure rate ``alpha``) or
    "mitsuba" (>= ``min_accept_fraction`` must accept). ``aggregate``: also test tile sums (``tile`` x
    ``tile`` pixels, all channels) and the global sum of normal scores (catches small global biases).
    See the module docstring for the reasoning.
    """
    img = _as_image("image", image)
    mean = _as_image("ref_mean", ref_mean)
    if mean.shape != img.shape:
        raise InvalidSceneError(f"ref_mean: shape {mean.shape} does not match image shape {img.shape}")
    var = np.broadcast_to(np.asarray(ref_var, dtype=np.float64), img.shape)
    mvar = np.broadcast_to(np.asarray(ref_mean_var, dtype=np.float64), img.shape)
    if np.any(~np.isfinite(var)) or np.any(var < 0) or np.any(~np.isfinite(mvar)) or np.any(mvar < 0):
        raise InvalidSceneError("ref_var / ref_mean_var: expected finite non-negative variances")
    if not isinstance(n_samples_image, (int, np.integer)) or n_samples_image < 1:
        raise InvalidSceneError(f"n_samples_image: expected a positive integer, got {n_samples_image!r}")
    if rule not in ("familywise", "mitsuba"):
        raise InvalidSceneError(f"rule: expected 'familywise' or 'mitsuba', got {rule!r}")
    if not (0.0 < min_accept_fraction <= 1.0):
        raise InvalidSceneError(f"min_accept_fraction: expected a fraction in (0, 1], got {min_accept_fraction!r}")
    if dof is not None and not dof > 0:
        raise InvalidSceneError(f"dof: expected a positive number of degrees of freedom or None, got {dof!r}")
    if not isinstance(tile, (int, np.integer)) or tile < 1:
        raise InvalidSceneError(f"tile: expected a positive integer, got {tile!r}")

    sd = np.sqrt(np.maximum(var, var_floor) / n_samples_image + mvar)
    diff = img - mean
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(sd > 0, diff / np.where(sd > 0, sd, 1.0), np.where(diff == 0, 0.0, np.inf * np.sign(diff)))
    p = _two_sided_p(z, dof)
    n_tests = int(z.size)
    aggregate = as_bool("aggregate", aggregate)
    families = 3 if aggregate else 1
    a_family = alpha / families
    a_pixel = sidak_alpha(a_family, n_tests)
    accept = p > a_pixel
    accept_fraction = float(accept.mean())
    n_reject = int(n_tests - accept.sum())
    reasons = []
    if rule == "familywise":
        ok_pixels = n_reject == 0
        if not ok_pixels:
            reasons.append(f"{n_reject} pixel-channel(s) reject at the Šidák level {a_pixel:.3g}")
    else:
        ok_pixels = accept_fraction >= min_accept_fraction
        if not ok_pixels:
            reasons.append(f"only {accept_fraction:.4%} of pixel-channels accept (need {min_accept_fraction:.2%})")

    tile_p = np.ones((1, 1))
    n_tile_reject = 0
    global_p = 1.0
    a_tile = a_pixel
    ok_aggregate = True
    if aggregate:
        from scipy import stats

        # Aggregates sum the raw differences and their variances over a tile (or the image): the sum of
        # ~hundreds of independent differences is normal (central limit theorem) and its variance estimate
        # pools hundreds of per-pixel estimates, so this stays calibrated when per-pixel statistics are
        # skewed (few samples of a heavy-tailed integrand) and the variances come from only K renders.
        # per channel: colour channels of one pixel are strongly correlated (a white light on a grey
        # surface gives identical noise in R, G and B), so summing them would understate the variance
        d3 = diff if diff.ndim == 3 else diff[..., None]
        v3 = sd**2 if sd.ndim == 3 else (sd**2)[..., None]
        h, w, c = d3.shape
        th, tw = -(-h // tile), -(-w // tile)
        ys = np.arange(h) // tile
        xs = np.arange(w) // tile
        dsum = np.zeros((th, tw, c))
        vsum = np.zeros((th, tw, c))
        np.add.at(dsum, (ys[:, None], xs[None, :]), d3)
        np.add.at(vsum, (ys[:, None], xs[None, :]), v3)
        with np.errstate(divide="ignore", invalid="ignore"):
            tile_z = np.where(vsum > 0, dsum / np.sqrt(np.where(vsum > 0, vsum, 1.0)), np.where(dsum == 0, 0.0, np.inf))
        tile_p = 2.0 * stats.norm.sf(np.abs(tile_z))
        a_tile = sidak_alpha(a_family, tile_p.size)
        n_tile_reject = int((tile_p <= a_tile).any(axis=-1).sum())
        vtot = v3.sum(axis=(0, 1))
        dtot = d3.sum(axis=(0, 1))
        with np.errstate(divide="ignore", invalid="ignore"):
            gz = np.where(vtot > 0, dtot / np.sqrt(np.where(vtot > 0, vtot, 1.0)), np.where(dtot == 0, 0.0, np.inf))
        gp = 2.0 * stats.norm.sf(np.abs(gz))
        a_global = sidak_alpha(a_family, c)
        global_p = float(gp.min())
        global_z = float(gz[int(np.argmin(gp))])
        if n_tile_reject:
            reasons.append(f"{n_tile_reject} of {th * tw} {tile}x{tile} tiles reject at {a_tile:.3g}")
        if global_p <= a_global:
            reasons.append(f"the whole-image mean differs (global z = {global_z:.2f}, p = {global_p:.3g})")
        ok_aggregate = n_tile_reject == 0 and global_p > a_global
    return ZTestResult(
        passed=bool(ok_pixels and ok_aggregate),
        rule=rule,
        alpha=alpha,
        alpha_pixel=a_pixel,
        alpha_tile=a_tile,
        accept_fraction=accept_fraction,
        n_reject=n_reject,
        n_tests=n_tests,
        global_p=global_p,
        tile_p=tile_p,
        n_tile_reject=n_tile_reject,
        p_values=p,
        z=z,
        reasons=reasons,
    )


@dataclass
class ReferenceEstimate:
    """Mean and per-sample variance of a noisy image, estimated from ``k`` independent renders of
    ``n_samples`` samples per pixel each (see :func:`estimate_reference`)."""

    mean: np.ndarray
    var: np.ndarray  #: per-sample variance (= variance of one render x n_samples)
    n_samples: int
    k: int
    seeds: list[int] = field(default_factory=list)

    @property
    def dof(self) -> int:
        return self.k - 1

    @property
    def mean_var(self) -> np.ndarray:
        """Variance of :attr:`mean` itself."""
        return self.var / (self.n_samples * self.k)

    @classmethod
    def from_images(cls, images: Sequence[ArrayLike], n_samples: int, seeds: Sequence[int] = ()) -> ReferenceEstimate:
        """Estimate from ``images`` (K >= 2 renders with different seeds, same settings)."""
        if len(images) < 2:
            raise InvalidSceneError(f"images: need at least 2 independent renders, got {len(images)}")
        stack = np.stack([_as_image(f"images[{i}]", im) for i, im in enumerate(images)])
        if not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
            raise InvalidSceneError(f"n_samples: expected a positive integer, got {n_samples!r}")
        return cls(
            mean=stack.mean(axis=0),
            var=stack.var(axis=0, ddof=1) * n_samples,
            n_samples=int(n_samples),
            k=len(images),
            seeds=list(seeds),
        )

    def z_test(self, image: ArrayLike, n_samples_image: int | None = None, **kwargs: Any) -> ZTestResult:
        """:func:`z_test` of ``image`` (default: rendered with the same sample count) against this estimate,
        with the estimate's own variance and t-distribution degrees of freedom taken into account."""
        n = self.n_samples if n_samples_image is None else n_samples_image
        kwargs.setdefault("dof", self.dof)
        return z_test(image, self.mean, self.var, n, ref_mean_var=self.mean_var, **kwargs)

    def compare(self, other: ReferenceEstimate, **kwargs: Any) -> ZTestResult:
        """Two-sample (Welch) test between two estimates, e.g. of two backends: are the means equal?

        Uses ``z = (m_a - m_b) / sqrt(v_a / N_a + v_b / N_b)`` with per-pixel Welch–Satterthwaite degrees
        of freedom (their minimum, conservative)."""
        if other.mean.shape != self.mean.shape:
            raise InvalidSceneError(f"other: shape {other.mean.shape} does not match {self.mean.shape}")
        floor = kwargs.pop("var_floor", 1e-4)
        va = np.maximum(self.var, floor) / (self.n_samples * self.k)
        vb = np.maximum(other.var, floor) / (other.n_samples * other.k)
        with np.errstate(divide="ignore", invalid="ignore"):
            welch = (va + vb) ** 2 / (va**2 / self.dof + vb**2 / other.dof)
        dof = float(np.nanmin(welch)) if np.isfinite(welch).any() else float(min(self.dof, other.dof))
        dof = max(dof, float(min(self.dof, other.dof)))
        kwargs.setdefault("dof", dof)
        # express as a one-sample test with n = 1 and the combined variance
        return z_test(self.mean, other.mean, va + vb, 1, var_floor=0.0, **kwargs)


def estimate_reference(
    render: Callable[[int], ArrayLike | RenderResult] | Scene,
    k: int = 8,
    *,
    samples: int = 64,
    seed0: int = 1000,
    output: str = "rgb",
    backend: str | None = None,
    progress: bool | None = None,
    **render_kwargs: Any,
) -> ReferenceEstimate:
    """Estimate a reference mean and variance from ``k`` independent renders.

    ``render`` is either a callable ``seed -> image`` (any (H, W[, C]) array, or a RenderResult) or a
    :class:`~blendify_core.Scene`, rendered ``k`` times with ``bf.render(scene, backend=backend,
    samples=samples, seed=seed0 + i, denoise=False, adaptive=False, **render_kwargs)``. ``output``
    picks the array of a RenderResult ("rgb" = premultiplied linear RGB, or "rgba", "albedo", ...).
    ``progress``: a progress bar over the ``k`` renders (None: only on a terminal or in a notebook; see
    :mod:`blendify_core.evaluate.progress`).
    """
    if not isinstance(k, (int, np.integer)) or k < 2:
        raise InvalidSceneError(f"k: expected an integer >= 2 independent renders, got {k!r}")
    if isinstance(render, Scene):
        scene = render
        kw = {"denoise": False, "adaptive": False, "pixel_filter": "box", **render_kwargs}
        outputs = kw.pop("outputs", ("rgb",))

        def scene_render(seed: int) -> RenderResult:
            return bf_render(scene, backend=backend, samples=samples, seed=seed, outputs=outputs, **kw)

        render_fn: Callable[[int], ArrayLike | RenderResult] = scene_render
    elif callable(render):
        render_fn = render
    else:
        raise InvalidSceneError(f"render: expected a Scene or a callable seed -> image, got {type(render).__name__}")

    images = []
    seeds = [seed0 + i for i in range(int(k))]
    bar = progress_bar(len(seeds), "estimate_reference", progress)
    try:
        for s in seeds:
            bar.set_postfix_str(f"seed {s}")
            images.append(_output_image(render_fn(s), output))
            bar.update(1)
    finally:
        bar.close()
    return ReferenceEstimate.from_images(images, samples, seeds)


def _output_image(out: ArrayLike | RenderResult, output: str) -> Float64Array:
    """The array ``output`` of a render (a RenderResult or an image), as float64."""
    if isinstance(out, RenderResult):
        arr: ArrayLike | None
        if output in ("rgb", "rgba"):
            arr = out.rgba if output == "rgba" else out.rgb
        else:
            arr = getattr(out, output, None)
        if arr is None:
            raise InvalidSceneError(f"output: the render has no {output!r} output")
        out = arr
    return np.asarray(out, dtype=np.float64)
