"""The pyrender translator: a handler for every IR type, unhandled types refused by name (through bf.render,
the backend's own translate and the translator's dispatch), the capability table of the previous release
(frozen copy) declared beside the handlers, and change detection from the core's tracker."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from blendify_pyrender import PyrenderBackend
from blendify_pyrender.translate import PyrenderTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.types import IR_TYPES
from blendify_core.pipeline.capabilities import ALL_FEATURES
from blendify_core.pipeline.settings import resolve_settings
from blendify_core.pipeline.translator import TranslationContext

pytestmark = pytest.mark.pyrender
FROZEN = Path(__file__).with_name("frozen_capabilities.json")


class MyMesh(bf.Mesh):
    pass


class MyLight(bf.PointLight):
    pass


class MySpot(bf.SpotLight):
    pass


class MyColors(bf.UniformColors):
    pass


class MyMaterial(bf.DiffuseMaterial):
    pass


def test_capability_table_equals_the_frozen_copy():
    """feature -> (level, note) exactly as the table was before the translator declared it (no behaviour change)."""
    frozen = {k: tuple(v) for k, v in json.loads(FROZEN.read_text()).items()}
    caps = {k: (c.level, c.note) for k, c in PyrenderBackend.capabilities().items()}
    assert set(frozen) == set(ALL_FEATURES)
    assert caps == frozen


def test_every_ir_type_has_a_handler():
    assert PyrenderTranslator.missing_handlers() == []
    assert PyrenderBackend.translator_class is PyrenderTranslator
    assert {PyrenderTranslator.handler_name(t) for t in IR_TYPES} >= {"mesh", "point_light", "uniform_colors"}


def _scene_with(kind: str) -> tuple[bf.Scene, object]:
    """every_feature_scene with one object turned into a subclass nobody registered."""
    scene = testing.every_feature_scene()
    if kind == "mesh":
        obj = next(r for r in scene.renderables if type(r) is bf.Mesh)
        obj.__class__ = MyMesh
    elif kind == "light":
        obj = scene.lights.add_point(50.0, tag="mine")
        obj.__class__ = MyLight
    elif kind == "spot":
        obj = scene.lights.add_spot(50.0, tag="mine")
        obj.__class__ = MySpot
    elif kind == "colors":
        r = scene.renderables.add_sphere_nurbs(0.1, bf.DiffuseMaterial(), MyColors((1, 0, 0)), tag="mine")
        obj = r.colors_list[0]
    else:
        r = scene.renderables.add_sphere_nurbs(0.1, MyMaterial(), bf.UniformColors((1, 0, 0)), tag="mine")
        obj = r.materials[0]
    return scene, obj


@pytest.mark.parametrize("kind", ["mesh", "light", "spot", "colors", "material"])
def test_an_unregistered_subclass_is_refused_by_name(pyr, kind):
    """An unknown light type is no longer skipped and an unknown colour source no longer a bare TypeError:
    every path refuses the type by name, naming the backend."""
    scene, obj = _scene_with(kind)
    name = type(obj).__name__
    pattern = rf"'pyrender' has no handler for the IR type .*{name}"
    with pytest.raises(bf.UnsupportedFeatureError, match=pattern) as exc:
        bf.render(scene, backend=pyr, quality="preview")
    assert exc.value.backend == "pyrender" and exc.value.feature.endswith(name)
    with pytest.raises(bf.UnsupportedFeatureError, match=pattern):
        PyrenderTranslator().dispatch(obj, TranslationContext())
    # the backend's own translate (no core check before it) refuses too, and starts over afterwards
    with pytest.raises(bf.UnsupportedFeatureError, match=pattern):
        pyr.translate(scene, resolve_settings())
    obj.__class__ = type(obj).__mro__[1]
    frame = pyr.translate(scene, resolve_settings())
    assert frame.rebuilt == len(scene.renderables)
    assert pyr.translate(scene, resolve_settings()).rebuilt == 0


def test_a_light_change_rebuilds_no_mesh_and_updates_the_lights(pyr):
    """What changed comes from the core's tracker: lights and world are updated, no mesh is rebuilt."""
    scene = testing.every_feature_scene()
    settings = resolve_settings()
    pyr.translate(scene, settings)
    spot = next(light for light in scene.lights if type(light) is bf.SpotLight)
    spot.strength = 400.0
    frame = pyr.translate(scene, settings)
    assert frame.rebuilt == 0
    by_light = {id(ir): node.light for node, ir, _ in pyr.engine_instance._light_nodes}
    assert by_light[id(spot)].intensity == pytest.approx(400.0 / (4 * np.pi), rel=1e-12)
    scene.lights.set_background_light(0.25, (1, 1, 1))
    frame = pyr.translate(scene, settings)
    assert frame.rebuilt == 0
    np.testing.assert_allclose(frame.ambient, 0.25, rtol=1e-9)
    np.testing.assert_allclose(pyr.engine_instance.pscene.ambient_light, 0.25 * 0.96, rtol=1e-9)


def test_attachments_are_ignored_with_a_reason(pyr, tmp_path):
    scene = testing.depth_plane_scene()
    scene.attachments.append(Attachment("blend", str(tmp_path / "x.blend")))
    res = bf.render(scene, backend=pyr, outputs=("depth",))
    assert res.meta["ignored"] == ["Attachment: pyrender draws the IR scene only; the attached .blend file is not read"]
    assert "ignored" not in bf.render(testing.depth_plane_scene(), backend=pyr, outputs=("depth",)).meta
