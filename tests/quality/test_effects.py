"""analyse_effects: every flag on and off with its reason (the cases issue 7 names), and requested outputs:
a geometry-only request runs no lighting."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf

WHITE = bf.UniformColors((0.8, 0.8, 0.8))


def ball(material=None, colors=WHITE, light=True, floor=False, floor_kw=None) -> bf.Scene:
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.5, material or bf.DiffuseMaterial(), colors, tag="ball")
    if floor:
        s.renderables.add_plane_mesh(
            5.0, bf.DiffuseMaterial(), WHITE, translation=(0, 0, -0.5), tag="floor", **(floor_kw or {})
        )
    if light:
        s.lights.add_point(100.0, translation=(0, 0, 3))
    s.set_perspective_camera((32, 32), fov_x=0.8, translation=(0, -3, 0.5), rotation_mode="look_at", rotation=(0, 0, 0))
    return s


def pyramid() -> bf.Scene:
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])
    f = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]]
    s.renderables.add_mesh(v, f, bf.DiffuseMaterial(), WHITE, tag="pyramid")
    s.lights.add_sun(2.0)
    return s


def no_caster() -> bf.Scene:
    s = ball(floor=True)
    for r in s.renderables:
        r.emit_shadows = False
    return s


def with_background(kind: str) -> bf.Scene:
    s = ball(light=False)
    if kind == "light":
        s.lights.set_background_light(1.0)
    else:
        s.lights.set_environment_map(np.ones((4, 8, 3), np.float32))
    return s


GLASS = bf.PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0)
CASES = [
    # (id, scene builder, flag, expected, substring of the reason)
    ("shadows-light", lambda: ball(floor=True), "shadows", True, "casts shadows"),
    ("shadows-catcher", lambda: ball(floor=True, floor_kw={"shadow_catcher": True}), "shadows", True, "catcher"),
    ("shadows-no-caster", no_caster, "shadows", False, "no object casts"),
    ("shadows-no-light", lambda: ball(light=False), "shadows", False, "no light"),
    ("indirect-two-objects", lambda: ball(floor=True), "indirect_diffuse", True, "light each other"),
    ("indirect-concave", pyramid, "indirect_diffuse", True, "not convex"),
    ("indirect-see-through", lambda: ball(bf.DiffuseMaterial(alpha=0.5)), "indirect_diffuse", True, "see-through"),
    ("indirect-lone-convex", ball, "indirect_diffuse", False, "single convex"),
    ("glossy-metal", lambda: ball(bf.MetalMaterial()), "glossy", True, "specular material"),
    ("glossy-diffuse", ball, "glossy", False, "diffuse"),
    ("transmission-glass", lambda: ball(GLASS), "transmission", True, "transmissive"),
    ("transmission-none", ball, "transmission", False, "no transmissive"),
    ("caustics-glass-floor", lambda: ball(GLASS, floor=True), "caustics", True, "'ball' can focus light onto 'floor'"),
    ("caustics-rough-metal-floor", lambda: ball(bf.MetalMaterial(roughness=0.6), floor=True), "caustics", True, "onto"),
    ("caustics-no-receiver", lambda: ball(GLASS), "caustics", False, "no glossy or refractive"),
    ("caustics-no-light", lambda: ball(GLASS, light=False, floor=True), "caustics", False, "no glossy"),
    ("caustics-all-diffuse", lambda: ball(floor=True), "caustics", False, "no glossy"),
    ("transparency-alpha", lambda: ball(bf.DiffuseMaterial(alpha=0.5)), "transparency", True, "alpha < 1"),
    (
        "transparency-colour-alpha",
        lambda: ball(colors=bf.UniformColors((0.8, 0.8, 0.8, 0.5))),
        "transparency",
        True,
        "alpha < 1",
    ),
    ("transparency-opaque", ball, "transparency", False, "opaque"),
    (
        "emission-on",
        lambda: ball(bf.PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=3.0)),
        "emission",
        True,
        "material",
    ),
    ("emission-off", ball, "emission", False, "no emissive"),
    ("background-light", lambda: with_background("light"), "background", True, "background light"),
    ("background-environment", lambda: with_background("env"), "background", True, "environment map"),
    ("background-none", ball, "background", False, "no background"),
]


@pytest.mark.parametrize(("build", "flag", "expected", "reason"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_each_flag_on_and_off_with_its_reason(build, flag, expected, reason):
    e = bf.analyse_effects(build())
    assert getattr(e, flag) is expected, e.reasons[flag]
    assert reason in e.reasons[flag]
    assert set(e.reasons) == {
        "shadows",
        "indirect_diffuse",
        "glossy",
        "transmission",
        "caustics",
        "transparency",
        "emission",
        "background",
    }


def test_lone_sphere_needs_only_direct_light():
    e = bf.analyse_effects(ball())
    assert e.shadows and not (e.indirect_diffuse or e.glossy or e.transmission or e.caustics or e.transparency)


# -- requested outputs: geometry only -> no lighting ---------------------------------------------------
GEOMETRY = ("depth", "normal", "instance")


def _geometry_render(backend: str) -> bf.RenderResult:
    return bf.render(ball(floor=True), backend=backend, samples=16, outputs=GEOMETRY)


def test_meta_says_no_lighting_for_geometry_only(mitsuba):
    r = _geometry_render(mitsuba)
    assert r.rgba is None and r.meta["simulated"]["lighting"] is False
    assert r.meta["estimated_error"] is None and "no colour output" in r.meta["estimated_error_kind"]
    rgb = bf.render(ball(floor=True), backend=mitsuba, samples=16)
    assert rgb.meta["simulated"]["lighting"] is True


def test_mitsuba_geometry_only_casts_rays_without_lighting(mitsuba):
    t = _geometry_render(mitsuba).meta["timings"]
    assert "ray_cast" in t and "render_rgb" not in t


def test_pyrender_geometry_only_runs_no_colour_pass(pyrender):
    t = _geometry_render(pyrender).meta["timings"]
    assert "gbuffer" in t and "color" not in t


def test_cycles_geometry_only_runs_no_lighting(cycles):
    es = _geometry_render(cycles).meta["engine_settings"]
    assert es["geometry_only"] and es["samples"] == 1 and es["max_bounces"] == 0 and not es["denoise"]
