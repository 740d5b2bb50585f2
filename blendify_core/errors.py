"""The error hierarchy of blendify-core.

Every error raised on purpose by the library derives from :class:`BlendifyError`, so callers can catch
them all at once, and each also derives from the builtin exception a Python user would expect
(``ValueError`` for bad input, ``ImportError`` for a missing engine, ``RuntimeError`` for a failed render).
"""

from __future__ import annotations

__all__ = [
    "BlendifyError",
    "InvalidSceneError",
    "UnsupportedFeatureError",
    "BackendUnavailableError",
    "RenderError",
]


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
