"""The result of a render: numpy arrays plus metadata, and how to save and show it."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.io.output import atomic_write, check_file_name
from blendify_core.io.paths import as_path
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.ir.validate import strict_api
from blendify_core.pipeline.meta import RenderMeta
from blendify_core.typing import AnyArray, BoolArray, Float32Array, Int32Array, UInt8Array

__all__ = ["RenderResult"]


def _jsonable(value: object) -> object:
    """``value`` with numpy values as Python ones, non-finite floats as strings and unknown objects as
    their repr: something ``json.dumps`` writes."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return str(value)
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


@strict_api
@dataclass
class RenderResult:
    """Arrays of one render. Outputs that were not requested are None.

    - ``rgba``: (H, W, 4) float32, scene-linear, premultiplied alpha
    - ``depth``: (H, W) float32 planar z along the camera axis, +inf where nothing was hit
    - ``normal``: (H, W, 3) float32 world-space unit normals, 0 where nothing was hit
    - ``albedo``: (H, W, 3) float32 linear base colour of the visible material, 0 where nothing was hit
    - ``instance``: (H, W) int32 index into ``instance_tags``, -1 for background
    - ``rgb_var``: (H, W, 3) float32 or None: the variance of each colour pixel-channel *as an estimate
      of the expected image*, measured from ``meta["passes"]`` independent passes (``bf.crosscheck``,
      ``blendify_core.evaluate.noise.render_passes`` and ``bf.render(target_error=...)`` keep it; the
      noise-aware verdict of ``bf.compare`` uses it); None when not measured (a single pass, a raster
      backend)
    - ``meta``: backend, engine version, settings, effects, approximations, timings, samples, ...: the
      keys documented in :class:`~blendify_core.pipeline.meta.RenderMeta` (a plain dict at run time)
    """

    rgba: Float32Array | None = None
    depth: Float32Array | None = None
    normal: Float32Array | None = None
    albedo: Float32Array | None = None
    instance: Int32Array | None = None
    instance_tags: list[str] = field(default_factory=list)
    meta: RenderMeta = field(default_factory=lambda: RenderMeta())
    rgb_var: Float32Array | None = field(default=None, repr=False)

    # -- derived ---------------------------------------------------------------------------------
    @property
    def resolution(self) -> tuple[int, int] | None:
        a: AnyArray | None
        for a in (self.rgba, self.depth, self.normal, self.albedo, self.instance):
            if a is not None:
                return (a.shape[1], a.shape[0])
        return None

    @property
    def mask(self) -> BoolArray | None:
        """(H, W) bool: where a surface was hit (from depth or instance when present, else alpha > 0)."""
        if self.depth is not None:
            return np.isfinite(self.depth)
        if self.instance is not None:
            return self.instance >= 0
        if self.rgba is not None:
            return self.rgba[..., 3] > 0
        return None

    @property
    def rgb(self) -> Float32Array | None:
        """(H, W, 3) premultiplied linear colour (over black)."""
        return None if self.rgba is None else self.rgba[..., :3]

    def straight_rgba(self) -> Float32Array:
        """(H, W, 4) float32 linear colour with straight (un-premultiplied) alpha."""
        if self.rgba is None:
            raise InvalidSceneError("outputs: this result has no 'rgb' output")
        a = self.rgba[..., 3:4]
        rgb: Float32Array = np.divide(self.rgba[..., :3], a, out=np.zeros_like(self.rgba[..., :3]), where=a > 0)
        out: Float32Array = np.concatenate([rgb, a], axis=-1).astype(np.float32)
        return out

    def to_srgb8(self) -> UInt8Array:
        """(H, W, 4) uint8: sRGB-encoded ("Standard" view transform) colour with straight alpha."""
        # a NaN/inf pixel (an engine's firefly) must not turn into an undefined byte or a cast warning
        s = np.nan_to_num(self.straight_rgba(), nan=0.0, posinf=1.0, neginf=0.0)
        out = np.empty(s.shape, dtype=np.uint8)
        out[..., :3] = np.round(linear_to_srgb(s[..., :3]) * 255.0)
        out[..., 3] = np.round(np.clip(s[..., 3], 0, 1) * 255.0)
        return out

    def provenance(self) -> dict[str, object]:
        keys = ("backend", "engine_version", "scene_fingerprint", "settings", "samples", "variant")
        meta: Mapping[str, object] = self.meta
        return {k: meta[k] for k in keys if k in meta}

    # -- saving ----------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str], output: str = "rgb") -> Path:
        """Write ``.png`` (8-bit sRGB, straight alpha), ``.exr`` (linear float, needs ``openexr``) or
        ``.npz`` (every output, lossless), atomically, with provenance in PNG text / EXR header / npz.

        The file gets the mode ``open(path, "w")`` would give it (``0o666 & ~umask``; an overwritten file
        keeps its permission bits). A path that cannot be written (missing folder, existing folder,
        read-only folder, name too long, NUL byte) raises :class:`~blendify_core.errors.OutputError`, an
        ``OSError`` naming the path, and leaves nothing behind."""
        p = as_path("path", path)
        suffix = p.suffix.lower()
        check_file_name("path", p)
        if suffix not in (".png", ".exr", ".npz"):
            raise InvalidSceneError(f"path: expected a .png, .exr or .npz file name, got {str(path)!r}")
        prov = json.dumps(_jsonable(self.provenance()))
        if suffix == ".npz":
            arrays = {
                k: getattr(self, k)
                for k in ("rgba", "depth", "normal", "albedo", "instance")
                if getattr(self, k) is not None
            }
            arrays["instance_tags"] = np.array(self.instance_tags, dtype=str)
            arrays["meta"] = np.array(json.dumps(_jsonable(self.meta)))

            def write_npz(tmp: str) -> None:
                with open(tmp, "wb") as f:
                    np.savez_compressed(f, **arrays)

            return atomic_write(p, write_npz)
        image = self._output_image(output, suffix)
        if suffix == ".png":
            from PIL import Image, PngImagePlugin

            info = PngImagePlugin.PngInfo()
            info.add_text("blendify", prov)

            def write_png(tmp: str) -> None:
                Image.fromarray(image).save(tmp, format="PNG", pnginfo=info)

            return atomic_write(p, write_png)
        try:
            import OpenEXR
        except ImportError:
            raise InvalidSceneError("path: writing .exr needs the 'openexr' package (pip install openexr)") from None

        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "blendify": prov}
        channels = {
            "RGBA" if image.shape[-1] == 4 else ("RGB" if image.ndim == 3 else "Y"): np.ascontiguousarray(
                image.astype(np.float32)
            )
        }

        def write_exr(tmp: str) -> None:
            with OpenEXR.File(header, channels) as f:
                f.write(tmp)

        return atomic_write(p, write_exr)

    def _output_image(self, output: str, suffix: str) -> AnyArray:
        name = "rgba" if output in ("rgb", "rgba") else output
        data: AnyArray | None = (
            getattr(self, name, None) if name in ("rgba", "depth", "normal", "albedo", "instance") else None
        )
        if data is None:
            raise InvalidSceneError(
                f"output: this result has no {output!r} output (it has "
                f"{[k for k in ('rgba', 'depth', 'normal', 'albedo', 'instance') if getattr(self, k) is not None]})"
            )
        if suffix == ".exr":
            return data.astype(np.float32) if name != "instance" else data.astype(np.float32)
        if name == "rgba":
            return self.to_srgb8()
        encoded: UInt8Array
        if name == "albedo":
            encoded = np.round(linear_to_srgb(data) * 255).astype(np.uint8)
            return encoded
        if name == "normal":
            encoded = np.round(np.clip(data * 0.5 + 0.5, 0, 1) * 255).astype(np.uint8)
            return encoded
        if name == "depth":
            return depth_to_image(data)
        return instance_to_image(data)

    def _repr_png_(self) -> bytes | None:
        if self.rgba is None:
            return None
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.to_srgb8()).save(buf, format="PNG")
        return buf.getvalue()

    def __repr__(self) -> str:
        have = [k for k in ("rgba", "depth", "normal", "albedo", "instance") if getattr(self, k) is not None]
        return f"RenderResult({self.resolution}, outputs={have}, backend={self.meta.get('backend')!r})"


def depth_to_image(depth: Float32Array) -> UInt8Array:
    """8-bit visualisation of a depth map: near = bright, background = black."""
    finite = np.isfinite(depth)
    out = np.zeros(depth.shape, dtype=np.uint8)
    if finite.any():
        lo, hi = float(depth[finite].min()), float(depth[finite].max())
        span = max(hi - lo, 1e-12)
        out[finite] = np.round(255 - 215 * (depth[finite] - lo) / span).astype(np.uint8)
    return out


def instance_to_image(instance: Int32Array) -> UInt8Array:
    """RGB visualisation of an instance map (a fixed colour per id, black background)."""
    rng = np.random.default_rng(12345)
    n = int(instance.max()) + 1 if instance.size else 0
    palette = rng.integers(60, 256, size=(max(n, 1), 3), dtype=np.uint8)
    out = np.zeros(instance.shape + (3,), dtype=np.uint8)
    valid = instance >= 0
    out[valid] = palette[instance[valid]]
    return out
