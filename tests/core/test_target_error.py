"""render(target_error=...) renders independent passes until the estimated error is low enough."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.render import relative_error_estimate
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import plane_scene

TRUTH = 0.5
SIGMA = 0.5  # per-sample standard deviation of the fake path tracer


class NoisyBackend(Backend):
    """A fake path tracer: the true value plus Gaussian noise shrinking as 1/sqrt(samples)."""

    name = "noisy-test"
    path_tracer = True

    @classmethod
    def capabilities(cls):
        return {k: Capability("exact") for k in ALL_FEATURES}

    def translate(self, scene, settings):
        return scene

    def render(self, native, settings):
        rng = np.random.default_rng(settings.seed)
        h, w = native.camera.height, native.camera.width
        rgb = TRUTH + rng.normal(size=(h, w, 3)) * SIGMA / np.sqrt(settings.samples)
        rgba = np.concatenate([rgb, np.ones((h, w, 1))], axis=-1).astype(np.float32)
        return RenderResult(rgba=rgba, meta={})


@pytest.fixture
def noisy():
    register_backend(NoisyBackend.name, NoisyBackend)
    yield NoisyBackend.name
    unregister_backend(NoisyBackend.name)
    bf.close_backends()


def true_error(rgba):
    return float(np.sqrt(np.mean((rgba[..., :3] - TRUTH) ** 2 / (TRUTH**2 + 1e-2))))


@pytest.mark.parametrize("target", [0.05, 0.01])
def test_target_error_reached_and_estimate_is_honest(noisy, target):
    result = bf.render(plane_scene("sun"), backend=noisy, samples=16, target_error=target)
    meta = result.meta
    assert meta["target_reached"] is True
    assert meta["estimated_error"] <= target
    assert meta["passes"] >= 4
    # the estimate is within a factor of 1.5 of the true error
    truth = true_error(result.rgba)
    assert truth / 1.5 <= meta["estimated_error"] <= truth * 1.5
    # and the work was not wildly more than needed (error ~ 1/sqrt(samples))
    needed = (SIGMA / TRUTH) ** 2 * (TRUTH**2 / (TRUTH**2 + 1e-2)) / target**2
    assert meta["samples"] <= 4 * needed + 64


def test_time_limit_stops_early(noisy):
    result = bf.render(plane_scene("sun"), backend=noisy, samples=1, target_error=1e-6, time_limit=1e-9)
    assert result.meta["target_reached"] is False
    assert result.meta["passes"] == 1


def test_raster_backend_warns_instead(monkeypatch, noisy):
    monkeypatch.setattr(NoisyBackend, "path_tracer", False)
    result = bf.render(plane_scene("sun"), backend=noisy, samples=4, target_error=0.01)
    assert "passes" not in result.meta
    assert any("not a path tracer" in w for w in result.meta["warnings"])


def test_estimator_weighting_matches_equal_split():
    rng = np.random.default_rng(0)
    passes = rng.normal(size=(6, 8, 8, 3)) + 1.0
    equal = relative_error_estimate(passes)
    weighted = relative_error_estimate(passes, np.full(6, 10.0))
    assert equal == pytest.approx(weighted)
    assert equal > 0
