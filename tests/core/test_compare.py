"""bf.compare / bf.crosscheck / the statistical Z-test on synthetic results (pure numpy, no engine)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import blendify_core as bf
from blendify_core.evaluate.crosscheck import crosscheck_main
from blendify_core.evaluate.metrics import alpha_centroids, heat_map
from blendify_core.evaluate.stats import ReferenceEstimate, estimate_reference, sidak_alpha, z_test
from blendify_core.evaluate.tiers import TIERS, choose_tier
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import depth_plane_scene, plane_scene, primitives_scene


def _metrics_installed() -> str | None:
    import importlib.util

    missing = [m for m in ("skimage", "flip_evaluator") if importlib.util.find_spec(m) is None]
    return None if not missing else f"the optional metrics ({', '.join(missing)}) are not installed"


needs_metrics = pytest.mark.skipif(_metrics_installed() is not None, reason=str(_metrics_installed()))

H, W = 40, 48


def make_result(shift: int = 0, value=(0.3, 0.5, 0.7), depth: float = 3.0, backend: str | None = None):
    """A rectangle object (rows 10..30 shifted by ``shift``, cols 8..40) over a transparent background."""
    mask = np.zeros((H, W), dtype=bool)
    mask[10 + shift : 30 + shift, 8:40] = True
    rgba = np.zeros((H, W, 4), dtype=np.float32)
    rgba[mask, :3] = value
    rgba[mask, 3] = 1.0
    d = np.full((H, W), np.inf, dtype=np.float32)
    d[mask] = depth
    normal = np.zeros((H, W, 3), dtype=np.float32)
    normal[mask] = (0, 0, 1)
    albedo = np.zeros((H, W, 3), dtype=np.float32)
    albedo[mask] = value
    inst = np.full((H, W), -1, dtype=np.int32)
    inst[mask] = 0
    meta = {"backend": backend} if backend else {}
    return bf.RenderResult(
        rgba=rgba, depth=d, normal=normal, albedo=albedo, instance=inst, instance_tags=["box"], meta=meta
    )


# -- metrics on hand-computed cases -----------------------------------------------------------------
@needs_metrics
def test_identical_results_pass_every_tier():
    a = make_result()
    for tier in TIERS:
        rep = bf.compare(a, make_result(), tier=tier)
        assert rep.passed, (tier, rep.failures)
        assert rep.failures == []
    m = bf.compare(a, make_result(), tier="identical").metrics
    assert m["rgb"]["mean_rel_error"] == 0.0
    assert m["rgb"]["ssim"] == pytest.approx(1.0)
    assert m["rgb"]["flip"] == 0.0
    assert m["rgb"]["psnr"] == float("inf")
    assert m["depth"]["rel_diff_q99"] == 0.0
    assert m["mask"]["iou"] == 1.0
    assert m["instance"]["agreement"] == 1.0
    assert set(m) == {"rgb", "depth", "mask", "normal", "albedo", "instance"}


@needs_metrics
def test_rgb_relative_error_and_rel_mse_by_hand():
    ref = make_result(value=(0.5, 0.5, 0.5))
    a = make_result(value=(0.505, 0.505, 0.505))
    m = bf.compare(a, ref, tier="pathtracer").metrics["rgb"]
    assert m["mean_rel_error"] == pytest.approx(0.01, rel=1e-4)
    assert m["max_rel_error"] == pytest.approx(0.01, rel=1e-4)
    assert m["rel_mse"] == pytest.approx(0.005**2 / (0.25 + 0.01), rel=1e-3)
    assert m["mean_ratio"] == pytest.approx(1.01, rel=1e-5)
    assert m["ratio_error"] == pytest.approx(0.01, rel=1e-3)
    assert m["mean_rel_error_interior"] == pytest.approx(0.01, rel=1e-4)
    assert m["n_interior"] == 18 * 30  # the 20 x 32 rectangle minus its 1-px rim
    assert m["n_covered"] == 20 * 32
    assert m["alpha_mean_abs_error"] == 0.0
    assert 0 < m["flip"] < 0.05
    assert m["ssim"] > 0.99


def test_rgb_error_floor_for_dark_pixels():
    # |a - r| / max(|r|, 0.02): reference 0.01, test 0.02 -> 0.01 / 0.02 = 0.5 (not 1.0)
    m = bf.compare(make_result(value=(0.02,) * 3), make_result(value=(0.01,) * 3)).metrics["rgb"]
    assert m["mean_rel_error"] == pytest.approx(0.5, rel=1e-4)


def test_depth_quantiles_by_hand():
    ref = make_result(depth=2.0)
    a = make_result(depth=2.0)
    a.depth[10:20, 8:40] = 2.004  # half of the object: relative difference 2e-3
    m = bf.compare(a, ref, tier="geometry").metrics["depth"]
    assert m["rel_diff_q50"] == pytest.approx(1e-3, rel=1e-3)  # median of {0 x 320, 2e-3 x 320}
    assert m["rel_diff_q99"] == pytest.approx(2e-3, rel=1e-3)
    assert m["rel_diff_max"] == pytest.approx(2e-3, rel=1e-3)
    rep = bf.compare(a, ref, tier="geometry")
    assert not rep.passed and any("rel_diff_q99" in f for f in rep.failures)


def test_shifted_mask_fails_and_edge_pixel_passes():
    ref = make_result()
    rep = bf.compare(make_result(shift=3), ref, tier="geometry")
    assert not rep.passed
    mm = rep.metrics["mask"]
    assert mm["n_disagree"] == 2 * 3 * 32
    assert mm["n_disagree_interior"] > 0
    assert mm["iou"] == pytest.approx(17 * 32 / (23 * 32))
    # one anti-aliased edge pixel flipped: not an interior disagreement
    a = make_result()
    a.depth[10, 20] = np.inf
    mm = bf.compare(a, ref, tier="geometry").metrics["mask"]
    assert mm["n_disagree"] == 1 and mm["n_disagree_interior"] == 0
    # a hole in the middle of the object is an interior disagreement
    a = make_result()
    a.depth[20, 24] = np.inf
    rep = bf.compare(a, ref, tier="geometry")
    assert rep.metrics["mask"]["n_disagree_interior"] == 1 and not rep.passed


def test_normal_angle_and_flip():
    ref = make_result()
    a = make_result()
    t = np.radians(10.0)
    a.normal[a.instance >= 0] = (0, np.sin(t), np.cos(t))
    m = bf.compare(a, ref).metrics["normal"]
    assert m["angle_q50_deg"] == pytest.approx(10.0, abs=1e-3)
    assert m["angle_max_deg"] == pytest.approx(10.0, abs=1e-3)
    assert m["flipped_fraction"] == 0.0
    a.normal[a.instance >= 0] = (0, 0, -1)
    assert bf.compare(a, ref).metrics["normal"]["flipped_fraction"] == 1.0


def test_instance_ids_matched_by_tag():
    ref = make_result()
    ref.instance_tags = ["other", "box"]
    ref.instance[ref.instance >= 0] = 1
    a = make_result()  # tags ["box"], id 0
    m = bf.compare(a, ref).metrics["instance"]
    assert m["agreement"] == 1.0
    a.instance_tags = ["other"]
    m = bf.compare(a, ref).metrics["instance"]
    assert m["agreement"] == 0.0 and m["n_disagree"] == 20 * 32
    a.instance[a.instance >= 0] = 5
    with pytest.raises(bf.InvalidSceneError, match="instance_tags"):
        bf.compare(a, ref)


def _two_walls(seam_owner: int = 0) -> bf.RenderResult:
    """Two walls meeting in a corner along column 24 (a seam exactly through the pixel centres: both walls
    are at the same depth there); ``seam_owner`` decides which wall the seam's pixels belong to."""
    r = make_result()
    r.instance_tags = ["left", "right"]
    hit = r.instance >= 0
    r.instance[hit] = 0
    r.instance[:, 25:][hit[:, 25:]] = 1
    r.instance[:, 24][hit[:, 24]] = seam_owner
    cols = np.arange(W, dtype=np.float32)
    r.depth[hit] = np.broadcast_to(3.0 + 0.01 * np.abs(cols - 24), (H, W))[hit]  # a V-shaped corner
    return r


