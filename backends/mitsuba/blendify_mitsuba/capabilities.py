"""The Mitsuba backend's capability table: what its translator's handlers declare, beside each handler
in :mod:`blendify_mitsuba.translate` (and ``MitsubaTranslator.extra_capabilities`` for the outputs and the
shadow switches). A feature no handler declares is "unsupported" (the one default)."""

from __future__ import annotations

from blendify_core.pipeline.capabilities import Capability

from .translate import MitsubaTranslator

__all__ = ["capabilities"]


def capabilities() -> dict[str, Capability]:
    """Feature name -> Capability for every feature of ``blendify_core.pipeline.capabilities.ALL_FEATURES``."""
    return MitsubaTranslator.capabilities()
