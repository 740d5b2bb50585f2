"""The noise-aware colour verdict on real renders: one engine with two seeds agrees, the same engine with an
injected defect does not, and Cycles and Mitsuba agree within noise on the Lambertian canonical scenes.

(The calibration with many scenes and seeds is benchmarks/crosscheck_calibration.py; these are its smallest
cases, so a change that breaks the statistics or the passes fails here.)"""

from __future__ import annotations

import pytest
from xb_canonical import CANONICAL
from xb_util import require

import blendify_core as bf
from blendify_core.evaluate.crosscheck import FIXED_SETTINGS
from blendify_core.evaluate.noise import render_passes
from blendify_core.evaluate.tiers import choose_tier
from blendify_core.testing import calibration_scene

OPTIONS = {"cycles": {}, "mitsuba": {"variant": "scalar_rgb"}}


def _passes(scene: bf.Scene, engine: str, seed: int) -> bf.RenderResult:
    return render_passes(scene, engine, samples=64, passes=4, seed=seed, **FIXED_SETTINGS, **OPTIONS[engine])


@pytest.mark.parametrize("engine", list(OPTIONS))
def test_same_engine_two_seeds_agree_and_defects_fail(engine):
    require(engine)
    scene = calibration_scene(3, (48, 36))
    a, b = _passes(scene, engine, 0), _passes(scene, engine, 1000)
    assert a.meta["passes"] == 4 and a.rgb_var is not None
    same = bf.compare(a, b, scene=scene)
    assert same.noise is not None and same.passed, same.summary()
    mirrored = _passes(calibration_scene(3, (48, 36), defect="mirrored_texture"), engine, 2000)
    bad = bf.compare(mirrored, b, scene=scene)
    assert not bad.passed and bad.noise is not None and bad.noise.n_tile_reject > 0
    brighter = bf.RenderResult(rgba=a.rgba.copy(), rgb_var=a.rgb_var * 1.02**2, meta=dict(a.meta))
    brighter.rgba[..., :3] *= 1.02
    biased = bf.compare(brighter, b, scene=scene)
    assert not biased.passed and any("whole image" in r for r in biased.noise.reasons)


#: Lambertian canonical scenes (delta / area / sky light): Cycles and Mitsuba must agree within noise
LAMBERTIAN = ("plane_sun", "plane_point", "plane_area", "plane_background", "textured_quad", "faces_material")


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in LAMBERTIAN if n in CANONICAL])
def test_cycles_mitsuba_agree_within_noise_on_lambertian_scenes(name):
    require("cycles")
    require("mitsuba")
    build, spp, _ = CANONICAL[name]
    scene = build()
    assert choose_tier("cycles", "mitsuba", scene) in ("pathtracer_delta", "pathtracer")
    rep = bf.crosscheck(
        scene,
        backends=("cycles", "mitsuba"),
        samples=max(spp, 64),
        outputs=("rgb",),
        progress=False,
        backend_options={"mitsuba": {"variant": "scalar_rgb"}},
    )
    pair = rep.pairs[("cycles", "mitsuba")]
    assert pair.noise is not None and pair.passed, pair.summary()
