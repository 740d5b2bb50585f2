"""export_mitsuba: write an IR scene as a Mitsuba 3 XML scene that ``mitsuba.load_file`` renders as this
backend does.

The scene is translated by the backend's own translator (:class:`blendify_mitsuba.translate.MitsubaTranslator`,
the same translation the renders use) with a stand-in engine (:data:`blendify_mitsuba.translate.ENGINE`) that
keeps the plain dictionaries, mesh buffers and bitmaps instead of loading them. Meshes are then written as
binary ``.ply`` files (with their ``vertex_color`` / ``vertex_alpha`` attributes), point clouds of spheres
(:mod:`blendify_mitsuba.points`) as ``linearcurve`` text files, and bitmaps as float32
``.exr`` files into the folder ``<name>_files`` beside the XML, and the dictionary becomes XML through
Mitsuba's own scene writer (``mitsuba.parser.write_file``). Every file is written atomically.

What a render of the XML cannot do is what the backend does around ``mi.render`` (listed in a warning):
compositing the coverage alpha of emissive surfaces under a sky, adding the sky back behind an opaque
film's hidden emitters, removing the lights the camera sees in scenes with emissive materials, the
shadow-catcher emulation and the resampling of non-square pixels.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError, RenderError
from blendify_core.io.output import atomic_write, ensure_folder
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.settings import resolve_settings

from . import translate as _translate
from .points import curve_file_text
from .session import MitsubaSession
from .translate import DEFAULT_SAMPLER, MitsubaTranslator

__all__ = ["export_mitsuba"]


@dataclass
class _Array:
    """A bitmap's pixels (what ``mi.TensorXf`` / ``mi.Bitmap`` would have held)."""

    data: np.ndarray


@dataclass
class _MeshData:
    """The buffers :func:`blendify_mitsuba.translate.build_mesh` would have made a ``mi.Mesh`` of."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uv: np.ndarray | None
    attributes: dict[str, np.ndarray] | None
    bsdf: Any
    emitter: Any


@dataclass
class _CurveData:
    """The points :func:`blendify_mitsuba.translate.build_curves` would have made a curve shape of."""

    name: str
    centres: np.ndarray
    radii: np.ndarray
    bsdf: Any
    axis: Any = (0.0, 0.0, 1.0)


class _DictEngine:
    """Stands in for the mitsuba module while the exporter translates: ``load_dict`` returns the dictionary,
    ``TensorXf`` / ``Bitmap`` the array, ``build_mesh`` the buffers; anything else is the real module's."""

    def __init__(self, mi: Any) -> None:
        self._mi = mi

    def __getattr__(self, name: str) -> Any:
        return getattr(self._mi, name)

    @staticmethod
    def load_dict(d: Any) -> Any:
        return d

    @staticmethod
    def TensorXf(data: Any) -> _Array:  # noqa: N802 - mitsuba's name
        return _Array(np.array(data, dtype=np.float32))

    @staticmethod
    def Bitmap(data: Any) -> _Array:  # noqa: N802 - mitsuba's name
        return _Array(np.array(data, dtype=np.float32))

    @staticmethod
    def build_mesh(*args: Any) -> _MeshData:
        return _MeshData(*args)

    @staticmethod
    def build_curves(*args: Any) -> _CurveData:
        return _CurveData(*args)


class _Writer:
    """Turns the translated dictionary into plain properties, writing meshes and bitmaps beside the XML."""

    def __init__(self, mi: Any, folder: Path, xml_dir: Path) -> None:
        self.mi = mi
        self.folder = folder
        self.xml_dir = xml_dir
        self.count = 0

    def _target(self, stem: str, suffix: str) -> tuple[Path, str]:
        self.count += 1
        path = self.folder / (f"{stem}{suffix}" if stem else f"file{self.count:04d}{suffix}")
        return path, path.relative_to(self.xml_dir).as_posix()

    def mesh(self, m: _MeshData) -> dict[str, Any]:
        path, rel = self._target(m.name, ".ply")
        mesh = _translate.build_mesh(m.name, m.vertices, m.faces, m.normals, m.uv, m.attributes)
        atomic_write(path, lambda tmp: mesh.write_ply(tmp))
        out: dict[str, Any] = {"type": "ply", "filename": rel}
        if m.normals is None:
            out["face_normals"] = True  # as the in-memory mesh without vertex normals
        if m.bsdf is not None:
            out["bsdf"] = self.plain(m.bsdf, f"{m.name}_bsdf")
        if m.emitter is not None:
            out["emitter"] = self.plain(m.emitter, f"{m.name}_emitter")
        return out

    def curves(self, c: _CurveData) -> dict[str, Any]:
        path, rel = self._target(c.name, ".txt")
        text = curve_file_text(c.centres, c.radii, c.axis)
        atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="ascii"))
        out: dict[str, Any] = {"type": "linearcurve", "filename": rel}
        if c.bsdf is not None:
            out["bsdf"] = self.plain(c.bsdf, f"{c.name}_bsdf")
        return out

    def bitmap(self, a: _Array, stem: str) -> str:
        path, rel = self._target(stem, ".exr")
        bitmap = self.mi.Bitmap(np.ascontiguousarray(a.data, dtype=np.float32))
        atomic_write(path, lambda tmp: bitmap.write(tmp), suffix=".exr")
        return rel

    def plain(self, value: Any, stem: str = "") -> Any:
        if isinstance(value, _MeshData):
            return self.mesh(value)
        if isinstance(value, _CurveData):
            return self.curves(value)
        if isinstance(value, dict):
            out: dict[str, Any] = {}
            for key, item in value.items():
                if isinstance(item, _Array):  # a bitmap's "data" or an envmap's "bitmap"
                    out["filename"] = self.bitmap(item, stem)
                else:
                    out[key] = self.plain(item, f"{stem}_{key}" if stem else key)
            return out
        if isinstance(value, (list, tuple)):
            return [self.plain(v, f"{stem}_{i}") for i, v in enumerate(value)]
        if isinstance(value, (np.floating, np.integer)):
            return value.item()
        return value


