"""Every canonical scene (xb_canonical.CANONICAL) through every available backend pair, compared at the
tier ``choose_tier`` picks for the pair and the scene (the same run benchmarks/crosscheck_report.py
documents in docs/crosscheck.md). Mostly slow (96-128 px renders at up to 256 spp); the per-face-material
scene (Lambertian, delta sun, interreflections) runs by default."""

from __future__ import annotations

import pytest
from xb_canonical import CANONICAL
from xb_util import PAIRS, require

import blendify_core as bf
from blendify_core.evaluate.tiers import choose_tier

OUTPUTS = ("rgb", "depth", "normal", "albedo", "instance")

#: measured, understood differences (docs/crosscheck.md): (scene, backend in the pair) -> reason.
#: The pairs are xfail (not strict): when a backend fixes the cause, the test XPASSes and the entry goes.
KNOWN = {
    ("fuze", "cycles"): "Cycles' colour is 0.28 % brighter than Mitsuba's (global ratio 1.0028): the noise-aware "
    "test of bf.crosscheck rejects 4 of its tiles (global excess z 4.3); cause not found (the textured, "
    "smooth-shaded mesh: texture decoding or filtering). The albedo agrees to 0.65 % since both engines take "
    "it at the pixel centre (3.4 % while Cycles averaged it over the pixel); the smooth normals agree since "
    "every backend gets the IR's angle-weighted vertex normals (tests/crossbackend/test_xb_geometry.py)",
    ("shadow_catcher", "cycles"): "Cycles' albedo pass on the catcher is 1.205 where Mitsuba and pyrender give "
    "the material's 0.604 (twice as much: the catcher's shader mix is counted twice?); the shadow alpha differs "
    "(mean over the catcher: Cycles 0.027, Mitsuba 0.028, pyrender 0.017) and Cycles leaves a little colour on the "
    "catcher (premultiplied RGB 0.0013 per pixel, Mitsuba 0); the noise-aware test rejects 7 of its tiles. The "
    "ball agrees (summed RGB 463.0 vs 462.9). Cycles hides the catcher from reflections and bounced light "
    "(blendify 2.1's catcher), and so does Mitsuba's emulation since it takes the other objects' pixels from a "
    "render without the catcher",
    ("shadow_catcher", "pyrender"): "pyrender's shadow catcher only catches shadow-mapped sun/spot shadows (no "
    "sky occlusion): mean catcher alpha 0.017 vs 0.027-0.028; the ball is 1.14x the path tracers' (summed RGB "
    "530 vs 463: no sky occlusion on it either)",
}


#: cheap enough for the default run (the rest is @slow)
FAST = ("faces_material",)


@pytest.mark.parametrize("pair", PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=pytest.mark.slow) for n in CANONICAL])
def test_canonical_pair(renders, name, pair, artifacts_dir, request):
    a, b = pair
    require(a)
    require(b)
    build, spp, _ = CANONICAL[name]
    results = []
    for backend in pair:
        try:
            results.append(renders.get(f"canonical-{name}", backend, build, samples=spp, outputs=OUTPUTS))
        except bf.UnsupportedFeatureError as exc:
            print(f"SKIP: {exc}")
            pytest.skip(str(exc))
    for backend in pair:
        if (name, backend) in KNOWN:
            request.applymarker(pytest.mark.xfail(reason=KNOWN[(name, backend)], strict=False))
    tier = choose_tier(a, b, build())
    rep = bf.compare(results[0], results[1], tier=tier, names=pair)
    print(rep)
    if not rep.passed:
        rep.save(artifacts_dir)
    assert rep.passed, rep.summary()
