"""The noise-aware colour verdict (blendify_core.evaluate.noise) on synthetic noisy images (numpy only):
its false-failure rate on agreeing images, its power against the defects it exists for, its errors."""

from __future__ import annotations

import numpy as np
import pytest
from core_fake_backend import NoisyPathTracer

import blendify_core as bf
from blendify_core.evaluate.noise import combine_passes, estimate_from_passes, noise_test, pass_samples, render_passes
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import depth_plane_scene

H, W, K = 48, 64, 4


def _truth() -> np.ndarray:
    """A checkerboard of 8 px squares on a gradient, three channels (edges for the shift test)."""
    yy, xx = np.mgrid[0:H, 0:W]
    board = 0.2 + 0.6 * (((xx // 8) + (yy // 8)) % 2) + 0.1 * xx / W
    return board[..., None] * np.array([1.0, 0.8, 0.6])


def _passes(rng: np.random.Generator, truth: np.ndarray, rel: float = 0.1, k: int = K) -> np.ndarray:
    """K passes: a skewed (gamma) multiplicative noise of relative sd ``rel`` around ``truth``."""
    shape = 1.0 / rel**2
    return np.stack([truth * rng.gamma(shape, 1.0 / shape, size=truth.shape) for _ in range(k)])


def _test(pa: np.ndarray, pb: np.ndarray, **kw) -> bf.evaluate.noise.NoiseTest:
    ma, va, da = estimate_from_passes(pa)
    mb, vb, db = estimate_from_passes(pb)
    return noise_test(ma, va, da, mb, vb, db, **kw)


def test_false_failure_rate_on_agreeing_images_is_at_most_alpha():
    rng = np.random.default_rng(1)
    truth = _truth()
    n = 200
    fails = sum(not _test(_passes(rng, truth), _passes(rng, truth)).passed for _ in range(n))
    # alpha = 0.01; with n = 200 the count is Binomial(200, <= 0.01): 8 or more has probability < 1e-3
    assert fails <= 7, fails


def test_no_margin_is_still_calibrated_and_margin_only_relaxes():
    rng = np.random.default_rng(2)
    truth = _truth()
    fails_none = fails_margin = 0
    for _ in range(100):
        pa, pb = _passes(rng, truth), _passes(rng, truth)
        fails_none += not _test(pa, pb, margin_global=0.0, margin_tile=0.0).passed
        fails_margin += not _test(pa, pb).passed
    assert fails_none <= 5 and fails_margin <= fails_none


@pytest.mark.parametrize(
    "defect",
    ["bias_1pct", "shift_half_px", "wrong_colour_space", "mirrored"],
)
def test_injected_defects_are_detected(defect):
    rng = np.random.default_rng(3)
    truth = _truth()
    yy, xx = np.mgrid[0:H, 0:W]
    if defect == "bias_1pct":
        bad = truth * 1.01
    elif defect == "shift_half_px":  # the expected image shifted by half a pixel (linear interpolation)
        bad = 0.5 * (truth + np.roll(truth, 1, axis=1))
        bad[:, 0] = truth[:, 0]
    elif defect == "wrong_colour_space":  # linear values treated as sRGB-encoded
        bad = np.where(truth <= 0.04045, truth / 12.92, ((truth + 0.055) / 1.055) ** 2.4)
    else:
        bad = truth[:, ::-1]
    detected = sum(not _test(_passes(rng, bad, rel=0.05), _passes(rng, truth, rel=0.05)).passed for _ in range(20))
    assert detected >= 19, detected
    if defect == "bias_1pct":
        res = _test(_passes(rng, bad, rel=0.05), _passes(rng, truth, rel=0.05))
        assert res.global_rel_diff == pytest.approx([0.01] * 3, abs=0.002)
        assert any("whole image" in r for r in res.reasons)
    if defect == "mirrored":
        res = _test(_passes(rng, bad, rel=0.05), _passes(rng, truth, rel=0.05))
        assert res.n_tile_reject > 0 and res.reject_map(H, W).shape == (H, W)


def test_bias_below_the_margin_passes_and_noise_free_images_are_exact():
    truth = _truth()
    zero = np.zeros_like(truth)
    assert noise_test(truth * 1.002, zero, 3, truth, zero, 3).passed  # 0.2 % < the 0.25 % margin, no noise
    res = noise_test(truth * 1.004, zero, 3, truth, zero, 3)
    assert not res.passed and res.global_excess == np.inf
    assert noise_test(truth, zero, 3, truth, zero, 3).passed
    # a 2-D image and a scalar variance are accepted
    assert noise_test(truth[..., 0], 0.0, 3, truth[..., 0], 0.0, 3).passed


def test_mask_limits_the_test_to_chosen_pixels():
    truth = _truth()
    zero = np.zeros_like(truth)
    bad = truth.copy()
    bad[:8, :8] *= 1.5
    keep = np.ones((H, W), bool)
    keep[:8, :8] = False
    assert not noise_test(bad, zero, 3, truth, zero, 3).passed
    assert noise_test(bad, zero, 3, truth, zero, 3, mask=keep).passed


def test_bad_inputs_are_refused_by_name():
    truth = _truth()
    cases = [
        (dict(mean_a=truth[0]), "mean_a"),
        (dict(mean_b=truth[:, :10]), "mean_b"),
        (dict(var_a=-np.ones_like(truth)), "var_a"),
        (dict(var_b=np.ones((3, 3))), "var_b"),
        (dict(dof_a=0), "dof_a"),
        (dict(alpha=1.5), "alpha"),
        (dict(tile=0), "tile"),
        (dict(margin_tile=-0.1), "margin_tile"),
        (dict(mask=np.ones((2, 2), bool)), "mask"),
        (dict(mean_a=np.full_like(truth, np.nan)), "mean_a"),
    ]
    for override, name in cases:
        kw = dict(mean_a=truth, var_a=0.0, dof_a=3, mean_b=truth, var_b=0.0, dof_b=3) | override
        with pytest.raises(bf.InvalidSceneError, match=name):
            noise_test(**kw)
    with pytest.raises(bf.InvalidSceneError, match="passes"):
        estimate_from_passes(truth[None])


def test_combine_passes_and_pass_samples():
    rng = np.random.default_rng(4)
    imgs = [rng.random((6, 5, 4)).astype(np.float32) for _ in range(4)]
    results = [bf.RenderResult(rgba=im, meta={"samples": 16}) for im in imgs]
    first = combine_passes(results[0], results[1:])
    stack = np.stack(imgs).astype(np.float64)
    assert np.allclose(first.rgba, stack.mean(axis=0), atol=1e-6)
    assert np.allclose(first.rgb_var, stack[..., :3].var(axis=0, ddof=1) / 4, atol=1e-7)
    assert first.meta["passes"] == 4 and first.meta["samples"] == 64
    assert pass_samples(256, 4) == 64 and pass_samples(10, 4) == 3 and pass_samples(1, 4) == 1
    assert pass_samples(None, 4) is None
    with pytest.raises(bf.InvalidSceneError, match="rgb"):
        combine_passes(bf.RenderResult(depth=np.ones((2, 2), np.float32)), [])


def test_compare_uses_the_noise_verdict_when_both_results_carry_their_noise():
    rng = np.random.default_rng(5)
    truth = _truth()

    def result(t: np.ndarray) -> bf.RenderResult:
        m, v, dof = estimate_from_passes(_passes(rng, t, rel=0.05))
        rgba = np.concatenate([m, np.ones((H, W, 1))], axis=-1).astype(np.float32)
        return bf.RenderResult(rgba=rgba, rgb_var=v.astype(np.float32), meta={"passes": dof + 1})

    a, b, biased = result(truth), result(truth), result(truth * 1.02)
    ok = bf.compare(a, b, tier="pathtracer")
    assert ok.passed and ok.noise is not None and ok.noise.passed
    assert set(ok.thresholds["rgb"]) == {"noise_tiles_rejected", "noise_global_excess"}
    bad = bf.compare(biased, b, tier="pathtracer")
    assert not bad.passed and any("noise_global_excess" in f for f in bad.failures)
    # rejected tiles are framed in magenta on the colour heat map
    mirrored = result(truth[:, ::-1])
    framed = bf.compare(mirrored, b, tier="pathtracer")
    assert framed.noise.n_tile_reject > 0 and "magenta" in framed.legends["rgb"]
    ty, tx = np.argwhere(framed.noise.tile_reject)[0]
    assert tuple(framed.diff_images["rgb"][ty * 8, tx * 8]) == (255, 0, 255)
    assert "magenta" not in ok.legends["rgb"]
    # the fixed tolerance (2 %) cannot tell a 2 % bias from noise; the noise verdict can
    assert bf.compare(biased, b, tier="pathtracer", noise=False).noise is None
    # raster tiers keep their fixed thresholds; noise=True without rgb_var is an error
    assert bf.compare(a, b, tier="raster").noise is None
    with pytest.raises(bf.InvalidSceneError, match="rgb_var"):
        bf.compare(bf.RenderResult(rgba=a.rgba), b, tier="pathtracer", noise=True)
    with pytest.raises(bf.InvalidSceneError, match="passes"):
        bf.compare(bf.RenderResult(rgba=a.rgba, rgb_var=a.rgb_var), b, tier="pathtracer")


def test_dark_channel_is_judged_against_the_image_brightness():
    """A green image: +20 % in its almost black red channel is 0.012 % of the image's mean brightness, below
    the margin's floor (a tenth of that brightness x 0.25 %); +1 % in green is not. Without the floor
    (``floor=0``) the red channel alone would be held to 0.25 % of itself."""
    zero = np.zeros((H, W, 3))
    green = np.zeros((H, W, 3))
    green[..., 1] = 0.5
    green[..., 0] = 1e-4
    tinted = green.copy()
    tinted[..., 0] += 2e-5
    assert noise_test(tinted, zero, 3, green, zero, 3).passed
    assert not noise_test(tinted, zero, 3, green, zero, 3, floor=0.0).passed
    brighter = green.copy()
    brighter[..., 1] *= 1.01
    assert not noise_test(brighter, zero, 3, green, zero, 3).passed


class _Seeded(NoisyPathTracer):
    """A fake path tracer: a constant grey plus Gaussian noise drawn from the render's seed."""

    name = "noise-fake-pt"
    sigma = 0.1


class _Raster(_Seeded):
    name = "noise-fake-raster"
    path_tracer = False


@pytest.fixture
def seeded():
    for cls in (_Seeded, _Raster):
        register_backend(cls.name, cls)
    yield
    for cls in (_Seeded, _Raster):
        unregister_backend(cls.name)
    bf.close_backends()


def test_render_passes_splits_samples_and_keeps_the_noise(seeded):
    scene = depth_plane_scene((16, 12))
    r = render_passes(scene, "noise-fake-pt", samples=64, passes=4, seed=10)
    assert r.meta["passes"] == 4 and r.meta["samples"] == 64
    passes = [bf.render(scene, backend="noise-fake-pt", samples=16, seed=10 + i).rgb for i in range(4)]
    assert np.allclose(r.rgb, np.mean(passes, axis=0), atol=1e-6)
    # the variance of the mean of 4 passes of 16 samples: 0.1^2 / 64 per pixel-channel, on average
    assert r.rgb_var.mean() == pytest.approx(0.01 / 64, rel=0.15)
    other = render_passes(scene, "noise-fake-pt", samples=64, passes=4, seed=100)
    assert bf.compare(r, other, tier="pathtracer").noise.passed
    raster = render_passes(scene, "noise-fake-raster", samples=64)
    assert raster.rgb_var is None and "passes" not in raster.meta
    with pytest.raises(bf.InvalidSceneError, match="passes"):
        render_passes(scene, "noise-fake-pt", passes=1)


def test_crosscheck_passes_argument(seeded):
    scene = depth_plane_scene((16, 12))
    rep = bf.crosscheck(scene, backends=("noise-fake-pt", "noise-fake-raster"), samples=8, outputs=("rgb",))
    assert rep.results["noise-fake-pt"].meta["passes"] == 4 and rep.settings["passes"] == 4
    assert rep.results["noise-fake-raster"].rgb_var is None  # a raster backend renders once
    for bad in (0, 1.5, "4"):
        with pytest.raises(bf.InvalidSceneError, match="passes"):
            bf.crosscheck(scene, backends=("noise-fake-pt",), passes=bad)
