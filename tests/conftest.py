"""Shared pytest options and fixtures for the whole test tree (core, backends, cross-backend, golden)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS_DIR = REPO_ROOT / "artifacts"  # git-ignored


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("blendify")
    group.addoption(
        "--keep-artifacts",
        action="store_true",
        default=False,
        help="keep images and files written by tests in artifacts/<test id>/ (default: temporary folders)",
    )
    group.addoption(
        "--update-golden",
        action="store_true",
        default=False,
        help="regenerate the golden reference images instead of comparing against them",
    )


#: the Mitsuba variant of every backend a test creates without naming one (tests that are about a variant ask
#: for it by name). The automatic choice depends on the machine's libLLVM: with one, each small test render
#: would pay for JIT-compiling its kernels (the default run took 1112 s instead of about 600 s, measured), and
#: outcomes would depend on what the machine has. Set BLENDIFY_MITSUBA_VARIANT before pytest to run the suite
#: in another variant (``auto``: the automatic choice).
TEST_MITSUBA_VARIANT = "scalar_rgb"


@pytest.fixture(scope="session", autouse=True)
def _mitsuba_default_variant():
    """Sets $BLENDIFY_MITSUBA_VARIANT for the session (and the processes it starts) unless the caller set it."""
    if "BLENDIFY_MITSUBA_VARIANT" in os.environ:
        yield
        return
    os.environ["BLENDIFY_MITSUBA_VARIANT"] = TEST_MITSUBA_VARIANT
    try:
        yield
    finally:
        os.environ.pop("BLENDIFY_MITSUBA_VARIANT", None)


@pytest.fixture
def rng() -> np.random.Generator:
    """A numpy generator with a fixed seed: tests are reproducible run to run."""
    return np.random.default_rng(20240601)


@pytest.fixture
def keep_artifacts(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--keep-artifacts"))


@pytest.fixture
def update_golden(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--update-golden"))


@pytest.fixture
def artifacts_dir(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    """Where a test writes files worth looking at: a temporary folder, or artifacts/<test id> with
    ``--keep-artifacts`` (emptied first so stale files never mislead)."""
    if not request.config.getoption("--keep-artifacts"):
        return tmp_path
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in request.node.nodeid)
    out = ARTIFACTS_DIR / safe
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    return out


@pytest.fixture
def data_dir() -> Path:
    """The repository's test data folder (tests/data, with sources and licences in its README)."""
    from blendify_core.testing import DATA_DIR

    return DATA_DIR
