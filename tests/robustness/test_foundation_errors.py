"""The bottom layer speaks the project's errors too: unknown keywords to the registry's functions are
InvalidSceneError naming them, and a .blend written over a folder is an OutputError (also an OSError)."""

from __future__ import annotations

import errno

import pytest

import blendify_core as bf
from blendify_core.testing import plane_scene


@pytest.mark.parametrize(
    ("func", "kwargs"),
    [
        (bf.available_backends, {"frobnicate": 1}),
        (bf.backend_names, {"frobnicate": 1}),
        (bf.close_backends, {"frobnicate": 1}),
        (bf.get_backend_class, {"name": "cycles", "frobnicate": 1}),
        (bf.register_backend, {"name": "x", "target": "a:b", "frobnicate": 1}),
    ],
)
def test_registry_unknown_keywords_are_invalid_scene_errors(func, kwargs):
    with pytest.raises(bf.InvalidSceneError, match="frobnicate"):
        func(**kwargs)
    assert "x" not in bf.backend_names()  # nothing registered by the refused call


def test_registry_calls_that_bind_are_unchanged():
    assert "cycles" in bf.backend_names()
    assert set(bf.available_backends()) >= {"cycles", "mitsuba", "pyrender"}


def test_export_blend_over_a_folder_is_an_output_error(tmp_path):
    pytest.importorskip("bpy", reason="the .blend export needs bpy")
    folder = tmp_path / "scene.blend"
    folder.mkdir()
    with pytest.raises(bf.OutputError, match="is a directory") as info:
        plane_scene("sun", (8, 8)).export_blend(folder)
    assert isinstance(info.value, OSError) and info.value.errno == errno.EISDIR
