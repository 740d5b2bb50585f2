"""scene.show() and the offline HTML view: the page is self-contained (three.js inlined from the package
data, no network), headless Chromium draws the objects where the camera says, and show() picks the right
viewer (pyrender with a display, HTML inline in a notebook or in a file without one)."""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys
import tempfile
import types
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.export import html as html_mod
from blendify_core.export import viewer as viewer_mod

CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="headless Chromium not found (Debian: apt-get install chromium)"
)
BACKGROUND = 0.05 ** (1 / 2.4) * 1.055 - 0.055  # the default background, sRGB-encoded by three.js


def screenshot(page, size, tmp_path):
    """Open ``page`` in headless Chromium (no network, a fresh profile) and return the RGB screenshot."""
    from PIL import Image

    run = Path(tempfile.mkdtemp(dir=tmp_path))  # a fresh profile per browser: a reused one may hang
    out = run / "shot.png"
    cmd = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",  # software WebGL (Chromium asks for this opt-in since 2024)
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={run / 'profile'}",
        f"--screenshot={out}",
        f"--window-size={size[0]},{size[1]}",
        "--virtual-time-budget=10000",
        page.resolve().as_uri(),
    ]
    subprocess.run(cmd, capture_output=True, timeout=180, check=False)
    assert out.is_file(), "Chromium wrote no screenshot"
    return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64) / 255.0


def quad(scene, centre, colour, tag, size=0.5):
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float) * size / 2
    scene.renderables.add_mesh(
        v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.UniformColors(colour), translation=centre, tag=tag
    )


def patch(img, uv, r=2):
    u, v = int(round(uv[0])), int(round(uv[1]))
    return img[v - r : v + r + 1, u - r : u + r + 1].reshape(-1, 3).mean(axis=0)


@needs_chromium
def test_chromium_shows_the_objects_where_the_camera_projects_them(tmp_path):
    size = (640, 480)
    scene = bf.Scene()
    # an off-centre principal point and fx != fy: the page must use the exact intrinsics
    scene.set_perspective_camera(size, K=[[560.0, 0, 280.0], [0, 500.0, 260.0], [0, 0, 1]], translation=(0, 0, 4))
    quad(scene, (0.9, 0.4, 0.0), (1.0, 0.0, 0.0), "red")
    quad(scene, (-1.0, -0.7, 0.5), (0.0, 1.0, 0.0), "green")
    scene.lights.add_point(100.0, translation=(0, 0, 3))
    page = scene.export(tmp_path / "view.html")
    img = screenshot(page, size, tmp_path)
    assert img.shape == (size[1], size[0], 3)
    cam = scene.camera
    for tag, channel in (("red", 0), ("green", 1)):
        r = scene.renderables[tag]
        corners = r.vertices + r.translation
        uv, _ = cam.project(corners)
        centre, _ = cam.project(r.translation[None])
        colour = patch(img, centre[0])
        assert colour[channel] > 0.6 and np.delete(colour, channel).max() < 0.25, (tag, colour)
        # 4 pixels inside each corner: the object's colour; 4 pixels outside: the background
        mid = uv.mean(axis=0)
        for corner in uv:
            step = np.sign(corner - mid) * 4
            inside, outside = patch(img, corner - step, 1), patch(img, corner + step, 1)
            assert inside[channel] > 0.6, (tag, corner, inside)
            assert outside[channel] < 0.35, (tag, corner, outside)
    empty = patch(img, (320, 80), 3)  # nothing there
    np.testing.assert_allclose(empty, BACKGROUND, atol=0.03)


@needs_chromium
@pytest.mark.slow
def test_chromium_orthographic_notebook_and_default_view(tmp_path):
    size = (640, 480)
    scene = bf.Scene()
    scene.set_orthographic_camera(size, ortho_scale=4.0, translation=(0, 0, 5), center=(300.0, 250.0))
    quad(scene, (1.0, -0.5, 0.0), (1.0, 0.0, 0.0), "red")
    page = scene.export(tmp_path / "ortho.html")
    img = screenshot(page, size, tmp_path)
    centre, _ = scene.camera.project(np.array([[1.0, -0.5, 0.0]]))
    colour = patch(img, centre[0])
    assert colour[0] > 0.6 and colour[1:].max() < 0.25, colour
    # in a notebook: the iframe holding the page (HTMLView._repr_html_) renders the same view
    view = viewer_mod.HTMLView(html_mod.html_document(scene), *size)
    wrapper = tmp_path / "notebook.html"
    wrapper.write_text(f'<!doctype html><html><body style="margin:0">{view._repr_html_()}</body></html>')
    framed = screenshot(wrapper, size, tmp_path)
    differ = np.abs(framed - img).max(axis=2) > 0.1
    assert differ.mean() < 0.01, differ.mean()  # anti-aliased edges may differ
    # no camera: a default view of the scene's bounds still shows the object near the middle
    scene.camera = None
    page = scene.export(tmp_path / "default.html")
    img = screenshot(page, (960, 720), tmp_path)
    red = (img[..., 0] > 0.6) & (img[..., 1:].max(axis=2) < 0.25)
    assert red.sum() > 500


