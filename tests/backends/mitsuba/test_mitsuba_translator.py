"""The Mitsuba translator's shape: a handler for every IR type, refusal by name of types nobody registered
(through bf.render, the backend and the translator itself), attachments recorded as ignored, and the
session's reuse of a translation decided by the core's change detection."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.translate import MitsubaContext, MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.types import IR_TYPES
from blendify_core.pipeline.settings import resolve_settings

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba


class MyMesh(bf.Mesh):
    pass


class MyLight(bf.PointLight):
    pass


class MyColors(bf.UniformColors):
    pass


class MyMaterial(bf.DiffuseMaterial):
    pass


def _scene() -> bf.Scene:
    s = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    s.renderables.add_mesh(v, [[0, 1, 2], [0, 2, 3]], bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="m")
    s.lights.add_point(50.0, translation=(0, 0, 2))
    s.set_perspective_camera((16, 16), fov_x=0.8, translation=(0, 0, 3))
    return s


def _with_unregistered(kind: str) -> tuple[bf.Scene, str]:
    """A scene using a subclass nobody registered (``kind``: mesh, light, colors, material), and its name."""
    s = _scene()
    mesh = s.renderables["m"]
    if kind == "mesh":
        mesh.__class__ = MyMesh
        return s, "MyMesh"
    if kind == "light":
        list(s.lights)[0].__class__ = MyLight
        return s, "MyLight"
    if kind == "colors":
        mesh.update_colors(MyColors((0.2, 0.4, 0.6)))
        return s, "MyColors"
    mesh.materials[0].__class__ = MyMaterial
    return s, "MyMaterial"


def test_every_ir_type_has_a_handler():
    assert MitsubaTranslator.missing_handlers() == []
    assert MitsubaBackend.translator_class is MitsubaTranslator
    assert all(MitsubaTranslator.handler_name(t) for t in IR_TYPES)


@pytest.mark.parametrize("kind", ["mesh", "light", "colors", "material"])
def test_an_unregistered_subclass_is_refused_by_name_through_bf_render(scalar_backend, kind):
    scene, name = _with_unregistered(kind)
    with pytest.raises(bf.UnsupportedFeatureError, match=rf"'mitsuba' has no handler for the IR type .*\.{name}") as e:
        bf.render(scene, backend=scalar_backend, samples=1)
    assert e.value.backend == "mitsuba" and e.value.feature.endswith(name)


@pytest.mark.parametrize("kind", ["mesh", "light", "colors", "material"])
def test_an_unregistered_subclass_is_refused_by_the_backend_and_the_translator(mi_scalar, scalar_backend, kind):
    """Without the core's pre-render check: the backend's translate and the translator's walk refuse it too."""
    scene, name = _with_unregistered(kind)
    pattern = rf"'mitsuba' has no handler for the IR type .*\.{name}"
    with pytest.raises(bf.UnsupportedFeatureError, match=pattern):
        scalar_backend.translate(scene, resolve_settings(samples=1))
    with pytest.raises(bf.UnsupportedFeatureError, match=pattern):
        MitsubaTranslator(resolve_settings(samples=1)).translate(scene)


@pytest.mark.parametrize(
    "obj",
    [
        MyLight(10.0),
        MyColors((1.0, 0.0, 0.0)),
        MyMaterial(),
    ],
    ids=["light", "colors", "material"],
)
def test_dispatch_refuses_an_unregistered_subclass(obj):
    with pytest.raises(bf.UnsupportedFeatureError, match=rf"'mitsuba' has no handler .*{type(obj).__name__}") as e:
        MitsubaTranslator().dispatch(obj, MitsubaContext())
    assert "subclass of" in str(e.value)


