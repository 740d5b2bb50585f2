"""Quality presets and explicit overrides reach every backend and are recorded in result.meta (frozen
settings, per-phase timings, error estimate or why there is none)."""

from __future__ import annotations

import dataclasses

import pytest

import blendify_core as bf
from blendify_core.pipeline.settings import RenderSettings, resolve_settings
from blendify_core.testing import plane_scene


@pytest.mark.parametrize(
    ("quality", "samples", "denoise", "bounces", "target"),
    [("preview", 8, True, 4, None), ("draft", 32, True, 8, None), ("final", 16, False, 12, 0.01)],
)
def test_presets(quality, samples, denoise, bounces, target):
    s = resolve_settings(quality)
    assert (s.samples, s.denoise, s.max_bounces, s.target_error) == (samples, denoise, bounces, target)
    assert s.clamp_indirect == 0.0 and not s.adaptive and s.effects


def test_final_targets_an_error_unless_samples_or_denoise_are_fixed():
    assert resolve_settings("final").target_error == bf.FINAL_TARGET_ERROR
    assert resolve_settings("final", samples=64).target_error is None  # the user fixed the sample count
    assert resolve_settings("final", denoise=True).target_error is None  # denoised passes are not independent
    assert resolve_settings("final", samples=8, target_error=0.05).target_error == 0.05
    assert resolve_settings("final", target_error=0.03).samples == 16


def test_overrides_win_and_settings_are_frozen():
    s = resolve_settings(
        "draft", samples=5, denoise=False, max_bounces=3, time_limit=2.0, target_error=0.05, pixel_filter="gaussian",
        clamp_direct=1.0, clamp_indirect=10.0, adaptive=True, effects=False,
    )  # fmt: skip
    assert (s.samples, s.denoise, s.max_bounces, s.time_limit, s.target_error) == (5, False, 3, 2.0, 0.05)
    assert (s.pixel_filter, s.clamp_direct, s.clamp_indirect, s.adaptive, s.effects) == ("gaussian", 1, 10, True, False)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.samples = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kw", "arg"),
    [({"quality": "best"}, "quality"), ({"samples": 0}, "samples"), ({"target_error": -1}, "target_error"),
     ({"pixel_filter": "tent"}, "pixel_filter"), ({"clamp_indirect": -1}, "clamp_indirect")],
)  # fmt: skip
def test_bad_overrides_name_the_argument(kw, arg):
    with pytest.raises(ValueError, match=arg):
        resolve_settings(**kw)


OVERRIDES = {
    "samples": 5,
    "denoise": False,
    "max_bounces": 3,
    "pixel_filter": "gaussian",
    "clamp_direct": 4.0,
    "clamp_indirect": 2.0,
    "adaptive": True,
    "time_limit": 30.0,
    "effects": False,
}


def _render(backend: str) -> bf.RenderResult:
    return bf.render(plane_scene("sun", (16, 16)), backend=backend, quality="draft", **OVERRIDES)


def _common_meta(r: bf.RenderResult) -> None:
    st = r.meta["settings"]
    assert RenderSettings(**{**st, "outputs": tuple(st["outputs"])}).to_dict() == st
    for k, v in OVERRIDES.items():
        assert st[k] == v, k
    assert st["quality"] == "draft"
    assert {"translate", "render", "total"} <= set(r.meta["timings"])
    assert r.meta["timings"]["total"] >= r.meta["timings"]["render"] >= 0
    assert r.meta["estimated_error"] is None and r.meta["estimated_error_kind"].startswith("not estimated")
    assert r.meta["simulated"] == {"lighting": True, "effects": "full", "why": "effects=False: full settings requested"}


def test_cycles_receives_every_override(cycles):
    r = _render(cycles)
    _common_meta(r)
    es = r.meta["engine_settings"]
    assert es["samples"] == 5 and es["max_bounces"] == 3 and es["denoise"] is False and es["adaptive"] is True
    assert es["pixel_filter"] == ("GAUSSIAN", 1.5) and es["clamp_direct"] == 4.0 and es["clamp_indirect"] == 2.0
    assert es["time_limit"] == 30.0 and es["effects_used"] is False
    assert r.meta["timings"]["read_back"] >= 0  # Cycles measures its EXR read back separately


def test_cycles_effects_reach_the_bounce_limits(cycles):
    es = bf.render(plane_scene("sun", (16, 16)), backend=cycles, samples=4).meta["engine_settings"]
    assert es["effects_used"] is True
    assert es["transmission_bounces"] == 0 and es["transparent_max_bounces"] == 0


def test_mitsuba_receives_overrides(mitsuba):
    r = _render(mitsuba)
    _common_meta(r)
    assert r.meta["spp"] == 5 and r.meta["max_depth"] == 3 + 2 and r.meta["pixel_filter"] == "gaussian"
    # what Mitsuba cannot do is said, not silently dropped
    assert any("adaptive" in n for n in r.meta["notes"])
    assert "one pass" in r.meta["estimated_error_kind"]


def test_mitsuba_effects_choose_direct_lighting(mitsuba):
    r = bf.render(plane_scene("sun", (16, 16)), backend=mitsuba, samples=4)
    assert r.meta["max_depth"] == 2  # direct light only: one convex plane under a sun


def test_pyrender_records_settings(pyrender):
    r = bf.render(plane_scene("sun", (16, 16)), backend=pyrender, quality="preview")
    assert r.meta["settings"]["quality"] == "preview"
    assert {"translate", "render", "total"} <= set(r.meta["timings"])
    assert "raster" in r.meta["estimated_error_kind"]


def test_cycles_target_error_gives_an_estimate(cycles):
    r = bf.render(plane_scene("sun", (16, 16)), backend=cycles, samples=4, target_error=0.05)
    assert isinstance(r.meta["estimated_error"], float) and r.meta["passes"] >= 4


def test_mitsuba_target_error_gives_an_estimate(mitsuba):
    r = bf.render(plane_scene("background", (16, 16)), backend=mitsuba, samples=4, target_error=0.05)
    assert isinstance(r.meta["estimated_error"], float) and r.meta["passes"] >= 4
    assert r.meta["target_reached"] and r.meta["estimated_error"] <= 0.05
