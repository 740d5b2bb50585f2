"""Parameters declared once (blendify_core/ir/params.py): every default is the declaration's, the one
validation policy holds for every declared parameter (ranges, Blender clamp ranges with a warning,
booleans, numbers), every parameter survives a scene file, and docs/parameters.md is current."""

from __future__ import annotations

import datetime
import inspect
import warnings
from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import NormalMap, TextureMap
from blendify_core.ir.lights import BackgroundLight, EnvironmentMap, LightsCollection
from blendify_core.ir.paramdocs import parameters_markdown
from blendify_core.ir.params import POSE, REQUIRED, TAG, BlenderClampWarning, Param
from blendify_core.ir.renderables import RenderablesCollection
from blendify_core.ir.types import LIGHT_TYPES, MATERIAL_TYPES, WORLD_TYPES

DECLARED = MATERIAL_TYPES + LIGHT_TYPES + WORLD_TYPES
REPO = Path(__file__).resolve().parents[2]
ENV_IMAGE = np.ones((2, 4, 3), np.float32)


def _make(cls: type, **kwargs):
    """An instance of ``cls`` with its required inputs filled in."""
    if cls is bf.AreaLight:
        kwargs = {"shape": "rectangle", "size": (1.0, 2.0), **kwargs}
    if cls is EnvironmentMap:
        kwargs = {"image_or_path": ENV_IMAGE, **kwargs}
    return cls(**kwargs)


def _float_params():
    for cls in DECLARED:
        for p in cls._stored:
            if p.kind == "float":
                yield pytest.param(cls, p, id=f"{cls.__name__}.{p.name}")


# ---------------------------------------------------------------------------------------------------
# one declaration: signatures, defaults and attributes come from it
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", DECLARED, ids=lambda c: c.__name__)
def test_every_signature_default_is_the_declared_default(cls):
    sig = inspect.signature(cls)
    assert sig == inspect.signature(cls.__init__).replace(parameters=list(sig.parameters.values()))
    named = [p for p in sig.parameters.values() if p.kind is p.POSITIONAL_OR_KEYWORD]
    assert [p.name for p in named] == list(cls._positional)
    for p in named:
        declared = cls._param_index[p.name]
        expected = inspect.Parameter.empty if declared.default is REQUIRED else declared.default
        assert p.default == expected, (cls.__name__, p.name)
    # every declared default is what a new object holds (after validation)
    obj = _make(cls)
    for p in cls._stored:
        if p.default is REQUIRED:
            continue
        value = getattr(obj, p.name)
        if p.name == "color_space" and cls is EnvironmentMap:
            assert value == "linear"  # None: decided from the float image
        elif p.kind == "color":
            assert value == tuple(p.default), p.name
        else:
            assert value == p.default, (cls.__name__, p.name, value)


@pytest.mark.parametrize(
    ("method", "cls"),
    [
        (LightsCollection.add_point, bf.PointLight),
        (LightsCollection.add_sun, bf.SunLight),
        (LightsCollection.add_spot, bf.SpotLight),
        (LightsCollection.add_area, bf.AreaLight),
        (LightsCollection.set_background_light, BackgroundLight),
        (LightsCollection.set_environment_map, EnvironmentMap),
        (RenderablesCollection.add_mesh, bf.Mesh),
        (RenderablesCollection.add_pointcloud, bf.PointCloud),
        (RenderablesCollection.add_cube_mesh, bf.CubeMesh),
        (RenderablesCollection.add_circle_mesh, bf.CircleMesh),
        (RenderablesCollection.add_cylinder_mesh, bf.CylinderMesh),
        (RenderablesCollection.add_plane_mesh, bf.PlaneMesh),
        (RenderablesCollection.add_sphere_nurbs, bf.SphereNURBS),
        (RenderablesCollection.add_ellipsoid_nurbs, bf.EllipsoidNURBS),
        (RenderablesCollection.add_curve_nurbs, bf.CurveBezier),
    ],
    ids=lambda x: getattr(x, "__name__", ""),
)
def test_facades_take_their_parameters_from_the_class(method, cls):
    """An add_* method lists its class's parameters (same names, order, defaults), then the pose and tag."""
    facade = [p for p in inspect.signature(method).parameters.values() if p.name != "self"]
    own = [p for p in inspect.signature(cls).parameters.values() if p.kind is p.POSITIONAL_OR_KEYWORD]
    if cls in (BackgroundLight, EnvironmentMap):  # set_*: exactly the class's signature
        assert facade == own
    else:
        own = [p for p in own if p.name not in ("tag", *(q.name for q in POSE))]
        assert facade[: len(own)] == own
        rest = [p.name for p in facade[len(own) :]]
        assert rest[:4] == ["rotation_mode", "rotation", "translation", "tag"]
        assert [p.default for p in facade[len(own) : len(own) + 4]] == [q.default for q in (*POSE, TAG)]
    assert inspect.signature(method).return_annotation == cls.__name__


