"""The indirect-light pilot of ``target_error`` on a stand-in engine whose passes are drawn from known numbers:
the full pass of a seed is picture + indirect light + noise, the direct pass of the same seed shares that noise
up to an engine-dependent remainder (how much of the same random numbers the two use). Where the remainder is
small two pilot passes decide; where it is large the pilot pairs more passes with the full ones (never more than
the full passes there are, never costing more than 1/PILOT_MIN_GAIN of the full samples) instead of keeping
light it cannot tell from noise; clear cases stop at two either way."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline import render as render_module
from blendify_core.pipeline.render import FIRST_PASSES, PILOT_PASSES, _effect_pilot, pass_seed
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import resolve_settings

SHAPE = (24, 32, 3)
#: per-pass relative noise of a 16-spp pass (about the dark-floor scene's in both engines)
NOISE = 0.04


def _scene() -> bf.Scene:
    """A diffuse ball on a diffuse floor under an area light: the effect analysis finds indirect light."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.3, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.3, 0.2)), tag="ball")
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.5,) * 3), tag="floor")
    s.lights.add_area("square", 1.0, strength=100.0, translation=(0, 0, 2))
    return s


def _plastic_scene() -> bf.Scene:
    """A plastic ball on a diffuse floor under an area light: the effect analysis finds caustics."""
    s = _scene()
    s.renderables.add_sphere_nurbs(0.2, bf.PlasticMaterial(roughness=0.1), bf.UniformColors((0.8, 0.2, 0.2)))
    return s


class _Engine:
    """Passes of a known picture: full = picture x (1 + indirect) + noise(seed); the pilot's (direct light, or
    no caustics) = picture + noise(seed) + remainder x fresh noise (0: the same random numbers, 1: as many again
    of its own); a pilot's sample costs ``cost`` full ones, a render call ``overhead`` pixel-samples."""

    name = "stand-in"

    def __init__(self, indirect: float, remainder: float, cost: float = 1.0, overhead: float = 0.0) -> None:
        self.indirect, self.remainder, self.cost, self.overhead = indirect, remainder, cost, overhead
        self.picture = 0.2 + 0.6 * np.random.default_rng(0).random(SHAPE)
        self.direct_seeds: list[int] = []

    def pilot_sample_cost(self, settings: Any) -> float:
        return 1.0 if settings.caustics else self.cost

    def pass_overhead(self, settings: Any) -> float:
        return self.overhead

    def render_scene(self, scene: Any, settings: Any) -> RenderResult:
        noise = NOISE * self.picture * np.random.default_rng(settings.seed).standard_normal(SHAPE)
        if settings.max_bounces == 0 or not settings.caustics:
            self.direct_seeds.append(settings.seed)
            own = np.random.default_rng(settings.seed + 10**6).standard_normal(SHAPE)
            rgb = self.picture + noise + self.remainder * NOISE * self.picture * own
        else:
            rgb = self.picture * (1.0 + self.indirect) + noise
        rgba = np.concatenate([rgb, np.ones(SHAPE[:2] + (1,))], axis=-1).astype(np.float32)
        how = "direct" if settings.max_bounces == 0 else "no caustics" if not settings.caustics else "full"
        return RenderResult(rgba=rgba, meta={"integrator": how, "engine_settings": {"caustics": settings.caustics}})


def _pilot(
    engine: _Engine, estimate_over_target: float = 4.0, kind: str = "indirect", scene: bf.Scene | None = None
) -> dict[str, Any]:
    settings = resolve_settings(quality="final", seed=3)
    passes = settings.replace(target_error=None, time_limit=None, denoise=False)
    colours = [
        engine.render_scene(None, passes.replace(seed=pass_seed(3, i))).rgba[..., :3].astype(np.float64)  # type: ignore[index]
        for i in range(FIRST_PASSES)
    ]
    counts = [settings.samples] * FIRST_PASSES
    target = float(settings.target_error)  # type: ignore[arg-type]
    if scene is None:
        scene = _plastic_scene() if kind == "caustics" else _scene()
    return _effect_pilot(kind, engine, scene, settings, passes, colours, counts, estimate_over_target * target)  # type: ignore[arg-type]


def test_same_random_numbers_two_passes_decide():
    engine = _Engine(indirect=0.0, remainder=0.02)
    pilot = _pilot(engine)
    assert pilot["dropped"], pilot
    assert pilot["passes"] == PILOT_PASSES
    # the pilot's passes have the seeds of the first full passes
    assert engine.direct_seeds == [pass_seed(3, i) for i in range(PILOT_PASSES)]


