"""Shared fixtures of the pyrender backend tests (skipped, with the reason printed, when unusable)."""

from __future__ import annotations

import pytest
from blendify_pyrender import PyrenderBackend
from blendify_pyrender._platform import prepare_platform, resolve_platform

from blendify_core.errors import BackendUnavailableError

_status = PyrenderBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"skipping the pyrender tests: {_status.reason}")
    pytest.skip(f"pyrender backend unavailable: {_status.reason}", allow_module_level=True)

PLATFORM = resolve_platform(None)
try:  # choose the OpenGL platform before anything imports OpenGL in this test process
    prepare_platform(PLATFORM)
except BackendUnavailableError as exc:  # pragma: no cover - depends on the machine
    print(f"skipping the pyrender tests: {exc}")
    pytest.skip(f"pyrender backend unavailable: {exc}", allow_module_level=True)


@pytest.fixture(scope="session")
def pyr():
    """One pyrender backend (one GL context) for the whole session, default options."""
    with PyrenderBackend(platform=PLATFORM) as b:
        yield b
