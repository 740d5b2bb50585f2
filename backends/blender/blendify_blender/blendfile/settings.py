"""A .blend scene's render settings -> blendify render settings (``attach_blend(..., render_settings=True)``).

:func:`file_render_settings` reads the file scene's Cycles settings and returns

- ``portable``: keyword arguments of ``bf.render`` (:class:`blendify_core.pipeline.settings.RenderSettings`
  fields: samples, seed, the bounce limits, pixel filter and width, clamps, filter glossy, adaptive,
  denoise, transparent background), for every backend;
- ``cycles``: the Cycles scene properties those fields cannot hold (volume bounces, caustics, light
  threshold and tree, adaptive threshold, film exposure), for the Cycles backend's ``cycles_settings``
  option;
- ``notes``: what neither carries (e.g. an animated seed).

A file written by :func:`blendify_blender.export.export_blend` stores the blendify settings it was written
with (the scene property ``blendify_render_settings``); those are read back as they were given.
"""

from __future__ import annotations

import json
from typing import Any

from blendify_core.pipeline.settings import resolve_settings

__all__ = [
    "CYCLES_KEYS",
    "PORTABLE_KEYS",
    "SETTINGS_PROPERTY",
    "UNIMPORTED",
    "apply_old_defaults",
    "cycles_changes",
    "describe_unimported",
    "file_render_settings",
    "file_version",
]

#: the start of the warning line naming the settings not imported (not an approximation of the IR parse: every
#: backend, Cycles included, renders with bf.render's settings)
UNIMPORTED = (
    "render settings not imported (pass render_settings=True to get them in result.render_settings and "
    "result.cycles_settings): "
)

#: scene custom property where export_blend stores the blendify render settings of the file (JSON)
SETTINGS_PROPERTY = "blendify_render_settings"

#: the RenderSettings fields a file's settings are imported into
PORTABLE_KEYS = (
    "samples",
    "seed",
    "max_bounces",
    "diffuse_bounces",
    "glossy_bounces",
    "transmission_bounces",
    "transparent_bounces",
    "pixel_filter",
    "pixel_filter_width",
    "clamp_direct",
    "clamp_indirect",
    "filter_glossy",
    "adaptive",
    "denoise",
    "transparent_background",
)

#: Cycles scene properties (``scene.cycles.<name>``) the RenderSettings cannot hold: the Cycles backend's
#: ``cycles_settings`` option sets them
CYCLES_KEYS = (
    "volume_bounces",
    "caustics_reflective",
    "caustics_refractive",
    "light_sampling_threshold",
    "use_light_tree",
    "adaptive_threshold",
    "adaptive_min_samples",
    "film_exposure",
)

#: Cycles' pixel filter types -> blendify's names
_FILTERS = {"BOX": "box", "GAUSSIAN": "gaussian", "BLACKMAN_HARRIS": "blackman_harris"}

#: settings that change only the noise of a render, not the picture it converges to
_NOISE_ONLY = ("samples", "seed", "adaptive")
_NOISE_ONLY_CYCLES = ("adaptive_threshold", "adaptive_min_samples", "use_light_tree")  # the light tree: unbiased
#: per-kind bounce limits Cycles caps by max_bounces (transparent bounces are counted apart)
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


#: Cycles' own versioning of scene settings whose default changed (its ``version_update`` runs when Blender
#: opens a file as the main file, not when a scene is appended): (last file version of the old default,
#: property, the old default set when the file did not set the property), in Cycles' order
_CYCLES_OLD_DEFAULTS = (
    ((2, 71, 0), "volume_bounces", 1),
    ((2, 76, 8), "samples", 10),
    ((2, 78, 2), "light_sampling_threshold", 0.0),
    ((2, 79, 0), "blur_glossy", 0.0),
    ((2, 79, 0), "sample_clamp_indirect", 0.0),
    ((3, 0, 25), "samples", 128),
    ((3, 0, 25), "use_adaptive_sampling", False),
    ((3, 0, 25), "use_denoising", False),
    ((3, 5, 3), "use_light_tree", False),
)


def file_version(bpy: Any, path: Any) -> tuple[int, int, int] | None:
    """The Blender version that saved ``path``, from the library bpy made for it while appending (None when
    bpy has none)."""
    import os

    want = os.path.realpath(str(path))
    for lib in bpy.data.libraries:
        if os.path.realpath(bpy.path.abspath(lib.filepath)) == want:
            return (int(lib.version[0]), int(lib.version[1]), int(lib.version[2]))
    return None


def apply_old_defaults(sc: Any, version: tuple[int, int, int] | None) -> None:
    """Give the appended scene ``sc`` of a file saved by Blender ``version`` the Cycles settings Blender
    gives it when it opens the file (:data:`_CYCLES_OLD_DEFAULTS`: e.g. no indirect clamp and no Filter Glossy
    before 2.79.1, where the current defaults are 10 and 1)."""
    if version is None:
        return
    cy = sc.cycles
    given = {name for _v, name, _d in _CYCLES_OLD_DEFAULTS if cy.is_property_set(name)}
    for last, name, value in _CYCLES_OLD_DEFAULTS:
        if version <= last and name not in given and hasattr(cy, name):
            setattr(cy, name, value)
            given.add(name)


