"""The error hierarchy of blendify-core.

Every error raised on purpose by the library derives from :class:`BlendifyError`, so callers can catch
them all at once, and each also derives from the builtin exception a Python user would expect
(``ValueError`` for bad input, ``ImportError`` for a missing engine, ``RuntimeError`` for a failed render,
``OSError`` for a file that cannot be written).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = [
    "BlendifyError",
    "InvalidSceneError",
    "UnsupportedFeatureError",
    "BackendUnavailableError",
    "RenderError",
    "OutputError",
    "MissingFolderError",
    "EXIT_CODES",
    "exit_code",
    "exit_code_epilog",
    "warn_at_caller",
    "strict_arguments",
]

_F = TypeVar("_F", bound=Callable[..., Any])


class BlendifyError(Exception):
    """Base class of every error raised on purpose by blendify-core."""


class InvalidSceneError(BlendifyError, ValueError):
    """Bad input: a wrong shape, dtype, range, unknown option or an inconsistent scene."""


class UnsupportedFeatureError(BlendifyError):
    """A backend cannot render a feature of the scene (or, with ``strict=True``, can only approximate it)."""

    def __init__(self, message: str, feature: str | None = None, backend: str | None = None):
        super().__init__(message)
        self.feature = feature
        self.backend = backend


class BackendUnavailableError(BlendifyError, ImportError):
    """A backend cannot be used here: its engine is not installed or cannot start."""


class RenderError(BlendifyError, RuntimeError):
    """The engine failed while translating or rendering; the message carries the engine's own words."""


class OutputError(BlendifyError, OSError):
    """A file the library writes for the user (an image, a scene file, a video, a report, a manifest) could
    not be written. The message names the argument and the path; ``errno`` holds the cause's error number
    (``errno.EACCES``, ``errno.ENAMETOOLONG``, ...) and ``filename`` the path."""

    def __init__(self, message: str, path: str | None = None, errno: int | None = None):
        super().__init__(message)
        self.errno = errno
        self.strerror = message
        self.filename = path

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""

    def __reduce__(self) -> tuple:  # keeps path and errno when a worker process sends the error back
        return (type(self), (str(self), self.filename, self.errno))


class MissingFolderError(OutputError, InvalidSceneError):
    """The folder a file should be written into does not exist. An :class:`OutputError` (so an ``OSError``)
    like every failed write, and also an :class:`InvalidSceneError`, as a bad path argument always was."""


#: the exit codes of every ``blendify`` subcommand (README, "Command line"); :func:`exit_code` picks one
EXIT_CODES = {
    0: "success (crosscheck: every pair agreed; batch: every job done or skipped)",
    1: "the work failed: a render, an output file, a batch job, or a crosscheck pair that disagreed "
    "(or fewer than two backends rendered)",
    2: "bad usage or input: unknown option or bad value, a missing or invalid scene / jobs file, "
    "an output folder that does not exist",
    3: "the backend asked for is unavailable here (not installed, or no GPU with strict)",
    130: "interrupted (Ctrl-C)",
}


def exit_code(exc: BaseException) -> int:
    """The ``blendify`` exit code for an exception that ended a subcommand (see :data:`EXIT_CODES`)."""
    if isinstance(exc, KeyboardInterrupt):
        return 130
    if isinstance(exc, BackendUnavailableError):
        return 3
    if isinstance(exc, (InvalidSceneError, FileNotFoundError, NotADirectoryError, IsADirectoryError)):
        return 2
    return 1


def exit_code_epilog() -> str:
    """The exit-code table as the epilog of every subcommand's ``--help``."""
    return "exit codes (every subcommand):\n" + "\n".join(f"  {code:<4} {text}" for code, text in EXIT_CODES.items())


_LIBRARY_MODULES = ("blendify_core", "blendify_blender", "blendify_mitsuba", "blendify_pyrender")


def warn_at_caller(message: str, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn`` pointing at the first frame outside blendify's packages (the user's line)."""
    import sys
    import warnings

    level, frame = 2, sys._getframe(1)  # level 2: the caller of this function
    while frame is not None and str(frame.f_globals.get("__name__", "")).startswith(_LIBRARY_MODULES):
        frame = frame.f_back  # type: ignore[assignment]
        level += 1
    warnings.warn(message, category, stacklevel=level)


def describe(value: object) -> str:
    """A short description of a bad value for error messages: its type and (shortened) repr, or an
    array's shape and dtype."""
    shape, dtype = getattr(value, "shape", None), getattr(value, "dtype", None)
    if shape is not None and dtype is not None and type(value).__module__.startswith("numpy"):
        return f"an array of shape {shape} and dtype {dtype}"
    text = repr(value)
    if len(text) > 80:
        text = text[:77] + "..."
    return f"{type(value).__name__} {text}"


def strict_arguments(func: _F) -> _F:
    """Decorator: a call with unknown keyword arguments (or missing / surplus arguments) raises
    InvalidSceneError naming them, instead of Python's bare TypeError. The signature is unchanged
    (``inspect.signature`` follows ``__wrapped__``). A call that binds costs nothing extra: the arguments
    are checked only when the call raised TypeError (Python binds before the body runs, so a binding
    failure means the body never ran; a TypeError from inside the body is raised unchanged)."""
    if getattr(func, "__blendify_strict__", False):
        return func
    sig = inspect.signature(func)

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except TypeError:
            try:
                sig.bind(*args, **kwargs)
            except TypeError as exc:
                raise InvalidSceneError(f"{func.__qualname__}: {exc}") from None
            raise

    wrapper.__blendify_strict__ = True  # type: ignore[attr-defined]
    return wrapper  # type: ignore[return-value]
