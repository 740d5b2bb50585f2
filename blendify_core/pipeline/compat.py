"""blendify 2.1's render keywords: mapped onto ``bf.render``'s (with a DeprecationWarning) or refused with
what to write instead.

blendify 2.1 rendered with ``scene.render(filepath=None, use_gpu=True, samples=128, save_depth=False,
save_albedo=False, verbose=False, use_denoiser=False, aa_filter_width=1.5)`` and
``scene.preview(filepath=None, save_depth=False, save_albedo=False, verbose=False, fast=False)``.
"""

from __future__ import annotations

import difflib
import warnings
from collections.abc import Iterable, Sequence
from typing import Any

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.validate import as_bool, as_float

__all__ = ["LEGACY_KEYWORDS", "map_legacy_keywords", "suggest"]

#: blendify 2.1 keyword -> what bf.render takes instead (the README's migration table lists the same)
LEGACY_KEYWORDS = {
    "use_gpu": "device='gpu' (or 'cpu')",
    "use_denoiser": "denoise=",
    "aa_filter_width": "pixel_filter='blackman_harris', pixel_filter_width=",
    "save_depth": "outputs=('rgb', 'depth')",
    "save_albedo": "outputs=('rgb', 'albedo')",
    # verbose= is the cycles backend's own option (Blender's log to stderr); elsewhere this hint
    "verbose": "logging.getLogger('blendify_core').setLevel(logging.DEBUG) (only backend='cycles' takes verbose=)",
    "filepath": "bf.render(...).save(path)",
    "fast": "quality='preview'",
}


def _deprecated(old: str, new: str) -> None:
    warnings.warn(
        f"{old}: blendify 2.1's keyword; mapped to {new} (write that instead)", DeprecationWarning, stacklevel=4
    )


def map_legacy_keywords(
    outputs: str | Sequence[str], kwargs: dict[str, Any]
) -> tuple[str | Sequence[str], dict[str, Any]]:
    """``(outputs, kwargs)`` with blendify 2.1's keywords replaced by their blendify-core spelling.

    ``filepath`` and ``fast`` have no keyword equivalent and raise InvalidSceneError saying what to write."""
    if not any(k in LEGACY_KEYWORDS and k != "verbose" for k in kwargs):
        return outputs, kwargs
    kw = dict(kwargs)
    out = [outputs] if isinstance(outputs, str) else list(outputs)
    if "filepath" in kw:
        raise InvalidSceneError(
            "filepath: bf.render returns a RenderResult and writes no file; did you mean "
            f"bf.render(...).save({kw['filepath']!r})? (result.save('x.exr', 'depth') writes the depth)"
        )
    if "fast" in kw:
        raise InvalidSceneError(
            "fast: blendify 2.1's preview switch; did you mean quality='preview' (the fast raster backend)?"
        )
    if "use_gpu" in kw:
        device = "gpu" if as_bool("use_gpu", kw.pop("use_gpu")) else "cpu"
        if "device" not in kw:
            kw["device"] = device
        _deprecated("use_gpu", f"device={device!r}")
    if "use_denoiser" in kw:
        value = as_bool("use_denoiser", kw.pop("use_denoiser"))
        if "denoise" in kw:
            raise InvalidSceneError("use_denoiser: give denoise= only (use_denoiser is blendify 2.1's name for it)")
        kw["denoise"] = value
        _deprecated("use_denoiser", f"denoise={value}")
    if "aa_filter_width" in kw:
        width = as_float("aa_filter_width", kw.pop("aa_filter_width"), min_value=0.0, max_value=10.0)
        if "pixel_filter" in kw or "pixel_filter_width" in kw:
            raise InvalidSceneError(
                "aa_filter_width: give pixel_filter= / pixel_filter_width= only (aa_filter_width is blendify 2.1's)"
            )
        # blendify's 0 turned the filter off (one point sample per pixel): the narrowest filter Cycles allows
        kw["pixel_filter"], kw["pixel_filter_width"] = "blackman_harris", max(width, 0.01)
        _deprecated("aa_filter_width", f"pixel_filter='blackman_harris', pixel_filter_width={max(width, 0.01):g}")
    for key, output in (("save_depth", "depth"), ("save_albedo", "albedo")):
        if key in kw:
            if as_bool(key, kw.pop(key)):
                if "rgb" not in out and "rgba" not in out:
                    out.insert(0, "rgb")
                if output not in out:
                    out.append(output)
            _deprecated(key, f"outputs={tuple(out)!r}")
    return tuple(out), kw


def suggest(name: str, known: Iterable[str]) -> str:
    """'; did you mean X?' for a mistyped keyword (blendify 2.1's names included), or ''."""
    if name in LEGACY_KEYWORDS:
        return f"; did you mean {LEGACY_KEYWORDS[name]}?"
    close = difflib.get_close_matches(name, sorted(set(known) | set(LEGACY_KEYWORDS)), n=1, cutoff=0.6)
    if not close:
        return ""
    return f"; did you mean {LEGACY_KEYWORDS.get(close[0], close[0] + '=')}?"
