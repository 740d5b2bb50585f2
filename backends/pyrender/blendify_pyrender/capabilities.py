"""The pyrender backend's capability table: exactly what :class:`PyrenderTranslator`'s handlers declare
(translate.py; one default: a feature no handler declares is unsupported). Reading it imports neither
pyrender nor OpenGL (the registry and the core read it before any OpenGL platform is chosen)."""

from __future__ import annotations

from blendify_core.pipeline.capabilities import Capability

from .translate import PyrenderTranslator

__all__ = ["capability_table"]


def capability_table() -> dict[str, Capability]:
    """Feature -> Capability for every name of ``ALL_FEATURES``, as declared beside the handlers."""
    return PyrenderTranslator.capabilities()
