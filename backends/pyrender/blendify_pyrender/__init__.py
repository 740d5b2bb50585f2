"""blendify-core backend `pyrender` (engine: pyrender). The engine is imported lazily, on first use."""

from __future__ import annotations

from typing import Any

from blendify_core.backend import Backend, BackendStatus
from blendify_core.errors import BackendUnavailableError

__all__ = ["PyrenderBackend"]


class PyrenderBackend(Backend):
    """Skeleton: registered, reports itself unavailable until its translator lands."""

    name = "pyrender"
    engine = "pyrender"

    @classmethod
    def probe(cls) -> BackendStatus:
        return BackendStatus(False, "the pyrender translator is not implemented yet", cls.engine_version())

    def translate(self, scene: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the pyrender translator is not implemented yet")

    def render(self, native: Any, settings: Any) -> Any:
        raise BackendUnavailableError("the pyrender translator is not implemented yet")
