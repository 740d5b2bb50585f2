"""Shared fixtures of the Mitsuba backend tests."""

from __future__ import annotations

import pytest
from blendify_mitsuba import MitsubaBackend


@pytest.fixture(scope="session", autouse=True)
def _private_probe_cache(tmp_path_factory):
    """The variant-probe cache of these tests (and of their child processes) lives in a temporary
    folder: the tests never read or write the user's ~/.cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BLENDIFY_MITSUBA_PROBE_CACHE", str(tmp_path_factory.mktemp("probe-cache") / "probes.json"))
        yield


@pytest.fixture(scope="session")
def scalar_backend():
    """One scalar_rgb backend for the whole session (the default tests never need a JIT variant)."""
    with MitsubaBackend(variant="scalar_rgb") as b:
        yield b


@pytest.fixture
def mi_scalar(scalar_backend):
    """The mitsuba module with the scalar_rgb variant set (set again for every test: it is global)."""
    return scalar_backend.session.set_variant()
