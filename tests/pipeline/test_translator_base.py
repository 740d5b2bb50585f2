"""The translator base every backend shares: exact-type dispatch, one refusal for unhandled types,
capabilities declared beside handlers with one default, and the pre-render handler check."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.ir.types import IR_TYPES, iter_ir_objects
from blendify_core.pipeline.capabilities import ALL_FEATURES
from blendify_core.pipeline.translator import (
    EXACT,
    TranslationContext,
    Translator,
    approximate,
    check_handlers,
    handles,
)
from blendify_core.testing import every_feature_scene


class _Tiny(Translator):
    backend = "tiny"

    @handles(bf.Mesh, features={"mesh": EXACT, "mesh.smooth": approximate("flat normals")})
    def mesh(self, mesh, ctx):
        return ("mesh", mesh.tag)

    @handles(bf.PointLight, bf.SunLight, features={"light.point": EXACT, "light.sun": EXACT})
    def light(self, light, ctx):
        ctx.ignore(light, "this tiny backend has no lights")
        return None


class _Tinier(_Tiny):
    backend = "tinier"

    @handles(bf.Mesh, features={"mesh.smooth": EXACT})
    def mesh_again(self, mesh, ctx):
        return ("mesh2", mesh.tag)


def _mesh(scene):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    return scene.renderables.add_mesh(v, np.array([[0, 1, 2]]), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))


def test_dispatch_calls_the_handler_of_the_exact_type():
    s = bf.Scene()
    m = _mesh(s)
    ctx = TranslationContext()
    assert _Tiny().dispatch(m, ctx) == ("mesh", m.tag)
    assert _Tinier().dispatch(m, ctx) == ("mesh2", m.tag)  # a subclass overrides one type's handler
    light = s.lights.add_point()
    assert _Tiny().dispatch(light, ctx) is None
    assert ctx.ignored == ["PointLight: this tiny backend has no lights"]


def test_an_unregistered_subclass_is_refused_by_name_not_translated_as_its_parent():
    class MyMesh(bf.Mesh):
        pass

    s = bf.Scene()
    m = _mesh(s)
    m.__class__ = MyMesh
    with pytest.raises(bf.UnsupportedFeatureError, match=r"'tiny' has no handler for the IR type .*MyMesh") as exc:
        _Tiny().dispatch(m, TranslationContext())
    assert "subclass of Mesh" in str(exc.value)
    assert exc.value.backend == "tiny" and exc.value.feature.endswith("MyMesh")
    with pytest.raises(bf.UnsupportedFeatureError, match="no handler"):
        _Tiny().dispatch(bf.SpotLight(), TranslationContext())


def test_capabilities_come_from_the_handlers_with_one_default():
    caps = _Tiny.capabilities()
    assert set(caps) == set(ALL_FEATURES)
    assert caps["mesh"].level == "exact" and caps["mesh.smooth"].level == "approximate"
    assert caps["light.sun"].level == "exact"
    assert caps["light.spot"].level == "unsupported" and "not declared" in caps["light.spot"].note
    assert _Tinier.capabilities()["mesh.smooth"].level == "exact"  # overridden in the subclass
    with pytest.raises(TypeError, match="unknown feature"):
        handles(bf.Mesh, features={"mesh.nonsense": EXACT})


def test_missing_handlers_lists_every_ir_type_without_one():
    missing = _Tiny.missing_handlers()
    assert bf.Mesh not in missing and bf.PointLight not in missing
    assert bf.SpotLight in missing and bf.PerspectiveCamera in missing
    assert len(missing) == len(IR_TYPES) - 3


def test_check_handlers_names_the_object_and_where_it_is_used():
    s = every_feature_scene()
    kinds = {type(o) for o, _ in iter_ir_objects(s)}
    assert {bf.Mesh, bf.PointCloud, bf.PerspectiveCamera, bf.UniformColors} <= kinds
    assert kinds <= set(IR_TYPES)
    with pytest.raises(bf.UnsupportedFeatureError, match=r"no handler for the IR type .* \(used by "):
        check_handlers(_Tiny, s)


def test_render_refuses_an_unhandled_type_before_the_backend_runs(monkeypatch):
    """bf.render checks every object against the backend's translator before translating."""
    from blendify_core.pipeline.backend import Backend

    calls = []

    class Fake(Backend):
        name = "fake_translator_check"
        translator_class = _Tiny

        def translate(self, scene, settings):
            calls.append("translate")

        def render(self, native, settings):
            calls.append("render")

    s = bf.Scene()
    _mesh(s)
    s.lights.add_spot()
    s.set_perspective_camera((8, 8), fov_x=0.5, translation=(0.2, 0.2, 2.0))
    with pytest.raises(bf.UnsupportedFeatureError, match="no handler for the IR type"):
        bf.render(s, backend=Fake())
    assert calls == []
