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


def _caustics_scene() -> bf.Scene:
    """A smooth plastic ball over a floor under a sun (the floor sees the sun in its coat)."""
    s = bf.Scene()
    s.set_orthographic_camera((24, 24), ortho_scale=2.0, translation=(0, 0, 3.0), near=0.1, far=10)
    s.renderables.add_sphere_nurbs(
        0.3, bf.PlasticMaterial(roughness=0.2), bf.UniformColors((0.8, 0.3, 0.2)), translation=(0, 0, 0.4)
    )
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.6,) * 3))
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    return s


def _alpha_scene() -> bf.Scene:
    """Two planes of alpha 0.3 over the floor, lit by a shadowing sun and a shadowless point light: the sun's
    shadow rays cross them (transparent shadows), the point light's are not traced."""
    s = bf.Scene()
    s.set_orthographic_camera((24, 24), ortho_scale=3.0, translation=(0, 0, 3.0), near=0.1, far=10)
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.6,) * 3))
    for i in range(2):
        s.renderables.add_plane_mesh(
            1.0,
            bf.PrincipledBSDFMaterial(alpha=0.3),
            bf.UniformColors((0.2, 0.7, 0.3)),
            translation=(0.4, 0, 0.5 + 0.1 * i),
        )
    s.lights.add_sun(2.0, rotation_mode="eulerXYZ", rotation=(20, 0, 0))
    s.lights.add_point(5.0, translation=(-0.5, 0.3, 1.0), use_shadow=False)
    return s


#: the integrator's code paths: shadowless lights, caustics off, transparent shadow rays with a shadowless light
#: (the scene, its settings and the objects compared region by region: the instance pass of an alpha surface is
#: stochastic, so only the floor there)
_JIT_CASES = {
    "no_shadow_point": (lambda: testing.occluder_scene("point", False, (24, 24)), {}, (0, 1)),
    "no_shadow_area": (lambda: testing.occluder_scene("area", False, (24, 24)), {}, (0, 1)),
    "caustics_off": (_caustics_scene, {"caustics": False}, (0, 1)),
    "transparent_shadows": (_alpha_scene, {}, (0,)),
}


@pytest.mark.parametrize("case", list(_JIT_CASES))
def test_llvm_variant_renders_as_scalar(case):
    """The integrator runs as one symbolic loop in the vectorised variants (the scalar ones run its body in
    Python): both give the same picture, as a whole and object by object (means within 2 %)."""
    from blendify_mitsuba.variant import choose_variant

    choice = choose_variant("llvm_ad_rgb")
    if choice.variant != "llvm_ad_rgb":
        print(f"llvm_ad_rgb is not usable here: {choice.reason}")
        pytest.skip(f"llvm_ad_rgb not usable here: {choice.reason}")
    make, settings, objects = _JIT_CASES[case]
    scene = make()
    with MitsubaBackend(variant="llvm_ad_rgb") as jit, MitsubaBackend(variant="scalar_rgb") as sc:
        a, b = (
            bf.render(
                scene, backend=be, samples=128, seed=3, outputs=("rgb", "instance"), pixel_filter="box", **settings
            )
            for be in (jit, sc)
        )
    for r, variant in ((a, "llvm_ad_rgb"), (b, "scalar_rgb")):
        assert r.meta["variant"] == variant and r.meta["integrator"] == INTEGRATOR, (variant, r.meta["integrator"])
    whole = a.rgba[..., :3].mean() / b.rgba[..., :3].mean()
    print(f"{case}: image llvm / scalar {whole:.4f}")
    assert abs(whole - 1) < 0.02, (case, whole)
    for obj in objects:
        region = (a.instance == obj) & (b.instance == obj)
        assert region.sum() >= 10
        ratio = a.rgba[region, :3].mean() / b.rgba[region, :3].mean()
        print(f"{case}: object {obj} ({region.sum()} px): llvm / scalar {ratio:.4f}")
        assert abs(ratio - 1) < 0.02, (case, obj, ratio)
