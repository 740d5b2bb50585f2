"""scene.show() with a display: pyrender's Viewer gets the scene as this backend translates it. No window is
opened here (no display on the test machines): the Viewer class is replaced by a recorder."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_pyrender import PyrenderBackend
from blendify_pyrender import viewer as viewer_mod

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.testing import every_feature_scene


def test_the_viewer_scene_holds_the_meshes_lights_and_camera():
    scene = every_feature_scene((64, 48))
    pscene, size = viewer_mod.build_viewer_scene(scene)
    assert size == (64, 48)
    names = {n.name for n in pscene.nodes}
    assert set(scene.renderables.keys()) <= names
    assert {light.tag for light in scene.lights} <= names
    assert pscene.main_camera_node.name == "camera"
    np.testing.assert_allclose(pscene.ambient_light, 0.3 * 0.96, rtol=1e-6)  # background 0.3, as the renders
    # the camera node: the render camera's pose, its exact projection
    pose = pscene.get_pose(pscene.main_camera_node)
    np.testing.assert_allclose(pose[:3, 3], scene.camera.translation)


def test_show_scene_opens_the_viewer_at_the_camera_resolution(monkeypatch):
    opened = []
    monkeypatch.setattr(viewer_mod, "_check_platform", lambda: None)  # this process renders offscreen (EGL)
    import pyrender

    monkeypatch.setattr(pyrender, "Viewer", lambda scene, **kw: opened.append((scene, kw)) or "window")
    scene = every_feature_scene((64, 48))
    assert PyrenderBackend.show_scene(scene, run_in_thread=True) == "window"
    assert opened[0][1] == {"viewport_size": (64, 48), "run_in_thread": True}


def test_an_offscreen_process_and_a_missing_camera_are_told(monkeypatch):
    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")
    import OpenGL  # noqa: F401 - the offscreen platform is chosen once OpenGL is imported

    with pytest.raises(BackendUnavailableError, match="before rendering"):
        PyrenderBackend.show_scene(every_feature_scene())
    scene = every_feature_scene()
    scene.camera = None
    with pytest.raises(InvalidSceneError, match="camera"):
        viewer_mod.build_viewer_scene(scene)