def test_presets_declare_only_what_they_change():
    base = {p.name: p.default for p in bf.PrincipledBSDFMaterial._params}
    for cls in (bf.MetalMaterial, bf.PlasticMaterial, bf.DiffuseMaterial, bf.MetalWireframeMaterial):
        m = cls()
        for name, default in base.items():
            assert getattr(m, name) == cls._preset.get(name, default), (cls.__name__, name)
    assert bf.MetalMaterial().roughness == 0.55 and bf.DiffuseMaterial().specular_ior == 0.0


def test_backends_read_attributes_and_core_code_no_parameter_dicts():
    """Nothing in blendify_core reads ``.parameters()`` (a public convenience for users); defaults are
    never re-stated as fallbacks."""
    users = [
        str(path.relative_to(REPO))
        for path in (REPO / "blendify_core").rglob("*.py")
        if ".parameters()" in path.read_text(encoding="utf-8") and path.name != "params.py"
    ]
    assert users == []
    mat = bf.PlasticMaterial(roughness=0.2)
    assert mat.roughness == mat.parameters()["roughness"] == 0.2


# ---------------------------------------------------------------------------------------------------
# the one validation policy
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cls", "name", "value", "clamped"),
    [
        (bf.PrincipledBSDFMaterial, "coat_ior", 0.0, 1.0),
        (bf.PrincipledBSDFMaterial, "coat_ior", 0.2, 1.0),
        (bf.MetalMaterial, "coat_ior", 0.8, 1.0),
        (bf.PlasticWireframeMaterial, "coat_ior", 0.1, 1.0),
        (bf.PrincipledBSDFMaterial, "subsurface_anisotropy", -0.5, 0.0),
        (bf.PrincipledBSDFMaterial, "subsurface_anisotropy", -1.0, 0.0),
        (bf.PrincipledBSDFMaterial, "subsurface_anisotropy", 0.95, 0.9),
        (bf.PrincipledBSDFMaterial, "subsurface_anisotropy", 1.0, 0.9),
    ],
)
def test_a_value_in_a_blender_clamp_range_is_clamped_with_a_warning_naming_it(cls, name, value, clamped):
    with pytest.warns(BlenderClampWarning, match=name) as record:
        mat = cls(**{name: value})
    assert getattr(mat, name) == clamped
    assert Path(record[0].filename).resolve() == Path(__file__).resolve()  # points at the caller's line
    mat = cls()
    rev = mat.revision
    with pytest.warns(BlenderClampWarning, match=name):
        setattr(mat, name, value)
    assert getattr(mat, name) == clamped and mat.revision == rev + 1


def test_values_inside_the_valid_range_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mat = bf.PrincipledBSDFMaterial(coat_ior=1.0, subsurface_anisotropy=0.9)
        mat.coat_ior = 4.0
        mat.subsurface_anisotropy = 0.0


