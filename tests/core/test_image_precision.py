"""Image files at full precision: Radiance .hdr and 16-bit PNG / TIFF decode exactly (files the test
writes), EXR as before; environment maps and textures keep what the file holds."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.io.images import read_png16, read_radiance_hdr
from blendify_core.ir.colors import load_image
from blendify_core.testing import rgbe_encode, write_png16, write_radiance_hdr

RNG = np.random.default_rng(22)


def _hdr_values(h: int, w: int) -> np.ndarray:
    vals = RNG.uniform(0.0, 1.0, (h, w, 3)) * np.exp(RNG.uniform(-6, 6, (h, w, 1)))
    vals[0, :5] = 0.0  # black pixels (exponent 0)
    vals[1, :] = (40.0, 2.0, 0.01)  # a run: RLE compresses it
    return vals


@pytest.mark.parametrize("rle", [True, False])
def test_radiance_hdr_decodes_to_rgbe_precision(tmp_path, rle):
    vals = _hdr_values(9, 37)
    path = write_radiance_hdr(tmp_path / "env.hdr", vals, rle=rle)
    got = load_image(path)
    assert got.dtype == np.float32 and got.shape == (9, 37, 3)
    # RGBE keeps 8 mantissa bits of the largest channel: each value within 1/256 of that channel
    tol = vals.max(axis=-1, keepdims=True) / 256.0
    assert np.all(np.abs(got - vals) <= tol + 1e-30)
    assert np.all(got[0, :5] == 0.0) and got[1, 0, 0] == pytest.approx(40.0, rel=1 / 256)
    # exactly Radiance's / Blender's decoding of the stored bytes
    rgbe = rgbe_encode(vals)
    expect = (rgbe[..., :3] + 0.5) * np.ldexp(1.0, rgbe[..., 3:].astype(int) - 136) * (rgbe[..., 3:] > 0)
    np.testing.assert_allclose(got, expect, rtol=1e-6)


def test_radiance_hdr_bad_files_name_the_problem(tmp_path):
    bad = tmp_path / "bad.hdr"
    bad.write_bytes(b"not radiance")
    with pytest.raises(bf.InvalidSceneError, match="no '#\\?' signature"):
        read_radiance_hdr(bad)
    path = write_radiance_hdr(tmp_path / "t.hdr", _hdr_values(4, 16))
    path.write_bytes(path.read_bytes()[:-20])
    with pytest.raises(bf.InvalidSceneError, match="truncated"):
        load_image(path)
    xyze = tmp_path / "xyze.hdr"
    xyze.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n\x00\x00\x00\x00")
    with pytest.raises(bf.InvalidSceneError, match="xyze"):
        load_image(xyze)


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png16_every_filter_type_decodes_exactly(tmp_path, channels):
    values = RNG.integers(0, 65536, (11, 13, channels), dtype=np.uint16)
    values[3] = values[2]  # repeated rows, as a real image has
    path = write_png16(tmp_path / "t.png", values, filters=(0, 1, 2, 3, 4))
    got = load_image(path)
    assert got.dtype == np.float32 and got.shape == (11, 13, channels)
    np.testing.assert_array_equal(np.round(got * 65535.0).astype(np.uint16), values)


@pytest.mark.parametrize("filters", [(0,), (1,), (2,), (1, 2)])
def test_png16_fast_path_filters(tmp_path, filters):
    values = RNG.integers(0, 65536, (7, 5, 3), dtype=np.uint16)
    got = read_png16(write_png16(tmp_path / "t.png", values, filters=filters))
    np.testing.assert_array_equal(np.round(got * 65535.0).astype(np.uint16), values)


def test_png16_keeps_steps_below_8_bits(tmp_path):
    """Two 16-bit levels 1/65535 apart stay apart (Pillow cut both to the same 8-bit value)."""
    values = np.array([[[32768, 32768, 32768], [32769, 32769, 32769]]], dtype=np.uint16)
    got = load_image(write_png16(tmp_path / "t.png", values, filters=(4,)))
    assert got[0, 1, 0] - got[0, 0, 0] == pytest.approx(1 / 65535, rel=1e-3)


def test_tiff16_reads_at_full_precision_or_names_tifffile(tmp_path, monkeypatch):
    values = RNG.integers(0, 65536, (6, 5, 3), dtype=np.uint16)
    path = tmp_path / "t.tif"
    try:
        import tifffile
    except ImportError:
        pytest.skip("tifffile is not installed: 16-bit RGB TIFFs are refused naming it (tested below)")
    tifffile.imwrite(str(path), values, photometric="rgb")
    got = load_image(path)
    np.testing.assert_array_equal(np.round(got * 65535.0).astype(np.uint16), values)
    monkeypatch.setitem(sys.modules, "tifffile", None)
    with pytest.raises(bf.InvalidSceneError, match="tifffile"):
        load_image(path)


def test_environment_map_from_hdr_keeps_values_above_one(tmp_path):
    vals = np.broadcast_to(np.array([3.0, 1.5, 0.25]), (8, 16, 3)).copy()
    path = write_radiance_hdr(tmp_path / "sky.hdr", vals)
    env = bf.Scene().lights.set_environment_map(path)
    assert env.color_space == "linear"
    np.testing.assert_allclose(env.linear_rgb_image(), vals, atol=3.0 / 256)  # RGBE: 8 bits of the largest channel


def test_16bit_texture_reaches_the_linear_image(tmp_path):
    values = np.array([[[30000, 30000, 30000], [30070, 30070, 30070]]], dtype=np.uint16)
    path = write_png16(tmp_path / "t.png", values, filters=(1,))
    tex = bf.FileTextureColors(str(path), bf.VertexUV(np.zeros((3, 2))), color_space="linear")
    lin = tex.linear_rgba_image()
    assert lin[0, 1, 0] - lin[0, 0, 0] == pytest.approx(70 / 65535, rel=1e-4)
