"""Colour sources and UV maps of renderables, and data textures of materials.

One rule for every colour class: values are sRGB-encoded by default (as colour pickers and image files
are), ``color_space="linear"`` takes linear values. Backends read linear values through ``linear_rgba``
(uniform and per-vertex colours) or ``linear_rgba_image()`` (textures), or pass the raw data and its
colour space to an engine that decodes sRGB itself. Data textures (roughness, metallic, normal maps) are
never colour-managed.

Texture images are stored with row 0 = the TOP of the image (as image files and numpy images are); UV
(0, 0) is the BOTTOM-left of the texture (OpenGL/Blender/OBJ convention).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.io.images import png_bit_depth, read_png16, read_radiance_hdr, read_tiff_full_precision
from blendify_core.ir.colorspace import srgb8_to_linear, srgb_to_linear
from blendify_core.ir.validate import _describe, as_array, as_choice, as_float, frozen, raw_array, strict_api
from blendify_core.typing import AnyArray

__all__ = [
    "Colors",
    "UniformColors",
    "VertexColors",
    "TextureColors",
    "FileTextureColors",
    "UVMap",
    "VertexUV",
    "FacesUV",
    "TextureMap",
    "NormalMap",
    "load_image",
]

COLOR_SPACES = ("srgb", "linear")
INTERPOLATIONS = ("linear", "closest")


def _color_space(value: Any) -> str:
    return as_choice("color_space", value, COLOR_SPACES)


def _to_linear(values: AnyArray, color_space: str) -> AnyArray:
    """Linearise the RGB channels of float values in [0, 1]; alpha is never colour-managed."""
    out = np.array(values, dtype=np.float32 if values.dtype == np.float32 else np.float64)
    if color_space == "srgb":
        out[..., :3] = srgb_to_linear(out[..., :3])
    return out


def load_image(path: str | os.PathLike[str]) -> AnyArray:
    """Read an image file: uint8 (H, W, C) for 8-bit formats, float32 for EXR, Radiance HDR (linear values)
    and 16-bit PNG/TIFF (value / 65535, full precision); row 0 = top."""
    p = Path(path)
    if not p.is_file():
        raise InvalidSceneError(f"texture_path: no such file {str(p)!r}")
    suffix = p.suffix.lower()
    if suffix == ".exr":
        try:
            import OpenEXR
        except ImportError:
            raise InvalidSceneError(
                f"texture_path: reading {p.name} needs the 'openexr' package (pip install openexr)"
            ) from None
        with OpenEXR.File(str(p)) as f:
            channels = f.channels()
            if "RGBA" in channels:
                return np.asarray(channels["RGBA"].pixels, dtype=np.float32)
            if "RGB" in channels:
                return np.asarray(channels["RGB"].pixels, dtype=np.float32)
            names = [n for n in ("R", "G", "B", "A") if n in channels]
            if not names:
                raise InvalidSceneError(f"texture_path: {p.name} has no R/G/B channels")
            return np.stack([np.asarray(channels[n].pixels, dtype=np.float32) for n in names], axis=-1)
    if suffix in (".hdr", ".pic", ".rgbe"):
        return read_radiance_hdr(p, "texture_path")
    if suffix == ".png" and png_bit_depth(p) == 16:
        return read_png16(p, "texture_path")
    if suffix in (".tif", ".tiff"):
        deep = read_tiff_full_precision(p, "texture_path")
        if deep is not None:
            return deep
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(p) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                return (np.asarray(im, dtype=np.float32) / 65535.0)[..., None]
            if im.mode == "F":
                return np.asarray(im, dtype=np.float32)[..., None]
            if im.mode not in ("L", "LA", "RGB", "RGBA"):
                im = im.convert("RGBA" if "A" in im.getbands() else "RGB")
            arr = np.asarray(im)
    except (UnidentifiedImageError, OSError) as exc:
        raise InvalidSceneError(f"texture_path: cannot read {str(p)!r} as an image ({exc})") from None
    if arr.ndim == 2:
        arr = arr[..., None]
    return arr


def _image_header(path: str) -> tuple[int, bool] | None:
    """(pixel count, has an alpha channel) from an image file's header without decoding the pixels, or
    None when the header cannot be read that way."""
    try:
        if Path(path).suffix.lower() == ".exr":
            import OpenEXR

            with OpenEXR.File(str(path), header_only=True) as f:  # read inside: closing empties it
                header = f.header()
                box = header["dataWindow"]
                pixels = int((box[1][0] - box[0][0] + 1) * (box[1][1] - box[0][1] + 1))
                names = [str(getattr(c, "name", "")) for c in header.get("channels", [])]
            if not names or not all(names):
                return None
            return pixels, any(n == "A" or n.endswith(".A") for n in names)
        from PIL import Image

        with Image.open(path) as im:  # lazy: reads the header only
            return im.width * im.height, "A" in im.getbands() or "transparency" in im.info
    except Exception:  # noqa: BLE001 - any doubt: fall back to decoding
        return None


def _check_image(name: str, texture: Any, *, max_value: float | None = 1.0) -> AnyArray:
    arr = raw_array(name, texture)
    if arr.dtype.kind not in "uif" or arr.dtype.kind == "b":
        raise InvalidSceneError(f"{name}: expected a uint8 or float image, got {_describe(texture)}")
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InvalidSceneError(
            f"{name}: expected an image of shape (H, W), (H, W, 3) or (H, W, 4), got {_describe(arr)}"
        )
    if arr.dtype == np.uint8:
        return frozen(np.array(arr))
    if arr.dtype.kind in "iu":
        raise InvalidSceneError(f"{name}: integer images must be uint8 (0-255), got dtype {arr.dtype}")
    return as_array(name, arr, dtype=np.float32, min_value=0.0, max_value=max_value)


def _to_rgba(img: AnyArray) -> AnyArray:
    if img.shape[2] == 4:
        return img
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    alpha = np.ones(img.shape[:2] + (1,), dtype=img.dtype)
    if img.dtype == np.uint8:
        alpha[:] = 255
    return np.concatenate([img, alpha], axis=2)


class _Immutable:
    """Public attributes are set once (in ``__init__``): backends cache colour sources and data textures
    by identity, so an in-place change would never reach them. Build a new one and pass it to
    ``update_colors`` (or assign it to the material parameter) instead."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        strict_api(cls)  # colour sources, UV maps, texture and normal maps: unknown keywords raise

    def __setattr__(self, name: str, value: Any) -> None:
        if not name.startswith("_") and name in self.__dict__:
            raise InvalidSceneError(
                f"{name}: a {type(self).__name__} cannot be changed in place; create a new one and pass it to "
                "update_colors(...) (or assign it to the material)"
            )
        object.__setattr__(self, name, value)


