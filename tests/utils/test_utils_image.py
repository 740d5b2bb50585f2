"""blend_with_background, crop_to_content, contact_sheet, to_display_uint8."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import blendify_core as bf
from blendify_core.ir.colorspace import linear_to_srgb, srgb_to_linear
from blendify_core.utils import blend_with_background, contact_sheet, crop_to_content, to_display_uint8


def test_blend_float_premultiplied_is_the_over_operator():
    rgba = np.zeros((2, 2, 4), np.float32)
    rgba[0, 0] = (0.2, 0.1, 0.0, 0.5)  # premultiplied
    rgba[1, 1] = (0.3, 0.3, 0.3, 1.0)
    out = blend_with_background(rgba, (1, 1, 1))
    assert out.shape == (2, 2, 3) and out.dtype == np.float32
    np.testing.assert_allclose(out[0, 0], [0.7, 0.6, 0.5], atol=1e-6)
    np.testing.assert_allclose(out[0, 1], [1, 1, 1])
    np.testing.assert_allclose(out[1, 1], [0.3, 0.3, 0.3])
    # background given in sRGB -> linearised for a linear image
    grey = blend_with_background(np.zeros((1, 1, 4), np.float32), (0.5, 0.5, 0.5))
    np.testing.assert_allclose(grey[0, 0], srgb_to_linear(0.5), rtol=1e-5)
    straight = blend_with_background(np.array([[[0.4, 0.2, 0.0, 0.5]]], np.float32), (0, 0, 0), premultiplied=False)
    np.testing.assert_allclose(straight[0, 0], [0.2, 0.1, 0.0], atol=1e-6)


def test_blend_uint8_straight_alpha_in_linear_light():
    img = np.zeros((1, 3, 4), np.uint8)
    img[0, 0] = (255, 0, 0, 255)
    img[0, 1] = (255, 0, 0, 0)
    img[0, 2] = (0, 0, 0, 128)
    out = blend_with_background(img, (1.0, 1.0, 1.0))
    assert out.dtype == np.uint8 and out.shape == (1, 3, 3)
    np.testing.assert_array_equal(out[0, 0], [255, 0, 0])
    np.testing.assert_array_equal(out[0, 1], [255, 255, 255])
    expected = round(float(linear_to_srgb(1 - 128 / 255)) * 255)  # half black over white, in linear light
    np.testing.assert_array_equal(out[0, 2], [expected] * 3)
    np.testing.assert_array_equal(blend_with_background(img[..., :3]), img[..., :3])  # no alpha: unchanged
    np.testing.assert_array_equal(blend_with_background(img, (255, 255, 255)), out)  # 0-255 colours accepted


def test_blend_accepts_render_results_and_rejects_bad_input():
    res = bf.RenderResult(rgba=np.zeros((3, 4, 4), np.float32))
    np.testing.assert_allclose(blend_with_background(res, (0, 0, 0)), 0.0)
    with pytest.raises(bf.InvalidSceneError, match="rgba"):
        blend_with_background(np.zeros((3, 4, 5)))
    with pytest.raises(bf.InvalidSceneError, match="color"):
        blend_with_background(np.zeros((3, 4, 4)), (2.0, 0, 0.5))
    with pytest.raises(bf.InvalidSceneError, match="rgba"):
        blend_with_background(bf.RenderResult())


def test_crop_to_content():
    img = np.zeros((20, 30, 4), np.float32)
    img[5:8, 10:15, 3] = 1.0
    out, box = crop_to_content(img, margin=2, return_box=True)
    assert box == (3, 10, 8, 17) and out.shape == (7, 9, 4)
    assert crop_to_content(img, margin=100).shape == img.shape
    assert crop_to_content(np.zeros((4, 4, 4))).shape == (4, 4, 4)  # no content: whole image
    rgb = np.full((10, 10, 3), 255, np.uint8)
    rgb[4, 6] = 0
    assert crop_to_content(rgb).shape == (1, 1, 3)
    with pytest.raises(bf.InvalidSceneError, match="margin"):
        crop_to_content(img, margin=-1)


def test_to_display_handles_every_layout():
    assert to_display_uint8(np.zeros((4, 5))).shape == (4, 5, 3)
    depth = np.array([[1.0, 2.0], [np.inf, 3.0]])
    d = to_display_uint8(depth)
    assert d[1, 0, 0] == 0 and d[1, 1, 0] == 255 and d[0, 0, 0] == 0
    lin = to_display_uint8(np.full((1, 1, 4), 0.5, np.float32))  # premultiplied 0.5 at alpha 0.5 = white
    np.testing.assert_array_equal(lin[0, 0], [255, 255, 255, 128])
    assert to_display_uint8(np.zeros((2, 2, 2), np.uint8)).shape == (2, 2, 4)


def test_contact_sheet_mixed_inputs_and_labels():
    imgs = [
        np.full((40, 60, 3), 200, np.uint8),
        np.zeros((20, 20), np.float32),
        np.ones((30, 10, 4), np.float32) * 0.5,
        bf.RenderResult(rgba=np.zeros((16, 16, 4), np.float32)),
        np.full((8, 8, 1), 255, np.uint8),
    ]
    sheet = contact_sheet(imgs, labels=["uint8 rgb", "gray", "rgba", "result", "a very long label " * 5], ncols=3)
    assert sheet.dtype == np.uint8 and sheet.ndim == 3 and sheet.shape[2] == 3
    pad = 4
    assert sheet.shape[1] == 3 * 60 + 4 * pad
    assert sheet.shape[0] > 2 * 40 + 3 * pad  # two rows of cells plus label strips
    # first tile is the uint8 grey at its native size
    np.testing.assert_array_equal(sheet[pad + 10, pad + 10], [200, 200, 200])
    # labels drew something dark under the first tile
    strip = sheet[pad + 40 : pad + 40 + 12, pad : pad + 60]
    assert strip.min() < 100
    no_labels = contact_sheet(imgs[:2])
    assert no_labels.shape == (40 + 2 * pad, 2 * 60 + 3 * pad, 3)
    single = contact_sheet(np.zeros((5, 5, 3), np.uint8))
    assert single.shape == (13, 13, 3)
    with pytest.raises(bf.InvalidSceneError, match="labels"):
        contact_sheet(imgs, labels=["a"])
    with pytest.raises(bf.InvalidSceneError, match="images"):
        contact_sheet([])
    with pytest.raises(bf.InvalidSceneError, match=r"images\[1\]"):
        contact_sheet([np.zeros((2, 2)), "nope"])


@settings(max_examples=50, deadline=None)
@given(
    img=arrays(np.uint8, st.tuples(st.integers(1, 6), st.integers(1, 6), st.just(4))),
    bg=st.tuples(*[st.floats(0.0, 1.0)] * 3),
)
def test_uint8_blend_lies_between_foreground_and_background(img, bg):
    out = blend_with_background(img, bg).astype(int)
    fg = img[..., :3].astype(int)
    b = np.broadcast_to(np.round(np.array(bg) * 255).astype(int), fg.shape)
    assert np.all(out >= np.minimum(fg, b) - 1) and np.all(out <= np.maximum(fg, b) + 1)
    opaque = img[..., 3] == 255
    np.testing.assert_array_equal(out[opaque], fg[opaque])
    clear = img[..., 3] == 0
    assert np.all(np.abs(out[clear] - b[clear]) <= 1)