#: blendify's Mitsuba plugins (written in Python) -> the module whose ``register()`` registers them in a process
_PLUGIN_MODULES = {
    "blendify_sided": "sided",
    "blendify_path": "integrator",
    "blendify_principled": "layered",
    "blendify_glass": "layered",
}
#: ... and that call as a user writes it
_PLUGIN_REGISTRARS = {name: f"blendify_mitsuba.{module}.register()" for name, module in _PLUGIN_MODULES.items()}


def _register_for_writer(mi: Any, own: set[str]) -> None:
    """Mitsuba 3.9.1's XML writer finds a Python plugin's object type (its XML tag) only when the plugin is
    registered in ``scalar_rgb`` (measured: a plugin registered in ``llvm_ad_rgb`` alone fails with "Cannot
    determine XML tag name ... unknown object type"), so ``own`` plugins are registered there too."""
    if not own or mi.variant() == "scalar_rgb" or "scalar_rgb" not in mi.variants():
        return
    import importlib

    variant = mi.variant()
    try:
        mi.set_variant("scalar_rgb")
        for module in sorted({_PLUGIN_MODULES[name] for name in own}):
            importlib.import_module(f"{__package__}.{module}").register()
    finally:
        mi.set_variant(variant)


def _own_plugins(value: Any) -> set[str]:
    """The plugin types of :data:`_PLUGIN_REGISTRARS` used anywhere in the plain scene dictionary."""
    found: set[str] = set()
    if isinstance(value, dict):
        if value.get("type") in _PLUGIN_REGISTRARS:
            found.add(value["type"])
        for item in value.values():
            found |= _own_plugins(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            found |= _own_plugins(item)
    return found


def export_mitsuba(
    scene: Any,
    path: str | os.PathLike[str],
    variant: str | None = None,
    max_analytic_spheres: int | None = None,
    sampler: str = DEFAULT_SAMPLER,
    **settings: Any,
) -> Path:
    """Write ``scene`` as a Mitsuba 3 XML file that ``mitsuba.load_file`` loads and renders as the ``mitsuba``
    backend does (the same translation: integrator, sensor with film and sampler, shapes, BSDFs, emitters).

    Meshes go to ``.ply``, curve point clouds to ``.txt`` and bitmaps to ``.exr`` files in ``<name>_files/``
    beside the XML, referenced by relative paths. ``settings`` are render settings
    (:func:`blendify_core.pipeline.settings.resolve_settings` keywords, e.g. ``quality="final", samples=64``)
    that fix the integrator and the sampler; ``variant``, ``max_analytic_spheres`` and ``sampler`` are the
    backend's options (the variant decides only how point clouds are translated: the XML loads in any RGB
    variant). Returns the written path."""
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera (the XML needs a sensor)")
    out = Path(os.fspath(path)).expanduser()
    if out.suffix.lower() != ".xml":
        raise InvalidSceneError(f"path: expected a .xml file name, got {str(path)!r}")
    render_settings = resolve_settings(**settings)
    session = MitsubaSession(variant, max_analytic_spheres, sampler)
    translator = MitsubaTranslator(
        render_settings,
        max_analytic_spheres=session.max_analytic_spheres,
        max_analytic_opaque=session.max_analytic_opaque,
        sampler=session.sampler,
    )
    with session.engine() as mi:
        token = _translate.ENGINE.set(_DictEngine(mi))
        try:
            tr = translator.translate(scene)
        finally:
            _translate.ENGINE.reset(token)
        ensure_folder(out.parent)
        folder = ensure_folder(out.parent / f"{out.stem}_files", arg="path")
        plain = _Writer(mi, folder, out.parent).plain(tr.scene_dict)
        try:
            import mitsuba.parser as mp

            _register_for_writer(mi, _own_plugins(plain))

            config = mp.ParserConfig(mi.variant())
            state = mp.parse_dict(config, plain)
            text = mp.write_string(state)
        except Exception as exc:
            raise RenderError(f"export_mitsuba: Mitsuba could not write the scene: {exc}") from exc
    written = atomic_write(out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    notes = []
    own = sorted(_own_plugins(plain))
    if own:
        calls = sorted({_PLUGIN_REGISTRARS[p] for p in own})
        notes.append(
            f"the XML uses blendify's own Mitsuba plugins ({', '.join(own)}): call {', '.join(calls)} with the "
            "variant set before mitsuba.load_file"
        )
    if tr.coverage_dict is not None:
        notes.append("emissive surfaces under a sky with a transparent background: the coverage alpha is composited")
    if tr.coverage_dict is None and tr.background_dict is not None:
        notes.append("emitters hidden from the camera under an opaque film: the backend adds the sky back behind them")
    if tr.light_shapes:
        notes.append("lights seen by the camera in a scene with emissive materials: the backend removes them")
    if tr.catcher_dict is not None:
        notes.append("shadow catchers: emulated by the backend from two more renders (catchers alone, all but them)")
    if tr.aniso is not None:
        notes.append("fx != fy: the XML renders the square-pixel camera, the backend resamples its rows")
    if tr.ignored:
        notes.extend(tr.ignored)
    if notes:
        warnings.warn(
            f"export {written.name}: a render of the XML differs from the backend's where it does more than "
            "mi.render: " + "; ".join(notes),
            UserWarning,
            stacklevel=3,
        )
    return written