class Colors(_Immutable):
    """Base of colour sources. ``kind`` names the class for backends and scene files."""

    kind = "base"
    color_space: str

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:  # pragma: no cover
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}(color_space={self.color_space!r})"


class UniformColors(Colors):
    """One colour for the whole object: RGB or RGBA in [0, 1] (RGB sRGB-encoded unless ``color_space="linear"``)."""

    kind = "uniform"

    def __init__(self, uniform_color: Any, color_space: str = "srgb"):
        c = raw_array("uniform_color", uniform_color)
        if c.dtype.kind in "iu" and c.size and np.any(c > 1):
            raise InvalidSceneError(
                f"uniform_color: expected floats in [0, 1], got integers {c.tolist()} (divide 8-bit values by 255)"
            )
        c = as_array("uniform_color", uniform_color, ndim=1, min_value=0.0, max_value=1.0)
        if c.shape[0] not in (3, 4):
            raise InvalidSceneError(f"uniform_color: expected 3 (RGB) or 4 (RGBA) values, got {c.shape[0]}")
        self.color = c
        self.color_space = _color_space(color_space)

    @property
    def has_alpha(self) -> bool:
        return self.color.shape[0] == 4 and self.color[3] < 1.0

    @property
    def linear_rgba(self) -> AnyArray:
        """(4,) float64 linear RGBA."""
        rgba = np.ones(4)
        rgba[: self.color.shape[0]] = self.color
        return _to_linear(rgba, self.color_space)

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        return {"kind": self.kind, "color": self.color.tolist(), "color_space": self.color_space}