def test_instance_tie_on_a_seam_is_not_a_defect():
    """Ties: the pixel-centre ray of the seam meets both walls at the same depth; each engine may pick
    either. Those pixels count as agreeing (``n_tie``), the tier passes."""
    a, ref = _two_walls(seam_owner=0), _two_walls(seam_owner=1)
    rep = bf.compare(a, ref, tier="geometry", outputs=("depth", "instance"))
    m = rep.metrics["instance"]
    assert m["n_tie"] == 20 and m["n_disagree"] == 0 and m["agreement"] == 1.0
    assert rep.passed, rep.failures
    # without depth (nothing to tell a tie by) every differing id counts
    a.depth = ref.depth = None
    m = bf.compare(a, ref, tier="geometry", outputs=("instance",)).metrics["instance"]
    assert m["n_tie"] == 0 and m["n_disagree"] == 20


@pytest.mark.parametrize("defect", ["interior", "deeper", "third_object"])
def test_instance_swap_still_fails(defect):
    """Injected defects that are not ties: ids swapped inside a wall, a seam pixel that one engine sees at
    another depth (it hit the wall behind), a seam labelled with an object that is not beside it."""
    a, ref = _two_walls(seam_owner=0), _two_walls(seam_owner=1)
    if defect == "interior":
        a.instance[14:18, 12:16] = 1  # inside the left wall (same depth: only the id is wrong)
        expected = 16
    elif defect == "deeper":
        a.depth[10:30, 24] += 0.05  # the seam's rays went past the corner: 1.7 % deeper
        expected = 20
    else:
        a.instance_tags = ["left", "right", "lamp"]
        a.instance[10:30, 24] = 2
        expected = 20
    rep = bf.compare(a, ref, tier="geometry", outputs=("depth", "instance"))
    m = rep.metrics["instance"]
    assert m["n_disagree"] == expected and m["n_tie"] == (20 if defect == "interior" else 0)
    assert not rep.passed
    assert any(f.startswith("instance.agreement") for f in rep.failures)


