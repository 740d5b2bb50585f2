"""RenderResult: sRGB 8-bit conversion with straight alpha, PNG/EXR/NPZ files with provenance, atomic
writes and the notebook preview."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from blendify_core.errors import InvalidSceneError
from blendify_core.io.output import atomic_write
from blendify_core.pipeline.result import RenderResult

META = {
    "backend": "fake",
    "engine_version": "1.2.3",
    "scene_fingerprint": "ab" * 32,
    "settings": {"quality": "draft", "samples": 4, "outputs": ["rgb", "depth"], "time_limit": None},
    "samples": 4,
    "timings": {"render": 0.5, "total": float("inf")},
}


def make_result(rng, h=6, w=8) -> RenderResult:
    alpha = rng.uniform(0, 1, size=(h, w, 1)).astype(np.float32)
    alpha[0, 0] = 0.0
    alpha[0, 1] = 1.0
    rgb = rng.uniform(0, 1, size=(h, w, 3)).astype(np.float32) * alpha
    depth = rng.uniform(1, 5, size=(h, w)).astype(np.float32)
    depth[0, 0] = np.inf
    normal = rng.normal(size=(h, w, 3)).astype(np.float32)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return RenderResult(
        rgba=np.concatenate([rgb, alpha], axis=-1),
        depth=depth,
        normal=normal,
        albedo=rng.uniform(0, 1, size=(h, w, 3)).astype(np.float32),
        instance=rng.integers(-1, 3, size=(h, w)).astype(np.int32),
        instance_tags=["a", "b", "c"],
        meta=dict(META),
    )


def test_to_srgb8_known_values():
    rgba = np.zeros((1, 4, 4), np.float32)
    rgba[0, 0] = (0.5, 0.5, 0.5, 1.0)  # linear 0.5 -> sRGB 0.7354 -> 188
    rgba[0, 1] = (0.25, 0.1070570, 0.0, 0.5)  # premultiplied: straight (0.5, 0.2141, 0) at alpha 0.5
    rgba[0, 2] = (0.0, 0.0, 0.0, 0.0)  # background
    rgba[0, 3] = (2.0, 1.0, 0.0031308, 1.0)  # over-range clips; the linear-segment knee
    out = RenderResult(rgba=rgba).to_srgb8()
    assert out.dtype == np.uint8 and out.shape == (1, 4, 4)
    assert out[0, 0].tolist() == [188, 188, 188, 255]
    assert out[0, 1].tolist() == [188, 128, 0, 128]
    assert out[0, 2].tolist() == [0, 0, 0, 0]
    assert out[0, 3].tolist() == [255, 255, 10, 255]  # 0.0031308 * 12.92 = 0.04045 -> 10.3


def test_straight_rgba_undoes_premultiplication(rng):
    r = make_result(rng)
    s = r.straight_rgba()
    a = r.rgba[..., 3:4]
    assert np.allclose(s[..., :3] * a, r.rgba[..., :3], atol=1e-6)
    assert np.all(s[0, 0] == 0)


def test_save_png_with_provenance(rng, artifacts_dir):
    from PIL import Image

    r = make_result(rng)
    path = r.save(artifacts_dir / "out.png")
    with Image.open(path) as im:
        assert im.mode == "RGBA" and im.size == (8, 6)
        assert np.array_equal(np.asarray(im), r.to_srgb8())
        prov = json.loads(im.text["blendify"])
    assert prov["backend"] == "fake" and prov["engine_version"] == "1.2.3"
    assert prov["scene_fingerprint"] == "ab" * 32
    assert prov["settings"]["quality"] == "draft" and prov["samples"] == 4


@pytest.mark.parametrize(
    ("output", "shape"), [("depth", (6, 8)), ("normal", (6, 8, 3)), ("albedo", (6, 8, 3)), ("instance", (6, 8, 3))]
)
def test_save_other_outputs_as_png(rng, tmp_path, output, shape):
    from PIL import Image

    r = make_result(rng)
    with Image.open(r.save(tmp_path / f"{output}.png", output=output)) as im:
        arr = np.asarray(im)
    assert arr.shape == shape and arr.dtype == np.uint8
    if output == "depth":
        assert arr[0, 0] == 0 and arr[np.isfinite(r.depth)].min() >= 40  # background black, surfaces bright
    if output == "instance":
        assert np.all(arr[r.instance < 0] == 0) and np.all(arr[r.instance >= 0].max(axis=-1) >= 60)


def test_save_exr_reads_back_exactly(rng, tmp_path):
    oexr = pytest.importorskip("OpenEXR", reason="the 'openexr' package is not installed")
    r = make_result(rng)
    path = r.save(tmp_path / "out.exr")
    with oexr.File(str(path)) as f:
        back = np.asarray(f.channels()["RGBA"].pixels)
        prov = json.loads(f.header()["blendify"])
    assert back.dtype == np.float32 and np.array_equal(back, r.rgba)
    assert prov["scene_fingerprint"] == "ab" * 32 and prov["backend"] == "fake"
    depth_path = r.save(tmp_path / "depth.exr", output="depth")
    with oexr.File(str(depth_path)) as f:
        channels = f.channels()
        assert list(channels) == ["Y"]
        depth = np.asarray(channels["Y"].pixels)
    assert np.array_equal(depth, r.depth)  # +inf background survives


def test_save_npz_every_output_without_pickle(rng, tmp_path):
    r = make_result(rng)
    path = r.save(tmp_path / "out.npz")
    with np.load(path, allow_pickle=False) as data:
        for name in ("rgba", "depth", "normal", "albedo", "instance"):
            assert np.array_equal(data[name], getattr(r, name)), name
            assert data[name].dtype == getattr(r, name).dtype
        assert data["instance_tags"].tolist() == ["a", "b", "c"]
        meta = json.loads(str(data["meta"]))
    assert meta["scene_fingerprint"] == "ab" * 32 and meta["timings"]["total"] == "inf"


def test_npz_of_partial_result(tmp_path):
    r = RenderResult(depth=np.ones((2, 3), np.float32))
    with np.load(r.save(tmp_path / "d.npz"), allow_pickle=False) as data:
        assert "rgba" not in data.files and data["depth"].shape == (2, 3)


def test_failed_write_leaves_no_file_and_keeps_the_old_one(rng, tmp_path, monkeypatch):
    r = make_result(rng)
    target = r.save(tmp_path / "out.png")
    before = target.read_bytes()
    from PIL import Image

    def broken_save(self, fp, *args, **kwargs):
        with open(fp, "wb") as f:
            f.write(b"\x89PNG partial")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(OSError, match="disk full"):
        r.save(target)
    with pytest.raises(OSError, match="disk full"):
        r.save(tmp_path / "new.png")
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.png"]


def test_atomic_write_cleans_up_on_any_exception(tmp_path):
    def writer(tmp):
        with open(tmp, "w") as f:
            f.write("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "x.txt", writer)
    assert list(tmp_path.iterdir()) == []
    atomic_write(tmp_path / "x.txt", lambda tmp: open(tmp, "w").write("ok"))
    assert (tmp_path / "x.txt").read_text() == "ok"
    with pytest.raises(InvalidSceneError, match="does not exist"):
        atomic_write(tmp_path / "nope" / "x.txt", lambda tmp: None)


def test_repr_png(rng):
    from PIL import Image

    r = make_result(rng)
    data = r._repr_png_()
    assert isinstance(data, bytes) and data[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(io.BytesIO(data)) as im:
        assert np.array_equal(np.asarray(im), r.to_srgb8())
    assert RenderResult(depth=np.ones((2, 2), np.float32))._repr_png_() is None


def test_mask_and_resolution(rng):
    r = make_result(rng)
    assert r.resolution == (8, 6)
    assert np.array_equal(r.mask, np.isfinite(r.depth))
    only_instance = RenderResult(instance=r.instance)
    assert np.array_equal(only_instance.mask, r.instance >= 0)
    only_rgb = RenderResult(rgba=r.rgba)
    assert np.array_equal(only_rgb.mask, r.rgba[..., 3] > 0)
    assert RenderResult().resolution is None and RenderResult().mask is None
    assert "fake" in repr(r)


def test_to_srgb8_survives_non_finite_pixels():
    rgba = np.array([[[np.nan, np.inf, -np.inf, 1.0], [0.5, 0.5, 0.5, np.nan]]], dtype=np.float32)
    with np.errstate(all="raise"):
        out = RenderResult(rgba=rgba).to_srgb8()
    assert out[0, 0].tolist() == [0, 255, 0, 255]
    assert out[0, 1, 3] == 0
