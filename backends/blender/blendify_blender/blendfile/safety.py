"""The auto-run guard: nothing embedded in a .blend file is ever executed, whatever the user's Blender
preferences say.

- ``preferences.filepaths.use_scripts_auto_execute`` is forced to False for the whole load and
  evaluation (and restored afterwards), see :func:`scripts_auto_execute_disabled`;
- text blocks are never requested from the library (a text block pulled in indirectly is removed
  before anything is evaluated; registered ``use_module`` texts only run on ``wm.open_mainfile``,
  which is never used);
- every driver with a Python expression (``type == 'SCRIPTED'`` and not a "simple expression", which
  Blender evaluates in C without Python) is deleted right after the load, BEFORE the first depsgraph
  evaluation: with auto-run off Blender would still run such expressions in its restricted namespace;
  the deleted drivers are listed in the warning (:func:`strip_python`).

Files are appended with ``bpy.data.libraries.load(path, link=False)`` into the running bpy session, never
opened as Blender's main file. :func:`loaded_blend` appends every scene of a file under these rules and
removes every datablock the load created on exit, so the session is left as it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from blendify_blender import session
from blendify_core.errors import InvalidSceneError

__all__ = [
    "all_ids",
    "appended_blend",
    "check_blend_path",
    "loaded_blend",
    "new_ids_since",
    "readable_copy",
    "scripts_auto_execute_disabled",
    "strip_python",
    "unreadable_blend",
]

# gzip (Blender < 3.0 compressed files) and zstd (Blender >= 3.0 compressed files) magic numbers
_BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


def check_blend_path(path: Any, name: str = "path") -> Path:
    """Validate that ``path`` names an existing .blend file (by its header); returns the resolved path."""
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidSceneError(f"{name}: expected a path to a .blend file, got {type(path).__name__} {path!r}")
    p = Path(path).expanduser()
    if not p.exists():
        raise InvalidSceneError(f"{name}: no such file {str(p)!r}")
    if not p.is_file():
        raise InvalidSceneError(f"{name}: expected a .blend file, got a directory {str(p)!r}")
    try:
        with open(p, "rb") as fh:
            head = fh.read(8)
    except OSError as exc:
        raise InvalidSceneError(f"{name}: cannot read {str(p)!r} ({exc})") from None
    if not any(head.startswith(m) for m in _BLEND_MAGICS):
        raise InvalidSceneError(
            f"{name}: {str(p)!r} is not a .blend file (its header is {head[:7]!r}, expected b'BLENDER' or a "
            "compressed .blend)"
        )
    return p.resolve()


@contextlib.contextmanager
def scripts_auto_execute_disabled() -> Iterator[None]:
    """Force Blender's "Auto Run Python Scripts" preference off inside the block, restore it afterwards."""
    bpy = session.bpy_module()
    prefs = bpy.context.preferences.filepaths
    old = bool(prefs.use_scripts_auto_execute)
    prefs.use_scripts_auto_execute = False
    try:
        yield
    finally:
        prefs.use_scripts_auto_execute = old


def _id_collections(bpy: Any) -> list[Any]:
    """Every ``bpy.data`` collection holding IDs (found through RNA, so new Blender versions are covered)."""
    out = []
    for prop in bpy.data.bl_rna.properties:
        if prop.type != "COLLECTION" or prop.identifier in ("window_managers", "screens", "workspaces"):
            continue
        base = getattr(prop, "fixed_type", None)
        while base is not None and base.identifier != "ID":
            base = base.base
        if base is not None:
            out.append(getattr(bpy.data, prop.identifier))
    return out


def all_ids(bpy: Any) -> dict[int, Any]:
    """Every datablock of the session (but window managers, screens and workspaces), by pointer."""
    ids: dict[int, Any] = {}
    for coll in _id_collections(bpy):
        for idb in coll:
            ids[idb.as_pointer()] = idb
    return ids


def new_ids_since(bpy: Any, before: set[int]) -> list[Any]:
    """The datablocks created since ``before`` (a set of pointers from :func:`all_ids`)."""
    return [idb for ptr, idb in all_ids(bpy).items() if ptr not in before]


def _python_drivers(idb: Any) -> Iterator[tuple[Any, Any, Any]]:
    """(owner, animation_data, fcurve) for every driver of ``idb`` (and its embedded node tree / shape
    keys) whose expression needs Python."""
    owners = [idb]
    for attr in ("node_tree", "shape_keys"):
        sub = getattr(idb, attr, None)
        if sub is not None and hasattr(sub, "animation_data"):
            owners.append(sub)
    for owner in owners:
        ad = getattr(owner, "animation_data", None)
        if ad is None:
            continue
        for fc in list(ad.drivers):
            drv = fc.driver
            if drv.type == "SCRIPTED" and not drv.is_simple_expression:
                yield owner, ad, fc


def strip_python(bpy: Any, new_ids: list[Any]) -> list[str]:
    """Remove Python drivers and text blocks among freshly loaded IDs; returns what was removed."""
    removed: list[str] = []
    texts = [i for i in new_ids if isinstance(i, bpy.types.Text)]
    for idb in new_ids:
        if isinstance(idb, bpy.types.Text):
            continue
        for owner, ad, fc in list(_python_drivers(idb)):
            what = f"Python driver on {owner.name!r} {fc.data_path}[{fc.array_index}] = {fc.driver.expression!r}"
            try:
                ad.drivers.remove(fc)
            except (RuntimeError, TypeError, AttributeError, ReferenceError) as exc:
                # e.g. data linked from another library is read-only: refuse rather than evaluate it
                raise InvalidSceneError(
                    f"path: the file contains a {what} that cannot be removed ({exc}); refusing to evaluate it"
                ) from None
            removed.append(f"{what} (removed, never evaluated)")
    for t in texts:
        removed.append(f"text block {t.name!r} (removed, never run)")
    if texts:
        bpy.data.batch_remove(texts)
    return removed