def test_albedo_relative_error():
    ref = make_result(value=(0.4, 0.4, 0.4))
    a = make_result(value=(0.4, 0.4, 0.4))
    a.albedo[a.instance >= 0] = (0.42, 0.4, 0.4)
    m = bf.compare(a, ref).metrics["albedo"]
    assert m["mean_rel_error"] == pytest.approx(0.05 / 3, rel=1e-4)
    assert m["max_rel_error"] == pytest.approx(0.05, rel=1e-4)


def test_required_keys_diff_images_and_repr(tmp_path):
    rep = bf.compare(make_result(value=(0.51, 0.5, 0.5)), make_result(value=(0.5, 0.5, 0.5)), tier="pathtracer_delta")
    assert "mean_rel_error" in rep.metrics["rgb"]
    assert "rel_diff_q99" in rep.metrics["depth"]
    assert "iou" in rep.metrics["mask"]
    assert not rep.passed  # 0.67 % mean relative error > 0.5 %
    assert any(f.startswith("rgb.mean_rel_error") for f in rep.failures)
    for out, img in rep.diff_images.items():
        assert img.shape == (H, W, 3) and img.dtype == np.uint8, out
    assert "FAIL" in repr(rep) and "pathtracer_delta" in repr(rep)
    text = rep.summary()
    assert "| rgb | mean_rel_error |" in text and "**FAIL**" in text
    rep.save(tmp_path / "rep")
    names = sorted(p.name for p in (tmp_path / "rep").iterdir())
    assert "report.md" in names and "diff_rgb.png" in names and "diff_mask.png" in names
    assert "a_rgb.png" in names and "b_depth.png" in names and "b_instance.png" in names
    data = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert data["passed"] is False and data["tier"] == "pathtracer_delta"


