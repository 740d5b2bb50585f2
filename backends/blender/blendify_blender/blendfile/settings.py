"""A .blend scene's render settings -> blendify render settings (``attach_blend(..., render_settings=True)``).

:func:`file_render_settings` reads the file scene's Cycles settings and returns

- ``portable``: keyword arguments of ``bf.render`` (:class:`blendify_core.pipeline.settings.RenderSettings`
  fields: samples, seed, max_bounces, pixel_filter, clamp_direct, clamp_indirect, adaptive, denoise,
  transparent_background), for every backend;
- ``cycles``: the Cycles scene properties those fields cannot hold (per-type bounce limits, the pixel
  filter's type and width, filter glossy, caustics, light threshold, adaptive threshold, film exposure),
  for the Cycles backend's ``cycles_settings`` option;
- ``notes``: what neither carries (e.g. an animated seed).

A file written by :func:`blendify_blender.export.export_blend` stores the blendify settings it was written
with (the scene property ``blendify_render_settings``); those are read back as they were given.
"""

from __future__ import annotations

import json
from typing import Any

from blendify_core.pipeline.settings import resolve_settings

__all__ = ["CYCLES_KEYS", "PORTABLE_KEYS", "SETTINGS_PROPERTY", "describe_unimported", "file_render_settings"]

#: scene custom property where export_blend stores the blendify render settings of the file (JSON)
SETTINGS_PROPERTY = "blendify_render_settings"

#: the RenderSettings fields a file's settings are imported into
PORTABLE_KEYS = (
    "samples",
    "seed",
    "max_bounces",
    "pixel_filter",
    "clamp_direct",
    "clamp_indirect",
    "adaptive",
    "denoise",
    "transparent_background",
)

#: Cycles scene properties (``scene.cycles.<name>``) the Cycles backend's ``cycles_settings`` option sets
CYCLES_KEYS = (
    "diffuse_bounces",
    "glossy_bounces",
    "transmission_bounces",
    "volume_bounces",
    "transparent_max_bounces",
    "pixel_filter_type",
    "filter_width",
    "blur_glossy",
    "caustics_reflective",
    "caustics_refractive",
    "light_sampling_threshold",
    "use_light_tree",
    "adaptive_threshold",
    "adaptive_min_samples",
    "film_exposure",
)


#: settings that change only the noise of a render, not the picture it converges to
_NOISE_ONLY = ("samples", "seed", "adaptive")
_NOISE_ONLY_CYCLES = ("adaptive_threshold", "adaptive_min_samples")
#: per-type bounce limits Cycles caps by max_bounces (transparent bounces are counted apart)
_CAPPED_BOUNCES = ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces")


def _stored_settings(sc: Any) -> dict[str, Any] | None:
    """The blendify settings export_blend stored in the scene, or None."""
    raw = sc.get(SETTINGS_PROPERTY)
    if not isinstance(raw, str):
        return None
    try:
        data = json.loads(raw)
    except ValueError:
        return None
    return {k: data[k] for k in PORTABLE_KEYS if k in data} if isinstance(data, dict) else None


def file_render_settings(sc: Any) -> tuple[dict[str, Any], dict[str, Any], list[str]]:
    """(portable bf.render keywords, Cycles-only properties, notes) of the bpy scene ``sc`` (see module)."""
    stored = _stored_settings(sc)
    if stored is not None:
        return stored, {}, []
    cy, r = sc.cycles, sc.render
    notes: list[str] = []
    portable: dict[str, Any] = {
        "samples": int(cy.samples),
        "seed": int(cy.seed),
        "max_bounces": int(cy.max_bounces),
        "clamp_direct": float(cy.sample_clamp_direct),
        "clamp_indirect": float(cy.sample_clamp_indirect),
        "adaptive": bool(cy.use_adaptive_sampling),
        "denoise": bool(cy.use_denoising),
        "transparent_background": bool(r.film_transparent),
    }
    ftype, width = str(cy.pixel_filter_type), float(cy.filter_width)
    if ftype == "BOX":
        portable["pixel_filter"] = "box"
    elif ftype == "GAUSSIAN" and abs(width - 1.5) < 1e-6:
        portable["pixel_filter"] = "gaussian"
    else:  # the closest portable filter; Cycles gets the exact one
        portable["pixel_filter"] = "gaussian"
        notes.append(
            f"pixel filter {ftype} {width:g} px: 'gaussian' (1.5 px) in result.render_settings, the exact filter "
            "in result.cycles_settings"
        )
    if cy.use_animated_seed:
        notes.append("animated seed read as the fixed seed")
    if r.engine != "CYCLES":
        notes.append(f"the file renders with {r.engine}, read as Cycles settings")
    cycles = {k: _plain(getattr(cy, k)) for k in CYCLES_KEYS if hasattr(cy, k)}
    return portable, cycles, notes


def _plain(v: Any) -> Any:
    if isinstance(v, bool):
        return v
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        return round(float(v), 6)
    return str(v)


def _cycles_defaults() -> dict[str, Any]:
    """The Cycles properties blendify sets itself (translate.apply_engine_settings) for a default render."""
    mb = resolve_settings().max_bounces
    return {
        "pixel_filter_type": "BOX",
        "filter_width": 1.0,
        "blur_glossy": 0.0,
        "caustics_reflective": True,
        "caustics_refractive": True,
        "use_light_tree": True,
        "adaptive_threshold": 0.01,
        "adaptive_min_samples": 0,
        "film_exposure": 1.0,
        "light_sampling_threshold": 0.01,
        "diffuse_bounces": mb,
        "glossy_bounces": mb,
        "transmission_bounces": mb,
        "volume_bounces": mb,
        "transparent_max_bounces": max(mb, 8),
    }


def describe_unimported(portable: dict[str, Any], cycles: dict[str, Any]) -> str | None:
    """The settings of a file that change the expected picture and differ from what ``bf.render`` uses by
    default, as one note line for ``attach_blend(render_settings=False)`` (None when there is none; the
    sample count, seed and adaptive sampling change only the noise and are not listed)."""
    defaults = resolve_settings()
    diffs = [
        f"{k}={v!r} (bf.render: {getattr(defaults, k)!r})"
        for k, v in portable.items()
        if v != getattr(defaults, k) and k not in _NOISE_ONLY
    ]
    cdef = _cycles_defaults()
    mb_file, mb_default = int(portable.get("max_bounces", defaults.max_bounces)), defaults.max_bounces
    for k, v in cycles.items():
        d = cdef.get(k)
        if k in _CAPPED_BOUNCES and isinstance(v, int) and isinstance(d, int):
            v, d = min(v, mb_file), min(d, mb_default)  # what Cycles uses: at most max_bounces
        if (
            d is None
            or k in _NOISE_ONLY_CYCLES
            or v == d
            or (isinstance(v, float) and isinstance(d, float) and abs(v - d) < 1e-5)
        ):
            continue
        diffs.append(f"cycles.{k}={v!r} (blendify: {d!r})")
    if not diffs:
        return None
    return (
        "render settings not imported (pass render_settings=True to get them in result.render_settings and "
        "result.cycles_settings): " + ", ".join(diffs)
    )