def test_attachments_are_recorded_as_ignored(mi_scalar, scalar_backend, tmp_path):
    scene = _scene()
    plain = bf.render(scene, backend=scalar_backend, samples=1)
    assert "ignored" not in plain.meta
    scene.attachments.append(Attachment("blend", str(tmp_path / "x.blend")))
    tr = MitsubaTranslator(resolve_settings(samples=1)).translate(scene)
    why = "Attachment: attached .blend files are read by the Cycles backend only"
    assert tr.ignored == [why]
    assert not any(k.startswith("attach") for k in tr.scene_dict)
    r = bf.render(scene, backend=scalar_backend, samples=1)
    assert r.meta["ignored"] == [why] and np.array_equal(r.rgba, plain.rgba)


def test_the_translation_is_reused_only_while_nothing_changes():
    """The session asks the core's ChangeTracker: a new seed reuses the loaded scene, a moved camera, a changed
    material, a new renderable or another scene translate again."""
    scene = testing.plane_scene("sun", resolution=(16, 16))
    with MitsubaBackend(variant="scalar_rgb") as b:

        def cached(s=scene, **kw):
            return bf.render(s, backend=b, samples=2, **kw).meta["translate_cached"]

        assert not cached() and cached(seed=7)
        scene.camera.set_position(translation=(0.1, 0.0, 3.0), rotation_mode="look_at", rotation=(0, 0, 0))
        assert not cached() and cached()
        scene.renderables["plane"].materials[0].alpha = 0.9  # DiffuseMaterial: roughness is fixed
        assert not cached() and cached()
        scene.renderables.add_sphere_nurbs(0.2, bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)), tag="s")
        assert not cached() and cached()
        other = testing.plane_scene("sun", resolution=(16, 16))
        assert not cached(other) and not cached(scene) and cached(scene)


def test_a_failed_translation_is_not_reused(scalar_backend):
    scene = testing.plane_scene("sun", resolution=(16, 16))
    settings = resolve_settings(samples=1)
    scene.renderables["plane"].emit_shadows = False
    with pytest.raises(bf.UnsupportedFeatureError, match="emit_shadows"):
        scalar_backend.translate(scene, settings)
    with pytest.raises(bf.UnsupportedFeatureError, match="emit_shadows"):
        scalar_backend.translate(scene, settings)  # nothing changed, but nothing was translated either
    scene.renderables["plane"].emit_shadows = True
    native = scalar_backend.translate(scene, settings)
    assert not native.translate_cached and scalar_backend.translate(scene, settings) is native


@pytest.mark.parametrize("view", ["resolution_percentage", "recentred"])
def test_a_camera_copy_with_the_same_sensor_keeps_the_translation(view):
    """bf.render hands the backend a new camera object for these scenes at every render (the core reports a
    camera change); the sensor is the same, so the loaded scene is reused, as with the scene fingerprint."""
    scene = testing.bunny_scene((24, 24))
    if view == "resolution_percentage":
        scene.camera.resolution_percentage = 50
    else:  # far from the origin: bf.render renders a re-centred view
        far = np.array([1e6, -2e6, 5e5])
        for obj in [scene.camera, *scene.renderables, *scene.lights]:
            obj.set_position(translation=obj.translation + far, rotation_mode="quaternionWXYZ", rotation=obj.quaternion)
    with MitsubaBackend(variant="scalar_rgb") as b:
        first = bf.render(scene, backend=b, samples=2, outputs=("rgb", "depth"))
        again = bf.render(scene, backend=b, samples=2, outputs=("rgb", "depth"))
        assert not first.meta["translate_cached"] and again.meta["translate_cached"]
        assert np.array_equal(first.rgba, again.rgba) and np.array_equal(first.depth, again.depth)
        scene.camera.set_position(
            translation=scene.camera.translation + 0.01,
            rotation_mode="quaternionWXYZ",
            rotation=scene.camera.quaternion,
        )
        moved = bf.render(scene, backend=b, samples=2, outputs=("rgb", "depth"))
        assert not moved.meta["translate_cached"] and not np.array_equal(moved.depth, first.depth)