@needs_metrics
def test_outputs_selection_and_errors():
    a, b = make_result(), make_result()
    assert set(bf.compare(a, b, outputs=("depth",)).metrics) == {"depth"}
    only_rgb = bf.RenderResult(rgba=a.rgba)
    assert set(bf.compare(only_rgb, b).metrics) == {"rgb", "mask"}  # mask from alpha >= 0.5
    with pytest.raises(bf.InvalidSceneError, match="has no 'depth'"):
        bf.compare(only_rgb, b, outputs=("depth",))
    with pytest.raises(bf.InvalidSceneError, match="unknown output"):
        bf.compare(a, b, outputs=("colour",))
    with pytest.raises(bf.InvalidSceneError, match="unknown tier"):
        bf.compare(a, b, tier="loose")
    with pytest.raises(bf.InvalidSceneError, match="unknown metric"):
        bf.compare(a, b, tier={"rgb": {"mean_error": 0.1}})
    with pytest.raises(bf.InvalidSceneError, match="resolutions differ"):
        bf.compare(a, bf.RenderResult(rgba=np.zeros((H, W + 1, 4), np.float32)))
    with pytest.raises(bf.InvalidSceneError, match="RenderResult"):
        bf.compare(a.rgba, b)
    rep = bf.compare(a, b, tier={"rgb": {"mean_rel_error": 0.0, "ssim": 1.0}})
    assert rep.passed and rep.tier == "custom"


def test_every_tier_documented():
    from blendify_core.evaluate.tiers import TIER_NOTES

    assert set(TIER_NOTES) == set(TIERS)


@pytest.fixture
def project_backend_names():
    """The project's three backend names resolvable by the registry: the real backends where installed,
    stand-ins with the same ``path_tracer`` flag where not (the numpy-2 core-only CI environment)."""
    from blendify_core.pipeline.backend import Backend
    from blendify_core.registry import backend_names, register_backend, unregister_backend

    added = []
    for name, pt in (("cycles", True), ("mitsuba", True), ("pyrender", False)):
        if name not in backend_names():
            register_backend(name, type(f"StandIn_{name}", (Backend,), {"name": name, "path_tracer": pt}))
            added.append(name)
    yield
    for name in added:
        unregister_backend(name)


def test_choose_tier(project_backend_names):
    assert choose_tier("cycles", "mitsuba") == "pathtracer"
    assert choose_tier("cycles", "mitsuba", plane_scene("sun")) == "pathtracer_delta"
    assert choose_tier("cycles", "mitsuba", plane_scene("area")) == "pathtracer"
    assert choose_tier("cycles", "mitsuba", plane_scene("background")) == "pathtracer"
    assert choose_tier("pyrender", "mitsuba") == "raster"
    assert choose_tier("cycles", "pyrender", plane_scene("sun")) == "raster"
    assert choose_tier("cycles", "mitsuba", primitives_scene()) == "pathtracer_material"
    assert choose_tier("pyrender", "mitsuba", primitives_scene()) == "raster_material"
    # auto tier from meta["backend"]
    rep = bf.compare(make_result(backend="pyrender"), make_result(backend="cycles"))
    assert rep.tier == "raster" and rep.names == ("pyrender", "cycles")
    rep = bf.compare(make_result(backend="mitsuba"), make_result(backend="cycles"), scene=primitives_scene())
    assert rep.tier == "pathtracer_material"


def test_empty_results_agree():
    empty = bf.RenderResult(
        rgba=np.zeros((H, W, 4), np.float32),
        depth=np.full((H, W), np.inf, np.float32),
        normal=np.zeros((H, W, 3), np.float32),
        albedo=np.zeros((H, W, 3), np.float32),
    )
    for tier in TIERS:
        rep = bf.compare(empty, empty, tier=tier)
        assert rep.passed, (tier, rep.failures)
    assert any("not checked" in n for n in bf.compare(empty, empty, tier="pathtracer").notes)
    # but an object seen by one backend only fails on the mask
    assert not bf.compare(make_result(), bf.RenderResult(depth=empty.depth), tier="geometry").passed


