"""Writing files for the user: one place for atomic writes, file modes and write errors.

Every file the library writes (images, scene files, videos, reports, manifests) goes through
:class:`AtomicOutput` / :func:`atomic_write`:

- the data is written to a temporary file next to the destination, which is renamed into place only when
  the writer succeeded: a failed or interrupted write leaves neither a partial nor a temporary file, and an
  existing file at the destination is unchanged;
- the new file gets the mode a plain ``open(path, "w")`` would give it: ``0o666 & ~umask`` (and the
  folder's default ACL, if any) for a new file, the permission bits of the file it replaces when
  overwriting. The umask is never read with ``os.umask`` (which changes it process-wide for a moment, so
  another thread creating a file then would get mode 0666): the temporary file is created with
  ``os.open(..., 0o666)`` and the kernel applies the umask;
- any ``OSError`` while writing becomes an :class:`~blendify_core.errors.OutputError` (also an
  ``OSError``) naming the argument and the path; a missing folder is a
  :class:`~blendify_core.errors.MissingFolderError`.
"""

from __future__ import annotations

import errno as errno_mod
import os
import secrets
import stat
from pathlib import Path
from typing import Any

from blendify_core.errors import MissingFolderError, OutputError

__all__ = ["AtomicOutput", "atomic_write", "check_file_name", "ensure_folder", "output_error"]

_NAME_MAX = 255  # when the file system does not say (os.pathconf missing or failing)
_TOKEN = 8  # hex characters of randomness in a temporary name


def output_error(arg: str, path: Any, exc: OSError, action: str = "cannot write") -> OutputError:
    """An OutputError for ``exc`` raised while writing ``path`` (given as argument ``arg``)."""
    if isinstance(exc, OutputError):
        return exc
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.errno == errno_mod.ENOENT and not _parent(Path(path)).is_dir():
        return MissingFolderError(
            f"{arg}: cannot write {str(path)!r}: the folder {str(_parent(Path(path)))!r} does not exist",
            str(path),
            exc.errno,
        )
    return OutputError(f"{arg}: {action} {str(path)!r}: {reason}", str(path), exc.errno)


