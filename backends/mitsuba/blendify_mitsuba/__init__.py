"""blendify-core backend `mitsuba` (engine: mitsuba). The engine is imported lazily, on first use."""

from __future__ import annotations

from typing import Any

from blendify_core.backend import Backend, BackendStatus
from blendify_core.errors import BackendUnavailableError

__all__ = ["MitsubaBackend"]


class MitsubaBackend(Backend):
    """Skeleton: registered, reports itself unavailable until its translator lands."""

    name = "mitsuba"
    engine = "mitsuba"

    @classmethod
    def probe(cls) -> BackendStatus:
        return BackendStatus(False, "the mitsuba translator is not implemented yet", cls.engine_version())

    def translate(self, scene: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the mitsuba translator is not implemented yet")

    def render(self, native: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the mitsuba translator is not implemented yet")
