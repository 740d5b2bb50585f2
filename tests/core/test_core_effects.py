"""analyse_effects on small scenes: every flag switched on and off, with the reason that says why."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline.effects import Effects

WHITE = bf.UniformColors((0.8, 0.8, 0.8))
V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])
PYRAMID = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]]


def sphere_scene(material=None, colors=WHITE, light="point", **light_kw) -> bf.Scene:
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.5, material or bf.DiffuseMaterial(), colors, tag="ball")
    if light == "point":
        s.lights.add_point(100.0, translation=(0, 0, 3), **light_kw)
    elif light == "background":
        s.lights.set_background_light(1.0)
    elif light == "environment":
        s.lights.set_environment_map(np.ones((4, 8, 3), np.float32))
    return s


def add_floor(s: bf.Scene, material=None, **kw) -> bf.Scene:
    s.renderables.add_plane_mesh(
        5.0, material or bf.DiffuseMaterial(), WHITE, translation=(0, 0, -0.5), tag="floor", **kw
    )
    return s


def test_minimal_scene_needs_almost_nothing():
    e = bf.analyse_effects(sphere_scene(light="none"))
    assert dataclasses.astuple(e)[:8] == (False,) * 8
    assert e.reasons["shadows"] == "no light at all"
    assert e.reasons["indirect_diffuse"].startswith("a single convex object")
    assert e.reasons["glossy"] == "all materials are diffuse"
    assert e.reasons["emission"] == "no emissive material"
    assert e.reasons["background"] == "no background light"
    assert set(e.reasons) == {f.name for f in dataclasses.fields(Effects)} - {"reasons"}


# -- shadows ---------------------------------------------------------------------------------------


def test_shadows_on_with_a_shadow_casting_light():
    e = bf.analyse_effects(sphere_scene())
    assert e.shadows and e.reasons["shadows"] == "light 'Point_000' casts shadows"


def test_shadows_off_when_no_light_casts_shadows():
    e = bf.analyse_effects(sphere_scene(use_shadow=False))
    assert not e.shadows and e.reasons["shadows"] == "no light casts shadows"


def test_shadows_off_when_no_object_casts_shadows():
    s = add_floor(sphere_scene())
    for r in s.renderables:
        r.emit_shadows = False
    e = bf.analyse_effects(s)
    assert not e.shadows and e.reasons["shadows"] == "no object casts shadows"


def test_shadows_from_background_light_occlusion():
    e = bf.analyse_effects(sphere_scene(light="background"))
    assert e.shadows and "occluded" in e.reasons["shadows"]


def test_shadows_on_with_a_shadow_catcher():
    s = add_floor(sphere_scene(use_shadow=False), shadow_catcher=True)
    e = bf.analyse_effects(s)
    assert e.shadows and e.reasons["shadows"] == "shadow catcher 'floor'"


def test_shadow_catcher_reason_is_consistent_without_lights():
    s = add_floor(sphere_scene(light="none"), shadow_catcher=True)
    e = bf.analyse_effects(s)
    assert e.shadows and e.reasons["shadows"] == "shadow catcher 'floor'"


def test_zero_strength_lights_do_not_count():
    s = sphere_scene()
    s.lights["Point_000"].strength = 0.0
    e = bf.analyse_effects(s)
    assert not e.shadows and e.reasons["shadows"] == "no light at all"


# -- indirect diffuse ------------------------------------------------------------------------------


def test_indirect_diffuse_single_convex_off_two_objects_on():
    assert not bf.analyse_effects(sphere_scene()).indirect_diffuse
    e = bf.analyse_effects(add_floor(sphere_scene()))
    assert e.indirect_diffuse and e.reasons["indirect_diffuse"] == "2 objects can light each other"


@pytest.mark.parametrize(
    "shape", ["sphere", "ellipsoid", "cube-rotated-and-moved"], ids=["sphere", "ellipsoid", "cube"]
)
def test_indirect_diffuse_on_when_a_light_is_inside_a_closed_convex_object(shape):
    """A single convex object cannot light itself from outside, but a light inside a closed one lights its
    inside, which sees itself: inside a sphere the path tracers lost all indirect light (Cycles' mean 0.0132
    with 0 and with 12 bounces, Mitsuba 1.8x that with a glossy material)."""
    s = bf.Scene()
    if shape == "sphere":
        s.renderables.add_sphere_nurbs(2.0, bf.DiffuseMaterial(), WHITE, tag="room")
        inside, outside = (0, 0, 1.5), (0, 0, 2.5)
    elif shape == "ellipsoid":
        s.renderables.add_ellipsoid_nurbs((3.0, 1.0, 1.0), bf.DiffuseMaterial(), WHITE, tag="room")
        inside, outside = (2.5, 0, 0), (0, 1.5, 0)
    else:
        s.renderables.add_cube_mesh(
            2.0,
            bf.DiffuseMaterial(),
            WHITE,
            tag="room",
            rotation_mode="eulerXYZ",
            rotation=(0, 0, 0.7),
            translation=(10, 0, 0),
        )
        inside, outside = (10.9, 0, 0), (8.5, 0, 0)
    s.lights.add_point(10.0, translation=outside, tag="lamp")
    s.lights.add_sun(1.0)
    assert not bf.analyse_effects(s).indirect_diffuse
    s.lights["lamp"].translation = inside
    e = bf.analyse_effects(s)
    assert e.indirect_diffuse and "light inside" in e.reasons["indirect_diffuse"]


def test_indirect_diffuse_single_concave_mesh():
    s = bf.Scene()
    s.renderables.add_mesh(V, PYRAMID, bf.DiffuseMaterial(), WHITE, tag="pyramid")
    s.lights.add_point()
    e = bf.analyse_effects(s)
    assert e.indirect_diffuse and e.reasons["indirect_diffuse"] == "'pyramid' may see itself (not convex)"


# -- glossy, transmission, caustics ------------------------------------------------------------------


@pytest.mark.parametrize(
    "material",
    [
        bf.PrincipledBSDFMaterial(),
        bf.MetalMaterial(),
        bf.GlossyBSDFMaterial(),
        bf.PrincipledBSDFMaterial(roughness=1.0, specular_ior=0.0, coat_weight=0.5),
    ],
    ids=["principled-default", "metal", "glossy", "coat"],
)
def test_glossy_on_for_specular_materials(material):
    e = bf.analyse_effects(sphere_scene(material))
    assert e.glossy and e.reasons["glossy"] == "specular material on 'ball'"


def test_glossy_off_for_diffuse_only():
    e = bf.analyse_effects(add_floor(sphere_scene(bf.DiffuseMaterial())))
    assert not e.glossy and e.reasons["glossy"] == "all materials are diffuse"


def test_transmission_on_and_off():
    e = bf.analyse_effects(sphere_scene(bf.PrincipledBSDFMaterial(transmission_weight=1.0)))
    assert e.transmission and e.reasons["transmission"] == "transmissive material on 'ball'"
    e = bf.analyse_effects(sphere_scene())
    assert not e.transmission and e.reasons["transmission"] == "no transmissive material"


def test_caustics_need_a_sharp_specular_a_diffuse_receiver_and_light():
    sharp = bf.MetalMaterial(roughness=0.05)
    e = bf.analyse_effects(add_floor(sphere_scene(sharp)))
    assert e.caustics and e.reasons["caustics"] == "specular 'ball' can focus light onto 'floor'"
    glass = bf.PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.6)
    assert bf.analyse_effects(add_floor(sphere_scene(glass))).caustics  # refraction focuses even when rough
    # a rough glossy surface lighting a diffuse one still needs glossy-after-diffuse paths: measured in
    # Cycles, switching caustics off for a roughness-0.5 metal ball on a floor changed the image (z = 96)
    rough = bf.MetalMaterial(roughness=0.6)
    e = bf.analyse_effects(add_floor(sphere_scene(rough)))
    assert e.caustics
    diffuse_only = bf.analyse_effects(add_floor(sphere_scene(bf.DiffuseMaterial())))
    assert not diffuse_only.caustics
    assert not bf.analyse_effects(sphere_scene(sharp)).caustics  # nothing diffuse to receive
    assert not bf.analyse_effects(add_floor(sphere_scene(sharp, light="none"))).caustics  # no light


# -- transparency, emission, background -------------------------------------------------------------


def test_transparency_from_material_alpha_or_colour_alpha():
    e = bf.analyse_effects(sphere_scene(bf.DiffuseMaterial(alpha=0.5)))
    assert e.transparency and e.reasons["transparency"] == "alpha < 1 on 'ball'"
    e = bf.analyse_effects(sphere_scene(colors=bf.UniformColors((1, 1, 1, 0.3))))
    assert e.transparency
    e = bf.analyse_effects(sphere_scene(colors=bf.UniformColors((1, 1, 1, 1.0))))
    assert not e.transparency and e.reasons["transparency"] == "everything is opaque"


def test_emission_from_materials_and_point_clouds():
    e = bf.analyse_effects(sphere_scene(bf.PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=2)))
    assert e.emission and e.reasons["emission"] == "material of 'ball'"
    # a colour without strength, or strength without colour, emits nothing
    assert not bf.analyse_effects(sphere_scene(bf.PrincipledBSDFMaterial(emission_color=(1, 1, 1)))).emission
    assert not bf.analyse_effects(sphere_scene(bf.PrincipledBSDFMaterial(emission_strength=5.0))).emission
    s = bf.Scene()
    s.renderables.add_pointcloud(V, bf.DiffuseMaterial(), WHITE, particle_emission_strength=1.0, tag="pts")
    e = bf.analyse_effects(s)
    assert e.emission and e.reasons["emission"] == "point cloud 'pts' emits"
    assert e.reasons["shadows"] != "no light at all"  # emission is light


@pytest.mark.parametrize(("light", "reason"), [("background", "background light"), ("environment", "environment map")])
def test_background_on(light, reason):
    e = bf.analyse_effects(sphere_scene(light=light))
    assert e.background and e.reasons["background"] == reason


def test_background_off_at_zero_strength():
    s = sphere_scene(light="background")
    s.lights.set_background_light(0.0)
    e = bf.analyse_effects(s)
    assert not e.background and e.reasons["background"] == "no background light"


def test_effects_value_object():
    e = Effects.full()
    assert dataclasses.astuple(e)[:8] == (True,) * 8 and all(e.reasons.values())
    with pytest.raises(dataclasses.FrozenInstanceError):
        e.shadows = False  # type: ignore[misc]
    d = bf.analyse_effects(sphere_scene()).to_dict()
    assert set(d) == {
        "shadows",
        "indirect_diffuse",
        "glossy",
        "transmission",
        "caustics",
        "transparency",
        "emission",
        "background",
        "reasons",
    }


def test_every_feature_scene_needs_everything_but_transmission():
    from blendify_core.testing import every_feature_scene

    e = bf.analyse_effects(every_feature_scene())
    assert e.shadows and e.indirect_diffuse and e.glossy and e.transparency and e.emission and e.caustics
    assert not e.transmission


def test_many_objects_are_analysed_without_tessellating_them(monkeypatch):
    """The light-inside test tessellates an object (1 ms per sphere): it runs only where it decides something
    (a lone object, or one that could focus light onto itself), not for each of many objects that light each
    other anyway: 2000 spheres and 2000 cubes under 3 point lights took 3.3 s per analysis, now 0.095 s."""
    from blendify_core.ir.renderables.parametric import SphereNURBS
    from blendify_core.ir.renderables.primitives import MeshPrimitive

    calls = []
    for cls in (SphereNURBS, MeshPrimitive):
        original = cls.to_mesh
        monkeypatch.setattr(cls, "to_mesh", lambda self, *a, _o=original, **k: calls.append(1) or _o(self, *a, **k))
    s = bf.Scene()
    rng = np.random.default_rng(0)
    for i in range(40):
        s.renderables.add_sphere_nurbs(0.03, bf.DiffuseMaterial(), WHITE, translation=rng.normal(size=3), tag=f"s{i}")
        s.renderables.add_cube_mesh(0.03, bf.DiffuseMaterial(), WHITE, translation=rng.normal(size=3), tag=f"c{i}")
    s.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), WHITE, translation=(0, 0, 5), tag="lamp_shade")
    s.lights.add_point(10.0, translation=(0, 0, 5))  # inside "lamp_shade": lights it, but 81 objects do anyway
    e = bf.analyse_effects(s)
    assert e.indirect_diffuse and e.reasons["indirect_diffuse"] == "81 objects can light each other"
    assert not e.caustics and e.shadows
    assert calls == []
    s.bounds()  # the scene's bounds need no tessellation of spheres and mesh primitives either
    assert calls == []
