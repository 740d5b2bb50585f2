"""The Cycles translator's shape: a handler for every IR type, unregistered subclasses refused by name
(through bf.render, the backend's own translate and the translator's dispatch), attachments of other
formats recorded as ignored, and no parameter read by dict key."""

from __future__ import annotations

import re
from pathlib import Path

import blendify_blender
import numpy as np
import pytest
from blendify_blender import CyclesBackend
from blendify_blender.session import BuiltScene
from blendify_blender.translate import CyclesTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.types import IR_TYPES
from blendify_core.pipeline.settings import resolve_settings
from blendify_core.pipeline.translator import TranslationContext

pytestmark = pytest.mark.cycles


class MyMesh(bf.Mesh):
    pass


class MyLight(bf.PointLight):
    pass


class MyColors(bf.UniformColors):
    pass


class MyMaterial(bf.DiffuseMaterial):
    pass


class MyCamera(bf.PerspectiveCamera):
    pass


def _scene_with(kind: str) -> tuple[bf.Scene, object]:
    """A small scene in which one object's class is replaced by an unregistered subclass of it."""
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    mesh = scene.renderables.add_mesh(v, np.array([[0, 1, 2]]), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    light = scene.lights.add_point(10.0, translation=(0, 0, 2))
    scene.set_perspective_camera((8, 8), fov_x=0.8, translation=(0.3, 0.3, 3))
    obj = {
        "mesh": mesh,
        "light": light,
        "colors": mesh.colors_list[0],
        "material": mesh.materials[0],
        "camera": scene.camera,
    }[kind]
    obj.__class__ = {"mesh": MyMesh, "light": MyLight, "colors": MyColors, "material": MyMaterial, "camera": MyCamera}[
        kind
    ]
    return scene, obj


KINDS = ["mesh", "light", "colors", "material", "camera"]


def test_every_ir_type_has_a_handler():
    assert CyclesTranslator.missing_handlers() == []
    assert all(CyclesTranslator.handler_name(t) for t in IR_TYPES)
    assert CyclesBackend.translator_class is CyclesTranslator


@pytest.mark.parametrize("kind", KINDS)
def test_unregistered_subclass_is_refused_by_bf_render(cycles, kind):
    scene, obj = _scene_with(kind)
    name = type(obj).__name__
    with pytest.raises(bf.UnsupportedFeatureError, match=rf"'cycles' has no handler for the IR type .*{name}") as exc:
        bf.render(scene, backend=cycles, samples=1)
    assert exc.value.backend == "cycles" and exc.value.feature.endswith(name)


@pytest.mark.parametrize("kind", KINDS)
def test_unregistered_subclass_is_refused_by_the_backend_translate(cycles, kind):
    """Without bf.render's pre-check, the translator's own dispatch refuses it."""
    scene, obj = _scene_with(kind)
    name = type(obj).__name__
    with pytest.raises(bf.UnsupportedFeatureError, match=rf"'cycles' has no handler for the IR type .*{name}"):
        cycles.translate(scene, resolve_settings(samples=1))
    # the half-built scene was dropped: the next scene translates and renders
    r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=cycles, samples=1)
    assert r.rgba.shape == (8, 8, 4)


@pytest.mark.parametrize("kind", KINDS)
def test_unregistered_subclass_is_refused_by_dispatch(kind):
    """The dispatch refuses before any bpy call (no bpy scene here)."""
    _scene, obj = _scene_with(kind)
    name = type(obj).__name__
    translator = CyclesTranslator(BuiltScene(bscene=None), resolve_settings())
    with pytest.raises(bf.UnsupportedFeatureError, match=rf"'cycles' has no handler for the IR type .*{name}") as exc:
        translator.dispatch(obj, TranslationContext())
    assert "subclasses are not translated as their parent" in str(exc.value)


def test_attachments_of_other_formats_are_ignored_with_the_reason():
    translator = CyclesTranslator(BuiltScene(bscene=None), resolve_settings())
    ctx = TranslationContext()
    assert translator.dispatch(Attachment("obj", "/nowhere/x.obj"), ctx) is None
    assert ctx.ignored == ["Attachment: Cycles renders attached .blend files only, not .obj"]


def test_no_parameter_is_read_by_dict_key_or_kind_string():
    """Parameters are read as attributes (material.roughness), IR types told apart by handlers."""
    modules = sorted(Path(blendify_blender.__file__).parent.glob("*.py"))
    assert {"translate.py", "materials.py", "session.py", "render.py"} <= {p.name for p in modules}
    offenders = []
    for path in modules:
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if ".parameters()" in line or re.search(r"\.kind\s*==", line):
                offenders.append(f"{path.name}:{i}: {line.strip()}")
    assert offenders == []
