"""blendify-core backend `cycles` (engine: bpy). The engine is imported lazily, on first use."""

from __future__ import annotations

from typing import Any

from blendify_core.backend import Backend, BackendStatus
from blendify_core.errors import BackendUnavailableError

__all__ = ["CyclesBackend"]


class CyclesBackend(Backend):
    """Skeleton: registered, reports itself unavailable until its translator lands."""

    name = "cycles"
    engine = "bpy"

    @classmethod
    def probe(cls) -> BackendStatus:
        return BackendStatus(False, "the cycles translator is not implemented yet", cls.engine_version())

    def translate(self, scene: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the cycles translator is not implemented yet")

    def render(self, native: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the cycles translator is not implemented yet")
