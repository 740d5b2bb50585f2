"""Image files at full precision, with numpy alone: Radiance ``.hdr`` (RGBE) and 16-bit PNG.

Pillow reads neither at full precision (it cannot open Radiance files and cuts 16-bit RGB PNGs to 8 bits);
these readers decode them exactly. 16-bit TIFFs are read with ``tifffile`` when it is installed (an error
naming it otherwise: never a silently truncated image). Everything else goes through Pillow in
:func:`blendify_core.ir.colors.load_image`.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.typing import AnyArray

__all__ = ["read_radiance_hdr", "png_bit_depth", "read_png16", "read_tiff_full_precision"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _bad(name: str, path: Path, why: str) -> InvalidSceneError:
    return InvalidSceneError(f"{name}: cannot read {str(path)!r} ({why})")


# ---------------------------------------------------------------------------------------------------
# Radiance RGBE (.hdr / .pic)
# ---------------------------------------------------------------------------------------------------


def read_radiance_hdr(path: str | Path, name: str = "path") -> AnyArray:
    """(H, W, 3) float32 linear RGB of a Radiance RGBE file (flat or run-length encoded scanlines), row 0 =
    top. Values are decoded as Radiance and Blender do: (mantissa + 0.5) * 2^(exponent - 136), 0 when the
    exponent is 0."""
    p = Path(path)
    data = p.read_bytes()
    if not data.startswith(b"#?"):
        raise _bad(name, p, "not a Radiance file: no '#?' signature")
    pos, fmt = 0, None
    first = True
    while True:  # header: lines up to an empty one
        end = data.find(b"\n", pos)
        if end < 0:
            raise _bad(name, p, "not a Radiance file: the header does not end")
        line = data[pos:end].strip()
        pos = end + 1
        if first:  # the signature line
            first = False
            continue
        if not line:
            break
        if line.startswith(b"FORMAT="):
            fmt = line[7:].decode("ascii", "replace")
    if fmt not in (None, "32-bit_rle_rgbe"):
        raise _bad(name, p, f"unsupported Radiance pixel format {fmt!r} (only 32-bit_rle_rgbe)")
    end = data.find(b"\n", pos)
    tokens = data[pos:end].split() if end >= 0 else []
    pos = end + 1
    if len(tokens) != 4 or tokens[0] not in (b"-Y", b"+Y") or tokens[2] != b"+X":
        raise _bad(name, p, f"unsupported resolution line {b' '.join(tokens)!r} (expected '-Y H +X W')")
    try:
        height, width = int(tokens[1]), int(tokens[3])
    except ValueError:
        raise _bad(name, p, "bad resolution line") from None
    if height < 1 or width < 1:
        raise _bad(name, p, f"bad image size {width}x{height}")
    rgbe = _rgbe_scanlines(data, pos, width, height, name, p)
    if tokens[0] == b"+Y":  # bottom-to-top file
        rgbe = rgbe[::-1]
    mant = rgbe[..., :3].astype(np.float32)
    exp = rgbe[..., 3].astype(np.int32)
    scale = np.where(exp == 0, 0.0, np.ldexp(1.0, exp - 136)).astype(np.float32)
    return np.ascontiguousarray((mant + 0.5) * scale[..., None] * (exp[..., None] > 0))


def _rgbe_scanlines(data: bytes, pos: int, width: int, height: int, name: str, p: Path) -> AnyArray:
    buf = np.frombuffer(data, dtype=np.uint8)
    out = np.empty((height, width, 4), dtype=np.uint8)
    for y in range(height):
        new_rle = (
            8 <= width < 32768
            and pos + 4 <= len(buf)
            and buf[pos] == 2
            and buf[pos + 1] == 2
            and (int(buf[pos + 2]) << 8 | int(buf[pos + 3])) == width
        )
        if not new_rle:  # flat scanlines (old-style run lengths are refused by name)
            chunk = buf[pos : pos + 4 * width]
            if len(chunk) < 4 * width:
                raise _bad(name, p, f"truncated at scanline {y}")
            px = chunk.reshape(width, 4)
            if np.any((px[:, 0] == 1) & (px[:, 1] == 1) & (px[:, 2] == 1)):
                raise _bad(name, p, "old-style run-length encoding is not supported")
            out[y] = px
            pos += 4 * width
            continue
        pos += 4
        for c in range(4):
            x = 0
            while x < width:
                if pos >= len(buf):
                    raise _bad(name, p, f"truncated at scanline {y}")
                count = int(buf[pos])
                pos += 1
                if count > 128:  # a run of one byte
                    count -= 128
                    if pos >= len(buf):
                        raise _bad(name, p, f"truncated at scanline {y}")
                    if x + count > width:
                        raise _bad(name, p, f"bad run length at scanline {y}")
                    out[y, x : x + count, c] = buf[pos]
                    pos += 1
                else:  # literal bytes
                    if pos + count > len(buf):
                        raise _bad(name, p, f"truncated at scanline {y}")
                    if count == 0 or x + count > width:
                        raise _bad(name, p, f"bad literal length at scanline {y}")
                    out[y, x : x + count, c] = buf[pos : pos + count]
                    pos += count
                x += count
    return out


# ---------------------------------------------------------------------------------------------------
# 16-bit PNG
# ---------------------------------------------------------------------------------------------------


def png_bit_depth(path: str | Path) -> int | None:
    """The bit depth in a PNG file's header, or None when the file is not a PNG."""
    with open(path, "rb") as f:
        head = f.read(29)
    if len(head) < 29 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    return int(head[24])