def test_missing_metric_packages_give_a_hint(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "flip_evaluator", None)  # import fails
    monkeypatch.setitem(sys.modules, "skimage.metrics", None)
    rep = bf.compare(make_result(backend="pyrender"), make_result(backend="cycles"))  # raster tier: flip
    assert np.isnan(rep.metrics["rgb"]["flip"]) and np.isnan(rep.metrics["rgb"]["ssim"])
    assert any("blendify-core[metrics]" in n for n in rep.notes)
    assert not rep.passed and "blendify-core[metrics]" in " ".join(rep.failures)


def test_heat_map_range():
    img = heat_map(np.array([[0.0, 0.5, 1.0, np.nan]]), valid=np.array([[True, True, True, False]]))
    assert img.dtype == np.uint8 and img.shape == (1, 4, 3)
    assert img[0, 0].sum() < img[0, 1].sum() < img[0, 2].sum()
    assert tuple(img[0, 3]) == (40, 40, 40)


def test_alpha_centroids_subpixel():
    # exact coverage of a disc of radius 3 px centred at (20.3, 15.7), by 16x16 supersampling
    ss = 16
    ys, xs = np.mgrid[0 : H * ss, 0 : W * ss]
    u = (xs + 0.5) / ss - 0.5
    v = (ys + 0.5) / ss - 0.5
    inside = (u - 20.3) ** 2 + (v - 15.7) ** 2 <= 9.0
    alpha = inside.reshape(H, ss, W, ss).mean(axis=(1, 3))
    rgba = np.zeros((H, W, 4), np.float32)
    rgba[..., 3] = alpha
    c = alpha_centroids(bf.RenderResult(rgba=rgba), np.array([[20.0, 16.0], [5.0, 35.0]]))
    assert np.abs(c[0] - (20.3, 15.7)).max() < 0.01
    assert np.isnan(c[1]).all()  # nothing near (5, 35)


# -- the statistical test --------------------------------------------------------------------------
SH, SW, K, N = 32, 32, 8, 64


def _truth(seed=0):
    rng = np.random.default_rng(seed)
    mean = rng.uniform(0.1, 1.0, (SH, SW, 3))
    return mean, 0.5 * mean  # per-sample standard deviation: 50 % of the mean


def _render(rng, mean, sd, bias=0.0, n=N):
    return mean * (1 + bias) + rng.normal(size=mean.shape) * sd / np.sqrt(n)


def test_sidak_alpha():
    assert sidak_alpha(0.01, 1) == pytest.approx(0.01)
    a = sidak_alpha(0.01, 1000)
    assert 1 - (1 - a) ** 1000 == pytest.approx(0.01, rel=1e-9)
    with pytest.raises(bf.InvalidSceneError):
        sidak_alpha(1.5, 10)


def test_z_test_known_variance_calibration():
    """Converged reference (known mean and variance): false failures ~ alpha over many seeds."""
    mean, sd = _truth()
    fails = sum(not z_test(_render(np.random.default_rng(s), mean, sd), mean, sd**2, N).passed for s in range(300))
    assert fails / 300 <= 0.035  # alpha = 0.01: expected 3 of 300; P(> 10) < 1e-3


def test_z_test_estimated_reference_calibration_and_power():
    """Reference from K = 8 renders (t distribution): identical distributions pass with a false-failure
    rate near alpha; a 2 % bias at 6 % per-pixel noise fails every time (tile/global aggregation: the
    per-pixel test alone cannot see it)."""
    mean, sd = _truth()
    fails = 0
    trials = 300
    for s in range(trials):
        rng = np.random.default_rng(1000 + s)
        ref = ReferenceEstimate.from_images([_render(rng, mean, sd) for _ in range(K)], N)
        fails += not ref.z_test(_render(rng, mean, sd)).passed
    assert fails / trials <= 0.035
    for s in range(20):
        rng = np.random.default_rng(5000 + s)
        ref = ReferenceEstimate.from_images([_render(rng, mean, sd) for _ in range(K)], N)
        r = ref.z_test(_render(rng, mean, sd, bias=0.02))
        assert not r.passed
        assert r.global_p < 1e-9
        assert r.n_reject == 0 or r.accept_fraction > 0.99  # invisible pixel by pixel


