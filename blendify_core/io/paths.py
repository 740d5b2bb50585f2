"""File-path arguments: one check for every public function that takes a path."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from blendify_core.errors import InvalidSceneError, describe

__all__ = ["as_path"]


def as_path(name: str, value: Any) -> Path:
    """Check a file path argument (str or os.PathLike) and return it as a ``pathlib.Path``."""
    if not isinstance(value, (str, os.PathLike)) or (isinstance(value, str) and not value):
        raise InvalidSceneError(f"{name}: expected a file path (str or os.PathLike), got {describe(value)}")
    return Path(value)