def file_render_settings(sc: Any) -> tuple[dict[str, Any], dict[str, Any], list[str]]:
    """(portable bf.render keywords, Cycles-only properties, notes) of the bpy scene ``sc`` (see module; an
    old file's scene first goes through :func:`apply_old_defaults`)."""
    stored = _stored_settings(sc)
    if stored is not None:
        return stored, {}, []
    cy, r = sc.cycles, sc.render
    notes: list[str] = []
    ftype = str(cy.pixel_filter_type)
    portable: dict[str, Any] = {
        # a sample subset renders its length (blendify's own files render past Cycles' fixed first sample)
        "samples": int(cy.sample_subset_length) if cy.use_sample_subset else int(cy.samples),
        "seed": int(cy.seed),
        "max_bounces": int(cy.max_bounces),
        "diffuse_bounces": int(cy.diffuse_bounces),
        "glossy_bounces": int(cy.glossy_bounces),
        "transmission_bounces": int(cy.transmission_bounces),
        "transparent_bounces": int(cy.transparent_max_bounces),
        "pixel_filter": _FILTERS.get(ftype, "gaussian"),
        "pixel_filter_width": round(float(cy.filter_width), 6),
        "clamp_direct": float(cy.sample_clamp_direct),
        "clamp_indirect": float(cy.sample_clamp_indirect),
        "filter_glossy": round(float(cy.blur_glossy), 6),
        "adaptive": bool(cy.use_adaptive_sampling),
        "denoise": bool(cy.use_denoising),
        "transparent_background": bool(r.film_transparent),
    }
    if ftype not in _FILTERS:  # pragma: no cover - Cycles 5 has exactly these three
        notes.append(f"pixel filter {ftype} read as Gaussian")
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
    """The Cycles properties blendify sets itself (translate.apply_engine_settings) beside RenderSettings."""
    return {
        "caustics_reflective": True,
        "caustics_refractive": True,
        "use_light_tree": True,
        "adaptive_threshold": 0.01,
        "adaptive_min_samples": 0,
        "film_exposure": 1.0,
        "light_sampling_threshold": 0.01,
        "volume_bounces": resolve_settings().max_bounces,
    }


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, (int, float)) and isinstance(b, (int, float)) and abs(float(a) - float(b)) < 1e-5
    return bool(a == b)


def cycles_changes(cycles: dict[str, Any], max_bounces: int, default_max_bounces: int | None = None) -> list[str]:
    """The Cycles-only settings of ``cycles`` (:data:`CYCLES_KEYS`) that change the expected picture against
    what blendify sets (noise-only ones left out), as ``"name=value (blendify: default)"``; volume bounces
    are capped by ``max_bounces`` (``default_max_bounces`` for blendify's side; the same when None)."""
    mb_default = max_bounces if default_max_bounces is None else default_max_bounces
    out = []
    for k, v in cycles.items():
        d = _cycles_defaults().get(k)
        if k in _CAPPED_BOUNCES and isinstance(v, int) and isinstance(d, int):
            v, d = min(v, max_bounces), min(d, mb_default)
        if d is None or k in _NOISE_ONLY_CYCLES or _same(v, d):
            continue
        out.append(f"{k}={v!r} (blendify: {d!r})")
    return out


def describe_unimported(portable: dict[str, Any], cycles: dict[str, Any]) -> str | None:
    """The settings of a file that change the expected picture and differ from what ``bf.render`` uses by
    default, as one note line for ``attach_blend(render_settings=False)`` (None when there is none; the
    sample count, seed and adaptive sampling change only the noise and are not listed)."""
    defaults = resolve_settings()
    mb_file, mb_default = int(portable.get("max_bounces", defaults.max_bounces)), defaults.max_bounces
    diffs = []
    for k, v in portable.items():
        d: Any = getattr(defaults, k)
        if k in _NOISE_ONLY:
            continue
        if k.endswith("_bounces") and k != "max_bounces":  # what Cycles uses: per-kind limits <= max_bounces
            d = defaults.bounces(k[: -len("_bounces")])
            if v is None:  # a file written by export_blend: the RenderSettings default of its max_bounces
                v = max(mb_file, 8) if k == "transparent_bounces" else mb_file
            if k in _CAPPED_BOUNCES:
                v, d = min(v, mb_file), min(d, mb_default)
        if _same(v, d):
            continue
        diffs.append(f"{k}={v!r} (bf.render: {d!r})")
    diffs += [f"cycles.{line}" for line in cycles_changes(cycles, mb_file, mb_default)]
    if not diffs:
        return None
    return UNIMPORTED + ", ".join(diffs)
