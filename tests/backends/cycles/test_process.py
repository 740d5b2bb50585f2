"""Process hygiene: threads, Ctrl-C, temporary files, working directory, logging, the isolated worker."""

from __future__ import annotations

import glob
import os
import signal
import tempfile
import threading

import numpy as np
import pytest
from blendify_blender import CyclesBackend

import blendify_core as bf
from blendify_core import testing
from blendify_core.errors import RenderError

pytestmark = pytest.mark.cycles


def _leftovers() -> set[str]:
    return set(glob.glob(os.path.join(tempfile.gettempdir(), "blendify_cycles_*")))


@pytest.fixture
def private_tmp(tmp_path, monkeypatch):
    """A private temporary directory (other processes may be rendering with Cycles at the same time)."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    return d


def test_no_files_left_and_cwd_unchanged(cycles, tmp_path, monkeypatch, private_tmp):
    monkeypatch.chdir(tmp_path)
    before = _leftovers()
    bf.render(
        testing.pointcloud_scene(n=50, resolution=(16, 16)),
        backend=cycles,
        samples=1,
        outputs=("rgb", "depth", "normal", "albedo", "instance"),
    )
    assert os.getcwd() == str(tmp_path)
    assert list(tmp_path.iterdir()) == [private_tmp]
    assert list(private_tmp.iterdir()) == []
    assert _leftovers() == before


def test_two_threads_are_serialised(cycles):
    scenes = [testing.pointcloud_scene(n=200, resolution=(24, 24), seed=s) for s in (1, 2)]
    serial = [bf.render(s, backend=cycles, samples=2).rgba for s in scenes]
    out: dict[int, np.ndarray] = {}
    errors: list[BaseException] = []

    def work(i: int) -> None:
        try:
            for _ in range(2):
                out[i] = bf.render(scenes[i], backend=cycles, samples=2).rgba
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for i in (0, 1):
        assert np.array_equal(out[i], serial[i])


def test_ctrl_c_leaves_the_backend_usable(cycles, bpy, private_tmp):
    scene = testing.pointcloud_scene(n=2000, resolution=(32, 32))
    before = _leftovers()

    @bpy.app.handlers.persistent  # survives the factory reset of a new scene
    def ctrl_c(*_args):  # Ctrl-C while Cycles renders
        os.kill(os.getpid(), signal.SIGINT)

    bpy.app.handlers.render_pre.append(ctrl_c)
    try:
        with pytest.raises(KeyboardInterrupt):
            bf.render(scene, backend=cycles, samples=16)
    finally:
        bpy.app.handlers.render_pre.remove(ctrl_c)
    assert _leftovers() == before == set()
    r = bf.render(scene, backend=cycles, samples=1, outputs=("rgb", "depth"))
    assert r.rgba[..., 3].max() > 0.5 and np.isfinite(r.depth).any()


def test_verbose_prints_blender_lines(capfd):
    with CyclesBackend(verbose=True) as b:
        bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=b, samples=1)
    err = capfd.readouterr().err
    assert "[blender]" in err


def test_quiet_by_default(cycles, capfd):
    bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=cycles, samples=1)
    captured = capfd.readouterr()
    assert "Saved" not in captured.out and "Saved" not in captured.err


def test_isolated_worker_matches_in_process(cycles):
    scene = testing.primitives_scene((32, 24))
    outputs = ("rgb", "depth", "normal", "albedo", "instance")
    local = bf.render(scene, backend=cycles, samples=2, outputs=outputs)
    with CyclesBackend(isolate=True, worker_max_renders=1) as b:
        a = bf.render(scene, backend=b, samples=2, outputs=outputs)
        pid = a.meta["isolated"]["worker_pid"]
        c = bf.render(scene, backend=b, samples=2, outputs=("rgb",))
        assert c.meta["isolated"]["worker_pid"] != pid  # restarted after worker_max_renders
    for k in outputs:
        key = "rgba" if k == "rgb" else k
        assert np.array_equal(getattr(a, key), getattr(local, key)), k
    assert a.instance_tags == local.instance_tags
    assert np.array_equal(c.rgba, local.rgba)


def test_isolated_worker_reports_errors_and_recovers(tmp_path):
    scene = testing.plane_scene("sun", resolution=(8, 8))
    with CyclesBackend(isolate=True) as b:
        bf.render(scene, backend=b, samples=1)
        b._worker._proc.kill()  # a crash of the worker
        b._worker._proc.wait()
        r = bf.render(scene, backend=b, samples=1)  # a fresh worker takes over
        assert r.rgba.shape == (8, 8, 4)
        bad = tmp_path / "broken.png"
        bad.write_bytes(b"not a png")
        scene2 = testing.plane_scene("sun", resolution=(8, 8))
        tex = bf.FileTextureColors.__new__(bf.FileTextureColors)
        tex.texture_path, tex.uv_map, tex.color_space, tex.interpolation, tex._cache = (
            str(bad),
            bf.VertexUV(np.zeros((4, 2))),
            "srgb",
            "linear",
            np.zeros((1, 1, 3), np.uint8),
        )
        v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
        scene2.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), tex, tag="broken")
        with pytest.raises((RenderError, bf.InvalidSceneError), match="broken.png"):
            bf.render(scene2, backend=b, samples=1)