@pytest.mark.parametrize(("cls", "p"), list(_float_params()))
def test_outside_the_valid_range_raises_naming_the_parameter(cls, p):
    lows = [c.low for c in p.clamps] + ([p.min_value] if p.min_value is not None else [])
    highs = [c.high for c in p.clamps] + ([p.max_value] if p.max_value is not None else [])
    bad = ([min(lows) - 0.5] if lows else []) + ([max(highs) + max(0.5, max(highs) / 2)] if highs else [])
    assert bad, f"{p.name} has no range to test"
    for value in bad:
        with pytest.raises(InvalidSceneError, match=p.name):
            _make(cls, **{p.name: value})
        obj = _make(cls)
        before = getattr(obj, p.name)
        with pytest.raises(InvalidSceneError, match=p.name):
            setattr(obj, p.name, value)
        assert getattr(obj, p.name) == before


@pytest.mark.parametrize(("cls", "p"), list(_float_params()))
def test_numbers_are_real_numbers_only(cls, p):
    junk = ["0.5", b"0.5", 0.5j, True, np.bool_(False), None, float("nan"), float("inf"), -float("inf")]
    junk += [datetime.timedelta(seconds=1), datetime.date(2024, 1, 1), np.datetime64("2024-01-01"), [0.5, 0.5]]
    obj = _make(cls)
    for value in junk:
        with pytest.raises(InvalidSceneError, match=p.name):
            setattr(obj, p.name, value)


@pytest.mark.parametrize("text", ["no", "False", "false", "0", "yes", "True"])
def test_booleans_given_as_strings_raise(text):
    s = bf.Scene()
    with pytest.raises(InvalidSceneError, match="use_shadow"):
        s.lights.add_point(use_shadow=text)
    with pytest.raises(InvalidSceneError, match="use_shadow"):
        bf.SunLight(use_shadow=text)
    light = s.lights.add_spot()
    with pytest.raises(InvalidSceneError, match="use_shadow"):
        light.use_shadow = text
    assert light.use_shadow is True
    sphere = s.renderables.add_sphere_nurbs(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    with pytest.raises(InvalidSceneError, match="emit_shadows"):
        sphere.emit_shadows = text
    with pytest.raises(InvalidSceneError, match="shadow_catcher"):
        s.renderables.add_plane_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), shadow_catcher=text)


def test_booleans_are_bool_numpy_bool_or_0_and_1():
    lights = bf.Scene().lights
    for value, expected in ((True, True), (np.bool_(False), False), (0, False), (1, True), (np.int64(1), True)):
        light = lights.add_point(use_shadow=value)
        assert light.use_shadow is expected
        light.use_shadow = not expected
        assert light.use_shadow is (not expected)
    for value in (2, -1, 0.0, 1.0, None, [], np.array([True])):
        with pytest.raises(InvalidSceneError, match="use_shadow"):
            lights.add_point(use_shadow=value)


def test_colours_check_their_channel_count():
    with pytest.raises(InvalidSceneError, match=r"emission_color: expected 3 \(RGB\) or 4 \(RGBA\)"):
        bf.PrincipledBSDFMaterial(emission_color=(1.0, 0.0))
    with pytest.raises(InvalidSceneError, match=r"color: expected 3 \(RGB\) values, got 4"):
        bf.PointLight(color=(0.5, 0.25, 1.0, 0.3))  # a light has no alpha: RGB only
    with pytest.raises(InvalidSceneError, match="color"):
        bf.PointLight(color=(0.5, 0.25, 1.0, 0.3, 0.1))