def test_z_test_localised_bias_fails_and_mitsuba_rule():
    mean, sd = _truth()
    rng = np.random.default_rng(3)
    img = _render(rng, mean, sd)
    img[:8, :8] *= 1.3  # a wrong 8x8 corner
    r = z_test(img, mean, sd**2, N)
    assert not r.passed and r.n_tile_reject >= 1
    assert r.reject_map().shape == (SH, SW)
    # one firefly: familywise fails, Mitsuba's 99.75 % rule (without aggregation) tolerates it
    img = _render(np.random.default_rng(4), mean, sd)
    img[5, 5, 0] += 50.0
    assert not z_test(img, mean, sd**2, N).passed
    assert z_test(img, mean, sd**2, N, rule="mitsuba", aggregate=False).passed


def test_z_test_variance_floor_and_validation():
    flat = np.full((8, 8, 3), 0.5)
    assert z_test(flat, flat, np.zeros_like(flat), 4).passed  # zero variance, zero difference
    r = z_test(flat + 0.1, flat, np.zeros_like(flat), 4)  # floor 1e-4 -> z = 0.1 / 0.005 = 20
    assert not r.passed and np.allclose(r.z, 20.0)
    with pytest.raises(bf.InvalidSceneError, match="ref_mean"):
        z_test(flat, flat[:4], 0.1, 4)
    with pytest.raises(bf.InvalidSceneError, match="n_samples_image"):
        z_test(flat, flat, 0.1, 0)
    with pytest.raises(bf.InvalidSceneError, match="rule"):
        z_test(flat, flat, 0.1, 4, rule="loose")
    with pytest.raises(bf.InvalidSceneError, match="non-finite"):
        z_test(flat * np.nan, flat, 0.1, 4)


def test_two_sample_compare_of_estimates():
    mean, sd = _truth()
    rng = np.random.default_rng(11)
    a = ReferenceEstimate.from_images([_render(rng, mean, sd) for _ in range(K)], N)
    b = ReferenceEstimate.from_images([_render(rng, mean, sd) for _ in range(K)], N)
    c = ReferenceEstimate.from_images([_render(rng, mean, sd, bias=0.03) for _ in range(K)], N)
    assert a.compare(b).passed
    assert not a.compare(c).passed


# -- crosscheck with fake backends -----------------------------------------------------------------
class _FakeBase(Backend):
    """Analytic 'renders' of depth_plane_scene: the exact plane depth, a constant colour."""

    path_tracer = True
    gain = 1.0

    @classmethod
    def capabilities(cls):
        caps = {k: Capability("exact") for k in ALL_FEATURES}
        caps["output.albedo"] = Capability("unsupported", "fake has no albedo")
        return caps

    def translate(self, scene, settings):
        return scene

    def render(self, native, settings):
        from blendify_core.testing import expected_plane_depth

        d = expected_plane_depth(native).astype(np.float32)
        hit = np.isfinite(d)
        rgba = np.zeros(d.shape + (4,), np.float32)
        rgba[hit] = (0.25 * self.gain, 0.25 * self.gain, 0.25 * self.gain, 1.0)
        inst = np.where(hit, 0, -1).astype(np.int32)
        normal = np.zeros(d.shape + (3,), np.float32)
        normal[hit] = (0, -0.5, np.sqrt(0.75))
        return bf.RenderResult(
            rgba=rgba,
            depth=d if settings.wants("depth") else None,
            normal=normal if settings.wants("normal") else None,
            instance=inst if settings.wants("instance") else None,
            meta={},
        )


class FakeA(_FakeBase):
    name = "fake-a"


class FakeB(_FakeBase):
    name = "fake-b"
    gain = 1.003


