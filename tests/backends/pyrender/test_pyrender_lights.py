"""Every pair of light types with every combination of shadow flags renders in pyrender (two lights, one
casting shadows and one not, used to fail in pyrender's shadow pass), and each light keeps its own flag:
the picture of a pair is the sum of the pictures of its lights alone."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from blendify_core import render, testing

pytestmark = pytest.mark.pyrender

KINDS = ("point", "sun", "spot", "area_square", "area_disk")


def _add(scene, kind: str, shadow: bool, x: float) -> None:
    lights = scene.lights
    if kind == "point":
        lights.add_point(strength=20.0, translation=(x, 0, 2.0), use_shadow=shadow)
    elif kind == "sun":
        lights.add_sun(strength=1.0, use_shadow=shadow, rotation_mode="eulerXYZ", rotation=(0, 10 * x, 0))
    elif kind == "spot":
        lights.add_spot(strength=40.0, translation=(x, 0, 2.0), use_shadow=shadow)
    else:
        shape = "square" if kind == "area_square" else "circle"
        lights.add_area(shape, 0.5, strength=20.0, translation=(x, 0, 1.5), use_shadow=shadow)


def _scene(lights: list[tuple[str, bool, float]]):
    scene = testing.occluder_scene("point", True, (24, 24))
    for light in list(scene.lights):
        scene.lights.remove(light.tag)
    for kind, shadow, x in lights:
        _add(scene, kind, shadow, x)
    return scene


@pytest.mark.parametrize("a,b", list(itertools.combinations_with_replacement(KINDS, 2)))
def test_every_pair_of_lights_and_shadow_flags(pyr, a, b):
    for sa, sb in itertools.product((True, False), repeat=2):
        one = (a, sa, -0.3)
        two = (b, sb, 0.3)
        both = render(_scene([one, two]), backend=pyr, quality="preview", outputs=("rgb", "instance"))
        alone = [render(_scene([x]), backend=pyr, quality="preview").rgba[..., :3] for x in (one, two)]
        plane = both.instance == 0
        assert np.isfinite(both.rgba).all()
        # each light keeps its own shadow flag: the pair is the sum of the lights alone (8-bit output)
        total = (alone[0] + alone[1])[plane]
        err = np.abs(both.rgba[..., :3][plane] - total).mean() / total.mean()
        assert err < 0.03, f"{a} (shadow={sa}) + {b} (shadow={sb}): {err:.3f}"


@pytest.mark.parametrize("kind", ["sun", "spot", "area_square", "area_disk"])
def test_no_shadow_acne_on_a_lit_plane(pyr, kind):
    """A plane with nothing above it looks the same whether a tilted light 1 m above casts shadows or not: no
    self-shadowing (pyrender's own depth bias left sparse pixels up to 3 % darker under area lights)."""
    pose = dict(translation=(0, 0, 1.0), rotation_mode="eulerXYZ", rotation=(15, 0, 30))
    images = []
    for shadow in (True, False):
        scene = testing.plane_scene("point", resolution=(48, 48))
        for light in list(scene.lights):
            scene.lights.remove(light.tag)
        if kind == "sun":
            scene.lights.add_sun(strength=1.0, use_shadow=shadow, rotation_mode="eulerXYZ", rotation=(15, 0, 30))
        elif kind == "spot":
            scene.lights.add_spot(strength=15.0, spot_size=np.deg2rad(120), use_shadow=shadow, **pose)
        else:
            shape = "square" if kind == "area_square" else "circle"
            scene.lights.add_area(shape, 0.5, strength=15.0, use_shadow=shadow, **pose)
        images.append(render(scene, backend=pyr, quality="preview").rgba[..., :3])
    diff = np.abs(images[0] - images[1])
    print(f"{kind}: max difference with/without shadows {diff.max():.4f}")
    assert diff.max() < 1.5 / 255


# ---------------------------------------------------------------------------------------------------
# more lights of a type than pyrender binds per draw (4; more for a shadowed type where texture units allow)
# ---------------------------------------------------------------------------------------------------


def _many(shadow: bool) -> list[tuple[str, bool, float, float]]:
    """9 points, 6 spots, 5 suns and 6 area lights (3 square, 3 disc) spread over the plane, shadows as asked
    (every third light casts none when ``shadow``)."""
    out = []
    counts = (("point", 9), ("spot", 6), ("sun", 5), ("area_square", 3), ("area_disk", 3))
    i = 0
    for kind, n in counts:
        for k in range(n):
            x = -0.9 + 1.8 * k / max(n - 1, 1)
            out.append((kind, shadow and i % 3 != 0, x, 0.6 * (-1) ** i))
            i += 1
    return out


def _many_scene(lights, strength_scale: float = 0.15):
    scene = testing.occluder_scene("point", True, (32, 32))
    for light in list(scene.lights):
        scene.lights.remove(light.tag)
    for kind, shadow, x, y in lights:
        _add(scene, kind, shadow, x)
        light = list(scene.lights)[-1]
        light.strength *= strength_scale
        if kind != "sun":
            light.set_position(translation=light.translation + np.array([0.0, y, 0.0]))
    return scene


def _passes(pyr, monkeypatch) -> list[int]:
    """Counts the renderer's forward passes (one per light group and colour render)."""
    renderer = pyr.engine_instance.renderer
    calls = [0]
    original = renderer._forward_pass

    def counted(*args, **kwargs):
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(renderer, "_forward_pass", counted)
    return calls


@pytest.mark.parametrize("wide", [64, 4], ids=["wide-arrays", "groups"])
@pytest.mark.parametrize("shadow", [True, False], ids=["shadows", "shadowless"])
def test_every_light_of_many_is_shaded(pyr, monkeypatch, shadow, wide):
    """26 lights (9 points, 6 spots, 5 suns, 6 area lights; pyrender binds 4 of a type per draw, or more of a
    shadowed type where texture units allow) light the plane and cube as the sum of the pictures of each light
    alone, the indirect-light probe's own renders included: types without shadow maps bound up to 64 per
    draw, or (``wide`` = 4, as pyrender) in groups of lights that fit, rendered and summed. Before, the nearest
    4 of each type were shaded (the approximation line is gone)."""
    import blendify_pyrender.probe as probe
    import blendify_pyrender.render as pr

    monkeypatch.setattr(pr, "MAX_UNSHADOWED_LIGHTS", wide)
    # one probe: a grid's probes next to the cube give each fragment strongly directional coefficients, whose
    # radiance clamped at 0 is not additive over lights (0.4 % here; 0.05 % without the clamp)
    monkeypatch.setattr(probe, "GRID", 1)
    lights = _many(shadow)
    every = render(_many_scene(lights), backend=pyr, quality="preview", outputs=("rgb", "instance"))
    assert not any(a.startswith("lights:") for a in every.meta["approximations"]), every.meta["approximations"]
    total = np.zeros_like(every.rgba[..., :3])
    for light in lights:
        total += render(_many_scene([light]), backend=pyr, quality="preview").rgba[..., :3]
    lit = every.instance >= 0
    err = np.abs(every.rgba[..., :3][lit] - total[lit])
    print(f"shadow={shadow}: mean |all - sum of each alone| / mean {err.mean() / total[lit].mean():.2e}")
    assert err.mean() < 2e-3 * total[lit].mean()
    assert err.max() < 2e-2 * total[lit].max()


def test_lights_at_the_limit_render_in_one_pass(pyr, monkeypatch):
    """4 lights of each type fit one pass: one forward pass per colour render, the picture as before; a fifth
    point light still renders in one pass (its shader binds up to 8) and adds its light."""
    import blendify_pyrender.render as pr

    lights = [x for x in _many(False) if x[0] in ("point", "sun", "spot")]
    at_limit = [x for k in ("point", "sun", "spot") for x in [y for y in lights if y[0] == k][:4]]
    scene = _many_scene(at_limit)
    calls = _passes(pyr, monkeypatch)
    monkeypatch.setattr(pr, "PROBE", False)  # the colour render alone (the probe renders 6 more per bounce)
    one = render(scene, backend=pyr, quality="preview", outputs=("rgb",))
    assert calls[0] == 1
    monkeypatch.setattr(pr, "LIGHT_GROUPS", False)
    assert np.array_equal(render(scene, backend=pyr, quality="preview", outputs=("rgb",)).rgba, one.rgba)
    monkeypatch.setattr(pr, "LIGHT_GROUPS", True)
    fifth = [x for x in lights if x[0] == "point"][4]
    calls[0] = 0
    more = render(_many_scene(at_limit + [fifth]), backend=pyr, quality="preview", outputs=("rgb",))
    assert calls[0] == 1
    alone = render(_many_scene([fifth]), backend=pyr, quality="preview", outputs=("rgb",)).rgba[..., :3]
    np.testing.assert_allclose(more.rgba[..., :3], one.rgba[..., :3] + alone, rtol=1e-4, atol=1e-5)


@pytest.mark.slow  # ~20 s: 27 shadow maps
def test_shadowed_spots_beyond_the_texture_units(pyr, monkeypatch):
    """Spot lights with shadow maps are bound as many as texture units allow (pyrender's count on this driver);
    one more takes a second pass, and every spot keeps its shadow: the picture is the sum of each alone."""
    import blendify_pyrender.render as pr
    from pyrender.constants import RenderFlags

    monkeypatch.setattr(pr, "PROBE", False)
    render(_many_scene([("spot", True, 0.0, 0.0)]), backend=pyr, quality="preview")  # the context exists
    fit = pyr.engine_instance.renderer._compute_max_n_lights(RenderFlags.SHADOWS_SPOT)[1]
    spots = [("spot", True, -0.9 + 1.8 * k / fit, 0.5 * (-1) ** k) for k in range(fit + 1)]
    calls = _passes(pyr, monkeypatch)
    every = render(_many_scene(spots, 1.0 / len(spots)), backend=pyr, quality="preview", outputs=("rgb",))
    assert calls[0] == 2
    total = sum(render(_many_scene([x], 1.0 / len(spots)), backend=pyr, quality="preview").rgba[..., :3] for x in spots)
    err = np.abs(every.rgba[..., :3] - total)
    print(f"{len(spots)} shadowed spots: mean |all - sum of each alone| / mean {err.mean() / total.mean():.2e}")
    assert err.mean() < 1e-4 * total.mean()


@pytest.mark.parametrize("antialias,samples", [("coverage", 8), ("coverage", 1), ("msaa", 8), ("ssaa", 8)])
def test_many_lights_in_every_antialiasing_mode(monkeypatch, antialias, samples):
    """Light groups (4 lights per pass, as pyrender) in every anti-aliasing mode (samples=1: none), a
    translucent cube and a cloud of spheres (blended edges) included: the picture is that of one pass binding
    every light (to float rounding, 1e-5), the colour the sum of each light's alone (to the indirect-light probe's
    clamp of negative SH lobes, which is not linear in the lights: 3e-4) and the alpha (coverage x opacity)
    that of one pass."""
    import blendify_pyrender.render as pr
    from blendify_pyrender import PyrenderBackend

    from blendify_core import DiffuseMaterial, UniformColors

    monkeypatch.setattr(pr, "MAX_UNSHADOWED_LIGHTS", 4)
    pts = np.random.default_rng(3).uniform((-0.8, -0.8, 0.05), (-0.2, -0.2, 0.4), size=(40, 3))
    lights = [x for x in _many(True) if x[0] == "point"]

    def scene_of(subset):
        scene = _many_scene(subset)
        for tag in ("plane", "cube"):
            scene.renderables.remove(tag)
        grey = UniformColors((0.5,) * 3)
        scene.renderables.add_plane_mesh(1.2, DiffuseMaterial(), grey, tag="plane")  # edges in view
        scene.renderables.add_cube_mesh(0.4, DiffuseMaterial(alpha=0.4), grey, translation=(0.75, 0.1, 0.5))
        scene.renderables.add_pointcloud(pts, DiffuseMaterial(), grey, point_size=0.06)
        return scene

    kw = dict(quality="preview", samples=samples, transparent_background=True)
    with PyrenderBackend(antialias=antialias, supersample=2) as be:
        every = render(scene_of(lights), backend=be, **kw)
        alone = [render(scene_of([x]), backend=be, **kw).rgba for x in lights]
        monkeypatch.setattr(pr, "MAX_UNSHADOWED_LIGHTS", 64)  # one pass with all 9 lights
        be.engine_instance.renderer.probe_cache = None
        one_pass = render(scene_of(lights), backend=be, **kw).rgba
    # to float rounding (the probe grid's texture stores what its renders summed in another order: 6e-6)
    np.testing.assert_allclose(every.rgba, one_pass, rtol=1e-3, atol=2e-5)
    assert every.meta["antialiasing"]["mode"] == ("none" if samples == 1 else antialias)
    total = np.sum([a[..., :3] for a in alone], axis=0)
    err = np.abs(every.rgba[..., :3] - total)
    print(f"{antialias}/{samples}: mean |all - sum of each alone| / mean {err.mean() / total.mean():.2e}")
    assert err.mean() < 2e-3 * total.mean()
    np.testing.assert_allclose(every.rgba[..., 3], alone[0][..., 3], atol=1e-6)
    a = every.rgba[..., 3]
    assert ((a > 0.5) & (a < 0.8)).sum() > 10, "the translucent cube (two faces: alpha 0.64) over the background"
    assert ((a > 0.02) & (a < 0.98)).sum() > 20, "anti-aliased edges"
