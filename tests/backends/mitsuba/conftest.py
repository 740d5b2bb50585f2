"""Shared fixtures of the Mitsuba backend tests."""

from __future__ import annotations

import pytest
from blendify_mitsuba import MitsubaBackend


@pytest.fixture(scope="session")
def scalar_backend():
    """One scalar_rgb backend for the whole session (the default tests never need a JIT variant)."""
    with MitsubaBackend(variant="scalar_rgb") as b:
        yield b


@pytest.fixture
def mi_scalar(scalar_backend):
    """The mitsuba module with the scalar_rgb variant set (set again for every test: it is global)."""
    return scalar_backend._set_variant()