class _NoisyFake(_FakeBase):
    """A fake path tracer: the constant colour plus seed-dependent Gaussian noise."""

    def render(self, native, settings):
        res = super().render(native, settings)
        rng = np.random.default_rng(settings.seed + 1000 * ord(self.name[-1]))  # independent per fake
        hit = res.rgba[..., 3] > 0
        noise = rng.normal(size=res.rgba.shape[:2] + (3,)) * 0.1 / np.sqrt(settings.samples)
        res.rgba[..., :3] += np.where(hit[..., None], noise, 0).astype(np.float32)
        return res


class NoisyA(_NoisyFake):
    name = "noisy-a"


class NoisyB(_NoisyFake):
    name = "noisy-b"


class NoisyBiased(_NoisyFake):
    name = "noisy-biased"
    gain = 1.02


@pytest.fixture
def fakes():
    register_backend(FakeA.name, FakeA)
    register_backend(FakeB.name, FakeB)
    for cls in (NoisyA, NoisyB, NoisyBiased):
        register_backend(cls.name, cls)
    yield
    for cls in (FakeA, FakeB, NoisyA, NoisyB, NoisyBiased):
        unregister_backend(cls.name)
    bf.close_backends()


def test_crosscheck_with_fakes(fakes, tmp_path):
    scene = depth_plane_scene()
    # passes=1: one render each, the tier's fixed colour tolerances (2 %: the 0.3 % difference passes)
    rep = bf.crosscheck(scene, backends=("fake-a", "fake-b", "no-such-backend"), samples=4, passes=1)
    assert set(rep.results) == {"fake-a", "fake-b"}
    assert "no-such-backend" in rep.skipped
    assert list(rep.pairs) == [("fake-a", "fake-b")]
    pair = rep.pairs[("fake-a", "fake-b")]
    assert pair.tier == "pathtracer"  # a background light: not the delta tier
    assert pair.metrics["rgb"]["mean_rel_error"] == pytest.approx(0.003 / 1.003, rel=1e-3)
    assert pair.metrics["depth"]["rel_diff_q99"] == 0.0
    assert "albedo" not in pair.metrics and any("albedo" in n for n in rep.notes)
    assert rep.passed
    # forced settings are recorded
    s = rep.results["fake-a"].meta["settings"]
    assert s["pixel_filter"] == "box" and s["denoise"] is False and s["adaptive"] is False and s["seed"] == 0
    sheet = rep.contact_sheet()
    assert sheet.dtype == np.uint8 and sheet.ndim == 3 and sheet.shape[2] == 3
    rep.save(tmp_path / "xc")
    assert (tmp_path / "xc" / "crosscheck.png").exists()
    md = (tmp_path / "xc" / "crosscheck.md").read_text()
    assert "no-such-backend" in md and "fake-a vs fake-b" in md
    assert pair.noise is None and rep.results["fake-a"].rgb_var is None
    # default: 4 passes; the fakes are noise-free, so their 0.3 % difference exceeds the 0.25 % margin for sure
    noisy = bf.crosscheck(scene, backends=("fake-a", "fake-b"), samples=4)
    res = noisy.results["fake-a"]
    assert res.meta["passes"] == 4 and res.meta["samples"] == 4 and np.all(res.rgb_var == 0)
    nt = noisy.pairs[("fake-a", "fake-b")].noise
    assert nt is not None and not nt.passed and not noisy.passed
    assert nt.global_rel_diff == pytest.approx([-0.003 / 1.0015] * 3, rel=1e-3)  # relative to the mean of both
    assert "whole image differs by -0.30%" in nt.reasons[0]
    assert "noise_global_excess" in noisy.pairs[("fake-a", "fake-b")].thresholds["rgb"]
    rep2 = bf.crosscheck(scene, backends=("fake-a", "fake-b"), samples=4, tier="pathtracer_delta", passes=1)
    assert rep2.pairs[("fake-a", "fake-b")].tier == "pathtracer_delta"
    with pytest.raises(bf.InvalidSceneError, match="fixed by crosscheck"):
        bf.crosscheck(scene, backends=("fake-a",), denoise=True)
    with pytest.raises(bf.InvalidSceneError, match="distinct"):
        bf.crosscheck(scene, backends=("fake-a", "fake-a"))


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), h=st.integers(8, 24), w=st.integers(8, 24))
def test_random_results_identical_to_themselves_and_masks_symmetric(seed, h, w):
    rng = np.random.default_rng(seed)
    hit = rng.random((h, w)) < 0.6
    rgba = np.where(hit[..., None], rng.random((h, w, 4)), 0).astype(np.float32)
    rgba[..., 3] = hit
    depth = np.where(hit, rng.uniform(1, 5, (h, w)), np.inf).astype(np.float32)
    a = bf.RenderResult(rgba=rgba, depth=depth)
    rep = bf.compare(a, bf.RenderResult(rgba=rgba.copy(), depth=depth.copy()), tier="identical")
    assert rep.passed, rep.failures
    hit2 = rng.random((h, w)) < 0.6
    b = bf.RenderResult(depth=np.where(hit2, 2.0, np.inf).astype(np.float32))
    m1 = bf.compare(a, b, outputs=("mask",)).metrics["mask"]
    m2 = bf.compare(b, a, outputs=("mask",)).metrics["mask"]
    assert m1 == m2  # every mask metric is symmetric
    assert m1["n_disagree"] == (hit ^ hit2).sum()
    assert m1["n_disagree_interior"] <= m1["n_disagree"]


