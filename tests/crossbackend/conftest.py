"""Fixtures for the cross-backend suite: every test is parametrised over backends or backend pairs; an
unavailable backend skips with its reason printed; renders are cached per session so a scene rendered
once per backend serves both the per-backend checks and every pairwise comparison."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from xb_util import BACKENDS, PAIRS, PATH_TRACERS, require

import blendify_core as bf


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    require(request.param)
    return request.param


@pytest.fixture(params=PATH_TRACERS)
def path_tracer(request: pytest.FixtureRequest) -> str:
    require(request.param)
    return request.param


@pytest.fixture(params=PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
def pair(request: pytest.FixtureRequest) -> tuple[str, str]:
    a, b = request.param
    require(a)
    require(b)
    return a, b


class RenderCache:
    """Session cache: (key, backend) -> RenderResult, rendered with comparable settings."""

    def __init__(self) -> None:
        self._cache: dict[tuple[str, str], bf.RenderResult] = {}

    def get(
        self,
        key: str,
        backend: str,
        build: Callable[[], bf.Scene],
        samples: int = 64,
        outputs: tuple[str, ...] = ("rgb", "depth", "normal", "instance"),
        **kwargs: Any,
    ) -> bf.RenderResult:
        k = (key, backend)
        if k not in self._cache:
            self._cache[k] = bf.render(
                build(),
                backend=backend,
                samples=samples,
                seed=0,
                outputs=outputs,
                pixel_filter="box",
                denoise=False,
                clamp_direct=0.0,
                clamp_indirect=0.0,
                adaptive=False,
                **kwargs,
            )
        return self._cache[k]


@pytest.fixture(scope="session")
def renders() -> RenderCache:
    return RenderCache()