def test_weakly_shared_random_numbers_more_passes_until_decided():
    """Mitsuba scalar_rgb's case: two pairs leave the bound above half the target though the light is absent."""
    # the full passes need ~600 more samples: a third pilot pass (48) would cost more than 1/16 of them
    two = _pilot(_Engine(indirect=0.0, remainder=1.0), estimate_over_target=3.07)
    assert two["passes"] == PILOT_PASSES and not two["dropped"], two
    assert two["indirect_error_low"] <= 0.5 * bf.FINAL_TARGET_ERROR < two["indirect_error"], two
    engine = _Engine(indirect=0.0, remainder=1.0)
    pilot = _pilot(engine, estimate_over_target=4.0)
    assert PILOT_PASSES < pilot["passes"] <= FIRST_PASSES, pilot
    assert pilot["dropped"], pilot
    assert pilot["indirect_error"] < two["indirect_error"]
    assert engine.direct_seeds == [pass_seed(3, i) for i in range(pilot["passes"])]


@pytest.mark.parametrize("remainder", [0.02, 1.0])
def test_clear_indirect_light_kept_after_two_passes(remainder):
    pilot = _pilot(_Engine(indirect=0.05, remainder=remainder))
    assert not pilot["dropped"], pilot
    assert pilot["passes"] == PILOT_PASSES
    assert pilot["indirect_error_low"] > 0.5 * bf.FINAL_TARGET_ERROR


def test_too_weakly_shared_keeps_the_light_after_every_pair():
    """When even all first full passes paired leave the bound above half the target, the light is kept."""
    pilot = _pilot(_Engine(indirect=0.0, remainder=2.0))
    assert pilot["passes"] == FIRST_PASSES, pilot
    assert not pilot["dropped"] and pilot["why"].startswith("kept: indirect light"), pilot


def test_pilot_never_costs_more_than_its_share(monkeypatch):
    """With the full passes needing little more, the undecided pilot stops instead of adding passes."""
    monkeypatch.setattr(render_module, "PILOT_MIN_GAIN", 16.0)
    # need_full = 64 x (2.2^2 x 1.1 - 1) = 277 samples: 2 x 16 x 16 = 512 > 277, the pilot is not even tried
    pilot = _pilot(_Engine(indirect=0.0, remainder=1.0), estimate_over_target=2.2)
    assert "passes" not in pilot and pilot["why"].startswith("not tried"), pilot


def test_caustics_pilot_drops_light_it_measures_below_half_the_target():
    engine = _Engine(indirect=0.002, remainder=0.02)
    pilot = _pilot(engine, kind="caustics")
    assert pilot["dropped"], pilot
    assert pilot["caustics_error"] <= 0.5 * bf.FINAL_TARGET_ERROR, pilot
    assert pilot["why"].startswith("caustics dropped (caustics=False)"), pilot
    assert engine.direct_seeds == [pass_seed(3, i) for i in range(PILOT_PASSES)]
    kept = _pilot(_Engine(indirect=0.05, remainder=0.02), kind="caustics")
    assert not kept["dropped"] and kept["caustics_error_low"] > 0.5 * bf.FINAL_TARGET_ERROR, kept


def test_caustics_pilot_weighs_its_samples_by_their_cost(monkeypatch):
    """A pilot sample dearer than a full one (Mitsuba's Python integrator) counts that many times: the same
    noise without the light pays at cost 1 and not at cost 30 (the pilot's ~280 samples against 5 % of the full
    passes' 112576), and the pilot is tried only when the full passes need PILOT_MIN_GAIN x its weighed cost."""
    monkeypatch.setattr(render_module, "DIRECT_SAMPLES_SLACK", 0.05)
    # need_full = 64 x (40^2 x 1.1 - 1) = 112576 samples >= 16 x 30 x 2 x 16: tried
    pilot = _pilot(_Engine(indirect=0.0, remainder=0.02, cost=30.0), estimate_over_target=40.0, kind="caustics")
    assert pilot["passes"] == PILOT_PASSES and pilot["sample_cost"] == 30.0, pilot
    assert not pilot["dropped"] and "each 30x the cost of a full one" in pilot["why"], pilot
    cheap = _pilot(_Engine(indirect=0.0, remainder=0.02, cost=1.0), estimate_over_target=40.0, kind="caustics")
    assert cheap["dropped"], cheap
    assert cheap["pilot_samples_needed"] == pilot["pilot_samples_needed"]
    # need_full = 64 x (4^2 x 1.1 - 1) = 1062 < 15360: not tried yet, to be retried after the next pass
    later = _pilot(_Engine(indirect=0.0, remainder=0.02, cost=30.0), estimate_over_target=4.0, kind="caustics")
    assert later.get("retry") and later["why"].startswith("not tried"), later