def test_crosscheck_repeats_statistical_test(fakes):
    scene = depth_plane_scene()
    rep = bf.crosscheck(scene, backends=("noisy-a", "noisy-b", "noisy-biased"), samples=4, repeats=4)
    assert set(rep.estimates) == {"noisy-a", "noisy-b", "noisy-biased"}
    assert rep.results["noisy-a"].meta["repeats"] == 4
    assert rep.settings["repeats"] == 4
    assert rep.ztests[("noisy-a", "noisy-b")].passed
    assert not rep.ztests[("noisy-a", "noisy-biased")].passed
    assert not rep.ztests[("noisy-b", "noisy-biased")].passed
    assert not rep.passed
    assert "statistical test noisy-a vs noisy-b" in rep.summary()
    with pytest.raises(bf.InvalidSceneError, match="repeats"):
        bf.crosscheck(scene, backends=("noisy-a",), repeats=0)


def test_crosscheck_main_cli(fakes, tmp_path, capsys):
    path = tmp_path / "scene.npz"
    depth_plane_scene().save(path)
    out = tmp_path / "out"
    code = crosscheck_main(
        [str(path), "-o", str(out), "--backends", "fake-a,fake-b", "--samples", "2", "--passes", "1"]
    )
    assert code == 0
    assert (out / "crosscheck.png").exists() and (out / "crosscheck.md").exists()
    assert "fake-a/fake-b: PASS" in capsys.readouterr().out
    assert crosscheck_main([str(tmp_path / "missing.npz"), "-o", str(out)]) == 2
    # one backend only: nothing compared -> 1
    assert crosscheck_main([str(path), "-o", str(out), "--backends", "fake-a", "--samples", "2"]) == 1
    assert "nothing was compared" in capsys.readouterr().err
    assert crosscheck_main(["--help"]) == 0


def test_estimate_reference_from_callable_and_scene(fakes):
    mean, sd = _truth()

    def render(seed):
        return _render(np.random.default_rng(seed), mean, sd)

    ref = estimate_reference(render, k=6, samples=N)
    assert ref.k == 6 and ref.dof == 5 and ref.seeds == list(range(1000, 1006))
    assert ref.z_test(render(99)).passed
    ref2 = estimate_reference(depth_plane_scene(), k=2, samples=2, backend="fake-a")
    assert ref2.mean.shape == (48, 64, 3) and np.allclose(ref2.var, 0.0)
    with pytest.raises(bf.InvalidSceneError, match="k:"):
        estimate_reference(render, k=1)