def unreadable_blend(path: Path, exc: Exception) -> InvalidSceneError:
    """The error for a file Blender refuses to load."""
    return InvalidSceneError(f"path: Blender cannot read {str(path)!r} as a .blend file ({exc})")


#: datablock kinds of a library whose names are not kept (never loaded, or handled separately)
_NAMES_NOT_KEPT = ("scenes", "screens", "workspaces", "texts", "version", "window_managers", "brushes", "palettes")


def _keep_file_names(bpy: Any, src: Any, renamed: list[tuple[Any, str]]) -> None:
    """Rename, for the duration of a load, the session's datablocks whose names the file uses, so the
    appended datablocks keep the names they have in the file (warnings and IR tags use them); the
    renamed ones are collected in ``renamed`` and restored by :func:`_restore_names`."""
    k = 0
    for kind in dir(src):
        if kind.startswith("_") or kind in _NAMES_NOT_KEPT:
            continue
        coll, names = getattr(bpy.data, kind, None), getattr(src, kind, None)
        if coll is None or not isinstance(names, list):
            continue
        for nm in names:
            existing = coll.get(nm)
            if existing is not None and existing.library is None:
                renamed.append((existing, nm))
                existing.name = f"~bf{k}~{nm}"[:60]
                k += 1


def _restore_names(renamed: list[tuple[Any, str]]) -> None:
    for idb, nm in reversed(renamed):
        idb.name = nm


@contextlib.contextmanager
def readable_copy(path: Path) -> Iterator[tuple[Path, list[str]]]:
    """(path to load, notes): ``path`` itself, or a temporary copy when it is bpy's current main file
    (Blender refuses to append from the open file); the copy holds what was saved, which is noted when
    the open file has unsaved changes."""
    bpy = session.bpy_module()
    main = bpy.data.filepath
    if not main or not Path(main).exists() or not Path(main).resolve().samefile(path):
        yield path, []
        return
    notes = []
    if bpy.data.is_dirty:
        notes.append(f"{str(path)!r} is bpy's current main file and has unsaved changes: the file as saved was read")
    with tempfile.TemporaryDirectory(prefix="blendify_main_") as tmp:
        copy = Path(tmp) / path.name
        try:
            shutil.copyfile(path, copy)
        except OSError as exc:
            raise InvalidSceneError(
                f"path: {str(path)!r} is bpy's current main file and could not be copied to be read ({exc})"
            ) from None
        yield copy, notes


@contextlib.contextmanager
def appended_blend(path: Path) -> Iterator[tuple[list[tuple[str, Any]], list[str], list[Any]]]:
    """Append all scenes of ``path`` safely, the datablocks keeping the names they have in the file for
    the duration of the block (session datablocks with those names are renamed meanwhile and get their
    names back on exit); yields ((name in the file, scene) sorted by name, notes about removed Python
    and the file, all new IDs). The new IDs stay (the caller owns them). Auto-run must already be
    forced off by the caller (:func:`scripts_auto_execute_disabled`)."""
    bpy = session.bpy_module()
    before = set(all_ids(bpy))
    renamed: list[tuple[Any, str]] = []
    try:
        with readable_copy(path) as (readable, notes):
            try:
                with bpy.data.libraries.load(str(readable), link=False) as (src, dst):
                    src_names = list(src.scenes)
                    dst.scenes = list(src_names)
                    _keep_file_names(bpy, src, renamed)
            except (OSError, RuntimeError, ValueError) as exc:
                raise unreadable_blend(path, exc) from None
        try:
            removed = strip_python(bpy, new_ids_since(bpy, before))
        except BaseException:
            bpy.data.batch_remove(new_ids_since(bpy, before))
            raise
        # (name in the file, appended scene): appended scenes are renamed when the session has the name
        scenes = sorted(((n, sc) for n, sc in zip(src_names, dst.scenes) if sc is not None), key=lambda x: x[0])
        yield scenes, notes + removed, new_ids_since(bpy, before)
    finally:
        if renamed:
            # the appended datablocks give the names back to the session's own
            for idb in new_ids_since(bpy, before):
                if any(idb.name == nm for _o, nm in renamed):
                    idb.name = f"{idb.name}.bf"[:60]
            _restore_names(renamed)


@contextlib.contextmanager
def loaded_blend(path: Path) -> Iterator[tuple[list[tuple[str, Any]], list[str], list[Any]]]:
    """:func:`appended_blend`, and every datablock the load created is removed on exit, so the session
    is left as it was (the file must contain a scene)."""
    bpy = session.bpy_module()
    before = set(all_ids(bpy))
    try:
        with appended_blend(path) as (scenes, notes, new_ids):
            if not scenes:
                raise InvalidSceneError(f"path: {str(path)!r} contains no scene")
            yield scenes, notes, new_ids
    finally:
        leftover = new_ids_since(bpy, before)
        if leftover:
            bpy.data.batch_remove(leftover)