def test_unknown_repeated_surplus_and_missing_arguments_raise_naming_them():
    with pytest.raises(InvalidSceneError, match="clearcoat"):
        bf.MetalMaterial(clearcoat=1.0)
    with pytest.raises(InvalidSceneError, match="roughness"):
        bf.MetalMaterial(0.5, roughness=0.5)
    with pytest.raises(InvalidSceneError, match="positional"):
        bf.GlossyBSDFMaterial(0.4, "GGX", 1.0, "srgb", 5)
    with pytest.raises(InvalidSceneError, match="metallic"):
        bf.GlossyBSDFMaterial(metallic=0.5)  # only its own parameters
    with pytest.raises(InvalidSceneError, match="shape"):
        bf.AreaLight(size=1.0)
    with pytest.raises(InvalidSceneError, match="add_sun"):
        bf.Scene().lights.add_sun(power=3.0)
    with pytest.raises(InvalidSceneError, match="color_space"):
        bf.PrincipledBSDFMaterial().color_space = "linear"  # fixed at creation, not a parameter


def test_choices_are_case_insensitive_and_stored_as_declared():
    assert bf.GlossyBSDFMaterial(distribution="beckmann").distribution == "BECKMANN"
    assert bf.PrincipledBSDFMaterial(distribution="ggx").distribution == "GGX"
    assert bf.Scene().lights.add_area("Square", 1.0).shape == "square"


def test_declaration_mistakes_fail_when_the_class_is_defined():
    with pytest.raises(TypeError, match="kind"):
        Param("x", 0.0, "double")
    with pytest.raises(TypeError, match="undeclared"):

        class Broken(bf.PrincipledBSDFMaterial):
            _preset = {"roughnes": 0.3}

    with pytest.raises(TypeError, match="signature"):

        class AlsoBroken(bf.PrincipledBSDFMaterial):
            _signature = bf.MetalMaterial._signature.__class__(("nope",), None)


def test_a_user_subclass_with_its_own_init_keeps_its_own_signature():
    class Shiny(bf.MetalMaterial):
        def __init__(self, shine: float = 1.0):
            super().__init__(roughness=1.0 - shine)

    assert list(inspect.signature(Shiny).parameters) == ["shine"]
    assert Shiny(0.75).roughness == 0.25


# ---------------------------------------------------------------------------------------------------
# scene files: every parameter round-trips
# ---------------------------------------------------------------------------------------------------


def _other(p: Param, default):
    """A valid value of ``p`` different from ``default``."""
    if p.kind == "float":
        if p.min_value is not None and p.max_value is not None:
            value = p.min_value + 0.37 * (p.max_value - p.min_value)
        else:
            value = (p.min_value or 0.0) + 0.73
        return value if value != default else value / 2
    if p.kind == "bool":
        return not default
    if p.kind == "choice":
        return next(c for c in p.choices if c != default)
    if p.kind == "color":
        return (0.2, 0.4, 0.6, 0.8)[: len(default)]
    if p.kind == "vec3":
        return (0.3, 0.4, 0.5)
    if p.kind == "texture":
        return TextureMap(np.linspace(0, 1, 12).reshape(3, 4), channel=0)
    if p.kind == "normal_map":
        return NormalMap(np.full((2, 2, 3), 0.5), strength=0.5)
    raise AssertionError(f"no test value for {p.name} ({p.kind})")


def _same(a, b) -> bool:
    if isinstance(a, TextureMap):
        return (
            type(a) is type(b)
            and np.array_equal(a.values(), b.values())
            and getattr(a, "channel", None) == getattr(b, "channel", None)
            and getattr(a, "strength", None) == getattr(b, "strength", None)
        )
    return a == b


