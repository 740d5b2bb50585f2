"""Small image helpers for figures: compositing over a colour, cropping, labelled contact sheets.

Conventions (the library's): a float RGBA image is scene-LINEAR with PREMULTIPLIED alpha (as
:attr:`RenderResult.rgba`); a uint8 image is sRGB-encoded with STRAIGHT alpha (as a PNG, or
:meth:`RenderResult.to_srgb8`). Every function here also accepts a :class:`RenderResult`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colorspace import linear_to_srgb, srgb8_to_linear, srgb_to_linear
from blendify_core.ir.validate import as_bool, strict_arguments
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import AnyArray, Float64Array

__all__ = ["blend_with_background", "crop_to_content", "contact_sheet", "to_display_uint8"]


def _as_image(name: str, image: ArrayLike | RenderResult) -> AnyArray:
    """An (H, W, C) array (C in 1, 2, 3, 4) of uint8 or float from an array or a RenderResult."""
    if isinstance(image, RenderResult):
        if image.rgba is None:
            raise InvalidSceneError(f"{name}: this RenderResult has no 'rgb' output")
        image = image.rgba
    if isinstance(image, (str, bytes)) or image is None:
        raise InvalidSceneError(f"{name}: expected an image array, got {_describe(image)}")
    arr = np.asarray(image)
    if arr.dtype == bool:
        arr = arr.astype(np.uint8) * 255
    if arr.dtype.kind not in "uif":
        raise InvalidSceneError(f"{name}: expected a uint8 or float image, got {_describe(image)}")
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InvalidSceneError(f"{name}: expected an image of shape (H, W), (H, W, 1|2|3|4), got {_describe(arr)}")
    if arr.dtype.kind in "iu" and arr.dtype != np.uint8:
        if arr.size and (arr.min() < 0 or arr.max() > 255):
            raise InvalidSceneError(f"{name}: integer images must hold 0-255 values, got dtype {arr.dtype}")
        arr = arr.astype(np.uint8)
    return arr


def _color3(name: str, color: ArrayLike) -> Float64Array:
    c = np.asarray(color, dtype=np.float64).ravel() if not isinstance(color, str) else None
    if c is None or c.shape not in ((3,), (4,), (1,)) or not np.all(np.isfinite(c)):
        raise InvalidSceneError(f"{name}: expected an RGB colour (3 values in [0, 1]), got {_describe(color)}")
    if c.shape == (1,):
        c = np.repeat(c, 3)
    c = c[:3]
    if np.any(c > 1.0) and np.all(c <= 255.0) and np.all(c == np.round(c)):
        c = c / 255.0  # (255, 255, 255)-style colours
    if np.any(c < 0) or np.any(c > 1):
        raise InvalidSceneError(f"{name}: expected RGB values in [0, 1] (or 0-255 integers), got {c.tolist()}")
    return c


@strict_arguments
def blend_with_background(
    rgba: ArrayLike | RenderResult,
    color: ArrayLike = (1.0, 1.0, 1.0),
    premultiplied: bool | None = None,
    color_space: str = "srgb",
) -> np.ndarray:
    """Composite an RGBA image over a uniform background colour; returns an RGB image.

    - float input (a :class:`RenderResult` or its ``rgba``): linear, premultiplied by default
      (``premultiplied=False`` for straight alpha); returns (H, W, 3) float32 LINEAR RGB
      (``out = rgb + (1 - alpha) * background``).
    - uint8 input: sRGB-encoded, straight alpha by default; blended in linear light (as a renderer
      composites) and returned as (H, W, 3) uint8 sRGB. (blendify blended the sRGB bytes directly,
      which darkens anti-aliased edges.)

    ``color``: the background, sRGB-encoded by default (``color_space="linear"`` for linear values);
    a triple of integers with some value above 1 is read as 0-255 (so (255, 255, 255) works, but (1, 1, 0)
    means [0, 1] values). RGB images without alpha are returned unchanged (as RGB).
    """
    img = _as_image("rgba", rgba)
    if color_space not in ("srgb", "linear"):
        raise InvalidSceneError(f"color_space: expected 'srgb' or 'linear', got {color_space!r}")
    bg = _color3("color", color)
    bg_lin = srgb_to_linear(bg) if color_space == "srgb" else bg
    channels = img.shape[2]
    if channels in (1, 2):  # gray or gray + alpha
        rgb_part = np.repeat(img[..., :1], 3, axis=2)
        img = np.concatenate([rgb_part, img[..., 1:2]], axis=2) if channels == 2 else rgb_part
    if img.dtype == np.uint8:
        if img.shape[2] == 3:
            return np.array(img)
        premul = False if premultiplied is None else as_bool("premultiplied", premultiplied)
        lin = srgb8_to_linear(img[..., :3]).astype(np.float64)
        a = img[..., 3:4].astype(np.float64) / 255.0
        fg = lin if premul else lin * a
        out = fg + (1.0 - a) * bg_lin
        return np.round(linear_to_srgb(np.clip(out, 0.0, 1.0)) * 255.0).astype(np.uint8)
    arr = img.astype(np.float32)
    if arr.shape[2] == 3:
        return np.array(arr)
    premul = True if premultiplied is None else as_bool("premultiplied", premultiplied)
    a = np.clip(arr[..., 3:4], 0.0, 1.0)
    fg = arr[..., :3] if premul else arr[..., :3] * a
    return (fg + (1.0 - a) * bg_lin.astype(np.float32)).astype(np.float32)


@strict_arguments
def to_display_uint8(image: ArrayLike | RenderResult, linear: bool = True, premultiplied: bool = True) -> np.ndarray:
    """Any image as uint8 for display: (H, W, 3) or (H, W, 4) (straight alpha, sRGB).

    uint8 inputs pass through (gray is expanded to RGB). Float RGB(A) inputs are scene-linear and
    premultiplied by default (the RenderResult convention) and are sRGB-encoded; ``linear=False`` takes
    display-ready values in [0, 1]. A single-channel float image (depth, a mask, a heat map) is mapped
    to [0, 1] over its finite values when it leaves that range (non-finite values -> 0)."""
    linear, premultiplied = as_bool("linear", linear), as_bool("premultiplied", premultiplied)
    img = _as_image("image", image)
    if img.dtype == np.uint8:
        if img.shape[2] in (1, 2):
            gray = np.repeat(img[..., :1], 3, axis=2)
            return np.concatenate([gray, img[..., 1:2]], axis=2) if img.shape[2] == 2 else gray
        return np.array(img)
    f = img.astype(np.float64)
    if f.shape[2] in (1, 2):
        g = f[..., 0]
        finite = np.isfinite(g)
        g = np.where(finite, g, 0.0)
        if finite.any():
            lo, hi = float(g[finite].min()), float(g[finite].max())
            if lo < 0.0 or hi > 1.0:
                g = np.where(finite, (g - lo) / max(hi - lo, 1e-12), 0.0)
        rgb = np.repeat(np.clip(g, 0.0, 1.0)[..., None], 3, axis=2)
        out = np.round(rgb * 255.0).astype(np.uint8)
        if f.shape[2] == 2:
            alpha = np.round(np.clip(np.nan_to_num(f[..., 1:2]), 0, 1) * 255.0).astype(np.uint8)
            out = np.concatenate([out, alpha], axis=2)
        return out
    f = np.nan_to_num(f, nan=0.0, posinf=1.0, neginf=0.0)
    rgb = f[..., :3]
    alpha = np.clip(f[..., 3:4], 0.0, 1.0) if f.shape[2] == 4 else None
    if alpha is not None and premultiplied:
        rgb = np.divide(rgb, alpha, out=np.zeros_like(rgb), where=alpha > 0)
    enc = linear_to_srgb(np.clip(rgb, 0.0, 1.0)) if linear else np.clip(rgb, 0.0, 1.0)
    out = np.round(enc * 255.0).astype(np.uint8)
    if alpha is not None:
        out = np.concatenate([out, np.round(alpha * 255.0).astype(np.uint8)], axis=2)
    return out


@strict_arguments
def crop_to_content(
    rgba: ArrayLike | RenderResult, margin: int = 0, threshold: float = 0.0, return_box: bool = False
) -> np.ndarray | tuple[np.ndarray, tuple[int, int, int, int]]:
    """Crop an image to the bounding box of its content plus ``margin`` pixels (clipped to the image).

    Content = alpha > ``threshold`` (alpha in [0, 1] units) for RGBA / gray+alpha images; for images
    without alpha, pixels that differ from the top-left pixel's colour by more than ``threshold``.
    An image without content is returned whole. ``return_box=True`` also returns the box
    ``(top, bottom, left, right)`` (slice bounds, bottom/right exclusive)."""
    return_box = as_bool("return_box", return_box)
    img = _as_image("rgba", rgba)
    m = int(margin) if np.isscalar(margin) and float(margin) == int(margin) else -1
    if m < 0:
        raise InvalidSceneError(f"margin: expected a non-negative integer number of pixels, got {margin!r}")
    scale = 255.0 if img.dtype == np.uint8 else 1.0
    if img.shape[2] in (2, 4):
        content = img[..., -1].astype(np.float64) / scale > threshold
    else:
        diff = np.abs(img.astype(np.float64) - img[:1, :1].astype(np.float64)).max(axis=2) / scale
        content = diff > threshold
    h, w = img.shape[:2]
    rows, cols = np.flatnonzero(content.any(axis=1)), np.flatnonzero(content.any(axis=0))
    if rows.size == 0:
        top, bottom, left, right = 0, h, 0, w
    else:
        top, bottom = max(0, rows[0] - m), min(h, rows[-1] + 1 + m)
        left, right = max(0, cols[0] - m), min(w, cols[-1] + 1 + m)
    box = (int(top), int(bottom), int(left), int(right))
    out = np.array(img[box[0] : box[1], box[2] : box[3]])
    if np.asarray(rgba if not hasattr(rgba, "rgba") else rgba.rgba).ndim == 2:
        out = out[..., 0]
    return (out, box) if return_box else out


def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: fixed-size bitmap font
        return ImageFont.load_default()


@strict_arguments
def contact_sheet(
    images: Sequence[ArrayLike | RenderResult],
    labels: Sequence[str] | None = None,
    ncols: int | None = None,
    cell_size: tuple[int, int] | None = None,
    background: ArrayLike = (1.0, 1.0, 1.0),
    pad: int = 4,
    font_size: int = 12,
    text_color: ArrayLike = (0.0, 0.0, 0.0),
    linear: bool = True,
) -> np.ndarray:
    """Tile images into one (H, W, 3) uint8 sRGB picture with a text label under each tile.

    ``images``: arrays (gray, gray+alpha, RGB or RGBA; uint8 sRGB straight alpha or float linear
    premultiplied, see :func:`to_display_uint8`) or RenderResults, of any sizes. Each is scaled to fit
    its cell (default: the largest image's size) keeping its aspect ratio, centred, and composited over
    ``background``. ``labels``: one string per image (or None); long labels are shortened with "...".
    ``ncols``: default ceil(sqrt(n)).
    """
    from PIL import Image, ImageDraw

    if isinstance(images, np.ndarray) and (images.ndim == 2 or (images.ndim == 3 and images.shape[2] <= 4)):
        images = [images]  # one image, not a stack
    if not isinstance(images, Sequence) and not isinstance(images, np.ndarray):
        raise InvalidSceneError(f"images: expected a list of images, got {_describe(images)}")
    images = list(images)
    n = len(images)
    if n == 0:
        raise InvalidSceneError("images: expected at least one image, got an empty list")
    if labels is not None:
        if isinstance(labels, str) or len(labels) != n:
            raise InvalidSceneError(f"labels: expected {n} strings (one per image), got {_describe(labels)}")
        labels = ["" if t is None else str(t) for t in labels]
    if ncols is None:
        ncols = int(np.ceil(np.sqrt(n)))
    if not isinstance(ncols, (int, np.integer)) or ncols < 1:
        raise InvalidSceneError(f"ncols: expected a positive integer, got {ncols!r}")
    ncols = int(min(ncols, n))
    nrows = int(np.ceil(n / ncols))
    if not isinstance(pad, (int, np.integer)) or pad < 0:
        raise InvalidSceneError(f"pad: expected a non-negative integer, got {pad!r}")
    disp = [to_display_uint8(_as_image(f"images[{i}]", im), linear=linear) for i, im in enumerate(images)]
    if cell_size is None:
        cw = max(d.shape[1] for d in disp)
        ch = max(d.shape[0] for d in disp)
    else:
        cs = np.asarray(cell_size)
        if cs.shape != (2,) or np.any(cs < 1):
            raise InvalidSceneError(f"cell_size: expected (width, height) in pixels, got {cell_size!r}")
        cw, ch = int(cs[0]), int(cs[1])
    bg = np.round(_color3("background", background) * 255).astype(np.uint8)
    fg = tuple(int(v) for v in np.round(_color3("text_color", text_color) * 255))
    font = _font(int(font_size))
    has_labels = labels is not None and any(labels)
    label_h = 0
    if has_labels:
        bbox = font.getbbox("Ag|")
        label_h = int(bbox[3] - min(bbox[1], 0)) + 4
    tile_h = ch + label_h
    sheet_w = ncols * cw + (ncols + 1) * pad
    sheet_h = nrows * tile_h + (nrows + 1) * pad
    sheet = Image.new("RGB", (sheet_w, sheet_h), tuple(int(v) for v in bg))
    draw = ImageDraw.Draw(sheet)
    for i, d in enumerate(disp):
        r, c = divmod(i, ncols)
        x0 = pad + c * (cw + pad)
        y0 = pad + r * (tile_h + pad)
        h, w = d.shape[:2]
        s = min(cw / w, ch / h)
        nw, nh = max(1, round(w * s)), max(1, round(h * s))
        im = Image.fromarray(d)
        if (nw, nh) != (w, h):
            resample = Image.Resampling.NEAREST if s >= 2 and float(s).is_integer() else Image.Resampling.LANCZOS
            if im.mode == "RGBA":  # resize premultiplied so transparent pixels do not bleed their colour
                im = im.convert("RGBa").resize((nw, nh), resample).convert("RGBA")
            else:
                im = im.resize((nw, nh), resample)
        px, py = x0 + (cw - nw) // 2, y0 + (ch - nh) // 2
        if im.mode == "RGBA":
            arr = np.asarray(im)
            comp = blend_with_background(arr, bg.astype(np.float64) / 255.0)
            sheet.paste(Image.fromarray(comp), (px, py))
        else:
            sheet.paste(im, (px, py))
        if has_labels and labels[i]:  # type: ignore[index]
            text = labels[i]  # type: ignore[index]
            if draw.textlength(text, font=font) > cw:
                while text and draw.textlength(text + "...", font=font) > cw:
                    text = text[:-1]
                text = text + "..."
            tw = draw.textlength(text, font=font)
            draw.text((x0 + (cw - tw) / 2, y0 + ch + 2), text, fill=fg, font=font)
    return np.asarray(sheet).copy()
