"""The integrator for lights that cast no shadow (blendify_mitsuba.integrator): with every light casting
shadows it renders what Mitsuba's own ``path`` renders; a light with ``use_shadow=False`` lights the plane
behind an occluder as if the occluder were not in its way (its shadow is gone, the rest unchanged)."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.integrator import INTEGRATOR, register
from blendify_mitsuba.translate import MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba


def _render(backend, scene, samples):
    return bf.render(scene, backend=backend, samples=samples, outputs=("rgb", "instance"), pixel_filter="box")


@pytest.mark.parametrize("light", ["point", "area"])
def test_same_as_path_when_every_light_casts_shadows(scalar_backend, mi_scalar, light):
    """Forced onto a scene whose lights all cast shadows, blendify_path gives path's image (same estimator:
    means within Monte-Carlo noise, also in the shadow and on the cube)."""
    scene = testing.occluder_scene(light, use_shadow=True, resolution=(24, 24))
    ref = _render(scalar_backend, scene, samples=64)
    assert ref.meta["integrator"] == "path"
    tr = MitsubaTranslator(resolve_settings(samples=64, pixel_filter="box")).translate(scene)
    d = dict(tr.scene_dict)
    assert register() == INTEGRATOR
    d["integrator"] = {**tr.integrator, "type": INTEGRATOR, "no_shadow": ""}
    img = np.array(mi_scalar.render(mi_scalar.load_dict(d), spp=64, seed=0))[..., :3]
    for region in (ref.instance == 0, ref.instance == 1):
        a, b = ref.rgba[region, :3].mean(), img[region].mean()
        print(f"{light}: path {a:.5f} blendify_path {b:.5f}")
        assert abs(b / a - 1) < 0.03


@pytest.mark.parametrize("light", ["point", "sun", "spot", "area", "area_disk"])
def test_no_shadow_light_ignores_the_occluder(scalar_backend, light):
    samples = 64 if light.startswith("area") else 4
    free = _render(scalar_backend, testing.occluder_scene(light, True, (24, 24), occluder=False), samples)
    shadowed = _render(scalar_backend, testing.occluder_scene(light, True, (24, 24)), samples)
    lit = _render(scalar_backend, testing.occluder_scene(light, False, (24, 24)), samples)
    assert lit.meta["integrator"] == INTEGRATOR and "light.no_shadow" not in lit.meta.get("approximations", {})
    plane = (lit.instance == 0) & (shadowed.instance == 0)
    shadow = plane & (shadowed.rgba[..., 0] < 0.8 * free.rgba[..., 0])
    assert shadow.sum() >= 4, "the cube must cast a shadow when the light casts shadows"
    f, s, n = (r.rgba[shadow, 0].mean() for r in (free, shadowed, lit))
    print(f"{light}: shadow region free {f:.4f} shadowed {s:.4f} use_shadow=False {n:.4f}")
    # the light's own light is back; the cube's bounce light only adds (a little) to it
    assert 0.97 * f < n < 1.15 * f
    if light.startswith("area"):
        return  # the cube's penumbra under the area light covers nearly all of the plane
    # where the cube casts no shadow, the pictures agree (the cube's indirect light aside)
    rest = plane & (shadowed.rgba[..., 0] > 0.97 * free.rgba[..., 0])
    assert rest.sum() > 100
    assert abs(lit.rgba[rest, 0].mean() / shadowed.rgba[rest, 0].mean() - 1) < 0.05


@pytest.mark.slow
def test_llvm_variant_renders_no_shadow_lights_as_scalar():
    """The integrator is written with Dr.Jit operations: the vectorised variant gives the scalar image."""
    from blendify_mitsuba.variant import choose_variant

    choice = choose_variant("llvm_ad_rgb")
    if choice.variant != "llvm_ad_rgb":
        print(f"llvm_ad_rgb is not usable here: {choice.reason}")
        pytest.skip(f"llvm_ad_rgb not usable here: {choice.reason}")
    for light in ("point", "area"):
        scene = testing.occluder_scene(light, False, (24, 24))
        with MitsubaBackend(variant="llvm_ad_rgb") as jit, MitsubaBackend(variant="scalar_rgb") as sc:
            a = _render(jit, scene, samples=64)
            b = _render(sc, scene, samples=64)
        assert a.meta["variant"] == "llvm_ad_rgb" and a.meta["integrator"] == INTEGRATOR
        plane = (a.instance == 0) & (b.instance == 0)
        ratio = a.rgba[plane, :3].mean() / b.rgba[plane, :3].mean()
        print(f"{light}: llvm / scalar on the plane {ratio:.4f}")
        assert abs(ratio - 1) < 0.02
