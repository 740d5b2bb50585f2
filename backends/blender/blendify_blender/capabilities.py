"""The Cycles capability table: exactly what :class:`~blendify_blender.translate.CyclesTranslator` declares
beside its handlers (and in its ``extra_capabilities``); a feature nobody declares is unsupported."""

from __future__ import annotations

from blendify_core.pipeline.capabilities import Capability

from .translate import CyclesTranslator

__all__ = ["capabilities"]


def capabilities() -> dict[str, Capability]:
    """Feature name -> Capability for every name in ``blendify_core.pipeline.capabilities.ALL_FEATURES``."""
    return CyclesTranslator.capabilities()