class VertexColors(Colors):
    """One colour per vertex (or per point): (N, 3) or (N, 4) floats in [0, 1], or uint8 (divided by 255)."""

    kind = "vertex"

    def __init__(self, vertex_colors: Any, color_space: str = "srgb"):
        raw = raw_array("vertex_colors", vertex_colors)
        if raw.dtype == np.uint8:
            raw = raw.astype(np.float32) / 255.0
        elif raw.dtype.kind in "iu":
            raise InvalidSceneError(f"vertex_colors: integer colours must be uint8 (0-255), got dtype {raw.dtype}")
        c = as_array("vertex_colors", raw, dtype=np.float32, ndim=2, min_value=0.0, max_value=1.0)
        if c.shape[1] not in (3, 4):
            raise InvalidSceneError(f"vertex_colors: expected shape (N, 3) or (N, 4), got {_describe(c)}")
        self.vertex_colors = c
        self.color_space = _color_space(color_space)
        self._linear: AnyArray | None = None

    def __len__(self) -> int:
        return self.vertex_colors.shape[0]

    @property
    def has_alpha(self) -> bool:
        return self.vertex_colors.shape[1] == 4 and bool(np.any(self.vertex_colors[:, 3] < 1.0))

    @property
    def linear_rgba(self) -> AnyArray:
        """(N, 4) float32 linear RGBA (cached, read-only)."""
        if self._linear is None:
            n = self.vertex_colors.shape[0]
            rgba = np.ones((n, 4), dtype=np.float32)
            rgba[:, : self.vertex_colors.shape[1]] = self.vertex_colors
            self._linear = frozen(_to_linear(rgba, self.color_space).astype(np.float32))
        return self._linear

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        arrays[prefix + "vertex_colors"] = self.vertex_colors
        return {"kind": self.kind, "vertex_colors": prefix + "vertex_colors", "color_space": self.color_space}


class UVMap(_Immutable):
    """Base of UV maps. UV (0, 0) is the bottom-left of the texture."""

    kind = "base"
    data: AnyArray


class VertexUV(UVMap):
    """One UV per vertex: (N, 2)."""

    kind = "vertex_uv"

    def __init__(self, data: Any):
        self.data = as_array("uv_map", data, dtype=np.float32, ndim=2)
        if self.data.shape[1] != 2:
            raise InvalidSceneError(f"uv_map: expected shape (N, 2) for VertexUV, got {_describe(self.data)}")

    def __repr__(self) -> str:
        return f"VertexUV({self.data.shape[0]} vertices)"


class FacesUV(UVMap):
    """One UV per face corner: (M, k, 2) for M faces of k corners (per original polygon). For polygons of
    mixed sizes: (M, k_max, 2) where a face of k corners uses its first k rows, or a list of M per-face
    (k, 2) arrays (padded to that shape)."""

    kind = "faces_uv"

    def __init__(self, data: Any):
        if isinstance(data, (list, tuple)) and data and len({np.shape(f) for f in data}) > 1:
            faces = [as_array(f"uv_map[{i}]", f, dtype=np.float32, ndim=2) for i, f in enumerate(data)]
            k_max = max(f.shape[0] for f in faces)
            padded = np.zeros((len(faces), k_max, 2), dtype=np.float32)
            for i, f in enumerate(faces):
                if f.shape[1] != 2 or f.shape[0] < 3:
                    raise InvalidSceneError(f"uv_map[{i}]: expected shape (k>=3, 2), got {_describe(f)}")
                padded[i, : f.shape[0]] = f
            data = padded
        self.data = as_array("uv_map", data, dtype=np.float32, ndim=3)
        if self.data.shape[2] != 2 or self.data.shape[1] < 3:
            raise InvalidSceneError(f"uv_map: expected shape (M, k>=3, 2) for FacesUV, got {_describe(self.data)}")

    def __repr__(self) -> str:
        return f"FacesUV({self.data.shape[0]} faces)"


