"""Portable scene files: one ``.npz`` holding a versioned JSON header and the arrays (no pickle).

This module stores and reads the container; what the header and arrays mean is the IR's business
(:mod:`blendify_core.ir.serialize`). File paths inside the header (keys ``texture_path`` and ``path``) are
stored relative to the file when asked, and resolved against the file's folder on reading, which they may
not leave unless ``allow_outside=True``.

Reading is bounded (a crafted file must not exhaust memory or the stack): the header's size and nesting
depth, and every array's size DECLARED in its ``.npy`` header, are checked against :data:`LIMITS` before
anything is allocated, and only the members the scene asks for are read (an extra member is never
decompressed). A violation is an InvalidSceneError naming the limit; ``LIMITS.override(...)`` (or
assigning its fields) raises a limit for a trusted large file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core._memo import digest_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.io.output import AtomicOutput
from blendify_core.io.paths import as_path

__all__ = [
    "FORMAT",
    "VERSION",
    "LIMITS",
    "SceneFileLimits",
    "SceneArrays",
    "write_scene_file",
    "read_scene_file",
    "walk_paths",
    "content_digest",
]

FORMAT = "blendify-core-scene"
VERSION = 1
_HEADER = "__header__"
_GIB = 1 << 30


@dataclass
class SceneFileLimits:
    """What a scene file may declare before reading it fails (InvalidSceneError naming the limit).
    The defaults hold any scene a workstation renders (a 4 GiB array is ~180 M float64 vertices)."""

    #: bytes of the JSON header
    max_header_bytes: int = 64 << 20
    #: nesting depth of the JSON header (blendify-core writes < 10)
    max_header_depth: int = 64
    #: bytes of one array, as its .npy header declares it (shape x item size)
    max_array_bytes: int = 4 * _GIB
    #: bytes of all arrays read from one file
    max_total_bytes: int = 16 * _GIB

    @contextlib.contextmanager
    def override(self, **changes: int) -> Iterator[SceneFileLimits]:
        """Change some limits for the ``with`` block (process-wide; not for concurrent threads)."""
        names = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise InvalidSceneError(f"SceneFileLimits.override: unknown limit(s) {unknown}; known: {sorted(names)}")
        before = {k: getattr(self, k) for k in changes}
        for k, v in changes.items():
            setattr(self, k, v)
        try:
            yield self
        finally:
            for k, v in before.items():
                setattr(self, k, v)


#: the limits every scene-file read checks (``blendify_core.io.scenefile.LIMITS``)
LIMITS = SceneFileLimits()


class SceneArrays(Mapping[str, np.ndarray]):
    """The arrays of an open scene file, read on first access with their declared size checked against
    :data:`LIMITS` first; members never asked for are never decompressed. Close it (or use ``with``)."""

    def __init__(self, zf: zipfile.ZipFile, path: str) -> None:
        self._zf = zf
        self._path = path
        self._members = {n[: -len(".npy")]: n for n in zf.namelist() if n.endswith(".npy") and n != _HEADER + ".npy"}
        self._cache: dict[str, np.ndarray] = {}
        self._total = 0

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._cache:
            member = self._members.get(key) if isinstance(key, str) else None
            if member is None:
                raise KeyError(key)
            self._cache[key] = self._read(key, member)
        return self._cache[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._members)

    def __len__(self) -> int:
        return len(self._members)

    def _read(self, key: str, member: str) -> np.ndarray:
        where = f"path: {self._path!r}: array {key!r}"
        try:
            with self._zf.open(member) as f:
                version = np.lib.format.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                else:
                    shape, _, dtype = np.lib.format.read_array_header_2_0(f)
            if dtype.hasobject:
                raise InvalidSceneError(f"{where}: holds Python objects (dtype {dtype}); scene files hold numbers")
            nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if nbytes > LIMITS.max_array_bytes:
                raise InvalidSceneError(
                    f"{where}: declares shape {shape} of {dtype} ({nbytes:,} bytes), above the limit "
                    f"max_array_bytes={LIMITS.max_array_bytes:,} (raise it with "
                    "blendify_core.io.scenefile.LIMITS.override(max_array_bytes=...) for a trusted file)"
                )
            if self._total + nbytes > LIMITS.max_total_bytes:
                raise InvalidSceneError(
                    f"{where}: the arrays read reach {self._total + nbytes:,} bytes, above the limit "
                    f"max_total_bytes={LIMITS.max_total_bytes:,}"
                )
            with self._zf.open(member) as f:
                array = np.lib.format.read_array(f, allow_pickle=False)
        except InvalidSceneError:
            raise
        except (zipfile.BadZipFile, ValueError, OSError, EOFError, RuntimeError) as exc:
            raise InvalidSceneError(f"{where} is unreadable ({type(exc).__name__}: {exc})") from None
        self._total += nbytes
        return array

    def close(self) -> None:
        self._zf.close()

    def __enter__(self) -> SceneArrays:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _depth(obj: Any) -> int:
    """Nesting depth of a parsed JSON value (iterative: no recursion limit)."""
    deepest, stack = 0, [(obj, 1)]
    while stack:
        value, d = stack.pop()
        if isinstance(value, (dict, list)):
            deepest = max(deepest, d)
            stack.extend((v, d + 1) for v in (value.values() if isinstance(value, dict) else value))
    return deepest


def _read_header(zf: zipfile.ZipFile, path: str) -> Any:
    try:
        info = zf.getinfo(_HEADER + ".npy")
    except KeyError:
        raise InvalidSceneError(f"path: {path!r} is not a blendify-core scene file (no header)") from None
    if info.file_size > LIMITS.max_header_bytes:
        raise InvalidSceneError(
            f"path: {path!r}: the header is {info.file_size:,} bytes, above the limit "
            f"max_header_bytes={LIMITS.max_header_bytes:,}"
        )
    with zf.open(info) as f:
        raw = np.lib.format.read_array(f, allow_pickle=False)
    try:
        header = json.loads(bytes(raw).decode("utf-8"))
    except RecursionError:
        header = None
    if header is None or _depth(header) > LIMITS.max_header_depth:
        raise InvalidSceneError(
            f"path: {path!r}: the header is nested deeper than the limit max_header_depth={LIMITS.max_header_depth}"
        )
    return header


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


def read_scene_file(path: str | os.PathLike[str], allow_outside: bool = False) -> tuple[dict[str, Any], SceneArrays]:
    """The header (file paths resolved and confined) and the arrays of a scene file (read on access,
    bounded by :data:`LIMITS`; close them when done)."""
    p = as_path("path", path)
    if not p.is_file():
        raise InvalidSceneError(f"path: no such scene file {str(path)!r}")
    zf: zipfile.ZipFile | None = None
    try:
        if not zipfile.is_zipfile(p):
            with open(p, "rb") as f:
                if f.read(6) == b"\x93NUMPY":
                    raise InvalidSceneError(
                        f"path: {str(path)!r} is not a blendify-core scene file (a single .npy array)"
                    )
            raise InvalidSceneError(f"path: {str(path)!r} is not a readable scene file (not an .npz archive)")
        zf = zipfile.ZipFile(p)
        header = _read_header(zf, str(path))
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, RuntimeError, UnicodeDecodeError) as exc:
        if zf is not None:
            zf.close()
        if isinstance(exc, InvalidSceneError):
            raise
        raise InvalidSceneError(
            f"path: {str(path)!r} is not a readable scene file ({type(exc).__name__}: {exc})"
        ) from None
    except BaseException:
        if zf is not None:
            zf.close()
        raise
    arrays = SceneArrays(zf, str(path))
    try:
        return _checked_header(p, str(path), header, allow_outside), arrays
    except BaseException:
        arrays.close()
        raise


def _checked_header(p: Path, path: str, header: Any, allow_outside: bool) -> dict[str, Any]:
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise InvalidSceneError(f"path: {path!r} is not a blendify-core scene file")
    version = header.get("version")
    if version != VERSION:
        raise InvalidSceneError(
            f"path: {path!r} has scene format version {version!r}; this blendify-core reads version {VERSION}"
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

    checked: dict[str, Any] = walk_paths(header, resolve)
    return checked


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
