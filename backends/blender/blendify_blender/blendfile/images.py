"""Images referenced by a .blend (textures, environment maps) -> what the IR takes: a file path or pixels.

External files are referenced by absolute path. PACKED images are written to ``texture_dir`` if given,
else to the cache directory ``$XDG_CACHE_HOME/blendify-core/blend-textures`` (``~/.cache/...``), named by
the SHA-256 of their bytes, and never deleted by the library. Generated images (and images whose file is
missing but whose pixels are loaded) give their pixels, read from Blender.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes
from blendify_core.errors import InvalidSceneError

__all__ = ["ImageReader", "ImageSource", "default_texture_cache_dir"]

_LINEAR_SPACES = ("linear", "non-color", "raw", "scene_linear", "xyz", "acescg", "aces2065")
_IMAGE_EXT = {
    "PNG": ".png",
    "JPEG": ".jpg",
    "OPEN_EXR": ".exr",
    "OPEN_EXR_MULTILAYER": ".exr",
    "TARGA": ".tga",
    "TARGA_RAW": ".tga",
    "BMP": ".bmp",
    "TIFF": ".tif",
    "HDR": ".hdr",
    "WEBP": ".webp",
}

#: ('file', absolute path, colour space) or ('pixels', (H, W, C) float array with row 0 at the top, colour space)
ImageSource = tuple[str, Any, str]


def default_texture_cache_dir() -> Path:
    """Where packed textures are unpacked when ``texture_dir`` is not given."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "blendify-core" / "blend-textures"


class ImageReader:
    """Reads the images of one .blend (each once); what it cannot read goes to ``notes``."""

    def __init__(self, bpy: Any, blend_path: Path, texture_dir: str | os.PathLike[str] | None, notes: Notes) -> None:
        self.bpy = bpy
        self.blend_path = blend_path
        self.texture_dir_arg = texture_dir
        #: where packed images were unpacked (None until one was)
        self.texture_dir: Path | None = None
        self.notes = notes
        self._cache: dict[int, ImageSource | None] = {}

    def source(self, image: Any, where: str) -> ImageSource | None:
        """('file', path, color_space) or ('pixels', array row 0 = top, color_space), or None (noted)."""
        key = image.as_pointer()
        if key not in self._cache:
            self._cache[key] = self._read(image, where)
        return self._cache[key]

    def _read(self, image: Any, where: str) -> ImageSource | None:
        cs = self._color_space(image, where)
        if image.source == "TILED":
            self.notes.add(f"{where}: UDIM image {image.name!r} not supported")
            return None
        if image.source in ("MOVIE", "SEQUENCE", "VIEWER"):
            self.notes.add(f"{where}: {image.source.lower()} image {image.name!r} not supported")
            return None
        if image.packed_file is not None:
            return ("file", str(self._unpack(image)), cs)
        fp = image.filepath_raw or image.filepath
        resolved = self._external_file(image, fp)
        result: ImageSource | None = None
        if resolved is not None:
            result = ("file", resolved, cs)
        elif image.has_data or image.source == "GENERATED":
            result = self._pixels(image, cs, where)
        if result is None:
            self.notes.add(f"{where}: image {image.name!r} file {fp!r} not found")
        return result

    def _color_space(self, image: Any, where: str) -> str:
        """'srgb' or 'linear' from the image's colour-space name (unknown spaces: sRGB, noted)."""
        cs_name = image.colorspace_settings.name
        low = cs_name.lower()
        if low in ("srgb", "srgb 2.2", "srgb texture") or low.startswith("srgb"):
            return "srgb"
        if any(low.startswith(x) for x in _LINEAR_SPACES):
            return "linear"
        self.notes.add(f"{where}: image {image.name!r} colour space {cs_name!r} read as sRGB (approximation)")
        return "srgb"

    def _unpack_dir(self) -> Path:
        if self.texture_dir is None:
            d = Path(self.texture_dir_arg).expanduser() if self.texture_dir_arg is not None else None
            d = d or default_texture_cache_dir()
            try:
                d.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise InvalidSceneError(f"texture_dir: cannot create {str(d)!r} ({exc})") from None
            self.texture_dir = d.resolve()
        return self.texture_dir

    def _unpack(self, image: Any) -> Path:
        """Write a packed image's bytes to the unpack folder under their hash (once); returns the file."""
        data = bytes(image.packed_file.data)
        ext = Path(image.filepath_raw or image.filepath or "").suffix.lower() or _IMAGE_EXT.get(
            image.file_format, ".png"
        )
        digest = hashlib.sha256(data).hexdigest()[:24]
        target = self._unpack_dir() / f"{digest}{ext}"
        if not target.is_file():
            tmp = target.with_name(target.name + f".{os.getpid()}.tmp")
            tmp.write_bytes(data)
            os.replace(tmp, target)
        return target

    def _external_file(self, image: Any, fp: str) -> str | None:
        """The absolute path of an image's existing file ('//' paths relative to the .blend), or None."""
        if not fp or image.source != "FILE":
            return None
        cand = self.bpy.path.abspath(fp, library=image.library)
        if fp.startswith("//"):
            alt = self.blend_path.parent / fp[2:]
            if alt.is_file():
                cand = str(alt)
        return os.path.abspath(cand) if os.path.isfile(cand) else None

    def _pixels(self, image: Any, cs: str, where: str) -> ImageSource | None:
        """The pixels Blender holds (clipped to [0, 1]; an opaque alpha channel dropped), or None if empty."""
        w, h = image.size
        if not (w and h):
            return None
        ch = image.channels
        px = np.empty(w * h * ch, dtype=np.float32)
        image.pixels.foreach_get(px)
        arr = px.reshape(h, w, ch)[::-1]
        if ch == 4 and np.all(arr[..., 3] >= 1.0):
            arr = arr[..., :3]
        # float buffers are scene-linear, byte buffers keep their colour space's encoding
        cs_px = "linear" if image.is_float else cs
        if float(arr.max(initial=0.0)) > 1.0:
            self.notes.add(f"{where}: image {image.name!r} has values > 1, clipped to [0, 1]")
        arr = np.ascontiguousarray(np.clip(arr, 0.0, 1.0))
        return ("pixels", arr, cs_px)