def _check_uv(uv_map: Any) -> UVMap:
    if not isinstance(uv_map, UVMap):
        raise InvalidSceneError(f"uv_map: expected a VertexUV or FacesUV, got {_describe(uv_map)}")
    return uv_map


def uv_to_dict(uv: UVMap | None, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any] | None:
    if uv is None:
        return None
    arrays[prefix + "uv"] = uv.data
    return {"kind": uv.kind, "data": prefix + "uv"}


class TextureColors(Colors):
    """An in-memory texture: (H, W[, 3|4]) uint8 (sRGB bytes by default) or float in [0, 1]; row 0 = top."""

    kind = "texture"

    def __init__(self, texture: Any, uv_map: UVMap, color_space: str = "srgb", interpolation: str = "linear"):
        self.texture = _check_image("texture", texture)
        self.uv_map = _check_uv(uv_map)
        self.color_space = _color_space(color_space)
        self.interpolation = as_choice("interpolation", interpolation, INTERPOLATIONS)

    @property
    def has_alpha(self) -> bool:
        t = self.texture
        return t.shape[2] == 4 and bool(np.any(t[..., 3] < (255 if t.dtype == np.uint8 else 1.0)))

    def image(self) -> AnyArray:
        """The texture as stored (uint8 or float32), row 0 = top."""
        return self.texture

    def linear_rgba_image(self) -> AnyArray:
        """(H, W, 4) float32 linear RGBA, row 0 = top."""
        return _linear_rgba_image(self.image(), self.color_space)

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        arrays[prefix + "texture"] = self.texture
        return {
            "kind": self.kind,
            "texture": prefix + "texture",
            "uv_map": uv_to_dict(self.uv_map, arrays, prefix),
            "color_space": self.color_space,
            "interpolation": self.interpolation,
        }


def _linear_rgba_image(img: AnyArray, color_space: str) -> AnyArray:
    rgba = _to_rgba(img)
    if rgba.dtype == np.uint8:
        out = np.empty(rgba.shape, dtype=np.float32)
        if color_space == "srgb":
            out[..., :3] = srgb8_to_linear(rgba[..., :3])
        else:
            out[..., :3] = rgba[..., :3].astype(np.float32) / 255.0
        out[..., 3] = rgba[..., 3].astype(np.float32) / 255.0
        return out
    return _to_linear(rgba.astype(np.float32), color_space).astype(np.float32)