def test_every_parameter_round_trips_through_a_scene_file(tmp_path):
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    uv = bf.VertexUV(v[:, :2])
    materials = []
    for cls in MATERIAL_TYPES:
        # DiffuseMaterial: only what keeps it Lambertian is settable (the rest raises, test_bad_inputs_round2)
        changes = {p.name: _other(p, p.default) for p in cls._params if p.name not in cls._fixed_params}
        mat = cls(color_space="linear", **changes)
        for name, value in changes.items():
            assert _same(getattr(mat, name), value if not isinstance(value, tuple) else tuple(value)), name
        materials.append(mat)
        scene.renderables.add_mesh(v, [[0, 1, 2]], mat, bf.UniformColors((1, 1, 1)), uv_map=uv, tag=cls.__name__)
    lights = []
    for cls in LIGHT_TYPES:
        changes = {p.name: _other(p, p.default) for p in cls._stored if p.name not in ("shape", "size")}
        shape = {"shape": "ellipse", "size": (1.5, 2.5)} if cls is bf.AreaLight else {}
        light = cls(**shape, **changes)
        lights.append(scene.lights._add(light, cls.__name__))
    scene.lights._add(bf.AreaLight("square", 0.75), "square")
    bg = scene.lights.set_background_light(**{p.name: _other(p, p.default) for p in BackgroundLight._stored})
    env = scene.lights.set_environment_map(ENV_IMAGE * 2, strength=3.5, color_space="srgb")
    scene.save(tmp_path / "params.npz")
    loaded = bf.Scene.load(tmp_path / "params.npz")
    for mat in materials:
        other = loaded.renderables[type(mat).__name__].material
        assert type(other) is type(mat) and other.color_space == "linear"
        for p in type(mat)._params:
            assert _same(getattr(other, p.name), getattr(mat, p.name)), (type(mat).__name__, p.name)
    for light in lights:
        other = loaded.lights[light.tag]
        assert type(other) is type(light)
        assert other.parameters() == light.parameters(), light.tag
    assert loaded.lights["square"].size == (0.75, 0.75)
    assert loaded.lights.background.parameters() == bg.parameters()
    assert loaded.lights.environment.parameters() == env.parameters() == {"strength": 3.5, "color_space": "srgb"}
    assert loaded.fingerprint() == scene.fingerprint()


def test_scene_files_refuse_unknown_parameters(tmp_path):
    from blendify_core.ir.serialize import light_from_dict, material_from_dict

    d = bf.PlasticMaterial().to_dict({}, "m.")
    d["params"]["clearcoat"] = 0.5
    with pytest.raises(InvalidSceneError, match="clearcoat"):
        material_from_dict(d, {})
    light = bf.Scene().lights.add_point()
    d = light.to_dict()
    d["params"]["radius"] = 1.0
    with pytest.raises(InvalidSceneError, match="radius"):
        light_from_dict(d)


# ---------------------------------------------------------------------------------------------------
# docs
# ---------------------------------------------------------------------------------------------------


def test_docs_parameters_md_is_current():
    path = REPO / "docs" / "parameters.md"
    assert path.is_file(), f"{path} is missing: run `python -m blendify_core.ir.paramdocs`"
    assert path.read_text(encoding="utf-8") == parameters_markdown(), (
        "docs/parameters.md is stale: run `uv run --no-sync python -m blendify_core.ir.paramdocs`"
    )


def test_docs_list_every_declared_parameter_with_its_clamp():
    text = parameters_markdown()
    for cls in DECLARED:
        for p in cls._stored:
            assert f"| `{p.name}` |" in text, (cls.__name__, p.name)
    assert "| `coat_ior` | float | 1.5 | [1, 4] | - | [0, 1) -> 1 |" in text
    conventions = (REPO / "docs" / "conventions.md").read_text(encoding="utf-8")
    assert "## Validation policy" in conventions and "BlenderClampWarning" in conventions


def test_principled_distribution_is_blenders_default_and_only_ggx_or_multi_ggx():
    for cls in (bf.PrincipledBSDFMaterial, bf.MetalMaterial, bf.PlasticMaterial, bf.PlasticWireframeMaterial):
        assert cls().distribution == "MULTI_GGX"
    mat = bf.MetalMaterial()
    mat.distribution = "GGX"
    assert mat.distribution == "GGX" and mat.revision == 1
    with pytest.raises(InvalidSceneError, match="distribution"):
        bf.PrincipledBSDFMaterial(distribution="BECKMANN")  # Blender's Principled node offers GGX and MULTI_GGX only
    with pytest.raises(InvalidSceneError, match="distribution"):
        mat.distribution = None
    assert mat.distribution == "GGX"
