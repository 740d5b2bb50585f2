"""The pyrender translator: its capability table is the one of the previous release (frozen copy), declared
beside the handlers; nothing is rendered here."""

from __future__ import annotations

import json
from pathlib import Path

from blendify_pyrender import PyrenderBackend

from blendify_core.pipeline.capabilities import ALL_FEATURES

FROZEN = Path(__file__).with_name("frozen_capabilities.json")


def test_capability_table_equals_the_frozen_copy():
    """feature -> (level, note) exactly as the table was before the translator declared it (no behaviour change)."""
    frozen = {k: tuple(v) for k, v in json.loads(FROZEN.read_text()).items()}
    caps = {k: (c.level, c.note) for k, c in PyrenderBackend.capabilities().items()}
    assert set(frozen) == set(ALL_FEATURES)
    assert caps == frozen
