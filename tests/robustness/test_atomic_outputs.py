"""Outputs are written atomically: a writer that fails half-way (disk full, Ctrl-C) leaves neither a
half-written file nor a temporary file behind, and an existing file at the destination is unchanged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf


def _result() -> bf.RenderResult:
    rgba = np.zeros((6, 8, 4), np.float32)
    rgba[..., 3] = 1.0
    return bf.RenderResult(rgba=rgba, depth=np.full((6, 8), 2.0, np.float32), meta={"backend": "test"})


def _scene() -> bf.Scene:
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    scene.set_perspective_camera((16, 12), fov_x=0.7, translation=(0, 0, 4))
    return scene


def _patch_png(monkeypatch, exc):
    from PIL import Image

    def save(self, fp, *args, **kwargs):
        Path(fp).write_bytes(b"PARTIAL" * 100)
        raise exc

    monkeypatch.setattr(Image.Image, "save", save)


def _patch_npz(monkeypatch, exc):
    def savez(f, **arrays):
        f.write(b"PARTIAL" * 100)
        raise exc

    monkeypatch.setattr(np, "savez_compressed", savez)


WRITERS = {
    "result-png": ("x.png", _patch_png, lambda p: _result().save(p)),
    "result-depth-png": ("x.depth.png", _patch_png, lambda p: _result().save(p, output="depth")),
    "result-npz": ("x.npz", _patch_npz, lambda p: _result().save(p)),
    "scene-npz": ("s.npz", _patch_npz, lambda p: _scene().save(p)),
}


@pytest.mark.parametrize(
    "exc", [OSError(28, "No space left on device"), KeyboardInterrupt()], ids=["disk-full", "ctrl-c"]
)
@pytest.mark.parametrize("writer", list(WRITERS))
@pytest.mark.parametrize("existing", [False, True], ids=["new", "overwrite"])
def test_failed_write_leaves_nothing_behind(writer, exc, existing, tmp_path, monkeypatch):
    """A writer failing half-way leaves no partial/temporary file; an existing file is unchanged."""
    name, patch, call = WRITERS[writer]
    target = tmp_path / name
    if existing:
        target.write_bytes(b"OLD CONTENT")
    patch(monkeypatch, exc)
    with pytest.raises(type(exc)):
        call(target)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == ([name] if existing else []), f"left behind: {left}"
    if existing:
        assert target.read_bytes() == b"OLD CONTENT", "the existing file was changed by a failed write"


def test_exr_failure_leaves_nothing_behind(tmp_path, monkeypatch):
    """The EXR writer too (OpenEXR raising inside the write)."""
    openexr = pytest.importorskip("OpenEXR")

    class Broken:
        def __init__(self, *a, **k):
            pass

        def write(self, path):
            Path(path).write_bytes(b"PARTIAL")
            raise OSError(28, "No space left on device")

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(openexr, "File", Broken)
    with pytest.raises(OSError):
        _result().save(tmp_path / "x.exr")
    assert list(tmp_path.iterdir()) == []


def test_successful_writes_leave_only_the_file(tmp_path):
    """A successful save leaves exactly the file (no temporary file), readable again."""
    _result().save(tmp_path / "x.png")
    _result().save(tmp_path / "x.npz")
    _scene().save(tmp_path / "s.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.npz", "x.npz", "x.png"]
    assert bf.Scene.load(tmp_path / "s.npz").renderables["ball"].radius == 0.5