def _parent(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def check_file_name(arg: str, path: Any) -> str:
    """``path`` as a str, or an OutputError naming it when no file can be written there: a NUL byte, an
    existing folder (checked before a file-type check, so ``save(folder)`` says what is wrong)."""
    text = _check_name(arg, path)
    if Path(text).name in ("", ".", "..") or os.path.isdir(text):
        raise OutputError(
            f"{arg}: cannot write {text!r}: it is an existing folder, expected a file name", text, errno_mod.EISDIR
        )
    return text


def _check_name(arg: str, path: Any) -> str:
    """``path`` as a str, or an OutputError when no file of that name can exist."""
    text = os.fspath(path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if "\x00" in text:
        raise OutputError(f"{arg}: cannot write {text!r}: the path contains a NUL byte", text, errno_mod.EINVAL)
    return text


def _name_max(folder: Path) -> int:
    try:
        value = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):  # no pathconf (Windows) or no such limit
        return _NAME_MAX
    return value if isinstance(value, int) and value > 0 else _NAME_MAX


def _temp_name(name: str, suffix: str, name_max: int) -> str:
    """``.<name>.<random>.tmp<suffix>``, shortened to fit ``name_max`` bytes (the suffix is kept whole when
    it fits: some writers, ffmpeg, choose the format from it)."""
    token = secrets.token_hex(_TOKEN // 2)
    fixed = len(os.fsencode(f"..{token}.tmp"))
    sfx = suffix if fixed + len(os.fsencode(suffix)) <= name_max else ""
    room = name_max - fixed - len(os.fsencode(sfx))
    stem = os.fsencode(name)[: max(room, 0)].decode(errors="ignore") if room > 0 else ""
    return f".{stem}.{token}.tmp{sfx}"


class AtomicOutput:
    """A temporary file next to ``path`` that :meth:`commit` renames to ``path`` (:meth:`discard` removes it).

    Created on construction, empty, with the final mode already applied (see the module's docstring), so a
    writer may open it by name (``tmp``) and truncate it. As a context manager it commits on success and
    discards on any exception (``KeyboardInterrupt`` too); an ``OSError`` from the block becomes an
    :class:`~blendify_core.errors.OutputError` naming ``path``.

    Checks before anything is written: a NUL byte in the path, a path that is an existing folder, a missing
    folder, a folder that is a file, a file name longer than the file system allows; a folder where the
    file cannot be created (read-only, permission denied, full disk) fails when the temporary file is made.
    """

    def __init__(self, path: str | os.PathLike[str], arg: str = "path", suffix: str | None = None) -> None:
        self.arg = arg
        text = check_file_name(arg, path)
        self.path = Path(text)
        parent = _parent(self.path)
        name = self.path.name
        if not parent.exists():
            raise MissingFolderError(
                f"{arg}: cannot write {text!r}: the folder {str(parent)!r} does not exist", text, errno_mod.ENOENT
            )
        if not parent.is_dir():
            raise OutputError(f"{arg}: cannot write {text!r}: {str(parent)!r} is not a folder", text, errno_mod.ENOTDIR)
        name_max = _name_max(parent)
        size = len(os.fsencode(name))
        if size > name_max:
            raise OutputError(
                f"{arg}: cannot write {text!r}: the file name is {size} bytes long, this file system allows {name_max}",
                text,
                errno_mod.ENAMETOOLONG,
            )
        # overwriting keeps the permission bits of the file replaced, as open(path, "w") would
        keep: int | None = None
        try:
            st = os.stat(text)
        except OSError:
            st = None
        if st is not None and stat.S_ISREG(st.st_mode):
            keep = stat.S_IMODE(st.st_mode) & 0o777
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOFOLLOW", 0)
        for _ in range(100):
            tmp = parent / _temp_name(name, self.path.suffix if suffix is None else suffix, name_max)
            try:
                fd = os.open(tmp, flags, 0o666)  # the kernel applies the umask (and a default ACL)
            except FileExistsError:
                continue
            except OSError as exc:
                raise output_error(arg, text, exc) from exc
            break
        else:  # pragma: no cover - 100 collisions of 32 random bits
            raise OutputError(
                f"{arg}: cannot write {text!r}: no free temporary name in {str(parent)!r}", text, errno_mod.EEXIST
            )
        self.tmp = tmp
        try:
            self.mode = keep if keep is not None else stat.S_IMODE(os.fstat(fd).st_mode) & 0o777
            if keep is not None:
                os.chmod(tmp, keep)
        except OSError as exc:
            os.close(fd)
            self.discard()
            raise output_error(arg, text, exc) from exc
        os.close(fd)
        self._open = True

    def commit(self) -> Path:
        """Give the temporary file its final mode (a writer may have re-created it) and rename it into place."""
        if not self._open:
            raise OutputError(f"{self.arg}: {str(self.path)!r} was already committed or discarded", str(self.path))
        try:
            if stat.S_IMODE(os.stat(self.tmp).st_mode) & 0o777 != self.mode:
                os.chmod(self.tmp, self.mode)
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self.discard()
            raise output_error(self.arg, self.path, exc) from exc
        self._open = False
        return self.path

    def discard(self) -> None:
        """Remove the temporary file (nothing happens when it is already gone)."""
        self._open = False
        try:
            os.unlink(self.tmp)
        except FileNotFoundError:
            pass

    def __enter__(self) -> AtomicOutput:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.commit()
            return
        self.discard()
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise output_error(self.arg, self.path, exc) from exc


def atomic_write(path: str | os.PathLike[str], writer: Any, suffix: str | None = None, arg: str = "path") -> Path:
    """Call ``writer(tmp_path)`` on a temporary file in the destination folder, then rename it into place.

    The new file gets the mode ``open(path, "w")`` would give it (``0o666 & ~umask`` for a new file, the
    old permission bits when overwriting); nothing is left behind when the writer fails; an ``OSError``
    becomes an :class:`~blendify_core.errors.OutputError` naming ``arg`` and ``path``. ``suffix`` (default:
    the destination's) ends the temporary file's name, for writers that pick the format from it."""
    with AtomicOutput(path, arg=arg, suffix=suffix) as out:
        writer(str(out.tmp))
    return out.path


def ensure_folder(folder: str | os.PathLike[str], arg: str = "folder") -> Path:
    """Create ``folder`` and its parents when missing; an OutputError naming ``arg`` when that fails."""
    text = _check_name(arg, folder)
    p = Path(text)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except FileExistsError as exc:  # a file of that name
        raise OutputError(
            f"{arg}: cannot create the folder {text!r}: a file of that name exists", text, exc.errno
        ) from exc
    except OSError as exc:
        raise output_error(arg, text, exc, action="cannot create the folder") from exc
    return p