def test_the_page_is_self_contained_and_the_libraries_ship_with_their_licence(tmp_path):
    scene = bf.Scene()
    quad(scene, (0, 0, 0), (1, 0, 0), "q")
    page = html_mod.html_document(scene, title="<b>x</b>")
    web = resources.files("blendify_core.export").joinpath("web")
    for name in (*html_mod.LIBRARIES.values(), "viewer.js"):
        text = web.joinpath(name).read_text(encoding="utf-8")
        assert "</script" not in text.lower() and "<!--" not in text, name
        assert text in page, name
    licence = web.joinpath("LICENSE-three.txt").read_text()
    assert "MIT" in licence or "Permission is hereby granted" in licence
    assert "three@0.160.1" in web.joinpath("SOURCES.md").read_text()
    assert "<script src" not in page and "<link" not in page  # nothing is fetched
    assert "<title>&lt;b>x&lt;/b></title>" in page
    wire = bf.Scene()
    wire.renderables.add_cube_mesh(1.0, bf.PlasticWireframeMaterial(), bf.UniformColors((1, 0, 0)))
    assert "Shown approximately: wireframe" in html_mod.html_document(wire)  # the help text names it
    with pytest.raises(InvalidSceneError, match="html"):
        scene.export(tmp_path / "x.htm5")
    with pytest.raises(InvalidSceneError, match="show_helpers"):
        html_mod.html_document(scene, show_helpers="yes")


def test_the_wheel_packages_the_viewer_files():
    pyproject = (html_mod.Path(__file__).resolve().parents[2] / "pyproject.toml").read_text()
    assert 'packages = ["blendify_core"]' in pyproject  # hatch ships every file under the package
    ignored = (html_mod.Path(__file__).resolve().parents[2] / ".gitignore").read_text().split()
    assert not any(p in ("*.js", "web/", "*.txt", "*.md") for p in ignored)


@pytest.fixture
def no_display(monkeypatch):
    monkeypatch.setattr(viewer_mod, "has_display", lambda: False)
    monkeypatch.setattr(viewer_mod, "in_notebook", lambda: False)


def _scene():
    scene = bf.Scene()
    quad(scene, (0, 0, 0), (1, 0, 0), "q")
    scene.set_perspective_camera((64, 48), fov_x=np.deg2rad(50), translation=(0, 0, 3))
    return scene


def test_show_without_a_display_writes_the_page(no_display, tmp_path, caplog, monkeypatch):
    opened = []
    monkeypatch.setattr(viewer_mod.webbrowser, "open", opened.append)
    with caplog.at_level(logging.WARNING, logger="blendify_core.export.viewer"):
        view = _scene().show(path=tmp_path / "v.html")
    assert isinstance(view, viewer_mod.HTMLView) and view.path == tmp_path / "v.html"
    assert view.path.read_text() == view.html and "no display" in caplog.text
    assert opened == []
    view = _scene().show(path=tmp_path / "w.html", open_browser=True)
    assert opened == [view.path.resolve().as_uri()]
    assert "aspect-ratio: 64 / 48" in view._repr_html_() and "srcdoc=" in view._repr_html_()
    with pytest.raises(InvalidSceneError, match="viewer"):
        _scene().show(viewer="vtk")


def test_show_in_a_notebook_displays_inline(monkeypatch):
    shown = []
    fake = types.ModuleType("IPython.display")
    fake.display = shown.append
    monkeypatch.setitem(sys.modules, "IPython.display", fake)
    monkeypatch.setattr(viewer_mod, "in_notebook", lambda: True)
    monkeypatch.setattr(viewer_mod, "has_display", lambda: True)  # a notebook on a desktop: still inline
    view = _scene().show()
    assert shown == [view] and view.path is None


def test_show_with_a_display_opens_pyrender_and_falls_back_to_html(monkeypatch, tmp_path):
    calls = []

    class FakePyrender:
        fail = False

        @classmethod
        def show_scene(cls, scene, **kwargs):
            calls.append((scene, kwargs))
            if cls.fail:
                raise BackendUnavailableError("pyrender viewer: cannot open a window (no GLX)")
            return "viewer"

    monkeypatch.setattr(viewer_mod, "has_display", lambda: True)
    monkeypatch.setattr(viewer_mod, "in_notebook", lambda: False)
    monkeypatch.setattr(viewer_mod, "get_backend_class", lambda name: FakePyrender)
    monkeypatch.setattr(viewer_mod.webbrowser, "open", lambda uri: True)
    scene = _scene()
    assert scene.show(run_in_thread=True) == "viewer"
    assert calls == [(scene, {"run_in_thread": True})]
    FakePyrender.fail = True
    view = scene.show(path=tmp_path / "fallback.html")
    assert isinstance(view, viewer_mod.HTMLView) and os.path.isfile(view.path)
    with pytest.raises(BackendUnavailableError):
        scene.show(viewer="pyrender")
