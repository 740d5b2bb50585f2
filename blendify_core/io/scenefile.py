"""Portable scene files: one ``.npz`` holding a versioned JSON header and the arrays (no pickle).

This module stores and reads the container; what the header and arrays mean is the IR's business
(:mod:`blendify_core.ir.serialize`). File paths inside the header (keys ``texture_path`` and ``path``) are
stored relative to the file when asked, and resolved against the file's folder on reading, which they may
not leave unless ``allow_outside=True``.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core._memo import digest_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.io.output import AtomicOutput
from blendify_core.io.paths import as_path

__all__ = ["FORMAT", "VERSION", "write_scene_file", "read_scene_file", "walk_paths", "content_digest"]

FORMAT = "blendify-core-scene"
VERSION = 1
_HEADER = "__header__"


def _rel(path: str, base: Path, relative: bool) -> str:
    if not relative:
        return path
    try:
        return os.path.relpath(path, base)
    except ValueError:  # another drive on Windows
        return path


def walk_paths(obj: Any, fn: Any) -> Any:
    """Apply ``fn`` to every file path in a header (keys 'texture_path' and 'path')."""
    if isinstance(obj, dict):
        return {
            k: (fn(v) if k in ("texture_path", "path") and isinstance(v, str) else walk_paths(v, fn))
            for k, v in obj.items()
        }
    if isinstance(obj, list):
        return [walk_paths(v, fn) for v in obj]
    return obj


def write_scene_file(
    path: str | os.PathLike[str],
    build: Callable[[], tuple[dict[str, Any], dict[str, np.ndarray]]],
    relative_paths: bool = True,
) -> None:
    """Write the header (JSON-able; ``format`` and ``version`` are added here) and arrays that ``build()``
    returns, atomically. The destination (folder, name, permissions) is checked before ``build`` runs."""
    p = as_path("path", path)
    if p.suffix.lower() != ".npz":
        raise InvalidSceneError(f"path: scene files end in .npz, got {str(path)!r}")
    out = AtomicOutput(p, arg="path")
    try:
        header, arrays = build()
        base = p.resolve().parent
        header = walk_paths({"format": FORMAT, "version": VERSION, **header}, lambda v: _rel(v, base, relative_paths))
        payload = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
        payload[_HEADER] = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    except BaseException:
        out.discard()
        raise
    with out, open(out.tmp, "wb") as f:
        np.savez_compressed(f, **payload)


def read_scene_file(
    path: str | os.PathLike[str], allow_outside: bool = False
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The header (file paths resolved and confined) and the arrays of a scene file."""
    p = as_path("path", path)
    if not p.is_file():
        raise InvalidSceneError(f"path: no such scene file {str(path)!r}")
    try:
        loaded = np.load(p, allow_pickle=False)
        if not hasattr(loaded, "files"):  # a plain .npy array under an .npz name
            raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file (a single .npy array)")
        with loaded as data:
            if _HEADER not in data.files:
                raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file (no header)")
            header = json.loads(bytes(data[_HEADER]).decode("utf-8"))
            arrays = {k: data[k] for k in data.files if k != _HEADER}
    except InvalidSceneError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InvalidSceneError(
            f"path: {str(path)!r} is not a readable scene file ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file")
    version = header.get("version")
    if version != VERSION:
        raise InvalidSceneError(
            f"path: {str(path)!r} has scene format version {version!r}; this blendify-core reads version {VERSION}"
        )
    base = p.resolve().parent

    def resolve(v: str) -> str:
        full = (base / v).resolve() if not os.path.isabs(v) else Path(v).resolve()
        if not allow_outside and base not in full.parents and full != base:
            raise InvalidSceneError(
                f"path: the scene references {v!r}, outside the scene's folder {str(base)!r}; "
                "pass allow_outside=True to read it"
            )
        return str(full)

    return walk_paths(header, resolve), arrays


_file_hash_cache: dict[tuple[str, float, int], str] = {}


def _file_digest(path: str) -> str:
    st = os.stat(path)
    key = (path, st.st_mtime, st.st_size)
    if key not in _file_hash_cache:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        _file_hash_cache[key] = h.hexdigest()
    return _file_hash_cache[key]


def content_digest(header: dict[str, Any], arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the canonical header and every array's dtype, shape and bytes; file paths in the header
    count by their content, so equal content hashes equal across processes and folders."""
    header = walk_paths(header, lambda v: "sha256:" + _file_digest(v) if os.path.isfile(v) else v)
    h = hashlib.sha256()
    h.update(json.dumps(header, sort_keys=True).encode("utf-8"))
    for key in sorted(arrays):
        a = arrays[key]
        h.update(f"{key}|{a.dtype.str}|{a.shape}|".encode())
        h.update(digest_memo(a, _array_digest).encode())
    return h.hexdigest()


def _array_digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()