class FileTextureColors(Colors):
    """A texture read from a file by the backend that needs it (the IR never loads the pixels)."""

    kind = "file_texture"

    def __init__(
        self,
        texture_path: str | os.PathLike[str],
        uv_map: UVMap,
        color_space: str = "srgb",
        interpolation: str = "linear",
    ):
        if not isinstance(texture_path, (str, os.PathLike)):
            raise InvalidSceneError(f"texture_path: expected a file path, got {_describe(texture_path)}")
        p = Path(texture_path).expanduser()
        if not p.is_file():
            raise InvalidSceneError(f"texture_path: no such file {str(p)!r}")
        self.texture_path = str(p.resolve())
        self.uv_map = _check_uv(uv_map)
        self.color_space = _color_space(color_space)
        self.interpolation = as_choice("interpolation", interpolation, INTERPOLATIONS)
        self._cache: AnyArray | None = None

    #: above this many pixels, ``has_alpha`` trusts the file header instead of decoding the pixels
    EXACT_ALPHA_LIMIT = 4096 * 4096

    @property
    def has_alpha(self) -> bool:
        """Whether the texture has an alpha channel with a value below 1. Decided from the file header
        when it has no alpha channel, or when the image is huge (conservatively True), so the core never
        decodes a 30000x30000 texture just to analyse the scene; otherwise exact."""
        if self._cache is None:
            header = _image_header(self.texture_path)
            if header is not None:
                pixels, alpha = header
                if not alpha:
                    return False
                if pixels > self.EXACT_ALPHA_LIMIT:
                    return True
        img = self.image()
        return img.shape[2] == 4 and bool(np.any(img[..., 3] < (255 if img.dtype == np.uint8 else 1.0)))

    def image(self) -> AnyArray:
        """Load (once) and return the pixels as stored in the file (uint8 or float32), row 0 = top."""
        if self._cache is None:
            self._cache = frozen(load_image(self.texture_path))
        return self._cache

    def linear_rgba_image(self) -> AnyArray:
        return _linear_rgba_image(self.image(), self.color_space)

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "texture_path": self.texture_path,
            "uv_map": uv_to_dict(self.uv_map, arrays, prefix),
            "color_space": self.color_space,
            "interpolation": self.interpolation,
        }


class TextureMap(_Immutable):
    """A non-colour data texture (roughness or metallic): an image (H, W[, C]) or a file path.

    Values are used as stored (never colour-managed); ``channel`` picks the channel of a multi-channel image.
    UVs come from the mesh (``add_mesh(..., uv_map=...)`` or its texture colours).
    """

    kind = "texture_map"

    def __init__(self, image_or_path: Any, channel: int = 0):
        path: str | None = None
        self._image: AnyArray | None = None
        if isinstance(image_or_path, (str, os.PathLike)):
            p = Path(image_or_path).expanduser()
            if not p.is_file():
                raise InvalidSceneError(f"image_or_path: no such file {str(p)!r}")
            path = str(p.resolve())
        else:
            self._image = _check_image("image_or_path", image_or_path)
        self.path = path
        if isinstance(channel, bool) or not isinstance(channel, (int, np.integer)) or channel < 0 or channel > 3:
            raise InvalidSceneError(f"channel: expected an integer channel index 0-3, got {channel!r}")
        self.channel = int(channel)
        if self._image is not None and self.channel >= self._image.shape[2]:
            raise InvalidSceneError(f"channel: image has {self._image.shape[2]} channel(s), got channel {channel}")

    def image(self) -> AnyArray:
        if self._image is None:
            self._image = frozen(load_image(str(self.path)))
        return self._image

    def values(self) -> AnyArray:
        """(H, W) float32 data values in [0, 1], row 0 = top."""
        img = self.image()
        ch = img[..., min(self.channel, img.shape[2] - 1)]
        return (ch.astype(np.float32) / 255.0) if ch.dtype == np.uint8 else ch.astype(np.float32)

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": self.kind, "channel": self.channel, "path": self.path}
        if self.path is None:
            arrays[prefix + "image"] = self.image()
            d["image"] = prefix + "image"
        return d

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.path or 'in-memory ' + str(self.image().shape)})"


class NormalMap(TextureMap):
    """A tangent-space normal map (OpenGL convention: +Y up / green = up), RGB in [0, 1] -> n = 2c - 1."""

    kind = "normal_map"

    def __init__(self, image_or_path: Any, strength: float = 1.0):
        super().__init__(image_or_path, channel=0)
        self.strength = as_float("strength", strength, min_value=0.0)

    def normals(self) -> AnyArray:
        """(H, W, 3) float32 tangent-space normals in [-1, 1], row 0 = top."""
        img = self.image()
        rgb = _to_rgba(img)[..., :3]
        v = rgb.astype(np.float32) / 255.0 if rgb.dtype == np.uint8 else rgb.astype(np.float32)
        return v * 2.0 - 1.0

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        d = super().to_dict(arrays, prefix)
        d["strength"] = self.strength
        return d