def read_png16(path: str | Path, name: str = "path") -> AnyArray:
    """(H, W, C) float32 in [0, 1] (value / 65535) of a 16-bit PNG (grey, grey+alpha, RGB, RGBA; not
    interlaced), row 0 = top."""
    p = Path(path)
    data = p.read_bytes()
    pos, header, idat = 8, None, []
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + length
    if header is None:
        raise _bad(name, p, "not a PNG file")
    width, height, depth, ctype, _comp, _filt, interlace = header
    channels = {0: 1, 4: 2, 2: 3, 6: 4}.get(ctype)
    if depth != 16 or channels is None:
        raise _bad(name, p, f"expected a 16-bit grey/RGB(A) PNG, got bit depth {depth}, colour type {ctype}")
    if interlace:
        raise _bad(name, p, "interlaced 16-bit PNGs are not supported; save it without interlacing")
    bpp = 2 * channels
    try:
        raw = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8)
    except zlib.error as exc:
        raise _bad(name, p, f"corrupt image data: {exc}") from None
    stride = 1 + width * bpp
    if raw.size < height * stride:
        raise _bad(name, p, "truncated image data")
    rows = raw[: height * stride].reshape(height, stride)
    pixels = _unfilter(rows[:, 0], rows[:, 1:].reshape(height, width, bpp))
    values = pixels.reshape(height, width, channels, 2).astype(np.uint16)
    out = (values[..., 0] << 8) | values[..., 1]
    return (out.astype(np.float32) / 65535.0).astype(np.float32)


def _paeth(a: AnyArray, b: AnyArray, c: AnyArray) -> AnyArray:
    pa, pb, pc = np.abs(b - c), np.abs(a - c), np.abs(a + b - 2 * c)
    return np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))


def _unfilter(kinds: AnyArray, filtered: AnyArray) -> AnyArray:
    """Undo PNG's per-row filters on (H, W, bpp) bytes. Rows filtered with None/Sub/Up are undone a row at
    a time; Average and Paeth depend on the pixel to the left and the row above, so those images are
    undone one anti-diagonal (all pixels with x + y = d) at a time: H + W numpy steps, not H x W."""
    height, width, bpp = filtered.shape
    if np.any(kinds > 4):
        raise InvalidSceneError(f"path: bad PNG filter type {int(kinds.max())}")
    out = np.zeros((height + 1, width + 1, bpp), dtype=np.int32)  # a zero row above and column left
    src = filtered.astype(np.int32)
    if not np.any(kinds >= 3):
        for y in range(height):
            k, row = int(kinds[y]), src[y]
            if k == 1:
                row = np.cumsum(row, axis=0)
            elif k == 2:
                row = row + out[y, 1:]
            out[y + 1, 1:] = row & 255
        return out[1:, 1:].astype(np.uint8)
    kind_col = kinds.astype(np.int32)
    for d in range(height + width - 1):
        ys = np.arange(max(0, d - width + 1), min(height - 1, d) + 1)
        xs = d - ys
        a, b, c = out[ys + 1, xs], out[ys, xs + 1], out[ys, xs]
        k = kind_col[ys][:, None]
        pred = np.select([k == 1, k == 2, k == 3, k == 4], [a, b, (a + b) >> 1, _paeth(a, b, c)], 0)
        out[ys + 1, xs + 1] = (src[ys, xs] + pred) & 255
    return out[1:, 1:].astype(np.uint8)


# ---------------------------------------------------------------------------------------------------
# TIFF
# ---------------------------------------------------------------------------------------------------


def read_tiff_full_precision(path: str | Path, name: str = "path") -> AnyArray | None:
    """(H, W, C) of a TIFF with more than 8 bits per sample (uint16 -> float32 / 65535, float as stored), or
    None for an 8-bit TIFF (Pillow reads those exactly). Needs ``tifffile`` for the deep ones."""
    from PIL import Image

    p = Path(path)
    with Image.open(p) as im:
        bits = im.tag_v2.get(258, (8,)) if hasattr(im, "tag_v2") else (8,)
        mode = im.mode
    bits_t = bits if isinstance(bits, tuple) else (bits,)
    if max(int(b) for b in bits_t) <= 8 or mode in ("I;16", "I;16B", "F"):
        return None  # Pillow reads these exactly
    try:
        import tifffile
    except ImportError:
        raise InvalidSceneError(
            f"{name}: {p.name} has {max(bits_t)}-bit samples; reading it at full precision needs the 'tifffile' "
            "package (pip install tifffile), or save it as a 16-bit PNG or an EXR"
        ) from None
    arr = np.asarray(tifffile.imread(str(p)))
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.dtype == np.uint16:
        return (arr.astype(np.float32) / 65535.0).astype(np.float32)
    if arr.dtype.kind == "f":
        return arr.astype(np.float32)
    if arr.dtype == np.uint32:
        return (arr.astype(np.float64) / 4294967295.0).astype(np.float32)
    return None
