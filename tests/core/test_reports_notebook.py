"""Reports in notebooks (``_repr_html_`` / ``_repr_png_``) and progress bars over many renders."""

from __future__ import annotations

import base64
import io
import re
import sys

import numpy as np
import pytest
from core_fake_backend import FlatPlane
from PIL import Image

import blendify_core as bf
from blendify_core.evaluate import progress as progress_mod
from blendify_core.evaluate.stats import estimate_reference
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import depth_plane_scene


class _Flat(FlatPlane):
    """The flat grey plane times ``gain_factor``."""

    gain_factor = 1.0

    def gain(self, settings):
        return self.gain_factor


class FlatA(_Flat):
    name = "nb-flat-a"


class FlatB(_Flat):
    name = "nb-flat-b"
    gain_factor = 1.5  # fails every colour tier


class Broken(_Flat):
    name = "nb-broken"

    def render(self, native, settings):
        raise bf.RenderError("nb-broken: engine exploded")


@pytest.fixture
def flats():
    for cls in (FlatA, FlatB, Broken):
        register_backend(cls.name, cls)
    yield
    for cls in (FlatA, FlatB, Broken):
        unregister_backend(cls.name)
    bf.close_backends()


def _png_image(data: bytes) -> np.ndarray:
    assert data.startswith(b"\x89PNG")
    return np.asarray(Image.open(io.BytesIO(data)))


def _embedded_images(html: str) -> list[np.ndarray]:
    return [_png_image(base64.b64decode(m)) for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


def test_compare_report_shows_verdict_metrics_and_sheet():
    scene = depth_plane_scene()
    a = FlatA().render(scene, bf.resolve_settings(outputs=("rgb", "depth")))
    b = FlatB().render(scene, bf.resolve_settings(outputs=("rgb", "depth")))
    rep = bf.compare(a, b, tier="pathtracer", names=("mine", "theirs<ref>"))
    assert not rep.passed
    html = rep._repr_html_()
    assert "mine vs theirs&lt;ref&gt;" in html  # names are escaped
    assert "FAIL" in html and "pathtracer" in html
    assert "mean_rel_error" in html and "rel_diff_q99" in html
    for failure in rep.failures:  # every failure is listed
        assert failure.split(" = ")[0] in html
    (sheet,) = _embedded_images(html)
    png = _png_image(rep._repr_png_())
    assert np.array_equal(sheet, png)
    assert np.array_equal(png, rep.contact_sheet())
    # three rows (a, b, the heat maps) of two outputs (rgb, depth): taller and wider than one tile
    h, w = a.rgba.shape[:2]
    tile_h = round(h * 160 / w)
    assert png.shape[0] >= 3 * tile_h and png.shape[1] >= 2 * 160
    # the colour tiles of a and b differ where the plane is (0.25 vs 0.375 linear grey)
    assert png.std() > 10


def test_crosscheck_report_html_tables_and_png(flats):
    scene = depth_plane_scene()
    rep = bf.crosscheck(
        scene, backends=("nb-flat-a", "nb-flat-b", "nb-broken", "nb-missing"), samples=2, outputs=("rgb", "depth")
    )
    assert not rep.passed
    html = rep._repr_html_()
    assert "Crosscheck of scene" in html
    for name in ("nb-flat-a", "nb-flat-b", "nb-broken", "nb-missing"):
        assert name in html
    assert "engine exploded" in html and "skipped: not registered" in html
    # the verdict table: one row for the pair, its verdict FAIL, its key metric
    row = re.search(r"<tr><td>nb-flat-a</td><td>nb-flat-b</td>.*?</tr>", html)
    assert row is not None and ">FAIL<" in row.group(0) and "rgb.mean_rel_error=" in row.group(0)
    (sheet,) = _embedded_images(html)
    assert np.array_equal(sheet, _png_image(rep._repr_png_()))
    assert np.array_equal(sheet, rep.contact_sheet())


def test_progress_is_automatic_forced_or_off(monkeypatch, flats):
    bars = []

    class Bar:
        def __init__(self, total, desc, unit, dynamic_ncols, file):
            self.total, self.desc, self.n, self.closed, self.postfix = total, desc, 0, False, []
            bars.append(self)

        def update(self, n=1):
            self.n += n

        def set_postfix_str(self, s="", refresh=True):
            self.postfix.append(s)

        def close(self):
            self.closed = True

    import tqdm.auto

    monkeypatch.setattr(tqdm.auto, "tqdm", Bar)
    scene = depth_plane_scene()
    # forced on: 2 backends x 3 repeats (path tracers) + a broken one (planned 3, counted when it fails)
    outs = ("rgb", "depth")
    bf.crosscheck(
        scene, backends=("nb-flat-a", "nb-flat-b", "nb-broken"), samples=2, repeats=3, outputs=outs, progress=True
    )
    (bar,) = bars
    assert (bar.desc, bar.total, bar.n, bar.closed) == ("crosscheck", 9, 9, True)
    assert bar.postfix == [f"{name} seed {s}" for name in ("nb-flat-a", "nb-flat-b") for s in (0, 1, 2)] + [
        "nb-broken seed 0"
    ]
    # off when asked, and automatic: off when stderr is not a terminal (pytest captures it)
    bf.crosscheck(scene, backends=("nb-flat-a",), samples=2, outputs=outs, progress=False)
    bf.crosscheck(scene, backends=("nb-flat-a",), samples=2, outputs=outs)
    assert len(bars) == 1
    monkeypatch.setattr(sys, "stderr", type("Tty", (io.StringIO,), {"isatty": lambda self: True})())
    bf.crosscheck(scene, backends=("nb-flat-a",), samples=2, outputs=outs)
    assert len(bars) == 2 and bars[1].n == bars[1].total == 4  # a path tracer: 4 independent passes by default
    # the reference estimate: one step per render
    estimate_reference(lambda seed: np.full((4, 4, 3), 0.5 + 0.01 * seed), k=5, progress=True)
    assert (bars[2].desc, bars[2].total, bars[2].n, bars[2].closed) == ("estimate_reference", 5, 5, True)
    with pytest.raises(bf.InvalidSceneError, match="progress"):
        estimate_reference(lambda seed: np.zeros((2, 2)), k=2, progress="yes")
    with pytest.raises(bf.InvalidSceneError, match="progress"):
        bf.crosscheck(scene, backends=("nb-flat-a",), progress=2)


def test_progress_without_tqdm_is_silent(monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)  # import fails
    bar = progress_mod.progress_bar(3, "x", True)
    bar.update(1)
    bar.close()
    assert not progress_mod.wants_progress(False)
