"""bf.render warns (and records in meta) when float64 itself cannot place the scene; shared backend
instances are reused even for unhashable options."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import register_backend, shared_backend, unregister_backend
from blendify_core.testing import _hc_base


class EmptyBackend(Backend):
    name = "empty-test"

    def __init__(self, **options):
        self.options = options
        self._closed = False

    @classmethod
    def capabilities(cls):
        return {k: Capability("exact") for k in ALL_FEATURES}

    def translate(self, scene, settings):
        return scene

    def render(self, native, settings):
        h, w = native.camera.height, native.camera.width
        return RenderResult(rgba=np.zeros((h, w, 4), np.float32), meta={})


@pytest.fixture
def empty():
    register_backend(EmptyBackend.name, EmptyBackend)
    yield EmptyBackend.name
    unregister_backend(EmptyBackend.name)
    bf.close_backends()


def _render_warnings(scene, backend):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bf.render(scene, backend=backend)
    return result, [str(w.message) for w in caught]


def test_beyond_float64_precision_is_reported(empty):
    result, messages = _render_warnings(_hc_base(offset=(1e30, 0.0, 0.0)), empty)
    assert any("float64 precision" in m for m in messages)
    assert any("float64 precision" in m for m in result.meta["warnings"])


def test_far_but_representable_scene_is_not_reported(empty):
    result, messages = _render_warnings(_hc_base(offset=(1e6, 0.0, 0.0)), empty)
    assert not any("precision" in m for m in messages)
    assert result.meta["recentred_origin"] is not None


def test_shared_instance_reused_for_unhashable_options(empty):
    a = shared_backend(empty, levels=[1, 2, 3])
    b = shared_backend(empty, levels=[1, 2, 3])
    c = shared_backend(empty, levels=[1, 2])
    assert a is b and a is not c