def test_a_pilot_counts_the_fixed_cost_of_its_render_calls():
    """On a small image a render call's fixed cost (scene update, film, read-back: Cycles about 30 ms) outweighs
    its samples: the pilot counts it for each of its passes and one switch of settings, so it is tried only
    where the full passes still need PILOT_MIN_GAIN x that; the decision stays a function of the pixels."""
    pixels = SHAPE[0] * SHAPE[1]
    # need_full = 64 x (4^2 x 1.1 - 1) = 1062 samples; 2 passes of 16 samples cost 32: tried without overhead
    free = _pilot(_Engine(indirect=0.0, remainder=0.02))
    assert free["passes"] == PILOT_PASSES and free["cost_in_samples"] == PILOT_PASSES * 16, free
    # 20 samples of fixed cost per call: 2 x (16 + 20) + 20 = 92, x 16 = 1472 > 1062: not tried yet
    dear = _pilot(_Engine(indirect=0.0, remainder=0.02, overhead=20.0 * pixels))
    assert dear.get("retry") and "a pass's fixed cost is 20 samples of this image" in dear["why"], dear
    # 10 samples per call: 2 x 26 + 10 = 62, x 16 = 992 <= 1062: tried, counted, and the same decision as free
    some = _pilot(_Engine(indirect=0.0, remainder=0.02, overhead=10.0 * pixels))
    assert some["cost_in_samples"] == 62 and some["dropped"] == free["dropped"], some
    assert some["pilot_samples_needed"] == free["pilot_samples_needed"]


class _Loading(_Engine):
    """A stand-in engine that loads the scene again for other settings (Mitsuba: 25-40 ms in scalar_rgb)."""

    def __init__(self, switch: float, **kw: Any) -> None:
        super().__init__(**kw)
        self.switch = switch

    def switch_overhead(self, settings: Any) -> float:
        return self.switch


def test_a_pilot_counts_the_switch_to_its_settings_once():
    """Switching to the pilot's settings (a translation and load) is counted once, at the engine's own
    cost: with 10 samples per call and 40 for the switch, 2 x 26 + 40 = 92, x 16 > 1062: not tried; with the
    switch costing one call (an engine without switch_overhead) the same pilot is tried."""
    pixels = SHAPE[0] * SHAPE[1]
    one_call = _pilot(_Engine(indirect=0.0, remainder=0.02, overhead=10.0 * pixels))
    assert one_call["cost_in_samples"] == 62, one_call
    loading = _pilot(_Loading(40.0 * pixels, indirect=0.0, remainder=0.02, overhead=10.0 * pixels))
    assert loading.get("retry") and "switching to the pilot's settings 40" in loading["why"], loading
    # 20 for the switch: 2 x 26 + 20 = 72, x 16 = 1152 > 1062 still; at 5x the target 1696 more: tried
    tried = _pilot(_Loading(20.0 * pixels, indirect=0.0, remainder=0.02, overhead=10.0 * pixels), 5.0)
    assert tried["cost_in_samples"] == 72 and tried["passes"] == PILOT_PASSES, tried


def test_caustics_pilot_not_tried_where_the_analysis_finds_none():
    pilot = _pilot(_Engine(indirect=0.0, remainder=0.02), kind="caustics", scene=_scene())  # all diffuse
    assert pilot["why"] == "not tried: the effect analysis already found no caustics", pilot


def test_a_dropped_effect_shows_in_how_the_picture_was_rendered(monkeypatch):
    """After the caustics pilot drops them, the picture is the passes without caustics: ``meta`` says how
    those were rendered (integrator, engine settings), not how the first full pass was."""
    monkeypatch.setattr(render_module, "PILOT_MIN_GAIN", 1.0)
    monkeypatch.setattr(render_module, "DIRECT_SAMPLES_SLACK", 2.0)  # the stand-in's noise is the same without
    engine = _Engine(indirect=0.002, remainder=0.02)
    settings = resolve_settings(quality="final", seed=3)
    r = render_module.render_to_target(engine, _plastic_scene(), settings)  # type: ignore[arg-type]
    assert r.meta["caustics_pilot"]["dropped"], r.meta["caustics_pilot"]
    assert "engine_meta" not in r.meta["caustics_pilot"]
    assert r.meta["integrator"] == "no caustics" and r.meta["engine_settings"] == {"caustics": False}
    kept = render_module.render_to_target(_Engine(indirect=0.05, remainder=0.02), _plastic_scene(), settings)  # type: ignore[arg-type]
    assert not kept.meta["caustics_pilot"]["dropped"] and kept.meta["integrator"] == "full"


def test_a_render_analyses_the_scene_once_for_all_its_pilot_rounds(monkeypatch):
    """render_to_target decides both pilots, and retries one as the estimate grows, from one effect analysis
    (each round analysed the scene again before: 7 analyses in one Mitsuba render of a plastic scene)."""
    calls = []
    analyse = render_module.analyse_effects
    monkeypatch.setattr(render_module, "analyse_effects", lambda scene: calls.append(1) or analyse(scene))
    settings = resolve_settings(quality="final", seed=3)
    result = render_module.render_to_target(_Engine(indirect=0.05, remainder=0.02), _plastic_scene(), settings)  # type: ignore[arg-type]
    meta = result.meta
    assert meta["caustics_pilot"]["why"] and meta["indirect_pilot"]["why"], meta
    assert len(calls) == 1
