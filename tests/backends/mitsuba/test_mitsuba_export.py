"""scene.export_mitsuba: the XML loads with mitsuba.load_file and renders what the backend renders (same
translation, same seed and samples)."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from blendify_mitsuba import translate as mitsuba_translate
from blendify_mitsuba.render import render_rgba, seen_lights

import blendify_core as bf
from blendify_core.errors import InvalidSceneError
from blendify_core.testing import every_feature_scene, pointcloud_scene, textured_quad_scene

pytestmark = pytest.mark.mitsuba

SETTINGS = {"quality": "draft", "samples": 4}


def _emitter_order(scene) -> list[str]:
    """The scene's emitters in sampling order: plugin and, for shape emitters, the shape's area."""
    return [f"{str(e).split('[')[0]}:{e.get_shape().surface_area() if e.get_shape() else ''}" for e in scene.emitters()]


def _render_xml(mi, path, seed):
    return np.array(mi.render(mi.load_file(str(path)), spp=SETTINGS["samples"], seed=seed), dtype=np.float32)


@pytest.mark.parametrize(
    "build",
    [
        lambda: every_feature_scene((40, 30)),
        lambda: textured_quad_scene((24, 24)),
        lambda: pointcloud_scene(150, (24, 24)),
        lambda: pointcloud_scene(800, (24, 24)),  # beyond 500 opaque points: one curve shape
    ],
    ids=["every_feature", "textured_quad", "pointcloud", "pointcloud_curves"],
)
def test_the_xml_renders_what_the_backend_renders(build, tmp_path, scalar_backend):
    scene = build()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = scene.export_mitsuba(
            tmp_path / "scene.xml", variant="scalar_rgb", transparent_background=False, **SETTINGS
        )
    ours = bf.render(scene, scalar_backend, seed=7, transparent_background=False, **SETTINGS).rgba
    mi = scalar_backend.session.set_variant()  # bf.render restores the previous variant
    theirs = _render_xml(mi, path, seed=7)
    assert theirs.shape[:2] == ours.shape[:2]
    native = scalar_backend.session.native
    keep = np.ones(ours.shape[:2], bool)
    if native.sky_scene is not None and native.coverage_scene is None:
        # an opaque film whose emitters the XML hides: the backend adds the sky back (said in the warning)
        assert any("adds the sky back" in str(w.message) for w in caught)
        with scalar_backend.session.engine():
            sky = render_rgba(native.sky_scene, SETTINGS["samples"], 7)[..., :3]
        theirs[..., :3] += (1.0 - theirs[..., 3:4]) * sky
    if native.light_shapes:
        # a scene with emissive materials keeps its emitters visible: the backend subtracts the lights the
        # camera sees (said in the export's warning); compared where it removed nothing
        assert any("the backend removes them" in str(w.message) for w in caught)
        with scalar_backend.session.engine():
            seen = seen_lights(native.scene, native.light_shapes, SETTINGS["samples"], 7)
        keep = seen.max(axis=-1) == 0
        assert 0 < keep.mean() < 1
    theirs, ours = theirs[keep][None], ours[keep][None]
    if _emitter_order(mi.load_file(str(path))) == _emitter_order(scalar_backend.session.native.scene):
        # the same scene, sampled with the same seed: equal up to float32 rounding (measured max 7e-7)
        assert np.abs(theirs[..., :3] - ours[..., :3]).max() < 1e-4
    else:
        # Mitsuba's XML loader lists shape emitters in a varying order (seen from one load_file to the next
        # with several emissive .ply shapes): the emitter sampling draws differently, the image agrees in noise
        print("emitter order of the loaded XML differs from the in-memory scene: comparing means")
        assert abs(theirs[..., :3].mean() / ours[..., :3].mean() - 1) < 0.02
    assert ours[..., :3].mean() > 0.01  # something was rendered
    other = _render_xml(mi, path, seed=8)[keep][None]
    assert np.abs(other[..., :3] - ours[..., :3]).max() > 1e-3  # the comparison can tell two renders apart


def test_files_sit_beside_the_xml_and_load_from_any_folder(tmp_path, scalar_backend, monkeypatch):
    scene = every_feature_scene((32, 24))
    with pytest.warns(UserWarning, match="coverage alpha"):  # emissive sphere + sky, transparent film
        path = scene.export(tmp_path / "out" / "scene.xml", **SETTINGS)
    text = path.read_text()
    files = sorted(p.name for p in (tmp_path / "out" / "scene_files").iterdir())
    assert any(f.endswith(".ply") for f in files) and any(f.endswith(".exr") for f in files)
    for f in files:
        assert f'value="scene_files/{f}"' in text, f
    assert str(tmp_path) not in text  # relative paths only
    monkeypatch.chdir(tmp_path)
    mi = scalar_backend.session.set_variant()
    loaded = mi.load_file(str(path))
    # the vertex colours travel as PLY attributes
    params = mi.traverse(loaded)
    assert any(k.endswith("vertex_color") for k in params.keys())
    assert not [f for f in os.listdir(tmp_path / "out") if f.startswith(".")]  # no temporary files left


def test_bad_input_and_the_stand_in_engine_is_always_reset(tmp_path):
    scene = textured_quad_scene()
    with pytest.raises(InvalidSceneError, match=".xml"):
        scene.export_mitsuba(tmp_path / "scene.txt")
    scene.camera = None
    with pytest.raises(InvalidSceneError, match="camera"):
        scene.export_mitsuba(tmp_path / "scene.xml")
    bad = textured_quad_scene()
    bad.renderables["quad"].emit_shadows = False  # refused by the translator, mid-translation
    with pytest.raises(bf.UnsupportedFeatureError):
        bad.export_mitsuba(tmp_path / "scene.xml")
    assert mitsuba_translate.ENGINE.get() is None
    assert not (tmp_path / "scene.xml").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        textured_quad_scene().export_mitsuba(tmp_path / "ok.xml", **SETTINGS)  # nothing to warn about


def test_every_hard_case_exports_an_xml_mitsuba_loads(tmp_path, scalar_backend):
    """The numerically awkward scenes of blendify_core.testing (far from the origin, degenerate and empty
    geometry, extreme cameras and lights) export, and Mitsuba loads every file."""
    from blendify_core.testing import hard_cases

    for name, build in hard_cases().items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # what the backend does around mi.render
            path = build().export_mitsuba(tmp_path / f"{name}.xml", variant="scalar_rgb", quality="draft", samples=8)
        mi = scalar_backend.session.set_variant()
        assert mi.load_file(str(path)) is not None, name


def test_xml_names_the_blendify_plugins_it_needs(tmp_path, scalar_backend):
    """A curve's tube takes blendify's own BSDF (blendify_mitsuba/sided.py): the export says which plugins the
    XML uses and how to register them; registered, it loads."""
    scene = textured_quad_scene()
    keys = np.array([[-0.5, 0.0, 0.2], [0.5, 0.0, 0.2], [0.6, 0.3, 0.3]])
    scene.renderables.add_curve_nurbs(keys, 0.05, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.2, 0.2)))
    with pytest.warns(UserWarning, match=r"blendify_sided\).*blendify_mitsuba\.sided\.register\(\)"):
        path = scene.export_mitsuba(tmp_path / "curve.xml", **SETTINGS)
    assert 'type="blendify_sided"' in path.read_text()
    mi = scalar_backend.session.set_variant()
    from blendify_mitsuba.sided import register

    register()
    assert mi.load_file(str(path)) is not None
